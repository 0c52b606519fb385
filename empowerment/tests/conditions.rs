//! Objects by their conditions only (`conditions:boulder`, what the potential forms count
//! of a destroy task's objects by default).
//!
//! A boulder's condition has two values, intact and destroyed, and destroying is for
//! good; in a deterministic world the conditions reachable from a state with an intact
//! boulder in h steps are {intact} (walk about) and, when some sequence of h actions
//! destroys it, {destroyed} too. So E^h(s) = 1 bit exactly when the fewest steps d(s)
//! to a destroyed boulder are at most h, and 0 otherwise (0 too once it is destroyed),
//! and the potential Phi(s) = sum over h = 1..H of E^h(s) = max(0, H + 1 - d(s)). The
//! reference d(s) is a breadth-first search with the world's own step function over
//! every action, independent of the engine's state space and set propagation.

use std::collections::{HashSet, VecDeque};

use fulcrum_empowerment::request::{object_set, potential_objects};
use fulcrum_empowerment::{Engine, Limits, Method, ToolSel};
use fulcrum_world::generate::GenSet;
use fulcrum_world::{ObjectKind, ObjectSet, State, Task, World, BOULDER_DESTROYED};

/// Fewest actions from `s` to a state where object `b` is destroyed, if at most `hmax`.
fn steps_to_destroy(w: &World, s: &State, b: usize, hmax: u32) -> Option<u32> {
    if s.objects[b] == BOULDER_DESTROYED {
        return Some(0);
    }
    let mut seen = HashSet::from([*s]);
    let mut frontier = VecDeque::from([(*s, 0u32)]);
    while let Some((t, d)) = frontier.pop_front() {
        if d == hmax {
            continue;
        }
        for a in 0..w.num_actions() as u8 {
            let n = w.step(&t, a);
            if n.objects[b] == BOULDER_DESTROYED {
                return Some(d + 1);
            }
            if seen.insert(n) {
                frontier.push_back((n, d + 1));
            }
        }
    }
    None
}

/// Generated worlds whose task is to destroy a boulder, with its index.
fn boulder_tasks() -> Vec<(World, usize)> {
    let set: GenSet = "gen:20:seed=2001".parse().unwrap();
    let mut out = Vec::new();
    for g in set.worlds().unwrap() {
        let w = g.world;
        let Task::Destroy(list) = &w.task else {
            continue;
        };
        if let Some(&b) = list
            .iter()
            .find(|&&i| w.objects[i].kind == ObjectKind::Boulder)
        {
            out.push((w, b));
        }
    }
    out
}

#[test]
fn a_boulder_by_its_condition_has_one_bit_where_it_can_be_destroyed_in_time() {
    const H: u32 = 8;
    let worlds = boulder_tasks();
    assert!(worlds.len() >= 3, "only {} boulder tasks", worlds.len());
    let (mut checked, mut movable) = (0, 0);
    let (mut ones, mut zeros) = (0, 0);
    for (w, b) in &worlds {
        let engine = Engine::new(w, Limits::default()).unwrap();
        let full = ObjectSet::Objects(vec![*b]);
        let cond = object_set(w, &format!("conditions:{}", w.objects[*b].name)).unwrap();
        assert_eq!(cond, full.conditions(w));
        // Where the boulder moves, by its cell it has more than two states within reach.
        let e_full = engine.values(ToolSel::All, &full, H, Method::Dp).unwrap();
        movable += e_full.iter().any(|&v| v > 1.5) as usize;
        let per_h: Vec<Vec<f64>> = (1..=H)
            .map(|h| engine.values(ToolSel::All, &cond, h, Method::Dp).unwrap())
            .collect();
        let phi = engine
            .lookup_values(ToolSel::All, &cond, H, 3, true)
            .unwrap();
        // Every 97th state (the space is 10^4 to 10^5 states; the searches are the cost).
        for id in (0..engine.space.len()).step_by(97) {
            let s = engine.space.state(id as u32);
            let d = steps_to_destroy(w, s, *b, H);
            let destroyed = s.objects[*b] == BOULDER_DESTROYED;
            for h in 1..=H {
                let want = if !destroyed && d.is_some_and(|d| d <= h) {
                    1.0
                } else {
                    0.0
                };
                assert_eq!(
                    per_h[h as usize - 1][id],
                    want,
                    "{} state {id} ({}), h = {h}: d = {d:?}",
                    w.name,
                    w.describe(s)
                );
            }
            let want_phi = match d {
                Some(d) if !destroyed => (H + 1 - d) as f32,
                _ => 0.0,
            };
            assert_eq!(phi[id], want_phi, "{} state {id}: Phi", w.name);
            if want_phi > 0.0 {
                ones += 1;
            } else {
                zeros += 1;
            }
            checked += 1;
        }
    }
    assert!(movable >= 2, "{movable} of the boulders can be pushed");
    assert!(checked > 1000, "{checked} states checked");
    assert!(
        ones > 50 && zeros > 50,
        "{ones} states in reach, {zeros} not"
    );
}

#[test]
fn the_potential_counts_a_destroy_tasks_objects_by_their_conditions_unless_named() {
    let worlds = boulder_tasks();
    let (w, b) = &worlds[0];
    let own = w.empowerment.objects.clone().unwrap();
    assert!(own.indices().contains(b));
    // A run of a potential form with potential_objects = "task", the objects not named.
    assert_eq!(potential_objects(w, None, true).unwrap(), own.conditions(w));
    // Named objects are counted as named; "full" counts the full state.
    let name = w.objects[*b].name.clone();
    assert_eq!(
        potential_objects(w, Some(&name), true).unwrap(),
        ObjectSet::Objects(vec![*b])
    );
    assert_eq!(potential_objects(w, None, false).unwrap(), own);
    // The service's requests and DESCRIBE carry the set as a mask, conditions and all.
    use fulcrum_empowerment::service::{mask_set, object_mask};
    let cond = own.conditions(w);
    assert_ne!(object_mask(&cond), object_mask(&own));
    assert_eq!(mask_set(w, object_mask(&cond)), Some(cond));
    assert_eq!(mask_set(w, object_mask(&own)), Some(own.clone()));
    // A tree has no cell: its set is left as it is.
    let tree = fulcrum_world::load_world("exp1-tree").unwrap();
    assert_eq!(
        potential_objects(&tree, None, true).unwrap(),
        tree.empowerment.objects.clone().unwrap()
    );
    // A push task is about the boulder's cell: counted in full.
    let exp3 = fulcrum_world::load_world("exp3").unwrap();
    assert!(matches!(exp3.task, Task::Push(_)));
    assert_eq!(
        potential_objects(&exp3, None, true).unwrap(),
        exp3.empowerment.objects.clone().unwrap()
    );
}
