//! Every value of `worlds/EXPECTED.md` (the paper's Tables II and III and Figs. 2, 3,
//! 6, 12 in our worlds), computed there by an independent brute-force implementation of
//! `docs/world.md`. Relative tolerance 1e-9.

use fulcrum_empowerment::{Engine, Limits, Method, ToolSel};
use fulcrum_world::{load_world, parse_world, ObjectSet, World};

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * b.abs().max(1e-300) || (a == 0.0 && b == 0.0)
}

fn objs(w: &World, names: &[&str]) -> ObjectSet {
    let mut v: Vec<usize> = names.iter().map(|n| w.object_index(n).unwrap()).collect();
    v.sort_unstable();
    ObjectSet::Objects(v)
}

fn tool(w: &World, name: &str) -> ToolSel {
    ToolSel::Tool(w.tool_index(name).unwrap())
}

#[test]
fn state_space_sizes() {
    for (name, states, normal) in [
        ("exp1-tree", 8880, 2052),
        ("exp1-wall", 8880, 2052),
        ("exp2", 10988, 2560),
        ("exp3", 52051, 14849),
    ] {
        let w = load_world(name).unwrap();
        let e = Engine::new(&w, Limits::default()).unwrap();
        assert_eq!(
            (e.space.len(), e.normal_states()),
            (states, normal),
            "{name}"
        );
    }
}

/// Check a matrix against rows of expected values and the expected selection.
fn check_matrix(
    world: &str,
    columns: &[&[&str]],
    hu: u32,
    he: u32,
    expected: &[&[f64]],
    selection: &[Option<&str>],
    method: Method,
) {
    let w = load_world(world).unwrap();
    let e = Engine::new(&w, Limits::default()).unwrap();
    let cols: Vec<ObjectSet> = columns.iter().map(|c| objs(&w, c)).collect();
    let m = e.matrix(&cols, hu, he, method).unwrap();
    for (j, row) in expected.iter().enumerate() {
        for (c, &v) in row.iter().enumerate() {
            assert!(
                close(m.values[j][c], v),
                "{world} [{}, {}] = {} expected {v}",
                m.tools[j],
                m.columns[c],
                m.values[j][c]
            );
        }
    }
    for (c, s) in selection.iter().enumerate() {
        assert_eq!(
            m.selection[c].map(|j| m.tools[j].as_str()),
            *s,
            "{world} selection of {}",
            m.columns[c]
        );
    }
}

#[test]
fn exp1_tree_matrix() {
    let t = 96.0 / 2052.0;
    let wv = 72.0 / 2052.0;
    check_matrix(
        "exp1-tree",
        &[&["tree"], &["wall"], &["tree", "wall"]],
        8,
        3,
        &[&[t, 0.0, t], &[0.0, wv, wv], &[0.0; 3], &[0.0; 3]],
        &[Some("axe"), Some("pickaxe"), Some("axe")],
        Method::Dp,
    );
}

/// The paper's method (every action sequence) gives the same exp2 column. exp1 at
/// h = 8 would need 6^8 sequences per state, which is what set propagation is for.
#[test]
fn exp2_matrix_by_enumeration() {
    check_matrix(
        "exp2",
        &[&["boulder"]],
        5,
        6,
        &[&[0.209375], &[0.0], &[0.0], &[0.0]],
        &[Some("wand")],
        Method::Enumerate,
    );
}

#[test]
fn exp2_matrix() {
    check_matrix(
        "exp2",
        &[&["boulder"], &["door"], &["boulder", "door"]],
        5,
        6,
        &[
            &[0.209375, 0.31875, 0.4859727539794917],
            &[0.0, 0.06328125, 0.06328125],
            &[0.0; 3],
            &[0.0; 3],
        ],
        &[Some("wand"), Some("wand"), Some("wand")],
        Method::Dp,
    );
}

/// exp3 values from `tests/reference/exp3_bruteforce.py` (the dynamics of `docs/world.md`). The
/// numbers first published in EXPECTED.md came from a brute force in which the agent
/// walks into an open doorway onto a boulder; `--walk-onto-boulder` reproduces them.
#[test]
fn exp3_matrix() {
    check_matrix(
        "exp3",
        &[&["door"], &["boulder"], &["door", "boulder"]],
        10,
        5,
        &[
            &[0.24264260219543404, 1.077179716291197, 1.2543753089786926],
            &[0.10216176173479695, 1.1666048575435286, 1.2424850126535198],
        ],
        &[Some("key"), Some("axe"), Some("key")],
        Method::Dp,
    );
}

/// Tool selection's matrix of exp3: one horizon (10, the world's horizon where the tool
/// is not held) for every state and row, from `tests/reference/exp3_bruteforce.py
/// --horizon 10`. The boulder's column now selects the key: neither tool has a rule for
/// a boulder, and the key opens the door the boulder can be pushed through.
#[test]
fn exp3_selection_matrix() {
    check_matrix(
        "exp3",
        &[&["door"], &["boulder"], &["door", "boulder"]],
        10,
        10,
        &[
            &[0.661728062495791, 2.042360751798079, 2.4749743255786685],
            &[0.20917233483736278, 2.0061106993148887, 2.155702806873758],
        ],
        &[Some("key"), Some("key"), Some("key")],
        Method::Dp,
    );
}

/// Cells of a landscape with a value, and the value at each.
fn landscape(
    world: &str,
    t: &str,
    objects: &[&str],
    h: u32,
    holding: &[&str],
) -> (World, Vec<Vec<Option<f64>>>) {
    let w = load_world(world).unwrap();
    let e = Engine::new(&w, Limits::default()).unwrap();
    let inv = holding
        .iter()
        .fold(0u16, |m, t| m | 1 << w.tool_index(t).unwrap());
    let l = e
        .landscape(tool(&w, t), &objs(&w, objects), h, inv, Method::Dp)
        .unwrap();
    drop(e);
    (w, l.values)
}

#[test]
fn exp1_landscape_unequipped_is_a_beacon_around_the_axe() {
    let (w, v) = landscape("exp1-tree", "axe", &["tree"], 8, &[]);
    let ones = [(3, 2), (5, 2), (4, 1), (4, 3)];
    let none = [(4, 2), (5, 4), (8, 4), (4, 6), (9, 2), (9, 6)];
    for (y, row) in v.iter().enumerate().take(w.height - 1).skip(1) {
        for (x, &got) in row.iter().enumerate().take(w.width - 1).skip(1) {
            if ones.contains(&(x, y)) {
                assert_eq!(got, Some(1.0), "({x},{y})");
            } else if none.contains(&(x, y)) {
                assert_eq!(got, None, "({x},{y})");
            } else {
                assert_eq!(got, Some(0.0), "({x},{y})");
            }
        }
    }
    // The border is rock: no value.
    assert!(v[0].iter().all(Option::is_none));
}

#[test]
fn exp1_landscape_equipped_rings_the_tree() {
    let (w, v) = landscape("exp1-tree", "axe", &["tree"], 3, &["axe"]);
    let ones = [(8, 2), (10, 2), (9, 1), (9, 3)];
    for (y, row) in v.iter().enumerate().take(w.height - 1).skip(1) {
        for (x, &cell) in row.iter().enumerate().take(w.width - 1).skip(1) {
            if let Some(val) = cell {
                let want = if ones.contains(&(x, y)) { 1.0 } else { 0.0 };
                assert_eq!(val, want, "({x},{y})");
            }
        }
    }
    assert!(ones.iter().all(|&(x, y)| v[y][x] == Some(1.0)));
}

#[test]
fn exp2_landscape_equipped_peaks_where_both_lines_are_clear() {
    let (_, v) = landscape("exp2", "wand", &["boulder", "door"], 6, &["wand"]);
    let l3 = 3f64.log2();
    assert_eq!(v[4][6], Some(2.0));
    // The upper room: x = 1..10, y = 2..6.
    for (y, row) in v.iter().enumerate().take(7).skip(2) {
        for (x, val) in row.iter().enumerate().take(11).skip(1) {
            if (x, y) == (6, 4) {
                continue;
            }
            if let Some(val) = val {
                assert!(close(*val, l3) || *val == 1.0, "({x},{y}) = {val}");
            }
        }
    }
}

#[test]
fn exp2_landscape_unequipped_table() {
    let (_, v) = landscape("exp2", "wand", &["boulder", "door"], 5, &[]);
    // EXPECTED.md, rows y = 2..6, x = 1..10; '.' = no value.
    let table = [
        "0 1 0 0 0 0 0 0 0 0",
        "1 . 1 0 0 0 0 0 . 0",
        "0 1 0 0 0 0 0 0 0 0",
        "0 0 . 0 0 0 0 0 0 0",
        "0 0 0 0 0 0 . 0 0 0",
    ];
    for (r, line) in table.iter().enumerate() {
        for (c, cell) in line.split(' ').enumerate() {
            let want = match cell {
                "." => None,
                n => Some(n.parse::<f64>().unwrap()),
            };
            assert_eq!(v[r + 2][c + 1], want, "({},{})", c + 1, r + 2);
        }
    }
}

fn trace(world: &str, t: &str, actions: &str) -> Vec<f64> {
    let w = load_world(world).unwrap();
    let e = Engine::new(&w, Limits::default()).unwrap();
    let acts: Vec<u8> = actions
        .split(',')
        .map(|a| w.parse_action(a).unwrap())
        .collect();
    let door = objs(&w, &["door"]);
    e.trace(tool(&w, t), &door, 3, &acts)
        .unwrap()
        .iter()
        .map(|s| s.value)
        .collect()
}

#[test]
fn exp3_key_trace() {
    // Pick up the key, stand west of the door (t = 7), open (t = 10), close (t = 13),
    // open again (t = 16): 1.0 at every step from the door front. Then E into the
    // doorway (t = 17): 0.0, since the door cannot close on the agent and leaving the
    // doorway takes a step too many.
    let v = trace(
        "exp3",
        "key",
        "N,N,E,E,E,E,S,apply,key,E,apply,key,E,apply,key,E,E",
    );
    assert_eq!(v.len(), 18);
    assert!(v[..7].iter().all(|&x| x == 0.0), "{v:?}");
    assert!(v[7..17].iter().all(|&x| x == 1.0), "{v:?}");
    assert_eq!(v[17], 0.0, "{v:?}");
}

#[test]
fn exp3_axe_trace() {
    let v = trace("exp3", "axe", "S,E,E,E,E,N,N,apply,axe,E,E,E");
    assert_eq!(&v[7..10], &[1.0, 1.0, 1.0], "{v:?}");
    assert!(v[10..].iter().all(|&x| x == 0.0), "{v:?}");
}

#[test]
fn closed_form_in_an_open_room() {
    // A 19x19 floor with the agent in the middle: the radius-8 diamond stays on the
    // floor. The cells within Manhattan distance n number 2n^2 + 2n + 1.
    let mut map = String::new();
    for y in 0..21 {
        for x in 0..21 {
            map.push(if x == 0 || y == 0 || x == 20 || y == 20 {
                '#'
            } else if (x, y) == (10, 10) {
                '@'
            } else {
                '.'
            });
        }
        map.push('\n');
    }
    let text = format!("name = \"open\"\nmap = \"\"\"\n{map}\"\"\"\n[tools]\n");
    let w = parse_world(&text, "open.toml").unwrap();
    let e = Engine::new(&w, Limits::default()).unwrap();
    let expected = [
        2.321928, 3.700440, 4.643856, 5.357552, 5.930737, 6.409391, 6.820179, 7.179909,
    ];
    let id = e.space.id(&w.initial).unwrap() as usize;
    for (k, want) in expected.iter().enumerate() {
        let n = k as u32 + 1;
        let v = e
            .values(ToolSel::All, &ObjectSet::Agent, n, Method::Dp)
            .unwrap()[id];
        let exact = ((2 * n * n + 2 * n + 1) as f64).log2();
        assert!(close(v, exact), "n = {n}: {v} vs log2(2n^2+2n+1) = {exact}");
        assert!(
            (v - want).abs() < 1e-6,
            "n = {n}: {v} vs EXPECTED.md {want}"
        );
    }
}
