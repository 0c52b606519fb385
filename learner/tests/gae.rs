//! GAE against numbers computed by the plain-Python definition below (kept beside the
//! test, as the reference):
//!
//! ```python
//! gamma, lam = 0.99, 0.95
//! r    = [[0.0, 1.0], [0.5, 0.0], [0.0, 0.0], [1.0, 0.25], [0.0, 0.0]]   # [t][e]
//! v    = [[0.1, 0.2], [0.3, 0.4], [0.5, 0.6], [0.7, 0.8], [0.9, 1.0]]
//! term = [[0, 1], [0, 0], [0, 0], [1, 0], [0, 0]]
//! trunc= [[0, 0], [0, 0], [1, 0], [0, 0], [0, 1]]
//! tv   = [[0, 0], [0, 0], [2.0, 0], [0, 0], [0, 3.0]]   # V(final obs) where truncated
//! last = [1.5, 2.5]
//! for e in range(2):
//!     nxt = 0.0
//!     for t in reversed(range(5)):
//!         if term[t][e]:    nv, cont = 0.0, 0.0
//!         elif trunc[t][e]: nv, cont = tv[t][e], 0.0
//!         else:             nv, cont = (last[e] if t == 4 else v[t + 1][e]), 1.0
//!         nxt = r[t][e] + gamma * nv - v[t][e] + gamma * lam * cont * nxt
//!         adv[t][e] = nxt
//! ```

use fulcrum_learner::{gae, Rollout};

#[test]
fn gae_with_termination_and_truncation() {
    let rewards = [0.0, 1.0, 0.5, 0.0, 0.0, 0.0, 1.0, 0.25, 0.0, 0.0];
    let values = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0];
    let terminated = [
        false, true, false, false, false, false, true, false, false, false,
    ];
    let truncated = [
        false, false, false, false, true, false, false, false, false, true,
    ];
    let truncated_values = [0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 3.0];
    let r = Rollout {
        envs: 2,
        rewards: &rewards,
        values: &values,
        terminated: &terminated,
        truncated: &truncated,
        truncated_values: &truncated_values,
        last_values: &[1.5, 2.5],
    };
    let (adv, ret) = gae(&r, 0.99, 0.95);
    let want = [
        2.15976707,
        0.8,
        2.08694,
        2.4026366170962494,
        1.48,
        2.3483642924999995,
        0.3,
        2.2927849999999994,
        0.585,
        1.97,
    ];
    for (i, (a, w)) in adv.iter().zip(want).enumerate() {
        assert!((*a as f64 - w).abs() < 1e-5, "adv[{i}] = {a}, want {w}");
        assert!((ret[i] - (a + values[i])).abs() < 1e-6);
    }
    // Truncation bootstraps: with the truncated value zeroed, the advantage at the
    // truncated step drops by exactly gamma * V(s_final).
    let zero = [0.0; 10];
    let r0 = Rollout {
        truncated_values: &zero,
        ..r
    };
    let (adv0, _) = gae(&r0, 0.99, 0.95);
    assert!((adv[4] - adv0[4] - 0.99 * 2.0).abs() < 1e-5);
}
