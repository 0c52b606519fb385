//! Stochastic worlds (`docs/world.md`, "Stochastic worlds"): `[dynamics]` and a rule's
//! `p` in world files and their errors at file:line:col, the exact transition
//! distribution, sampling against it, and deterministic worlds left exactly as they were.
//!
//! Lines and columns are counted by hand from the texts below, one line per string.

use fulcrum_world::generate::{generate, GenParams};
use fulcrum_world::{load_world, parse_world, State, World, WorldError, EAST, NORTH, SOUTH, WEST};

const FILE: &str = "test.toml";

fn lines(ls: &[&str]) -> String {
    let mut s = ls.join("\n");
    s.push('\n');
    s
}

/// Parse, expecting an error placed at (line, col) whose message contains every word.
fn expect_at(text: &str, line: usize, col: usize, words: &[&str]) {
    match parse_world(text, FILE) {
        Ok(_) => panic!("expected an error at {line}:{col}, the world loaded:\n{text}"),
        Err(e) => {
            let shown = e.to_string();
            match &e {
                WorldError::At {
                    line: l, col: c, ..
                } => {
                    assert_eq!((*l, *c), (line, col), "{shown}\n{text}");
                    assert!(shown.starts_with(&format!("{FILE}:{line}:{col}: ")));
                    assert_eq!(shown.lines().count(), 1, "{shown}");
                    for w in words {
                        assert!(shown.contains(w), "message lacks {w:?}: {shown}");
                    }
                }
                other => panic!("expected a placed error, got {other:?}"),
            }
        }
    }
}

/// A 5 x 3 room with the axe beside the agent and a tree, and extra lines at the end
/// (line 11 on).
fn room(extra: &[&str]) -> String {
    let mut ls = vec![
        "name = \"t\"", // 1
        "map = \"\"\"", // 2
        "#######",      // 3
        "#@a..T#",      // 4
        "#.....#",      // 5
        "#######",      // 6
        "\"\"\"",       // 7
        "",             // 8
        "[tools]",      // 9
        "a = \"axe\"",  // 10
    ];
    ls.extend_from_slice(extra);
    lines(&ls)
}

const AXE_TREE: [&str; 6] = [
    "[[rules]]",          // 11
    "tool = \"axe\"",     // 12
    "target = \"tree\"",  // 13
    "from = \"intact\"",  // 14
    "to = \"destroyed\"", // 15
    "range = 1",          // 16
];

#[test]
fn dynamics_and_p_are_read() {
    let w = parse_world(&room(&["[dynamics]", "slip = 0.25"]), FILE).unwrap();
    assert_eq!(w.slip, 0.25);
    assert!(w.is_stochastic());
    let mut extra = AXE_TREE.to_vec();
    extra.push("p = 0.5");
    let w = parse_world(&room(&extra), FILE).unwrap();
    assert!(w.is_stochastic());
    assert_eq!(w.slip, 0.0);
    // It set the default rule's p and added no rule.
    assert_eq!(w.rules.len(), fulcrum_world::world::default_rules().len());
    let r = w
        .rules
        .iter()
        .find(|r| r.tool == "axe" && r.target.name() == "tree");
    assert_eq!(r.unwrap().p, 0.5);
    // slip = 0 (an integer) and p = 1 written out: deterministic.
    let mut extra = AXE_TREE.to_vec();
    extra.extend(["p = 1", "[dynamics]", "slip = 0"]);
    let w = parse_world(&room(&extra), FILE).unwrap();
    assert!(!w.is_stochastic());
    // A p on a rule of a kind no tool of the world has is refused as before; a p below 1
    // on a default rule of a tool not in play cannot be given, so chance needs a tool.
    assert!(!load_world("exp1-tree").unwrap().is_stochastic());
    assert!(load_world("exp1-tree-slip").unwrap().is_stochastic());
    assert!(load_world("exp2-slip").unwrap().is_stochastic());
}

#[test]
fn bad_dynamics_and_p_are_placed() {
    // `slip = 1` on line 12: the value at column 8.
    expect_at(
        &room(&["[dynamics]", "slip = 1"]),
        12,
        8,
        &["slip = 1", "below 1"],
    );
    expect_at(
        &room(&["[dynamics]", "slip = -0.1"]),
        12,
        8,
        &["slip = -0.1"],
    );
    expect_at(&room(&["[dynamics]", "slip = \"a lot\""]), 12, 8, &["slip"]);
    // An unknown key in [dynamics]: `wind` on line 12, column 1.
    expect_at(&room(&["[dynamics]", "wind = 0.1"]), 12, 1, &["wind"]);
    // p = 0 and p = 1.5 on line 17, the value at column 5.
    for bad in ["p = 0", "p = 1.5", "p = -1"] {
        let mut extra = AXE_TREE.to_vec();
        extra.push(bad);
        expect_at(&room(&extra), 17, 5, &[bad, "above 0 and at most 1"]);
    }
    // An entry that sets a default rule's p with another range: at the range (16:9).
    let mut extra = AXE_TREE.to_vec();
    extra[5] = "range = \"bolt\"";
    extra.push("p = 0.5");
    expect_at(&room(&extra), 16, 9, &["default rule", "range = 1"]);
}

/// The state with the agent at (x, y) and everything else as in `s`.
fn at(s: &State, x: u8, y: u8) -> State {
    let mut t = *s;
    t.x = x;
    t.y = y;
    t
}

#[test]
fn slip_outcomes_are_the_four_directions() {
    let w = parse_world(&room(&["[dynamics]", "slip = 0.3"]), FILE).unwrap();
    let s0 = at(&w.initial, 3, 2);
    let mut out = Vec::new();
    // Open floor on three sides, the wall to the south: N, E, W move, S stays.
    w.outcomes(&s0, EAST, &mut out);
    let p = |x: u8, y: u8| out.iter().find(|(t, _)| (t.x, t.y) == (x, y)).map(|o| o.1);
    assert_eq!(out.len(), 4);
    assert!((p(4, 2).unwrap() - 0.7).abs() < 1e-15);
    assert!((p(3, 1).unwrap() - 0.1).abs() < 1e-15);
    assert!((p(2, 2).unwrap() - 0.1).abs() < 1e-15);
    assert!((p(3, 2).unwrap() - 0.1).abs() < 1e-15);
    // In the corner (1, 2): W and S are walls, so both stay: merged into one outcome.
    w.outcomes(&at(&w.initial, 1, 2), NORTH, &mut out);
    assert_eq!(out.len(), 3);
    let stay = out.iter().find(|(t, _)| (t.x, t.y) == (1, 2)).unwrap().1;
    assert!((stay - 0.2).abs() < 1e-15);
    // A slip onto the axe picks it up, as a move would.
    w.outcomes(&at(&w.initial, 2, 2), WEST, &mut out);
    let up = out.iter().find(|(t, _)| (t.x, t.y) == (2, 1)).unwrap();
    assert!(up.0.holds(0) && (up.1 - 0.1).abs() < 1e-15);
    // Nothing else slips: apply and selects have one outcome.
    for a in [4u8, 5] {
        w.outcomes(&s0, a, &mut out);
        assert_eq!(out, vec![(w.step(&s0, a), 1.0)]);
    }
}

#[test]
fn a_rule_acts_with_its_probability() {
    let mut extra = AXE_TREE.to_vec();
    extra.push("p = 0.8");
    let w = parse_world(&room(&extra), FILE).unwrap();
    // Holding the axe beside the tree, at the direction prompt.
    let mut s = at(&w.initial, 4, 1);
    s.inventory = 1;
    let s = w.step(&w.step(&s, 4), 5);
    assert_eq!(s.mode, 2);
    let mut out = Vec::new();
    w.outcomes(&s, EAST, &mut out);
    assert_eq!(out.len(), 2);
    assert_eq!(out[0].0.objects[0], 2, "destroyed first");
    assert!((out[0].1 - 0.8).abs() < 1e-15 && (out[1].1 - 0.2).abs() < 1e-12);
    assert_eq!(out[1].0.objects[0], 0, "or intact");
    assert!(
        out.iter().all(|(t, _)| t.mode == 0),
        "back to normal mode either way"
    );
    // A direction where no rule acts: one outcome.
    w.outcomes(&s, SOUTH, &mut out);
    assert_eq!(out.len(), 1);
    // step is the intended outcome: the rule acts.
    assert_eq!(w.step(&s, EAST), out_first(&w, &s, EAST));
}

fn out_first(w: &World, s: &State, a: u8) -> State {
    let mut out = Vec::new();
    w.outcomes(s, a, &mut out);
    out[0].0
}

/// SplitMix64: the test's own generator, with a fixed seed.
struct SplitMix(u64);
impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
}

/// Pearson's chi-square of `n` draws of `step_sampled` against `outcomes`.
fn chi_square(w: &World, s: &State, a: u8, n: usize, seed: u64) -> (f64, usize) {
    let mut out = Vec::new();
    w.outcomes(s, a, &mut out);
    let mut counts = vec![0usize; out.len()];
    let mut rng = SplitMix(seed);
    for _ in 0..n {
        let t = w.step_sampled(s, a, rng.next());
        let k = out
            .iter()
            .position(|(o, _)| *o == t)
            .expect("a listed outcome");
        counts[k] += 1;
    }
    let chi = counts
        .iter()
        .zip(&out)
        .map(|(&c, (_, p))| {
            let e = p * n as f64;
            (c as f64 - e).powi(2) / e
        })
        .sum();
    (chi, out.len() - 1)
}

// 10^5 draws, level 0.001: the critical values of chi-square are 16.266 with 3 degrees
// of freedom and 10.828 with 1 (tables). A sampler that ignored slip, or drew the other
// directions unevenly (say 0.1/0.05/0.15), would be off by thousands.
#[test]
fn sampling_matches_the_distribution() {
    let w = load_world("exp1-tree-slip").unwrap();
    let s = at(&w.initial, 3, 4);
    let (chi, df) = chi_square(&w, &s, EAST, 100_000, 7);
    assert_eq!(df, 3);
    assert!(chi < 16.266, "chi-square {chi}");
    // The axe beside the tree at the direction prompt: p = 0.8.
    let mut s = at(&w.initial, 8, 2);
    s.inventory = 1;
    let s = w.step(&w.step(&s, 4), 5);
    let (chi, df) = chi_square(&w, &s, EAST, 100_000, 11);
    assert_eq!(df, 1);
    assert!(chi < 10.828, "chi-square {chi}");
}

fn generated(seed: u64) -> World {
    let text = generate(&GenParams {
        width: 9,
        height: 7,
        tools: 3,
        objects: 3,
        rock: 0.1,
        seed,
    })
    .unwrap();
    parse_world(&text, "generated").unwrap()
}

// Deterministic worlds: one outcome, the sampler equals step whatever the draw, and an
// episode stepped with draws never asks for one (so runs consume no draws).
#[test]
fn deterministic_worlds_take_no_draws() {
    let mut worlds: Vec<World> = fulcrum_world::builtin::NAMES
        .iter()
        .map(|n| load_world(n).unwrap())
        .collect();
    worlds.extend((0..4).map(generated));
    let mut out = Vec::new();
    for w in &worlds {
        assert!(!w.is_stochastic(), "{}", w.name);
        let mut rng = SplitMix(3);
        let mut a_ep = w.reset();
        let mut b_ep = w.reset();
        for _ in 0..2000 {
            let a = (rng.next() % w.num_actions() as u64) as u8;
            let s = a_ep.state;
            w.outcomes(&s, a, &mut out);
            assert_eq!(out, vec![(w.step(&s, a), 1.0)]);
            assert_eq!(w.step_sampled(&s, a, rng.next()), w.step(&s, a));
            let oa = w.env_step(&mut a_ep, a);
            let ob = w.env_step_drawn(&mut b_ep, a, || panic!("a draw in a deterministic world"));
            assert_eq!((oa, a_ep), (ob, b_ep));
            if oa.terminated || oa.truncated {
                a_ep = w.reset();
                b_ep = w.reset();
            }
        }
    }
}

// A stochastic world's episode takes one draw per step, and its states stay in what
// `outcomes` allows.
#[test]
fn stochastic_episodes_take_one_draw_per_step() {
    let w = load_world("exp2-slip").unwrap();
    let mut rng = SplitMix(5);
    let mut ep = w.reset();
    let mut draws = 0;
    let mut out = Vec::new();
    for _ in 0..5000 {
        let a = (rng.next() % w.num_actions() as u64) as u8;
        let before = ep.state;
        let o = w.env_step_drawn(&mut ep, a, || {
            draws += 1;
            rng.next()
        });
        w.outcomes(&before, a, &mut out);
        assert!(out.iter().any(|(t, p)| *t == ep.state && *p > 0.0));
        if o.terminated || o.truncated {
            ep = w.reset();
        }
    }
    assert_eq!(draws, 5000);
}

#[test]
fn outcome_probabilities_sum_to_one() {
    for name in fulcrum_world::builtin::STOCHASTIC {
        let w = load_world(name).unwrap();
        let mut rng = SplitMix(9);
        let mut s = w.initial;
        let mut out = Vec::new();
        for _ in 0..3000 {
            let a = (rng.next() % w.num_actions() as u64) as u8;
            w.outcomes(&s, a, &mut out);
            let total: f64 = out.iter().map(|o| o.1).sum();
            assert!((total - 1.0).abs() < 1e-12, "{name}: {total}");
            for (i, (t, _)) in out.iter().enumerate() {
                assert!(!out[..i].iter().any(|(u, _)| u == t), "merged");
            }
            s = w.step_sampled(&s, a, rng.next());
        }
    }
}
