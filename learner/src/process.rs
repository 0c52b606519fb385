//! The learner process of `fulcrum train`: gathers trajectory chunks from shared memory,
//! runs PPO, publishes weights, writes `metrics.csv` and checkpoints.
//!
//! Per update u (of U), with K = `actors` chunks:
//!
//! 1. gather K valid chunks: synchronous mode takes one chunk per actor made by the
//!    current policy version v; with `max_policy_lag = L` any chunk with
//!    `v - L <= version <= v` counts. Each chunk is copied out of shared memory and the
//!    copy checked whole (the `intake` module); invalid chunks (another run or world, or
//!    anything an actor of this world could not have written) and stale ones are
//!    dropped and counted, never used; a local actor that does not deliver within its
//!    deadline, or whose chunk was refused, is left out until its next chunk
//!    ([`crate::watch`]);
//! 2. order them by (actor, sequence) so the update does not depend on arrival order;
//! 3. per chunk, reward `r_t = R_t + beta * E(s_{t+1})` and GAE (truncation bootstraps
//!    from the chunk's `trunc_value`, termination does not);
//! 4. PPO on the concatenated batch with `lr = lr0 * (1 - u / U)`;
//! 5. check that the weights are finite (else stop: [`crate::error::LearnerError::Diverged`]),
//!    publish them as version v + 1, append a metrics row, checkpoint every N
//!    updates and at the end (weights, Adam moments and step, the minibatch RNG,
//!    counters, and each actor's episode records, so that a resumed run continues
//!    exactly where the checkpoint was taken).

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use candle_core::Device;
use fulcrum_contracts::config::RunConfig;
use fulcrum_contracts::ppo_config::PpoConfig;
use fulcrum_contracts::traj::{self, ChunkHeader, ChunkLayout, Section};
use fulcrum_world::{LayoutPool, World};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::adam::Adam;
use crate::batch::{Batch, Chunk};
use crate::checkpoint::{self, Extra};
use crate::counters::Counters;
use crate::csv::trim_rows;
use crate::diagnostics::Stats;
use crate::error::LearnerError;
use crate::evalcsv::EvalRow;
use crate::hosts::{HostsLog, HOSTS_COLUMNS};
use crate::intake::take_chunk;
use crate::local::update;
use crate::metrics::{append_row, open_metrics, read_metrics, sync_rows, trim_metrics, MetricsRow};
use crate::net::Net;
use crate::paths::RunPaths;
use crate::ports::Ports;
use crate::trap::TrapDetector;
use crate::watch::{Fault, LocalStall, Notice};
use fulcrum_contracts::IpcError;

/// Why the learner stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LearnerExit {
    /// Every update done; final checkpoint written.
    Finished,
    /// Asked to stop; a checkpoint of the last finished update was written.
    Interrupted,
}

/// Run the learner until every update is done or `stop` is set. `progress` gets each
/// metrics row as it is written.
pub fn run_learner(
    world: &World,
    cfg: &RunConfig,
    paths: &RunPaths,
    namespace: &str,
    stop: &'static AtomicBool,
    progress: impl FnMut(&MetricsRow, u64),
) -> Result<LearnerExit, LearnerError> {
    let hooks = Hooks {
        notice: Box::new(|_| {}),
        evaluate: None,
    };
    run_learner_with(world, cfg, paths, namespace, stop, progress, hooks)
}

/// Plays the policy of the given flat weights (the order of
/// [`fulcrum_contracts::layout::NetShape::params`]) greedily and says what it did: the
/// periodic evaluation of `train --eval-every`. The learner fills in the row's update and
/// env steps, appends it to `eval.csv` and gives its scalars to TensorBoard.
pub type Evaluate<'a> = Box<dyn FnMut(&[f32]) -> Result<EvalRow, String> + 'a>;

/// What the learner tells its process, and asks of it, besides the metrics rows.
pub struct Hooks<'a> {
    /// Told when the learner waits for chunks and when it goes on without a local actor
    /// ([`crate::watch`]).
    pub notice: Box<dyn FnMut(&Notice) + 'a>,
    /// Called every `eval_every` updates and after the last (runs with
    /// `eval_every > 0`).
    pub evaluate: Option<Evaluate<'a>>,
}

impl std::fmt::Debug for Hooks<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Hooks")
            .field("evaluate", &self.evaluate.is_some())
            .finish_non_exhaustive()
    }
}

/// [`run_learner`], with its [`Hooks`].
pub fn run_learner_with<'a>(
    world: &'a World,
    cfg: &'a RunConfig,
    paths: &'a RunPaths,
    namespace: &str,
    stop: &'static AtomicBool,
    progress: impl FnMut(&MetricsRow, u64),
    hooks: Hooks<'a>,
) -> Result<LearnerExit, LearnerError> {
    let mut l = Learner::new(world, cfg, paths, namespace, stop)?;
    l.notice = hooks.notice;
    l.evaluate = hooks.evaluate;
    l.run(progress)
}

/// The learner process: the network and its optimiser, the counters a checkpoint
/// carries, the ports, the run's files, and what it knows of the actors. One method per
/// phase of an update: [`Learner::gather`] (with [`Learner::admit`]), [`Learner::update`],
/// [`Learner::publish`], [`Learner::record`], [`Learner::checkpoint`].
struct Learner<'a> {
    world: &'a World,
    cfg: &'a RunConfig,
    paths: &'a RunPaths,
    stop: &'static AtomicBool,
    net: Net,
    adam: Adam,
    /// The minibatch generator.
    rng: ChaCha8Rng,
    ctr: Counters,
    /// Each actor's worlds (`env/<actor>`) as of its last chunk used.
    env_blobs: BTreeMap<String, Vec<u8>>,
    /// Updates in the run (runs without remote actors).
    updates: u64,
    world_hash: u64,
    /// The run's tag, which chunks must carry.
    run: u64,
    layout: ChunkLayout,
    ports: Ports,
    metrics: std::fs::File,
    /// TensorBoard's view of the rows (None once writing it failed: `metrics.csv`
    /// stays the record, and the events are rebuilt from it on `--resume`).
    tb: Option<crate::tensorboard::EventWriter>,
    hosts: Option<HostsLog>,
    /// Remote actors seen, and whether the learner waits for them (a stalled one is
    /// live again with its next chunk).
    roster: BTreeMap<u32, bool>,
    /// Per actor: (incarnation, last sequence number): a gap is a lost chunk.
    last_seq: BTreeMap<u32, (u32, u64)>,
    /// Per actor, its highest incarnation (its restarts).
    restarts: BTreeMap<u32, u32>,
    /// Chunks received that belong to a later update.
    pending: Vec<Chunk>,
    /// When this session started, and the run's wall time before it.
    started: Instant,
    wall0: f64,
    /// When the last update ended.
    last: Instant,
    /// The fault-injection hook of the tests ([`crate::watch`]).
    fault: Fault,
    /// Local actors left out in synchronous mode, and the deadline's measure.
    local: LocalStall,
    /// Where the learner's notices go.
    notice: Box<dyn FnMut(&Notice) + 'a>,
    /// The periodic evaluation (`train --eval-every`).
    evaluate: Option<Evaluate<'a>>,
    /// The beacon-trap detector, and whether it has spoken in this session.
    trap: TrapDetector,
    trap_told: bool,
    /// A run on a world family: its layouts, which chunks' records are checked against.
    family: Option<LayoutPool>,
}

impl<'a> Learner<'a> {
    /// A fresh learner, or the one of the run's checkpoint; its ports open and its
    /// weights published.
    fn new(
        world: &'a World,
        cfg: &'a RunConfig,
        paths: &'a RunPaths,
        namespace: &str,
        stop: &'static AtomicBool,
    ) -> Result<Learner<'a>, LearnerError> {
        let shape = cfg.shape(world);
        let net = Net::new(shape, cfg.seed, &Device::Cpu)?;
        let mut adam = Adam::new(&net)?;
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed ^ 0x5eed_5eed);
        let mut ctr = Counters {
            kl_coef: cfg.ppo.kl_coef,
            ..Counters::default()
        };
        let mut env_blobs = BTreeMap::new();
        let ckpt = paths.checkpoint();
        if ckpt.exists() {
            let extra = checkpoint::load(&ckpt, &net, &mut adam)?;
            cfg.fits_checkpoint(&extra)
                .map_err(|e| LearnerError::Run(format!("{}: {e}", ckpt.display())))?;
            ctr.restore(&extra);
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
        } else {
            // Rows of an earlier start that failed before its first checkpoint.
            trim_metrics(&paths.metrics(), 0)?;
            trim_rows(&paths.hosts(), HOSTS_COLUMNS, 0)?;
        }
        let layout = ChunkLayout {
            envs: cfg.envs_per_actor,
            steps: cfg.steps_per_chunk,
            cells: shape.cells,
            flags: shape.flags,
        };
        let (run, world_hash) = (traj::run_tag(namespace), world.content_hash());
        let ports = Ports::open(namespace, net.len(), cfg.weights_subscribers())?;
        ports.publish(&net, run, world_hash, ctr.update)?;
        let metrics = open_metrics(&paths.metrics())?;
        // The detector sees the rows a resume keeps, so that it marks the next ones
        // exactly as an uninterrupted run would.
        let mut trap = TrapDetector::new(cfg.form(), cfg.beta, world);
        if ctr.update > 0 {
            for row in read_metrics(&paths.metrics()).unwrap_or_default() {
                trap.observe(&row);
            }
        }
        // Periodic evaluations after the checkpoint are made again.
        let evals = crate::evalcsv::trim_periodic(&paths.eval(), ctr.update).map_err(|e| {
            LearnerError::Run(format!("cannot trim {}: {e}", paths.eval().display()))
        })?;
        let tb = open_events(paths, &evals, ctr.wall_s);
        let family = match cfg.layouts {
            None => None,
            Some(l) => {
                let f = fulcrum_world::family::load_family(&cfg.world)
                    .map_err(|e| LearnerError::Run(e.to_string()))?;
                Some(LayoutPool::new(f, l.pool_size(256)))
            }
        };
        let hosts = if cfg.remote {
            Some(HostsLog::open(paths)?)
        } else {
            None
        };
        Ok(Learner {
            world,
            cfg,
            paths,
            stop,
            net,
            adam,
            rng,
            ctr,
            env_blobs,
            updates: cfg.updates(),
            world_hash,
            run,
            layout,
            ports,
            metrics,
            tb,
            hosts,
            roster: BTreeMap::new(),
            last_seq: BTreeMap::new(),
            restarts: BTreeMap::new(),
            pending: Vec::new(),
            started: Instant::now(),
            wall0: ctr.wall_s,
            last: Instant::now(),
            fault: Fault::from_env(),
            local: LocalStall::default(),
            notice: Box::new(|_| {}),
            evaluate: None,
            trap,
            trap_told: false,
            family,
        })
    }

    /// Update after update until the run is done or asked to stop.
    fn run(
        mut self,
        mut progress: impl FnMut(&MetricsRow, u64),
    ) -> Result<LearnerExit, LearnerError> {
        while self.more() {
            let version = self.ctr.update;
            let Some(chunks) = self.gather(version)? else {
                return Ok(LearnerExit::Interrupted);
            };
            let batch = Batch::new(
                &chunks,
                &self.layout,
                self.cfg,
                version,
                &mut self.ctr.int_std,
            );
            for c in &chunks {
                self.env_blobs.insert(
                    format!("env/{}", c.h.actor),
                    c.data[self.layout.range(Section::EnvState)].to_vec(),
                );
            }
            let stats = self.update(&batch)?;
            self.fault.inject(&self.net, self.ctr.update)?;
            self.publish(self.ctr.update)?;
            let row = self.record(stats, &batch, &chunks)?;
            progress(&row, self.planned(batch.len));
            let every = self.cfg.eval_every;
            if every > 0 && (self.ctr.update % every == 0 || !self.more()) {
                self.periodic_eval(row.wall_s)?;
            }
            if self.ctr.update % self.cfg.checkpoint_every == 0 || !self.more() {
                self.ctr.wall_s = row.wall_s;
                self.checkpoint()?;
            }
        }
        Ok(LearnerExit::Finished)
    }

    /// Whether updates remain: by count, or with remote actors by env steps.
    fn more(&self) -> bool {
        if self.cfg.remote {
            self.ctr.env_steps < self.cfg.total_steps
        } else {
            self.ctr.update < self.updates
        }
    }

    /// Chunks an update takes: one per local actor not left out and per live remote
    /// one (at least one: an update is never made of no chunk).
    fn target(&self) -> usize {
        let local = self.cfg.actors.saturating_sub(self.local.stalled.len());
        (local + self.roster.values().filter(|&&l| l).count()).max(1)
    }

    /// Gather the chunks of the update after `version`, ordered by (actor, sequence) so
    /// that the update does not depend on arrival order; `None` when asked to stop (a
    /// checkpoint of the last finished update written).
    fn gather(&mut self, version: u64) -> Result<Option<Vec<Chunk>>, LearnerError> {
        let mut batch: Vec<Chunk> = Vec::with_capacity(self.target());
        // Chunks received earlier that are still usable.
        for c in std::mem::take(&mut self.pending) {
            let k = self.target();
            self.admit(c, version, k, &mut batch);
        }
        let stall = Duration::from_secs_f64(self.cfg.stall_timeout_s);
        let local_deadline = self.local.deadline(stall);
        let began = Instant::now();
        let mut idle = Instant::now();
        let mut gather = Instant::now();
        while batch.len() < self.target() {
            if self.stop.load(Ordering::Relaxed) {
                self.ctr.wall_s = self.wall0 + self.started.elapsed().as_secs_f64();
                self.checkpoint()?;
                return Ok(None);
            }
            let got = self.receive(version, &mut batch)?;
            if self.cfg.remote && !got && gather.elapsed() > stall {
                self.go_on_without_stalled(&batch);
                gather = Instant::now();
            }
            if self.cfg.max_policy_lag == 0
                && !got
                && !batch.is_empty()
                && began.elapsed() > local_deadline
            {
                self.go_on_without_local(&batch, began);
            }
            if !got && batch.len() < self.target() {
                let _ = self
                    .ports
                    .listener
                    .timed_wait(|_| {}, Duration::from_millis(50));
                if idle.elapsed() > Duration::from_secs(1) {
                    // Weights may have been missed by a (re)started actor: repeat them.
                    idle = Instant::now();
                    self.publish(version)?;
                    let actors = self.missing(&batch);
                    (self.notice)(&Notice::Waiting {
                        waited_s: began.elapsed().as_secs_f64(),
                        actors,
                    });
                }
            }
        }
        self.local.gathered(began.elapsed());
        batch.sort_by_key(|c| (c.h.actor, c.h.incarnation, c.h.seq));
        Ok(Some(batch))
    }

    /// Take what has arrived: invalid chunks (another run or world, or refused by
    /// `take_chunk`) are dropped and counted, the others admitted, until the
    /// batch is full. Returns whether anything arrived.
    fn receive(&mut self, version: u64, batch: &mut Vec<Chunk>) -> Result<bool, LearnerError> {
        let mut got = false;
        while let Some(sample) = self
            .ports
            .sub
            .receive()
            .map_err(|e| IpcError::new("receive", e))?
        {
            got = true;
            let h = *sample.user_header();
            if h.run != self.run || h.world_hash != self.world_hash {
                self.ctr.dropped += 1;
                tracing::warn!(actor = h.actor, "dropped a chunk of another run or world");
                continue;
            }
            // Copied out of shared memory first, then checked: the copy is what is used.
            let family = self.family.as_mut().zip(self.cfg.layouts);
            let c = match take_chunk(
                self.world,
                family,
                &self.layout,
                self.cfg.action_mask,
                h,
                sample.payload(),
            ) {
                Ok(c) => c,
                Err(why) => {
                    self.ctr.dropped += 1;
                    tracing::warn!(actor = h.actor, seq = h.seq, %why, "dropped a bad chunk");
                    self.refused(&h, version);
                    continue;
                }
            };
            drop(sample);
            self.arrived(&h);
            let k = self.target();
            self.admit(c, version, k, batch);
            // Synchronous actors send one chunk per version: read all that came (at
            // most one per actor), so that a queue served after another's is never
            // left to go stale; asynchronous ones are held back by the queue instead.
            if batch.len() >= k && self.cfg.max_policy_lag > 0 {
                break;
            }
        }
        Ok(got)
    }

    /// Note a valid chunk's sender: its restarts, the chunks lost before it (a gap in
    /// its sequence), a remote actor joining.
    fn arrived(&mut self, h: &ChunkHeader) {
        let r = self.restarts.entry(h.actor).or_default();
        *r = (*r).max(h.incarnation);
        if let Some(&(inc, s)) = self.last_seq.get(&h.actor) {
            if inc == h.incarnation && h.seq > s + 1 {
                let gap = h.seq - s - 1;
                self.ctr.lost += gap;
                if let Some(log) = self.hosts.as_mut() {
                    *log.lost.entry(traj::host_of(h.actor)).or_default() += gap;
                }
                tracing::warn!(
                    actor = h.actor,
                    lost = gap,
                    "chunks of an actor never arrived"
                );
            }
        }
        self.last_seq.insert(h.actor, (h.incarnation, h.seq));
        if self.local.back(h.actor) {
            tracing::info!(actor = h.actor, "a stalled local actor is back");
        }
        if self.cfg.remote
            && traj::host_of(h.actor) > 0
            && self.roster.insert(h.actor, true) != Some(true)
        {
            tracing::info!(
                actor = h.actor,
                host = traj::host_of(h.actor),
                "a remote actor joined"
            );
        }
    }

    /// Put a received chunk where it belongs: into this update's batch, back into
    /// `pending` (made by a newer policy than the learner's: cannot happen in order, kept
    /// for safety), or dropped as stale. Synchronous mode takes one chunk per actor made
    /// by the current policy version; with `max_policy_lag = L` any chunk with
    /// `version - L <= its version <= version` counts.
    fn admit(&mut self, c: Chunk, version: u64, target: usize, batch: &mut Vec<Chunk>) {
        let v = c.h.policy_version;
        if v > version {
            self.pending.push(c);
            return;
        }
        let lag = version - v;
        let fresh = if self.cfg.max_policy_lag == 0 {
            lag == 0 && !batch.iter().any(|b| b.h.actor == c.h.actor)
        } else {
            lag <= self.cfg.max_policy_lag
        };
        if fresh && batch.len() < target {
            batch.push(c);
        } else if fresh {
            self.pending.push(c);
        } else {
            self.ctr.dropped += 1;
            tracing::debug!(actor = c.h.actor, v, version, "dropped a stale chunk");
        }
    }

    /// Go on without the remote actors that have not delivered within the stall
    /// timeout; each is awaited again from its next chunk.
    fn go_on_without_stalled(&mut self, batch: &[Chunk]) {
        for (a, live) in self.roster.iter_mut() {
            if *live && !batch.iter().any(|c| c.h.actor == *a) {
                *live = false;
                tracing::warn!(
                    actor = *a,
                    host = traj::host_of(*a),
                    "no chunk from a remote actor within the stall timeout: going on without it"
                );
            }
        }
    }

    /// The actors whose chunks this update still waits for.
    fn missing(&self, batch: &[Chunk]) -> Vec<u32> {
        let local = (0..self.cfg.actors as u32).filter(|a| !self.local.stalled.contains(a));
        let remote = self.roster.iter().filter(|(_, &l)| l).map(|(&a, _)| a);
        local
            .chain(remote)
            .filter(|a| !batch.iter().any(|c| c.h.actor == *a))
            .collect()
    }

    /// Synchronous mode: go on without the local actors that have not delivered within
    /// the local deadline ([`crate::watch`]); each is awaited again from its next chunk.
    fn go_on_without_local(&mut self, batch: &[Chunk], began: Instant) {
        for a in 0..self.cfg.actors as u32 {
            if !self.local.stalled.contains(&a) && !batch.iter().any(|c| c.h.actor == a) {
                self.local.stalled.insert(a);
                tracing::info!(
                    actor = a,
                    "no chunk from a local actor: going on without it"
                );
                (self.notice)(&Notice::Stalled {
                    actor: a,
                    waited_s: began.elapsed().as_secs_f64(),
                    refused: false,
                });
            }
        }
    }

    /// A local actor's chunk for `version` was refused: in synchronous mode it waits for
    /// the next weights and sends no other chunk for this version, so this update does
    /// not wait for it.
    fn refused(&mut self, h: &ChunkHeader, version: u64) {
        // Its sequence number is taken: the next chunk is no gap (nothing was lost).
        self.last_seq.insert(h.actor, (h.incarnation, h.seq));
        let local = traj::host_of(h.actor) == 0 && (h.actor as usize) < self.cfg.actors;
        if self.cfg.max_policy_lag == 0
            && local
            && h.policy_version == version
            && self.local.stalled.insert(h.actor)
        {
            (self.notice)(&Notice::Stalled {
                actor: h.actor,
                waited_s: 0.0,
                refused: true,
            });
        }
    }

    /// PPO on the batch, at the learning rate of this update (annealed linearly to 0
    /// over the run's updates, or over its env steps with remote actors); the KL
    /// coefficient adapts, the counters advance.
    fn update(&mut self, batch: &Batch) -> Result<Stats, LearnerError> {
        let ppo = self.cfg.ppo;
        let lr = if self.cfg.remote && ppo.lr_anneal {
            ppo.lr * (1.0 - (self.ctr.env_steps as f64 / self.cfg.total_steps as f64).min(1.0))
        } else {
            ppo.lr_at(self.ctr.update, self.updates)
        };
        let stats = update(
            &self.net,
            &mut self.adam,
            &PpoConfig {
                kl_coef: self.ctr.kl_coef,
                ..ppo
            },
            lr,
            &mut self.rng,
            &batch.update_data(),
        )?;
        self.ctr.kl_coef = ppo.adapt_kl(self.ctr.kl_coef, stats.approx_kl);
        self.ctr.update += 1;
        self.ctr.env_steps += batch.len as u64;
        self.ctr.episodes += batch.sums.episodes;
        Ok(stats)
    }

    /// The periodic evaluation of the weights just made, appended to `eval.csv` and
    /// TensorBoard (before the update's checkpoint, so that a resume from an earlier one
    /// drops the row and makes it again).
    fn periodic_eval(&mut self, wall_s: f64) -> Result<(), LearnerError> {
        let Some(evaluate) = self.evaluate.as_mut() else {
            return Ok(());
        };
        let flat = self.net.flat()?;
        let mut row = evaluate(&flat)
            .map_err(|e| LearnerError::Run(format!("the periodic evaluation failed: {e}")))?;
        row.update = self.ctr.update;
        row.env_steps = self.ctr.env_steps;
        let path = self.paths.eval();
        crate::evalcsv::append(&path, &row)
            .map_err(|e| LearnerError::Run(format!("cannot write {}: {e}", path.display())))?;
        if let Some(tb) = self.tb.as_mut() {
            if let Err(e) = tb.append_eval(&row, wall_s) {
                tracing::warn!(
                    "TensorBoard events stop here ({}: {e}); eval.csv goes on, and --resume writes them again",
                    tb.path().display()
                );
                self.tb = None;
            }
        }
        Ok(())
    }

    /// Publish the weights as `version`.
    fn publish(&self, version: u64) -> Result<(), LearnerError> {
        self.ports
            .publish(&self.net, self.run, self.world_hash, version)
    }

    /// The update's metrics row, appended to `metrics.csv` (and `hosts.csv`).
    fn record(
        &mut self,
        stats: Stats,
        batch: &Batch,
        chunks: &[Chunk],
    ) -> Result<MetricsRow, LearnerError> {
        let s = batch.sums;
        let total = batch.len;
        let per_ep = |x: f64| {
            if s.episodes > 0 {
                x / s.episodes as f64
            } else {
                f64::NAN
            }
        };
        let now = Instant::now();
        if self.ctr.first_pickup == 0 && s.pickups > 0 {
            self.ctr.first_pickup = self.ctr.env_steps;
        }
        let mut row = MetricsRow {
            update: self.ctr.update,
            env_steps: self.ctr.env_steps,
            episodes: s.episodes,
            extrinsic_return: per_ep(s.ext_return),
            success_rate: per_ep(s.successes as f64),
            intrinsic_return: per_ep(s.int_return),
            intrinsic_mean: s.int_reward / total as f64,
            episode_length: per_ep(s.length),
            pickup_rate: per_ep(s.pickups as f64),
            stats,
            sps: total as f64 / now.duration_since(self.last).as_secs_f64().max(1e-9),
            policy_lag: s.lag / chunks.len() as f64,
            dropped_chunks: self.ctr.dropped,
            actor_restarts: self.restarts.values().map(|&r| r as u64).sum(),
            wall_s: self.wall0 + self.started.elapsed().as_secs_f64(),
            e_positive_frac: if self.cfg.form().uses_empowerment() {
                s.e_positive as f64 / total as f64
            } else {
                f64::NAN
            },
            first_pickup_step: (self.ctr.first_pickup > 0).then_some(self.ctr.first_pickup),
            lost_chunks: self.ctr.lost,
            remote_actors: chunks
                .iter()
                .filter(|c| traj::host_of(c.h.actor) > 0)
                .count() as u64,
            trap: false,
        };
        if let Some(signs) = self.trap.observe(&row) {
            row.trap = true;
            if !self.trap_told {
                self.trap_told = true;
                (self.notice)(&Notice::Trap(signs));
            }
        }
        self.last = now;
        append_row(&mut self.metrics, &self.paths.metrics(), &row)?;
        if let Some(tb) = self.tb.as_mut() {
            if let Err(e) = tb.append(&row) {
                tracing::warn!(
                    "TensorBoard events stop here ({}: {e}); metrics.csv goes on, and --resume writes them again",
                    tb.path().display()
                );
                self.tb = None;
            }
        }
        if let Some(log) = self.hosts.as_mut() {
            let per_chunk = (self.layout.envs * self.layout.steps) as u64;
            log.append(self.paths, self.ctr.update, chunks, per_chunk, &self.roster)?;
        }
        Ok(row)
    }

    /// The updates the run will have: with remote actors, those so far plus those the
    /// remaining steps need at this batch size of `total` steps.
    fn planned(&self, total: usize) -> u64 {
        if self.cfg.remote {
            self.ctr.update
                + self
                    .cfg
                    .total_steps
                    .saturating_sub(self.ctr.env_steps)
                    .div_ceil(total as u64)
        } else {
            self.updates
        }
    }

    /// Write the checkpoint: weights, Adam's moments and step, the minibatch generator,
    /// the counters, and each actor's worlds, so that a resumed run continues exactly
    /// where it was taken.
    fn checkpoint(&self) -> Result<(), LearnerError> {
        let mut extra = Extra::default();
        self.ctr.store(&mut extra);
        for (key, mark) in self.cfg.checkpoint_marks() {
            extra.meta.insert(key.into(), mark);
        }
        extra
            .blobs
            .insert("learner_rng".into(), checkpoint::rng_state(&self.rng));
        for (k, v) in &self.env_blobs {
            extra.blobs.insert(k.clone(), v.clone());
        }
        sync_rows(&self.metrics, &self.paths.metrics())?;
        let path = self.paths.checkpoint();
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir)
                .map_err(|e| LearnerError::Run(format!("cannot create {}: {e}", dir.display())))?;
        }
        checkpoint::save(&path, &self.net, &self.adam, &extra)?;
        Ok(())
    }
}

/// The run's TensorBoard events, rewritten from the rows `metrics.csv` holds; None (with
/// a warning) when they cannot be written: they are a view, not the record.
fn open_events(
    paths: &RunPaths,
    evals: &[EvalRow],
    wall_s: f64,
) -> Option<crate::tensorboard::EventWriter> {
    let config = std::fs::read_to_string(paths.config()).unwrap_or_default();
    let rows = crate::metrics::read_metrics(&paths.metrics()).unwrap_or_default();
    match crate::tensorboard::EventWriter::create(&paths.tb(), &config, &rows, evals, wall_s) {
        Ok(w) => Some(w),
        Err(e) => {
            tracing::warn!(
                "no TensorBoard events for this run ({}: {e}); metrics.csv is written as usual",
                paths.tb().display()
            );
            None
        }
    }
}
