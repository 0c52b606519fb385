//! Empowerment of a family's layouts computed on demand (the family service's tables)
//! against the engine on the same layout written out as a world file and read back, at
//! every state, for 50 layouts drawn at random from the training and held-out seeds of
//! `toolbox`.
//!
//! The two routes share the engine's propagation but nothing else: the table is made
//! from the layout in memory, its tool chosen per layout by the tables and its values
//! from one propagation over every horizon; the reference reads the layout's TOML text
//! as any world file is read, selects the tool from the engine's matrix at the layout's
//! one selection horizon, its `horizon_unequipped` (the paper's equation 6) and asks `Engine::values` once per horizon, choosing the horizon by what
//! each state holds by hand.

use fulcrum_empowerment::service::{FamilyConfig, FamilyTables};
use fulcrum_empowerment::{Engine, Limits, Method, StateSpace, ToolSel};
use fulcrum_world::family::load_family;
use fulcrum_world::{parse_world, HELD_OUT_START};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const HU: u32 = 8;
const HE: u32 = 3;

/// The family service's settings with the family's tool and horizons.
fn config(horizon_sum: bool, task_conditions: bool, cache_bytes: usize, keep: u64) -> FamilyConfig {
    FamilyConfig {
        tool: None,
        horizon_unequipped: HU,
        horizon_equipped: HE,
        horizon_sum,
        task_conditions,
        cache_bytes,
        keep,
    }
}

fn tables(horizon_sum: bool) -> FamilyTables {
    FamilyTables::new(
        load_family("toolbox").unwrap(),
        config(horizon_sum, false, 1 << 20, 2),
    )
    .unwrap()
}

#[test]
fn tables_made_on_demand_equal_the_engine_on_the_layout_written_out() {
    let family = load_family("toolbox").unwrap();
    let (mut e_tables, mut phi_tables) = (tables(false), tables(true));
    let mut rng = ChaCha8Rng::seed_from_u64(27);
    let mut states = 0usize;
    for k in 0..50 {
        // Half from the training seeds, half held out.
        let seed = if k % 2 == 0 {
            rng.random_range(0..1_000_000)
        } else {
            HELD_OUT_START + rng.random_range(0..1_000_000)
        };
        let text = family.layout_text(seed).unwrap();
        let w = parse_world(&text, &format!("toolbox-{seed}.toml")).unwrap();
        let engine = Engine::new(&w, Limits::default()).unwrap();
        // One task object per toolbox layout: it is the column.
        assert_eq!(w.objects.len(), 1, "layout {seed}");
        let set = fulcrum_world::ObjectSet::Objects(vec![0]);
        let h = w.empowerment.horizon_unequipped;
        let m = engine
            .matrix(std::slice::from_ref(&set), h, h, Method::Dp)
            .unwrap();
        let tool = ToolSel::Tool(m.selection[0].expect("a tool fits every toolbox layout"));
        let by_h: Vec<Vec<f64>> = (1..=HU)
            .map(|h| engine.values(tool, &set, h, Method::Dp).unwrap())
            .collect();
        let space = StateSpace::enumerate(&w, &Limits::default()).unwrap();
        for s in space.states() {
            let id = engine.state_id(s).unwrap() as usize;
            let h = if tool.held(s) { HE } else { HU };
            let e = by_h[h as usize - 1][id] as f32;
            let phi = by_h.iter().map(|v| v[id]).sum::<f64>() as f32;
            assert_eq!(e_tables.lookup(seed, s), Some(e), "layout {seed}, {s:?}");
            assert_eq!(
                phi_tables.lookup(seed, s),
                Some(phi),
                "layout {seed}, {s:?}"
            );
            states += 1;
        }
        // A state of no layout is not answered.
        let mut off = w.initial;
        off.x = 200;
        assert_eq!(e_tables.lookup(seed, &off), None);
    }
    assert!(states > 50 * 1000, "{states} states compared");
    assert_eq!(e_tables.stats.made, 2 + 50);
}

/// The tables outgrowing the cache drop the oldest layouts beyond the kept ones, and a
/// dropped layout asked for again is made again, to the same values.
#[test]
fn the_cache_drops_the_oldest_layouts_and_keeps_the_first() {
    let family = load_family("toolbox").unwrap();
    let mut t = FamilyTables::new(
        family.clone(),
        // Room for one layout beyond the kept one, at most (a tree's table is ~46 KB:
        // 1,990 values and a direct index of 9,600 keys; a boulder's ~1.2 MB), so every
        // layout made evicts the one before.
        config(true, false, 60 << 10, 1),
    )
    .unwrap();
    let start = |seed| family.layout(seed).unwrap().initial;
    let first: Vec<Option<f32>> = (0..20).map(|seed| t.lookup(seed, &start(seed))).collect();
    assert!(first.iter().all(Option::is_some));
    assert_eq!(t.stats.made, 20);
    assert!(t.stats.dropped > 0, "{:?}", t.stats);
    let dropped = t.stats.dropped;
    // Layout 0 is kept: asking again makes nothing.
    assert_eq!(t.lookup(0, &start(0)), first[0]);
    assert_eq!(t.stats.made, 20);
    // Layout 1 was the oldest beyond it: made again, the same value.
    assert_eq!(t.lookup(1, &start(1)), first[1]);
    assert_eq!(t.stats.made, 21);
    assert!(t.stats.dropped > dropped);
}

/// A run of a potential form counts a layout's boulder by its condition
/// (`task_conditions`): the family's table is the engine's over `conditions:boulder` on
/// the layout written out, Phi = max(0, H + 1 - d) a whole number of bits (the values
/// themselves are checked against a search in `conditions.rs`).
#[test]
fn a_potential_runs_tables_count_a_boulder_by_its_condition() {
    let family = load_family("toolbox").unwrap();
    let mut t = FamilyTables::new(family.clone(), config(true, true, 1 << 30, 0)).unwrap();
    let mut boulders = 0;
    for seed in 0..200u64 {
        let w = parse_world(&family.layout_text(seed).unwrap(), "layout.toml").unwrap();
        if w.objects[0].kind != fulcrum_world::ObjectKind::Boulder {
            continue;
        }
        let engine = Engine::new(&w, Limits::default()).unwrap();
        let full = fulcrum_world::ObjectSet::Objects(vec![0]);
        let cond = full.conditions(&w);
        let (tool, _) =
            fulcrum_empowerment::request::tool_sel_with_column(&w, &engine, None, &cond).unwrap();
        let phi = engine.lookup_values(tool, &cond, HU, HE, true).unwrap();
        let full_phi = engine.lookup_values(tool, &full, HU, HE, true).unwrap();
        assert!(
            full_phi.iter().copied().fold(0.0, f32::max) > HU as f32,
            "layout {seed}: the boulder's cells make Phi larger"
        );
        for (id, s) in engine.space.states().iter().enumerate() {
            let v = t.lookup(seed, s).unwrap();
            assert_eq!(v, phi[id], "layout {seed}, {s:?}");
            assert!(v == v.round() && v <= HU as f32, "layout {seed}: Phi {v}");
        }
        boulders += 1;
        if boulders == 5 {
            break;
        }
    }
    assert_eq!(boulders, 5);
}

/// The requests waiting at once are answered as each would be alone: `prepare` makes the
/// new layouts they name (once each, several at a time) and nothing else, and the
/// answers that follow are those of a service that met the requests one by one.
#[test]
fn requests_prepared_together_are_answered_as_one_by_one() {
    use fulcrum_contracts::msg::{kind, status, EmpRequest, EmpResponse};
    use fulcrum_empowerment::service::Answer;
    let family = load_family("toolbox").unwrap();
    let mut together = FamilyTables::new(family.clone(), config(true, true, 1 << 30, 1)).unwrap();
    let mut alone = FamilyTables::new(family.clone(), config(true, true, 1 << 30, 1)).unwrap();
    let hash = together.describe().world_hash;
    // Three requests: layouts 0 (kept), 5, 9 and 12, some named twice and in two
    // requests, each state the initial state or one step from it; and a request of
    // another world naming layout 40, which nobody makes.
    let request = |hash: u64, seeds: &[u64]| {
        let mut r = EmpRequest::boxed();
        r.world_hash = hash;
        r.kind = kind::LOOKUP;
        r.count = seeds.len() as u32;
        for (i, &seed) in seeds.iter().enumerate() {
            let w = family.layout(seed).unwrap();
            let s = if i % 2 == 0 {
                w.initial
            } else {
                w.step(&w.initial, fulcrum_world::EAST)
            };
            r.states[i] = s.to_bytes();
            r.layouts[i] = seed;
        }
        r
    };
    let reqs = [
        request(hash, &[5, 0, 9, 5]),
        request(hash ^ 1, &[40]),
        request(hash, &[12, 9, 12, 0, 5]),
    ];
    let refs: Vec<&EmpRequest> = reqs.iter().map(|r| &**r).collect();
    together.prepare(&refs);
    assert_eq!(together.stats.made, 1 + 3, "layouts 5, 9 and 12, once each");
    for r in &reqs {
        let (mut a, mut b) = (EmpResponse::boxed(), EmpResponse::boxed());
        together.answer(r, &mut a);
        alone.answer(r, &mut b);
        assert_eq!(a.status, b.status);
        assert_eq!(a.count, b.count);
        assert_eq!(a.item_status, b.item_status);
        assert_eq!(a.values, b.values);
        // Phi by the task object's condition: a whole number of bits (max(0, 9 - d)).
        let n = a.count as usize;
        assert!(a.values[..n].iter().all(|v| v.fract() == 0.0 && *v <= 9.0));
    }
    let mut out = EmpResponse::boxed();
    together.answer(&reqs[1], &mut out);
    assert_eq!(out.status, status::WRONG_WORLD, "another world's request");
    assert_eq!(together.stats.made, 4, "answering made nothing more");
    assert_eq!(alone.stats.made, 4);
}
