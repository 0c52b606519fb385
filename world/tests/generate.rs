//! Generated worlds: the fewest steps to a world's task (hand-counted worlds), and the
//! sets `fulcrum experiment --worlds gen:N` trains on, every world of which is checked
//! solvable within an episode by a search of this file's own over the episode layer
//! (`World::reset`, `World::env_step`: rewards and termination as training sees them).

use std::collections::{HashSet, VecDeque};

use fulcrum_world::generate::{fewest_steps_to_task, task_doable_within, GenSet, GEN_SET_DEFAULTS};
use fulcrum_world::{parse_world, Episode, World};

fn world(map: &str) -> World {
    let text = format!(
        "name = \"hand\"\nmax_steps = 100\nmap = \"\"\"\n{map}\"\"\"\n[tools]\na = \"axe\"\n\n[task]\nkind = \"destroy\"\nobjects = [\"tree\"]\n"
    );
    parse_world(&text, "hand.toml").unwrap()
}

/// Breadth-first over whole episodes: the fewest steps after which an episode
/// terminates, searching (state, objects paid) with the episode's own step.
fn episode_search(w: &World) -> Option<u32> {
    let start = w.reset();
    let mut seen: HashSet<(fulcrum_world::State, u16)> = HashSet::new();
    seen.insert((start.state, start.rewarded));
    let mut queue = VecDeque::from([start]);
    while let Some(ep) = queue.pop_front() {
        if ep.t >= w.max_steps {
            continue;
        }
        for a in 0..w.num_actions() as u8 {
            let mut next: Episode = ep;
            let out = w.env_step(&mut next, a);
            if out.terminated {
                return Some(next.t);
            }
            if seen.insert((next.state, next.rewarded)) {
                queue.push_back(next);
            }
        }
    }
    None
}

#[test]
fn fewest_steps_by_hand() {
    // E picks the axe up, E, then apply, select the axe, E chops the tree: 5 steps.
    let w = world("#######\n#@a.T.#\n#######\n");
    assert_eq!(fewest_steps_to_task(&w, 100), Some(5));
    assert_eq!(fewest_steps_to_task(&w, 4), None);
    assert_eq!(episode_search(&w), Some(5));
    // Around a rock: S, E, E (the axe), E, N is next to nothing; the tree at (4,1) is
    // reached from (4,2) facing N: S, E (axe at 2,2), E, E, apply, select, N = 7.
    let w = world("#######\n#@.#T.#\n#.a...#\n#######\n");
    assert_eq!(fewest_steps_to_task(&w, 100), Some(7));
    assert_eq!(episode_search(&w), Some(7));
    // The tree walled in: never.
    let w = world("#######\n#@a#T##\n#######\n");
    assert_eq!(fewest_steps_to_task(&w, 100), None);
    assert_eq!(episode_search(&w), None);
}

#[test]
fn every_world_of_the_experiment_set_is_solvable_within_an_episode() {
    // The set RESULTS.md's "Worlds nobody wrote" trains on, and a harder one.
    for spec in [
        "gen:20",
        "gen:10:width=10,height=10,tools=4,objects=3,rock=0.3,seed=7",
    ] {
        let set: GenSet = spec.parse().unwrap();
        let worlds = set.worlds().unwrap();
        assert_eq!(worlds.len(), set.count);
        let mut seeds = HashSet::new();
        for w in &worlds {
            assert!(seeds.insert(w.seed), "{spec}: seed {} twice", w.seed);
            let found = episode_search(&w.world);
            assert_eq!(found, Some(w.fewest_steps), "{spec}: {}", w.world.name);
            assert!(w.fewest_steps <= w.world.max_steps);
        }
        // The seeds skipped are exactly those whose task cannot be done in an episode.
        let last = worlds.last().unwrap().seed;
        for seed in set.params.seed..=last {
            if seeds.contains(&seed) {
                continue;
            }
            let text = fulcrum_world::generate::generate(&fulcrum_world::generate::GenParams {
                seed,
                ..set.params
            })
            .unwrap();
            let w = parse_world(&text, "gen.toml").unwrap();
            assert_eq!(episode_search(&w), None, "{spec}: seed {seed} was skipped");
        }
    }
}

#[test]
fn sets_are_parsed_and_refused_in_one_sentence() {
    let d: GenSet = "gen:3".parse().unwrap();
    assert_eq!(d.count, 3);
    assert_eq!(d.params, GEN_SET_DEFAULTS);
    assert_eq!(
        d.to_string(),
        "gen:3:width=12,height=8,tools=3,objects=2,rock=0.1,seed=1"
    );
    let back: GenSet = d.to_string().parse().unwrap();
    assert_eq!(back, d);
    let k: GenSet = "gen:5:width=9,seed=40,rock=0".parse().unwrap();
    assert_eq!(
        (k.count, k.params.width, k.params.seed, k.params.rock),
        (5, 9, 40, 0.0)
    );
    for (bad, says) in [
        ("20", "does not start with gen:"),
        ("gen:0", "not a number from 1 to 10000"),
        ("gen:x", "not a number from 1 to 10000"),
        ("gen:2:depth=3", "unknown key 'depth'"),
        ("gen:2:width", "'width' is not key=value"),
        ("gen:2:width=big", "width = 'big' is not a whole number"),
        ("gen:2:objects=0", "objects >= 1"),
        ("gen:2:width=2", "between 3 and 64"),
        ("gen:2:rock=0.7", "rock fraction"),
    ] {
        let e = bad.parse::<GenSet>().unwrap_err().to_string();
        assert!(e.contains(says), "{bad}: {e}");
        assert!(e.contains(&format!("'{bad}'")), "{bad}: {e}");
        assert_eq!(e.lines().count(), 1, "{e}");
    }
    // A set no seed range can fill: a 3 x 3 room holds the agent alone.
    let e = "gen:2:width=4,height=4,tools=0,objects=1"
        .parse::<GenSet>()
        .unwrap()
        .worlds()
        .unwrap_err()
        .to_string();
    assert!(e.contains("fewer than the 2 asked for"), "{e}");
}

/// `task_doable_within` (a short plan, played with the world's own step, before the
/// whole search) says what `fewest_steps_to_task` says at every limit around each
/// world's fewest steps d: yes at d, no at d - 1; on the hand-counted worlds, on 500
/// layouts of each built-in family (two-rooms' object lies behind a door the plan
/// cannot open, so there the whole search answers) and on 300 generated worlds with
/// much rock and one to three objects, some of which cannot be done.
#[test]
fn a_short_plan_answers_as_the_whole_search_at_every_limit() {
    let mut worlds = vec![
        world("#######\n#@a.T.#\n#######\n"),
        world("#######\n#@.#T.#\n#.a...#\n#######\n"),
        world("#######\n#@a#T##\n#######\n"),
    ];
    for name in ["toolbox", "two-rooms"] {
        let f = fulcrum_world::family::load_family(name).unwrap();
        worlds.extend((0..500).map(|seed| f.layout(seed * 7919).unwrap()));
    }
    // Generated worlds as they come, solvable or not (rock walls some objects in).
    for seed in 0..300 {
        let p = fulcrum_world::generate::GenParams {
            rock: 0.35,
            objects: 1 + (seed as usize % 3),
            seed,
            ..GEN_SET_DEFAULTS
        };
        let text = fulcrum_world::generate::generate(&p).unwrap();
        worlds.push(parse_world(&text, &format!("gen-{seed}")).unwrap());
    }
    let mut planned = 0;
    let mut never = 0;
    for w in &worlds {
        let Some(d) = fewest_steps_to_task(w, 100) else {
            assert!(!task_doable_within(w, 100), "{}", w.name);
            never += 1;
            continue;
        };
        assert!(
            task_doable_within(w, d),
            "{} at its fewest steps {d}",
            w.name
        );
        assert!(
            !task_doable_within(w, d - 1),
            "{} below its fewest steps {d}",
            w.name
        );
        assert!(!task_doable_within(w, 0), "{}", w.name);
        planned += 1;
    }
    assert!(planned >= 1000, "{planned} solvable worlds");
    assert!(never >= 10, "{never} worlds whose task cannot be done");
}

/// A task a short plan does in exactly its fewest steps, counted by hand (pick the axe
/// up, walk next to the tree, apply, select, the direction): yes at 6, no at 5.
#[test]
fn a_short_plan_does_a_layouts_task_in_its_fewest_steps() {
    // The axe 2 east, the tree 2 further east: E, E (axe), E, apply, select, E = 6.
    let w = world("########\n#@.a.T.#\n########\n");
    assert_eq!(fewest_steps_to_task(&w, 100), Some(6));
    assert!(task_doable_within(&w, 6));
    assert!(!task_doable_within(&w, 5));
}
