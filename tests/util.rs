//! The one test toolkit: one way to start the binary, one temporary directory that
//! cleans up after itself, unique iceoryx2 namespaces, and the process helpers the
//! tests of real processes share.

use std::ops::Deref;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// The `fulcrum` binary under test, with stdin closed.
pub fn fulcrum() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_fulcrum"));
    c.stdin(Stdio::null());
    c
}

/// Runs `fulcrum args` to its end.
pub fn run(args: &[&str]) -> Output {
    fulcrum()
        .args(args)
        .output()
        .expect("the fulcrum binary runs")
}

/// A name no other test (of this or another test process) uses at the same time:
/// `<prefix>-<tag>-<pid>-<nanos>-<counter>`.
fn unique(prefix: &str, tag: &str) -> String {
    static N: AtomicU64 = AtomicU64::new(0);
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or(0);
    format!(
        "{prefix}-{tag}-{}-{nanos}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    )
}

/// A unique iceoryx2 namespace for one test.
pub fn namespace(tag: &str) -> String {
    unique("t", tag)
}

/// A directory under the system's temporary directory, removed with everything in it
/// when dropped. Derefs to its path.
#[derive(Debug)]
pub struct TempDir(PathBuf);

impl TempDir {
    /// A new, empty directory.
    pub fn new(tag: &str) -> TempDir {
        let d = TempDir::fresh(tag);
        std::fs::create_dir_all(&d.0).expect("the temporary directory can be made");
        d
    }

    /// A path that does not exist yet (for a command that makes it), removed when
    /// dropped.
    pub fn fresh(tag: &str) -> TempDir {
        let d = std::env::temp_dir().join(unique("fulcrum-test", tag));
        let _ = std::fs::remove_dir_all(&d);
        TempDir(d)
    }
}

impl Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for TempDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<std::ffi::OsStr> for TempDir {
    fn as_ref(&self) -> &std::ffi::OsStr {
        self.0.as_os_str()
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Pids of live (not zombie) processes whose command line contains every needle.
pub fn pids_with(needles: &[&str]) -> Vec<u32> {
    let mut out = Vec::new();
    for e in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = e.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(cmd) = std::fs::read(e.path().join("cmdline")) else {
            continue;
        };
        let cmd = String::from_utf8_lossy(&cmd).replace('\0', " ");
        let state = std::fs::read_to_string(e.path().join("stat")).unwrap_or_default();
        let zombie = state.split_whitespace().nth(2) == Some("Z");
        if !zombie && needles.iter().all(|n| cmd.contains(n)) {
            out.push(pid);
        }
    }
    out
}

/// Sends signal `sig` (as `kill` spells it: `-INT`, `-KILL`, ...) to `pid`.
pub fn signal(pid: u32, sig: &str) {
    assert!(Command::new("kill")
        .args([sig, &pid.to_string()])
        .status()
        .unwrap()
        .success());
}

/// Waits until `f` holds, failing the test with `what` after `limit`.
pub fn wait_until(limit: Duration, what: &str, mut f: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !f() {
        assert!(t0.elapsed() < limit, "{what}: not after {limit:?}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Whether a child's line says it is ready (the child protocol's own reading).
pub fn is_ready(line: &str) -> bool {
    fulcrum_contracts::lines::ChildLine::says_ready(line)
}

/// A metrics row's columns that must match bit for bit between two runs of the same
/// seed (all but the timings).
pub fn deterministic(r: &fulcrum_learner::metrics::MetricsRow) -> String {
    let mut r = *r;
    r.sps = 0.0;
    r.wall_s = 0.0;
    r.csv()
}

/// The policy's weights in a run's latest checkpoint, flat; `world` is the run's world
/// (a built-in name or a file), which gives the network's shape.
pub fn weights(run: &Path, world: &str) -> Vec<f32> {
    let dev = candle_core::Device::Cpu;
    let (w, _) = fulcrum_world::family::load_world_or_family(world).unwrap();
    let shape = fulcrum_contracts::config::RunConfig::load(&run.join("config.toml"))
        .unwrap()
        .shape(&w);
    let net = fulcrum_learner::net::Net::new(shape, 99, &dev).unwrap();
    let mut adam = fulcrum_learner::adam::Adam::new(&net).unwrap();
    fulcrum_learner::checkpoint::load(&run.join("checkpoints/latest.safetensors"), &net, &mut adam)
        .unwrap();
    net.flat().unwrap()
}

/// Whether two weight vectors are the same bits.
pub fn same_bits(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// A TCP port that was free a moment ago (the tests between hosts and on Slurm).
#[cfg(any(feature = "multihost", feature = "slurm"))]
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}
