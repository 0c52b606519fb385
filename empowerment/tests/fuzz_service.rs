//! Service requests, fuzzed (proptest, bounded): whatever a client sends, the service's
//! answer function never panics, answers with a known status, and never marks garbage
//! as a valid value. This is the code `fulcrum serve` runs on every request.

use std::time::Duration;

use fulcrum_contracts::msg::{item, kind, status, EmpRequest, EmpResponse, MAX_BATCH, STATE_BYTES};
use fulcrum_empowerment::service::{ServeConfig, Tables};
use fulcrum_empowerment::{Engine, Limits, ToolSel};
use fulcrum_world::{load_world, ObjectSet};
use proptest::prelude::*;

fn zeroed<T>() -> Box<T> {
    // SAFETY: the message types are plain integers, floats and byte arrays; all-zero is
    // a valid value of each.
    unsafe { Box::new(std::mem::zeroed()) }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn arbitrary_requests_get_a_status_never_a_panic(
        k in 0u32..8, count in 0u32..2000, tool in -3i32..8, horizon in 0u32..80,
        objects in any::<u32>(), right_world in any::<bool>(),
        bytes in prop::collection::vec(any::<u8>(), 0..(16 * STATE_BYTES)),
    ) {
        let w = load_world("exp2").unwrap();
        let e = Engine::new(&w, Limits { max_bytes: 256 << 20 }).unwrap();
        let mut t = Tables::new(e, ServeConfig {
            horizon_sum: false,
            namespace: "fuzz".into(),
            tool: ToolSel::Tool(0),
            objects: ObjectSet::Objects(vec![0]),
            horizon_unequipped: 3,
            horizon_equipped: 3,
            cache_bytes: 16 << 20,
            spin: Duration::ZERO,
            max_clients: fulcrum_contracts::msg::MAX_CLIENTS,
        }).unwrap();
        let mut req: Box<EmpRequest> = zeroed();
        req.world_hash = if right_world { w.content_hash() } else { 42 };
        req.kind = k;
        req.count = count;
        req.tool = tool;
        req.horizon = horizon;
        req.objects = objects;
        for (i, chunk) in bytes.chunks(STATE_BYTES).enumerate() {
            req.states[i][..chunk.len()].copy_from_slice(chunk);
        }
        let mut out: Box<EmpResponse> = zeroed();
        t.answer(&req, &mut out);
        prop_assert!(out.status <= status::TOO_LARGE, "status {}", out.status);
        if !right_world && k != kind::DESCRIBE {
            prop_assert_eq!(out.status, status::WRONG_WORLD);
        }
        if count as usize > MAX_BATCH && right_world && k != kind::DESCRIBE {
            prop_assert_eq!(out.status, status::BAD_COUNT);
        }
        if out.status == status::OK && (k == kind::LOOKUP || k == kind::VISIT) {
            for i in 0..out.count as usize {
                let s = out.item_status[i];
                prop_assert!(s == item::OK || s == item::NOT_IN_SPACE);
                // A valid value is finite and not negative (bits, or a count >= 1).
                if s == item::OK {
                    prop_assert!(out.values[i].is_finite() && out.values[i] >= 0.0);
                }
            }
        }
    }
}
