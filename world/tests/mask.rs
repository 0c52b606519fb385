//! Per-mode action masking against the world's own dynamics (the table of modes and actions
//! in `docs/world.md`, "Actions and modes"): over random reachable states of every built-in
//! world, an action the mask removes is exactly one that the world turns into nothing
//! (normal mode) or into "cancel back to normal, nothing else happens" (a prompt), and
//! every action it allows changes the mode or the world as the table says.

use fulcrum_world::mask::action_mask;
use fulcrum_world::{load_world, State, World};
use proptest::prelude::*;

/// The state after a random walk of `steps` actions (drawn from `seeds`) from the start.
fn walk(w: &World, seeds: &[u8]) -> State {
    let mut s = w.initial;
    for &r in seeds {
        s = w.step(&s, r % w.num_actions() as u8);
    }
    s
}

fn check(w: &World, s: &State) -> Result<(), TestCaseError> {
    let spec = w.obs_spec();
    let (mut g, mut f) = (vec![0u8; spec.cells()], vec![0u8; spec.flags]);
    w.observe(s, &mut g, &mut f);
    let mask = action_mask(&f);
    let n = w.tools.len();
    let cancel = State { mode: 0, ..*s };
    prop_assert!(mask != 0, "empty mask in {}", w.describe(s));
    for a in 0..w.num_actions() as u8 {
        let allowed = mask >> a & 1 == 1;
        let next = w.step(s, a);
        match s.mode {
            // Normal: a select never does anything; apply does nothing without a tool
            // and opens the prompt with one; moves are always allowed.
            0 => {
                if a < 4 {
                    prop_assert!(allowed);
                } else if a == 4 {
                    prop_assert_eq!(allowed, s.inventory != 0);
                    prop_assert_eq!(next.mode == 1, allowed);
                } else {
                    prop_assert!(!allowed);
                    prop_assert_eq!(next, *s);
                }
            }
            // Choosing a tool: exactly the held tools' selects go on to a direction.
            1 => {
                let k = a as usize;
                let held_select = k >= 5 && k - 5 < n && s.holds(k - 5);
                prop_assert_eq!(allowed, held_select);
                if allowed {
                    prop_assert_eq!(next.mode as usize, 2 + (k - 5));
                } else {
                    prop_assert_eq!(next, cancel);
                }
            }
            // Choosing a direction: the four directions use the tool; the rest cancel.
            _ => {
                prop_assert_eq!(allowed, a < 4);
                prop_assert_eq!(next.mode, 0);
                if !allowed {
                    prop_assert_eq!(next, cancel);
                }
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn masks_remove_exactly_the_actions_that_do_nothing(
        world in prop::sample::select(vec!["exp1-tree", "exp1-wall", "exp2", "exp3", "room"]),
        seeds in prop::collection::vec(any::<u8>(), 0..200),
    ) {
        let w = load_world(world).unwrap();
        let s = walk(&w, &seeds);
        check(&w, &s)?;
    }
}

/// Every prompt state is covered, not only the ones random walks happen to reach: with
/// each tool held in turn, the tool prompt and each direction prompt.
#[test]
fn every_prompt_of_exp2() {
    let w = load_world("exp2").unwrap();
    let n = w.tools.len();
    for inv in 1u16..(1 << n) {
        for mode in 0..(2 + n as u8) {
            let s = State {
                inventory: inv,
                mode,
                ..w.initial
            };
            check(&w, &s).unwrap();
        }
    }
}
