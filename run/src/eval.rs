//! Evaluation of a run's policy: N episodes from the initial state, actions greedy (the
//! most probable allowed action) or sampled as the actors sample them, on the run's world
//! or on another world of the same shape (generalisation).
//!
//! Per episode: success (the task's terminal state reached), return (the task's reward),
//! length (steps), tool use (a tool held at the end: tools are picked up, never
//! dropped). Summaries carry 95% confidence intervals: Wilson's score interval for the
//! two rates, `mean +/- t_{0.975, n-1} * sd / sqrt(n)` (Student's t) for return and
//! length. Greedy episodes of a deterministic world from one start are all the same
//! episode, so their interval is the point; `--sample` gives a spread.

use std::path::Path;

use crate::error::Result;
use fulcrum_actors::policy::Policy;
use fulcrum_contracts::config::RunConfig;
use fulcrum_learner::evalcsv::{EvalRow, PERIODIC};
use fulcrum_learner::paths::RunPaths;
use fulcrum_learner::process::Evaluate;
use fulcrum_world::{View, World};
use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::error::bad;
use crate::record::load_policy;
use crate::stats::{incomplete_beta, mean_std};

/// One episode's outcome.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Episode {
    /// The task's terminal state was reached.
    pub success: bool,
    /// Sum of task rewards.
    pub ret: f64,
    /// Steps taken.
    pub length: u32,
    /// A tool was held at the end.
    pub tool_use: bool,
}

/// A point estimate and its 95% interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// The estimate.
    pub value: f64,
    /// Lower end of the 95% interval.
    pub lo: f64,
    /// Upper end.
    pub hi: f64,
}

/// What N episodes showed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Summary {
    /// Episodes played.
    pub episodes: usize,
    /// Share of episodes that reached the task's end (Wilson interval).
    pub success: Estimate,
    /// Mean return (t interval).
    pub ret: Estimate,
    /// Mean length (t interval).
    pub length: Estimate,
    /// Share of episodes that picked a tool up (Wilson interval).
    pub tool_use: Estimate,
}

/// Wilson's 95% score interval for `k` successes in `n` trials.
pub fn wilson(k: usize, n: usize) -> Estimate {
    if n == 0 {
        return Estimate {
            value: f64::NAN,
            lo: f64::NAN,
            hi: f64::NAN,
        };
    }
    let z = 1.959_963_984_540_054_f64;
    let (n, p) = (n as f64, k as f64 / n as f64);
    let d = 1.0 + z * z / n;
    let centre = (p + z * z / (2.0 * n)) / d;
    let half = z * (p * (1.0 - p) / n + z * z / (4.0 * n * n)).sqrt() / d;
    Estimate {
        value: p,
        lo: (centre - half).max(0.0),
        hi: (centre + half).min(1.0),
    }
}

/// The 0.975 quantile of Student's t with `df` degrees of freedom (bisection on the
/// distribution function, `P(T <= t) = 1 - I_{df/(df+t^2)}(df/2, 1/2) / 2` for t > 0).
pub fn t975(df: f64) -> f64 {
    let cdf = |t: f64| 1.0 - 0.5 * incomplete_beta(df / 2.0, 0.5, df / (df + t * t));
    let (mut lo, mut hi) = (0.0, 1000.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if cdf(mid) < 0.975 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The mean of `xs` and its 95% t interval (the point when n < 2).
pub fn mean_ci(xs: &[f64]) -> Estimate {
    let (m, sd) = mean_std(xs);
    if xs.len() < 2 {
        return Estimate {
            value: m,
            lo: m,
            hi: m,
        };
    }
    let half = t975(xs.len() as f64 - 1.0) * sd / (xs.len() as f64).sqrt();
    Estimate {
        value: m,
        lo: m - half,
        hi: m + half,
    }
}

/// The summary of `eps`.
pub fn summarise(eps: &[Episode]) -> Summary {
    let n = eps.len();
    let f = |g: fn(&Episode) -> f64| eps.iter().map(g).collect::<Vec<f64>>();
    Summary {
        episodes: n,
        success: wilson(eps.iter().filter(|e| e.success).count(), n),
        ret: mean_ci(&f(|e| e.ret)),
        length: mean_ci(&f(|e| e.length as f64)),
        tool_use: wilson(eps.iter().filter(|e| e.tool_use).count(), n),
    }
}

/// Plays `episodes` episodes of the policy in `ckpt` on `world` (the run's, or another
/// of the same shape): greedy, or sampled with a ChaCha generator seeded by `seed`.
/// Returns the episodes and the checkpoint's update and env steps.
#[allow(clippy::too_many_arguments)]
pub fn evaluate(
    paths: &RunPaths,
    cfg: &RunConfig,
    run_world: &World,
    world: &World,
    ckpt: &Path,
    episodes: usize,
    greedy: bool,
    seed: u64,
) -> Result<(Vec<Episode>, u64, u64)> {
    if cfg.shape(world) != cfg.shape(run_world) {
        let (a, b) = (world.obs_spec(), run_world.obs_spec());
        let (n, m) = (world.tools.len(), run_world.tools.len());
        return bad(match cfg.view {
            View::Full => format!(
                "world '{}' ({}x{}, {n} tools) does not fit the run's policy, which takes worlds of {}x{} with {m} tools",
                world.name, a.width, a.height, b.width, b.height
            ),
            View::Crop(_) => format!(
                "world '{}' ({n} tools) does not fit the run's policy, which sees a {} window of worlds with {m} tools",
                world.name, cfg.view
            ),
        });
    }
    let (mut policy, counters) = load_policy(ckpt, paths, cfg, run_world)?;
    let eps = play(&mut policy, cfg.view, world, episodes, greedy, seed);
    let count = |k: &str| counters.get(k).copied().unwrap_or(0);
    Ok((eps, count("update"), count("env_steps")))
}

/// Plays `episodes` episodes of `policy` on `world` seen through `view`: greedy, or
/// sampled with a ChaCha generator seeded by `seed`; the same generator draws a
/// stochastic world's outcomes (greedy play too: the policy is greedy, the world is not).
pub fn play(
    policy: &mut Policy,
    view: View,
    world: &World,
    episodes: usize,
    greedy: bool,
    seed: u64,
) -> Vec<Episode> {
    let spec = view.spec(world);
    let (mut g, mut f) = (vec![0u8; spec.cells()], vec![0u8; spec.flags]);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut act, mut lp, mut v) = ([0u8], [0.0f32], [0.0f32]);
    let mut out = Vec::with_capacity(episodes);
    for _ in 0..episodes {
        let mut ep = world.reset();
        let mut ret = 0.0f64;
        view.observe(world, &ep.state, &mut g, &mut f);
        loop {
            let a = if greedy {
                policy.greedy(&g, &f)
            } else {
                policy.act(&g, &f, &mut rng, &mut act, &mut lp, &mut v);
                act[0]
            };
            let prev = ep.state;
            let o = world.env_step_drawn(&mut ep, a, || rng.next_u64());
            view.update(world, &prev, &ep.state, &mut g, &mut f);
            ret += o.reward as f64;
            if o.terminated || o.truncated {
                out.push(Episode {
                    success: o.terminated,
                    ret,
                    length: ep.t,
                    tool_use: ep.state.inventory != 0,
                });
                break;
            }
        }
    }
    out
}

/// The periodic evaluation of `train --eval-every`: the learner's weights played
/// greedily for the run's `eval_episodes` episodes on its world, as a row of `eval.csv`
/// (the learner fills in the update and env steps).
pub fn periodic<'a>(cfg: &'a RunConfig, world: &'a World) -> Evaluate<'a> {
    let mut policy = Policy::new(cfg.shape(world)).with_action_mask(cfg.action_mask);
    Box::new(move |flat: &[f32]| {
        if !policy.set(flat) {
            return Err(format!(
                "{} weights do not fit the network of {}",
                flat.len(),
                policy.len()
            ));
        }
        let eps = play(
            &mut policy,
            cfg.view,
            world,
            cfg.eval_episodes,
            true,
            cfg.seed,
        );
        Ok(summarise(&eps).row(0, 0, &world.name, PERIODIC, cfg.seed))
    })
}

impl Summary {
    /// The summary as a row of `eval.csv`.
    pub fn row(&self, update: u64, env_steps: u64, world: &str, mode: &str, seed: u64) -> EvalRow {
        let t = |e: &Estimate| [e.value, e.lo, e.hi];
        EvalRow {
            update,
            env_steps,
            world: world.to_string(),
            mode: mode.to_string(),
            seed,
            episodes: self.episodes,
            success: t(&self.success),
            ret: t(&self.ret),
            length: t(&self.length),
            tool_use: t(&self.tool_use),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wilson_matches_scipy() {
        // scipy.stats.binomtest(k, n).proportion_ci(method="wilson"), kept in
        // scripts/reference/eval_ci.py: (7, 10) -> (0.3967781, 0.8922087);
        // (0, 20) -> (0.0, 0.1611252); (20, 20) -> (0.8388748, 1.0).
        let e = wilson(7, 10);
        assert!((e.lo - 0.396_778_1).abs() < 1e-6 && (e.hi - 0.892_208_7).abs() < 1e-6);
        let e = wilson(0, 20);
        assert!(e.lo == 0.0 && (e.hi - 0.161_125_2).abs() < 1e-6);
        let e = wilson(20, 20);
        assert!((e.lo - 0.838_874_8).abs() < 1e-6 && e.hi == 1.0);
    }

    #[test]
    fn t_quantiles_match_scipy() {
        // scipy.stats.t.ppf(0.975, df) for df = 1, 4, 29, 99 (scripts/reference/eval_ci.py).
        for (df, want) in [
            (1.0, 12.706_204_736),
            (4.0, 2.776_445_105),
            (29.0, 2.045_229_642),
            (99.0, 1.984_216_952),
        ] {
            assert!((t975(df) - want).abs() < 1e-6, "df {df}: {}", t975(df));
        }
    }
}
