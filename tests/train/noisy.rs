//! Training on stochastic worlds: the actors draw each step's outcome from the chunk's
//! seeded generator, so a run on a noisy world learns, is reproducible and resumes bit
//! for bit; `--empowerment-model deterministic` computes E on the map without its noise.

use std::path::Path;
use std::time::Duration;

use fulcrum_contracts::config::{EmpowermentModel, RunConfig};
use fulcrum_learner::metrics::read_metrics;

use super::{finish, resumed_equals_uninterrupted_on, train};
use crate::util::{fulcrum, TempDir};

/// The room of the training tests with the dynamics given (`""` for none).
fn room_with(dynamics: &str) -> String {
    let room = fulcrum_world::builtin::source("room").expect("room is built in");
    format!("{room}\n{dynamics}")
}

/// Moves slip one time in four, the axe fells the tree half the times it is swung.
const NOISE: &str = "[dynamics]\nslip = 0.25\n\n[[rules]]\ntool = \"axe\"\ntarget = \"tree\"\nfrom = \"intact\"\nto = \"destroyed\"\nrange = 1\np = 0.5\n";

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

/// Success rate over the last `n` updates, weighted by their episodes.
fn tail_success(dir: &Path, n: usize) -> f64 {
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    let tail = &rows[rows.len() - n..];
    let (eps, succ) = tail.iter().fold((0.0, 0.0), |(e, s), r| {
        (
            e + r.episodes as f64,
            s + r.success_rate * r.episodes as f64,
        )
    });
    succ / eps
}

/// A run on a noisy room stopped and resumed equals one that never stopped (the
/// outcomes come from the same per-chunk stream), with every form whose state is
/// checkpointed, E as if deterministic, and periodic evaluations (which draw outcomes
/// too). The count form's visit counts live in the service and start again from zero on
/// a resume (README, "count"), in any world: it only has to train here.
#[test]
fn a_run_on_a_noisy_world_resumes_bit_for_bit_with_every_form() {
    let home = TempDir::new("noisy-worlds");
    let noisy = write(&home, "room-noisy.toml", &room_with(NOISE));
    resumed_equals_uninterrupted_on(&noisy, "noisy-hp", &["--eval-every", "2"]);
    for form in ["additive", "potential", "first-visit"] {
        resumed_equals_uninterrupted_on(&noisy, &format!("noisy-{form}"), &["--intrinsic", form]);
    }
    resumed_equals_uninterrupted_on(
        &noisy,
        "noisy-det",
        &["--empowerment-model", "deterministic"],
    );
    let dir = home.join("count");
    let args = [
        &noisy,
        "--intrinsic",
        "count",
        "--actors",
        "1",
        "--steps",
        "768",
        "--envs-per-actor",
        "4",
        "--steps-per-chunk",
        "32",
        "--out",
        dir.to_str().unwrap(),
    ];
    let (s, err, _) = finish(train(&args), Duration::from_secs(120));
    assert!(s.success(), "{err}");
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_eq!(rows.len(), 6);
    assert!(
        rows.iter().any(|r| r.intrinsic_mean > 0.0),
        "count paid nothing"
    );
}

/// The actors do draw: the same map and seed without the noise trains on other
/// episodes, and two runs of the noisy room with one seed are the same run.
#[test]
fn the_noise_reaches_the_episodes_and_the_seed_fixes_it() {
    let home = TempDir::new("noisy-draws");
    let noisy = write(&home, "room-noisy.toml", &room_with(NOISE));
    let plain = write(&home, "room-plain.toml", &room_with(""));
    let run = |world: &str, tag: &str| {
        let dir = home.join(tag);
        let d = dir.to_str().unwrap().to_string();
        let args = [
            world,
            "--actors",
            "1",
            "--steps",
            "4096",
            "--seed",
            "3",
            "--envs-per-actor",
            "4",
            "--steps-per-chunk",
            "32",
            "--out",
            &d,
        ];
        let (s, err, _) = finish(train(&args), Duration::from_secs(120));
        assert!(s.success(), "{err}");
        read_metrics(&dir.join("metrics.csv"))
            .unwrap()
            .iter()
            .map(|r| {
                (
                    r.episodes,
                    r.success_rate.to_bits(),
                    r.episode_length.to_bits(),
                )
            })
            .collect::<Vec<_>>()
    };
    let (a, b, c) = (run(&noisy, "a"), run(&noisy, "b"), run(&plain, "c"));
    assert_eq!(a, b, "one seed, one noisy run");
    assert_ne!(a, c, "the noisy room trained on the plain room's episodes");
}

/// PPO through the whole system learns exp1-tree-slip (moves slip one time in ten, the
/// axe fells the tree four times in five) within 200k env steps, with E of the noisy
/// channel and with E computed as if the world were deterministic; `eval` plays the
/// noisy world.
#[test]
fn the_whole_system_learns_a_noisy_world() {
    for (model, extra) in [
        (EmpowermentModel::Exact, &[][..]),
        (
            EmpowermentModel::Deterministic,
            &["--empowerment-model", "deterministic"][..],
        ),
    ] {
        let dir = TempDir::fresh("noisy-learn");
        let d = dir.to_str().unwrap();
        let args = [
            &[
                "exp1-tree-slip",
                "--actors",
                "1",
                "--steps",
                "200704",
                "--seed",
                "1",
                "--out",
                d,
            ][..],
            extra,
        ]
        .concat();
        let (s, err, _) = finish(train(&args), Duration::from_secs(300));
        assert!(s.success(), "{err}");
        let cfg = RunConfig::load(&dir.join("config.toml")).unwrap();
        assert_eq!(cfg.empowerment_model, model);
        let rate = tail_success(&dir, 10);
        assert!(rate >= 0.9, "{model:?}: success {rate}");
        let out = fulcrum()
            .args(["eval", d, "--episodes", "200", "--sample"])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = std::fs::read_to_string(dir.join("eval.csv")).unwrap();
        assert_eq!(text.lines().count(), 2, "{text}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
