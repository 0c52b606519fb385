//! `fulcrum eval`: a trained room policy evaluated greedily reaches the success it
//! trained to; greedy evaluation is deterministic; sampled evaluation is reproducible by
//! seed; another world of the same shape is played, one of another shape refused (a
//! cropped policy plays worlds of any size with its tools). `train --eval-every`: its
//! rows come at the asked updates, and the last equals `fulcrum eval` of the final
//! checkpoint (the learner's weights in memory against the file's).

use std::process::Output;

use crate::util::{fulcrum, TempDir};

fn eval(run: &str, extra: &[&str]) -> Output {
    fulcrum().args(["eval", run]).args(extra).output().unwrap()
}

/// The value after `label` in eval's output ("success rate    1.000 (95% CI ...").
fn figure(out: &str, label: &str) -> f64 {
    let line = out
        .lines()
        .find(|l| l.starts_with(label))
        .unwrap_or_else(|| panic!("no '{label}' in {out}"));
    line[label.len()..]
        .split_whitespace()
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

/// `fulcrum train ARGS`, which must succeed.
fn train_ok(args: &[&str]) {
    let out = fulcrum().arg("train").args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The run in `run` is played on the world file `world` (named `name`), and refused on
/// exp1-tree with `refusal` (exit 2).
fn plays_one_and_refuses_exp1_tree(run: &str, world: &std::path::Path, name: &str, refusal: &str) {
    let o = eval(
        run,
        &["--episodes", "3", "--world", world.to_str().unwrap()],
    );
    let text = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(text.contains(&format!("on world '{name}'")), "{text}");
    let bad = eval(run, &["--world", "exp1-tree"]);
    let err = String::from_utf8_lossy(&bad.stderr);
    assert_eq!(bad.status.code(), Some(2), "{err}");
    assert!(err.contains(refusal), "{err}");
}

#[test]
fn a_trained_policy_is_evaluated_greedily_sampled_and_on_another_world() {
    let dir = TempDir::fresh("eval");
    let d = dir.to_str().unwrap();
    // room's defaults: the training tests see success 1.0 well within 100k steps.
    train_ok(&[
        "room",
        "--steps",
        "102400",
        "--seed",
        "2",
        "--eval-every",
        "30",
        "--eval-episodes",
        "20",
        "--out",
        d,
    ]);
    let rows = fulcrum_learner::metrics::read_metrics(&dir.join("metrics.csv")).unwrap();
    let trained = rows.last().unwrap().success_rate;
    assert!(trained >= 0.9, "training ended at success {trained}");

    let a = eval(d, &["--episodes", "20"]);
    let text = String::from_utf8_lossy(&a.stdout).to_string();
    assert!(a.status.success(), "{}", String::from_utf8_lossy(&a.stderr));
    assert!(
        text.contains("20 episodes of the policy of update 100 (102400 env steps), greedy"),
        "{text}"
    );
    assert!(figure(&text, "success rate") >= trained, "{text}");
    // room has one tool, the axe, which fits its tree: every success used it first.
    assert!(
        figure(&text, "tool choice") >= figure(&text, "success rate"),
        "{text}"
    );
    assert!(
        text.contains("(first tool used is one that fits the task: axe)"),
        "{text}"
    );
    // Greedy play from one start in a deterministic world is one episode, 20 times:
    // the interval of its length is the point, and a second evaluation is the same.
    let len = figure(&text, "episode length");
    assert!(
        text.contains(&format!(
            "episode length  {len:.2} (95% CI {len:.2} to {len:.2})"
        )),
        "{text}"
    );
    let b = eval(d, &["--episodes", "20"]);
    assert_eq!(String::from_utf8_lossy(&b.stdout), text);

    // Sampled: reproducible by seed; its success and tool use are rates with intervals.
    let s1 = eval(d, &["--episodes", "50", "--sample", "--seed", "7"]);
    let s2 = eval(d, &["--episodes", "50", "--sample", "--seed", "7"]);
    assert!(s1.status.success());
    assert_eq!(s1.stdout, s2.stdout);
    let st = String::from_utf8_lossy(&s1.stdout).to_string();
    assert!(st.contains(", sample, on world 'room'"), "{st}");

    // Another world of room's shape (the tree moved): played; exp1-tree: refused.
    let other = dir.join("moved.toml");
    std::fs::write(
        &other,
        std::fs::read_to_string("worlds/room.toml")
            .unwrap()
            .replace("name = \"room\"", "name = \"room-moved\"")
            .replace("#@a..T#\n#.....#", "#@a...#\n#....T#"),
    )
    .unwrap();
    plays_one_and_refuses_exp1_tree(
        d,
        &other,
        "room-moved",
        "world 'exp1-tree' (12x8, 4 tools) does not fit the run's policy, which takes worlds of 7x5 with 1 tools",
    );

    // eval.csv: a header, the periodic rows of updates 30, 60, 90 and the last (100),
    // then one whole row per evaluation that ran (5 of them).
    let csv = std::fs::read_to_string(dir.join("eval.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 1 + 4 + 5, "{csv}");
    assert!(lines[0].starts_with("update,env_steps,world,layouts,mode,seed,episodes,success"));
    for (line, (u, steps)) in
        lines[1..5]
            .iter()
            .zip([(30, 30720), (60, 61440), (90, 92160), (100, 102400)])
    {
        assert!(
            line.starts_with(&format!("{u},{steps},room,,train-greedy,2,20,")),
            "{csv}"
        );
    }
    // The last periodic evaluation and `fulcrum eval` of the final checkpoint: the same
    // policy, the same 20 greedy episodes, the same row but for the mode.
    assert!(
        lines[5].starts_with("100,102400,room,,greedy,2,20,"),
        "{csv}"
    );
    assert_eq!(
        lines[4].replace("train-greedy", "greedy"),
        lines[5],
        "{csv}"
    );
    assert!(lines.iter().all(|l| l.split(',').count() == 22), "{csv}");
    assert!(lines[0]
        .ends_with(",tool_use,tool_use_lo,tool_use_hi,tool_choice,tool_choice_lo,tool_choice_hi"));
}

/// A policy that sees the 5 x 5 window around the agent plays a larger room with the
/// same tool; a world with other tools is refused, naming the view.
#[test]
fn a_cropped_policy_plays_a_world_of_another_size() {
    let dir = TempDir::fresh("eval-crop");
    let d = dir.to_str().unwrap();
    train_ok(&["room", "--view", "crop:2", "--steps", "10240", "--out", d]);
    let big = dir.join("big.toml");
    std::fs::write(
        &big,
        "name = \"big\"\nmax_steps = 60\nmap = \"\"\"\n###########\n#@...a...T#\n#.........#\n#.........#\n###########\n\"\"\"\n[tools]\na = \"axe\"\n[task]\nkind = \"destroy\"\nobjects = [\"tree\"]\n",
    )
    .unwrap();
    plays_one_and_refuses_exp1_tree(
        d,
        &big,
        "big",
        "world 'exp1-tree' (4 tools) does not fit the run's policy, which sees a crop:2 window of worlds with 1 tools",
    );
}
