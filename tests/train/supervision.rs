//! The supervisor and its children: killed actors, services, learners and
//! supervisors, and a stopped learner that must not make actors spin.

use super::*;

#[test]
fn a_killed_actor_is_replaced_and_the_run_finishes() {
    let dir = TempDir::fresh("kill");
    let d = dir.to_str().unwrap();
    // 4000 updates of 256 steps (ten seconds or more here): long enough for three kills
    // of actor 0, each after its replacement has taken part in updates.
    let mut c = train(
        &[
            &[
                "room",
                "--actors",
                "2",
                "--steps",
                "1024000",
                "--no-empowerment",
                "--out",
                d,
            ][..],
            SMALL,
        ]
        .concat(),
    );
    let rows_now = || {
        read_metrics(&dir.join("metrics.csv"))
            .map(|r| r.len())
            .unwrap_or(0)
    };
    let mut at = 3;
    for kill in 1..=3 {
        wait_rows(&dir, at, Duration::from_secs(60));
        let victims = pids_with(&["__actor", d, "--index 0"]);
        assert!(
            c.try_wait().unwrap().is_none(),
            "the run ended before kill {kill}"
        );
        assert_eq!(victims.len(), 1, "one actor 0 before kill {kill}");
        signal(victims[0], "-KILL");
        wait_until(Duration::from_secs(20), "actor 0 replaced", || {
            let now = pids_with(&["__actor", d, "--index 0"]);
            !now.is_empty() && now != victims
        });
        // The next kill after the new actor 0 took part in some updates.
        at = rows_now() + 20;
    }
    let (status, err, _) = finish(c, Duration::from_secs(180));
    assert!(status.success(), "{err}");
    assert_eq!(
        err.matches("actor 0 stopped (signal 9); restarted").count(),
        3,
        "{err}"
    );
    // Every update is whole (one full chunk per actor: the step count grows by the
    // batch each row) and the run reaches its steps.
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_contiguous(&rows, 4000, 256);
    assert_eq!(rows.last().unwrap().actor_restarts, 3);
    assert_nothing_left(&namespace_of(&err));
}

#[test]
fn a_killed_service_is_restarted_and_actors_resume() {
    let dir = TempDir::fresh("service");
    let twin = TempDir::fresh("service-twin");
    let d = dir.to_str().unwrap();
    let common = [
        &["room", "--actors", "1", "--steps", "256000", "--seed", "7"][..],
        &["--intrinsic", "additive"][..],
        SMALL,
    ]
    .concat();
    let c = train(&[&common[..], &["--out", d]].concat());
    wait_rows(&dir, 3, Duration::from_secs(60));
    let svc = children_with(c.id(), "serve");
    assert_eq!(svc.len(), 1, "one service: {svc:?}");
    signal(svc[0], "-KILL");
    let (status, err, _) = finish(c, Duration::from_secs(180));
    assert!(status.success(), "{err}");
    assert!(
        err.contains("the empowerment service stopped (signal 9); restarting it"),
        "{err}"
    );
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_contiguous(&rows, 2000, 128);
    // No chunk was lost or refused across the restart (actors held theirs and asked
    // the new service).
    assert!(rows.iter().all(|r| r.dropped_chunks == 0));
    assert_nothing_left(&namespace_of(&err));
    // The intrinsic rewards of every chunk are the table's, never zeros or a stand-in:
    // the same run with a service nobody killed trains to the same bits, row by row
    // (one synchronous actor; the additive form depends on the table alone).
    let (status, err, _) = finish(
        train(&[&common[..], &["--out", twin.to_str().unwrap()]].concat()),
        Duration::from_secs(180),
    );
    assert!(status.success(), "{err}");
    let undisturbed = read_metrics(&twin.join("metrics.csv")).unwrap();
    let a: Vec<String> = rows.iter().map(deterministic).collect();
    let b: Vec<String> = undisturbed.iter().map(deterministic).collect();
    assert!(a == b, "a service restart changed what the run trained on");
}

#[test]
fn a_killed_learner_ends_the_run_with_a_resumable_checkpoint() {
    let dir = TempDir::fresh("learner");
    let d = dir.to_str().unwrap();
    let c = train(
        &[
            &[
                "room",
                "--actors",
                "1",
                "--steps",
                "256000",
                "--no-empowerment",
                "--checkpoint-every",
                "5",
                "--seed",
                "7",
                "--out",
                d,
            ][..],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 12, Duration::from_secs(60));
    let l = children_with(c.id(), "__learner");
    assert_eq!(l.len(), 1);
    signal(l[0], "-KILL");
    let (status, err, _) = finish(c, Duration::from_secs(30));
    assert_eq!(status.code(), Some(1), "{err}");
    assert!(err.contains("the learner failed (signal 9)"), "{err}");
    assert!(err.contains(&format!("--resume {d}")), "{err}");
    assert_nothing_left(&namespace_of(&err));
    let killed_at = read_metrics(&dir.join("metrics.csv")).unwrap().len() as u64;
    assert!(killed_at >= 12);
    // Continue to the end (2000 updates): the rows after the last checkpoint (a
    // multiple of 5) are redone, not duplicated.
    let c = train(&["--resume", d]);
    let (status, err, _) = finish(c, Duration::from_secs(120));
    assert!(status.success(), "{err}");
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_contiguous(&rows, 2000, 128);
    // And redone to the same bits: the same run, never killed (the same step count,
    // which sets the learning-rate schedule).
    let twin = TempDir::fresh("learner-twin");
    let (status, err, _) = finish(
        train(
            &[
                &["room", "--actors", "1", "--steps", "256000"][..],
                &["--no-empowerment", "--checkpoint-every", "5", "--seed", "7"],
                &["--out", twin.to_str().unwrap()],
                SMALL,
            ]
            .concat(),
        ),
        Duration::from_secs(120),
    );
    assert!(status.success(), "{err}");
    let twin_rows = read_metrics(&twin.join("metrics.csv")).unwrap();
    let a: Vec<String> = rows.iter().map(deterministic).collect();
    let b: Vec<String> = twin_rows.iter().map(deterministic).collect();
    assert!(
        a == b,
        "the resume after a SIGKILL left the uninterrupted path"
    );
}

/// CPU seconds (user + system) a process has used so far.
fn cpu_s(pid: u32) -> f64 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
    // Fields after the command (which may hold spaces) start after the last ')'.
    let rest = stat.rsplit(')').next().unwrap_or("");
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    // utime and stime are fields 14 and 15 of stat, 12 and 13 after the ')'.
    (ticks(11) + ticks(12)) / 100.0
}

#[test]
fn a_stopped_learner_blocks_actors_without_burning_a_core_or_losing_chunks() {
    let dir = TempDir::fresh("sigstop");
    let d = dir.to_str().unwrap();
    // Asynchronous actors: they keep producing until the learner's queue is full, then
    // wait under backpressure.
    let c = train(
        &[
            &["room", "--actors", "2", "--steps", "128000", "--out", d][..],
            &["--no-empowerment", "--max-policy-lag", "1000"],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 5, Duration::from_secs(60));
    let l = children_with(c.id(), "__learner");
    assert_eq!(l.len(), 1);
    let actors = children_with(c.id(), "__actor");
    assert_eq!(actors.len(), 2);
    signal(l[0], "-STOP");
    // Let the queue fill, then measure the actors' CPU over 2 s.
    std::thread::sleep(Duration::from_millis(1000));
    let rows_stopped = read_metrics(&dir.join("metrics.csv")).unwrap().len();
    let before: f64 = actors.iter().map(|&p| cpu_s(p)).sum();
    std::thread::sleep(Duration::from_secs(2));
    let used: f64 = actors.iter().map(|&p| cpu_s(p)).sum::<f64>() - before;
    assert!(
        used < 0.5,
        "two blocked actors used {used:.2} s of CPU in 2 s"
    );
    // Nothing was learned while stopped.
    assert_eq!(
        read_metrics(&dir.join("metrics.csv")).unwrap().len(),
        rows_stopped
    );
    signal(l[0], "-CONT");
    let (status, err, _) = finish(c, Duration::from_secs(120));
    assert!(status.success(), "{err}");
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_contiguous(&rows, 500, 256);
    assert!(rows.iter().all(|r| r.dropped_chunks == 0), "no chunk lost");
    assert_nothing_left(&namespace_of(&err));
}

#[test]
fn a_killed_supervisor_takes_its_children_and_the_run_resumes() {
    let dir = TempDir::fresh("supervisor");
    let d = dir.to_str().unwrap();
    let mut c = train(
        &[
            &["room", "--actors", "1", "--steps", "256000", "--out", d][..],
            &["--checkpoint-every", "5"],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 12, Duration::from_secs(60));
    // The supervisor's stderr names the namespace; read it after the kill.
    signal(c.id(), "-KILL");
    let _ = c.wait();
    let mut err = String::new();
    let _ = c.stderr.take().unwrap().read_to_string(&mut err);
    let ns = namespace_of(&err);
    // Children notice (PR_SET_PDEATHSIG) and go.
    wait_until(Duration::from_secs(10), "the children gone", || {
        pids_with(&[&ns]).is_empty()
    });
    let done = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert!(done.len() >= 12);
    // The same run continues from its last checkpoint, 20 updates past the rows the dead
    // run wrote (an update takes about a millisecond here: between the kill and their
    // death the children may write 30 rows more).
    let total = done.len() as u64 + 20;
    let steps = (total * 128).to_string();
    let c2 = train(&["--resume", d, "--steps", &steps]);
    let (status, err2, _) = finish(c2, Duration::from_secs(60));
    assert!(status.success(), "{err2}");
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_contiguous(&rows, total, 128);
    // Whatever the dead left in shared memory, the next start cleaned: the test lists
    // the old namespace's services without cleaning anything itself.
    assert_eq!(
        services_of(&ns),
        Vec::<String>::new(),
        "left by the dead run"
    );
}
