//! Tool selection (`tool = "auto"`, the paper's equation 6) compares rows that can be
//! compared: its matrix takes one horizon for every state and row.
//!
//! The reason, as a property: where tool k has no rule for any object of the world, every
//! action sequence of k's subset {N, E, S, W, apply, select_k} changes the objects only
//! by the agent's moves (its uses of k change nothing, and a select in normal mode is a
//! stay), so the same moves with tool j's subset, each use of k replaced by as many
//! stays (select_j in normal mode), bring about the same objects' states in as many
//! steps. At one horizon E_j(s) >= E_k(s) in every state, so row j >= row k (floating
//! sums of larger terms in the same order are no smaller). A matrix whose rows switch
//! to a shorter horizon where their own tool is held breaks this: a row is then
//! favoured for being held in fewer states.

use fulcrum_empowerment::request::{selection_horizon, tool_sel_with_column};
use fulcrum_empowerment::{Engine, Limits, Method, ToolSel};
use fulcrum_world::generate::GenSet;
use fulcrum_world::{ObjectSet, World};

/// Tools of `w` with no rule for any kind of object the world holds.
fn idle_tools(w: &World) -> Vec<usize> {
    (0..w.tools.len())
        .filter(|&k| {
            !w.rules
                .iter()
                .any(|r| r.tool == w.tools[k].kind && w.objects.iter().any(|o| o.kind == r.target))
        })
        .collect()
}

#[test]
fn a_tool_with_no_rule_never_outranks_another_in_the_selection() {
    let set: GenSet = "gen:12:seed=1001".parse().unwrap();
    let mut pairs = 0;
    for g in set.worlds().unwrap() {
        let w = &g.world;
        let idle = idle_tools(w);
        let engine = Engine::new(w, Limits::default()).unwrap();
        for i in 0..w.objects.len() {
            let col = ObjectSet::Objects(vec![i]);
            let (tool, m) = tool_sel_with_column(w, &engine, Some("auto"), &col).unwrap();
            let m = m.expect("auto gives its matrix");
            assert_eq!(m.values.len(), w.tools.len(), "{}: one row a tool", w.name);
            for &k in &idle {
                for j in 0..w.tools.len() {
                    assert!(
                        m.values[j][0] >= m.values[k][0],
                        "{} object {i}: {} ({}) below {} ({}), which has no rule",
                        w.name,
                        w.tools[j].name,
                        m.values[j][0],
                        w.tools[k].name,
                        m.values[k][0]
                    );
                    pairs += 1;
                }
            }
            // The selected tool is the column's argmax.
            let ToolSel::Tool(sel) = tool else {
                panic!("{}: auto selects a tool", w.name)
            };
            assert!(m.values.iter().all(|r| r[0] <= m.values[sel][0]));
        }
    }
    assert!(pairs > 20, "{pairs} pairs compared");
}

/// `gen-12x8-t3-o2-s1006` (`fulcrum world generate --tools 3 --objects 2 --rock 0.1
/// --seed 1006`): a boulder to destroy, an axe, a pickaxe and a key, no door. The
/// pickaxe destroys boulders (`docs/world.md`, "What tools do"); the key has no rule
/// for anything here. With rows that switch horizon where their tool is held (8 not
/// held, 3 held) the key's row was the larger and the key was selected.
#[test]
fn the_boulder_world_selects_the_tool_that_destroys_it() {
    let set: GenSet = "gen:6:seed=1001".parse().unwrap();
    let g = set
        .worlds()
        .unwrap()
        .into_iter()
        .find(|g| g.world.name == "gen-12x8-t3-o2-s1006")
        .expect("s1006 is among the set's first six solvable worlds");
    let w = &g.world;
    let boulder = w.object_index("boulder").unwrap();
    let col = ObjectSet::Objects(vec![boulder]);
    let engine = Engine::new(w, Limits::default()).unwrap();
    let (tool, _) = tool_sel_with_column(w, &engine, None, &col).unwrap();
    assert_eq!(tool, ToolSel::Tool(w.tool_index("pickaxe").unwrap()));
    assert_eq!(selection_horizon(w), 8);
    // The switching matrix: the key over the pickaxe.
    let mixed = engine
        .matrix(std::slice::from_ref(&col), 8, 3, Method::Dp)
        .unwrap();
    let (p, k) = (
        w.tool_index("pickaxe").unwrap(),
        w.tool_index("key").unwrap(),
    );
    assert!(mixed.values[k][0] > mixed.values[p][0]);
    assert_eq!(mixed.selection[0], Some(k));
}
