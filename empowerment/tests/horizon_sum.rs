//! The potential of `--intrinsic horizon-potential`: the service's LOOKUP with
//! `horizon_sum` answers Phi(s) = sum over h = 1..H of E^h(s).
//!
//! Hand count on exp1-tree (axe -> tree, H = 8). The tree has two states, so E^h(s) is
//! 1 bit when the agent can destroy it within h steps and 0 otherwise, and
//! Phi(s) = max(0, H + 1 - d(s)), d(s) the fewest steps to destroy it. From the start
//! (1,4) the shortest plan is E, E, E, N, N (the axe at (4,2) is picked up), E, E, E, E
//! (next to the tree at (9,2)), apply, select axe, E: 12 steps. After t of them
//! d = 12 - t, so Phi = max(0, t - 3): 0 for the first four states, then one more per
//! step, up to 8 at the direction prompt.

use std::time::Duration;

use fulcrum_empowerment::service::{ServeConfig, Tables};
use fulcrum_empowerment::{Engine, Limits, ToolSel};
use fulcrum_world::{load_world, ObjectSet, APPLY, EAST, NORTH, SELECT0};

fn tables(horizon_sum: bool) -> (fulcrum_world::World, ServeConfig) {
    let w = load_world("exp1-tree").unwrap();
    let axe = w.tool_index("axe").unwrap();
    let tree = w.objects.iter().position(|o| o.name == "tree").unwrap();
    let cfg = ServeConfig {
        namespace: "unused".into(),
        tool: ToolSel::Tool(axe),
        objects: ObjectSet::Objects(vec![tree]),
        horizon_unequipped: 8,
        horizon_equipped: 3,
        horizon_sum,
        cache_bytes: 1 << 20,
        spin: Duration::ZERO,
        max_clients: fulcrum_contracts::msg::MAX_CLIENTS,
    };
    (w, cfg)
}

fn path(w: &fulcrum_world::World) -> Vec<fulcrum_world::State> {
    let axe = w.tool_index("axe").unwrap() as u8;
    let plan = [
        EAST,
        EAST,
        EAST,
        NORTH,
        NORTH,
        EAST,
        EAST,
        EAST,
        EAST,
        APPLY,
        SELECT0 + axe,
        EAST,
    ];
    let mut s = w.initial;
    let mut out = vec![s];
    for a in plan {
        s = w.step(&s, a);
        out.push(s);
    }
    out
}

#[test]
fn phi_along_the_optimal_exp1_tree_path_rises_by_one_per_step() {
    let (w, cfg) = tables(true);
    let e = Engine::new(&w, Limits::default()).unwrap();
    let t = Tables::new(e, cfg).unwrap();
    let states = path(&w);
    let phi: Vec<f32> = states[..12].iter().map(|s| t.lookup(s).unwrap()).collect();
    let want: Vec<f32> = (0..12).map(|t: i32| (t - 3).max(0) as f32).collect();
    assert_eq!(phi, want);
    // The last step destroys the tree: nothing can change it any more.
    assert_eq!(t.lookup(&states[12]).unwrap(), 0.0);
}

#[test]
fn without_horizon_sum_lookup_is_e_with_switched_horizons() {
    let (w, cfg) = tables(false);
    let e = Engine::new(&w, Limits::default()).unwrap();
    let t = Tables::new(e, cfg).unwrap();
    let states = path(&w);
    // Not held (h = 8): E = 1 once d <= 8 (from t = 4 on, before the pick-up at t = 5);
    // held (h = 3): only within 3 steps of the tree (t >= 9).
    let got: Vec<f32> = states[..12].iter().map(|s| t.lookup(s).unwrap()).collect();
    let want = [0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 1., 1.];
    assert_eq!(got, want);
}
