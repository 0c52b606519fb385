//! An update's batch: the chunks it takes, turned into training data. Per chunk, the
//! reward `r_t = R_t + beta * b_t` and GAE (truncation bootstraps from the chunk's
//! truncated-episode values, termination does not), or with two value heads one GAE per
//! reward stream; then everything concatenated in the batch's order.

use fulcrum_contracts::config::RunConfig;
use fulcrum_contracts::traj::{read_f32s, ChunkHeader, ChunkLayout, Section};

use crate::gae::{gae, Rollout};
use crate::local::UpdateData;
use crate::running_std::RunningStd;

/// A chunk copied out of shared memory.
pub(crate) struct Chunk {
    pub(crate) h: ChunkHeader,
    pub(crate) data: Vec<u8>,
}

/// What the episodes of a batch did, summed over its chunks' headers.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Sums {
    pub(crate) episodes: u64,
    pub(crate) successes: u64,
    pub(crate) pickups: u64,
    pub(crate) e_positive: u64,
    pub(crate) ext_return: f64,
    pub(crate) int_return: f64,
    pub(crate) length: f64,
    pub(crate) int_reward: f64,
    /// Policy versions the chunks lag behind the learner's, summed.
    pub(crate) lag: f64,
}

/// A batch as training data, concatenated over its chunks.
#[derive(Debug)]
pub(crate) struct Batch {
    glyphs: Vec<u8>,
    flags: Vec<u8>,
    actions: Vec<u32>,
    logprobs: Vec<f32>,
    values: Vec<f32>,
    advantages: Vec<f32>,
    returns: Vec<f32>,
    /// Intrinsic values and returns (two value heads; else empty).
    values_int: Vec<f32>,
    returns_int: Vec<f32>,
    two_heads: bool,
    action_mask: bool,
    /// Transitions.
    pub(crate) len: usize,
    pub(crate) sums: Sums,
}

impl Batch {
    /// The training data of `chunks` (made by policy versions up to `version`); with two
    /// value heads the intrinsic rewards' running scale `int_std` takes each chunk's
    /// rewards first.
    pub(crate) fn new(
        chunks: &[Chunk],
        layout: &ChunkLayout,
        cfg: &RunConfig,
        version: u64,
        int_std: &mut RunningStd,
    ) -> Batch {
        let ppo = cfg.ppo;
        let (m, t_len) = (layout.envs, layout.steps);
        let n = m * t_len;
        let total = n * chunks.len();
        let (c_len, f_len) = (layout.cells, layout.flags);
        let two_heads = cfg.intrinsic_value_head;
        let mut b = Batch {
            glyphs: Vec::with_capacity(total * c_len),
            flags: Vec::with_capacity(total * f_len),
            actions: Vec::with_capacity(total),
            logprobs: vec![0.0f32; total],
            values: vec![0.0f32; total],
            advantages: Vec::with_capacity(total),
            returns: Vec::with_capacity(total),
            values_int: vec![0.0f32; if two_heads { total } else { 0 }],
            returns_int: Vec::new(),
            two_heads,
            action_mask: cfg.action_mask,
            len: total,
            sums: Sums::default(),
        };
        let mut ext = vec![0.0f32; n];
        let mut int = vec![0.0f32; n];
        let mut tv = vec![0.0f32; n];
        let mut lv = vec![0.0f32; m];
        for (k, c) in chunks.iter().enumerate() {
            let p = &c.data;
            b.glyphs
                .extend_from_slice(&p[layout.range(Section::Glyphs)]);
            b.flags.extend_from_slice(&p[layout.range(Section::Flags)]);
            b.actions
                .extend(p[layout.range(Section::Actions)].iter().map(|&a| a as u32));
            read_f32s(
                &p[layout.range(Section::Logprob)],
                &mut b.logprobs[k * n..(k + 1) * n],
            );
            read_f32s(
                &p[layout.range(Section::Value)],
                &mut b.values[k * n..(k + 1) * n],
            );
            read_f32s(&p[layout.range(Section::ExtReward)], &mut ext);
            read_f32s(&p[layout.range(Section::IntReward)], &mut int);
            read_f32s(&p[layout.range(Section::TruncValue)], &mut tv);
            read_f32s(&p[layout.range(Section::LastValue)], &mut lv);
            let beta = cfg.beta as f32;
            let term: Vec<bool> = p[layout.range(Section::Terminated)]
                .iter()
                .map(|&b| b == 1)
                .collect();
            let trunc: Vec<bool> = p[layout.range(Section::Truncated)]
                .iter()
                .map(|&b| b == 1)
                .collect();
            let gae_of = |rewards: &[f32], values: &[f32], tv: &[f32], lv: &[f32], gamma: f32| {
                gae(
                    &Rollout {
                        envs: m,
                        rewards,
                        values,
                        terminated: &term,
                        truncated: &trunc,
                        truncated_values: tv,
                        last_values: lv,
                    },
                    gamma,
                    ppo.gae_lambda,
                )
            };
            let values = &b.values[k * n..(k + 1) * n];
            if two_heads {
                // Two streams: the task reward with V, the intrinsic reward (divided by
                // its running std) with V_int and gamma_int; A = A_ext + beta * A_int.
                int_std.update(&int);
                let scale = (int_std.std() + 1e-8) as f32;
                let int_n: Vec<f32> = int.iter().map(|x| x / scale).collect();
                let (mut tvi, mut lvi) = (vec![0.0f32; n], vec![0.0f32; m]);
                read_f32s(
                    &p[layout.range(Section::ValueInt)],
                    &mut b.values_int[k * n..(k + 1) * n],
                );
                read_f32s(&p[layout.range(Section::TruncValueInt)], &mut tvi);
                read_f32s(&p[layout.range(Section::LastValueInt)], &mut lvi);
                let (adv_e, ret_e) = gae_of(&ext, values, &tv, &lv, ppo.gamma);
                let values_int = &b.values_int[k * n..(k + 1) * n];
                let (adv_i, ret_i) = gae_of(&int_n, values_int, &tvi, &lvi, cfg.gamma_int);
                b.advantages
                    .extend(adv_e.iter().zip(&adv_i).map(|(e, i)| e + beta * i));
                b.returns.extend_from_slice(&ret_e);
                b.returns_int.extend_from_slice(&ret_i);
            } else {
                let rewards: Vec<f32> = ext.iter().zip(&int).map(|(r, e)| r + beta * e).collect();
                let (adv, ret) = gae_of(&rewards, values, &tv, &lv, ppo.gamma);
                b.advantages.extend_from_slice(&adv);
                b.returns.extend_from_slice(&ret);
            }
            let s = &mut b.sums;
            s.episodes += c.h.episodes as u64;
            s.successes += c.h.successes as u64;
            s.pickups += c.h.pickups as u64;
            s.e_positive += c.h.e_positive as u64;
            s.ext_return += c.h.ext_return_sum;
            s.int_return += c.h.int_return_sum;
            s.length += c.h.length_sum;
            s.int_reward += c.h.int_reward_sum;
            s.lag += (version - c.h.policy_version.min(version)) as f64;
        }
        b
    }

    /// The batch as the PPO update takes it.
    pub(crate) fn update_data(&self) -> UpdateData<'_> {
        UpdateData {
            glyphs: &self.glyphs,
            flags: &self.flags,
            actions: &self.actions,
            logprobs: &self.logprobs,
            values: &self.values,
            advantages: &self.advantages,
            returns: &self.returns,
            action_mask: self.action_mask,
            int: self
                .two_heads
                .then_some((&self.values_int[..], &self.returns_int[..])),
        }
    }
}
