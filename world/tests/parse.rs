//! World files: every error of `docs/world.md` at its file:line:col, names and orders,
//! and the built-in worlds (property tests that no input makes the parser panic:
//! `parse_fuzz.rs`).
//!
//! Lines and columns are 1-based and counted by hand from the texts below (columns in
//! characters); each test writes its text one line per string so the count is plain.

use fulcrum_world::world::{ObjectKind, Terrain};
use fulcrum_world::{load_world, parse_world, Task, World, WorldError};

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
                    file,
                    line: l,
                    col: c,
                    msg,
                } => {
                    assert_eq!(file, FILE, "{shown}");
                    assert_eq!((*l, *c), (line, col), "{shown}\n{text}");
                    for w in words {
                        assert!(msg.contains(w), "message lacks {w:?}: {shown}");
                    }
                    // The one-line form is file:line:col: message.
                    assert!(
                        shown.starts_with(&format!("{FILE}:{line}:{col}: ")),
                        "{shown}"
                    );
                }
                other => panic!("expected WorldError::At, got {other:?}"),
            }
        }
    }
}

fn ok(text: &str) -> World {
    parse_world(text, FILE).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

// ---------------------------------------------------------------------------------
// The errors `docs/world.md` lists.

#[test]
fn unknown_glyph() {
    // Line 4 is `#@X.#`: X is the 3rd character.
    let t = lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        "#####",
        "#@X.#",
        "#####",
        "\"\"\"",
    ]);
    expect_at(&t, 4, 3, &["unknown glyph", "'X'"]);
    // Columns count characters, not bytes: `#@.é#` has é 4th (after 3 one-byte chars),
    // and a 2-byte char before the bad glyph does not shift it: `#é@.#` has é 2nd.
    let t = lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        "#####",
        "#@.é#",
        "#####",
        "\"\"\"",
    ]);
    expect_at(&t, 4, 4, &["unknown glyph", "at 3,1"]);
    let t = lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        "#####",
        "#.@.#",
        "#.§$#",
        "\"\"\"",
    ]);
    expect_at(&t, 5, 3, &["unknown glyph"]);
}

#[test]
fn unknown_glyph_in_a_literal_string_map() {
    // `'''` literal strings place cells the same way.
    let t = lines(&[
        "name = \"t\"",
        "map = '''",
        "#####",
        "#@.?#",
        "#####",
        "'''",
    ]);
    expect_at(&t, 4, 4, &["unknown glyph", "'?'"]);
}

#[test]
fn unknown_glyph_with_crlf_line_ends() {
    // The same file with Windows line ends: still line 4, column 3.
    let t = lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        "#####",
        "#@X.#",
        "#####",
        "\"\"\"",
    ])
    .replace('\n', "\r\n");
    expect_at(&t, 4, 3, &["unknown glyph", "'X'"]);
    let t = lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        "#####",
        "#@..#",
        "#..X#",
        "\"\"\"",
    ])
    .replace('\n', "\r\n");
    expect_at(&t, 5, 4, &["unknown glyph", "'X'"]);
}

#[test]
fn map_letter_missing_from_tools() {
    // `#a@b#` on line 4: b, the 4th character, is not in [tools].
    let t = lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        "#####",
        "#a@b#",
        "#####",
        "\"\"\"",
        "[tools]",
        "a = \"axe\"",
    ]);
    expect_at(&t, 4, 4, &["'b'", "[tools]"]);
}

#[test]
fn no_agent() {
    // Placed at the map's string, which opens on line 2, column 7 (`map = """`).
    let t = lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        "#####",
        "#...#",
        "#####",
        "\"\"\"",
    ]);
    expect_at(&t, 2, 7, &["no agent"]);
}

#[test]
fn two_agents() {
    // The second '@' of `#@.@#` (line 4) is the 4th character.
    let t = lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        "#####",
        "#@.@#",
        "#####",
        "\"\"\"",
    ]);
    expect_at(&t, 4, 4, &["second agent"]);
    // Two agents on different lines: the later one in reading order (line 5, col 2).
    let t = lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        "#####",
        "#..@#",
        "#@..#",
        "\"\"\"",
    ]);
    expect_at(&t, 5, 2, &["second agent"]);
}

#[test]
fn map_wider_than_64() {
    let wide = format!("#@{}", ".".repeat(63)); // 65 characters
    let border = "#".repeat(65);
    // Every row 65 wide: the first row (line 3) fails at its 65th character.
    let t = lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        &border,
        &wide,
        &border,
        "\"\"\"",
    ]);
    expect_at(&t, 3, 65, &["65", "64"]);
    // Only the second row (line 4) is too wide: its 65th character.
    let t = lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        "#####",
        &wide,
        "#####",
        "\"\"\"",
    ]);
    expect_at(&t, 4, 65, &["65", "64"]);
    // 64 is allowed.
    let w64 = format!("@{}", ".".repeat(63));
    let w = ok(&lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        &w64,
        &".".repeat(64),
        "\"\"\"",
    ]));
    assert_eq!((w.width, w.height), (64, 2));
}

#[test]
fn map_taller_than_64() {
    // 65 rows starting on line 3: row 65 is on line 67.
    let mut ls = vec!["name = \"t\"", "map = \"\"\"", "@"];
    ls.extend(std::iter::repeat_n(".", 64));
    ls.push("\"\"\"");
    expect_at(&lines(&ls), 67, 1, &["65", "64"]);
    // 64 rows are allowed.
    ls.remove(3);
    let w = ok(&lines(&ls));
    assert_eq!((w.width, w.height), (1, 64));
    // The largest map: 64 x 64, agent in the far corner.
    let mut rows: Vec<String> = (0..64).map(|_| ".".repeat(64)).collect();
    rows[63] = format!("{}@", ".".repeat(63));
    let mut t = String::from("name = \"t\"\nmap = \"\"\"\n");
    for r in &rows {
        t.push_str(r);
        t.push('\n');
    }
    t.push_str("\"\"\"\n");
    let w = ok(&t);
    assert_eq!(
        (w.width, w.height, w.initial.x, w.initial.y),
        (64, 64, 63, 63)
    );
}

#[test]
fn rows_of_different_lengths() {
    // Row 2 (line 4) is 4 wide, row 1 is 5: placed at the start of line 4.
    let t = lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        "#####",
        "#@.#",
        "#####",
        "\"\"\"",
    ]);
    expect_at(&t, 4, 1, &["row 2", "4", "5"]);
    // A longer third row (line 5).
    let t = lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        "#####",
        "#@..#",
        "######",
        "\"\"\"",
    ]);
    expect_at(&t, 5, 1, &["row 3", "6", "5"]);
    // Padding with spaces is allowed, and a space is solid rock.
    let w = ok(&lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        "#### ",
        "#@.# ",
        "#####",
        "\"\"\"",
    ]));
    assert_eq!(w.width, 5);
    assert_eq!(w.terrain(4, 0), Terrain::Rock);
    assert_eq!(w.terrain(2, 1), Terrain::Floor);
}

#[test]
fn task_naming_an_object_not_on_the_map() {
    // Line 10 `objects = ["tree", "door"]`: "door" opens at column 20
    // (`objects = [` is 11 characters, `"tree", ` 8 more).
    let head = [
        "name = \"t\"",
        "map = \"\"\"",
        "#####",
        "#@T.#",
        "#####",
        "\"\"\"",
        "",
        "[task]",
    ];
    let mut ls = head.to_vec();
    ls.extend(["kind = \"destroy\"", "objects = [\"tree\", \"door\"]"]);
    expect_at(&lines(&ls), 10, 20, &["'door'", "not on the map"]);
    // An ordinal past the end: only one tree, so `tree#1` does not exist (column 12).
    let mut ls = head.to_vec();
    ls.extend(["kind = \"destroy\"", "objects = [\"tree#1\"]"]);
    expect_at(&lines(&ls), 10, 12, &["tree#1", "not on the map"]);
    // A push task naming a boulder on a map without one: `object = "boulder"`, col 10.
    let mut ls = head.to_vec();
    ls.extend(["kind = \"push\"", "object = \"boulder\""]);
    expect_at(&lines(&ls), 10, 10, &["'boulder'", "not on the map"]);
}

#[test]
fn more_than_16_tools() {
    // [tools] a..q is 17 entries, a on line 6: q on line 22, its value at column 5.
    let mut ls = vec!["name = \"t\"", "map = \"\"\"", "#@#", "\"\"\"", "[tools]"];
    let entries: Vec<String> = ('a'..='q').map(|c| format!("{c} = \"axe\"")).collect();
    ls.extend(entries.iter().map(String::as_str));
    expect_at(&lines(&ls), 22, 5, &["at most 16 tools", "17"]);
    // 16 tools, all on the map, are allowed.
    let map = format!("@{}", ('a'..='p').collect::<String>());
    let mut ls = vec!["name = \"t\"", "map = \"\"\"", &map, "\"\"\"", "[tools]"];
    ls.extend(entries[..16].iter().map(String::as_str));
    assert_eq!(ok(&lines(&ls)).tools.len(), 16);
}

#[test]
fn more_than_16_objects() {
    // 17 objects on line 3 after `#@`: the 17th is at column 2 + 17 = 19. Kinds mix:
    // the limit counts all objects together.
    let row17 = format!("#@{}#", "T=+0".repeat(4) + "T");
    let t = lines(&["name = \"t\"", "map = \"\"\"", &row17, "\"\"\""]);
    expect_at(&t, 3, 19, &["at most 16 objects"]);
    let row16 = format!("#@{}#", "T=+0".repeat(4));
    let w = ok(&lines(&["name = \"t\"", "map = \"\"\"", &row16, "\"\"\""]));
    assert_eq!(w.objects.len(), 16);
    // The 17th object first on the next line (19 wide like row16): line 4, column 1.
    let t = lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        &row16,
        &format!("T{}", ".".repeat(18)),
        "\"\"\"",
    ]);
    expect_at(&t, 4, 1, &["at most 16 objects"]);
}

#[test]
fn unknown_tool_kind_in_rules() {
    // [[rules]] names wand, but the world has only an axe: `tool = "wand"` on line 8,
    // the string at column 8.
    let t = lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        "#@a#",
        "\"\"\"",
        "[tools]",
        "a = \"axe\"",
        "[[rules]]",
        "tool = \"wand\"",
        "target = \"door\"",
        "from = \"closed\"",
        "to = \"destroyed\"",
        "range = \"bolt\"",
    ]);
    expect_at(&t, 8, 8, &["unknown tool kind", "'wand'"]);
}

#[test]
fn invalid_tool_kind_name() {
    // `a = "Axe!"` on line 6: the value at column 5.
    let t = lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        "#@a#",
        "\"\"\"",
        "[tools]",
        "a = \"Axe!\"",
    ]);
    expect_at(&t, 6, 5, &["unknown tool kind", "Axe!"]);
    // An unknown but well-formed kind is a distractor and loads.
    let w = ok(&lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        "#@a#",
        "\"\"\"",
        "[tools]",
        "a = \"spork\"",
    ]));
    assert_eq!(w.tools[0].kind, "spork");
}

#[test]
fn bad_rule_fields_are_placed() {
    let rule = |target: &str, from: &str, to: &str, range: &str| {
        lines(&[
            "name = \"t\"",
            "map = \"\"\"",
            "#@a#",
            "\"\"\"",
            "[tools]",
            "a = \"axe\"",
            "[[rules]]",
            "tool = \"axe\"",
            &format!("target = {target}"),
            &format!("from = {from}"),
            &format!("to = {to}"),
            &format!("range = {range}"),
        ])
    };
    // Line 9 `target = "dragon"`: column 10.
    expect_at(
        &rule("\"dragon\"", "\"intact\"", "\"destroyed\"", "1"),
        9,
        10,
        &["dragon"],
    );
    // Line 10 `from = "open"` for a tree: column 8.
    expect_at(
        &rule("\"tree\"", "\"open\"", "\"destroyed\"", "1"),
        10,
        8,
        &["open", "tree"],
    );
    // Line 12 `range = 2`: column 9.
    expect_at(
        &rule("\"tree\"", "\"intact\"", "\"destroyed\"", "2"),
        12,
        9,
        &["range"],
    );
}

#[test]
fn a_file_name_is_kept_as_given() {
    let t = lines(&["name = \"t\"", "map = \"\"\"", "#X@#", "\"\"\""]);
    match parse_world(&t, "dir/My World.toml") {
        Err(WorldError::At {
            file, line, col, ..
        }) => {
            assert_eq!((file.as_str(), line, col), ("dir/My World.toml", 3, 2))
        }
        other => panic!("{other:?}"),
    }
}

// ---------------------------------------------------------------------------------
// Names and orders.

#[test]
fn objects_are_named_by_kind_and_reading_order() {
    //  #########
    //  #@..T..+#   row 1: tree (4,1), door (7,1)
    //  #.+.0..0#   row 2: door (2,2), boulder (4,2), boulder (7,2)
    //  #...=...#   row 3: wall (4,3)
    //  #########
    // Reading order is row by row: the door at (7,1) comes before the one at (2,2).
    let w = ok(&lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        "#########",
        "#@..T..+#",
        "#.+.0..0#",
        "#...=...#",
        "#########",
        "\"\"\"",
    ]));
    let got: Vec<(&str, ObjectKind, (u8, u8))> = w
        .objects
        .iter()
        .map(|o| (o.name.as_str(), o.kind, o.pos))
        .collect();
    assert_eq!(
        got,
        vec![
            ("tree", ObjectKind::Tree, (4, 1)),
            ("door#0", ObjectKind::Door, (7, 1)),
            ("door#1", ObjectKind::Door, (2, 2)),
            ("boulder#0", ObjectKind::Boulder, (4, 2)),
            ("boulder#1", ObjectKind::Boulder, (7, 2)),
            ("wall", ObjectKind::Wall, (4, 3)),
        ]
    );
    assert_eq!(w.object_index("door#1"), Some(2));
    assert_eq!(w.object_index("wall"), Some(5));
    assert_eq!(
        w.object_index("door"),
        None,
        "two doors: the bare kind is ambiguous"
    );
    // Initial state: boulders on their cells (y * 9 + x), everything else intact.
    assert_eq!(w.initial.objects[..6], [0, 0, 0, 2 * 9 + 4, 2 * 9 + 7, 0]);
    // A task can name them.
    let mut t = w.source.clone();
    t.push_str("[task]\nkind = \"destroy\"\nobjects = [\"door#1\", \"tree\"]\n");
    assert_eq!(ok(&t).task, Task::Destroy(vec![2, 0]));
}

#[test]
fn a_single_object_of_a_kind_is_named_by_its_kind() {
    let w = ok(&lines(&["name = \"t\"", "map = \"\"\"", "#@+T#", "\"\"\""]));
    let names: Vec<&str> = w.objects.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(names, ["door", "tree"]);
}

#[test]
fn tools_are_in_tools_order() {
    // Map order (one row, y = 0) a, m, z; [tools] order z, a, m. Tool k is the k-th [tools] entry, and a
    // kind listed twice is named kind#i in [tools] order.
    let w = ok(&lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        "#@a.m.z#",
        "\"\"\"",
        "[tools]",
        "z = \"key\"",
        "a = \"axe\"",
        "m = \"key\"",
    ]));
    let got: Vec<(char, &str, &str, (u8, u8))> = w
        .tools
        .iter()
        .map(|t| (t.letter, t.kind.as_str(), t.name.as_str(), t.pos))
        .collect();
    assert_eq!(
        got,
        vec![
            ('z', "key", "key#0", (6, 0)),
            ('a', "axe", "axe", (2, 0)),
            ('m', "key", "key#1", (4, 0))
        ]
    );
    // |A| = 5 + 3; select_k = 5 + k.
    assert_eq!(w.num_actions(), 8);
    assert_eq!(w.parse_action("key#1"), Some(7));
    assert_eq!(w.parse_action("axe"), Some(6));
}

#[test]
fn empowerment_section() {
    use fulcrum_world::{ObjectSet, ToolChoice};
    let base = lines(&[
        "name = \"t\"",
        "map = \"\"\"",
        "#@ak+0#",
        "\"\"\"",
        "[tools]",
        "a = \"axe\"",
        "k = \"key\"",
    ]);
    // One horizon given: it serves both (`docs/world.md`, the tool-object matrix).
    let w = ok(&format!("{base}[empowerment]\nhorizon_equipped = 5\n"));
    assert_eq!(
        (
            w.empowerment.horizon_unequipped,
            w.empowerment.horizon_equipped
        ),
        (5, 5)
    );
    let w = ok(&format!("{base}[empowerment]\nhorizon_unequipped = 7\n"));
    assert_eq!(
        (
            w.empowerment.horizon_unequipped,
            w.empowerment.horizon_equipped
        ),
        (7, 7)
    );
    // Both given: as written. A tool by kind is its [tools] index; objects are a set.
    let w = ok(&format!(
        "{base}[empowerment]\ntool = \"key\"\nobjects = [\"boulder\", \"door\"]\nhorizon_unequipped = 4\nhorizon_equipped = 2\nbeta = 0.5\n"
    ));
    let e = &w.empowerment;
    assert_eq!(e.tool, ToolChoice::Tool(1));
    // door (4,0) is object 0, boulder (5,0) object 1.
    assert_eq!(e.objects, Some(ObjectSet::Objects(vec![0, 1])));
    assert_eq!(
        (e.horizon_unequipped, e.horizon_equipped, e.beta),
        (4, 2, 0.5)
    );
    let w = ok(&format!(
        "{base}[empowerment]\ntool = \"all\"\nobjects = [\"agent\"]\n"
    ));
    assert_eq!(
        (w.empowerment.tool.clone(), w.empowerment.objects.clone()),
        (ToolChoice::All, Some(ObjectSet::Agent))
    );
    let w = ok(&format!("{base}[empowerment]\ntool = \"auto\"\n"));
    assert_eq!(w.empowerment.tool, ToolChoice::Auto);
    // The empowerment section's names are checked like the task's: line 9
    // `objects = ["tree"]`, the string at column 12.
    expect_at(
        &format!("{base}[empowerment]\nobjects = [\"tree\"]\n"),
        9,
        12,
        &["'tree'", "not on the map"],
    );
    // An unknown tool: line 9 `tool = "wand"`, column 8.
    expect_at(
        &format!("{base}[empowerment]\ntool = \"wand\"\n"),
        9,
        8,
        &["wand"],
    );
}

#[test]
fn max_steps_defaults_to_100() {
    let w = ok(&lines(&["name = \"t\"", "map = \"\"\"", "@.", "\"\"\""]));
    assert_eq!(w.max_steps, 100);
    assert_eq!(w.task, Task::None);
}

#[test]
fn builtin_worlds_load() {
    let names = |w: &World| -> (Vec<String>, Vec<String>) {
        (
            w.tools.iter().map(|t| t.name.clone()).collect(),
            w.objects.iter().map(|o| o.name.clone()).collect(),
        )
    };
    // From the files in worlds/ (tools in [tools] order, objects in reading order).
    struct Case {
        name: &'static str,
        tools: &'static [&'static str],
        objects: &'static [&'static str],
        agent: (u8, u8),
        max_steps: u32,
    }
    let case = |name, tools, objects, agent, max_steps| Case {
        name,
        tools,
        objects,
        agent,
        max_steps,
    };
    let cases = [
        case(
            "exp1-tree",
            &["axe", "pickaxe", "tin_opener", "key"],
            &["tree", "wall"],
            (1, 4),
            100,
        ),
        case(
            "exp1-wall",
            &["axe", "pickaxe", "tin_opener", "key"],
            &["tree", "wall"],
            (1, 4),
            100,
        ),
        // exp2: the boulder on row 1 comes before the door on row 4.
        case(
            "exp2",
            &["wand", "axe", "tin_opener", "katana"],
            &["boulder", "door"],
            (1, 6),
            100,
        ),
        // exp3: door (6,3) then boulder (7,3) on the same row.
        case("exp3", &["key", "axe"], &["door", "boulder"], (1, 4), 150),
        case("room", &["axe"], &["tree"], (1, 1), 50),
    ];
    for Case {
        name,
        tools,
        objects,
        agent,
        max_steps,
    } in cases
    {
        let w = load_world(name).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(w.name, name);
        let (t, o) = names(&w);
        assert_eq!(t, tools, "{name}");
        assert_eq!(o, objects, "{name}");
        assert_eq!((w.initial.x, w.initial.y), agent, "{name}");
        assert_eq!(w.max_steps, max_steps, "{name}");
        assert_eq!(w.num_actions(), 5 + tools.len(), "{name}");
    }
    assert_eq!(
        load_world("exp1-tree").unwrap().task,
        Task::Destroy(vec![0])
    );
    assert_eq!(
        load_world("exp1-wall").unwrap().task,
        Task::Destroy(vec![1])
    );
    assert_eq!(load_world("exp2").unwrap().task, Task::Destroy(vec![0, 1]));
    assert_eq!(load_world("exp3").unwrap().task, Task::Push(1));
    assert!(matches!(
        load_world("no-such-world"),
        Err(WorldError::Unknown(_))
    ));
}
