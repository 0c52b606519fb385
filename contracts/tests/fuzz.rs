//! Bad input, fuzzed (proptest, bounded cases so that the suite stays fast): state
//! descriptions and trajectory chunks. Nothing may panic; every refusal is one line.
//! (World files are fuzzed in `parse.rs`, service requests in the empowerment crate.)

use fulcrum_contracts::traj::{ChunkHeader, ChunkLayout, Section};
use fulcrum_world::{load_world, World};
use proptest::prelude::*;

fn exp3() -> World {
    load_world("exp3").unwrap()
}

fn one_line(e: impl std::fmt::Display) -> bool {
    let s = e.to_string();
    !s.is_empty() && !s.contains('\n')
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn arbitrary_state_descriptions_never_panic(text in any::<String>()) {
        if let Err(e) = exp3().parse_state(&text) {
            prop_assert!(one_line(e));
        }
    }

    #[test]
    fn description_like_strings_never_panic(
        text in "(agent|holding|mode|door|boulder|tree|key|axe)=[a-z0-9,:#-]{0,12}( [a-z]{1,8}=[a-z0-9,:#-]{0,10}){0,4}"
    ) {
        let w = exp3();
        match w.parse_state(&text) {
            // A description that parses names a state the world can describe back.
            Ok(s) => prop_assert!(!w.describe(&s).is_empty()),
            Err(e) => prop_assert!(one_line(e)),
        }
    }
}

/// A valid chunk of 2 worlds x 3 steps for exp3, and its layout.
fn valid(w: &World) -> (ChunkHeader, ChunkLayout, Vec<u8>) {
    let spec = w.obs_spec();
    let l = ChunkLayout {
        envs: 2,
        steps: 3,
        cells: spec.cells(),
        flags: spec.flags,
    };
    let h = ChunkHeader {
        envs: 2,
        steps: 3,
        cells: spec.cells() as u32,
        flags: spec.flags as u32,
        actions: w.num_actions() as u32,
        len: l.bytes() as u64,
        ..ChunkHeader::default()
    };
    (h, l, vec![0u8; l.bytes()])
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn chunks_with_arbitrary_bytes_are_checked_not_trusted(
        bytes in prop::collection::vec(any::<u8>(), 0..4096),
        envs in 0u32..5, steps in 0u32..5, actions in 0u32..20, len in 0u64..100_000,
    ) {
        let w = exp3();
        let (mut h, l, _) = valid(&w);
        h.envs = envs;
        h.steps = steps;
        h.actions = actions;
        h.len = len;
        let r = l.validate(&h, w.num_actions(), &bytes);
        // Whatever the header claims, a payload of the wrong length never passes.
        if bytes.len() != l.bytes() {
            prop_assert!(r.is_err());
        }
        if let Err(e) = r {
            prop_assert!(one_line(e));
        }
    }

    #[test]
    fn one_corrupted_byte_is_refused_exactly_when_out_of_range(
        which in 0usize..3, at in 0usize..6, value in any::<u8>(),
    ) {
        let w = exp3();
        let (h, l, mut p) = valid(&w);
        prop_assert!(l.validate(&h, w.num_actions(), &p).is_ok());
        // One byte of the actions (valid below |A|) or of a done flag (valid 0 or 1).
        let (section, limit) = [
            (Section::Actions, w.num_actions()),
            (Section::Terminated, 2),
            (Section::Truncated, 2),
        ][which];
        p[l.range(section).start + at] = value;
        let r = l.validate(&h, w.num_actions(), &p);
        prop_assert_eq!(r.is_ok(), (value as usize) < limit, "{:?} byte {} = {}: {:?}", section, at, value, r);
    }
}
