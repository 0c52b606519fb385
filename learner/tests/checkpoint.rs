//! Checkpoints: bit-exact round trips, refusal of bad files without half-loading, and
//! atomic replacement.

use std::collections::{BTreeMap, HashMap};
use std::fs;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use candle_core::{Device, Tensor};
use fulcrum_contracts::layout::NetShape;
use fulcrum_learner::adam::Adam;
use fulcrum_learner::checkpoint::{
    load, rng_restore, rng_state, save, CheckpointError, Extra, RNG_STATE_LEN,
};
use fulcrum_learner::net::Net;
use rand::{Rng, RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A fresh directory under the system temp dir, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> Self {
        static N: AtomicU64 = AtomicU64::new(0);
        let dir = std::env::temp_dir().join(format!(
            "fulcrum-ckpt-{tag}-{}-{}",
            std::process::id(),
            N.fetch_add(1, Ordering::Relaxed)
        ));
        fs::create_dir_all(&dir).expect("create temp dir");
        Self(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

fn shape(cells: usize) -> NetShape {
    NetShape {
        cells,
        glyphs: 5,
        flags: 3,
        hidden: 8,
        actions: 4,
        int_value: false,
    }
}

fn net(cells: usize, seed: u64) -> Net {
    Net::new(shape(cells), seed, &Device::Cpu).expect("net")
}

/// Adam after two steps with non-trivial gradients: m, v and step all nonzero.
fn trained_adam(net: &Net) -> Adam {
    let mut adam = Adam::new(net).expect("adam");
    for k in 0..2 {
        let grads: Vec<Tensor> = net
            .params
            .iter()
            .map(|(_, v)| {
                let t = v.as_tensor();
                ((t.ones_like().unwrap() * (0.3 + k as f64)).unwrap() + t.sin().unwrap()).unwrap()
            })
            .collect();
        adam.apply(net, &grads, 1e-3).expect("adam step");
    }
    adam
}

fn flat(t: &[Tensor]) -> Vec<Vec<u32>> {
    t.iter()
        .map(|t| {
            t.flatten_all()
                .unwrap()
                .to_vec1::<f32>()
                .unwrap()
                .iter()
                .map(|x| x.to_bits())
                .collect()
        })
        .collect()
}

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn extra() -> Extra {
    let mut e = Extra::default();
    e.counters.insert("env_steps".into(), 123_456_789_012);
    e.counters.insert("updates".into(), 0);
    e.counters.insert("max".into(), u64::MAX);
    for (k, v) in [
        ("lr", 0.1),
        ("tiny", 1e-30),
        ("third", 1.0 / 3.0),
        ("neg_zero", -0.0),
        ("subnormal", 5e-324),
        ("big", f64::MAX),
        ("inf", f64::INFINITY),
        ("ninf", f64::NEG_INFINITY),
    ] {
        e.floats.insert(k.into(), v);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let _ = rng.next_u64();
    e.blobs.insert("rng.learner".into(), rng_state(&rng));
    e.blobs.insert("empty".into(), Vec::new());
    e.blobs.insert("bytes".into(), (0..=255).collect());
    e.meta
        .insert("config".into(), "[ppo]\nlr = 2.5e-4\n\"quoted\" é".into());
    e.meta.insert("git".into(), String::new());
    e
}

#[test]
fn round_trip_is_bit_exact() {
    let dir = TempDir::new("roundtrip");
    let path = dir.0.join("latest.safetensors");
    let a = net(6, 1);
    let adam = trained_adam(&a);
    assert_eq!(adam.step, 2);
    let ex = extra();
    save(&path, &a, &adam, &ex).expect("save");
    let names: Vec<_> = fs::read_dir(&dir.0)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, ["latest.safetensors"], "no temporary file left");

    let b = net(6, 2);
    let mut adam_b = Adam::new(&b).expect("adam");
    assert_ne!(bits(&a.flat().unwrap()), bits(&b.flat().unwrap()));
    let got = load(&path, &b, &mut adam_b).expect("load");
    assert_eq!(bits(&b.flat().unwrap()), bits(&a.flat().unwrap()));
    assert_eq!(flat(&adam_b.m), flat(&adam.m));
    assert_eq!(flat(&adam_b.v), flat(&adam.v));
    assert_eq!(adam_b.step, 2);
    assert_eq!(got.counters, ex.counters);
    assert_eq!(got.blobs, ex.blobs);
    assert_eq!(got.meta, ex.meta);
    assert_eq!(got.floats.len(), ex.floats.len());
    for (k, v) in &ex.floats {
        assert_eq!(got.floats[k].to_bits(), v.to_bits(), "float {k}");
    }
    assert_eq!(got, ex);

    // NaN floats survive as NaN.
    let mut ex2 = Extra::default();
    ex2.floats.insert("nan".into(), f64::NAN);
    save(&path, &a, &adam, &ex2).expect("save over");
    let got = load(&path, &b, &mut adam_b).expect("load");
    assert!(got.floats["nan"].is_nan());
    assert!(got.counters.is_empty() && got.blobs.is_empty() && got.meta.is_empty());

    // The loaded network and optimiser keep training identically to the originals.
    let grads: Vec<Tensor> = a
        .params
        .iter()
        .map(|(_, v)| v.as_tensor().cos().unwrap())
        .collect();
    let mut adam = adam;
    adam.apply(&a, &grads, 1e-3).unwrap();
    adam_b.apply(&b, &grads, 1e-3).unwrap();
    assert_eq!(bits(&b.flat().unwrap()), bits(&a.flat().unwrap()));
}

#[test]
fn file_format_is_as_documented() {
    let dir = TempDir::new("format");
    let path = dir.0.join("c.safetensors");
    let a = net(6, 1);
    let adam = trained_adam(&a);
    save(&path, &a, &adam, &extra()).expect("save");
    let bytes = fs::read(&path).unwrap();
    let (_, header) = safetensors::SafeTensors::read_metadata(&bytes).unwrap();
    let meta = header.metadata().as_ref().expect("metadata");
    assert_eq!(meta["fulcrum.checkpoint"], "1");
    assert_eq!(meta["adam.step"], "2");
    assert_eq!(meta["counter.env_steps"], "123456789012");
    assert_eq!(meta["float.lr"], "0.1");
    assert_eq!(meta["float.tiny"], "1e-30");
    assert_eq!(meta["meta.git"], "");
    assert_eq!(meta["fulcrum.checksum"].len(), 16);
    let st = safetensors::SafeTensors::deserialize(&bytes).unwrap();
    let embed = st.tensor("param/policy.embed").unwrap();
    assert_eq!(embed.dtype(), safetensors::Dtype::F32);
    assert_eq!(embed.shape(), &[6 * 5, 8]);
    assert_eq!(st.tensor("adam.m/policy.v.b").unwrap().shape(), &[1]);
    assert_eq!(st.tensor("adam.v/policy.l2.w").unwrap().shape(), &[8, 8]);
    let blob = st.tensor("blob/rng.learner").unwrap();
    assert_eq!(blob.dtype(), safetensors::Dtype::U8);
    assert_eq!(blob.shape(), &[RNG_STATE_LEN]);
    assert_eq!(st.len(), 3 * a.params.len() + 3);
}

#[test]
fn rng_restored_mid_stream_continues_identically() {
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    rng.set_stream(9);
    // Mid-block, not at a multiple of anything convenient.
    for _ in 0..37 {
        let _ = rng.next_u32();
    }
    let _: f32 = rng.random();
    let state = rng_state(&rng);
    assert_eq!(state.len(), RNG_STATE_LEN);
    let mut restored = rng_restore(&state).expect("restore");
    let a: Vec<u64> = (0..100).map(|_| rng.next_u64()).collect();
    let b: Vec<u64> = (0..100).map(|_| restored.next_u64()).collect();
    assert_eq!(a, b);
    // Through a checkpoint file as well.
    let dir = TempDir::new("rng");
    let path = dir.0.join("r.safetensors");
    let n = net(4, 3);
    let mut adam = Adam::new(&n).unwrap();
    let mut e = Extra::default();
    e.blobs.insert("rng".into(), rng_state(&rng));
    save(&path, &n, &adam, &e).unwrap();
    let got = load(&path, &n, &mut adam).unwrap();
    let mut restored = rng_restore(&got.blobs["rng"]).expect("restore");
    let a: Vec<u64> = (0..100).map(|_| rng.next_u64()).collect();
    let b: Vec<u64> = (0..100).map(|_| restored.next_u64()).collect();
    assert_eq!(a, b);
    // A fresh generator round-trips too; bad lengths are refused.
    let fresh = ChaCha8Rng::seed_from_u64(5);
    let mut r = rng_restore(&rng_state(&fresh)).unwrap();
    assert_eq!(r.next_u64(), fresh.clone().next_u64());
    assert!(rng_restore(&state[..55]).is_none());
    assert!(rng_restore(&[]).is_none());
}

/// Loads `path` into a fresh network and checks it is refused, leaving the network
/// and optimiser unchanged; returns the error.
fn refused(path: &Path, cells: usize) -> CheckpointError {
    let target = net(cells, 99);
    let mut adam = trained_adam(&target);
    let before = bits(&target.flat().unwrap());
    let (m, v) = (flat(&adam.m), flat(&adam.v));
    let err = load(path, &target, &mut adam).expect_err("bad checkpoint must be refused");
    assert_eq!(
        bits(&target.flat().unwrap()),
        before,
        "net changed by {err}"
    );
    assert_eq!(flat(&adam.m), m);
    assert_eq!(flat(&adam.v), v);
    assert_eq!(adam.step, 2);
    let msg = err.to_string();
    assert!(msg.contains(&path.display().to_string()), "{msg}");
    assert!(!msg.contains('\n'), "{msg}");
    err
}

#[test]
fn damaged_files_are_refused_without_half_loading() {
    let dir = TempDir::new("damaged");
    let good = dir.0.join("good.safetensors");
    let a = net(6, 1);
    save(&good, &a, &trained_adam(&a), &extra()).unwrap();
    let bytes = fs::read(&good).unwrap();
    let header_len = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;

    // Cut in half.
    let half = dir.0.join("half.safetensors");
    fs::write(&half, &bytes[..bytes.len() / 2]).unwrap();
    let e = refused(&half, 6);
    assert!(matches!(e, CheckpointError::Corrupt { .. }), "{e}");
    assert!(e.to_string().contains("truncated or corrupt"), "{e}");

    // Flipped bytes in the header.
    let mut flipped = bytes.clone();
    for i in [12, 40, 41, header_len / 2] {
        flipped[8 + i] ^= 0xff;
    }
    let path = dir.0.join("flipped.safetensors");
    fs::write(&path, &flipped).unwrap();
    let e = refused(&path, 6);
    assert!(matches!(e, CheckpointError::Corrupt { .. }), "{e}");

    // One flipped bit in the weights: caught by the checksum.
    let mut flipped = bytes.clone();
    let k = bytes.len() - 100;
    flipped[k] ^= 0x01;
    let path = dir.0.join("bitrot.safetensors");
    fs::write(&path, &flipped).unwrap();
    let e = refused(&path, 6);
    assert!(e.to_string().contains("checksum"), "{e}");

    // Empty, missing, not safetensors at all.
    let path = dir.0.join("empty.safetensors");
    fs::write(&path, b"").unwrap();
    assert!(matches!(refused(&path, 6), CheckpointError::Corrupt { .. }));
    let e = refused(&dir.0.join("missing.safetensors"), 6);
    assert!(matches!(e, CheckpointError::Read { .. }), "{e}");
    let path = dir.0.join("text.safetensors");
    fs::write(&path, b"hello, this is not a checkpoint at all").unwrap();
    assert!(matches!(refused(&path, 6), CheckpointError::Corrupt { .. }));
}

type Tensors = Vec<(String, safetensors::Dtype, Vec<usize>, Vec<u8>)>;

/// The checksum exactly as the module docs define it (FNV-1a 64).
fn documented_checksum(meta: &HashMap<String, String>, tensors: &Tensors) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut feed = |bytes: &[u8]| {
        for &b in bytes {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    let sorted: BTreeMap<_, _> = meta.iter().collect();
    for (k, v) in sorted {
        if k != "fulcrum.checksum" {
            feed(k.as_bytes());
            feed(&[0]);
            feed(v.as_bytes());
            feed(&[0]);
        }
    }
    let mut ts: Vec<_> = tensors.iter().collect();
    ts.sort_by(|a, b| a.0.cmp(&b.0));
    for (name, dtype, shape, data) in ts {
        feed(name.as_bytes());
        feed(&[0]);
        feed(dtype.to_string().as_bytes());
        feed(&[0]);
        for &d in shape {
            feed(&(d as u64).to_le_bytes());
        }
        feed(data);
    }
    format!("{h:016x}")
}

/// Rewrites a checkpoint with `edit` applied to its metadata and tensors; with
/// `fix_checksum`, the checksum is recomputed (a writer other than `save` that made a
/// consistent but wrong file).
fn rewrite(
    src: &Path,
    dst: &Path,
    fix_checksum: bool,
    edit: impl FnOnce(&mut HashMap<String, String>, &mut Tensors),
) {
    let bytes = fs::read(src).unwrap();
    let (_, header) = safetensors::SafeTensors::read_metadata(&bytes).unwrap();
    let mut meta = header.metadata().clone().unwrap();
    let st = safetensors::SafeTensors::deserialize(&bytes).unwrap();
    let mut tensors: Tensors = st
        .tensors()
        .into_iter()
        .map(|(n, v)| (n, v.dtype(), v.shape().to_vec(), v.data().to_vec()))
        .collect();
    assert_eq!(
        meta["fulcrum.checksum"],
        documented_checksum(&meta, &tensors)
    );
    edit(&mut meta, &mut tensors);
    if fix_checksum {
        let sum = documented_checksum(&meta, &tensors);
        meta.insert("fulcrum.checksum".into(), sum);
    }
    let views: Vec<(String, safetensors::tensor::TensorView<'_>)> = tensors
        .iter()
        .map(|(n, d, s, b)| {
            (
                n.clone(),
                safetensors::tensor::TensorView::new(*d, s.clone(), b).unwrap(),
            )
        })
        .collect();
    fs::write(dst, safetensors::serialize(views, Some(meta)).unwrap()).unwrap();
}

#[test]
fn wrong_version_and_tampered_files_are_refused() {
    let dir = TempDir::new("version");
    let good = dir.0.join("good.safetensors");
    let a = net(6, 1);
    save(&good, &a, &trained_adam(&a), &Extra::default()).unwrap();

    let path = dir.0.join("v2.safetensors");
    rewrite(&good, &path, true, |m, _| {
        m.insert("fulcrum.checkpoint".into(), "2".into());
    });
    let e = refused(&path, 6);
    assert!(matches!(e, CheckpointError::Version { .. }), "{e}");
    assert!(e.to_string().contains("version 2"), "{e}");

    let path = dir.0.join("noversion.safetensors");
    rewrite(&good, &path, true, |m, _| {
        m.remove("fulcrum.checkpoint");
    });
    assert!(matches!(refused(&path, 6), CheckpointError::Version { .. }));

    // A changed counter without a matching checksum.
    let path = dir.0.join("tampered.safetensors");
    rewrite(&good, &path, false, |m, _| {
        m.insert("adam.step".into(), "3".into());
    });
    assert!(refused(&path, 6).to_string().contains("checksum"));

    // A valid safetensors file of other tensors (e.g. a plain model export).
    let path = dir.0.join("foreign.safetensors");
    rewrite(&good, &path, false, |m, t| {
        m.clear();
        t.truncate(1);
    });
    assert!(matches!(refused(&path, 6), CheckpointError::Version { .. }));
}

#[test]
fn non_finite_weights_are_refused() {
    let dir = TempDir::new("nan");
    let path = dir.0.join("c.safetensors");
    let a = net(6, 1);
    let adam = Adam::new(&a).unwrap();
    save(&path, &a, &adam, &Extra::default()).unwrap();
    let old = fs::read(&path).unwrap();

    // Saving NaN weights is refused and keeps the old file.
    let mut w = a.flat().unwrap();
    w[17] = f32::NAN;
    a.set_flat(&w).unwrap();
    let e = save(&path, &a, &adam, &Extra::default()).expect_err("NaN weights");
    assert!(matches!(e, CheckpointError::NonFinite { .. }), "{e}");
    assert!(e.to_string().contains("policy.embed"), "{e}");
    assert_eq!(fs::read(&path).unwrap(), old);

    // A file with an infinite weight and a matching checksum (another writer) is refused,
    // as is one with a NaN moment.
    let good = dir.0.join("good.safetensors");
    save(&good, &net(6, 1), &adam, &Extra::default()).unwrap();
    for (tensor, value) in [
        ("param/policy.l2.w", f32::INFINITY),
        ("adam.v/policy.embed", f32::NAN),
    ] {
        let path = dir.0.join("nan.safetensors");
        rewrite(&good, &path, true, |_, t| {
            let (_, _, _, data) = t.iter_mut().find(|(n, ..)| n == tensor).unwrap();
            data[8..12].copy_from_slice(&value.to_le_bytes());
        });
        let e = refused(&path, 6);
        assert!(matches!(e, CheckpointError::NonFinite { .. }), "{e}");
        let msg = e.to_string();
        assert!(msg.contains("element 2"), "{msg}");
        assert!(msg.contains(tensor.rsplit('/').next().unwrap()), "{msg}");
    }
}

#[test]
fn checkpoint_of_another_shape_is_refused_naming_the_parameter() {
    let dir = TempDir::new("shape");
    let path = dir.0.join("c.safetensors");
    let a = net(10, 1);
    save(&path, &a, &trained_adam(&a), &extra()).unwrap();
    let e = refused(&path, 6);
    assert!(matches!(e, CheckpointError::Shape { .. }), "{e}");
    let msg = e.to_string();
    assert!(
        msg.contains("policy.embed is [50, 8], expected [30, 8]"),
        "{msg}"
    );
    assert!(msg.contains("other shape"), "{msg}");

    // Another hidden size: also named.
    let b = Net::new(
        NetShape {
            hidden: 9,
            ..shape(6)
        },
        1,
        &Device::Cpu,
    )
    .unwrap();
    save(&path, &b, &Adam::new(&b).unwrap(), &Extra::default()).unwrap();
    let msg = refused(&path, 6).to_string();
    assert!(
        msg.contains("policy.embed is [30, 9], expected [30, 8]"),
        "{msg}"
    );
}

#[test]
fn failed_save_keeps_the_old_checkpoint() {
    use std::os::unix::fs::PermissionsExt;
    let dir = TempDir::new("readonly");
    let sub = dir.0.join("checkpoints");
    fs::create_dir(&sub).unwrap();
    let path = sub.join("latest.safetensors");
    let a = net(6, 1);
    let adam = trained_adam(&a);
    let mut ex = Extra::default();
    ex.counters.insert("env_steps".into(), 1);
    save(&path, &a, &adam, &ex).unwrap();

    let other = net(6, 2);
    let mut ex2 = Extra::default();
    ex2.counters.insert("env_steps".into(), 2);

    // A stale temp file from a crashed save (its writer's pid is over any pid_max)
    // does not matter, and is what the cleaning at a run's start removes.
    let stale = sub.join(".latest.safetensors.tmp-999999999-0");
    fs::write(&stale, b"junk").unwrap();
    save(&path, &a, &adam, &ex).expect("save beside a stale temp file");
    assert_eq!(
        fulcrum_contracts::fsio::remove_stale_temps(&sub).unwrap(),
        1
    );
    assert!(!stale.exists());

    fs::set_permissions(&sub, fs::Permissions::from_mode(0o555)).unwrap();
    // Root (or some file systems) ignore the mode: then the failure cannot be provoked.
    let probe = sub.join("probe");
    let enforced = fs::write(&probe, b"x").is_err();
    let _ = fs::remove_file(&probe);
    let result = save(&path, &other, &Adam::new(&other).unwrap(), &ex2);
    fs::set_permissions(&sub, fs::Permissions::from_mode(0o755)).unwrap();
    if enforced {
        let e = result.expect_err("save into a read-only directory");
        assert!(matches!(e, CheckpointError::Write { .. }), "{e}");
        let msg = e.to_string();
        assert!(msg.contains(&path.display().to_string()), "{msg}");
        assert!(msg.contains(".latest.safetensors.tmp-"), "{msg}");
        let target = net(6, 3);
        let mut adam_t = Adam::new(&target).unwrap();
        let got = load(&path, &target, &mut adam_t).expect("old file still loads");
        assert_eq!(got, ex);
        assert_eq!(bits(&target.flat().unwrap()), bits(&a.flat().unwrap()));
    } else {
        eprintln!("read-only directory not enforced (root?): skipping the failure check");
    }

    // A failure root cannot override: the target is a non-empty directory (cannot be
    // renamed over).
    save(&path, &a, &adam, &ex).unwrap();
    let dir_target = sub.join("adir");
    fs::create_dir(&dir_target).unwrap();
    fs::write(dir_target.join("x"), b"x").unwrap();
    let e = save(&dir_target, &a, &adam, &ex).expect_err("rename over a directory");
    assert!(e.to_string().contains("adir"), "{e}");
    assert!(
        fs::read_dir(&sub).unwrap().all(|e| !e
            .unwrap()
            .file_name()
            .to_string_lossy()
            .contains(".tmp-")),
        "temp file left behind"
    );

    // A missing directory: an error naming the path, nothing created.
    let missing = dir.0.join("nope").join("c.safetensors");
    let e = save(&missing, &a, &adam, &ex).expect_err("missing dir");
    assert!(e.to_string().contains("nope"), "{e}");

    // An optimiser for another network is refused before writing.
    let small = net(4, 1);
    let e = save(&path, &a, &Adam::new(&small).unwrap(), &ex).expect_err("mismatch");
    assert!(matches!(e, CheckpointError::Mismatch { .. }), "{e}");
    let got = load(&path, &net(6, 4), &mut Adam::new(&a).unwrap()).unwrap();
    assert_eq!(got.counters.get("env_steps"), Some(&1));
}

#[test]
fn consistent_files_with_wrong_contents_are_refused() {
    let dir = TempDir::new("contents");
    let good = dir.0.join("good.safetensors");
    let a = net(6, 1);
    save(&good, &a, &trained_adam(&a), &extra()).unwrap();
    let path = dir.0.join("bad.safetensors");
    type Edit = Box<dyn FnOnce(&mut HashMap<String, String>, &mut Tensors)>;
    let cases: Vec<(Edit, &str)> = vec![
        (
            Box::new(|_, t| t.retain(|(n, ..)| n != "param/policy.pi.b")),
            "other shape: it has no parameter policy.pi.b",
        ),
        (
            Box::new(|_, t| {
                let extra = t.iter().find(|(n, ..)| n == "param/policy.pi.b").unwrap();
                let extra = (
                    "param/policy.pi2.b".to_string(),
                    extra.1,
                    extra.2.clone(),
                    extra.3.clone(),
                );
                t.push(extra);
            }),
            "it has a parameter policy.pi2.b that the network lacks",
        ),
        (
            Box::new(|_, t| t.retain(|(n, ..)| n != "adam.m/policy.l1.b")),
            "it has no tensor adam.m/policy.l1.b",
        ),
        (
            Box::new(|_, t| {
                let x = t
                    .iter_mut()
                    .find(|(n, ..)| n == "adam.v/policy.l2.w")
                    .unwrap();
                x.2 = vec![64];
            }),
            "adam.v/policy.l2.w is [64], expected [8, 8]",
        ),
        (
            Box::new(|_, t| {
                let x = t
                    .iter_mut()
                    .find(|(n, ..)| n == "param/policy.v.b")
                    .unwrap();
                x.1 = safetensors::Dtype::I32;
            }),
            "policy.v.b has dtype I32, expected F32",
        ),
        (
            Box::new(|m, _| {
                m.insert("counter.env_steps".into(), "-1".into());
            }),
            "counter env_steps is \"-1\", not an unsigned integer",
        ),
        (
            Box::new(|m, _| {
                m.insert("float.lr".into(), "fast".into());
            }),
            "float lr is \"fast\", not a number",
        ),
        (
            Box::new(|m, _| {
                m.remove("adam.step");
            }),
            "it has no adam.step entry",
        ),
        (
            Box::new(|m, _| {
                m.insert("format".into(), "pt".into());
            }),
            "unknown header entry \"format\"",
        ),
        (
            Box::new(|_, t| {
                t.push(("weird".into(), safetensors::Dtype::U8, vec![1], vec![0]));
            }),
            "unknown tensor \"weird\"",
        ),
        (
            Box::new(|_, t| {
                let x = t.iter_mut().find(|(n, ..)| n == "blob/bytes").unwrap();
                x.2 = vec![16, 16];
            }),
            "blob blob/bytes is U8 [16, 16], expected a 1-D U8 tensor",
        ),
    ];
    for (edit, want) in cases {
        rewrite(&good, &path, true, edit);
        let msg = refused(&path, 6).to_string();
        assert!(msg.contains(want), "{msg}\n  should contain: {want}");
    }
}

/// Two writers of one checkpoint at once (what two invocations on one run directory
/// did): each has its own temporary file, so the file is always one whole checkpoint
/// of one of them, never a mix (a shared temporary name let one truncate the other's).
#[test]
fn concurrent_saves_never_mix_two_checkpoints() {
    let dir = TempDir::new("concurrent");
    let path = dir.0.join("latest.safetensors");
    let nets = [net(6, 1), net(6, 2)];
    let flats: Vec<Vec<u32>> = nets.iter().map(|n| bits(&n.flat().unwrap())).collect();
    std::thread::scope(|s| {
        for (i, n) in nets.iter().enumerate() {
            let path = path.clone();
            s.spawn(move || {
                let adam = Adam::new(n).unwrap();
                let mut ex = Extra::default();
                ex.counters.insert("writer".into(), i as u64);
                for _ in 0..40 {
                    save(&path, n, &adam, &ex).expect("concurrent save");
                }
            });
        }
        for _ in 0..200 {
            // Once there, the file is always one whole checkpoint.
            if !path.exists() {
                continue;
            }
            let t = net(6, 3);
            let got = load(&path, &t, &mut Adam::new(&t).unwrap()).expect("a whole checkpoint");
            let w = *got.counters.get("writer").unwrap() as usize;
            assert_eq!(bits(&t.flat().unwrap()), flats[w], "a mixed checkpoint");
        }
    });
    let t = net(6, 3);
    let got = load(&path, &t, &mut Adam::new(&t).unwrap()).expect("whole at the end");
    let w = *got.counters.get("writer").unwrap() as usize;
    assert_eq!(bits(&t.flat().unwrap()), flats[w]);
    let names: Vec<_> = fs::read_dir(&dir.0)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, ["latest.safetensors"], "no temporary file left");
}
