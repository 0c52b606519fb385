//! World families: layouts are a pure function of (family, seed), keep the family's
//! shape, and every layout of the built-in families can be solved, checked by a search
//! written here from the rule table of `docs/world.md` (not the world's own step and not
//! the generator's search); bad families are one sentence at their file:line:col.

use std::collections::{HashSet, VecDeque};

use fulcrum_world::family::{load_family, parse_family, Family};
use fulcrum_world::world::ObjectKind;
use fulcrum_world::{parse_world, World, WorldError};

/// Layout 0 of `toolbox`, as drawn by ChaCha8 from seed 0 (checked by eye against the
/// family's rules: a rock border, the agent, the axe `a`, pickaxe `b` and wand `c`, one
/// task object). The same map on every machine and every build: the layout of a seed
/// must never change under a run that trains on it.
const TOOLBOX_0: &str = "\
##########
#...c....#
#b..@....#
#...T....#
#a.......#
#........#
#........#
##########
";

#[test]
fn a_layout_is_the_same_on_every_machine() {
    let f = load_family("toolbox").unwrap();
    let w = f.layout(0).unwrap();
    assert_eq!(w.render(&w.initial), TOOLBOX_0);
    // The same seed twice, and from a fresh load: the same text, byte for byte.
    assert_eq!(f.layout_text(7).unwrap(), f.layout_text(7).unwrap());
    assert_eq!(
        f.layout_text(7).unwrap(),
        load_family("toolbox").unwrap().layout_text(7).unwrap()
    );
    assert_ne!(f.layout_text(7).unwrap(), f.layout_text(8).unwrap());
}

/// The tool kinds that destroy each task object, by hand from the table "What tools do".
fn fits(kind: ObjectKind) -> &'static [&'static str] {
    match kind {
        ObjectKind::Tree => &["axe"],
        ObjectKind::Wall => &["pickaxe"],
        ObjectKind::Boulder => &["pickaxe", "wand"],
        ObjectKind::Door => &["axe", "pickaxe", "wand"],
    }
}

/// Fewest moves from `from` to each cell over cells `open` lets through (4-connected).
fn moves(
    w: &World,
    grid: &[Vec<char>],
    from: (usize, usize),
    open: &dyn Fn(char) -> bool,
) -> Vec<Vec<Option<u32>>> {
    let mut d = vec![vec![None; w.width]; w.height];
    let mut q = VecDeque::from([from]);
    d[from.1][from.0] = Some(0);
    while let Some((x, y)) = q.pop_front() {
        let here = d[y][x].unwrap();
        for (dx, dy) in [(0i32, -1i32), (1, 0), (0, 1), (-1, 0)] {
            let (nx, ny) = ((x as i32 + dx) as usize, (y as i32 + dy) as usize);
            if ny < w.height && nx < w.width && d[ny][nx].is_none() && open(grid[ny][nx]) {
                d[ny][nx] = Some(here + 1);
                q.push_back((nx, ny));
            }
        }
    }
    d
}

/// Fewest steps of a plan that surely works, or None: walk to a fitting tool, (with a
/// door in the way: walk beside the door and break it with that tool, 3 actions: apply,
/// select, direction), walk beside the task object and use the tool on it (3 actions).
/// Objects are never pushed and other tools are walked over (picked up), so this is an
/// upper bound on the fewest steps: a layout it solves can be solved.
fn plan_steps(f: &Family, w: &World) -> Option<u32> {
    let text = w.render(&w.initial);
    let grid: Vec<Vec<char>> = text.lines().map(|l| l.chars().collect()).collect();
    let find = |c: char| -> Vec<(usize, usize)> {
        let mut v = Vec::new();
        for (y, row) in grid.iter().enumerate() {
            for (x, &g) in row.iter().enumerate() {
                if g == c {
                    v.push((x, y));
                }
            }
        }
        v
    };
    let agent = find('@')[0];
    let target = w
        .objects
        .iter()
        .find(|o| o.kind != ObjectKind::Door || !f.divider)?;
    let object = (target.pos.0 as usize, target.pos.1 as usize);
    let door = if f.divider {
        find('+').first().copied()
    } else {
        None
    };
    let walk = |c: char| c == '.' || c == '@' || c.is_ascii_lowercase();
    let walk_door = |c: char| walk(c) || c == '+';
    let beside = |d: &Vec<Vec<Option<u32>>>, (x, y): (usize, usize)| {
        [
            (x, y.wrapping_sub(1)),
            (x + 1, y),
            (x, y + 1),
            (x.wrapping_sub(1), y),
        ]
        .into_iter()
        .filter_map(|(a, b)| d.get(b).and_then(|r| r.get(a)).copied().flatten())
        .min()
    };
    let from_agent = moves(w, &grid, agent, &walk);
    let mut best: Option<u32> = None;
    for (k, t) in w.tools.iter().enumerate() {
        if !fits(target.kind).contains(&t.kind.as_str()) {
            continue;
        }
        let _ = k;
        let tool = (t.pos.0 as usize, t.pos.1 as usize);
        let Some(to_tool) = from_agent[tool.1][tool.0] else {
            continue;
        };
        let from_tool = moves(w, &grid, tool, &walk);
        let steps = match door {
            None => beside(&from_tool, object).map(|m| to_tool + m + 3),
            Some(dc) => {
                // Break the door with the fitting tool (it breaks doors too), then go on
                // through the doorway.
                if !fits(ObjectKind::Door).contains(&t.kind.as_str()) {
                    continue;
                }
                let to_door = beside(&from_tool, dc);
                let through = moves(w, &grid, dc, &walk_door);
                to_door.and_then(|a| beside(&through, object).map(|b| to_tool + a + 3 + 1 + b + 3))
            }
        };
        if let Some(s) = steps {
            best = Some(best.map_or(s, |b: u32| b.min(s)));
        }
    }
    best
}

fn check_family(name: &str, layouts: u64) {
    let f = load_family(name).unwrap();
    let first = f.layout(0).unwrap();
    let mut kinds = HashSet::new();
    for s in 0..layouts {
        let w = f
            .layout(s)
            .unwrap_or_else(|e| panic!("{name} layout {s}: {e}"));
        // The family's shape: what the observation and the action space depend on.
        assert_eq!((w.width, w.height), (f.width, f.height), "{name} {s}");
        assert_eq!(w.num_actions(), first.num_actions(), "{name} {s}");
        assert_eq!(w.obs_spec(), first.obs_spec(), "{name} {s}");
        let tools: Vec<&str> = w.tools.iter().map(|t| t.kind.as_str()).collect();
        assert_eq!(
            tools,
            f.tools.iter().map(String::as_str).collect::<Vec<_>>()
        );
        assert_eq!(w.objects.len(), 1 + usize::from(f.divider), "{name} {s}");
        let target = w
            .objects
            .iter()
            .find(|o| o.kind != ObjectKind::Door || !f.divider)
            .unwrap();
        assert!(f.objects.contains(&target.kind), "{name} {s}");
        kinds.insert(target.kind);
        let steps = plan_steps(&f, &w);
        assert!(
            steps.is_some_and(|n| n <= w.max_steps),
            "{name} layout {s} has no plan within {} steps:\n{}",
            w.max_steps,
            w.render(&w.initial)
        );
        // The layout is its own ordinary world file.
        let again = parse_world(&f.layout_text(s).unwrap(), "again").unwrap();
        assert_eq!(again.content_hash(), w.content_hash());
    }
    assert_eq!(
        kinds.len(),
        f.objects.len(),
        "{name}: every task object is drawn"
    );
}

#[test]
fn every_toolbox_layout_of_the_first_10000_is_solvable_and_of_one_shape() {
    check_family("toolbox", 10_000);
}

#[test]
fn every_two_rooms_layout_of_the_first_10000_is_solvable_and_of_one_shape() {
    check_family("two-rooms", 10_000);
}

#[test]
fn the_tools_that_fit_are_the_rule_tables() {
    let f = load_family("toolbox").unwrap();
    // In two-rooms the door is no task object: only the tree's or wall's tools fit.
    let r = load_family("two-rooms").unwrap();
    for s in 0..50 {
        let w = r.layout(s).unwrap();
        let kind = w
            .objects
            .iter()
            .find(|o| o.kind != ObjectKind::Door)
            .unwrap()
            .kind;
        let got: Vec<&str> = w
            .fitting_tools()
            .unwrap()
            .iter()
            .map(|&k| w.tools[k].kind.as_str())
            .collect();
        assert_eq!(got, fits(kind), "two-rooms layout {s}");
    }
    for s in 0..200 {
        let w = f.layout(s).unwrap();
        let kind = w.objects[0].kind;
        let got: Vec<&str> = w
            .fitting_tools()
            .unwrap()
            .iter()
            .map(|&k| w.tools[k].kind.as_str())
            .collect();
        assert_eq!(got, fits(kind), "layout {s}");
    }
}

fn refused(text: &str) -> String {
    match parse_family(text, "fam.toml") {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => e.to_string(),
    }
}

fn family(body: &str) -> String {
    format!("name = \"f\"\n\n[family]\n{body}")
}

#[test]
fn bad_families_are_one_sentence_at_their_place() {
    for (body, line, col, words) in [
        (
            "width = 4\nheight = 8\ntools = [\"axe\"]\nobjects = [\"tree\"]\n",
            4,
            9,
            "[family] width 4 must be 5 to 64",
        ),
        (
            "width = 10\nheight = 8\ntools = [\"axe\"]\nobjects = [\"rock\"]\n",
            7,
            12,
            "unknown object kind 'rock'",
        ),
        (
            "width = 10\nheight = 8\ntools = [\"key\"]\nobjects = [\"tree\"]\n",
            7,
            12,
            "no tool of [family] tools destroys a tree (tools that do: axe)",
        ),
        (
            "width = 10\nheight = 8\ntools = [\"axe\", \"axe\"]\nobjects = [\"tree\"]\n",
            6,
            17,
            "tool kind 'axe' is listed twice",
        ),
        (
            "width = 10\nheight = 8\ntools = [\"axe\"]\nobjects = [\"tree\"]\nrock = 0.5\n",
            8,
            8,
            "[family] rock 0.5 must be in [0, 0.5)",
        ),
        (
            "width = 10\nheight = 8\ntools = [\"axe\"]\nobjects = []\n",
            7,
            11,
            "[family] objects lists no object kind",
        ),
        (
            "width = 12\nheight = 8\ntools = [\"axe\"]\nobjects = [\"door\"]\ndivider = true\n",
            7,
            12,
            "with divider the door between the rooms is not a task object",
        ),
        (
            "width = 10\nheight = 8\ntools = [\"axe\"]\nobjects = [\"tree\"]\nsize = 3\n",
            8,
            1,
            "unknown field `size`",
        ),
    ] {
        let msg = refused(&family(body));
        let at = format!("fam.toml:{line}:{col}: ");
        assert!(
            msg.starts_with(&at) && msg.contains(words),
            "{msg}\n(wanted {at}{words})"
        );
        assert_eq!(msg.lines().count(), 1, "{msg}");
    }
    // A room too small for what it must hold (5 x 5: 9 inner cells; 1 + 8 tools + 1 > 9).
    let msg = refused(&family(
        "width = 5\nheight = 5\ntools = [\"axe\", \"a1\", \"a2\", \"a3\", \"a4\", \"a5\", \"a6\", \"a7\", \"a8\"]\nobjects = [\"tree\"]\n",
    ));
    assert!(
        msg.contains("a 5x5 room is too small for the agent, 9 tools and the task object"),
        "{msg}"
    );
}

#[test]
fn a_family_is_not_one_world() {
    let text = fulcrum_world::builtin::family_source("toolbox").unwrap();
    match parse_world(text, "toolbox.toml") {
        Err(WorldError::File { msg, .. }) => {
            assert!(
                msg.contains("world family") && msg.contains("--layout N"),
                "{msg}"
            )
        }
        other => panic!("{other:?}"),
    }
}
