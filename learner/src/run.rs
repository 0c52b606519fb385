//! The learner process of `fulcrum train`: gathers trajectory chunks from shared memory,
//! runs PPO, publishes weights, writes `metrics.csv` and checkpoints.
//!
//! Per update u (of U), with K = `actors` chunks:
//!
//! 1. gather K valid chunks: synchronous mode takes one chunk per actor made by the
//!    current policy version v; with `max_policy_lag = L` any chunk with
//!    `v - L <= version <= v` counts. Invalid chunks (shape, action range, non-finite
//!    numbers, another run or world) and stale ones are dropped and counted, never used;
//! 2. order them by (actor, sequence) so the update does not depend on arrival order;
//! 3. per chunk, reward `r_t = R_t + beta * E(s_{t+1})` and GAE (truncation bootstraps
//!    from the chunk's `trunc_value`, termination does not);
//! 4. PPO on the concatenated batch with `lr = lr0 * (1 - u / U)`;
//! 5. publish the weights as version v + 1, append a metrics row, checkpoint every N
//!    updates and at the end (weights, Adam moments and step, the minibatch RNG,
//!    counters, and each actor's episode records, so that a resumed run continues
//!    exactly where the checkpoint was taken).

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use candle_core::Device;
use fulcrum_shared::traj::{
    self, read_f32s, ChunkHeader, ChunkLayout, Section, TrainNames, WeightsHeader,
};
use fulcrum_shared::World;
use iceoryx2::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::adam::Adam;
use crate::checkpoint::{self, Extra};
use crate::diagnostics::Stats;
use crate::gae::{gae, Rollout};
use crate::local::{update, UpdateData};
use crate::net::Net;
use fulcrum_shared::config::RunConfig;
use fulcrum_shared::ppo_config::PpoConfig;

/// The columns of `metrics.csv`, in order.
pub const METRICS_COLUMNS: &[&str] = &[
    "update",
    "env_steps",
    "episodes",
    "extrinsic_return",
    "success_rate",
    "intrinsic_return",
    "intrinsic_mean",
    "episode_length",
    "pickup_rate",
    "policy_loss",
    "value_loss",
    "entropy",
    "approx_kl",
    "clip_frac",
    "sps",
    "policy_lag",
    "dropped_chunks",
    "actor_restarts",
    "wall_s",
    "e_positive_frac",
    "first_pickup_step",
    "lost_chunks",
    "remote_actors",
];

/// Columns of `metrics.csv` files written before `e_positive_frac` and
/// `first_pickup_step`, and before `lost_chunks` and `remote_actors` (still read).
const LEGACY_COLUMNS: [usize; 2] = [19, 21];

/// One row of `metrics.csv`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MetricsRow {
    /// Updates done (1-based).
    pub update: u64,
    /// Env steps so far.
    pub env_steps: u64,
    /// Episodes finished in this update.
    pub episodes: u64,
    /// Mean extrinsic return of those episodes (NaN when none finished).
    pub extrinsic_return: f64,
    /// Fraction of those that reached the task's terminal state.
    pub success_rate: f64,
    /// Mean intrinsic return (sum of E in bits) of those episodes.
    pub intrinsic_return: f64,
    /// Mean E(s_{t+1}) per step in this update, bits.
    pub intrinsic_mean: f64,
    /// Mean length of those episodes.
    pub episode_length: f64,
    /// Fraction of those episodes in which a tool was picked up.
    pub pickup_rate: f64,
    /// PPO diagnostics.
    pub stats: Stats,
    /// Env steps per second over this update (collection + learning).
    pub sps: f64,
    /// Mean policy lag of the chunks used (0 in synchronous mode).
    pub policy_lag: f64,
    /// Chunks dropped so far (invalid or stale).
    pub dropped_chunks: u64,
    /// Actor restarts so far.
    pub actor_restarts: u64,
    /// Wall time of the run so far (seconds, over all resumes).
    pub wall_s: f64,
    /// Fraction of this update's transitions whose E(s_{t+1}) > 0 (NaN for forms that
    /// do not look E up).
    pub e_positive_frac: f64,
    /// Env steps at the end of the first update in which an episode with a tool pick-up
    /// ended (None before that).
    pub first_pickup_step: Option<u64>,
    /// Chunks that never arrived so far: gaps in an actor's chunk sequence (remote
    /// hosts whose link went down; 0 on one machine).
    pub lost_chunks: u64,
    /// Actors of other hosts whose chunks this update used.
    pub remote_actors: u64,
}

impl MetricsRow {
    /// The row as a point of a learning curve ([`crate::stats`]).
    pub fn point(&self) -> crate::stats::Point {
        crate::stats::Point {
            steps: self.env_steps as f64,
            episodes: self.episodes as f64,
            success: self.success_rate,
            ret: self.extrinsic_return,
        }
    }
    /// The CSV line (no newline).
    pub fn csv(&self) -> String {
        let f = |x: f64| {
            if x.is_finite() {
                format!("{x}")
            } else {
                String::new()
            }
        };
        [
            self.update.to_string(),
            self.env_steps.to_string(),
            self.episodes.to_string(),
            f(self.extrinsic_return),
            f(self.success_rate),
            f(self.intrinsic_return),
            f(self.intrinsic_mean),
            f(self.episode_length),
            f(self.pickup_rate),
            f(self.stats.policy_loss as f64),
            f(self.stats.value_loss as f64),
            f(self.stats.entropy as f64),
            f(self.stats.approx_kl as f64),
            f(self.stats.clip_frac as f64),
            f(self.sps),
            f(self.policy_lag),
            self.dropped_chunks.to_string(),
            self.actor_restarts.to_string(),
            f(self.wall_s),
            f(self.e_positive_frac),
            self.first_pickup_step
                .map(|s| s.to_string())
                .unwrap_or_default(),
            self.lost_chunks.to_string(),
            self.remote_actors.to_string(),
        ]
        .join(",")
    }

    /// Parse a CSV line written by [`MetricsRow::csv`] (empty fields are NaN).
    pub fn parse(line: &str) -> Option<MetricsRow> {
        let v: Vec<&str> = line.trim_end().split(',').collect();
        if v.len() != METRICS_COLUMNS.len() && !LEGACY_COLUMNS.contains(&v.len()) {
            return None;
        }
        let f = |i: usize| -> Option<f64> {
            if v[i].is_empty() {
                Some(f64::NAN)
            } else {
                v[i].parse().ok()
            }
        };
        let u = |i: usize| -> Option<u64> { v[i].parse().ok() };
        Some(MetricsRow {
            update: u(0)?,
            env_steps: u(1)?,
            episodes: u(2)?,
            extrinsic_return: f(3)?,
            success_rate: f(4)?,
            intrinsic_return: f(5)?,
            intrinsic_mean: f(6)?,
            episode_length: f(7)?,
            pickup_rate: f(8)?,
            stats: Stats {
                policy_loss: f(9)? as f32,
                value_loss: f(10)? as f32,
                entropy: f(11)? as f32,
                approx_kl: f(12)? as f32,
                clip_frac: f(13)? as f32,
            },
            sps: f(14)?,
            policy_lag: f(15)?,
            dropped_chunks: u(16)?,
            actor_restarts: u(17)?,
            wall_s: f(18)?,
            e_positive_frac: if v.len() > 19 { f(19)? } else { f64::NAN },
            first_pickup_step: match v.get(20) {
                None | Some(&"") => None,
                Some(_) => Some(u(20)?),
            },
            lost_chunks: if v.len() > 21 { u(21)? } else { 0 },
            remote_actors: if v.len() > 22 { u(22)? } else { 0 },
        })
    }
}

/// Read a run's `metrics.csv` (rows that do not parse are skipped).
pub fn read_metrics(path: &Path) -> std::io::Result<Vec<MetricsRow>> {
    let text = std::fs::read_to_string(path)?;
    Ok(text.lines().skip(1).filter_map(MetricsRow::parse).collect())
}

/// Paths inside a run directory.
#[derive(Debug, Clone)]
pub struct RunPaths {
    /// The directory.
    pub dir: PathBuf,
}

impl RunPaths {
    /// `config.toml`.
    pub fn config(&self) -> PathBuf {
        self.dir.join("config.toml")
    }
    /// `metrics.csv`.
    pub fn metrics(&self) -> PathBuf {
        self.dir.join("metrics.csv")
    }
    /// `checkpoints/latest.safetensors`.
    pub fn checkpoint(&self) -> PathBuf {
        self.dir.join("checkpoints").join("latest.safetensors")
    }
    /// `plots/`.
    pub fn plots(&self) -> PathBuf {
        self.dir.join("plots")
    }
    /// `hosts.csv`: per update and host, the chunks used (runs with `--listen`).
    pub fn hosts(&self) -> PathBuf {
        self.dir.join("hosts.csv")
    }
    /// `hosts.txt`: `index name address` per remote host, written by the bridge.
    pub fn host_names(&self) -> PathBuf {
        self.dir.join("hosts.txt")
    }
}

/// Why the learner stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LearnerExit {
    /// Every update done; final checkpoint written.
    Finished,
    /// Asked to stop; a checkpoint of the last finished update was written.
    Interrupted,
}

/// Learner failures.
#[derive(Debug, thiserror::Error)]
pub enum LearnerError {
    /// The run directory or its files.
    #[error("{0}")]
    Run(String),
    /// A checkpoint could not be written or read.
    #[error(transparent)]
    Checkpoint(#[from] checkpoint::CheckpointError),
    /// candle failed.
    #[error("candle: {0}")]
    Candle(#[from] candle_core::Error),
    /// iceoryx2 failed.
    #[error("shared memory: {0}")]
    Ipc(String),
}

/// A chunk copied out of shared memory.
struct Chunk {
    h: ChunkHeader,
    data: Vec<u8>,
}

/// Counters a checkpoint carries.
#[derive(Debug, Clone, Copy, Default)]
struct Counters {
    update: u64,
    env_steps: u64,
    episodes: u64,
    dropped: u64,
    wall_s: f64,
    /// Env steps at the first update with a pick-up (0 = none yet).
    first_pickup: u64,
    /// Chunks lost in transit (sequence gaps).
    lost: u64,
    /// The KL penalty's coefficient now (it adapts after each update).
    kl_coef: f32,
    /// The intrinsic rewards' running scale (intrinsic value head).
    int_std: crate::stats::RunningStd,
}

fn ipc(what: &str) -> impl Fn(&dyn std::fmt::Debug) -> LearnerError + '_ {
    move |e| LearnerError::Ipc(format!("{what}: {e:?}"))
}

/// Run the learner until every update is done or `stop` is set. `progress` gets each
/// metrics row as it is written.
pub fn run_learner(
    world: &World,
    cfg: &RunConfig,
    paths: &RunPaths,
    namespace: &str,
    stop: &'static AtomicBool,
    mut progress: impl FnMut(&MetricsRow, u64),
) -> Result<LearnerExit, LearnerError> {
    let dev = Device::Cpu;
    let shape = cfg.shape(world);
    let net = Net::new(shape, cfg.seed, &dev)?;
    let mut adam = Adam::new(&net)?;
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed ^ 0x5eed_5eed);
    let mut ctr = Counters {
        kl_coef: cfg.ppo.kl_coef,
        ..Counters::default()
    };
    let mut env_blobs: BTreeMap<String, Vec<u8>> = BTreeMap::new();
    let ckpt = paths.checkpoint();
    if ckpt.exists() {
        let extra = checkpoint::load(&ckpt, &net, &mut adam)?;
        cfg.fits_checkpoint(&extra)
            .map_err(|e| LearnerError::Run(format!("{}: {e}", ckpt.display())))?;
        let get = |k: &str| extra.counters.get(k).copied().unwrap_or(0);
        ctr.update = get("update");
        ctr.env_steps = get("env_steps");
        ctr.episodes = get("episodes");
        ctr.dropped = get("dropped_chunks");
        ctr.first_pickup = get("first_pickup_step");
        ctr.lost = get("lost_chunks");
        ctr.wall_s = extra.floats.get("wall_s").copied().unwrap_or(0.0);
        if let Some(&k) = extra.floats.get("kl_coef") {
            ctr.kl_coef = k as f32;
        }
        let f = |k: &str| extra.floats.get(k).copied().unwrap_or(0.0);
        ctr.int_std = crate::stats::RunningStd {
            count: f("int_std_count"),
            mean: f("int_std_mean"),
            m2: f("int_std_m2"),
        };
        if let Some(r) = extra
            .blobs
            .get("learner_rng")
            .and_then(|b| checkpoint::rng_restore(b))
        {
            rng = r;
        }
        env_blobs = extra
            .blobs
            .into_iter()
            .filter(|(k, _)| k.starts_with("env/"))
            .collect();
        trim_metrics(&paths.metrics(), ctr.update)?;
        trim_rows(&paths.hosts(), HOSTS_COLUMNS, ctr.update)?;
        tracing::info!(update = ctr.update, "resumed from checkpoint");
    }
    let updates = cfg.updates();
    let world_hash = world.content_hash();
    let run = traj::run_tag(namespace);
    let layout = ChunkLayout {
        envs: cfg.envs_per_actor,
        steps: cfg.steps_per_chunk,
        cells: shape.cells,
        flags: shape.flags,
    };

    let node = NodeBuilder::new()
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|e| ipc("node")(&e))?;
    let names = TrainNames::new(namespace);
    let tsvc = traj::trajectory_service(&node, &names).map_err(LearnerError::Ipc)?;
    let sub = tsvc
        .subscriber_builder()
        .create()
        .map_err(|e| ipc("subscriber")(&e))?;
    let twake = traj::wake_service(&node, &names.trajectories_wake).map_err(LearnerError::Ipc)?;
    let listener = twake
        .listener_builder()
        .create()
        .map_err(|e| ipc("listener")(&e))?;
    let psvc = traj::policy_service(&node, &names).map_err(LearnerError::Ipc)?;
    let publisher = psvc
        .publisher_builder()
        .initial_max_slice_len(net.len())
        .max_loaned_samples(2)
        .create()
        .map_err(|e| ipc("publisher")(&e))?;
    let pwake = traj::wake_service(&node, &names.policy_wake).map_err(LearnerError::Ipc)?;
    let notifier = pwake
        .notifier_builder()
        .create()
        .map_err(|e| ipc("notifier")(&e))?;

    let publish = |version: u64| -> Result<(), LearnerError> {
        let flat = net.flat()?;
        let mut s = publisher
            .loan_slice_uninit(flat.len())
            .map_err(|e| ipc("loan weights")(&e))?;
        *s.user_header_mut() = WeightsHeader {
            run,
            world_hash,
            version,
            len: flat.len() as u64,
        };
        let s = s.write_from_slice(&flat);
        s.send().map_err(|e| ipc("send weights")(&e))?;
        let _ = notifier.notify();
        Ok(())
    };
    publish(ctr.update)?;

    let mut metrics = open_metrics(&paths.metrics())?;
    let remote = cfg.remote;
    let stall = Duration::from_secs_f64(cfg.stall_timeout_s);
    // Remote actors seen, and whether the learner waits for them (a stalled one is
    // live again with its next chunk).
    let mut roster: BTreeMap<u32, bool> = BTreeMap::new();
    // Per actor: (incarnation, last sequence number): a gap is a lost chunk.
    let mut last_seq: BTreeMap<u32, (u32, u64)> = BTreeMap::new();
    let mut hosts = if remote {
        Some(HostsLog::open(paths)?)
    } else {
        None
    };
    let target =
        |roster: &BTreeMap<u32, bool>| cfg.actors + roster.values().filter(|&&l| l).count();
    let mut restarts: BTreeMap<u32, u32> = BTreeMap::new();
    let mut pending: Vec<Chunk> = Vec::new();
    let ppo = cfg.ppo;
    let started = Instant::now();
    let wall0 = ctr.wall_s;
    let mut last = Instant::now();
    let n_actions = world.num_actions();
    let more = |ctr: &Counters| {
        if remote {
            ctr.env_steps < cfg.total_steps
        } else {
            ctr.update < updates
        }
    };
    while more(&ctr) {
        let version = ctr.update;
        // 1. Gather.
        let mut batch: Vec<Chunk> = Vec::with_capacity(target(&roster));
        // Chunks received earlier that are still usable.
        for c in std::mem::take(&mut pending) {
            let k = target(&roster);
            admit(
                c,
                version,
                cfg,
                k,
                &mut batch,
                &mut pending,
                &mut ctr.dropped,
            );
        }
        let mut idle = Instant::now();
        let mut gather = Instant::now();
        while batch.len() < target(&roster) {
            if stop.load(Ordering::Relaxed) {
                ctr.wall_s = wall0 + started.elapsed().as_secs_f64();
                save(paths, cfg, &net, &adam, &rng, &ctr, &env_blobs)?;
                return Ok(LearnerExit::Interrupted);
            }
            let mut got = false;
            while let Some(sample) = sub.receive().map_err(|e| ipc("receive")(&e))? {
                got = true;
                let h = *sample.user_header();
                let payload: &[u8] = sample.payload();
                if h.run != run || h.world_hash != world_hash {
                    ctr.dropped += 1;
                    tracing::warn!(actor = h.actor, "dropped a chunk of another run or world");
                    continue;
                }
                if let Err(why) = layout.validate(&h, n_actions, payload) {
                    ctr.dropped += 1;
                    tracing::warn!(actor = h.actor, seq = h.seq, why, "dropped a bad chunk");
                    continue;
                }
                let r = restarts.entry(h.actor).or_default();
                *r = (*r).max(h.incarnation);
                if let Some(&(inc, s)) = last_seq.get(&h.actor) {
                    if inc == h.incarnation && h.seq > s + 1 {
                        let gap = h.seq - s - 1;
                        ctr.lost += gap;
                        if let Some(log) = hosts.as_mut() {
                            *log.lost.entry(traj::host_of(h.actor)).or_default() += gap;
                        }
                        tracing::warn!(
                            actor = h.actor,
                            lost = gap,
                            "chunks of an actor never arrived"
                        );
                    }
                }
                last_seq.insert(h.actor, (h.incarnation, h.seq));
                if remote
                    && traj::host_of(h.actor) > 0
                    && roster.insert(h.actor, true) != Some(true)
                {
                    tracing::info!(
                        actor = h.actor,
                        host = traj::host_of(h.actor),
                        "a remote actor joined"
                    );
                }
                let c = Chunk {
                    h,
                    data: payload.to_vec(),
                };
                let k = target(&roster);
                admit(
                    c,
                    version,
                    cfg,
                    k,
                    &mut batch,
                    &mut pending,
                    &mut ctr.dropped,
                );
                if batch.len() >= k {
                    break;
                }
            }
            if remote && !got && gather.elapsed() > stall {
                // Go on without the remote actors that have not delivered; each is
                // awaited again from its next chunk.
                for (a, live) in roster.iter_mut() {
                    if *live && !batch.iter().any(|c| c.h.actor == *a) {
                        *live = false;
                        tracing::warn!(
                            actor = *a,
                            host = traj::host_of(*a),
                            "no chunk from a remote actor within the stall timeout: going on without it"
                        );
                    }
                }
                gather = Instant::now();
            }
            if !got && batch.len() < target(&roster) {
                let _ = listener.timed_wait(|_| {}, Duration::from_millis(50));
                if idle.elapsed() > Duration::from_secs(1) {
                    // Weights may have been missed by a (re)started actor: repeat them.
                    idle = Instant::now();
                    publish(version)?;
                }
            }
        }
        batch.sort_by_key(|c| (c.h.actor, c.h.incarnation, c.h.seq));

        // 2. Rewards and GAE per chunk, concatenated.
        let (m, t_len) = (layout.envs, layout.steps);
        let n = m * t_len;
        let total = n * batch.len();
        let (c_len, f_len) = (layout.cells, layout.flags);
        let mut d_glyphs = Vec::with_capacity(total * c_len);
        let mut d_flags = Vec::with_capacity(total * f_len);
        let mut d_actions = Vec::with_capacity(total);
        let mut d_lp = vec![0.0f32; total];
        let mut d_val = vec![0.0f32; total];
        let mut d_adv = Vec::with_capacity(total);
        let mut d_ret = Vec::with_capacity(total);
        let two_heads = cfg.intrinsic_value_head;
        let mut d_val_int = vec![0.0f32; if two_heads { total } else { 0 }];
        let mut d_ret_int = Vec::new();
        let mut row = MetricsRow::default();
        let (mut ext_sum, mut int_ret_sum, mut len_sum, mut int_sum, mut lag_sum) =
            (0.0, 0.0, 0.0, 0.0, 0.0);
        let (mut episodes, mut successes, mut pickups, mut e_positive) = (0u64, 0u64, 0u64, 0u64);
        let mut ext = vec![0.0f32; n];
        let mut int = vec![0.0f32; n];
        let mut tv = vec![0.0f32; n];
        let mut lv = vec![0.0f32; m];
        for (k, c) in batch.iter().enumerate() {
            let p = &c.data;
            d_glyphs.extend_from_slice(&p[layout.range(Section::Glyphs)]);
            d_flags.extend_from_slice(&p[layout.range(Section::Flags)]);
            d_actions.extend(p[layout.range(Section::Actions)].iter().map(|&a| a as u32));
            read_f32s(
                &p[layout.range(Section::Logprob)],
                &mut d_lp[k * n..(k + 1) * n],
            );
            read_f32s(
                &p[layout.range(Section::Value)],
                &mut d_val[k * n..(k + 1) * n],
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
            let values = &d_val[k * n..(k + 1) * n];
            if two_heads {
                // Two streams: the task reward with V, the intrinsic reward (divided by
                // its running std) with V_int and gamma_int; A = A_ext + beta * A_int.
                ctr.int_std.update(&int);
                let scale = (ctr.int_std.std() + 1e-8) as f32;
                let int_n: Vec<f32> = int.iter().map(|x| x / scale).collect();
                let (mut tvi, mut lvi) = (vec![0.0f32; n], vec![0.0f32; m]);
                read_f32s(
                    &p[layout.range(Section::ValueInt)],
                    &mut d_val_int[k * n..(k + 1) * n],
                );
                read_f32s(&p[layout.range(Section::TruncValueInt)], &mut tvi);
                read_f32s(&p[layout.range(Section::LastValueInt)], &mut lvi);
                let (adv_e, ret_e) = gae_of(&ext, values, &tv, &lv, ppo.gamma);
                let values_int = &d_val_int[k * n..(k + 1) * n];
                let (adv_i, ret_i) = gae_of(&int_n, values_int, &tvi, &lvi, cfg.gamma_int);
                d_adv.extend(adv_e.iter().zip(&adv_i).map(|(e, i)| e + beta * i));
                d_ret.extend_from_slice(&ret_e);
                d_ret_int.extend_from_slice(&ret_i);
            } else {
                let rewards: Vec<f32> = ext.iter().zip(&int).map(|(r, e)| r + beta * e).collect();
                let (adv, ret) = gae_of(&rewards, values, &tv, &lv, ppo.gamma);
                d_adv.extend_from_slice(&adv);
                d_ret.extend_from_slice(&ret);
            }
            episodes += c.h.episodes as u64;
            successes += c.h.successes as u64;
            pickups += c.h.pickups as u64;
            e_positive += c.h.e_positive as u64;
            ext_sum += c.h.ext_return_sum;
            int_ret_sum += c.h.int_return_sum;
            len_sum += c.h.length_sum;
            int_sum += c.h.int_reward_sum;
            lag_sum += (version - c.h.policy_version.min(version)) as f64;
            env_blobs.insert(
                format!("env/{}", c.h.actor),
                p[layout.range(Section::EnvState)].to_vec(),
            );
        }

        // 3. PPO.
        let lr = if remote && ppo.lr_anneal {
            ppo.lr * (1.0 - (ctr.env_steps as f64 / cfg.total_steps as f64).min(1.0))
        } else {
            ppo.lr_at(ctr.update, updates)
        };
        row.stats = update(
            &net,
            &mut adam,
            &PpoConfig {
                kl_coef: ctr.kl_coef,
                ..ppo
            },
            lr,
            &mut rng,
            &UpdateData {
                glyphs: &d_glyphs,
                flags: &d_flags,
                actions: &d_actions,
                logprobs: &d_lp,
                values: &d_val,
                advantages: &d_adv,
                returns: &d_ret,
                action_mask: cfg.action_mask,
                int: two_heads.then_some((&d_val_int[..], &d_ret_int[..])),
            },
        )?;
        ctr.kl_coef = ppo.adapt_kl(ctr.kl_coef, row.stats.approx_kl);
        ctr.update += 1;
        ctr.env_steps += total as u64;
        ctr.episodes += episodes;
        publish(ctr.update)?;

        // 4. Metrics and checkpoints.
        let per_ep = |x: f64| {
            if episodes > 0 {
                x / episodes as f64
            } else {
                f64::NAN
            }
        };
        let now = Instant::now();
        row.update = ctr.update;
        row.env_steps = ctr.env_steps;
        row.episodes = episodes;
        row.extrinsic_return = per_ep(ext_sum);
        row.success_rate = per_ep(successes as f64);
        row.intrinsic_return = per_ep(int_ret_sum);
        row.intrinsic_mean = int_sum / total as f64;
        row.episode_length = per_ep(len_sum);
        row.pickup_rate = per_ep(pickups as f64);
        row.e_positive_frac = if cfg.form().uses_empowerment() {
            e_positive as f64 / total as f64
        } else {
            f64::NAN
        };
        if ctr.first_pickup == 0 && pickups > 0 {
            ctr.first_pickup = ctr.env_steps;
        }
        row.first_pickup_step = (ctr.first_pickup > 0).then_some(ctr.first_pickup);
        row.sps = total as f64 / now.duration_since(last).as_secs_f64().max(1e-9);
        row.policy_lag = lag_sum / batch.len() as f64;
        row.dropped_chunks = ctr.dropped;
        row.actor_restarts = restarts.values().map(|&r| r as u64).sum();
        row.wall_s = wall0 + started.elapsed().as_secs_f64();
        row.lost_chunks = ctr.lost;
        row.remote_actors = batch
            .iter()
            .filter(|c| traj::host_of(c.h.actor) > 0)
            .count() as u64;
        last = now;
        writeln!(metrics, "{}", row.csv())
            .and_then(|_| metrics.flush())
            .map_err(|e| {
                LearnerError::Run(format!(
                    "cannot append to {}: {e}",
                    paths.metrics().display()
                ))
            })?;
        if let Some(log) = hosts.as_mut() {
            log.append(paths, ctr.update, &batch, n as u64, &roster)?;
        }
        let planned = if remote {
            // Updates so far plus those the remaining steps need at this batch size.
            ctr.update
                + cfg
                    .total_steps
                    .saturating_sub(ctr.env_steps)
                    .div_ceil(total as u64)
        } else {
            updates
        };
        progress(&row, planned);
        if ctr.update % cfg.checkpoint_every == 0 || !more(&ctr) {
            ctr.wall_s = row.wall_s;
            save(paths, cfg, &net, &adam, &rng, &ctr, &env_blobs)?;
        }
    }
    Ok(LearnerExit::Finished)
}

/// Put a received chunk where it belongs: into this update's batch, back into
/// `pending` (made by a newer policy than the learner's: cannot happen in order, kept
/// for safety), or dropped as stale.
fn admit(
    c: Chunk,
    version: u64,
    cfg: &RunConfig,
    target: usize,
    batch: &mut Vec<Chunk>,
    pending: &mut Vec<Chunk>,
    dropped: &mut u64,
) {
    let v = c.h.policy_version;
    if v > version {
        pending.push(c);
        return;
    }
    let lag = version - v;
    let fresh = if cfg.max_policy_lag == 0 {
        lag == 0 && !batch.iter().any(|b| b.h.actor == c.h.actor)
    } else {
        lag <= cfg.max_policy_lag
    };
    if fresh && batch.len() < target {
        batch.push(c);
    } else if fresh {
        pending.push(c);
    } else {
        *dropped += 1;
        tracing::debug!(actor = c.h.actor, v, version, "dropped a stale chunk");
    }
}

fn save(
    paths: &RunPaths,
    cfg: &RunConfig,
    net: &Net,
    adam: &Adam,
    rng: &ChaCha8Rng,
    ctr: &Counters,
    env_blobs: &BTreeMap<String, Vec<u8>>,
) -> Result<(), LearnerError> {
    let mut extra = Extra::default();
    extra.counters.insert("update".into(), ctr.update);
    extra.counters.insert("env_steps".into(), ctr.env_steps);
    extra.counters.insert("episodes".into(), ctr.episodes);
    extra
        .counters
        .insert("first_pickup_step".into(), ctr.first_pickup);
    extra.counters.insert("dropped_chunks".into(), ctr.dropped);
    extra.counters.insert("lost_chunks".into(), ctr.lost);
    extra.floats.insert("wall_s".into(), ctr.wall_s);
    extra.floats.insert("kl_coef".into(), ctr.kl_coef as f64);
    extra
        .floats
        .insert("int_std_count".into(), ctr.int_std.count);
    extra.floats.insert("int_std_mean".into(), ctr.int_std.mean);
    extra.floats.insert("int_std_m2".into(), ctr.int_std.m2);
    extra
        .meta
        .insert("action_mask".into(), cfg.action_mask.to_string());
    extra
        .blobs
        .insert("learner_rng".into(), checkpoint::rng_state(rng));
    for (k, v) in env_blobs {
        extra.blobs.insert(k.clone(), v.clone());
    }
    let path = paths.checkpoint();
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)
            .map_err(|e| LearnerError::Run(format!("cannot create {}: {e}", dir.display())))?;
    }
    checkpoint::save(&path, net, adam, &extra)?;
    Ok(())
}

/// The columns of `hosts.csv`.
pub const HOSTS_COLUMNS: &[&str] = &[
    "update",
    "host",
    "name",
    "actors",
    "chunks",
    "env_steps",
    "lost_chunks",
];

/// `hosts.csv` of a run with remote hosts: one row per update and host.
struct HostsLog {
    file: std::fs::File,
    names: BTreeMap<u32, String>,
    /// Chunks lost per host so far (this session).
    lost: BTreeMap<u32, u64>,
}

impl HostsLog {
    fn open(paths: &RunPaths) -> Result<HostsLog, LearnerError> {
        let file = open_csv(&paths.hosts(), HOSTS_COLUMNS)?;
        Ok(HostsLog {
            file,
            names: BTreeMap::from([(0, "local".to_string())]),
            lost: BTreeMap::new(),
        })
    }

    fn append(
        &mut self,
        paths: &RunPaths,
        update: u64,
        batch: &[Chunk],
        steps_per_chunk: u64,
        roster: &BTreeMap<u32, bool>,
    ) -> Result<(), LearnerError> {
        let mut per: BTreeMap<u32, (u64, u64)> = BTreeMap::new(); // host -> (actors, chunks)
        for c in batch {
            per.entry(traj::host_of(c.h.actor)).or_default().1 += 1;
        }
        for (&a, &live) in roster {
            let e = per.entry(traj::host_of(a)).or_default();
            e.0 += live as u64;
        }
        for h in self.lost.keys() {
            per.entry(*h).or_default();
        }
        if per.keys().any(|h| !self.names.contains_key(h)) {
            // Names of hosts that joined since: `index name address` lines.
            if let Ok(text) = std::fs::read_to_string(paths.host_names()) {
                for line in text.lines() {
                    let mut w = line.split_whitespace();
                    if let (Some(i), Some(name)) = (w.next().and_then(|i| i.parse().ok()), w.next())
                    {
                        self.names.insert(i, name.to_string());
                    }
                }
            }
        }
        let mut out = String::new();
        for (h, (actors, chunks)) in per {
            let actors = if h == 0 { chunks } else { actors };
            let name = self
                .names
                .get(&h)
                .cloned()
                .unwrap_or_else(|| format!("host{h}"));
            out.push_str(&format!(
                "{update},{h},{name},{actors},{chunks},{},{}\n",
                chunks * steps_per_chunk,
                self.lost.get(&h).copied().unwrap_or(0)
            ));
        }
        self.file
            .write_all(out.as_bytes())
            .and_then(|_| self.file.flush())
            .map_err(|e| {
                LearnerError::Run(format!("cannot append to {}: {e}", paths.hosts().display()))
            })
    }
}

/// Open `metrics.csv` for appending, writing the header if it is new.
fn open_metrics(path: &Path) -> Result<std::fs::File, LearnerError> {
    open_csv(path, METRICS_COLUMNS)
}

/// Open a CSV file for appending, writing `columns` as its header if it is new.
fn open_csv(path: &Path, columns: &[&str]) -> Result<std::fs::File, LearnerError> {
    let fresh = !path.exists()
        || std::fs::metadata(path)
            .map(|m| m.len() == 0)
            .unwrap_or(true);
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(path)
        .map_err(|e| LearnerError::Run(format!("cannot open {}: {e}", path.display())))?;
    if fresh {
        writeln!(f, "{}", columns.join(","))
            .map_err(|e| LearnerError::Run(format!("cannot write {}: {e}", path.display())))?;
    }
    Ok(f)
}

/// Keep the header and the whole rows of updates `<= upto` of a CSV file whose first
/// column is the update (`hosts.csv`); rewritten atomically.
fn trim_rows(path: &Path, columns: &[&str], upto: u64) -> Result<(), LearnerError> {
    rewrite_rows(path, columns, |line| {
        line.split(',').count() == columns.len()
            && line
                .split(',')
                .next()
                .and_then(|u| u.parse::<u64>().ok())
                .is_some_and(|u| u <= upto)
    })
}

/// Keep the header and the rows of updates `<= upto` (rows written after the last
/// checkpoint belong to updates that will be redone); rewritten atomically. A file from
/// an older version gains the new columns' header; a row torn by a crash does not parse
/// and goes.
fn trim_metrics(path: &Path, upto: u64) -> Result<(), LearnerError> {
    rewrite_rows(path, METRICS_COLUMNS, |line| {
        MetricsRow::parse(line).is_some_and(|r| r.update <= upto)
    })
}

/// Rewrite a CSV file (atomically, and only if something changes) with the header
/// `columns` and the rows that `keep`.
fn rewrite_rows(
    path: &Path,
    columns: &[&str],
    keep: impl Fn(&str) -> bool,
) -> Result<(), LearnerError> {
    let Ok(text) = std::fs::read_to_string(path) else {
        return Ok(());
    };
    let mut out = columns.join(",") + "\n";
    for line in text.lines().skip(1).filter(|l| keep(l)) {
        out.push_str(line);
        out.push('\n');
    }
    if out != text {
        fulcrum_shared::fsio::write_atomic(path, out.as_bytes())
            .map_err(|e| LearnerError::Run(format!("cannot rewrite {}: {e}", path.display())))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metrics_row_round_trips() {
        let r = MetricsRow {
            update: 3,
            env_steps: 3072,
            episodes: 7,
            extrinsic_return: 0.5,
            success_rate: 0.25,
            intrinsic_return: f64::NAN,
            intrinsic_mean: 0.125,
            episode_length: 43.5,
            pickup_rate: 1.0,
            stats: Stats {
                policy_loss: -0.01,
                value_loss: 0.2,
                entropy: 1.9,
                approx_kl: 0.003,
                clip_frac: 0.1,
            },
            sps: 1234.5,
            policy_lag: 0.0,
            dropped_chunks: 2,
            actor_restarts: 1,
            wall_s: 9.75,
            e_positive_frac: 0.375,
            first_pickup_step: Some(2048),
            lost_chunks: 5,
            remote_actors: 2,
        };
        let line = r.csv();
        assert_eq!(line.split(',').count(), METRICS_COLUMNS.len());
        let back = MetricsRow::parse(&line).unwrap();
        assert!(back.intrinsic_return.is_nan());
        assert_eq!(back.first_pickup_step, Some(2048));
        assert_eq!(back.csv(), line);
        // No pick-up yet: an empty field.
        let none = MetricsRow {
            first_pickup_step: None,
            ..r
        };
        assert!(none.csv().ends_with(",0.375,,5,2"));
        assert_eq!(
            MetricsRow::parse(&none.csv()).unwrap().first_pickup_step,
            None
        );
        // Rows of files written before the last columns still parse.
        let mid: Vec<&str> = line.split(',').take(21).collect();
        let mid = MetricsRow::parse(&mid.join(",")).unwrap();
        assert_eq!((mid.first_pickup_step, mid.lost_chunks), (Some(2048), 0));
        let legacy: Vec<&str> = line.split(',').take(19).collect();
        let old = MetricsRow::parse(&legacy.join(",")).unwrap();
        assert_eq!(old.wall_s, 9.75);
        assert!(old.e_positive_frac.is_nan() && old.first_pickup_step.is_none());
    }
}
