//! Generalised advantage estimation with termination and truncation.
//!
//! For one env and a rollout of T steps (time-major buffers, `[t * envs + e]`):
//!
//! ```text
//! next_v_t = 0                       if the step terminated (the task's end: no future)
//!          = V(s_final)              if it was truncated (time limit: the future exists)
//!          = V(s_{t+1})              otherwise (V(s_T) = `last_values` after the rollout)
//! delta_t  = r_t + gamma * next_v_t - V(s_t)
//! A_t      = delta_t + gamma * lambda * c_t * A_{t+1},   c_t = 0 at episode ends, else 1
//! R_t      = A_t + V(s_t)                                (the value target)
//! ```
//!
//! Truncation is not termination: a truncated step bootstraps from the value of the
//! final observation (the actor sends it with the chunk), and only the GAE chain is cut,
//! since the next buffer entry belongs to a new episode.

/// One rollout's inputs, time-major `[t * envs + e]`.
#[derive(Debug, Clone, Copy)]
pub struct Rollout<'a> {
    /// Environments per step.
    pub envs: usize,
    /// Rewards r_t (extrinsic plus intrinsic).
    pub rewards: &'a [f32],
    /// V(s_t).
    pub values: &'a [f32],
    /// The step ended the episode at the task's terminal state.
    pub terminated: &'a [bool],
    /// The step ended the episode by the time limit.
    pub truncated: &'a [bool],
    /// V(s_final) where truncated (ignored elsewhere).
    pub truncated_values: &'a [f32],
    /// V(s_T) per env, the state after the rollout.
    pub last_values: &'a [f32],
}

/// Advantages and returns (value targets), time-major like the inputs.
pub fn gae(r: &Rollout, gamma: f32, lambda: f32) -> (Vec<f32>, Vec<f32>) {
    let n = r.rewards.len();
    let e = r.envs;
    assert!(
        e > 0 && n % e == 0,
        "rollout length {n} is not a multiple of {e} envs"
    );
    let steps = n / e;
    let mut adv = vec![0.0f32; n];
    for env in 0..e {
        let mut next_adv = 0.0f32;
        for t in (0..steps).rev() {
            let i = t * e + env;
            let (next_v, cont) = if r.terminated[i] {
                (0.0, 0.0)
            } else if r.truncated[i] {
                (r.truncated_values[i], 0.0)
            } else if t + 1 == steps {
                (r.last_values[env], 1.0)
            } else {
                (r.values[i + e], 1.0)
            };
            let delta = r.rewards[i] + gamma * next_v - r.values[i];
            next_adv = delta + gamma * lambda * cont * next_adv;
            adv[i] = next_adv;
        }
    }
    let ret = adv.iter().zip(r.values).map(|(a, v)| a + v).collect();
    (adv, ret)
}
