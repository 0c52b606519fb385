//! Checkpoint files: the network's weights, Adam's state and the trainer's counters in
//! one safetensors file, written atomically and validated completely before anything is
//! used. The learner saves and loads its candle network through this format; an actor
//! reads the worlds it resumes from the same file.
//!
//! # File format (`fulcrum.checkpoint = 1`)
//!
//! One [safetensors](https://github.com/huggingface/safetensors) file. Tensors:
//!
//! | name               | dtype | shape                     | content                                |
//! |--------------------|-------|---------------------------|----------------------------------------|
//! | `param/<name>`     | F32   | the parameter's shape     | weights, e.g. `param/policy.embed`     |
//! | `adam.m/<name>`    | F32   | the parameter's shape     | Adam's first moment of the parameter   |
//! | `adam.v/<name>`    | F32   | the parameter's shape     | Adam's second moment of the parameter  |
//! | `blob/<key>`       | U8    | `[len]`                   | [`Extra::blobs`] entry (opaque bytes)  |
//!
//! The safetensors header metadata (`__metadata__`, string to string) holds:
//!
//! | key                  | value                                                          |
//! |----------------------|----------------------------------------------------------------|
//! | `fulcrum.checkpoint` | format version, `1`                                            |
//! | `fulcrum.checksum`   | FNV-1a 64 of everything else, 16 lowercase hex digits (below)  |
//! | `adam.step`          | Adam's step count, decimal                                     |
//! | `counter.<key>`      | [`Extra::counters`] entry, decimal u64                         |
//! | `float.<key>`        | [`Extra::floats`] entry, Rust's shortest round-trip text (`{:?}`: `0.1`, `1e-30`, `inf`, `NaN`) |
//! | `meta.<key>`         | [`Extra::meta`] entry, verbatim                                |
//!
//! The checksum is FNV-1a 64 over, in this order: for every metadata entry except the
//! checksum itself, sorted by key, `key 0x00 value 0x00`; then for every tensor, sorted by
//! name, `name 0x00 dtype 0x00`, each dimension as u64 little endian, then the raw data.
//! It catches flipped bits in the weights, which the safetensors header check cannot.
//! Floats come back bit-exact except NaN payloads (every NaN is read back as
//! `f64::NAN`).
//!
//! # Guarantees
//!
//! * [`write`] writes a temporary file of its own in the same directory, fsyncs it, renames it over
//!   `path` and fsyncs the directory: `path` always holds either the previous checkpoint
//!   or the new one, never a partial file. It refuses to write non-finite weights (that
//!   would replace a good checkpoint with one that [`read`] refuses).
//! * [`read`] checks the whole file (parse, version, checksum, every tensor's presence,
//!   dtype and shape against the network's parameter table, no unknown entries, finite
//!   weights and moments, parsable counters) before it returns anything: a bad file
//!   never half-loads.
//! * Every error is one sentence naming the file and what is wrong.
//!
//! [`Extra::blobs`]: crate::checkpoint::Extra::blobs
//! [`Extra::counters`]: crate::checkpoint::Extra::counters
//! [`Extra::floats`]: crate::checkpoint::Extra::floats
//! [`Extra::meta`]: crate::checkpoint::Extra::meta
//! [`write`]: fn@crate::checkpoint::write
//! [`read`]: crate::checkpoint::read

use std::collections::{BTreeMap, HashMap};
use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use safetensors::tensor::{Dtype, TensorView, View};
use safetensors::SafeTensors;

/// The format version this build writes and reads.
pub const FORMAT_VERSION: u32 = 1;
/// Metadata key of the format version.
pub const VERSION_KEY: &str = "fulcrum.checkpoint";
/// Metadata key of the checksum.
pub const CHECKSUM_KEY: &str = "fulcrum.checksum";
const STEP_KEY: &str = "adam.step";
const COUNTER: &str = "counter.";
const FLOAT: &str = "float.";
const META: &str = "meta.";
/// Name prefix of a parameter's weights.
pub const PARAM: &str = "param/";
/// Name prefix of a parameter's first moment.
pub const ADAM_M: &str = "adam.m/";
/// Name prefix of a parameter's second moment.
pub const ADAM_V: &str = "adam.v/";
const BLOB: &str = "blob/";

/// Everything but tensors that a checkpoint carries.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Extra {
    /// Integer counters (env steps, updates, ...).
    pub counters: BTreeMap<String, u64>,
    /// Floating-point values, stored exactly.
    pub floats: BTreeMap<String, f64>,
    /// Opaque byte strings (generator states, the actors' worlds, ...).
    pub blobs: BTreeMap<String, Vec<u8>>,
    /// Free text (config, git revision, ...).
    pub meta: BTreeMap<String, String>,
}

/// Why a checkpoint could not be saved or loaded. Each message is one sentence naming
/// the file.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    /// The file could not be read.
    #[error("cannot read checkpoint {}: {source}", path.display())]
    Read {
        /// The checkpoint.
        path: PathBuf,
        /// The I/O error.
        source: io::Error,
    },
    /// The file is not a well-formed safetensors file, or its checksum does not match.
    #[error("checkpoint {} is truncated or corrupt: {detail}", path.display())]
    Corrupt {
        /// The checkpoint.
        path: PathBuf,
        /// What is wrong.
        detail: String,
    },
    /// The file has no version key or another version.
    #[error(
        "checkpoint {} has format version {found}, but this build reads version {FORMAT_VERSION}",
        path.display()
    )]
    Version {
        /// The checkpoint.
        path: PathBuf,
        /// The version found ("none" when the key is missing).
        found: String,
    },
    /// A parameter is missing, extra, or of another shape or dtype than the network's.
    #[error("checkpoint {} was written for a network of other shape: {detail}", path.display())]
    Shape {
        /// The checkpoint.
        path: PathBuf,
        /// E.g. "policy.embed is [400, 64], expected [300, 64]".
        detail: String,
    },
    /// Weights or moments hold NaN or infinite values.
    #[error("checkpoint {} holds non-finite values: {detail}", path.display())]
    NonFinite {
        /// The checkpoint.
        path: PathBuf,
        /// E.g. "policy.l2.w has NaN at element 17".
        detail: String,
    },
    /// Some other entry is missing or malformed (a well-formed safetensors file that is not
    /// a valid checkpoint).
    #[error("checkpoint {} is not a valid fulcrum checkpoint: {detail}", path.display())]
    Invalid {
        /// The checkpoint.
        path: PathBuf,
        /// What is wrong.
        detail: String,
    },
    /// The optimiser state does not fit the network.
    #[error("cannot save checkpoint {}: {detail}", path.display())]
    Mismatch {
        /// The checkpoint.
        path: PathBuf,
        /// What does not fit.
        detail: String,
    },
    /// Writing the file failed; the previous file at `path`, if any, is intact.
    #[error("cannot write checkpoint {}: {what}: {source}", path.display())]
    Write {
        /// The checkpoint.
        path: PathBuf,
        /// The step that failed, e.g. "cannot create the temporary file x.tmp".
        what: String,
        /// The I/O error.
        source: io::Error,
    },
    /// A tensor operation failed (reading weights off the device, making tensors).
    #[error("checkpoint {}: tensor operation failed: {detail}", path.display())]
    Tensor {
        /// The checkpoint.
        path: PathBuf,
        /// The tensor library's error.
        detail: String,
    },
}

/// A parameter's weights and Adam moments as a checkpoint holds them (f32, row-major).
#[derive(Debug, Clone, PartialEq)]
pub struct ParamState {
    /// The parameter's name (`policy.embed`, ...).
    pub name: String,
    /// Its dimensions.
    pub dims: Vec<usize>,
    /// Its weights.
    pub weights: Vec<f32>,
    /// Adam's first moment.
    pub m: Vec<f32>,
    /// Adam's second moment.
    pub v: Vec<f32>,
}

/// Everything a checkpoint holds.
#[derive(Debug, Clone, PartialEq)]
pub struct Contents {
    /// The parameters, in the network's order.
    pub params: Vec<ParamState>,
    /// Adam's step count.
    pub step: u64,
    /// Counters, floats, blobs and text.
    pub extra: Extra,
}

/// A tensor owned as little-endian bytes, for safetensors' serializer.
struct Bytes {
    dtype: Dtype,
    shape: Vec<usize>,
    data: Vec<u8>,
}

impl View for &Bytes {
    fn dtype(&self) -> Dtype {
        self.dtype
    }
    fn shape(&self) -> &[usize] {
        &self.shape
    }
    fn data(&self) -> std::borrow::Cow<'_, [u8]> {
        std::borrow::Cow::Borrowed(&self.data)
    }
    fn data_len(&self) -> usize {
        self.data.len()
    }
}

/// FNV-1a 64.
#[derive(Debug, Clone, Copy)]
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn update(&mut self, bytes: &[u8]) {
        let mut h = self.0;
        for &b in bytes {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
        self.0 = h;
    }
}

/// The checksum of metadata (without the checksum key) and tensors, as in the module docs.
fn checksum<'a>(
    meta: &BTreeMap<&str, &str>,
    tensors: impl IntoIterator<Item = (&'a str, Dtype, &'a [usize], &'a [u8])>,
) -> String {
    let mut h = Fnv::new();
    for (k, v) in meta {
        if *k == CHECKSUM_KEY {
            continue;
        }
        h.update(k.as_bytes());
        h.update(&[0]);
        h.update(v.as_bytes());
        h.update(&[0]);
    }
    let mut sorted: Vec<_> = tensors.into_iter().collect();
    sorted.sort_by(|a, b| a.0.cmp(b.0));
    for (name, dtype, shape, data) in sorted {
        h.update(name.as_bytes());
        h.update(&[0]);
        h.update(dtype.to_string().as_bytes());
        h.update(&[0]);
        for &d in shape {
            h.update(&(d as u64).to_le_bytes());
        }
        h.update(data);
    }
    format!("{:016x}", h.0)
}

/// First non-finite value of `data`, as "NaN at element 17".
fn non_finite(data: &[f32]) -> Option<String> {
    data.iter().position(|x| !x.is_finite()).map(|i| {
        let kind = if data[i].is_nan() {
            "NaN"
        } else {
            "an infinite value"
        };
        format!("{kind} at element {i}")
    })
}

/// The refusal [`write()`] makes: an error naming parameter `name` if `weights` holds a
/// NaN or an infinite value (a checkpoint that [`read`] would refuse must never replace
/// a good one).
pub fn check_finite(path: &Path, name: &str, weights: &[f32]) -> Result<(), CheckpointError> {
    match non_finite(weights) {
        Some(what) => Err(CheckpointError::NonFinite {
            path: path.to_path_buf(),
            detail: format!("refusing to save: parameter {name} has {what}"),
        }),
        None => Ok(()),
    }
}

fn f32_bytes(x: &[f32]) -> Vec<u8> {
    x.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Writes `params`, Adam's `step` and `extra` to `path`, atomically (see the module
/// docs). On error the previous file at `path`, if any, is left intact.
pub fn write(
    path: &Path,
    params: &[ParamState],
    step: u64,
    extra: &Extra,
) -> Result<(), CheckpointError> {
    let mismatch = |detail: String| CheckpointError::Mismatch {
        path: path.to_path_buf(),
        detail,
    };
    let mut tensors: Vec<(String, Bytes)> =
        Vec::with_capacity(3 * params.len() + extra.blobs.len());
    for p in params {
        check_finite(path, &p.name, &p.weights)?;
        let len: usize = p.dims.iter().product();
        if p.weights.len() != len || p.m.len() != len || p.v.len() != len {
            return Err(mismatch(format!(
                "parameter {} of dimensions {:?} has {} weights and {} and {} moments",
                p.name,
                p.dims,
                p.weights.len(),
                p.m.len(),
                p.v.len()
            )));
        }
        for (prefix, data) in [(PARAM, &p.weights), (ADAM_M, &p.m), (ADAM_V, &p.v)] {
            tensors.push((
                format!("{prefix}{}", p.name),
                Bytes {
                    dtype: Dtype::F32,
                    shape: p.dims.clone(),
                    data: f32_bytes(data),
                },
            ));
        }
    }
    for (key, blob) in &extra.blobs {
        tensors.push((
            format!("{BLOB}{key}"),
            Bytes {
                dtype: Dtype::U8,
                shape: vec![blob.len()],
                data: blob.clone(),
            },
        ));
    }

    let mut meta: BTreeMap<String, String> = BTreeMap::new();
    meta.insert(VERSION_KEY.into(), FORMAT_VERSION.to_string());
    meta.insert(STEP_KEY.into(), step.to_string());
    for (k, v) in &extra.counters {
        meta.insert(format!("{COUNTER}{k}"), v.to_string());
    }
    for (k, v) in &extra.floats {
        meta.insert(format!("{FLOAT}{k}"), format!("{v:?}"));
    }
    for (k, v) in &extra.meta {
        meta.insert(format!("{META}{k}"), v.clone());
    }
    let sum = checksum(
        &meta.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect(),
        tensors.iter().map(|(name, b)| {
            (
                name.as_str(),
                b.dtype,
                b.shape.as_slice(),
                b.data.as_slice(),
            )
        }),
    );
    meta.insert(CHECKSUM_KEY.into(), sum);

    let header: HashMap<String, String> = meta.into_iter().collect();
    let bytes = safetensors::serialize(tensors.iter().map(|(k, b)| (k, b)), Some(header))
        .map_err(|e| mismatch(format!("safetensors cannot serialize it: {e}")))?;
    write_atomic(path, &bytes)
}

/// A temporary file of its own (`.<name>.tmp-<pid>-<n>`, [`crate::fsio::temp_path`]),
/// fsync, rename over `path`, fsync the directory.
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), CheckpointError> {
    let fail = |what: String, source: io::Error| CheckpointError::Write {
        path: path.to_path_buf(),
        what,
        source,
    };
    let tmp = crate::fsio::temp_path(path)
        .map_err(|e| fail("the path does not name a file".into(), e))?;
    crate::fsio::replace_via(path, &tmp, bytes, true).map_err(|(what, source)| fail(what, source))
}

/// A validated tensor of the file, as f32 values.
fn read_f32(
    path: &Path,
    st: &SafeTensors<'_>,
    name: &str,
    expect: &[usize],
    is_param: bool,
) -> Result<Vec<f32>, CheckpointError> {
    let invalid = |detail: String| CheckpointError::Invalid {
        path: path.to_path_buf(),
        detail,
    };
    let view = match st.tensor(name) {
        Ok(v) => v,
        Err(_) if is_param => {
            return Err(CheckpointError::Shape {
                path: path.to_path_buf(),
                detail: format!(
                    "it has no parameter {}",
                    name.strip_prefix(PARAM).unwrap_or(name)
                ),
            })
        }
        Err(_) => return Err(invalid(format!("it has no tensor {name}"))),
    };
    let short = if is_param {
        name.strip_prefix(PARAM).unwrap_or(name)
    } else {
        name
    };
    if view.shape() != expect {
        return Err(CheckpointError::Shape {
            path: path.to_path_buf(),
            detail: format!("{short} is {:?}, expected {expect:?}", view.shape()),
        });
    }
    if view.dtype() != Dtype::F32 {
        return Err(CheckpointError::Shape {
            path: path.to_path_buf(),
            detail: format!("{short} has dtype {}, expected F32", view.dtype()),
        });
    }
    let data: Vec<f32> = view
        .data()
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    if let Some(what) = non_finite(&data) {
        return Err(CheckpointError::NonFinite {
            path: path.to_path_buf(),
            detail: format!("{short} has {what}"),
        });
    }
    Ok(data)
}

/// Reads a checkpoint written by [`write()`] for a network whose parameters are `params`
/// (names and dimensions, in order: [`crate::layout::NetShape::params`]).
///
/// The file is validated completely (see the module docs); the parameters come back in
/// the order of `params`.
pub fn read(path: &Path, params: &[(&str, Vec<usize>)]) -> Result<Contents, CheckpointError> {
    let bytes = fs::read(path).map_err(|source| CheckpointError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    let corrupt = |detail: String| CheckpointError::Corrupt {
        path: path.to_path_buf(),
        detail,
    };
    let st = SafeTensors::deserialize(&bytes).map_err(|e| {
        corrupt(format!(
            "the file ({} bytes) is not a readable safetensors file ({e})",
            bytes.len()
        ))
    })?;
    let (_, header) = SafeTensors::read_metadata(&bytes)
        .map_err(|e| corrupt(format!("the safetensors header cannot be read ({e})")))?;
    let empty = HashMap::new();
    let meta_map = header.metadata().as_ref().unwrap_or(&empty);
    let meta: BTreeMap<&str, &str> = meta_map
        .iter()
        .map(|(k, v)| (k.as_str(), v.as_str()))
        .collect();

    // Version, then checksum: everything after this reads trustworthy bytes.
    let views = st.tensors();
    check_version_and_sum(path, &meta, &views)?;

    // Tensors: every parameter and moment, nothing unknown.
    let n = params.len();
    let mut weights = Vec::with_capacity(n);
    let mut ms = Vec::with_capacity(n);
    let mut vs = Vec::with_capacity(n);
    for (name, shape) in params {
        weights.push(read_f32(path, &st, &format!("{PARAM}{name}"), shape, true)?);
        ms.push(read_f32(
            path,
            &st,
            &format!("{ADAM_M}{name}"),
            shape,
            false,
        )?);
        vs.push(read_f32(
            path,
            &st,
            &format!("{ADAM_V}{name}"),
            shape,
            false,
        )?);
    }
    let mut extra = Extra::default();
    read_other_tensors(path, &st, &views, params, &mut extra)?;
    let step = read_header(path, &meta, &mut extra)?;

    let params = params
        .iter()
        .zip(weights.into_iter().zip(ms.into_iter().zip(vs)))
        .map(|((name, dims), (weights, (m, v)))| ParamState {
            name: name.to_string(),
            dims: dims.clone(),
            weights,
            m,
            v,
        })
        .collect();
    Ok(Contents {
        params,
        step,
        extra,
    })
}

/// The file's format version, then its checksum over `meta` and `views`.
fn check_version_and_sum(
    path: &Path,
    meta: &BTreeMap<&str, &str>,
    views: &[(String, TensorView<'_>)],
) -> Result<(), CheckpointError> {
    let corrupt = |detail: String| CheckpointError::Corrupt {
        path: path.to_path_buf(),
        detail,
    };
    let invalid = |detail: String| CheckpointError::Invalid {
        path: path.to_path_buf(),
        detail,
    };
    match meta.get(VERSION_KEY) {
        Some(v) if *v == FORMAT_VERSION.to_string() => {}
        found => {
            return Err(CheckpointError::Version {
                path: path.to_path_buf(),
                found: found.map_or_else(|| "none".to_string(), |v| v.to_string()),
            })
        }
    }
    let want = checksum(
        meta,
        views
            .iter()
            .map(|(name, v)| (name.as_str(), v.dtype(), v.shape(), v.data())),
    );
    match meta.get(CHECKSUM_KEY) {
        Some(sum) if *sum == want => {}
        Some(sum) => {
            return Err(corrupt(format!(
                "its checksum is {sum}, but its contents hash to {want}"
            )))
        }
        None => return Err(invalid(format!("it has no {CHECKSUM_KEY} entry"))),
    }

    Ok(())
}

/// The tensors besides the parameters' and moments': no parameter or moment the
/// network lacks, the blobs into `extra`, nothing unknown.
fn read_other_tensors(
    path: &Path,
    st: &SafeTensors<'_>,
    views: &[(String, TensorView<'_>)],
    params: &[(&str, Vec<usize>)],
    extra: &mut Extra,
) -> Result<(), CheckpointError> {
    let corrupt = |detail: String| CheckpointError::Corrupt {
        path: path.to_path_buf(),
        detail,
    };
    let invalid = |detail: String| CheckpointError::Invalid {
        path: path.to_path_buf(),
        detail,
    };
    let known = |n: &str| params.iter().any(|(p, _)| *p == n);
    let mut names: Vec<&str> = views.iter().map(|(n, _)| n.as_str()).collect();
    names.sort_unstable();
    for name in names {
        if let Some(p) = name.strip_prefix(PARAM) {
            if !known(p) {
                return Err(CheckpointError::Shape {
                    path: path.to_path_buf(),
                    detail: format!("it has a parameter {p} that the network lacks"),
                });
            }
        } else if let Some(p) = name
            .strip_prefix(ADAM_M)
            .or_else(|| name.strip_prefix(ADAM_V))
        {
            if !known(p) {
                return Err(invalid(format!(
                    "it has optimiser state {name} for a parameter the network lacks"
                )));
            }
        } else if let Some(key) = name.strip_prefix(BLOB) {
            let view = st
                .tensor(name)
                .map_err(|e| corrupt(format!("tensor {name} cannot be read ({e})")))?;
            if view.dtype() != Dtype::U8 || view.shape().len() != 1 {
                return Err(invalid(format!(
                    "blob {name} is {} {:?}, expected a 1-D U8 tensor",
                    view.dtype(),
                    view.shape()
                )));
            }
            extra.blobs.insert(key.to_string(), view.data().to_vec());
        } else {
            return Err(invalid(format!("it has an unknown tensor {name:?}")));
        }
    }

    Ok(())
}

/// The header's step, counters, floats and text (into `extra`); nothing unknown.
/// Returns the step.
fn read_header(
    path: &Path,
    meta: &BTreeMap<&str, &str>,
    extra: &mut Extra,
) -> Result<u64, CheckpointError> {
    let invalid = |detail: String| CheckpointError::Invalid {
        path: path.to_path_buf(),
        detail,
    };
    let mut step = None;
    for (&key, &value) in meta {
        if key == VERSION_KEY || key == CHECKSUM_KEY {
        } else if key == STEP_KEY {
            step = Some(value.parse::<u64>().map_err(|_| {
                invalid(format!("{STEP_KEY} is {value:?}, not an unsigned integer"))
            })?);
        } else if let Some(k) = key.strip_prefix(COUNTER) {
            let v = value.parse::<u64>().map_err(|_| {
                invalid(format!("counter {k} is {value:?}, not an unsigned integer"))
            })?;
            extra.counters.insert(k.to_string(), v);
        } else if let Some(k) = key.strip_prefix(FLOAT) {
            let v = value
                .parse::<f64>()
                .map_err(|_| invalid(format!("float {k} is {value:?}, not a number")))?;
            extra.floats.insert(k.to_string(), v);
        } else if let Some(k) = key.strip_prefix(META) {
            extra.meta.insert(k.to_string(), value.to_string());
        } else {
            return Err(invalid(format!("it has an unknown header entry {key:?}")));
        }
    }
    step.ok_or_else(|| invalid(format!("it has no {STEP_KEY} entry")))
}
