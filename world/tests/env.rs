//! Episodes (task rewards, termination, truncation), the observation encoding, and the
//! text form of states. Expected values are derived by hand from `docs/world.md` and
//! the encoding documented at the top of `world/src/env.rs`.

use std::collections::{HashSet, VecDeque};

use fulcrum_world::generate::{generate, GenParams};
use fulcrum_world::world::ObjectKind;
use fulcrum_world::{parse_world, Mode, State, Task, World};
use proptest::prelude::*;

// Actions (`docs/world.md`).
const E: u8 = 1;
const S: u8 = 2;
const W: u8 = 3;
const APPLY: u8 = 4;
const SEL: u8 = 5;

fn world(rows: &[&str], tools: &[(&str, &str)], extra: &str) -> World {
    let mut t = format!(
        "name = \"test\"\nmap = \"\"\"\n{}\n\"\"\"\n{extra}\n[tools]\n",
        rows.join("\n")
    );
    for (l, k) in tools {
        t.push_str(&format!("{l} = \"{k}\"\n"));
    }
    parse_world(&t, "test.toml").unwrap_or_else(|e| panic!("{e}\n{t}"))
}

/// Step an episode through `actions`, returning (reward, terminated, truncated) per step.
fn play(w: &World, actions: &[u8]) -> Vec<(f32, bool, bool)> {
    let mut ep = w.reset();
    actions
        .iter()
        .map(|&a| {
            let o = w.env_step(&mut ep, a);
            (o.reward, o.terminated, o.truncated)
        })
        .collect()
}

// ---------------------------------------------------------------------------------
// Tasks.

#[test]
fn destroy_pays_once_per_listed_object_and_ends_when_all_are_destroyed() {
    // `#@ap+T=.#`: axe (2,1), pickaxe (3,1), door (4,1) not listed, tree (5,1) and wall
    // (6,1) listed.
    let w = world(
        &["#########", "#@ap+T=.#", "#########"],
        &[("a", "axe"), ("p", "pickaxe")],
        "max_steps = 100\n[task]\nkind = \"destroy\"\nobjects = [\"tree\", \"wall\"]\n",
    );
    let steps = [
        E,
        E, // pick up axe and pickaxe: agent on (3,1)
        APPLY,
        SEL,
        E, // axe destroys the door: not listed, 0
        E, // into the doorway (4,1)
        APPLY,
        SEL,
        E, // axe fells the tree: +1, the wall remains
        APPLY,
        SEL,
        E, // the axe again on the destroyed tree: no rule, 0
        E, // onto the tree's cell (5,1): 0 (the tree paid already)
        APPLY,
        SEL + 1,
        E, // pickaxe digs the wall: +1, all listed destroyed: terminal
    ];
    let out = play(&w, &steps);
    let rewards: Vec<f32> = out.iter().map(|o| o.0).collect();
    let mut want = vec![0.0; steps.len()];
    want[8] = 1.0;
    want[15] = 1.0;
    assert_eq!(rewards, want);
    let terminated: Vec<usize> = (0..out.len()).filter(|&i| out[i].1).collect();
    assert_eq!(terminated, [15]);
    assert!(out.iter().all(|o| !o.2), "no truncation within 100 steps");
}

#[test]
fn destroy_listing_an_object_twice_pays_it_once() {
    // `#@aT.#` with objects = ["tree", "tree"]: E, apply, select, E fells it: +1 once and
    // terminal (every listed object is destroyed).
    let w = world(
        &["######", "#@aT.#", "######"],
        &[("a", "axe")],
        "[task]\nkind = \"destroy\"\nobjects = [\"tree\", \"tree\"]\n",
    );
    let out = play(&w, &[E, APPLY, SEL, E]);
    assert_eq!(
        out,
        vec![
            (0.0, false, false),
            (0.0, false, false),
            (0.0, false, false),
            (1.0, true, false)
        ]
    );
}

#[test]
fn destroy_counts_a_destroyed_boulder() {
    // A pickaxe breaks the listed boulder at (3,1): +1, terminal.
    let w = world(
        &["######", "#@p0.#", "######"],
        &[("p", "pickaxe")],
        "[task]\nkind = \"destroy\"\nobjects = [\"boulder\"]\n",
    );
    let out = play(&w, &[E, APPLY, SEL, E]);
    assert_eq!(out[3], (1.0, true, false));
    assert_eq!(out[..3].iter().map(|o| o.0).sum::<f32>(), 0.0);
}

#[test]
fn push_pays_when_the_boulder_reaches_the_goal() {
    // `#@0.>#`: the first E pushes the boulder to (3,1) (0), the second onto the goal
    // (4,1): +1 and terminal.
    let w = world(
        &["######", "#@0.>#", "######"],
        &[],
        "[task]\nkind = \"push\"\nobject = \"boulder\"\n",
    );
    assert_eq!(w.task, Task::Push(0));
    assert_eq!(
        play(&w, &[E, E]),
        vec![(0.0, false, false), (1.0, true, false)]
    );
}

#[test]
fn push_pays_only_for_the_named_boulder() {
    // #######
    // #@0.>.#   boulder#0 (2,1), goal (4,1)
    // #.0.>.#   boulder#1 (2,2), goal (4,2); the task names boulder#1
    // #######
    let w = world(
        &["#######", "#@0.>.#", "#.0.>.#", "#######"],
        &[],
        "[task]\nkind = \"push\"\nobject = \"boulder#1\"\n",
    );
    // E, E puts boulder#0 on a goal: nothing. W, W, S, E, E: boulder#1 onto (4,2): +1.
    let out = play(&w, &[E, E, W, W, S, E, E]);
    let rewards: Vec<f32> = out.iter().map(|o| o.0).collect();
    assert_eq!(rewards, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
    assert!(out[..6].iter().all(|o| !o.1));
    assert!(out[6].1);
}

#[test]
fn no_task_no_reward() {
    let w = world(&["######", "#@aT.#", "######"], &[("a", "axe")], "");
    assert_eq!(w.task, Task::None);
    for (r, term, _) in play(&w, &[E, APPLY, SEL, E, E, E]) {
        assert_eq!((r, term), (0.0, false));
    }
}

#[test]
fn truncation_at_max_steps() {
    // max_steps = 3, no task: steps 1 and 2 run on, step 3 is truncated, not terminated.
    let w = world(&["#####", "#@..#", "#####"], &[], "max_steps = 3\n");
    assert_eq!(w.max_steps, 3);
    let out = play(&w, &[E, W, E]);
    assert_eq!(
        out,
        vec![(0.0, false, false), (0.0, false, false), (0.0, false, true)]
    );
    // A reset starts again at t = 0 from the initial state.
    let ep = w.reset();
    assert_eq!((ep.t, ep.state, ep.rewarded), (0, w.initial, 0));
}

#[test]
fn truncation_with_a_task_that_is_not_done() {
    // max_steps = 2 with a tree to fell: the task is not done, the episode is truncated.
    let w = world(
        &["######", "#@aT.#", "######"],
        &[("a", "axe")],
        "max_steps = 2\n[task]\nkind = \"destroy\"\nobjects = [\"tree\"]\n",
    );
    assert_eq!(
        play(&w, &[E, APPLY]),
        vec![(0.0, false, false), (0.0, false, true)]
    );
}

#[test]
fn terminal_on_the_last_step_is_terminated_not_truncated() {
    // max_steps = 4 and the tree falls on step 4: the episode ends by the task.
    let w = world(
        &["######", "#@aT.#", "######"],
        &[("a", "axe")],
        "max_steps = 4\n[task]\nkind = \"destroy\"\nobjects = [\"tree\"]\n",
    );
    assert_eq!(play(&w, &[E, APPLY, SEL, E])[3], (1.0, true, false));
}

// ---------------------------------------------------------------------------------
// Observations.

// Glyph ids of env.rs: 0 rock, 1 floor, 2 goal, 3 agent, 4 tree, 5 wall, 6 closed door,
// 7 open door, 8 boulder, 9 + k tool k lying.
const ROCK: u8 = 0;
const FLOOR: u8 = 1;
const GOAL: u8 = 2;
const AGENT: u8 = 3;
const TREE: u8 = 4;
const WALL: u8 = 5;
const CLOSED: u8 = 6;
const OPEN: u8 = 7;
const BOULDER: u8 = 8;
const TOOL0: u8 = 9;

/// #######
/// #@a>T+#    agent (1,1), axe (2,1), goal (3,1), tree (4,1), door (5,1)
/// #.0=b.#    boulder (2,2), wall (3,2), key (4,2)
/// #######
/// [tools]: b = key is tool 0, a = axe is tool 1. Objects: tree 0, door 1, boulder 2,
/// wall 3.
fn obs_world() -> World {
    world(
        &["#######", "#@a>T+#", "#.0=b.#", "#######"],
        &[("b", "key"), ("a", "axe")],
        "",
    )
}

fn observe(w: &World, s: &State) -> (Vec<u8>, Vec<u8>) {
    let spec = w.obs_spec();
    // Filled with junk first: observe must write every entry.
    let mut g = vec![0xEE; spec.cells()];
    let mut f = vec![0xEE; spec.flags];
    w.observe(s, &mut g, &mut f);
    (g, f)
}

#[test]
fn observation_shapes() {
    let spec = obs_world().obs_spec();
    // 7 x 4 cells, 9 + 2 glyph ids, 2 * 2 + 2 flags.
    assert_eq!(
        (
            spec.width,
            spec.height,
            spec.glyphs,
            spec.flags,
            spec.cells()
        ),
        (7, 4, 11, 6, 28)
    );
}

#[test]
fn observation_of_the_initial_state() {
    let w = obs_world();
    let (g, f) = observe(&w, &w.initial);
    let r = ROCK;
    #[rustfmt::skip]
    let want = [
        r, r, r, r, r, r, r,
        r, AGENT, TOOL0 + 1, GOAL, TREE, CLOSED, r,
        r, FLOOR, BOULDER, WALL, TOOL0, FLOOR, r,
        r, r, r, r, r, r, r,
    ];
    assert_eq!(g, want);
    // Nothing held; mode normal at index n = 2.
    assert_eq!(f, [0, 0, 1, 0, 0, 0]);
}

#[test]
fn observation_of_a_hand_made_state() {
    let w = obs_world();
    // Agent in the open doorway (5,1), key held, tree and wall destroyed, the boulder on
    // the goal (3,1) = slot 1 * 7 + 3 = 10, mode choosing-direction(key = tool 0) = 2.
    let s = hand_made();
    let (g, f) = observe(&w, &s);
    let r = ROCK;
    #[rustfmt::skip]
    let want = [
        r, r, r, r, r, r, r,
        // the axe still lies (tool 1); the boulder hides the goal; the felled tree is
        // floor; the agent hides the open door
        r, FLOOR, TOOL0 + 1, BOULDER, FLOOR, AGENT, r,
        // the boulder's old cell, the dug wall and the key's cell (held) are floor
        r, FLOOR, FLOOR, FLOOR, FLOOR, FLOOR, r,
        r, r, r, r, r, r, r,
    ];
    assert_eq!(g, want);
    // held: key (0) yes, axe (1) no; mode: choosing-direction(0) at n + 2 + 0 = 4.
    assert_eq!(f, [1, 0, 0, 0, 1, 0]);

    // The door open without the agent on it; a destroyed boulder shows floor.
    let mut s2 = s;
    s2.x = 1;
    s2.y = 2;
    s2.objects[2] = u16::MAX;
    s2.mode = 1; // choosing-tool
    let (g, f) = observe(&w, &s2);
    assert_eq!(&g[7..14], &[r, FLOOR, TOOL0 + 1, GOAL, FLOOR, OPEN, r]);
    assert_eq!(&g[14..21], &[r, AGENT, FLOOR, FLOOR, FLOOR, FLOOR, r]);
    assert_eq!(f, [1, 0, 0, 1, 0, 0]);

    // Both held, choosing-direction(axe = tool 1) at n + 2 + 1 = 5.
    let mut s3 = s2;
    s3.inventory = 0b11;
    s3.mode = 3;
    let (g, f) = observe(&w, &s3);
    assert_eq!(g[9], FLOOR, "the axe's cell once it is held");
    assert_eq!(f, [1, 1, 0, 0, 0, 1]);
}

/// Agent (5,1) in the open doorway, key held, tree and wall destroyed, boulder on the
/// goal (3,1), mode choosing-direction(key), written field by field (state.rs layout).
fn hand_made() -> State {
    let w = obs_world();
    let mut s = w.initial;
    s.x = 5;
    s.y = 1;
    s.inventory = 0b01;
    s.mode = 2;
    s.objects[0] = 2; // tree destroyed
    s.objects[1] = 1; // door open
    s.objects[2] = 10; // boulder on (3,1)
    s.objects[3] = 2; // wall destroyed
    s
}

// ---------------------------------------------------------------------------------
// The text form of states.

#[test]
fn parse_state_reads_a_description() {
    let w = obs_world();
    let s = w
        .parse_state("agent=5,1 holding=key mode=choosing-direction:key tree=destroyed door=open boulder=3,1 wall=destroyed")
        .unwrap();
    assert_eq!(s, hand_made());
    assert_eq!(s.mode(), Mode::ChoosingDirection(0));
    // Tools by letter; objects not named keep their initial state; mode defaults to
    // normal.
    let s = w.parse_state("agent=1,2 holding=b,a").unwrap();
    assert_eq!(
        (s.x, s.y, s.inventory, s.mode()),
        (1, 2, 0b11, Mode::Normal)
    );
    assert_eq!(s.objects, w.initial.objects);
    let s = w.parse_state("agent=1,2").unwrap();
    assert_eq!(s.inventory, 0);
}

#[test]
fn describe_names_every_part() {
    let w = obs_world();
    let d = w.describe(&hand_made());
    for part in [
        "agent=5,1",
        "holding=key",
        "mode=choosing-direction:key",
        "tree=destroyed",
        "door=open",
        "boulder=3,1",
        "wall=destroyed",
    ] {
        assert!(
            d.split_whitespace().any(|p| p == part),
            "{part} missing from {d}"
        );
    }
}

/// All states reachable from the initial one, by breadth-first search.
fn reachable(w: &World) -> Vec<State> {
    let mut seen = HashSet::from([w.initial]);
    let mut queue = VecDeque::from([w.initial]);
    let mut all = vec![];
    while let Some(s) = queue.pop_front() {
        all.push(s);
        for a in 0..w.num_actions() as u8 {
            let n = w.step(&s, a);
            if seen.insert(n) {
                queue.push_back(n);
            }
        }
    }
    all
}

#[test]
fn describe_and_parse_state_round_trip_on_every_reachable_state() {
    // A world where boulders and doors get destroyed (wand, pickaxe) as well.
    let breaker = world(
        &["#######", "#@w.0.#", "#.p+.>#", "#######"],
        &[("w", "wand"), ("p", "pickaxe")],
        "",
    );
    for w in [
        obs_world(),
        fulcrum_world::load_world("exp3").unwrap(),
        breaker,
    ] {
        let all = reachable(&w);
        assert!(all.len() > 100, "{}: {}", w.name, all.len());
        let modes: HashSet<u8> = all.iter().map(|s| s.mode).collect();
        assert!(modes.len() >= 3, "prompt states are covered");
        let gone = all.iter().filter(|s| s.objects.contains(&u16::MAX)).count();
        assert_eq!(
            gone > 0,
            w.name == "test" && w.tools[0].kind == "wand",
            "{}",
            w.name
        );
        for s in all {
            let d = w.describe(&s);
            assert_eq!(w.parse_state(&d), Ok(s), "{d}");
        }
    }
}

fn refused(w: &World, text: &str, words: &[&str]) {
    match w.parse_state(text) {
        Ok(s) => panic!("{text:?} was accepted as {s:?}"),
        Err(e) => {
            for word in words {
                assert!(
                    e.0.contains(word),
                    "{text:?}: reason {:?} lacks {word:?}",
                    e.0
                );
            }
        }
    }
}

#[test]
fn parse_state_refuses_impossible_states_with_a_reason() {
    let w = obs_world();
    // The agent in rock: (0,0) is the border.
    refused(&w, "agent=0,0", &["rock"]);
    // The agent on a lying tool: the key lies on (4,2) unless held.
    refused(&w, "agent=4,2", &["key"]);
    assert!(w.parse_state("agent=4,2 holding=key").is_ok());
    // The agent on an intact tree or a closed door.
    refused(&w, "agent=4,1", &["tree"]);
    refused(&w, "agent=5,1", &["door", "closed"]);
    assert!(w.parse_state("agent=4,1 tree=destroyed").is_ok());
    // The agent on the boulder.
    refused(&w, "agent=2,2", &["boulder"]);
    // Choosing a direction for a tool not held; choosing a tool with none held.
    refused(
        &w,
        "agent=1,1 holding=key mode=choosing-direction:axe",
        &["axe", "held"],
    );
    refused(&w, "agent=1,1 mode=choosing-tool", &["held"]);
    // A boulder in rock or on an intact wall.
    refused(&w, "agent=1,1 boulder=0,2", &["boulder", "rock"]);
    refused(&w, "agent=1,1 boulder=3,2", &["boulder", "wall"]);
    // Form: outside the map, unknown names and values, no agent.
    refused(&w, "agent=7,1", &["agent=7,1"]);
    refused(&w, "agent=1,1 dragon=3", &["dragon"]);
    refused(&w, "agent=1,1 holding=wand", &["wand"]);
    refused(&w, "agent=1,1 door=ajar", &["door=ajar"]);
    refused(&w, "agent=1,1 mode=sleeping", &["mode=sleeping"]);
    refused(&w, "holding=key", &["agent"]);
    refused(&w, "agent", &["key=value"]);
}

#[test]
fn parse_state_refuses_two_boulders_on_one_cell() {
    // `#@0.0.#`: boulder#0 (2,1), boulder#1 (4,1).
    let w = world(&["#######", "#@0.0.#", "#######"], &[], "");
    refused(
        &w,
        "agent=1,1 boulder#0=3,1 boulder#1=3,1",
        &["two boulders", "3,1"],
    );
    let s = w
        .parse_state("agent=1,1 boulder#0=3,1 boulder#1=destroyed")
        .unwrap();
    assert_eq!((s.objects[0], s.objects[1]), (3 + 7, u16::MAX));
}

// ---------------------------------------------------------------------------------
// Random walks in generated worlds: every state reached describes itself, and its
// observation agrees with it.

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn random_walks_keep_states_consistent(
        width in 3usize..10,
        height in 3usize..10,
        tools in 0usize..7,
        objects in 0usize..7,
        rock in 0.0f64..0.3,
        seed in any::<u64>(),
        actions in prop::collection::vec(any::<u8>(), 0..150),
    ) {
        let p = GenParams { width, height, tools, objects, rock, seed };
        let Ok(text) = generate(&p) else { return Ok(()) };
        let w = parse_world(&text, "gen.toml").unwrap();
        let listed = match &w.task {
            Task::Destroy(v) => v.len(),
            _ => 0,
        };
        let mut ep = w.reset();
        let mut total = 0.0;
        let mut ended = false;
        for a in actions {
            let a = a % w.num_actions() as u8;
            let o = w.env_step(&mut ep, a);
            let s = ep.state;
            prop_assert_eq!(w.parse_state(&w.describe(&s)), Ok(s));
            let (g, f) = {
                let spec = w.obs_spec();
                let mut g = vec![0xEE; spec.cells()];
                let mut f = vec![0xEE; spec.flags];
                w.observe(&s, &mut g, &mut f);
                (g, f)
            };
            let count = |id: u8| g.iter().filter(|&&x| x == id).count();
            prop_assert_eq!(count(AGENT), 1);
            prop_assert_eq!(g[s.y as usize * width + s.x as usize], AGENT);
            let boulders = w
                .objects
                .iter()
                .enumerate()
                .filter(|(i, o)| o.kind == ObjectKind::Boulder && s.objects[*i] != u16::MAX)
                .count();
            prop_assert_eq!(count(BOULDER), boulders);
            for (k, &held) in f.iter().enumerate().take(tools) {
                prop_assert_eq!(count(TOOL0 + k as u8), usize::from(!s.holds(k)));
                prop_assert_eq!(held, u8::from(s.holds(k)));
            }
            prop_assert!(g.iter().all(|&x| (x as usize) < w.obs_spec().glyphs));
            prop_assert_eq!(f[tools..].iter().filter(|&&x| x == 1).count(), 1, "one mode");
            prop_assert!(f.iter().all(|&x| x <= 1));
            // A destroy task never pays more than once per listed object, and is
            // terminal exactly when it has paid for all of them.
            if !ended {
                total += o.reward;
                prop_assert!(total <= listed as f32);
                prop_assert_eq!(o.terminated, listed > 0 && total == listed as f32);
                ended = o.terminated || o.truncated;
            }
        }
    }
}

/// The incremental observation equals the full one after every step of long random
/// walks, in every built-in world and in generated worlds with boulders, doors and
/// bolts.
#[test]
fn incremental_observation_equals_the_full_one() {
    use fulcrum_world::generate::{generate, GenParams};
    use rand::{Rng, SeedableRng};
    let mut worlds: Vec<fulcrum_world::World> = fulcrum_world::builtin::NAMES
        .iter()
        .map(|n| fulcrum_world::load_world(n).unwrap())
        .collect();
    for seed in 0..6 {
        let p = GenParams {
            width: 7,
            height: 6,
            tools: 4,
            objects: 4,
            rock: 0.1,
            seed,
        };
        worlds.push(fulcrum_world::parse_world(&generate(&p).unwrap(), "gen").unwrap());
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    for w in &worlds {
        let spec = w.obs_spec();
        let (mut g, mut f) = (vec![0u8; spec.cells()], vec![0u8; spec.flags]);
        let (mut g2, mut f2) = (g.clone(), f.clone());
        let mut ep = w.reset();
        w.observe(&ep.state, &mut g, &mut f);
        for step in 0..20_000 {
            let prev = ep.state;
            let out = w.env_step(&mut ep, rng.random_range(0..w.num_actions() as u8));
            w.observe_update(&prev, &ep.state, &mut g, &mut f);
            w.observe(&ep.state, &mut g2, &mut f2);
            assert_eq!(
                (&g, &f),
                (&g2, &f2),
                "{} step {step}: {}",
                w.name,
                w.describe(&ep.state)
            );
            if out.terminated || out.truncated {
                let prev = ep.state;
                ep = w.reset();
                // A reset is a jump, not a step: still only the changed slots move.
                w.observe_update(&prev, &ep.state, &mut g, &mut f);
                w.observe(&ep.state, &mut g2, &mut f2);
                assert_eq!((&g, &f), (&g2, &f2), "{} after a reset", w.name);
            }
        }
    }
}
