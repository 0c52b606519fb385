//! Checkpoints of the candle network and its optimiser: [`save`] and [`load`] move the
//! weights and Adam's state of a [`Net`] and an [`Adam`] to and from a checkpoint file
//! (the format, its checks and its atomic writes: [`fulcrum_contracts::checkpoint`]), and
//! [`rng_state`] and [`rng_restore`] turn the learner's generator into a blob and back.
//!
//! [`save`]: crate::checkpoint::save
//! [`load`]: crate::checkpoint::load
//! [`Net`]: crate::net::Net
//! [`Adam`]: crate::adam::Adam
//! [`rng_state`]: crate::checkpoint::rng_state
//! [`rng_restore`]: crate::checkpoint::rng_restore

use std::path::Path;

use candle_core::{DType, Tensor};
use fulcrum_contracts::checkpoint::{self as file, ParamState, ADAM_M, ADAM_V};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::adam::Adam;
use crate::net::Net;

// What `save` and `load` take and give, where the learner's callers have always found it.
pub use fulcrum_contracts::checkpoint::{CheckpointError, Extra};

/// Length of [`rng_state`]'s output: seed (32) + stream (8) + word position (16).
pub const RNG_STATE_LEN: usize = 56;

fn tensor_err(path: &Path) -> impl Fn(candle_core::Error) -> CheckpointError + '_ {
    move |e| CheckpointError::Tensor {
        path: path.to_path_buf(),
        detail: e.to_string(),
    }
}

/// A tensor's elements as f32 (row-major).
fn f32s(t: &Tensor) -> candle_core::Result<Vec<f32>> {
    t.to_dtype(DType::F32)?.flatten_all()?.to_vec1::<f32>()
}

/// Writes the network, Adam's state and `extra` to `path`, atomically (see
/// [`fulcrum_contracts::checkpoint`]). On error the previous file at `path`, if any, is left
/// intact.
pub fn save(path: &Path, net: &Net, adam: &Adam, extra: &Extra) -> Result<(), CheckpointError> {
    let mismatch = |detail: String| CheckpointError::Mismatch {
        path: path.to_path_buf(),
        detail,
    };
    let n = net.params.len();
    if adam.m.len() != n || adam.v.len() != n {
        return Err(mismatch(format!(
            "the optimiser has {} first and {} second moments for {n} parameters",
            adam.m.len(),
            adam.v.len()
        )));
    }
    let mut params = Vec::with_capacity(n);
    for (i, (name, var)) in net.params.iter().enumerate() {
        let shape = var.as_tensor().dims().to_vec();
        let weights = f32s(var.as_tensor()).map_err(tensor_err(path))?;
        file::check_finite(path, name, &weights)?;
        let mut moments = Vec::with_capacity(2);
        for (prefix, moment) in [(ADAM_M, &adam.m), (ADAM_V, &adam.v)] {
            let t = &moment[i];
            if t.dims() != shape.as_slice() {
                return Err(mismatch(format!(
                    "the optimiser's {prefix}{name} is {:?}, the parameter {shape:?}",
                    t.dims()
                )));
            }
            moments.push(f32s(t).map_err(tensor_err(path))?);
        }
        let v = moments.pop().unwrap_or_default();
        let m = moments.pop().unwrap_or_default();
        params.push(ParamState {
            name: name.clone(),
            dims: shape,
            weights,
            m,
            v,
        });
    }
    file::write(path, &params, adam.step, extra)
}

/// Reads a checkpoint written by [`save`] into `net` and `adam` and returns the rest.
///
/// The file is validated completely first (see [`fulcrum_contracts::checkpoint`]); on any
/// error `net` and `adam` are unchanged.
pub fn load(path: &Path, net: &Net, adam: &mut Adam) -> Result<Extra, CheckpointError> {
    let table: Vec<(&str, Vec<usize>)> = net
        .params
        .iter()
        .map(|(name, var)| (name.as_str(), var.as_tensor().dims().to_vec()))
        .collect();
    let contents = file::read(path, &table)?;

    // Build every tensor before changing anything.
    let make = |data: Vec<f32>, like: &Tensor| -> Result<Tensor, CheckpointError> {
        Tensor::from_vec(data, like.dims(), like.device())
            .and_then(|t| t.to_dtype(like.dtype()))
            .map_err(tensor_err(path))
    };
    let n = net.params.len();
    let mut new_w = Vec::with_capacity(n);
    let mut new_m = Vec::with_capacity(n);
    let mut new_v = Vec::with_capacity(n);
    for (p, (_, var)) in contents.params.into_iter().zip(&net.params) {
        let like = var.as_tensor();
        new_w.push(make(p.weights, like)?);
        new_m.push(make(p.m, like)?);
        new_v.push(make(p.v, like)?);
    }
    // Var::set only fails on a shape mismatch or aliasing, both excluded above.
    for ((_, var), w) in net.params.iter().zip(&new_w) {
        var.set(w).map_err(tensor_err(path))?;
    }
    adam.m = new_m;
    adam.v = new_v;
    adam.step = contents.step;
    Ok(contents.extra)
}

/// A ChaCha8 generator's full state: seed (32 bytes), stream (u64) and word position
/// (u128), little endian, [`RNG_STATE_LEN`] bytes.
pub fn rng_state(rng: &ChaCha8Rng) -> Vec<u8> {
    let mut out = Vec::with_capacity(RNG_STATE_LEN);
    out.extend_from_slice(&rng.get_seed());
    out.extend_from_slice(&rng.get_stream().to_le_bytes());
    out.extend_from_slice(&rng.get_word_pos().to_le_bytes());
    out
}

/// The generator whose state [`rng_state`] returned; None if `bytes` is not
/// [`RNG_STATE_LEN`] long.
pub fn rng_restore(bytes: &[u8]) -> Option<ChaCha8Rng> {
    if bytes.len() != RNG_STATE_LEN {
        return None;
    }
    let seed: [u8; 32] = bytes[..32].try_into().ok()?;
    let stream = u64::from_le_bytes(bytes[32..40].try_into().ok()?);
    let pos = u128::from_le_bytes(bytes[40..56].try_into().ok()?);
    let mut rng = ChaCha8Rng::from_seed(seed);
    rng.set_stream(stream);
    rng.set_word_pos(pos);
    Some(rng)
}
