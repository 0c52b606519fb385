//! The actor process of `fulcrum train`.
//!
//! An actor steps M worlds in lock-step (auto-reset), chooses actions with its own copy
//! of the policy, and writes chunks of T steps straight into a loaned shared-memory
//! sample (layout: `fulcrum_contracts::traj`). Per chunk:
//!
//! 1. take the newest weights (synchronous mode: wait until the learner has published
//!    the version after the one of the last chunk);
//! 2. for t in 0..T: copy each world's observation o_t into the sample, run the policy on
//!    the M observations (one batch), sample a_t from our seeded generator, step the
//!    worlds, record r_t, terminated/truncated, and s_{t+1}; the next-state values of
//!    truncated episodes are computed in one batch at the end of the chunk;
//! 3. E(s_{t+1}) comes from the empowerment service: the states are sent in batches of
//!    up to [`fulcrum_contracts::msg::MAX_BATCH`] as soon as they are collected, so the
//!    service answers while the actor steps on (pipelined), and the answers are
//!    collected at the chunk's end. If the service fails, the chunk is held (never sent
//!    without its intrinsic rewards) and the actor reconnects and asks again;
//! 4. send the chunk (blocking while the learner's queue is full: backpressure) and
//!    notify the learner.
//!
//! Sampling is seeded per chunk from (run seed, actor, policy version, chunk), so a run
//! resumed from a checkpoint draws the same actions as one that was never stopped. In a
//! stochastic world the same generator draws each step's outcome
//! ([`fulcrum_world::World::env_step_drawn`]; none in a deterministic world), so the
//! resumed run also meets the same slips and failed tool uses.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use fulcrum_contracts::config::RunConfig;
use fulcrum_contracts::intrinsic::{Intrinsic, Shaping};
use fulcrum_contracts::msg::{MAX_BATCH, MAX_IN_FLIGHT};
use fulcrum_contracts::traj::{
    self, put_f32, ChunkHeader, ChunkLayout, EnvRecord, Section, ENV_BYTES,
};
use fulcrum_empowerment::service::{Ask, Client};
use fulcrum_world::{State, World};
use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::error::ActorError;
use crate::policy::Policy;
use crate::ports::Ports;
use crate::resume::{reset_unknown_states, resume_records};
use crate::seeds::chunk_seed;
use crate::service::{connect, look_up_resets, pump, service_trouble, Asked};
use crate::weights::WeightsIn;
use crate::worlds::EnvWorlds;
use fulcrum_contracts::IpcError;

/// Who this actor is.
#[derive(Debug, Clone, Copy)]
pub struct ActorId {
    /// Index (0..K).
    pub index: u32,
    /// Restarts before this process.
    pub incarnation: u32,
}

/// Run an actor until `stop` is set (or the learner goes away). Its chunks carry
/// `run_tag`, or [`traj::run_tag`] of `namespace` (an actor on another host than the
/// learner's works in a namespace of its own and carries the run's tag).
pub fn run_actor(
    world: &World,
    cfg: &RunConfig,
    checkpoint_path: &Path,
    namespace: &str,
    run_tag: Option<u64>,
    id: ActorId,
    stop: &'static AtomicBool,
) -> Result<(), ActorError> {
    match Actor::new(world, cfg, checkpoint_path, namespace, run_tag, id, stop)? {
        Some(actor) => actor.run(),
        None => Ok(()),
    }
}

/// Where a chunk's lookups stand.
#[derive(Debug, Clone, Copy, Default)]
struct Lookups {
    /// States sent to the service.
    sent: usize,
    /// States whose values came back.
    answered: usize,
    /// Whether the service failed during the chunk (the rest is asked again).
    failed: bool,
}

/// An actor: its worlds, its copy of the policy, its ports and its service client, and
/// the buffers a chunk reuses. One method per phase of a chunk: [`Actor::collect`],
/// [`Actor::look_up`], [`Actor::rewards`], then [`Actor::chunk`] sends it, and
/// [`Actor::receive_weights`].
struct Actor<'a> {
    /// The run's world (on a family, the family's [`fulcrum_world::family::Family::run_world`]):
    /// the shape, the actions and the hash every chunk carries.
    world: &'a World,
    /// What each env plays: the one world, or a family's layouts.
    worlds: EnvWorlds,
    /// Each env's current world (on a family, its episode's layout).
    env_world: Vec<Arc<World>>,
    cfg: &'a RunConfig,
    namespace: &'a str,
    id: ActorId,
    stop: &'static AtomicBool,
    client: Option<Client>,
    weights: WeightsIn,
    ports: Ports,
    policy: Policy,
    layout: ChunkLayout,
    run: u64,
    world_hash: u64,
    form: Intrinsic,
    ask: Ask,
    /// The policy version of the weights in use.
    version: u64,
    /// Chunks sent, and chunks sent with this version.
    seq: u64,
    per_version: u64,
    envs: Vec<EnvRecord>,
    /// Potential shaping: E(s_t) of each world's current state, and of the initial state.
    phi: Vec<f32>,
    phi_reset: f32,
    /// Each world's current observation.
    cur_g: Vec<u8>,
    cur_f: Vec<u8>,
    /// First-visit: each world's current inventory and whether it has been paid.
    inv: Vec<u16>,
    paid: Vec<bool>,
    next_inv: Vec<u16>,
    /// The chunk's states reached (on a family, with their layouts), their values from
    /// the service and the rewards.
    next_states: Vec<State>,
    next_layouts: Vec<u64>,
    /// Potential forms on a family: the initial states of the episodes begun in the chunk
    /// (transition, state, layout), their potentials, and the potential each transition's
    /// world resets to (where it ends an episode).
    resets: Vec<(usize, State, u64)>,
    reset_vals: Vec<f32>,
    reset_phi: Vec<f32>,
    intrinsic: Vec<f32>,
    bonus: Vec<f32>,
    lookups: Lookups,
    /// States per lookup request.
    sub_batch: usize,
    /// Truncated episodes' final observations: (transition, glyphs, flags).
    finals: Vec<(usize, Vec<u8>, Vec<u8>)>,
    acts: Vec<u8>,
    lps: Vec<f32>,
    vals: Vec<f32>,
    /// Values after the chunk.
    last: Vec<f32>,
    /// Intrinsic values (empty without the intrinsic value head: nothing is computed).
    vals_int: Vec<f32>,
    last_int: Vec<f32>,
}

impl<'a> Actor<'a> {
    /// An actor with its ports open, its service client connected, the learner's first
    /// weights taken and its worlds ready (from the checkpoint when it was taken at those
    /// weights); `None` when stopped before that.
    fn new(
        world: &'a World,
        cfg: &'a RunConfig,
        checkpoint_path: &Path,
        namespace: &'a str,
        run_tag: Option<u64>,
        id: ActorId,
        stop: &'static AtomicBool,
    ) -> Result<Option<Actor<'a>>, ActorError> {
        let shape = cfg.shape(world);
        let mut policy = Policy::new(shape).with_action_mask(cfg.action_mask);
        let (m, t_len) = (cfg.envs_per_actor, cfg.steps_per_chunk);
        let layout = ChunkLayout {
            envs: m,
            steps: t_len,
            cells: shape.cells,
            flags: shape.flags,
        };
        let (c, f) = (shape.cells, shape.flags);
        let n = layout.n();
        let run = run_tag.unwrap_or_else(|| traj::run_tag(namespace));
        let world_hash = world.content_hash();

        // An actor on another host (a run tag given) shares its host's weights service
        // with the bridge, which makes it for the most actors a host may have.
        let subscribers = if run_tag.is_some() {
            traj::WEIGHTS_SUBSCRIBERS
        } else {
            cfg.weights_subscribers()
        };
        let (ports, sub, listener) = Ports::open(namespace, layout.bytes(), subscribers, stop)?;

        let form = cfg.form();
        let ask = if form == Intrinsic::Count {
            Ask::Visit
        } else {
            Ask::Lookup
        };
        let mut client = if cfg.empowerment {
            match connect(namespace, world, stop)? {
                Some(c) => Some(c),
                None => return Ok(None),
            }
        } else {
            None
        };

        let weights = WeightsIn {
            sub,
            listener,
            run,
            world_hash,
            stop,
        };
        let Some(v0) = weights.take(&mut policy, None, true)? else {
            return Ok(None);
        };

        // Worlds: from the checkpoint when it was taken at this policy version.
        let mut worlds = EnvWorlds::new(world, cfg)?;
        let (mut env_world, mut envs): (Vec<Arc<World>>, Vec<EnvRecord>) =
            worlds.first(cfg.seed, id.index, m)?.into_iter().unzip();
        if let Some(mut recs) =
            resume_records(checkpoint_path, shape, id.index, v0, m, &mut worlds)?
        {
            if let Some(cl) = client.as_mut() {
                reset_unknown_states(cl, id.index, &mut worlds, &mut recs)?;
            }
            (env_world, envs) = recs.into_iter().unzip();
            tracing::info!(
                actor = id.index,
                version = v0,
                "worlds resumed from checkpoint"
            );
        }
        // Intrinsic values (empty without the intrinsic value head: nothing is computed).
        let int_len = if cfg.intrinsic_value_head { m } else { 0 };
        let mut actor = Actor {
            world,
            worlds,
            env_world,
            cfg,
            namespace,
            id,
            stop,
            client,
            weights,
            ports,
            policy,
            layout,
            run,
            world_hash,
            form,
            ask,
            version: v0,
            seq: 0,
            per_version: 0,
            inv: envs.iter().map(|r| r.episode.state.inventory).collect(),
            paid: envs.iter().map(|r| r.paid).collect(),
            envs,
            phi: vec![0.0f32; m],
            phi_reset: 0.0,
            cur_g: vec![0u8; m * c],
            cur_f: vec![0u8; m * f],
            next_inv: Vec::with_capacity(n),
            next_states: Vec::with_capacity(n),
            next_layouts: Vec::with_capacity(n),
            resets: Vec::new(),
            reset_vals: Vec::new(),
            reset_phi: vec![0.0f32; n],
            intrinsic: vec![0.0f32; n],
            bonus: vec![0.0f32; n],
            lookups: Lookups::default(),
            sub_batch: MAX_BATCH.min(n.div_ceil(MAX_IN_FLIGHT).max(m)),
            finals: Vec::new(),
            acts: vec![0u8; m],
            lps: vec![0.0f32; m],
            vals: vec![0.0f32; m],
            last: vec![0.0f32; m],
            vals_int: vec![0.0f32; int_len],
            last_int: vec![0.0f32; int_len],
        };
        if form.is_potential() && !actor.initial_potentials()? {
            return Ok(None);
        }
        for (e, r) in actor.envs.iter().enumerate() {
            cfg.view.observe(
                &actor.env_world[e],
                &r.episode.state,
                &mut actor.cur_g[e * c..(e + 1) * c],
                &mut actor.cur_f[e * f..(e + 1) * f],
            );
        }
        Ok(Some(actor))
    }

    /// Potential shaping needs E(s_t) of each world's current state and of the initial
    /// state (where worlds reset); both come from the service, so a resumed actor gets
    /// the same values as the one that stopped. False when stopped while reconnecting.
    fn initial_potentials(&mut self) -> Result<bool, ActorError> {
        let m = self.envs.len();
        let mut ask_states: Vec<State> = self.envs.iter().map(|r| r.episode.state).collect();
        let mut ask_layouts: Vec<u64> = self.envs.iter().map(|r| r.layout).collect();
        ask_states.push(self.world.reset().state);
        ask_layouts.push(0);
        let layouts = self.worlds.is_family().then_some(ask_layouts.as_slice());
        let mut vals = vec![0.0f32; ask_states.len()];
        while let Some(cl) = self.client.as_mut() {
            let (mut sent, mut got) = (0, 0);
            let mut result = Ok(());
            while got < ask_states.len() && result.is_ok() {
                result = pump(
                    cl,
                    self.ask,
                    Asked {
                        states: &ask_states,
                        layouts,
                    },
                    &mut sent,
                    &mut got,
                    &mut vals,
                    MAX_BATCH,
                    true,
                );
            }
            match result {
                Ok(()) => break,
                Err(e) => {
                    service_trouble(self.stop, self.id.index, &e);
                    match connect(self.namespace, self.world, self.stop)? {
                        Some(new) => *cl = new,
                        None => return Ok(false),
                    }
                }
            }
        }
        self.phi.copy_from_slice(&vals[..m]);
        self.phi_reset = vals[m];
        Ok(true)
    }

    /// Chunk after chunk until stopped (or the learner goes away).
    fn run(mut self) -> Result<(), ActorError> {
        while !self.stop.load(Ordering::Relaxed) {
            if !self.chunk()? {
                return Ok(());
            }
        }
        Ok(())
    }

    /// One chunk, written straight into a loaned sample: collect it, finish its lookups,
    /// add its rewards, send it, take the next weights. False when stopping.
    fn chunk(&mut self) -> Result<bool, ActorError> {
        let (m, t_len) = (self.layout.envs, self.layout.steps);
        let v = self.version;
        let mut rng = ChaCha8Rng::seed_from_u64(chunk_seed(
            self.cfg.seed,
            self.id.index,
            v,
            self.per_version,
        ));
        let mut sample = self
            .ports
            .publisher
            .loan_slice(self.layout.bytes())
            .map_err(|e| IpcError::new("loan chunk", e))?;
        let mut h = ChunkHeader {
            run: self.run,
            world_hash: self.world_hash,
            seq: self.seq,
            policy_version: v,
            actor: self.id.index,
            incarnation: self.id.incarnation,
            envs: m as u32,
            steps: t_len as u32,
            cells: self.layout.cells as u32,
            flags: self.layout.flags as u32,
            actions: self.world.num_actions() as u32,
            len: self.layout.bytes() as u64,
            ..ChunkHeader::default()
        };
        self.next_states.clear();
        self.next_layouts.clear();
        self.resets.clear();
        self.finals.clear();
        let carry: Vec<f32> = self.envs.iter().map(|r| r.int_return).collect();
        self.lookups = Lookups::default();
        self.collect(sample.payload_mut(), &mut h, &mut rng)?;
        if !self.look_up()? {
            return Ok(false);
        }
        self.rewards(sample.payload_mut(), &mut h, carry);
        crate::fault::corrupt(
            self.id.index,
            self.id.incarnation,
            self.seq,
            &self.layout,
            sample.payload_mut(),
        );
        *sample.user_header_mut() = h;
        match sample.send() {
            Ok(_) => {}
            Err(e) if self.stop.load(Ordering::Relaxed) => {
                tracing::debug!(?e, "chunk not sent: stopping");
                return Ok(false);
            }
            Err(e) => return Err(IpcError::new("send chunk", e).into()),
        }
        let _ = self.ports.notifier.notify();
        self.seq += 1;
        self.per_version += 1;
        self.receive_weights()
    }

    /// Step the worlds T times into the chunk; the states reached go to the service as
    /// they are collected (pipelined: it answers while the actor steps on); then the
    /// values after the chunk, and of truncated episodes' final observations (in one
    /// batch).
    fn collect(
        &mut self,
        buf: &mut [u8],
        h: &mut ChunkHeader,
        rng: &mut ChaCha8Rng,
    ) -> Result<(), ActorError> {
        let t_len = self.layout.steps;
        let family = self.worlds.is_family();
        for t in 0..t_len {
            self.step(buf, t, h, rng)?;
            // Pipelined lookups: send what is collected, collect what has come back.
            if let Some(cl) = self.client.as_mut().filter(|_| !self.lookups.failed) {
                let ready = self.next_states.len() - self.lookups.sent;
                if ready >= self.sub_batch || (t + 1 == t_len && ready > 0) {
                    if let Err(e) = pump(
                        cl,
                        self.ask,
                        Asked {
                            states: &self.next_states,
                            layouts: family.then_some(self.next_layouts.as_slice()),
                        },
                        &mut self.lookups.sent,
                        &mut self.lookups.answered,
                        &mut self.intrinsic,
                        self.sub_batch,
                        false,
                    ) {
                        service_trouble(self.stop, self.id.index, &e);
                        self.lookups.failed = true;
                    }
                }
            }
        }
        self.final_values(buf);
        Ok(())
    }

    /// Step t of the chunk: each world's observation o_t into the sample, the policy on
    /// the M observations (one batch), a_t from our seeded generator, the worlds stepped,
    /// r_t, terminated/truncated and s_{t+1} recorded; ended episodes counted into the
    /// header and their worlds reset.
    fn step(
        &mut self,
        buf: &mut [u8],
        t: usize,
        h: &mut ChunkHeader,
        rng: &mut ChaCha8Rng,
    ) -> Result<(), ActorError> {
        let layout = self.layout;
        let (m, c, f) = (layout.envs, layout.cells, layout.flags);
        let base = t * m;
        let gr = layout.range(Section::Glyphs);
        let fr = layout.range(Section::Flags);
        let g_slot = gr.start + base * c..gr.start + (base + m) * c;
        let f_slot = fr.start + base * f..fr.start + (base + m) * f;
        buf[g_slot.clone()].copy_from_slice(&self.cur_g);
        buf[f_slot.clone()].copy_from_slice(&self.cur_f);
        self.policy.act_all(
            &buf[g_slot],
            &buf[f_slot],
            rng,
            &mut self.acts,
            &mut self.lps,
            &mut self.vals,
            &mut self.vals_int,
        );
        for (e, v) in self.vals_int.iter().enumerate() {
            put_f32(&mut buf[layout.range(Section::ValueInt)], base + e, *v);
        }
        for e in 0..m {
            let i = base + e;
            let rec = &mut self.envs[e];
            let prev = rec.episode.state;
            // A stochastic world's outcome is drawn from the chunk's generator, after the
            // actions: a deterministic world draws nothing, so its stream is unchanged.
            let world = &self.env_world[e];
            let out = world.env_step_drawn(&mut rec.episode, self.acts[e], || rng.next_u64());
            let next = rec.episode.state;
            self.next_states.push(next);
            self.next_layouts.push(rec.layout);
            rec.ext_return += out.reward;
            rec.picked |= next.inventory != 0 && prev.inventory != next.inventory;
            buf[layout.range(Section::Actions).start + i] = self.acts[e];
            buf[layout.range(Section::Terminated).start + i] = out.terminated as u8;
            buf[layout.range(Section::Truncated).start + i] = out.truncated as u8;
            put_f32(&mut buf[layout.range(Section::Logprob)], i, self.lps[e]);
            put_f32(&mut buf[layout.range(Section::Value)], i, self.vals[e]);
            put_f32(&mut buf[layout.range(Section::ExtReward)], i, out.reward);
            let (ge, fe) = (e * c..(e + 1) * c, e * f..(e + 1) * f);
            if out.terminated || out.truncated {
                if out.truncated {
                    let mut gg = vec![0u8; c];
                    let mut ff = vec![0u8; f];
                    self.cfg.view.observe(world, &next, &mut gg, &mut ff);
                    self.finals.push((i, gg, ff));
                }
                h.episodes += 1;
                h.successes += out.terminated as u32;
                h.pickups += rec.picked as u32;
                h.ext_return_sum += rec.ext_return as f64;
                h.length_sum += rec.episode.t as f64;
                let (new_world, new_rec) = self.worlds.fresh(|| rng.next_u64())?;
                *rec = new_rec;
                if self.worlds.is_family() && self.form.is_potential() {
                    self.resets.push((i, rec.episode.state, rec.layout));
                }
                self.cfg.view.observe(
                    &new_world,
                    &rec.episode.state,
                    &mut self.cur_g[ge],
                    &mut self.cur_f[fe],
                );
                self.env_world[e] = new_world;
            } else {
                self.cfg.view.update(
                    world,
                    &prev,
                    &next,
                    &mut self.cur_g[ge],
                    &mut self.cur_f[fe],
                );
            }
        }
        Ok(())
    }

    /// Values after the chunk, and of truncated episodes' final observations.
    fn final_values(&mut self, buf: &mut [u8]) {
        let layout = self.layout;
        self.policy
            .values_all(&self.cur_g, &self.cur_f, &mut self.last, &mut self.last_int);
        for (e, v) in self.last.iter().enumerate() {
            put_f32(&mut buf[layout.range(Section::LastValue)], e, *v);
        }
        for (e, v) in self.last_int.iter().enumerate() {
            put_f32(&mut buf[layout.range(Section::LastValueInt)], e, *v);
        }
        if !self.finals.is_empty() {
            let finals = &self.finals;
            let fg: Vec<u8> = finals.iter().flat_map(|x| x.1.iter().copied()).collect();
            let ff: Vec<u8> = finals.iter().flat_map(|x| x.2.iter().copied()).collect();
            let mut fv = vec![0.0f32; finals.len()];
            let int_heads = !self.vals_int.is_empty();
            let mut fvi = vec![0.0f32; if int_heads { finals.len() } else { 0 }];
            self.policy.values_all(&fg, &ff, &mut fv, &mut fvi);
            for ((i, _, _), v) in finals.iter().zip(fv) {
                put_f32(&mut buf[layout.range(Section::TruncValue)], *i, v);
            }
            for ((i, _, _), v) in finals.iter().zip(fvi) {
                put_f32(&mut buf[layout.range(Section::TruncValueInt)], *i, v);
            }
        }
    }

    /// Finish the chunk's lookups. If the service fails, the chunk is held (never sent
    /// without its intrinsic rewards): reconnect and ask for the whole chunk again.
    /// False when stopped while reconnecting.
    fn look_up(&mut self) -> Result<bool, ActorError> {
        let n = self.layout.n();
        let Some(cl) = self.client.as_mut() else {
            return Ok(true);
        };
        let mut failed = self.lookups.failed;
        let family = self.worlds.is_family();
        loop {
            if !failed {
                while self.lookups.answered < n {
                    if let Err(e) = pump(
                        cl,
                        self.ask,
                        Asked {
                            states: &self.next_states,
                            layouts: family.then_some(self.next_layouts.as_slice()),
                        },
                        &mut self.lookups.sent,
                        &mut self.lookups.answered,
                        &mut self.intrinsic,
                        self.sub_batch,
                        true,
                    ) {
                        service_trouble(self.stop, self.id.index, &e);
                        failed = true;
                        break;
                    }
                }
                if !failed {
                    match look_up_resets(cl, self.ask, &self.resets, &mut self.reset_vals) {
                        Ok(()) => break,
                        Err(e) => service_trouble(self.stop, self.id.index, &e),
                    }
                }
            }
            // Reconnect and ask for the whole chunk again.
            match connect(self.namespace, self.world, self.stop)? {
                Some(new) => *cl = new,
                None => return Ok(false),
            }
            self.lookups.sent = 0;
            self.lookups.answered = 0;
            failed = false;
        }
        Ok(true)
    }

    /// Intrinsic rewards into the chunk (the form's b_t from the service's values);
    /// intrinsic returns of the episodes that ended (they may have begun in earlier
    /// chunks: `carry`); each world's record after the chunk.
    fn rewards(&mut self, buf: &mut [u8], h: &mut ChunkHeader, carry: Vec<f32>) {
        let layout = self.layout;
        let (m, t_len, n) = (layout.envs, layout.steps, layout.n());
        let term = layout.range(Section::Terminated).start;
        let trunc = layout.range(Section::Truncated).start;
        let ir = layout.range(Section::IntReward);
        if self.form.uses_empowerment() {
            h.e_positive = self.intrinsic.iter().filter(|&&v| v > 0.0).count() as u32;
        }
        let shaping = Shaping {
            form: self.form,
            gamma: self.cfg.ppo.gamma,
            phi_reset: self.phi_reset,
            inventory_reset: self.world.initial.inventory,
        };
        self.next_inv.clear();
        self.next_inv
            .extend(self.next_states.iter().map(|s| s.inventory));
        if self.worlds.is_family() {
            // Each world resets to its next layout's initial state.
            for (&(i, _, _), &v) in self.resets.iter().zip(&self.reset_vals) {
                self.reset_phi[i] = v;
            }
            shaping.chunk_reset(
                &self.intrinsic,
                &self.next_inv,
                &buf[term..term + n],
                &buf[trunc..trunc + n],
                &self.reset_phi,
                &mut self.phi,
                &mut self.inv,
                &mut self.paid,
                &mut self.bonus,
            );
        } else {
            shaping.chunk(
                &self.intrinsic,
                &self.next_inv,
                &buf[term..term + n],
                &buf[trunc..trunc + n],
                &mut self.phi,
                &mut self.inv,
                &mut self.paid,
                &mut self.bonus,
            );
        }
        let mut acc = carry;
        for t in 0..t_len {
            for (e, a) in acc.iter_mut().enumerate() {
                let i = t * m + e;
                let val = self.bonus[i];
                put_f32(&mut buf[ir.clone()], i, val);
                h.int_reward_sum += val as f64;
                *a += val;
                if buf[term + i] == 1 || buf[trunc + i] == 1 {
                    h.int_return_sum += *a as f64;
                    *a = 0.0;
                }
            }
        }
        let er = layout.range(Section::EnvState).start;
        for (e, r) in self.envs.iter_mut().enumerate() {
            r.int_return = acc[e];
            r.paid = self.paid[e];
            buf[er + e * ENV_BYTES..er + (e + 1) * ENV_BYTES].copy_from_slice(&r.to_bytes());
        }
    }

    /// Weights for the next chunk: synchronous PPO waits for the version after this
    /// chunk's; with a policy lag allowed, the newest there is, if any. False when
    /// stopping.
    fn receive_weights(&mut self) -> Result<bool, ActorError> {
        let blocking = self.cfg.max_policy_lag == 0;
        match self
            .weights
            .take(&mut self.policy, Some(self.version), blocking)?
        {
            Some(v) => {
                self.version = v;
                self.per_version = 0;
            }
            None if blocking => return Ok(false), // stopping
            None => {}
        }
        Ok(true)
    }
}
