//! Tool selection and the table in one propagation (`Engine::auto_table`) against the
//! two computations it replaces: the matrix column (`Engine::matrix`, equation 6's
//! selection) and then `Engine::lookup_values` for the selected tool. Equal to the bit:
//! the column's every entry, the selection, and the value in every state, for Phi and
//! for E, with the selection's horizons equal to the table's and apart from them; on
//! every built-in world with tools, every object column, and on layouts of both built-in
//! families (boulder, wall, tree and door layouts among them).

use fulcrum_empowerment::auto::AutoHorizons;
use fulcrum_empowerment::{Engine, Limits, Method};
use fulcrum_world::family::load_family;
use fulcrum_world::{load_world, ObjectSet, World};

/// (selection's horizon, table's H_uneq, H_eq)
const HORIZONS: [(u32, u32, u32); 4] = [(8, 8, 3), (5, 5, 6), (8, 4, 7), (3, 8, 3)];

/// Compares every column of `w` under every horizon and form; the number of states
/// compared.
fn compare(w: &World) -> usize {
    let engine = Engine::new(w, Limits::default()).unwrap();
    let mut compared = 0;
    for i in 0..w.objects.len() {
        let set = ObjectSet::Objects(vec![i]);
        for (sh, hu, he) in HORIZONS {
            let m = engine
                .matrix(std::slice::from_ref(&set), sh, sh, Method::Dp)
                .unwrap();
            for horizon_sum in [false, true] {
                let hz = AutoHorizons {
                    select: sh,
                    unequipped: hu,
                    equipped: he,
                    horizon_sum,
                };
                let what = format!("{} column {i} {hz:?}", w.name);
                let a = engine.auto_table(&set, hz).expect(&what);
                let column: Vec<f64> = m.values.iter().map(|row| row[0]).collect();
                assert_eq!(
                    a.column.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                    column.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                    "{what}"
                );
                assert_eq!(a.tool, m.selection[0], "{what}");
                let Some(j) = a.tool else {
                    assert!(a.values.is_empty(), "{what}");
                    continue;
                };
                let tool = fulcrum_empowerment::ToolSel::Tool(j);
                let want = engine
                    .lookup_values(tool, &set, hu, he, horizon_sum)
                    .unwrap();
                assert_eq!(a.values.len(), want.len(), "{what}");
                for (s, (x, y)) in a.values.iter().zip(&want).enumerate() {
                    assert_eq!(x.to_bits(), y.to_bits(), "{what}, state {s}: {x} vs {y}");
                }
                compared += want.len();
            }
        }
    }
    compared
}

#[test]
fn one_propagation_equals_the_matrix_then_the_table_on_the_built_in_worlds() {
    let mut compared = 0;
    for name in ["exp1-tree", "exp1-wall", "exp2", "exp3", "room"] {
        let w = load_world(name).unwrap();
        assert!(!w.tools.is_empty(), "{name}");
        compared += compare(&w);
    }
    assert!(compared > 100_000, "{compared} values compared");
}

#[test]
fn one_propagation_equals_the_matrix_then_the_table_on_layouts() {
    let mut kinds = std::collections::BTreeSet::new();
    for family in ["toolbox", "two-rooms"] {
        let f = load_family(family).unwrap();
        for seed in 0..24 {
            let w = f.layout(seed).unwrap();
            for o in &w.objects {
                kinds.insert(format!("{:?}", o.kind));
            }
            assert!(compare(&w) > 0, "{family} layout {seed}");
        }
    }
    // The layouts met every kind of task object the families draw.
    for k in ["Tree", "Wall", "Boulder", "Door"] {
        assert!(kinds.contains(k), "no {k} among {kinds:?}");
    }
}

#[test]
fn where_it_does_not_apply_it_says_so() {
    // A stochastic world, and a horizon of 0.
    let w = load_world("exp1-tree-slip").unwrap();
    let engine = Engine::new(&w, Limits::default()).unwrap();
    let set = ObjectSet::Objects(vec![0]);
    let hz = AutoHorizons {
        select: 8,
        unequipped: 8,
        equipped: 3,
        horizon_sum: true,
    };
    assert_eq!(engine.auto_table(&set, hz), None);
    let w = load_world("exp1-tree").unwrap();
    let engine = Engine::new(&w, Limits::default()).unwrap();
    assert!(engine.auto_table(&set, hz).is_some());
    let zero = AutoHorizons { equipped: 0, ..hz };
    assert_eq!(engine.auto_table(&set, zero), None);
}
