//! Set propagation equals the paper's enumeration of action sequences: on many small
//! random worlds, for every state, every tool (and `all`), several object sets (each
//! object, all objects jointly, the agent) and every h <= 4.

use fulcrum_empowerment::{enumerate, Engine, Limits, Method, ToolSel};
use fulcrum_world::generate::{generate, GenParams};
use fulcrum_world::{parse_world, ObjectSet};
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    #[test]
    fn propagation_equals_enumeration(
        width in 4usize..8,
        height in 4usize..7,
        tools in 0usize..4,
        objects in 0usize..4,
        rock in 0.0f64..0.3,
        seed in any::<u64>(),
    ) {
        let p = GenParams { width, height, tools, objects, rock, seed };
        let Ok(text) = generate(&p) else { return Ok(()) };
        let world = parse_world(&text, "generated").unwrap();
        let engine = Engine::new(&world, Limits::default()).unwrap();
        // Keep each case to a second or so.
        prop_assume!(engine.space.len() <= 1500);
        let mut sets: Vec<ObjectSet> = (0..world.objects.len()).map(|i| ObjectSet::Objects(vec![i])).collect();
        if world.objects.len() > 1 {
            sets.push(ObjectSet::Objects((0..world.objects.len()).collect()));
        }
        sets.push(ObjectSet::Agent);
        let mut sels: Vec<ToolSel> = (0..world.tools.len()).map(ToolSel::Tool).collect();
        sels.push(ToolSel::All);
        let horizons = [0, 1, 2, 3, 4];
        for &tool in &sels {
            let actions = tool.actions(&world);
            for set in &sets {
                let dp = engine.counts(tool, set, &horizons, Method::Dp).unwrap();
                for (i, s) in engine.space.states().iter().enumerate() {
                    for (k, &h) in horizons.iter().enumerate() {
                        let want = enumerate::reachable_count(&world, s, &actions, set, h) as u32;
                        prop_assert_eq!(dp[k][i], want, "state {} tool {:?} set {:?} h {}\n{}", world.describe(s), tool, set, h, text);
                    }
                }
            }
        }
    }
}
