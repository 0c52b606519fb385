//! The default intrinsic form and the beacon-trap detector, with real training: the
//! additive bonus on a world built to trap it is warned of and marked within the
//! detector's window, the default form solves the same world, a solving additive run
//! is never marked, and `--paper` is the paper's setting.

use std::path::Path;
use std::time::Duration;

use fulcrum_learner::metrics::read_metrics;
use fulcrum_learner::trap::WINDOW_STEPS;

use super::{beta_of, finish, train};
use crate::util::TempDir;

/// Standing next to the tree with the axe pays beta * E = 0.05 a step (E = 1 bit),
/// worth 0.05 / (1 - 0.99) = 5 to a learner that bootstraps at the time limit; chopping
/// the tree pays 1 and ends the episode. The axe lies next to the agent.
const BEACON: &str = r#"name = "beacon"
max_steps = 100
map = """
########
#@a....#
#......#
#....T.#
########
"""

[tools]
a = "axe"

[task]
kind = "destroy"
objects = ["tree"]

[empowerment]
tool = "axe"
objects = ["tree"]
horizon_unequipped = 8
horizon_equipped = 3
beta = 0.05
"#;

fn config(dir: &Path) -> String {
    std::fs::read_to_string(dir.join("config.toml")).unwrap()
}

/// `fulcrum train ARGS --out OUT` to its end: status and stderr.
fn train_to(args: &[&str], out: &Path, limit: u64) -> (std::process::ExitStatus, String) {
    let args = [args, &["--out", out.to_str().unwrap()][..]].concat();
    let (s, err, _) = finish(train(&args), Duration::from_secs(limit));
    (s, err)
}

#[test]
fn the_additive_bonus_is_caught_in_a_constructed_trap_and_the_default_is_not() {
    let home = TempDir::new("beacon");
    let world = home.join("beacon.toml");
    std::fs::write(&world, BEACON).unwrap();
    let w = world.to_str().unwrap();
    let steps = "307200"; // 300 updates of 1024
    let (trapped, solved) = (home.join("additive"), home.join("default"));
    let (s, err) = train_to(
        &[
            w,
            "--intrinsic",
            "additive",
            "--actors",
            "1",
            "--steps",
            steps,
        ],
        &trapped,
        240,
    );
    assert!(s.success(), "{err}");
    // One warning, naming the trap and the form that cannot fall into it.
    assert_eq!(err.matches("likely beacon trap").count(), 1, "{err}");
    assert!(
        err.contains("`--intrinsic horizon-potential` (the default) cannot trap"),
        "{err}"
    );
    let rows = read_metrics(&trapped.join("metrics.csv")).unwrap();
    let last_success = rows
        .iter()
        .filter(|r| r.success_rate > 0.0)
        .map(|r| r.env_steps)
        .max()
        .unwrap_or(0);
    let first_mark = rows
        .iter()
        .find(|r| r.trap)
        .map(|r| r.env_steps)
        .expect("the detector marks the trapped run");
    // Within its window: the first update whose window of >= 100,000 steps holds no
    // success, i.e. at most one batch past last_success + WINDOW_STEPS.
    assert!(
        first_mark > last_success && first_mark <= last_success + WINDOW_STEPS + 1024,
        "last success at {last_success}, first mark at {first_mark}"
    );
    // Marked from there to the end, the run never succeeding again.
    assert!(rows
        .iter()
        .filter(|r| r.env_steps >= first_mark)
        .all(|r| r.trap));
    assert!(rows.last().unwrap().success_rate == 0.0);

    // The default form on the same world: potential-based, solves it, never marked.
    let (s, err) = train_to(&[w, "--actors", "1", "--steps", steps], &solved, 240);
    assert!(s.success(), "{err}");
    assert!(!err.contains("beacon trap"), "{err}");
    let cfg = config(&solved);
    assert!(cfg.contains("intrinsic = \"horizon-potential\"\n"), "{cfg}");
    assert!(cfg.contains("beta = 0.05\n"), "{cfg}");
    let rows = read_metrics(&solved.join("metrics.csv")).unwrap();
    assert!(rows.iter().all(|r| !r.trap));
    assert!(
        rows.last().unwrap().success_rate >= 0.9,
        "{:?}",
        rows.last()
    );
}

#[test]
fn a_solving_additive_run_is_never_marked() {
    // exp1-tree's additive seed 1 of RESULTS.md's masked table: 0.9 at 83k env steps.
    let dir = TempDir::fresh("solving");
    let (s, err) = train_to(
        &[
            "exp1-tree",
            "--intrinsic",
            "additive",
            "--actors",
            "1",
            "--seed",
            "1",
            "--steps",
            "499712",
        ],
        &dir,
        240,
    );
    assert!(s.success(), "{err}");
    assert!(!err.contains("beacon trap"), "{err}");
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert!(rows.iter().all(|r| !r.trap));
    assert!(
        rows.last().unwrap().success_rate >= 0.9,
        "{:?}",
        rows.last()
    );
}

#[test]
fn paper_is_the_papers_setting_in_one_flag() {
    let dir = TempDir::fresh("paper");
    let (s, err) = train_to(
        &["room", "--paper", "--actors", "1", "--steps", "4096"],
        &dir,
        120,
    );
    assert!(s.success(), "{err}");
    let cfg = config(&dir);
    for line in [
        "intrinsic = \"additive\"\n",
        "action_mask = false\n",
        // The world file's beta, and RLlib's PPO (lr 5e-5, 30 epochs, 512 steps a chunk).
        "beta = 0.0009\n",
        "steps_per_chunk = 512\n",
        "epochs = 30\n",
        "lr = 0.00005\n",
    ] {
        assert!(cfg.contains(line), "{line}: {cfg}");
    }
    // --paper sets the form and the preset: naming them too contradicts it.
    for extra in [["--intrinsic", "potential"], ["--ppo-preset", "cleanrl"]] {
        let d = TempDir::fresh("paper-bad");
        let (s, err) = train_to(&["room", "--paper", extra[0], extra[1]], &d, 30);
        assert_eq!(s.code(), Some(2), "{err}");
        assert!(err.contains("--paper"), "{err}");
        assert!(!d.exists());
    }
}

/// A corridor with a boulder east of the agent: with every action (N, E, S, W, apply;
/// no tool), the boulder can stand on min(h, 3) + 1 cells after exactly h steps (pushed
/// east up to the wall; any other action stays), most from the start, so
/// max Phi = sum over h = 1..8 of log2(min(h, 3) + 1) = 1 + log2 3 + 6 * 2.
const CORRIDOR: &str = r#"name = "corridor"
max_steps = 20
map = """
#######
#@0...#
#######
"""

[empowerment]
tool = "all"
objects = ["boulder"]
horizon_unequipped = 8
horizon_equipped = 8
"#;

#[test]
fn the_default_beta_of_horizon_potential_keeps_a_path_worth_0_4() {
    let home = TempDir::new("corridor");
    let world = home.join("corridor.toml");
    std::fs::write(&world, CORRIDOR).unwrap();
    let max_phi = 1.0 + 3f64.log2() + 12.0;
    let d = home.join("run");
    let (s, err) = train_to(
        &[world.to_str().unwrap(), "--actors", "1", "--steps", "1024"],
        &d,
        60,
    );
    assert!(s.success(), "{err}");
    let cfg = config(&d);
    let beta = beta_of(&cfg);
    // The table holds Phi in f32.
    assert!((beta - 0.4 / max_phi).abs() < 1e-6, "beta {beta}: {cfg}");
    // An explicit beta is kept as given.
    let d = home.join("explicit");
    let (s, err) = train_to(
        &[
            world.to_str().unwrap(),
            "--actors",
            "1",
            "--steps",
            "1024",
            "--beta",
            "0.3",
        ],
        &d,
        60,
    );
    assert!(s.success(), "{err}");
    assert!(config(&d).contains("beta = 0.3\n"));
}
