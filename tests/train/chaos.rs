//! The chaos soak: a training run whose children are killed and frozen at random for a
//! given time. Ignored in the suite (it runs for minutes); one command runs it:
//!
//! ```text
//! FULCRUM_SOAK_SECS=1800 cargo test --release --test integration chaos -- --ignored --nocapture
//! ```
//!
//! Every one to four seconds (seeded, `FULCRUM_SOAK_SEED`, default 1) one child of the
//! run (an actor, the empowerment service, now and then the learner) gets SIGKILL, or
//! SIGSTOP and a SIGCONT up to two seconds later. A killed learner ends the run (exit
//! 1, as FAULTS.md promises); the soak then resumes it, as a user would. At the end the
//! run is stopped with SIGINT and checked: its rows are updates 1, 2, ... made of whole
//! chunks (both actors', or one while the other is left out past its deadline), no
//! chunk was lost, the checkpoint resumes, nothing of any of its
//! invocations is left, and the run's memory and `/dev/shm` did not grow.

use std::process::Child;
use std::time::{Duration, Instant};

use rand::{Rng, SeedableRng};

use fulcrum_learner::metrics::MetricsRow;

use super::{
    assert_nothing_left, children_with, finish, namespace_of, read_metrics, train, wait_rows, SMALL,
};
use crate::util::{signal, TempDir};

/// Resident memory (kB) of a process and its children.
fn tree_rss_kb(root: u32) -> u64 {
    let rss = |p: u32| -> u64 {
        std::fs::read_to_string(format!("/proc/{p}/status"))
            .unwrap_or_default()
            .lines()
            .find_map(|l| l.strip_prefix("VmRSS:"))
            .and_then(|v| v.split_whitespace().next()?.parse().ok())
            .unwrap_or(0)
    };
    let kids = ["__actor", "__learner", "serve"]
        .iter()
        .flat_map(|n| children_with(root, n))
        .map(rss)
        .sum::<u64>();
    rss(root) + kids
}

/// Bytes in use on `/dev/shm` (the whole mount: run the soak on an otherwise idle
/// machine).
fn shm_used() -> u64 {
    let c = std::ffi::CString::new("/dev/shm").unwrap();
    // SAFETY: statvfs fills the struct we pass; the path is a valid C string.
    let mut s: libc::statvfs = unsafe { std::mem::zeroed() };
    let r = unsafe { libc::statvfs(c.as_ptr(), &mut s) };
    assert_eq!(r, 0, "statvfs /dev/shm");
    (s.f_blocks - s.f_bfree) * s.f_frsize
}

/// Rows are updates 1, 2, ... and each is made of whole chunks of 128 steps: both
/// actors' (256), or one while the other is left out past its deadline. Returns how
/// many updates had one actor only.
fn whole_chunks(rows: &[MetricsRow]) -> usize {
    let mut partial = 0;
    let mut steps = 0;
    for (i, r) in rows.iter().enumerate() {
        assert_eq!(r.update, i as u64 + 1, "one row per update");
        let grew = r.env_steps - steps;
        assert!(
            grew == 128 || grew == 256,
            "update {}: {grew} steps",
            r.update
        );
        partial += usize::from(grew == 128);
        steps = r.env_steps;
    }
    partial
}

#[derive(Debug, Default)]
struct Tally {
    kills: [u32; 3],
    freezes: u32,
    resumes: u32,
}

/// Start the run, or resume it.
fn start(dir: &str, fresh: bool) -> Child {
    if fresh {
        train(
            &[
                &["room", "--actors", "2", "--out", dir][..],
                // Far more updates than the soak makes; it stops the run with SIGINT.
                &["--steps", "2560000000", "--checkpoint-every", "20"],
                // A kill of the same child every 20 s or so on average, for half an hour:
                // the default budget (5 restarts in 60 s per child) would, by chance, end
                // the run; the policy has tests of its own.
                &["--max-restarts", "100"],
                SMALL,
            ]
            .concat(),
        )
    } else {
        // Supervision settings are the invocation's, not the run's: again on resume.
        train(&["--resume", dir, "--max-restarts", "100"])
    }
}

#[test]
#[ignore = "a soak of FULCRUM_SOAK_SECS seconds (default 120); run with --ignored"]
fn chaos_soak_keeps_rows_whole_and_resources_flat() {
    let secs: u64 = std::env::var("FULCRUM_SOAK_SECS")
        .ok()
        .map(|s| s.parse().expect("FULCRUM_SOAK_SECS is a number of seconds"))
        .unwrap_or(120);
    let seed: u64 = std::env::var("FULCRUM_SOAK_SEED")
        .ok()
        .map(|s| s.parse().expect("FULCRUM_SOAK_SEED is a number"))
        .unwrap_or(1);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let dir = TempDir::fresh("chaos");
    let d = dir.to_str().unwrap().to_string();
    let shm_before = shm_used();
    let mut run = start(&d, true);
    wait_rows(&dir, 20, Duration::from_secs(60));
    std::thread::sleep(Duration::from_secs(5));
    let (rss_start, shm_start) = (tree_rss_kb(run.id()), shm_used());
    let mut tally = Tally::default();
    let mut stderrs = Vec::new();
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(secs) {
        std::thread::sleep(Duration::from_millis(rng.random_range(1000..4000)));
        if let Some(status) = run.try_wait().unwrap() {
            let (_, err, _) = finish(run, Duration::from_secs(1));
            // Only a killed learner ends the run, with the resume command.
            assert_eq!(status.code(), Some(1), "{err}");
            assert!(err.contains("the learner failed (signal 9)"), "{err}");
            assert!(err.contains(&format!("--resume {d}")), "{err}");
            stderrs.push(err);
            run = start(&d, false);
            tally.resumes += 1;
            continue;
        }
        // Actors most often, the service often, the learner now and then.
        let kind = match rng.random_range(0..10) {
            0..=5 => 0,
            6..=8 => 1,
            _ => 2,
        };
        let needle = ["__actor", "serve", "__learner"][kind];
        let pids = children_with(run.id(), needle);
        let Some(&pid) = pids.get(rng.random_range(0..pids.len().max(1))) else {
            continue; // between a death and its restart
        };
        if rng.random_bool(0.7) {
            signal(pid, "-KILL");
            tally.kills[kind] += 1;
        } else {
            signal(pid, "-STOP");
            std::thread::sleep(Duration::from_millis(rng.random_range(100..2000)));
            signal(pid, "-CONT");
            tally.freezes += 1;
        }
    }
    // Let a last restart settle, then measure and stop.
    std::thread::sleep(Duration::from_secs(5));
    let (rss_end, shm_end) = (tree_rss_kb(run.id()), shm_used());
    signal(run.id(), "-INT");
    let (status, err, _) = finish(run, Duration::from_secs(60));
    assert!(
        status.code() == Some(130) || status.code() == Some(1),
        "{status:?}: {err}"
    );
    stderrs.push(err);
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    let n = rows.len() as u64;
    let partial = whole_chunks(&rows);
    let last = rows.last().unwrap();
    assert_eq!(last.lost_chunks, 0, "chunks lost");
    // The checkpoint resumes: five more updates, rows still whole (a SIGINT writes a
    // checkpoint at the last update; a learner killed at the very end leaves the one
    // of the last multiple of 20).
    let (status, err, out) = finish(
        train(&["--resume", &d, "--stop-after-updates", "5"]),
        Duration::from_secs(120),
    );
    assert!(status.success(), "{err}");
    assert!(out.contains("stopped as asked"), "{out}");
    stderrs.push(err);
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    let m = rows.len() as u64;
    assert!(m + 20 > n + 5 && m <= n + 5, "{n} rows, then {m}");
    whole_chunks(&rows);
    for err in &stderrs {
        assert_nothing_left(&namespace_of(err));
    }
    let shm_after = shm_used();
    println!(
        "chaos soak: {secs} s, seed {seed}: kills actor {} service {} learner {}, \
         freezes {}, resumes {}; {n} updates, {partial} of them without one actor; RSS {rss_start} -> {rss_end} kB; \
         /dev/shm used {shm_start} -> {shm_end} B during, {shm_before} -> {shm_after} B \
         before and after",
        tally.kills[0], tally.kills[1], tally.kills[2], tally.freezes, tally.resumes
    );
    // Flat: a restart's memory and segments replace the dead one's, they do not pile up.
    assert!(
        rss_end <= rss_start + rss_start / 2 + 50_000,
        "RSS grew: {rss_start} -> {rss_end} kB"
    );
    assert!(
        shm_end <= shm_start + (16 << 20),
        "/dev/shm grew: {shm_start} -> {shm_end} B"
    );
    assert!(
        shm_after <= shm_before + (1 << 20),
        "/dev/shm left behind: {shm_before} -> {shm_after} B"
    );
}
