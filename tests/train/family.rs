//! Training on a world family: runs on N layouts and on a fresh layout every episode
//! resume to the same bits as runs never stopped (the layouts each env plays travel in
//! the checkpoint's records and later ones come from the chunk's generator), periodic
//! evaluations play held-out layouts, and `fulcrum eval` plays held-out or training
//! layouts, refusing held-out seeds that fall among the run's training layouts.

use std::time::Duration;

use fulcrum_learner::evalcsv::EvalRow;

use super::{finish, resumed_equals_uninterrupted_on, train, SMALL};
use crate::util::{fulcrum, TempDir};

#[test]
fn family_runs_resume_bit_for_bit() {
    for (tag, extra) in [
        // Four layouts, the potential of each layout's own table, held-out evaluations.
        (
            "family-4-hp",
            &[
                "--layouts",
                "4",
                "--intrinsic",
                "horizon-potential",
                "--eval-every",
                "2",
            ][..],
        ),
        // A fresh layout every episode, the paper's bonus (tables made on first sight).
        (
            "family-all",
            &["--layouts", "all", "--intrinsic", "additive"][..],
        ),
    ] {
        resumed_equals_uninterrupted_on("toolbox", tag, extra);
    }
}

fn eval(run: &str, extra: &[&str]) -> std::process::Output {
    fulcrum().args(["eval", run]).args(extra).output().unwrap()
}

fn rows(dir: &TempDir) -> Vec<EvalRow> {
    std::fs::read_to_string(dir.join("eval.csv"))
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| EvalRow::parse(l).unwrap())
        .collect()
}

// `--eval-sample`: the periodic evaluations sample their actions, seeded by the run's
// seed, so the one after the last update is `fulcrum eval --sample` of the final
// checkpoint on the same held-out layouts, figure for figure.
#[test]
fn a_family_run_can_be_evaluated_sampled_during_training() {
    let dir = trained_on_four(
        "family-eval-sample",
        &["--eval-episodes", "40", "--eval-sample"],
    );
    let d = dir.to_str().unwrap();
    let config = std::fs::read_to_string(dir.join("config.toml")).unwrap();
    assert!(config.contains("eval_sample = true"), "{config}");
    let periodic = rows(&dir);
    assert_eq!(periodic.len(), 2);
    for r in &periodic {
        assert_eq!(
            (r.mode.as_str(), r.layouts.as_str(), r.episodes),
            ("train-sample", "test:40", 40),
            "{r:?}"
        );
    }
    let o = eval(d, &["--layouts", "test:40", "--sample"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let all = rows(&dir);
    let (last, by_eval) = (&all[1], &all[2]);
    assert_eq!((by_eval.mode.as_str(), by_eval.update), ("sample", 2));
    assert_eq!(last.update, 2);
    let figures = |r: &EvalRow| (r.success, r.ret, r.length, r.tool_use, r.tool_choice);
    assert_eq!(figures(last), figures(by_eval));
    // Sampled play is not greedy play: 40 greedy episodes give other lengths.
    let o = eval(d, &["--layouts", "test:40"]);
    assert!(o.status.success());
    let greedy = &rows(&dir)[3];
    assert_eq!(greedy.mode, "greedy");
    assert_ne!(greedy.length, by_eval.length);
}

/// `train toolbox --layouts 4` for two updates of [`SMALL`] chunks, evaluated after
/// each (`--eval-every 1`) with `extra`; its run directory.
fn trained_on_four(tag: &str, extra: &[&str]) -> TempDir {
    let dir = TempDir::fresh(tag);
    let d = dir.to_str().unwrap();
    let head = [
        "toolbox",
        "--layouts",
        "4",
        "--actors",
        "1",
        "--steps",
        "256",
    ];
    let args = [
        &head[..],
        &["--eval-every", "1"],
        extra,
        &["--out", d],
        SMALL,
    ]
    .concat();
    let (s, err, _) = finish(train(&args), Duration::from_secs(120));
    assert!(s.success(), "{err}");
    dir
}

#[test]
fn a_family_run_is_evaluated_on_held_out_and_training_layouts() {
    let dir = trained_on_four("family-eval", &["--eval-episodes", "6"]);
    let d = dir.to_str().unwrap();
    let config = std::fs::read_to_string(dir.join("config.toml")).unwrap();
    assert!(config.contains("layouts = \"4\""), "{config}");
    // The periodic rows: one episode on each of the first 6 held-out layouts.
    let periodic = rows(&dir);
    assert_eq!(periodic.len(), 2);
    for r in &periodic {
        assert_eq!((r.layouts.as_str(), r.episodes), ("test:6", 6), "{r:?}");
        assert_eq!(r.world, "toolbox");
    }

    // Held-out layouts by default, one episode each.
    let o = eval(d, &["--layouts", "test:20"]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        out.contains("20 episodes of the policy of update 2 (256 env steps), greedy, on 20 layouts of 'toolbox' (test:20)"),
        "{out}"
    );
    assert!(out.contains("tool choice"), "{out}");
    // Greedy play is deterministic: the same layouts give the same figures.
    let again = eval(d, &["--layouts", "test:20"]);
    let lines = |o: &std::process::Output| {
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .filter(|l| !l.starts_with("appended"))
            .map(str::to_string)
            .collect::<Vec<_>>()
    };
    assert_eq!(lines(&o), lines(&again));
    let o = eval(d, &["--layouts", "train:9", "--episodes", "8"]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // train:9 of a run on 4 layouts is its 4 layouts, played round twice.
    assert!(out.contains("8 episodes"), "{out}");
    assert!(out.contains("on 4 layouts of 'toolbox' (train:9)"), "{out}");
    let all = rows(&dir);
    let labels: Vec<(&str, usize)> = all[2..]
        .iter()
        .map(|r| (r.layouts.as_str(), r.episodes))
        .collect();
    assert_eq!(labels, [("test:20", 20), ("test:20", 20), ("train:9", 8)]);

    // Held-out seeds among the training layouts, or a world for a family run: refused,
    // one sentence, nothing appended.
    for (args, says) in [
        (
            &["--layouts", "test:2..6"][..],
            "held-out layouts 2..6 overlap the run's training layouts 0..4 (--layouts 4): take seeds from 4 on",
        ),
        (&["--layouts", "test:0"][..], "'0' is not a number of layouts"),
        (
            &["--layouts", "test:3", "--world", "exp1-tree"][..],
            "--world and --layouts contradict each other",
        ),
    ] {
        let o = eval(d, args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(err.contains(says), "{args:?}: {err}");
    }
    assert_eq!(rows(&dir).len(), 5);
    // A held-out range beyond the training seeds is taken as asked.
    let o = eval(d, &["--layouts", "test:4..7"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(rows(&dir).last().unwrap().layouts, "test:4..7");
}

#[test]
fn layouts_on_a_run_of_one_world_are_refused() {
    let dir = TempDir::fresh("family-one-world");
    let d = dir.to_str().unwrap();
    let (s, err, _) = finish(
        train(
            &[
                &["room", "--actors", "1", "--steps", "128", "--out", d][..],
                SMALL,
            ]
            .concat(),
        ),
        Duration::from_secs(120),
    );
    assert!(s.success(), "{err}");
    let o = eval(d, &["--layouts", "test:5"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--layouts test:5 needs a run on a world family"),
        "{err}"
    );
}
