//! The dynamics of `docs/world.md`, case by case.
//!
//! Every expected value is derived by hand from `docs/world.md` (the reasoning is in the
//! comments), never read back from the code under test. States are built either by
//! stepping from a parsed world or by writing the packed fields documented in
//! `world/src/state.rs` directly: a tree, wall or door slot holds 0 intact/closed,
//! 1 open, 2 destroyed; a boulder slot holds its cell `y * width + x`, or `u16::MAX`
//! once destroyed.

use fulcrum_world::{parse_world, Episode, Mode, State, World};

// Action numbers (`docs/world.md`): N=0, E=1, S=2, W=3, apply=4, select_k = 5 + k.
const N: u8 = 0;
const E: u8 = 1;
const S: u8 = 2;
const W: u8 = 3;
const APPLY: u8 = 4;
const SEL: u8 = 5;

// Slot values of state.rs.
const INTACT: u16 = 0;
const CLOSED: u16 = 0;
const OPEN: u16 = 1;
const DESTROYED: u16 = 2;
const GONE: u16 = u16::MAX;

/// A world from map rows, `[tools]` entries (in this order) and extra TOML.
fn world(rows: &[&str], tools: &[(&str, &str)], extra: &str) -> World {
    let mut t = format!(
        "name = \"test\"\nmap = \"\"\"\n{}\n\"\"\"\n\n[tools]\n",
        rows.join("\n")
    );
    for (l, k) in tools {
        t.push_str(&format!("{l} = \"{k}\"\n"));
    }
    t.push_str(extra);
    parse_world(&t, "test.toml").unwrap_or_else(|e| panic!("{e}\n{t}"))
}

/// A one-row corridor with a rock border around it.
fn corridor(row: &str, tools: &[(&str, &str)], extra: &str) -> World {
    let border = "#".repeat(row.chars().count());
    world(&[&border, row, &border], tools, extra)
}

fn run(w: &World, s: &State, actions: &[u8]) -> State {
    actions.iter().fold(*s, |s, &a| w.step(&s, a))
}

/// apply, select_k, direction: the three steps of one tool use.
fn use_tool(w: &World, s: &State, k: u8, dir: u8) -> State {
    run(w, s, &[APPLY, SEL + k, dir])
}

/// Everything but the mode is equal.
fn same_but_mode(a: &State, b: &State) {
    assert_eq!((a.x, a.y), (b.x, b.y), "agent moved");
    assert_eq!(a.inventory, b.inventory, "inventory changed");
    assert_eq!(a.objects, b.objects, "objects changed");
}

#[test]
fn action_numbers_are_those_of_world_md() {
    use fulcrum_world as f;
    assert_eq!(
        [f::NORTH, f::EAST, f::SOUTH, f::WEST, f::APPLY, f::SELECT0],
        [N, E, S, W, APPLY, SEL]
    );
    // |A| = 5 + n.
    let w = corridor("#@ab#", &[("a", "axe"), ("b", "key")], "");
    assert_eq!(w.num_actions(), 7);
    // A^{T_1} = {N, E, S, W, apply, select_1}.
    assert_eq!(w.tool_actions(1), [N, E, S, W, APPLY, SEL + 1]);
}

// ---------------------------------------------------------------------------------
// The default rule table.

/// What one use of a tool leaves in the target's slot.
#[derive(Clone, Copy, Debug)]
enum Want {
    Unchanged,
    To(u16),
}

#[test]
fn default_rule_table_at_range_one() {
    use Want::*;
    // `#@tX.#` (width 6): E picks the tool up (agent on (2,1)); apply, select_0, E uses
    // it on X at (3,1). X is object 0; an intact boulder's slot is 1 * 6 + 3 = 9.
    // Expected from the table: axe: tree, door -> destroyed; pickaxe: wall, door, boulder
    // -> destroyed; key: closed door -> open; wand (bolt, starting next to the agent):
    // boulder, door -> destroyed; tin_opener, katana: nothing.
    let d = To(DESTROYED);
    let cases: [(&str, [Want; 4]); 6] = [
        //              T          =          +          0
        ("axe", [d, Unchanged, d, Unchanged]),
        ("pickaxe", [Unchanged, d, d, To(GONE)]),
        ("key", [Unchanged, Unchanged, To(OPEN), Unchanged]),
        ("wand", [Unchanged, Unchanged, d, To(GONE)]),
        ("tin_opener", [Unchanged; 4]),
        ("katana", [Unchanged; 4]),
    ];
    for (tool, wants) in cases {
        for (glyph, want) in ['T', '=', '+', '0'].into_iter().zip(wants) {
            let w = corridor(&format!("#@t{glyph}.#"), &[("t", tool)], "");
            let held = w.step(&w.initial, E);
            assert_eq!(
                (held.x, held.y, held.inventory),
                (2, 1, 1),
                "{tool} on {glyph}"
            );
            let before = held.objects[0];
            let after = use_tool(&w, &held, 0, E);
            let ctx = format!("{tool} on {glyph}");
            // Three steps, and the agent is back in normal mode where it stood.
            assert_eq!(after.mode(), Mode::Normal, "{ctx}");
            assert_eq!((after.x, after.y, after.inventory), (2, 1, 1), "{ctx}");
            let expect = match want {
                Unchanged => before,
                To(v) => v,
            };
            assert_eq!(after.objects[0], expect, "{ctx}");
            // Walking east afterwards: a destroyed object leaves floor and an open door
            // lets the agent in; an intact boulder is pushed to (4,1) = slot 10; anything
            // else that is intact blocks.
            let walked = w.step(&after, E);
            let passable = matches!(want, To(DESTROYED) | To(OPEN) | To(GONE));
            if passable {
                assert_eq!((walked.x, walked.y), (3, 1), "{ctx}: walk in");
            } else if glyph == '0' {
                assert_eq!(
                    (walked.x, walked.y, walked.objects[0]),
                    (3, 1, 10),
                    "{ctx}: push"
                );
            } else {
                assert_eq!(walked, after, "{ctx}: blocked");
            }
        }
    }
}

#[test]
fn key_opens_and_closes_a_door() {
    // `#@k+.#`: the key is picked up at (2,1), the door is at (3,1).
    let w = corridor("#@k+.#", &[("k", "key")], "");
    let s = w.step(&w.initial, E);
    let opened = use_tool(&w, &s, 0, E);
    assert_eq!(opened.objects[0], OPEN);
    let closed = use_tool(&w, &opened, 0, E);
    assert_eq!(closed.objects[0], CLOSED);
    // And open again: the key toggles for ever.
    assert_eq!(use_tool(&w, &closed, 0, E).objects[0], OPEN);
    // A closed door blocks the agent, an open one does not.
    assert_eq!(w.step(&closed, E), closed);
    assert_eq!((w.step(&opened, E).x, w.step(&opened, E).y), (3, 1));
}

#[test]
fn key_and_axe_do_not_reach_two_cells() {
    // Range 1: `#@k.+#` leaves the door closed, `#@a.T#` the tree intact.
    for (row, tool) in [("#@k.+#", "key"), ("#@a.T#", "axe"), ("#@p.=#", "pickaxe")] {
        let w = corridor(row, &[(&row[2..3], tool)], "");
        let s = w.step(&w.initial, E);
        let after = use_tool(&w, &s, 0, E);
        same_but_mode(&after, &s);
        assert_eq!(after.objects[0], INTACT, "{row}");
    }
}

#[test]
fn a_tool_acts_in_the_chosen_direction_only() {
    // Agent at (2,2) holding the axe, trees at N (2,1) = tree#0, W (1,2) = tree#1,
    // E (3,2) = tree#2, S (2,3) = tree#3 (reading order). N is y - 1.
    let w = world(
        &["#####", "#aT.#", "#T@T#", "#.T.#", "#####"],
        &[("a", "axe")],
        "",
    );
    let mut s = w.initial;
    s.inventory = 1;
    for (dir, tree) in [(N, 0), (E, 2), (S, 3), (W, 1)] {
        let after = use_tool(&w, &s, 0, dir);
        for i in 0..4 {
            let want = if i == tree { DESTROYED } else { INTACT };
            assert_eq!(after.objects[i], want, "direction {dir}, tree#{i}");
        }
    }
}

#[test]
fn a_tool_without_a_rule_still_spends_its_steps() {
    // `#@oT.#` with a tin opener, then with a katana: E, apply, select, E is four
    // steps; the tree stays intact and the agent is back in normal mode on (2,1).
    for kind in ["tin_opener", "katana"] {
        let w = corridor("#@oT.#", &[("o", kind)], "");
        let mut ep: Episode = w.reset();
        for a in [E, APPLY, SEL, E] {
            w.env_step(&mut ep, a);
        }
        assert_eq!(ep.t, 4, "{kind}");
        assert_eq!(ep.state.mode(), Mode::Normal);
        assert_eq!((ep.state.x, ep.state.y, ep.state.inventory), (2, 1, 1));
        assert_eq!(ep.state.objects[0], INTACT);
        // The middle steps really were prompts.
        let a1 = w.step(&w.step(&w.initial, E), APPLY);
        assert_eq!(a1.mode(), Mode::ChoosingTool);
        assert_eq!(w.step(&a1, SEL).mode(), Mode::ChoosingDirection(0));
    }
}

// ---------------------------------------------------------------------------------
// The mode table.

/// `#.@aT.#` over `#..b..#`: agent (2,1), axe (tool 0) at (3,1), tree at (4,1), key
/// (tool 1) at (3,2).
fn mode_world() -> World {
    world(
        &["#######", "#.@aT.#", "#..b..#", "#######"],
        &[("a", "axe"), ("b", "key")],
        "",
    )
}

#[test]
fn normal_mode_apply_and_select_without_tools_do_nothing() {
    let w = mode_world();
    let s = w.initial;
    assert_eq!(s.inventory, 0);
    // apply with an empty inventory: nothing; select_k in normal mode: nothing.
    for a in [APPLY, SEL, SEL + 1] {
        assert_eq!(w.step(&s, a), s, "action {a}");
    }
}

#[test]
fn normal_mode_select_with_a_tool_held_does_nothing() {
    let w = mode_world();
    let h = w.step(&w.initial, E); // axe picked up at (3,1)
    assert_eq!((h.x, h.y, h.inventory), (3, 1, 0b01));
    for a in [SEL, SEL + 1] {
        assert_eq!(w.step(&h, a), h, "action {a}");
    }
}

#[test]
fn choosing_tool_transitions() {
    let w = mode_world();
    let h = w.step(&w.initial, E); // normal, holding the axe, at (3,1)
    let ct = w.step(&h, APPLY);
    assert_eq!(ct.mode(), Mode::ChoosingTool);
    same_but_mode(&ct, &h);

    // select_0, the axe is held: choosing-direction(0).
    let cd = w.step(&ct, SEL);
    assert_eq!(cd.mode(), Mode::ChoosingDirection(0));
    same_but_mode(&cd, &h);

    // select_1, the key is not held: back to normal, nothing else.
    assert_eq!(w.step(&ct, SEL + 1), h);

    // Moves: back to normal and the agent does not move. From (3,1) a real W would
    // reach (2,1), a real S would pick up the key at (3,2): neither happens.
    for d in [N, E, S, W] {
        assert_eq!(w.step(&ct, d), h, "direction {d} in choosing-tool");
    }
    // apply again: back to normal.
    assert_eq!(w.step(&ct, APPLY), h);
}

#[test]
fn choosing_direction_transitions() {
    let w = mode_world();
    let h = w.step(&w.initial, E);
    let cd = run(&w, &h, &[APPLY, SEL]);
    assert_eq!(cd.mode(), Mode::ChoosingDirection(0));
    // apply or select: back to normal, nothing else (the tree east stays intact).
    for a in [APPLY, SEL, SEL + 1] {
        assert_eq!(w.step(&cd, a), h, "action {a} in choosing-direction");
    }
    // A direction uses the tool, back to normal: E chops the tree at (4,1).
    let chopped = w.step(&cd, E);
    assert_eq!(chopped.mode(), Mode::Normal);
    assert_eq!((chopped.x, chopped.y), (3, 1));
    assert_eq!(chopped.objects[0], DESTROYED);
    // A direction with nothing to act on (W: floor (2,1); S: the key's cell) still ends
    // the prompt, and the agent does not move nor pick the key up.
    for d in [W, S, N] {
        assert_eq!(w.step(&cd, d), h, "direction {d}");
    }
}

#[test]
fn choosing_direction_uses_the_selected_tool() {
    // Holding both axe (0) and key (1) in front of a closed door at (4,1):
    // select_1 then E opens it (key), select_0 then E destroys it (axe).
    let w = world(
        &["######", "#@ak+#", "######"],
        &[("a", "axe"), ("k", "key")],
        "",
    );
    let s = run(&w, &w.initial, &[E, E]);
    assert_eq!((s.x, s.y, s.inventory), (3, 1, 0b11));
    assert_eq!(use_tool(&w, &s, 1, E).objects[0], OPEN);
    assert_eq!(use_tool(&w, &s, 0, E).objects[0], DESTROYED);
}

// ---------------------------------------------------------------------------------
// Moving and picking up.

#[test]
fn walking_onto_tools_picks_them_up_in_tools_order() {
    // [tools] lists b first: b = key is tool 0, a = axe is tool 1.
    let w = corridor("#@ab.#", &[("b", "key"), ("a", "axe")], "");
    let s1 = w.step(&w.initial, E); // onto 'a' = tool 1
    assert_eq!((s1.x, s1.y, s1.inventory), (2, 1, 0b10));
    let s2 = w.step(&s1, E); // onto 'b' = tool 0
    assert_eq!((s2.x, s2.y, s2.inventory), (3, 1, 0b11));
    // Walking back over the empty cells changes nothing but the position.
    let back = run(&w, &s2, &[W, W]);
    assert_eq!((back.x, back.y, back.inventory), (1, 1, 0b11));
}

#[test]
fn what_blocks_the_agent() {
    // Row `#@X.#`, agent at (1,1) walking E onto (2,1).
    // Rock (#, -, |, space), intact tree, intact wall and a closed door block.
    for g in ['#', '-', '|', ' ', 'T', '=', '+'] {
        let w = corridor(&format!("#@{g}.#"), &[], "");
        assert_eq!(w.step(&w.initial, E), w.initial, "glyph {g:?}");
    }
    // Floor, goal, an open door and destroyed objects do not.
    for (g, slot) in [
        ('.', None),
        ('>', None),
        ('+', Some(OPEN)),
        ('+', Some(DESTROYED)),
        ('T', Some(DESTROYED)),
        ('=', Some(DESTROYED)),
    ] {
        let w = corridor(&format!("#@{g}.#"), &[], "");
        let mut s = w.initial;
        if let Some(v) = slot {
            s.objects[0] = v;
        }
        let n = w.step(&s, E);
        assert_eq!((n.x, n.y), (2, 1), "glyph {g:?} slot {slot:?}");
        assert_eq!(n.objects, s.objects);
    }
}

#[test]
fn the_map_edge_blocks_the_agent() {
    // A map with no border: the agent on (0,0) of a 2x2 map cannot leave it.
    let w = world(&["@.", ".."], &[], "");
    assert_eq!(w.step(&w.initial, N), w.initial);
    assert_eq!(w.step(&w.initial, W), w.initial);
    let se = run(&w, &w.initial, &[E, S]);
    assert_eq!((se.x, se.y), (1, 1));
    assert_eq!(w.step(&se, E), se);
    assert_eq!(w.step(&se, S), se);
}

// ---------------------------------------------------------------------------------
// Pushing boulders.

/// `[tools]` entries of a case.
type Tools = Vec<(&'static str, &'static str)>;
/// Changes made to the initial state before a case runs.
type Setup = Box<dyn Fn(&mut State)>;

/// Row `#@0X...#`: the agent at (1,1) pushes the boulder (object 0, at (2,1)) east
/// toward (3,1). Returns (state before, state after).
fn push_east(
    row: &str,
    tools: &[(&str, &str)],
    setup: impl Fn(&mut State),
) -> (World, State, State) {
    let w = corridor(row, tools, "");
    let mut s = w.initial;
    setup(&mut s);
    let n = w.step(&s, E);
    (w, s, n)
}

#[test]
fn a_boulder_does_not_move_into_blockers() {
    let none = |_: &mut State| {};
    let blocked: Vec<(&str, Tools, &str)> = vec![
        ("#@0#", vec![], "rock #"),
        ("#@0-.#", vec![], "rock -"),
        ("#@0|.#", vec![], "rock |"),
        ("#@0 .#", vec![], "solid rock (space)"),
        ("#@0T.#", vec![], "intact tree"),
        ("#@0=.#", vec![], "intact wall block"),
        ("#@0+.#", vec![], "closed door"),
        ("#@00.#", vec![], "another boulder"),
        ("#@0a.#", vec![("a", "axe")], "a tool lying on the floor"),
    ];
    for (row, tools, what) in blocked {
        let (_, s, n) = push_east(row, &tools, none);
        // Nothing moves: the agent stays on (1,1), the boulder on (2,1).
        assert_eq!(n, s, "{what}");
    }
}

#[test]
fn a_boulder_does_not_move_past_the_map_edge() {
    // East: `@0` is the whole map; the cell beyond the boulder is outside.
    let w = world(&["@0"], &[], "");
    assert_eq!(w.step(&w.initial, E), w.initial);
    // South: a one-column map, boulder on the last row.
    let w = world(&["@", "0"], &[], "");
    assert_eq!(w.step(&w.initial, S), w.initial);
}

#[test]
fn a_boulder_moves_onto_free_cells() {
    // Width 6, row 1: the boulder ends on (3,1) = slot 1 * 6 + 3 = 9, the agent on (2,1).
    let no_tools: Tools = vec![];
    let set1 = |v: u16| move |s: &mut State| s.objects[1] = v;
    let cases: Vec<(&str, Tools, Setup, &str)> = vec![
        (
            "#@0..#",
            no_tools.clone(),
            Box::new(|_: &mut State| {}),
            "floor",
        ),
        (
            "#@0>.#",
            no_tools.clone(),
            Box::new(|_: &mut State| {}),
            "goal",
        ),
        (
            "#@0+.#",
            no_tools.clone(),
            Box::new(set1(OPEN)),
            "open door",
        ),
        (
            "#@0+.#",
            no_tools.clone(),
            Box::new(set1(DESTROYED)),
            "destroyed door",
        ),
        (
            "#@0T.#",
            no_tools.clone(),
            Box::new(set1(DESTROYED)),
            "destroyed tree",
        ),
        (
            "#@0=.#",
            no_tools.clone(),
            Box::new(set1(DESTROYED)),
            "destroyed wall",
        ),
        (
            "#@00.#",
            no_tools.clone(),
            Box::new(set1(GONE)),
            "destroyed boulder",
        ),
        // The tool's cell once the tool has been picked up (it left the map).
        (
            "#@0a.#",
            vec![("a", "axe")],
            Box::new(|s: &mut State| s.inventory = 1),
            "held tool's cell",
        ),
    ];
    for (row, tools, setup, what) in cases {
        let (_, s, n) = push_east(row, &tools, setup);
        assert_eq!((n.x, n.y), (2, 1), "{what}: agent");
        assert_eq!(n.objects[0], 9, "{what}: boulder");
        assert_eq!(n.objects[1..], s.objects[1..], "{what}: others");
        assert_eq!(n.inventory, s.inventory, "{what}: inventory");
    }
}

#[test]
fn pushes_in_all_four_directions() {
    // Agent at (3,3) of a 7x7 room, boulders N (3,2), W (2,3), E (4,3), S (3,4)
    // (reading order: boulder#0 N, #1 W, #2 E, #3 S). Width 7.
    let w = world(
        &[
            "#######", "#.....#", "#..0..#", "#.0@0.#", "#..0..#", "#.....#", "#######",
        ],
        &[],
        "",
    );
    let cell = |x: u16, y: u16| y * 7 + x;
    for (dir, b, to) in [
        (N, 0, cell(3, 1)),
        (W, 1, cell(1, 3)),
        (E, 2, cell(5, 3)),
        (S, 3, cell(3, 5)),
    ] {
        let n = w.step(&w.initial, dir);
        assert_eq!(n.objects[b], to, "direction {dir}");
        // The agent takes the boulder's old cell.
        assert_eq!(
            cell(n.x as u16, n.y as u16),
            w.initial.objects[b],
            "direction {dir}"
        );
    }
}

#[test]
fn a_boulder_can_be_pushed_through_an_opened_door_and_the_key_cannot_close_on_it() {
    // ########
    // #@k....#     agent (1,1), key (2,1)
    // #...0+.#     boulder (4,2) = object 0, door (5,2) = object 1
    // ########
    let w = world(
        &["########", "#@k....#", "#...0+.#", "########"],
        &[("k", "key")],
        "",
    );
    let cell = |x: u16, y: u16| y * 8 + x;
    // Pick the key up, walk to (5,1) above the door and open it southwards.
    let s = run(&w, &w.initial, &[E, E, E, E]);
    assert_eq!((s.x, s.y, s.inventory), (5, 1, 1));
    let s = use_tool(&w, &s, 0, S);
    assert_eq!(s.objects[1], OPEN);
    // To (3,2), then E pushes the boulder into the open doorway (5,2).
    let s = run(&w, &s, &[W, W, S]);
    assert_eq!((s.x, s.y), (3, 2));
    let s = w.step(&s, E);
    assert_eq!((s.x, s.y), (4, 2));
    assert_eq!(s.objects[0], cell(5, 2));
    // The key cannot close the door while the boulder stands in the doorway; the boulder
    // is not touched either (the key has no boulder rule).
    let refused = use_tool(&w, &s, 0, E);
    assert_eq!(refused.objects[1], OPEN);
    assert_eq!(refused.objects[0], cell(5, 2));
    same_but_mode(&refused, &s);
    // Push on: the boulder to (6,2), the agent into the doorway; step back out W and the
    // key closes the empty doorway.
    let s = w.step(&s, E);
    assert_eq!((s.x, s.y, s.objects[0]), (5, 2, cell(6, 2)));
    let s = w.step(&s, W);
    assert_eq!(use_tool(&w, &s, 0, E).objects[1], CLOSED);
}

// ---------------------------------------------------------------------------------
// Bolts.

/// Row `#@w.X.0.#` (width 9): the agent picks the wand up at (2,1) and zaps E. The bolt
/// visits (3,1), X at (4,1), (5,1), then the boulder at (6,1).
fn zap_east(
    mid: char,
    tools: &[(&str, &str)],
    setup: impl Fn(&mut State),
) -> (World, State, State) {
    let mut all = vec![("w", "wand")];
    all.extend_from_slice(tools);
    let w = corridor(&format!("#@w.{mid}.0.#"), &all, "");
    let mut s = w.step(&w.initial, E);
    assert_eq!((s.x, s.y, s.inventory & 1), (2, 1, 1));
    setup(&mut s);
    let n = use_tool(&w, &s, 0, E);
    assert_eq!(n.mode(), Mode::Normal);
    assert_eq!((n.x, n.y), (2, 1));
    (w, s, n)
}

#[test]
fn a_bolt_stops_at_blockers() {
    let none = |_: &mut State| {};
    // Rock of every glyph: the far boulder (object 0) stays where it is (slot 1*9+6 = 15).
    for g in ['#', '-', '|', ' '] {
        let (_, s, n) = zap_east(g, &[], none);
        assert_eq!(n.objects[0], 15, "rock {g:?}");
        same_but_mode(&n, &s);
    }
    // An intact tree or wall block (no wand rule): nothing changes at all.
    for g in ['T', '='] {
        let (_, s, n) = zap_east(g, &[], none);
        assert_eq!((n.objects[0], n.objects[1]), (INTACT, 15), "{g}");
        same_but_mode(&n, &s);
    }
    // A closed door: the bolt destroys it and stops; the boulder behind is intact.
    let (_, _, n) = zap_east('+', &[], none);
    assert_eq!((n.objects[0], n.objects[1]), (DESTROYED, 15));
    // An intact boulder: destroyed, and the bolt stops; the far boulder is intact.
    let (_, _, n) = zap_east('0', &[], none);
    assert_eq!((n.objects[0], n.objects[1]), (GONE, 15));
}

#[test]
fn a_bolt_passes_over_what_does_not_block() {
    // The far boulder is destroyed in each case; what the bolt passed over is unchanged.
    let none = |_: &mut State| {};
    for g in ['.', '>'] {
        let (_, _, n) = zap_east(g, &[], none);
        assert_eq!(n.objects[0], GONE, "{g:?}");
    }
    let set0 = |v: u16| move |s: &mut State| s.objects[0] = v;
    for (g, v, what) in [
        ('+', OPEN, "open door"),
        ('+', DESTROYED, "destroyed door"),
        ('T', DESTROYED, "destroyed tree"),
        ('=', DESTROYED, "destroyed wall"),
        ('0', GONE, "destroyed boulder"),
    ] {
        let (_, _, n) = zap_east(g, &[], set0(v));
        assert_eq!((n.objects[0], n.objects[1]), (v, GONE), "{what}");
    }
    // A lying tool: passed over and not picked up.
    let (_, s, n) = zap_east('a', &[("a", "axe")], none);
    assert_eq!(n.objects[0], GONE);
    assert_eq!(n.inventory, s.inventory);
    assert_eq!(n.inventory, 0b01);
}

#[test]
fn a_bolt_hits_a_boulder_standing_in_an_open_doorway() {
    // `#@w.+.0.#`: the door (object 0) opened and the boulder (object 1) moved into the
    // doorway (4,1) = slot 13. The first cell with an object the wand has a rule for in
    // its current state is (4,1): the open door has none, the boulder has one.
    let (_, _, n) = zap_east('+', &[], |s: &mut State| {
        s.objects[0] = OPEN;
        s.objects[1] = 13;
    });
    assert_eq!((n.objects[0], n.objects[1]), (OPEN, GONE));
}

#[test]
fn a_bolt_stops_at_the_map_edge() {
    // No border: `@w...`, the wand picked up on (1,0). Nothing to hit in any direction.
    let w = world(&["@w..."], &[("w", "wand")], "");
    let s = w.step(&w.initial, E);
    for d in [N, E, S, W] {
        let n = use_tool(&w, &s, 0, d);
        assert_eq!(n, s, "direction {d}");
    }
    // A boulder on the last column is still reached.
    let w = world(&["@w..0"], &[("w", "wand")], "");
    let s = w.step(&w.initial, E);
    assert_eq!(use_tool(&w, &s, 0, E).objects[0], GONE);
}

// ---------------------------------------------------------------------------------
// [[rules]].

fn rule(tool: &str, target: &str, from: &str, to: &str, range: &str) -> String {
    format!("\n[[rules]]\ntool = \"{tool}\"\ntarget = \"{target}\"\nfrom = \"{from}\"\nto = \"{to}\"\nrange = {range}\n")
}

#[test]
fn a_rule_makes_the_tin_opener_open_doors() {
    let extra = rule("tin_opener", "door", "closed", "open", "1");
    let w = corridor("#@o+.#", &[("o", "tin_opener")], &extra);
    let s = w.step(&w.initial, E);
    let n = use_tool(&w, &s, 0, E);
    assert_eq!(n.objects[0], OPEN);
    assert_eq!((w.step(&n, E).x, w.step(&n, E).y), (3, 1));
    // The rule adds only closed -> open: no closing again.
    assert_eq!(use_tool(&w, &n, 0, E).objects[0], OPEN);
    // Range 1: a door two cells away stays closed.
    let w = corridor("#@o.+#", &[("o", "tin_opener")], &extra);
    let s = w.step(&w.initial, E);
    assert_eq!(use_tool(&w, &s, 0, E).objects[0], CLOSED);
    // Without the rule the tin opener does nothing.
    let w = corridor("#@o+.#", &[("o", "tin_opener")], "");
    let s = w.step(&w.initial, E);
    assert_eq!(use_tool(&w, &s, 0, E).objects[0], CLOSED);
}

#[test]
fn a_bolt_rule_for_a_new_tool_kind() {
    // A "staff" (unknown kind, a distractor without rules) that burns trees by bolt.
    let extra = rule("staff", "tree", "intact", "destroyed", "\"bolt\"");
    // `#@s..T.#`: from (2,1) the bolt crosses (3,1), (4,1) and burns the tree at (5,1).
    let w = corridor("#@s..T.#", &[("s", "staff")], &extra);
    let s = w.step(&w.initial, E);
    assert_eq!(use_tool(&w, &s, 0, E).objects[0], DESTROYED);
    // Whatever blocks bolts stops it: rock, an intact wall block, a closed door, an
    // intact boulder (the staff has no rule for any of them, so only blocking stops it).
    // `#@s.XT.#`: the tree at (5,1) is the last object.
    for x in ['#', '=', '+', '0'] {
        let w = corridor(&format!("#@s.{x}T.#"), &[("s", "staff")], &extra);
        let s = w.step(&w.initial, E);
        let n = use_tool(&w, &s, 0, E);
        same_but_mode(&n, &s);
        assert_eq!(n.objects[w.objects.len() - 1], INTACT, "{x}");
    }
    // A lying tool and an open door let it pass.
    let w = corridor("#@s.aT.#", &[("s", "staff"), ("a", "axe")], &extra);
    let s = w.step(&w.initial, E);
    assert_eq!(use_tool(&w, &s, 0, E).objects[0], DESTROYED);
    let w = corridor("#@s.+T.#", &[("s", "staff")], &extra);
    let mut s = w.step(&w.initial, E);
    s.objects[0] = OPEN;
    assert_eq!(use_tool(&w, &s, 0, E).objects[1], DESTROYED);
    // Without the rule the staff is a distractor.
    let w = corridor("#@s..T.#", &[("s", "staff")], "");
    let s = w.step(&w.initial, E);
    assert_eq!(use_tool(&w, &s, 0, E).objects[0], INTACT);
}

#[test]
fn range_one_rules_of_a_bolt_tool_act_next_to_the_agent_only() {
    // The wand gets a range-1 rule for trees. A bolt applies bolt rules only: a tree two
    // cells away is not felled (and, being intact, stops the bolt); a tree next to the
    // agent is.
    let extra = rule("wand", "tree", "intact", "destroyed", "1");
    let w = corridor("#@w.T0#", &[("w", "wand")], &extra);
    let s = w.step(&w.initial, E);
    let n = use_tool(&w, &s, 0, E);
    assert_eq!((n.objects[0], n.objects[1]), (INTACT, 12)); // the boulder stays on (5,1) = 1 * 7 + 5
    let w = corridor("#@wT.#", &[("w", "wand")], &extra);
    let s = w.step(&w.initial, E);
    assert_eq!(use_tool(&w, &s, 0, E).objects[0], DESTROYED);
    // The same for a door two cells away: it stays closed and stops the bolt.
    let extra = rule("wand", "door", "open", "closed", "1");
    let w = corridor("#@w.+.#", &[("w", "wand")], &extra);
    let mut s = w.step(&w.initial, E);
    s.objects[0] = OPEN;
    assert_eq!(use_tool(&w, &s, 0, E).objects[0], OPEN);
}

#[test]
fn a_rule_extends_an_existing_tool_and_keeps_its_defaults() {
    // axe breaks boulders too; it still fells trees.
    let extra = rule("axe", "boulder", "intact", "destroyed", "1");
    let w = corridor("#@a0.#", &[("a", "axe")], &extra);
    let s = w.step(&w.initial, E);
    assert_eq!(use_tool(&w, &s, 0, E).objects[0], GONE);
    let w = corridor("#@aT.#", &[("a", "axe")], &extra);
    let s = w.step(&w.initial, E);
    assert_eq!(use_tool(&w, &s, 0, E).objects[0], DESTROYED);
}

// ---------------------------------------------------------------------------------
// The state.

#[test]
fn the_step_counter_is_not_part_of_the_state() {
    // E then W returns to the start cell: the same state, byte for byte, as the initial
    // one, although two steps were taken.
    let w = corridor("#@..#", &[], "");
    let back = run(&w, &w.initial, &[E, W]);
    assert_eq!(back, w.initial);
    assert_eq!(back.to_bytes(), w.initial.to_bytes());
    // The packed state is agent (2) + mode (1) + reserved (1) + inventory (2) + 16
    // object slots (32) = 38 bytes: no room for a counter.
    assert_eq!(std::mem::size_of::<State>(), 38);
}

#[test]
fn actions_out_of_range_act_as_stay() {
    // Two tools: |A| = 7, so 7.. are out of range. In normal mode they change nothing,
    // with or without a tool held.
    let w = mode_world();
    let held = w.step(&w.initial, E);
    for s in [w.initial, held] {
        for a in [7u8, 8, 21, 100, 255] {
            assert_eq!(w.step(&s, a), s, "action {a}");
        }
    }
    // In a prompt an out-of-range action is "anything else" of the choosing-tool row
    // and not a direction in choosing-direction: back to normal, nothing else.
    for prompt in [run(&w, &held, &[APPLY]), run(&w, &held, &[APPLY, SEL])] {
        for a in [7u8, 255] {
            assert_eq!(
                w.step(&prompt, a),
                held,
                "action {a} in {:?}",
                prompt.mode()
            );
        }
    }
}
