//! Single-process PPO training: M worlds stepped in lock-step, T steps per update,
//! reward `R + beta * E(s_{t+1})` with E from a caller-supplied function (an engine's
//! table in-process; the empowerment service in `fulcrum train`).
//!
//! This is the reference loop: the multi-process training distributes exactly these
//! steps (actors collect, the learner runs [`update`]).
//!
//! [`update`]: crate::local::update

use candle_core::{Device, Result};
use fulcrum_contracts::layout::shape_for;
use fulcrum_world::View;
use fulcrum_world::{Episode, World};
use rand::seq::SliceRandom;
use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::adam::Adam;
use crate::diagnostics::Stats;
use crate::fused::{Data, Learner};
use crate::gae::{gae, Rollout};
use crate::net::{mask_bias, sample, Net};
// The network's shape for a world, where the binary has always found it.
use fulcrum_contracts::ppo_config::PpoConfig;

/// What to train.
#[derive(Debug, Clone, Copy)]
pub struct LocalConfig {
    /// Worlds stepped together.
    pub envs: usize,
    /// Steps per world per update.
    pub steps: usize,
    /// Env steps in all (rounded up to whole updates).
    pub total_steps: u64,
    /// Hidden units.
    pub hidden: usize,
    /// Seed of weights, sampling and minibatch order.
    pub seed: u64,
    /// Weight of the intrinsic reward.
    pub beta: f32,
    /// Per-mode action masking ([`fulcrum_world::mask`]).
    pub action_mask: bool,
    /// PPO hyperparameters.
    pub ppo: PpoConfig,
}

impl Default for LocalConfig {
    fn default() -> Self {
        LocalConfig {
            envs: 8,
            steps: 128,
            total_steps: 200_000,
            hidden: 64,
            seed: 1,
            beta: 0.0,
            action_mask: true,
            ppo: PpoConfig::default(),
        }
    }
}

/// One update's record (a row of metrics.csv).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct UpdateLog {
    /// Env steps so far.
    pub env_steps: u64,
    /// Episodes finished in this update.
    pub episodes: u32,
    /// Of those, how many reached the task's terminal state.
    pub successes: u32,
    /// Mean extrinsic return of those episodes.
    pub extrinsic_return: f32,
    /// Mean intrinsic reward per step in this update.
    pub intrinsic_mean: f32,
    /// Mean episode length.
    pub episode_length: f32,
    /// Last minibatch's diagnostics, averaged over the update.
    pub stats: Stats,
}

impl UpdateLog {
    /// Success rate of the episodes finished in this update (0 when none finished).
    pub fn success_rate(&self) -> f32 {
        if self.episodes == 0 {
            0.0
        } else {
            self.successes as f32 / self.episodes as f32
        }
    }
}

/// Train; `intrinsic(s)` is E at the state reached. Calls `on_update` after each update.
pub fn train(
    world: &World,
    cfg: &LocalConfig,
    intrinsic: &dyn Fn(&fulcrum_world::State) -> f32,
    mut on_update: impl FnMut(&UpdateLog),
) -> Result<(Net, Vec<UpdateLog>)> {
    let dev = Device::Cpu;
    let shape = shape_for(world, View::Full, cfg.hidden);
    let net = Net::new(shape, cfg.seed, &dev)?;
    let mut adam = Adam::new(&net)?;
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed ^ 0x5eed_5eed);
    let (m, t_len) = (cfg.envs, cfg.steps);
    let (c, f) = (shape.cells, shape.flags);
    let batch = m * t_len;
    let updates = cfg.total_steps.div_ceil(batch as u64).max(1);
    let mut eps: Vec<Episode> = (0..m).map(|_| world.reset()).collect();
    let mut ep_ret = vec![0.0f32; m];
    let mut logs = Vec::new();
    let mut env_steps = 0u64;
    let mut kl_coef = cfg.ppo.kl_coef;
    let mut g = vec![0u8; batch * c];
    let mut fl = vec![0u8; batch * f];
    let mut acts = vec![0u32; batch];
    let mut lps = vec![0.0f32; batch];
    let mut vals = vec![0.0f32; batch];
    let mut rews = vec![0.0f32; batch];
    let mut term = vec![false; batch];
    let mut trunc = vec![false; batch];
    let mut tvals = vec![0.0f32; batch];
    for u in 0..updates {
        let lr = cfg.ppo.lr_at(u, updates);
        let mut log = UpdateLog::default();
        let mut ep_len_sum = 0u64;
        let mut intrinsic_sum = 0.0f64;
        // Final observations of truncated episodes, valued after the rollout.
        let mut finals: Vec<(usize, Vec<u8>, Vec<u8>)> = Vec::new();
        for t in 0..t_len {
            let base = t * m;
            for (e, ep) in eps.iter().enumerate() {
                let i = base + e;
                world.observe(
                    &ep.state,
                    &mut g[i * c..(i + 1) * c],
                    &mut fl[i * f..(i + 1) * f],
                );
            }
            let obs = net.batch(&g[base * c..(base + m) * c], &fl[base * f..(base + m) * f])?;
            let (logits, value) = net.forward(&obs)?;
            let logits = if cfg.action_mask {
                (logits + mask_bias(&fl[base * f..(base + m) * f], f, shape.actions, &dev)?)?
            } else {
                logits
            };
            let (a, lp) = sample(&logits, &mut rng)?;
            let v: Vec<f32> = value.to_vec1()?;
            for e in 0..m {
                let i = base + e;
                acts[i] = a[e];
                lps[i] = lp[e];
                vals[i] = v[e];
                let out = world.env_step_drawn(&mut eps[e], a[e] as u8, || rng.next_u64());
                let bonus = cfg.beta * intrinsic(&eps[e].state);
                intrinsic_sum += bonus as f64;
                rews[i] = out.reward + bonus;
                ep_ret[e] += out.reward;
                term[i] = out.terminated;
                trunc[i] = out.truncated;
                if out.terminated || out.truncated {
                    log.episodes += 1;
                    log.successes += out.terminated as u32;
                    log.extrinsic_return += ep_ret[e];
                    ep_len_sum += eps[e].t as u64;
                    if out.truncated {
                        let mut gg = vec![0u8; c];
                        let mut ff = vec![0u8; f];
                        world.observe(&eps[e].state, &mut gg, &mut ff);
                        finals.push((i, gg, ff));
                    }
                    ep_ret[e] = 0.0;
                    eps[e] = world.reset();
                }
            }
        }
        env_steps += batch as u64;
        // Values after the rollout and of truncated episodes' final observations.
        let mut lg = vec![0u8; m * c];
        let mut lf = vec![0u8; m * f];
        for (e, ep) in eps.iter().enumerate() {
            world.observe(
                &ep.state,
                &mut lg[e * c..(e + 1) * c],
                &mut lf[e * f..(e + 1) * f],
            );
        }
        let last: Vec<f32> = net.forward(&net.batch(&lg, &lf)?)?.1.to_vec1()?;
        tvals.fill(0.0);
        if !finals.is_empty() {
            let fg: Vec<u8> = finals.iter().flat_map(|x| x.1.iter().copied()).collect();
            let ff: Vec<u8> = finals.iter().flat_map(|x| x.2.iter().copied()).collect();
            let fv: Vec<f32> = net.forward(&net.batch(&fg, &ff)?)?.1.to_vec1()?;
            for ((i, _, _), v) in finals.iter().zip(fv) {
                tvals[*i] = v;
            }
        }
        let (adv, ret) = gae(
            &Rollout {
                envs: m,
                rewards: &rews,
                values: &vals,
                terminated: &term,
                truncated: &trunc,
                truncated_values: &tvals,
                last_values: &last,
            },
            cfg.ppo.gamma,
            cfg.ppo.gae_lambda,
        );
        log.stats = update(
            &net,
            &mut adam,
            &PpoConfig { kl_coef, ..cfg.ppo },
            lr,
            &mut rng,
            &UpdateData {
                glyphs: &g,
                flags: &fl,
                actions: &acts,
                logprobs: &lps,
                values: &vals,
                advantages: &adv,
                returns: &ret,
                action_mask: cfg.action_mask,
                int: None,
            },
        )?;
        kl_coef = cfg.ppo.adapt_kl(kl_coef, log.stats.approx_kl);
        log.env_steps = env_steps;
        if log.episodes > 0 {
            log.extrinsic_return /= log.episodes as f32;
            log.episode_length = ep_len_sum as f32 / log.episodes as f32;
        }
        log.intrinsic_mean = (intrinsic_sum / batch as f64) as f32;
        on_update(&log);
        logs.push(log);
    }
    Ok((net, logs))
}

/// One rollout, flat, sample-major (`[i * cells ..]` for glyphs).
#[derive(Debug)]
pub struct UpdateData<'a> {
    /// Glyph grids.
    pub glyphs: &'a [u8],
    /// Flags.
    pub flags: &'a [u8],
    /// Actions.
    pub actions: &'a [u32],
    /// log pi_old.
    pub logprobs: &'a [f32],
    /// V_old.
    pub values: &'a [f32],
    /// GAE advantages.
    pub advantages: &'a [f32],
    /// Returns.
    pub returns: &'a [f32],
    /// Whether the policy's logits are masked per mode ([`fulcrum_world::mask`]).
    pub action_mask: bool,
    /// With the intrinsic value head: V_int old and the intrinsic returns.
    pub int: Option<(&'a [f32], &'a [f32])>,
}

/// PPO epochs over shuffled minibatches; returns the mean diagnostics.
///
/// Same math as [`crate::ppo::loss`] + [`crate::ppo::clipped_grads`] + [`Adam::apply`]
/// per minibatch (CleanRL's `ppo.py`), computed by [`crate::fused`] on flat buffers: the
/// parameters and Adam's moments are copied out of `net` and `adam` once and written back
/// at the end.
pub fn update(
    net: &Net,
    adam: &mut Adam,
    cfg: &PpoConfig,
    lr: f64,
    rng: &mut ChaCha8Rng,
    d: &UpdateData,
) -> Result<Stats> {
    let n = d.actions.len();
    // RLlib standardises advantages once over the batch: (A - mean) / max(std, floor),
    // the population std.
    let normed: Vec<f32> = if cfg.adv_norm_batch {
        let k = n.max(1) as f64;
        let mean = d.advantages.iter().map(|&a| a as f64).sum::<f64>() / k;
        let var = d
            .advantages
            .iter()
            .map(|&a| (a as f64 - mean).powi(2))
            .sum::<f64>()
            / k;
        let s = var.sqrt().max(cfg.adv_std_floor as f64);
        d.advantages
            .iter()
            .map(|&a| ((a as f64 - mean) / s) as f32)
            .collect()
    } else {
        Vec::new()
    };
    let advantages = if cfg.adv_norm_batch {
        &normed[..]
    } else {
        d.advantages
    };
    let data = Data::new(
        net.shape, d.glyphs, d.flags, d.actions, d.logprobs, d.values, advantages, d.returns,
    )?
    .with_action_mask(d.action_mask)?;
    let data = match d.int {
        Some((v, r)) => data.with_intrinsic(v, r)?,
        None => data,
    };
    let mut fl = Learner::load(net, adam)?;
    let mb = n / cfg.minibatches.max(1);
    let mut idx: Vec<usize> = (0..n).collect();
    let mut sum = Stats::default();
    let mut count = 0;
    for _ in 0..cfg.epochs {
        idx.shuffle(rng);
        for chunk in idx.chunks(mb.max(1)) {
            let s = fl.gradient(&data, chunk, cfg);
            fl.clip_and_step(cfg.max_grad_norm, lr);
            sum.policy_loss += s.policy_loss;
            sum.value_loss += s.value_loss;
            sum.entropy += s.entropy;
            sum.approx_kl += s.approx_kl;
            sum.clip_frac += s.clip_frac;
            count += 1;
        }
    }
    fl.store(net, adam)?;
    let k = count.max(1) as f32;
    Ok(Stats {
        policy_loss: sum.policy_loss / k,
        value_loss: sum.value_loss / k,
        entropy: sum.entropy / k,
        approx_kl: sum.approx_kl / k,
        clip_frac: sum.clip_frac / k,
    })
}
