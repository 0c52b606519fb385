//! Storage and resources: one invocation per run directory, shared memory sized and
//! checked before anything starts, and a disk that fills up under a real run.
//!
//! The tests that need a small file system or a small `/dev/shm` make them for real:
//! a tmpfs mounted in a private mount namespace (`unshare -m`, so nothing leaks to the
//! machine). That needs root (CI runs as root); without it they fail, saying so.

use std::path::Path;
use std::process::{Command, Output};
use std::time::{Duration, Instant};

use fulcrum_learner::metrics::{read_metrics, MetricsRow};

use super::{assert_contiguous, finish, train, wait_rows, SMALL};
use crate::util::TempDir;

/// The exit code the scripts below use when a mount fails.
const NO_MOUNT: i32 = 97;

/// Runs the shell `script` in a private mount namespace with `args` as `$1`...; fails
/// the test loudly when the namespace or a mount cannot be made (not root).
fn in_private_mounts(script: &str, args: &[&str]) -> Output {
    let out = Command::new("unshare")
        .args(["-m", "--propagation", "private", "sh", "-c", script, "sh"])
        .args(args)
        .output()
        .expect("unshare (util-linux) runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.code() != Some(NO_MOUNT) && !err.contains("unshare failed"),
        "this test needs root to make a private mount namespace and mount a tmpfs (CI runs as root); it cannot run here: {err}"
    );
    out
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_default()
}

fn code(dir: &Path, name: &str) -> i32 {
    read(&dir.join(name)).trim().parse().unwrap_or(-1)
}

/// The first refused line of a stderr that must be one sentence.
fn one_sentence(err: &str) -> &str {
    assert_eq!(err.trim().lines().count(), 1, "one sentence: {err}");
    err.trim()
}

#[test]
fn two_invocations_on_one_run_directory_one_is_refused_naming_the_other() {
    let dir = TempDir::fresh("lock");
    let d = dir.to_str().unwrap();
    // 4 updates, then the same run continued to 1200 updates (seconds).
    let (s, err, _) = finish(
        train(
            &[
                &["room", "--actors", "1", "--steps", "512", "--out", d][..],
                SMALL,
            ]
            .concat(),
        ),
        Duration::from_secs(60),
    );
    assert!(s.success(), "{err}");
    let first = train(&["--resume", d, "--steps", "153600"]);
    let holder = first.id();
    wait_rows(&dir, 6, Duration::from_secs(60));
    // A second resume, and a new run into the same directory: refused at once, before
    // anything is written, naming the holder.
    let rows_before = read_metrics(&dir.join("metrics.csv")).unwrap().len();
    for args in [
        vec!["--resume", d, "--steps", "153600"],
        [&["room", "--actors", "1", "--out", d][..], SMALL].concat(),
    ] {
        let t0 = Instant::now();
        let (s, err, _) = finish(train(&args), Duration::from_secs(30));
        assert_eq!(s.code(), Some(2), "{err}");
        let line = one_sentence(&err);
        assert!(
            line.contains(&format!("pid {holder}")),
            "names the holder: {line}"
        );
        assert!(line.contains(d) && line.contains("in use"), "{line}");
        assert!(!err.contains("namespace"), "no process started: {err}");
        assert!(t0.elapsed() < Duration::from_secs(10), "refused at once");
    }
    let (s, err, _) = finish(first, Duration::from_secs(120));
    assert!(s.success(), "{err}");
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert!(rows.len() > rows_before);
    assert_contiguous(&rows, 1200, 128);
    // The lock went with the holder: the next resume is not refused.
    let (s, err, _) = finish(
        train(&["--resume", d, "--steps", "153856"]),
        Duration::from_secs(60),
    );
    assert!(s.success(), "{err}");
    assert_contiguous(&read_metrics(&dir.join("metrics.csv")).unwrap(), 1202, 128);
}

/// A run whose disk fills when its next checkpoint is due: exit 1 naming the
/// checkpoint and the full disk, the previous checkpoint kept; after space is freed,
/// `--resume` continues with contiguous rows.
#[test]
fn a_full_disk_at_a_checkpoint_ends_the_run_clearly_and_resume_continues() {
    let mnt = TempDir::new("full-ckpt");
    let out = TempDir::new("full-ckpt-out");
    let script = r#"
F=$1; D=$2; O=$3; shift 3
mount -t tmpfs -o size=8m tmpfs "$D" || exit 97
"$F" train room --out "$D/run" --steps 5120 --checkpoint-every 10 --stop-after-updates 10 "$@" 2>"$O/err1"; echo $? >"$O/rc1"
C=$(stat -c %s "$D/run/checkpoints/latest.safetensors")
echo "$C" >"$O/ckpt_bytes"
# Leave room for the rows of 10 more updates, not for another checkpoint.
A=$(($(stat -f -c '%a*%S' "$D")))
fallocate -l $((A - C / 2)) "$D/filler" || exit 97
"$F" train --resume "$D/run" 2>"$O/err2"; echo $? >"$O/rc2"
ls -a "$D/run/checkpoints" >"$O/ckpts"
rm "$D/filler"
"$F" train --resume "$D/run" 2>"$O/err3"; echo $? >"$O/rc3"
cp "$D/run/metrics.csv" "$O/metrics.csv"
"#;
    let o = out.to_str().unwrap();
    let run = in_private_mounts(
        script,
        &[
            &[env!("CARGO_BIN_EXE_fulcrum"), mnt.to_str().unwrap(), o][..],
            &["--actors", "1", "--no-empowerment"],
            SMALL,
        ]
        .concat(),
    );
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert_eq!(code(&out, "rc1"), 0, "{}", read(&out.join("err1")));
    assert!(read(&out.join("ckpt_bytes")).trim().parse::<u64>().unwrap() > 8192);
    let err2 = read(&out.join("err2"));
    assert_eq!(code(&out, "rc2"), 1, "{err2}");
    assert!(
        err2.contains("checkpoints/latest.safetensors") && err2.contains("No space left on device"),
        "names the checkpoint and the full disk: {err2}"
    );
    assert!(err2.contains("--resume"), "{err2}");
    // The failed write left no temporary file beside the good checkpoint.
    assert_eq!(
        read(&out.join("ckpts"))
            .split_whitespace()
            .collect::<Vec<_>>(),
        [".", "..", "latest.safetensors"]
    );
    let err3 = read(&out.join("err3"));
    assert_eq!(code(&out, "rc3"), 0, "{err3}");
    assert_contiguous(&read_metrics(&out.join("metrics.csv")).unwrap(), 40, 128);
}

/// A disk that fills while rows are appended: exit 1 naming `metrics.csv` and the full
/// disk; after space is freed `--resume` continues from the checkpoint, the rows after
/// it dropped and redone, whole and contiguous.
#[test]
fn a_full_disk_while_appending_rows_ends_the_run_clearly_and_resume_continues() {
    let mnt = TempDir::new("full-rows");
    let out = TempDir::new("full-rows-out");
    let script = r#"
F=$1; D=$2; O=$3; shift 3
mount -t tmpfs -o size=8m tmpfs "$D" || exit 97
"$F" train room --out "$D/run" --steps 256000 --checkpoint-every 1000000 --stop-after-updates 1 "$@" 2>"$O/err1"; echo $? >"$O/rc1"
"$F" train --resume "$D/run" 2>"$O/err2" &
P=$!
# Once the run appends rows again, take every free block.
i=0
while [ "$(wc -l <"$D/run/metrics.csv")" -lt 4 ] && [ $i -lt 600 ]; do sleep 0.05; i=$((i+1)); done
# (written until the disk is full: the run may take a block between a look at the
# free space and an allocation of all of it)
dd if=/dev/zero of="$D/filler" bs=4096 2>/dev/null
df -B1 --output=avail "$D" | tail -1 >"$O/avail-after-fill"
wait $P; echo $? >"$O/rc2"
cp "$D/run/metrics.csv" "$O/metrics-at-failure.csv"
rm "$D/filler"
"$F" train --resume "$D/run" --steps 12800 2>"$O/err3"; echo $? >"$O/rc3"
cp "$D/run/metrics.csv" "$O/metrics.csv"
"#;
    let o = out.to_str().unwrap();
    let run = in_private_mounts(
        script,
        &[
            &[env!("CARGO_BIN_EXE_fulcrum"), mnt.to_str().unwrap(), o][..],
            &["--actors", "1", "--no-empowerment"],
            SMALL,
        ]
        .concat(),
    );
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert_eq!(code(&out, "rc1"), 0, "{}", read(&out.join("err1")));
    let err2 = read(&out.join("err2"));
    assert_eq!(
        read(&out.join("avail-after-fill")).trim(),
        "0",
        "the disk was full"
    );
    assert_eq!(code(&out, "rc2"), 1, "{err2}");
    assert!(
        err2.contains("metrics.csv") && err2.contains("No space left on device"),
        "names metrics.csv and the full disk: {err2}"
    );
    let at_failure = read_metrics(&out.join("metrics-at-failure.csv")).unwrap();
    assert!(
        at_failure.len() > 4 && at_failure.len() < 2000,
        "failed mid-run ({} rows)",
        at_failure.len()
    );
    let err3 = read(&out.join("err3"));
    assert_eq!(code(&out, "rc3"), 0, "{err3}");
    let text = read(&out.join("metrics.csv"));
    assert!(
        text.lines().skip(1).all(|l| MetricsRow::parse(l).is_some()),
        "whole rows only: {text}"
    );
    assert_contiguous(&read_metrics(&out.join("metrics.csv")).unwrap(), 100, 128);
}

/// Settings whose chunks or shared memory no machine here has: refused before anything
/// starts (exit 2, one sentence saying how much is needed and how much there is),
/// nothing written.
#[test]
fn absurd_chunk_settings_are_refused_before_anything_starts() {
    let dir = TempDir::fresh("absurd");
    let d = dir.to_str().unwrap();
    for (args, says) in [
        // 16.7 M transitions a chunk: gigabytes, over the per-chunk limit.
        (
            vec!["--envs-per-actor", "4096", "--steps-per-chunk", "4096"],
            "over the limit of 64 MiB per chunk",
        ),
        (vec!["--envs-per-actor", "1000000"], "must be 1 to 4096"),
        (vec!["--steps-per-chunk", "1000000"], "must be 1 to 4096"),
        // Chunks under the limit, but 64 actors' worth: tens of GB of shared memory.
        (
            vec![
                "--actors",
                "64",
                "--envs-per-actor",
                "256",
                "--steps-per-chunk",
                "1024",
            ],
            "of shared memory (",
        ),
    ] {
        let (s, err, _) = finish(
            train(&[&["exp2", "--out", d][..], &args].concat()),
            Duration::from_secs(30),
        );
        assert_eq!(s.code(), Some(2), "{args:?}: {err}");
        let line = one_sentence(&err);
        assert!(line.contains(says), "{args:?}: {line}");
        if says.contains("shared memory") {
            assert!(
                line.contains("MiB free") || line.contains("MiB of memory available"),
                "says what there is: {line}"
            );
        }
        assert!(!dir.exists(), "nothing written: {args:?}");
    }
}

/// What `fulcrum_run::sizes` estimates against what a real run maps: an exp2 run of two
/// actors with empowerment in a private, empty `/dev/shm` (and `/tmp/iceoryx2`); the
/// estimate covers every byte and is not more than a tenth over.
#[test]
fn the_shared_memory_estimate_covers_what_a_real_run_maps() {
    let mnt = TempDir::new("shm-estimate");
    let out = TempDir::new("shm-estimate-out");
    let script = r#"
F=$1; D=$2; O=$3; shift 3
mount -t tmpfs -o size=2g tmpfs /dev/shm || exit 97
mkdir -p /tmp/iceoryx2 && mount -t tmpfs tmpfs /tmp/iceoryx2 || exit 97
"$F" train --out "$D/run" "$@" 2>"$O/err" &
P=$!
i=0
while [ "$(wc -l <"$D/run/metrics.csv" 2>/dev/null || echo 0)" -lt 3 ] && [ $i -lt 1200 ]; do sleep 0.05; i=$((i+1)); done
du -sb /dev/shm | cut -f1 >"$O/used"
kill -INT $P; wait $P
"#;
    let o = out.to_str().unwrap();
    let run = in_private_mounts(
        script,
        &[
            env!("CARGO_BIN_EXE_fulcrum"),
            mnt.to_str().unwrap(),
            o,
            "exp2",
            "--actors",
            "2",
            "--steps",
            "2048000",
        ],
    );
    let err = read(&out.join("err"));
    assert!(run.status.success() || err.contains("interrupted"), "{err}");
    let used: u64 = read(&out.join("used")).trim().parse().expect("du ran");
    let cfg = fulcrum_contracts::config::RunConfig::load(&mnt.join("run/config.toml"))
        .expect("the run's config");
    let world = fulcrum_world::load_world(&cfg.world).unwrap();
    let need = fulcrum_run::sizes::shared_memory(&cfg, &world);
    let mib = |b: u64| b as f64 / (1 << 20) as f64;
    assert!(
        need.total() >= used,
        "estimated {:.1} MiB ({need:?}), the run maps {:.1} MiB",
        mib(need.total()),
        mib(used)
    );
    assert!(
        (need.total() as f64) <= used as f64 * 1.1,
        "estimated {:.1} MiB ({need:?}), far over the {:.1} MiB the run maps",
        mib(need.total()),
        mib(used)
    );
}

/// A container's default `/dev/shm` of 64 MiB (a private tmpfs of that size, and a
/// private `/tmp/iceoryx2`: iceoryx2 keeps its node and service descriptions there, and
/// other processes on the machine must not see services whose memory they cannot
/// reach): exp2 (one actor) and exp1-tree (two) with empowerment and otherwise default
/// settings fit and finish, since a run's empowerment
/// service and weights are made for its own actors (they once took about 140 MiB
/// whatever the run, and these runs were refused); a run too big (exp2 with 256 worlds
/// per actor, 100 MiB of chunks) is refused before anything starts, one sentence
/// with what is needed and what is free.
#[test]
fn a_64_mib_dev_shm_runs_the_papers_worlds_and_refuses_what_does_not_fit() {
    let mnt = TempDir::new("shm64");
    let out = TempDir::new("shm64-out");
    let script = r#"
F=$1; D=$2; O=$3
mount -t tmpfs -o size=64m tmpfs /dev/shm || exit 97
mkdir -p /tmp/iceoryx2 && mount -t tmpfs tmpfs /tmp/iceoryx2 || exit 97
"$F" train exp2 --actors 1 --steps 10240 --out "$D/exp2" 2>"$O/err-exp2"; echo $? >"$O/rc-exp2"
"$F" train exp1-tree --actors 2 --steps 10240 --out "$D/tree" 2>"$O/err-tree"; echo $? >"$O/rc-tree"
"$F" train exp2 --envs-per-actor 256 --out "$D/big" 2>"$O/err-big"; echo $? >"$O/rc-big"
ls -a "$D" >"$O/ls"
cp "$D/exp2/metrics.csv" "$O/exp2.csv"
cp "$D/tree/metrics.csv" "$O/tree.csv"
"#;
    let o = out.to_str().unwrap();
    in_private_mounts(
        script,
        &[env!("CARGO_BIN_EXE_fulcrum"), mnt.to_str().unwrap(), o],
    );
    for (w, batch) in [("exp2", 1024), ("tree", 2048)] {
        let err = read(&out.join(format!("err-{w}")));
        assert_eq!(code(&out, &format!("rc-{w}")), 0, "{w}: {err}");
        let rows = read_metrics(&out.join(format!("{w}.csv"))).unwrap();
        assert_contiguous(&rows, 10240 / batch, batch);
    }
    let err = read(&out.join("err-big"));
    assert_eq!(code(&out, "rc-big"), 2, "{err}");
    let line = one_sentence(&err);
    assert!(
        line.contains("of shared memory (") && line.contains("but /dev/shm has 64 MiB free"),
        "{line}"
    );
    assert!(line.contains("MiB for the empowerment service"), "{line}");
    // Nothing of the refused run was written.
    assert_eq!(
        read(&out.join("ls")).split_whitespace().collect::<Vec<_>>(),
        [".", "..", "exp2", "tree"]
    );
}

/// Rows missing below the checkpoint (the learner syncs them before each checkpoint, so
/// only a lost or hand-cut file lacks them): refused on `--resume` before anything
/// starts, exit 2, one sentence naming the file and the missing updates.
#[test]
fn rows_missing_before_the_checkpoint_are_refused_on_resume() {
    let dir = TempDir::fresh("missing-rows");
    let d = dir.to_str().unwrap();
    let (s, err, _) = finish(
        train(
            &[
                &["room", "--actors", "1", "--steps", "1024", "--out", d][..],
                SMALL,
            ]
            .concat(),
        ),
        Duration::from_secs(60),
    );
    assert!(s.success(), "{err}");
    // Keep the header and the rows of updates 1 and 2 of 8.
    let path = dir.join("metrics.csv");
    let text = read(&path);
    let cut: Vec<&str> = text.lines().take(3).collect();
    std::fs::write(&path, cut.join("\n") + "\n").unwrap();
    let before = std::fs::read(&path).unwrap();
    let config = std::fs::read(dir.join("config.toml")).unwrap();
    let (s, err, _) = finish(
        train(&["--resume", d, "--steps", "2048"]),
        Duration::from_secs(30),
    );
    assert_eq!(s.code(), Some(2), "{err}");
    let line = one_sentence(&err);
    assert!(line.contains(&path.display().to_string()), "{line}");
    assert!(
        line.contains("checkpoint is at update 8") && line.contains("rows 3 to 8 are missing"),
        "{line}"
    );
    assert_eq!(std::fs::read(&path).unwrap(), before);
    assert_eq!(std::fs::read(dir.join("config.toml")).unwrap(), config);
}

/// A learner killed before its first checkpoint: `--resume` has nothing to continue
/// from and starts over, and the rows of the failed start go (no update twice).
#[test]
fn a_start_that_never_checkpointed_is_redone_without_duplicate_rows() {
    let dir = TempDir::fresh("no-ckpt");
    let d = dir.to_str().unwrap();
    let c = train(
        &[
            &["room", "--actors", "1", "--steps", "25600", "--out", d][..],
            &["--checkpoint-every", "100000"],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 5, Duration::from_secs(60));
    let learner = crate::util::pids_with(&["__learner", d]);
    assert_eq!(learner.len(), 1, "{learner:?}");
    crate::util::signal(learner[0], "-KILL");
    let (s, err, _) = finish(c, Duration::from_secs(30));
    assert_eq!(s.code(), Some(1), "{err}");
    assert!(
        err.contains(&format!(
            "before its first checkpoint; `fulcrum train --resume {d}` starts the run over"
        )),
        "{err}"
    );
    assert!(!dir.join("checkpoints/latest.safetensors").exists());
    let before = read_metrics(&dir.join("metrics.csv")).unwrap().len();
    assert!((5..200).contains(&before), "{before} rows");
    let (s, err, _) = finish(train(&["--resume", d]), Duration::from_secs(120));
    assert!(s.success(), "{err}");
    assert_contiguous(&read_metrics(&dir.join("metrics.csv")).unwrap(), 200, 128);
}
