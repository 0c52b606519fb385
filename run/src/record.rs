//! Recordings: episodes of a run's policy as strips of frames, so a person can see what the agent does.
//!
//! The run's checkpoint gives the policy (the weights of its last update); episodes are
//! played from the world's initial state with actions sampled from the policy, as the
//! actors sample them (a ChaCha generator seeded by the caller, by default with the run's seed).
//! Each frame colours every cell by E (the run's tool, objects and horizons, the held /
//! not-held horizon by the inventory) for the agent standing there, with the inventory
//! and objects of that moment: where the bonus is, and where the agent goes.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::error::{Context, Result};
use fulcrum_actors::policy::Policy;
use fulcrum_contracts::checkpoint;
use fulcrum_contracts::config::RunConfig;
use fulcrum_empowerment::Method;
use fulcrum_learner::paths::RunPaths;
use fulcrum_world::World;
use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::error::bad;
use crate::plan::{channel, Channel};

/// Plays `episodes` episodes of the run's policy and draws each as
/// `out/episode-<k>.png` (and, with `gif`, as the animation `out/episode-<k>.gif`, one
/// frame per step); returns each file with the steps of its episode.
pub fn record(
    paths: &RunPaths,
    cfg: &RunConfig,
    w: &World,
    episodes: usize,
    seed: u64,
    out: &Path,
    gif: bool,
) -> Result<Vec<(PathBuf, u32)>> {
    let (mut policy, _) = load_policy(&paths.checkpoint(), paths, cfg, w)?;

    // E for every state, by the run's channel (the objects its service counts, the tool
    // it recorded at its start).
    let Channel {
        engine: e,
        set,
        tool,
    } = channel(w, cfg)?;
    let vu = e.values(tool, &set, cfg.horizon_unequipped, Method::Dp)?;
    let ve = e.values(tool, &set, cfg.horizon_equipped, Method::Dp)?;
    let value = |s: &fulcrum_world::State| -> Option<f64> {
        let id = e.space.id(s)? as usize;
        Some(if tool.held(s) { ve[id] } else { vu[id] })
    };

    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let spec = cfg.view.spec(w);
    let (mut g, mut f) = (vec![0u8; spec.cells()], vec![0u8; spec.flags]);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut act, mut lp, mut v) = ([0u8], [0.0f32], [0.0f32]);
    let mut written = Vec::new();
    for k in 1..=episodes {
        let mut ep = w.reset();
        let mut frames = Vec::new();
        let mut caption = "t=0".to_string();
        let (mut ret, mut e_sum) = (0.0f32, 0.0f64);
        loop {
            let s = ep.state;
            let here = value(&s).unwrap_or(0.0);
            frames.push(frame(w, &s, &value, format!("{caption} E={here:.2}")));
            cfg.view.observe(w, &s, &mut g, &mut f);
            policy.act(&g, &f, &mut rng, &mut act, &mut lp, &mut v);
            let o = w.env_step_drawn(&mut ep, act[0], || rng.next_u64());
            ret += o.reward;
            e_sum += value(&ep.state).unwrap_or(0.0);
            caption = format!("t={} {}", ep.t, w.action_name(act[0]));
            if o.terminated || o.truncated {
                let s = ep.state;
                let here = value(&s).unwrap_or(0.0);
                frames.push(frame(w, &s, &value, format!("{caption} E={here:.2}")));
                let outcome = if o.terminated {
                    "task done"
                } else {
                    "time limit"
                };
                let strip = fulcrum_plot::Strip {
                    title: format!(
                        "{}: episode {k} of the policy (seed {seed}), {} steps, {outcome}, return {ret}, E summed {e_sum:.1} bits",
                        w.name, ep.t
                    ),
                    width: w.width,
                    height: w.height,
                    frames,
                };
                let path = out.join(format!("episode-{k}.png"));
                fulcrum_plot::episode_png(&path, &strip)
                    .with_context(|| format!("cannot draw {}", path.display()))?;
                written.push((path, ep.t));
                if gif {
                    let path = out.join(format!("episode-{k}.gif"));
                    fulcrum_plot::episode_gif(&path, &strip)
                        .with_context(|| format!("cannot draw {}", path.display()))?;
                    written.push((path, ep.t));
                }
                break;
            }
        }
    }
    Ok(written)
}

/// One frame: the glyphs of `s` and, per cell, E for the agent standing there.
fn frame(
    w: &World,
    s: &fulcrum_world::State,
    value: &dyn Fn(&fulcrum_world::State) -> Option<f64>,
    caption: String,
) -> fulcrum_plot::Frame {
    let mut glyphs = Vec::with_capacity(w.width * w.height);
    let mut values = Vec::with_capacity(w.width * w.height);
    for y in 0..w.height {
        for x in 0..w.width {
            glyphs.push(w.glyph_at(s, x, y));
            let mut t = *s;
            t.x = x as u8;
            t.y = y as u8;
            values.push(value(&t));
        }
    }
    fulcrum_plot::Frame {
        caption,
        glyphs,
        values,
    }
}

/// The policy of a checkpoint (the run's latest unless `ckpt` names another), its weights
/// checked against the network the run's configuration and `w` give, and the
/// checkpoint's counters (update, env steps, ...).
pub fn load_policy(
    ckpt: &Path,
    paths: &RunPaths,
    cfg: &RunConfig,
    w: &World,
) -> Result<(Policy, BTreeMap<String, u64>)> {
    if !ckpt.exists() {
        return bad(format!(
            "{}: no checkpoint yet, so no policy to play",
            paths.dir.display()
        ));
    }
    let shape = cfg.shape(w);
    // The weights, checked against the layout, in the layout's order: the flat vector
    // the policy takes.
    let contents = checkpoint::read(ckpt, &shape.params())?;
    if let Err(e) = cfg.fits_checkpoint(&contents.extra) {
        return bad(format!("{}: {e}", ckpt.display()));
    }
    let flat: Vec<f32> = contents
        .params
        .into_iter()
        .flat_map(|p| p.weights)
        .collect();
    let mut policy = Policy::new(shape).with_action_mask(cfg.action_mask);
    crate::ensure!(
        policy.set(&flat),
        "the checkpoint's weights do not fit the network"
    );
    Ok((policy, contents.extra.counters))
}
