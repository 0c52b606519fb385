//! Evaluation of a run's policy: N episodes from the initial state, actions greedy (the
//! most probable allowed action) or sampled as the actors sample them, on the run's world
//! or on another world of the same shape (generalisation).
//!
//! Per episode: success (the task's terminal state reached), return (the task's reward),
//! length (steps), tool use (a tool held at the end: tools are picked up, never
//! dropped) and tool choice (the first tool the agent used, at the direction prompt, is
//! one that fits the task: [`World::fitting_tools`], by the rule table; an episode
//! without a tool use counts as a wrong choice; not defined for a push task). Summaries
//! carry 95% confidence intervals: Wilson's score interval for the three rates, `mean +/- t_{0.975, n-1} * sd / sqrt(n)` (Student's t) for return and
//! length. Greedy episodes of a deterministic world from one start are all the same
//! episode, so their interval is the point; `--sample` gives a spread.

use std::path::Path;

use crate::error::Result;
use fulcrum_actors::policy::Policy;
use fulcrum_contracts::config::RunConfig;
use fulcrum_learner::evalcsv::{EvalRow, PERIODIC, PERIODIC_SAMPLE};
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
    /// The first tool used (its index), if any.
    pub first_tool: Option<u8>,
    /// Whether that tool fits the world's task (`None` where no tool can: a push task,
    /// or none; `Some(false)` when no tool was used).
    pub tool_fits: Option<bool>,
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
    /// Share of episodes whose first tool use is a tool that fits the task (Wilson
    /// interval; NaN where no tool can fit: a push task, or none).
    pub tool_choice: Estimate,
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

/// The summary of `eps` (tool choice over the episodes whose world has a tool that fits).
pub fn summarise(eps: &[Episode]) -> Summary {
    let n = eps.len();
    let judged: Vec<bool> = eps.iter().filter_map(|e| e.tool_fits).collect();
    let tool_choice = wilson(judged.iter().filter(|&&f| f).count(), judged.len());
    let f = |g: fn(&Episode) -> f64| eps.iter().map(g).collect::<Vec<f64>>();
    Summary {
        episodes: n,
        success: wilson(eps.iter().filter(|e| e.success).count(), n),
        ret: mean_ci(&f(|e| e.ret)),
        length: mean_ci(&f(|e| e.length as f64)),
        tool_use: wilson(eps.iter().filter(|e| e.tool_use).count(), n),
        tool_choice,
    }
}

/// Plays `episodes` episodes of the policy in `ckpt` on `worlds` (the run's world, another
/// of the same shape, or a family's layouts), episode i on `worlds[i mod len]`: greedy,
/// or sampled with a ChaCha generator seeded by `seed`. Returns the episodes and the
/// checkpoint's update and env steps.
#[allow(clippy::too_many_arguments)]
pub fn evaluate(
    paths: &RunPaths,
    cfg: &RunConfig,
    run_world: &World,
    worlds: &[World],
    ckpt: &Path,
    episodes: usize,
    greedy: bool,
    seed: u64,
) -> Result<(Vec<Episode>, u64, u64)> {
    let Some(world) = worlds
        .iter()
        .find(|w| cfg.shape(w) != cfg.shape(run_world))
        .or(worlds.first())
    else {
        return bad("no world to play on".to_string());
    };
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
    let eps = play(&mut policy, cfg.view, worlds, episodes, greedy, seed);
    let count = |k: &str| counters.get(k).copied().unwrap_or(0);
    Ok((eps, count("update"), count("env_steps")))
}

/// Plays `episodes` episodes of `policy` seen through `view`, episode i on
/// `worlds[i mod len]`: greedy, or sampled with a ChaCha generator seeded by `seed`; the
/// same generator draws a stochastic world's outcomes (greedy play too: the policy is
/// greedy, the world is not).
pub fn play(
    policy: &mut Policy,
    view: View,
    worlds: &[World],
    episodes: usize,
    greedy: bool,
    seed: u64,
) -> Vec<Episode> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut act, mut lp, mut v) = ([0u8], [0.0f32], [0.0f32]);
    (0..episodes)
        .map(|i| {
            episode(view, &worlds[i % worlds.len()], &mut rng, |g, f, _, rng| {
                if greedy {
                    policy.greedy(g, f)
                } else {
                    policy.act(g, f, rng, &mut act, &mut lp, &mut v);
                    act[0]
                }
            })
        })
        .collect()
}

/// One episode from the initial state, each action chosen by `choose` from the
/// observation (glyphs, flags), the state and the generator (which also draws a
/// stochastic world's outcomes, after the action).
pub fn episode(
    view: View,
    world: &World,
    rng: &mut ChaCha8Rng,
    mut choose: impl FnMut(&[u8], &[u8], &fulcrum_world::State, &mut ChaCha8Rng) -> u8,
) -> Episode {
    let spec = view.spec(world);
    let (mut g, mut f) = (vec![0u8; spec.cells()], vec![0u8; spec.flags]);
    let mut ep = world.reset();
    let mut ret = 0.0f64;
    let mut first_tool = None;
    view.observe(world, &ep.state, &mut g, &mut f);
    loop {
        let a = choose(&g, &f, &ep.state, rng);
        let prev = ep.state;
        // A direction at the direction prompt: tool k acts.
        if let fulcrum_world::Mode::ChoosingDirection(k) = prev.mode() {
            if a < fulcrum_world::APPLY && first_tool.is_none() {
                first_tool = Some(k);
            }
        }
        let o = world.env_step_drawn(&mut ep, a, || rng.next_u64());
        view.update(world, &prev, &ep.state, &mut g, &mut f);
        ret += o.reward as f64;
        if o.terminated || o.truncated {
            return Episode {
                success: o.terminated,
                ret,
                length: ep.t,
                tool_use: ep.state.inventory != 0,
                first_tool,
                tool_fits: world
                    .fitting_tools()
                    .map(|fit| first_tool.is_some_and(|k| fit.contains(&(k as usize)))),
            };
        }
    }
}

/// The periodic evaluation of `train --eval-every`: the learner's weights played
/// greedily (sampled with `eval_sample`, seeded by the run's seed, as `fulcrum eval
/// --sample`) for the run's `eval_episodes` episodes on its world (on a family, one
/// episode on each of the held-out layouts `test:eval_episodes`), as a row of
/// `eval.csv` (the learner fills in the update and env steps).
pub fn periodic<'a>(cfg: &'a RunConfig, world: &'a World) -> Result<Evaluate<'a>> {
    let mut policy = Policy::new(cfg.shape(world)).with_action_mask(cfg.action_mask);
    let (worlds, label) = match cfg.layouts {
        None => (vec![world.clone()], String::new()),
        Some(train) => {
            let held = fulcrum_world::EvalLayouts::Test(
                fulcrum_world::HELD_OUT_START
                    ..fulcrum_world::HELD_OUT_START + cfg.eval_episodes as u64,
            );
            (layout_worlds(&cfg.world, &held, train)?, held.label())
        }
    };
    Ok(Box::new(move |flat: &[f32]| {
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
            &worlds,
            cfg.eval_episodes,
            !cfg.eval_sample,
            cfg.seed,
        );
        let mode = if cfg.eval_sample {
            PERIODIC_SAMPLE
        } else {
            PERIODIC
        };
        let mut row = summarise(&eps).row(0, 0, &world.name, mode, cfg.seed);
        row.layouts = label.clone();
        Ok(row)
    }))
}

/// The layouts `which` of the family `spec` a run on `train` is evaluated on, made;
/// refused where held-out layouts fall among the training ones.
pub fn layout_worlds(
    spec: &str,
    which: &fulcrum_world::EvalLayouts,
    train: fulcrum_world::Layouts,
) -> Result<Vec<World>> {
    let seeds = which.seeds(train).map_err(crate::error::BadRequest)?;
    if seeds.end - seeds.start > 100_000 {
        return bad(format!(
            "--layouts {}: at most 100000 layouts an evaluation",
            which.label()
        ));
    }
    let family = fulcrum_world::family::load_family(spec)?;
    seeds
        .map(|s| family.layout(s).map_err(Into::into))
        .collect()
}

impl Summary {
    /// The summary as a row of `eval.csv`.
    pub fn row(&self, update: u64, env_steps: u64, world: &str, mode: &str, seed: u64) -> EvalRow {
        let t = |e: &Estimate| [e.value, e.lo, e.hi];
        EvalRow {
            update,
            env_steps,
            world: world.to_string(),
            layouts: String::new(),
            mode: mode.to_string(),
            seed,
            episodes: self.episodes,
            success: t(&self.success),
            ret: t(&self.ret),
            length: t(&self.length),
            tool_use: t(&self.tool_use),
            tool_choice: t(&self.tool_choice),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The moves of a shortest walk (the world's own step, moves only) from the initial
    /// state to holding tool `k`.
    fn walk_to_tool(w: &World, k: usize) -> Vec<u8> {
        use std::collections::{HashMap, VecDeque};
        let start = w.initial;
        let mut back: HashMap<fulcrum_world::State, (fulcrum_world::State, u8)> = HashMap::new();
        let mut q = VecDeque::from([start]);
        while let Some(s) = q.pop_front() {
            if s.inventory >> k & 1 == 1 {
                let mut path = Vec::new();
                let mut at = s;
                while at != start {
                    let (prev, a) = back[&at];
                    path.push(a);
                    at = prev;
                }
                path.reverse();
                return path;
            }
            for a in [
                fulcrum_world::NORTH,
                fulcrum_world::EAST,
                fulcrum_world::SOUTH,
                fulcrum_world::WEST,
            ] {
                let n = w.step(&s, a);
                if n != start && !back.contains_key(&n) {
                    back.insert(n, (s, a));
                    q.push_back(n);
                }
            }
        }
        panic!("tool {k} out of reach in {}", w.name);
    }

    /// Fewest moves from the agent to each tool's cell over the floor (the map's glyphs:
    /// rock and objects block), counted here from the rendered map.
    fn grid_moves(w: &World) -> Vec<usize> {
        let rows: Vec<Vec<char>> = w
            .render(&w.initial)
            .lines()
            .map(|l| l.chars().collect())
            .collect();
        let mut d = vec![vec![usize::MAX; w.width]; w.height];
        let (ax, ay) = (w.initial.x as usize, w.initial.y as usize);
        d[ay][ax] = 0;
        let mut q = std::collections::VecDeque::from([(ax, ay)]);
        while let Some((x, y)) = q.pop_front() {
            for (nx, ny) in [(x, y - 1), (x + 1, y), (x, y + 1), (x - 1, y)] {
                let c = rows[ny][nx];
                if d[ny][nx] == usize::MAX && (c == '.' || c.is_ascii_lowercase()) {
                    d[ny][nx] = d[y][x] + 1;
                    q.push_back((nx, ny));
                }
            }
        }
        w.tools
            .iter()
            .map(|t| d[t.pos.1 as usize][t.pos.0 as usize])
            .collect()
    }

    /// Two scripted agents on 60 layouts of `toolbox`: one walks to the nearest tool and
    /// uses it, the other to a tool that fits the task object and uses it. The figure must
    /// give the second 60 of 60 and the first exactly the layouts where the nearest tool
    /// happens to fit (counted here from the map and the rule table of docs/world.md).
    #[test]
    fn tool_choice_tells_the_nearest_tool_from_the_fitting_one() {
        let fam = fulcrum_world::family::load_family("toolbox").unwrap();
        let fits = |kind: &str, object: fulcrum_world::ObjectKind| match object {
            fulcrum_world::ObjectKind::Tree => kind == "axe",
            fulcrum_world::ObjectKind::Wall => kind == "pickaxe",
            fulcrum_world::ObjectKind::Boulder => kind == "pickaxe" || kind == "wand",
            fulcrum_world::ObjectKind::Door => false,
        };
        let (mut nearest_eps, mut fitting_eps, mut nearest_fits) = (Vec::new(), Vec::new(), 0);
        for seed in 0..60 {
            let w = fam.layout(seed).unwrap();
            let object = w.objects[0].kind;
            let d = grid_moves(&w);
            let nearest = (0..w.tools.len()).min_by_key(|&k| (d[k], k)).unwrap();
            let fitting = (0..w.tools.len())
                .find(|&k| fits(&w.tools[k].kind, object))
                .unwrap();
            if fits(&w.tools[nearest].kind, object) {
                nearest_fits += 1;
            }
            for (k, out) in [(nearest, &mut nearest_eps), (fitting, &mut fitting_eps)] {
                let mut plan = walk_to_tool(&w, k);
                plan.extend([
                    fulcrum_world::APPLY,
                    fulcrum_world::SELECT0 + k as u8,
                    fulcrum_world::NORTH,
                ]);
                let mut plan = plan.into_iter();
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                // After the plan: select in normal mode, which does nothing.
                let ep = episode(View::Full, &w, &mut rng, |_, _, _, _| {
                    plan.next().unwrap_or(fulcrum_world::SELECT0)
                });
                assert_eq!(ep.first_tool, Some(k as u8), "layout {seed}");
                out.push(ep);
            }
        }
        let (n, f) = (summarise(&nearest_eps), summarise(&fitting_eps));
        assert_eq!(f.tool_choice.value, 1.0);
        assert_eq!(n.tool_choice.value, nearest_fits as f64 / 60.0);
        assert!(
            nearest_fits < 60 && nearest_fits > 0,
            "the case must tell them apart: {nearest_fits}"
        );
        assert_eq!(n.tool_choice, wilson(nearest_fits, 60));
        // A push task has no tool that fits: the figure is not defined.
        let push = fulcrum_world::load_world("exp3").unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let ep = episode(View::Full, &push, &mut rng, |_, _, _, _| {
            fulcrum_world::NORTH
        });
        assert_eq!(ep.tool_fits, None);
        assert!(summarise(&[ep]).tool_choice.value.is_nan());
    }

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
