//! No silent hang, and the restart policy, with real processes: a diverged update ends
//! the run before its weights reach an actor; a stopped actor in a synchronous run is
//! left out and taken back; a run whose actors all stall is ended by the supervisor's
//! watchdog naming them; an actor killed faster than its budget allows ends the run,
//! one killed now and then does not, and the back-off between restarts grows.

use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

use fulcrum_learner::metrics::read_metrics;

use super::{assert_nothing_left, finish, namespace_of, train, wait_rows, SMALL};
use crate::util::{fulcrum, pids_with, signal, wait_until, TempDir};

/// The one actor of index `i` of the run in `d`, once it is up.
fn actor(d: &str, i: usize) -> u32 {
    let needle = format!("--index {i}");
    let mut pid = 0;
    wait_until(Duration::from_secs(20), &format!("actor {i} up"), || {
        let p = pids_with(&["__actor", d, &needle]);
        pid = p.first().copied().unwrap_or(0);
        p.len() == 1
    });
    pid
}

/// Env steps per update, from the metrics rows (first row: its own steps).
fn steps_per_update(d: &std::path::Path) -> Vec<u64> {
    let rows = read_metrics(&d.join("metrics.csv")).unwrap_or_default();
    let mut prev = 0;
    rows.iter()
        .map(|r| {
            let s = r.env_steps - prev;
            prev = r.env_steps;
            s
        })
        .collect()
}

#[test]
fn non_finite_weights_end_the_run_at_their_update_and_resume_continues() {
    let dir = TempDir::fresh("nonfinite");
    let d = dir.to_str().unwrap();
    let t0 = Instant::now();
    let c: Child = fulcrum()
        .args(
            [
                &[
                    "train",
                    "room",
                    "--actors",
                    "2",
                    "--steps",
                    "5120",
                    "--checkpoint-every",
                    "2",
                    "--out",
                    d,
                ][..],
                SMALL,
            ]
            .concat(),
        )
        .env("FULCRUM_FAULT_NONFINITE_AT_UPDATE", "5")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (status, err, _) = finish(c, Duration::from_secs(60));
    // The whole run, service build included, is a few seconds: the fault at update 5
    // ends it well within 30 s of its start.
    assert!(t0.elapsed() < Duration::from_secs(30), "{:?}", t0.elapsed());
    assert_eq!(status.code(), Some(1), "{err}");
    assert!(
        err.contains("training diverged: the weights after update 5 are not finite"),
        "{err}"
    );
    assert!(err.contains("the learner failed (exit code 1)"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    // Update 5 was never recorded nor published: four rows, the checkpoint of update 4.
    assert_eq!(read_metrics(&dir.join("metrics.csv")).unwrap().len(), 4);
    assert_nothing_left(&namespace_of(&err));
    // Nothing lost: without the fault the run resumes from update 4 and finishes.
    let (status, err, _) = finish(train(&["--resume", d]), Duration::from_secs(60));
    assert!(status.success(), "{err}");
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_eq!(rows.len(), 20);
    assert!(rows.iter().all(|r| r.stats.policy_loss.is_finite()));
}

#[test]
fn a_stopped_actor_of_a_synchronous_run_is_left_out_then_taken_back() {
    let dir = TempDir::fresh("stopped-actor");
    let d = dir.to_str().unwrap();
    // 2 actors x 128 steps: 256 an update with both, 128 with one; 6000 updates.
    let c = train(
        &[
            &[
                "room",
                "--actors",
                "2",
                "--steps",
                "1536000",
                "--no-empowerment",
                "--out",
                d,
            ][..],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 5, Duration::from_secs(60));
    let victim = actor(d, 1);
    signal(victim, "-STOP");
    // The learner waits its deadline (10 s floor), then goes on with actor 0 alone.
    wait_until(Duration::from_secs(30), "updates without actor 1", || {
        steps_per_update(&dir).iter().filter(|&&s| s == 128).count() >= 20
    });
    signal(victim, "-CONT");
    let (status, err, _) = finish(c, Duration::from_secs(180));
    assert!(status.success(), "{err}");
    assert!(
        err.contains("no chunk from actor 1 for")
            && err.contains("the learner goes on without it until its next chunk"),
        "{err}"
    );
    let steps = steps_per_update(&dir);
    assert_eq!(steps.len(), 6000, "every update made");
    // Whole chunks only: each update used one chunk of each actor it waited for.
    assert!(steps.iter().all(|&s| s == 128 || s == 256), "{steps:?}");
    // Actor 1 was taken back: updates of both actors after the ones without it.
    let first_alone = steps.iter().position(|&s| s == 128).unwrap();
    assert!(
        steps[first_alone..].contains(&256),
        "actor 1 never came back"
    );
    assert_nothing_left(&namespace_of(&err));
}

#[test]
fn a_run_whose_actors_all_stall_is_ended_by_the_watchdog_naming_them() {
    let dir = TempDir::fresh("watchdog");
    let d = dir.to_str().unwrap();
    let c = train(
        &[
            &[
                "room",
                "--actors",
                "2",
                "--steps",
                "25600000",
                "--no-empowerment",
                "--hang-timeout",
                "3",
                "--out",
                d,
            ][..],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 5, Duration::from_secs(60));
    let (a0, a1) = (actor(d, 0), actor(d, 1));
    signal(a0, "-STOP");
    signal(a1, "-STOP");
    let t0 = Instant::now();
    let (status, err, _) = finish(c, Duration::from_secs(60));
    // 3 s of watchdog, the learner's checkpoint, 4 s to kill the stopped actors.
    assert!(t0.elapsed() < Duration::from_secs(15), "{:?}", t0.elapsed());
    assert_eq!(status.code(), Some(1), "{err}");
    let line = err
        .lines()
        .find(|l| l.contains("no update for"))
        .unwrap_or_else(|| panic!("no watchdog sentence: {err}"));
    assert!(
        line.contains("at least 3 s): the learner is waiting for actor"),
        "{line}"
    );
    // It names the stopped actors it waits for, and no other.
    let named: Vec<&str> = ["actor 0", "actor 1"]
        .into_iter()
        .filter(|a| line.contains(a))
        .collect();
    assert!(!named.is_empty(), "{line}");
    assert!(line.contains(&format!("--resume {d}")), "{line}");
    assert_nothing_left(&namespace_of(&err));
}

/// Kill actor `i` of the run in `d` `n` times, each time as soon as its replacement
/// is up; the seconds from each kill to the replacement.
fn kill_quickly(c: &mut Child, d: &str, i: usize, n: usize) -> Vec<f64> {
    let needle = format!("--index {i}");
    let mut gaps = Vec::new();
    for _ in 0..n {
        let victim = actor(d, i);
        signal(victim, "-KILL");
        let t = Instant::now();
        loop {
            if c.try_wait().unwrap().is_some() {
                return gaps;
            }
            let now = pids_with(&["__actor", d, &needle]);
            if now.len() == 1 && now[0] != victim {
                gaps.push(t.elapsed().as_secs_f64());
                break;
            }
            assert!(
                t.elapsed() < Duration::from_secs(20),
                "actor {i} not replaced"
            );
            std::thread::sleep(Duration::from_millis(5));
        }
    }
    gaps
}

/// The back-offs the supervisor reports for actor `i`'s restarts, in order.
fn backoffs(err: &str, i: usize) -> Vec<f64> {
    let head = format!("actor {i} stopped (signal 9); restarted after ");
    err.lines()
        .filter_map(|l| l.split_once(&head))
        .map(|(_, rest)| rest.split(' ').next().unwrap().parse().unwrap())
        .collect()
}

#[test]
fn an_actor_killed_faster_than_its_budget_ends_the_run_after_growing_back_offs() {
    let dir = TempDir::fresh("budget");
    let d = dir.to_str().unwrap();
    let mut c = train(
        &[
            &[
                "room",
                "--actors",
                "2",
                "--steps",
                "25600000",
                "--no-empowerment",
                "--max-restarts",
                "3",
                "--restart-window",
                "60",
                "--out",
                d,
            ][..],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 3, Duration::from_secs(60));
    let gaps = kill_quickly(&mut c, d, 1, 3);
    assert_eq!(gaps.len(), 3, "three restarts");
    // The fourth stop within the window is one too many.
    let victim = actor(d, 1);
    signal(victim, "-KILL");
    let (status, err, _) = finish(c, Duration::from_secs(30));
    assert_eq!(status.code(), Some(1), "{err}");
    assert!(
        err.contains(
            "actor 1 stopped (signal 9), its stop number 4 within 60 s: over its budget of 3 restarts in 60 s"
        ),
        "{err}"
    );
    // The back-off doubles (0.1, 0.2, 0.4 s) and the replacements came no sooner.
    assert_eq!(backoffs(&err, 1), [0.1, 0.2, 0.4], "{err}");
    for (gap, wait) in gaps.iter().zip([0.1, 0.2, 0.4]) {
        assert!(
            *gap >= wait,
            "replaced after {gap} s, before its back-off {wait} s"
        );
    }
    assert!(gaps[2] > gaps[0], "{gaps:?}");
    assert_nothing_left(&namespace_of(&err));
}

#[test]
fn kills_spread_wider_than_the_window_do_not_use_up_the_budget() {
    let dir = TempDir::fresh("spread");
    let d = dir.to_str().unwrap();
    let mut c = train(
        &[
            &[
                "room",
                "--actors",
                "2",
                "--steps",
                "25600000",
                "--no-empowerment",
                "--max-restarts",
                "1",
                "--restart-window",
                "2",
                "--out",
                d,
            ][..],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 3, Duration::from_secs(60));
    // Three kills, 2.5 s apart: never two in one 2-s window.
    for _ in 0..3 {
        assert_eq!(kill_quickly(&mut c, d, 0, 1).len(), 1, "actor 0 replaced");
        std::thread::sleep(Duration::from_millis(2500));
    }
    assert!(c.try_wait().unwrap().is_none(), "the run went on");
    signal(c.id(), "-INT");
    let (status, err, _) = finish(c, Duration::from_secs(30));
    assert_eq!(status.code(), Some(130), "{err}");
    assert!(!err.contains("over its budget"), "{err}");
    assert_eq!(
        err.matches("restarted after 0.1 s (restart 1 of 1 allowed in 2 s)")
            .count(),
        3,
        "{err}"
    );
    assert_nothing_left(&namespace_of(&err));
}

/// A child's stderr, read as it comes.
struct LiveErr(
    std::sync::Arc<std::sync::Mutex<String>>,
    std::thread::JoinHandle<()>,
);

impl LiveErr {
    fn of(c: &mut Child) -> LiveErr {
        use std::io::BufRead;
        let pipe = c.stderr.take().unwrap();
        let text = std::sync::Arc::new(std::sync::Mutex::new(String::new()));
        let t = text.clone();
        let h = std::thread::spawn(move || {
            for l in std::io::BufReader::new(pipe).lines().map_while(|l| l.ok()) {
                let mut s = t.lock().unwrap();
                s.push_str(&l);
                s.push('\n');
            }
        });
        LiveErr(text, h)
    }

    fn text(&self) -> String {
        self.0.lock().unwrap().clone()
    }

    fn wait_for(&self, needle: &str, limit: Duration) {
        wait_until(limit, needle, || self.text().contains(needle));
    }
}

#[test]
fn a_restarting_service_does_not_block_the_supervisor_or_trip_the_watchdog() {
    let dir = TempDir::fresh("slow-service");
    let d = dir.to_str().unwrap();
    let mut c = train(
        &[
            &[
                "room",
                "--actors",
                "2",
                "--steps",
                "25600000",
                "--hang-timeout",
                "3",
                "--out",
                d,
            ][..],
            SMALL,
        ]
        .concat(),
    );
    let err = LiveErr::of(&mut c);
    wait_rows(&dir, 3, Duration::from_secs(60));
    let old = super::children_with(c.id(), "serve");
    assert_eq!(old.len(), 1, "one service: {old:?}");
    signal(old[0], "-KILL");
    // Hold the new service before it is ready (its table takes tens of ms; the
    // supervisor starts it 0.1 s after the old one died).
    let t = Instant::now();
    let new = loop {
        let now = super::children_with(c.id(), "serve");
        if now.len() == 1 && now != old {
            signal(now[0], "-STOP");
            break now[0];
        }
        assert!(t.elapsed() < Duration::from_secs(20), "no new service");
    };
    let held = Instant::now();
    // While the service is held, the supervisor's loop goes on: it restarts an actor.
    let victim = actor(d, 1);
    signal(victim, "-KILL");
    err.wait_for(
        "actor 1 stopped (signal 9); restarted after",
        Duration::from_secs(10),
    );
    assert!(
        !err.text()
            .contains("the empowerment service is ready again"),
        "the new service was ready before it was held (the test lost its race): {}",
        err.text()
    );
    // The watchdog is held too: 5 s without an update, its limit 3 s.
    std::thread::sleep(Duration::from_secs(5).saturating_sub(held.elapsed()));
    assert!(c.try_wait().unwrap().is_none(), "{}", err.text());
    signal(new, "-CONT");
    err.wait_for(
        "the empowerment service is ready again",
        Duration::from_secs(10),
    );
    let n = read_metrics(&dir.join("metrics.csv")).unwrap().len();
    wait_rows(&dir, n + 10, Duration::from_secs(30));
    signal(c.id(), "-INT");
    let status = c.wait().unwrap();
    let LiveErr(text, reader) = err;
    reader.join().unwrap();
    let text = text.lock().unwrap().clone();
    assert_eq!(status.code(), Some(130), "{text}");
    assert!(!text.contains("no update for"), "{text}");
    assert_nothing_left(&namespace_of(&text));
}

#[test]
fn a_refused_chunk_does_not_leave_actor_and_learner_waiting_on_each_other() {
    let dir = TempDir::fresh("refused");
    let d = dir.to_str().unwrap();
    // 40 updates of 2 actors; actor 1's sixth chunk (policy version 5) carries an
    // action out of range (the actors' test hook).
    let c: Child = fulcrum()
        .args(
            [
                &[
                    "train",
                    "room",
                    "--actors",
                    "2",
                    "--steps",
                    "10240",
                    "--no-empowerment",
                    "--out",
                    d,
                ][..],
                SMALL,
            ]
            .concat(),
        )
        .env("FULCRUM_FAULT_BAD_CHUNK", "1:5")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (status, err, _) = finish(c, Duration::from_secs(60));
    assert!(status.success(), "{err}");
    assert!(
        err.contains("the learner refused a chunk of actor 1: it goes on without it"),
        "{err}"
    );
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_eq!(rows.len(), 40, "every update made");
    // The refused chunk (and, on a busy machine, a chunk of actor 1 that the learner's
    // updates without it made stale before it came).
    assert!(rows.last().unwrap().dropped_chunks >= 1);
    assert_eq!(rows.last().unwrap().lost_chunks, 0, "refused, not lost");
    // Update 6 (the one its refused chunk was for) is made without actor 1, and so
    // are the next ones until its next chunk comes (on a busy machine the learner may
    // make a few with actor 0 alone meanwhile); from then on both actors, whole chunks.
    let steps = steps_per_update(&dir);
    assert!(steps[..5].iter().all(|&s| s == 256), "{steps:?}");
    assert_eq!(steps[5], 128, "{steps:?}");
    let back = 5 + steps[5..]
        .iter()
        .position(|&s| s == 256)
        .expect("actor 1 back");
    assert!(steps[5..back].iter().all(|&s| s == 128), "{steps:?}");
    assert!(steps[back..].iter().all(|&s| s == 256), "{steps:?}");
    // Nobody waited for the refused chunk: no update took anywhere near the local
    // deadline (10 s).
    let slowest = rows
        .windows(2)
        .map(|w| w[1].wall_s - w[0].wall_s)
        .fold(0.0, f64::max);
    assert!(slowest < 5.0, "an update took {slowest} s");
    assert_nothing_left(&namespace_of(&err));
}

#[test]
fn a_stopped_learner_is_named_by_the_watchdog() {
    let dir = TempDir::fresh("stopped-learner");
    let d = dir.to_str().unwrap();
    let c = train(
        &[
            &[
                "room",
                "--actors",
                "1",
                "--steps",
                "12800000",
                "--no-empowerment",
                "--hang-timeout",
                "3",
                "--out",
                d,
            ][..],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 5, Duration::from_secs(60));
    let l = super::children_with(c.id(), "__learner");
    assert_eq!(l.len(), 1);
    signal(l[0], "-STOP");
    let t0 = Instant::now();
    let (status, err, _) = finish(c, Duration::from_secs(60));
    assert!(t0.elapsed() < Duration::from_secs(15), "{:?}", t0.elapsed());
    assert_eq!(status.code(), Some(1), "{err}");
    assert!(
        err.contains("at least 3 s): the learner itself stalled"),
        "{err}"
    );
    assert!(!err.contains("waiting for actor"), "{err}");
    assert_nothing_left(&namespace_of(&err));
}

#[test]
fn bad_supervision_settings_are_refused_before_anything_starts() {
    for (args, flag) in [
        (&["--hang-timeout", "0"][..], "--hang-timeout 0 must be"),
        (&["--hang-timeout", "inf"][..], "--hang-timeout inf must be"),
        (&["--restart-window", "0"][..], "--restart-window 0 must be"),
        (
            &["--restart-window", "NaN"][..],
            "--restart-window NaN must be",
        ),
    ] {
        let dir = TempDir::fresh("bad-supervision");
        let d = dir.to_str().unwrap();
        let out = crate::util::run(&[&["train", "room", "--out", d][..], args].concat());
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains(flag) && err.contains("a positive number of seconds"),
            "{args:?}: {err}"
        );
        assert_eq!(err.trim().lines().count(), 1, "one sentence: {err}");
        assert!(!dir.exists(), "nothing written for {args:?}");
    }
}
