//! Property tests of world files: no input makes the parser panic, and every refusal is
//! one sentence that names the file, the line and the column.

use fulcrum_world::generate::{generate, GenParams};
use fulcrum_world::parse_world;
use fulcrum_world::world::Terrain;
use proptest::prelude::*;

/// A file using every section, for mutation.
const RICH: &str = r#"name = "rich"
max_steps = 20
map = """
##########
#@a.k.w.>#
#..T.=.+.#
#.0..o.0.#
##########
"""

[tools]
a = "axe"
k = "key"
w = "wand"
o = "tin_opener"

[task]
kind = "push"
object = "boulder#1"

[empowerment]
tool = "auto"
objects = ["door", "boulder#0"]
horizon_unequipped = 4
horizon_equipped = 2
beta = 0.001

[[rules]]
tool = "tin_opener"
target = "door"
from = "closed"
to = "open"
range = 1
"#;

const ALPHABET: &[char] = &[
    '#', '.', '@', '>', 'T', '=', '+', '0', ' ', '-', '|', 'a', 'k', 'w', 'o', 'z', 'A', '\n',
    '\r', '"', '\'', '[', ']', '{', '}', ',', '\\', '1', '9', '-', '_', '#', 'é', '€', '\u{0}',
    '\t',
];

#[derive(Clone, Debug)]
enum Edit {
    Replace(usize, char),
    Delete(usize),
    Insert(usize, char),
}

fn edit() -> impl Strategy<Value = Edit> {
    let ch = prop::sample::select(ALPHABET);
    prop_oneof![
        3 => (any::<usize>(), ch.clone()).prop_map(|(i, c)| Edit::Replace(i, c)),
        1 => any::<usize>().prop_map(Edit::Delete),
        1 => (any::<usize>(), ch).prop_map(|(i, c)| Edit::Insert(i, c)),
    ]
}

fn apply_edits(base: &str, edits: &[Edit]) -> String {
    let mut cs: Vec<char> = base.chars().collect();
    for e in edits {
        match *e {
            Edit::Replace(i, c) if !cs.is_empty() => {
                let i = i % cs.len();
                cs[i] = c;
            }
            Edit::Delete(i) if !cs.is_empty() => {
                cs.remove(i % cs.len());
            }
            Edit::Insert(i, c) => cs.insert(i % (cs.len() + 1), c),
            _ => {}
        }
    }
    cs.into_iter().collect()
}

/// Parse; a refusal is one sentence placed as `fuzz.toml:LINE:COL: ...` with the line
/// within the text (or just past its end) and a column from 1; when a world comes out,
/// it must be usable: step every action from the start and from each successor, and
/// read its own description back.
fn parse_and_use(text: &str) {
    let w = match parse_world(text, "fuzz.toml") {
        Ok(w) => w,
        Err(e) => {
            let m = e.to_string();
            assert!(!m.contains('\n'), "not one line: {m:?}");
            let rest = m
                .strip_prefix("fuzz.toml:")
                .unwrap_or_else(|| panic!("does not name the file: {m:?}"));
            let mut parts = rest.splitn(3, ':');
            let line: usize = parts
                .next()
                .and_then(|l| l.parse().ok())
                .unwrap_or_else(|| panic!("names no line: {m:?}"));
            let col: usize = parts
                .next()
                .and_then(|c| c.parse().ok())
                .unwrap_or_else(|| panic!("names no column: {m:?}"));
            let lines = text.split('\n').count();
            assert!(
                line >= 1 && line <= lines + 1,
                "line {line} of {lines}: {m:?}"
            );
            assert!(col >= 1, "column {col}: {m:?}");
            assert!(
                parts.next().is_some_and(|r| r.len() > 1),
                "no sentence after the place: {m:?}"
            );
            return;
        }
    };
    let s0 = w.initial;
    assert!((s0.x as usize) < w.width && (s0.y as usize) < w.height);
    assert_eq!(w.parse_state(&w.describe(&s0)), Ok(s0));
    let na = w.num_actions() as u8;
    for a in 0..na {
        let s1 = w.step(&s0, a);
        for b in 0..na {
            let s2 = w.step(&s1, b);
            assert!((s2.x as usize) < w.width && (s2.y as usize) < w.height);
        }
    }
}

fn bases() -> Vec<&'static str> {
    let b = |n| fulcrum_world::builtin::source(n).unwrap();
    vec![RICH, b("exp1-tree"), b("exp2"), b("exp3"), b("room")]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        let text = String::from_utf8_lossy(&bytes);
        parse_and_use(&text);
    }

    #[test]
    fn arbitrary_strings_never_panic(text in any::<String>()) {
        parse_and_use(&text);
    }

    #[test]
    fn toml_like_strings_never_panic(text in "[a-z_ =\"\\[\\]#.@>T+0\n'{},0-9-]{0,400}") {
        parse_and_use(&text);
    }

    #[test]
    fn mutated_world_files_never_panic(
        base in 0usize..5,
        edits in prop::collection::vec(edit(), 1..6),
    ) {
        let text = apply_edits(bases()[base], &edits);
        parse_and_use(&text);
    }

    #[test]
    fn mutated_maps_never_panic(
        base in 0usize..5,
        edits in prop::collection::vec(
            (0usize..3, any::<usize>(), prop::sample::select(CELLS)).prop_map(|(k, i, c)| match k {
                0 => Edit::Delete(i),
                1 => Edit::Insert(i, c),
                _ => Edit::Replace(i, c),
            }),
            1..6,
        ),
    ) {
        // Edits inside the map string only, so the TOML stays well formed.
        let text = bases()[base];
        let start = text.find("\"\"\"\n").unwrap() + 4;
        let end = start + text[start..].find("\n\"\"\"").unwrap();
        let map = apply_edits(&text[start..end], &edits);
        parse_and_use(&format!("{}{map}{}", &text[..start], &text[end..]));
    }

    #[test]
    fn arbitrary_maps_never_panic(
        body in "[#.@>T=+0 \\-|a-dxé\n]{0,300}",
        tools in prop::sample::subsequence(vec!['a', 'b', 'c', 'd'], 0..=4),
        literal in any::<bool>(),
    ) {
        let q = if literal { "'''" } else { "\"\"\"" };
        let mut t = format!("name = \"m\"\nmap = {q}\n{body}\n{q}\n[tools]\n");
        for c in tools {
            t.push_str(&format!("{c} = \"wand\"\n"));
        }
        parse_and_use(&t);
    }

    #[test]
    fn arbitrary_rectangular_maps_never_panic(
        grid in (1usize..9, 1usize..7).prop_flat_map(|(w, h)| {
            prop::collection::vec(prop::collection::vec(prop::sample::select(CELLS), w), h)
        }),
        agent in any::<prop::sample::Index>(),
        order in Just(vec!['a', 'b', 'c', 'd']).prop_shuffle(),
        stray in prop::collection::vec(prop::sample::select(vec!['a', 'b', 'c', 'd', 'e']), 0..2),
        kinds in prop::collection::vec(prop::sample::select(&["axe", "pickaxe", "key", "wand", "katana"][..]), 4),
    ) {
        // Rectangular rows and one agent: most of these load, so the dynamics of odd
        // worlds (no border, tools next to boulders, ...) get stepped as well.
        let mut cells: Vec<char> = grid.iter().flatten().copied().collect();
        let i = agent.index(cells.len());
        cells[i] = '@';
        // Each letter once at most (a second copy becomes floor); [tools] lists the
        // letters on the map, in the order drawn, unless `stray` leaves one out.
        let mut seen = Vec::new();
        for c in cells.iter_mut().filter(|c| c.is_ascii_lowercase()) {
            if seen.contains(c) {
                *c = '.';
            } else {
                seen.push(*c);
            }
        }
        let w = grid[0].len();
        let rows: Vec<String> = cells.chunks(w).map(|r| r.iter().collect()).collect();
        let mut t = format!("name = \"m\"\nmap = \"\"\"\n{}\n\"\"\"\n[tools]\n", rows.join("\n"));
        for (c, k) in order.iter().filter(|c| seen.contains(c) != stray.contains(c)).zip(&kinds) {
            t.push_str(&format!("{c} = \"{k}\"\n"));
        }
        parse_and_use(&t);
    }
}

/// Map cells for rectangular fuzzing.
const CELLS: &[char] = &[
    '#', '.', '.', '.', '.', '>', 'T', '=', '+', '0', '0', ' ', 'a', 'b', 'c', 'd',
];

// ---------------------------------------------------------------------------------
// Generated worlds.

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn generated_worlds_parse(
        width in 3usize..=64,
        height in 3usize..=64,
        tools in 0usize..=16,
        objects in 0usize..=16,
        rock in 0.0f64..0.5,
        seed in any::<u64>(),
    ) {
        let p = GenParams { width, height, tools, objects, rock, seed };
        let inner = (width - 2) * (height - 2);
        match generate(&p) {
            // The only refusal for parameters in range: too few inner cells for the
            // agent, the tools and the objects.
            Err(e) => prop_assert!(1 + tools + objects > inner, "{e}"),
            Ok(text) => {
                prop_assert!(1 + tools + objects <= inner);
                let w = parse_world(&text, "gen.toml").map_err(|e| TestCaseError::fail(format!("{e}\n{text}")))?;
                prop_assert_eq!((w.width, w.height), (width, height));
                prop_assert_eq!(w.tools.len(), tools);
                prop_assert_eq!(w.objects.len(), objects);
                let (x, y) = (w.initial.x as usize, w.initial.y as usize);
                // The agent is on an inner floor cell, with no tool or object under it.
                prop_assert!(x >= 1 && x < width - 1 && y >= 1 && y < height - 1);
                prop_assert_eq!(w.terrain(x as i32, y as i32), Terrain::Floor);
                prop_assert!(w.tool_cell(x, y).is_none());
                prop_assert!(w.objects.iter().all(|o| o.pos != (x as u8, y as u8)));
                // The border is rock.
                for cx in 0..width as i32 {
                    prop_assert_eq!(w.terrain(cx, 0), Terrain::Rock);
                    prop_assert_eq!(w.terrain(cx, height as i32 - 1), Terrain::Rock);
                }
                // Same parameters, same file.
                prop_assert_eq!(generate(&p).unwrap(), text);
            }
        }
    }
}
