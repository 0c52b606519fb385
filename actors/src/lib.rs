//! fulcrum-actors: the actor process of `fulcrum train`.
//!
//! An actor steps M worlds in lock-step (auto-reset), chooses actions with its own copy
//! of the policy, and writes chunks of T steps straight into a loaned shared-memory
//! sample (layout: `fulcrum_shared::traj`). Per chunk:
//!
//! 1. take the newest weights (synchronous mode: wait until the learner has published
//!    the version after the one of the last chunk);
//! 2. for t in 0..T: copy each world's observation o_t into the sample, run the policy on
//!    the M observations (one batch), sample a_t from our seeded generator, step the
//!    worlds, record r_t, terminated/truncated, and s_{t+1}; the next-state values of
//!    truncated episodes are computed in one batch at the end of the chunk;
//! 3. E(s_{t+1}) comes from the empowerment service: the states are sent in batches of
//!    up to [`fulcrum_shared::msg::MAX_BATCH`] as soon as they are collected, so the
//!    service answers while the actor steps on (pipelined), and the answers are
//!    collected at the chunk's end. If the service fails, the chunk is held (never sent
//!    without its intrinsic rewards) and the actor reconnects and asks again;
//! 4. send the chunk (blocking while the learner's queue is full: backpressure) and
//!    notify the learner.
//!
//! Sampling is seeded per chunk from (run seed, actor, policy version, chunk), so a run
//! resumed from a checkpoint draws the same actions as one that was never stopped.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use fulcrum_empowerment::service::{clean_dead_nodes, Ask, Client, ClientError};
use fulcrum_shared::checkpoint;
use fulcrum_shared::config::RunConfig;
use fulcrum_shared::intrinsic::Intrinsic;
use fulcrum_shared::layout::NetShape;
use fulcrum_shared::msg::{item, MAX_BATCH, MAX_IN_FLIGHT};
use fulcrum_shared::traj::{
    self, put_f32, ChunkHeader, ChunkLayout, EnvRecord, Section, TrainNames, ENV_BYTES,
};
use fulcrum_shared::{State, World};
use iceoryx2::port::BackpressureAction;
use iceoryx2::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// The policy evaluated on plain buffers.
pub mod policy;
pub use policy::Policy;

/// Actor failures.
#[derive(Debug, thiserror::Error)]
pub enum ActorError {
    /// iceoryx2 failed.
    #[error("shared memory: {0}")]
    Ipc(String),
    /// The empowerment service failed in a way retrying cannot fix.
    #[error("empowerment service: {0}")]
    Service(String),
}

fn ipc(what: &str) -> impl Fn(&dyn std::fmt::Debug) -> ActorError + '_ {
    move |e| ActorError::Ipc(format!("{what}: {e:?}"))
}

/// Who this actor is.
#[derive(Debug, Clone, Copy)]
pub struct ActorId {
    /// Index (0..K).
    pub index: u32,
    /// Restarts before this process.
    pub incarnation: u32,
}

/// A seed for one chunk's sampling.
pub fn chunk_seed(seed: u64, actor: u32, version: u64, k: u64) -> u64 {
    let mut x = seed ^ 0xa076_1d64_78bd_642f;
    for v in [actor as u64, version, k] {
        x = (x ^ v).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        x ^= x >> 29;
    }
    x
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

    let node = NodeBuilder::new()
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|e| ipc("node")(&e))?;
    let names = TrainNames::new(namespace);
    let tsvc = traj::trajectory_service(&node, &names).map_err(ActorError::Ipc)?;
    let publisher = tsvc
        .publisher_builder()
        .initial_max_slice_len(layout.bytes())
        .max_loaned_samples(2)
        .backpressure_strategy(BackpressureStrategy::RetryUntilDelivered)
        .set_backpressure_handler(move |info: &iceoryx2::port::BackpressureInfo| {
            // The learner's queue is full: wait without burning a core, clean up after
            // a dead learner now and then, and give up when asked to stop.
            if stop.load(Ordering::Relaxed) {
                return BackpressureAction::DiscardDataAndFail;
            }
            if info.retries % 200 == 199 {
                clean_dead_nodes();
            }
            std::thread::sleep(Duration::from_micros(500));
            BackpressureAction::Retry
        })
        .create()
        .map_err(|e| ipc("publisher")(&e))?;
    let twake = traj::wake_service(&node, &names.trajectories_wake).map_err(ActorError::Ipc)?;
    let notifier = twake
        .notifier_builder()
        .create()
        .map_err(|e| ipc("notifier")(&e))?;
    let psvc = traj::policy_service(&node, &names).map_err(ActorError::Ipc)?;
    let weights = psvc
        .subscriber_builder()
        .create()
        .map_err(|e| ipc("subscriber")(&e))?;
    let pwake = traj::wake_service(&node, &names.policy_wake).map_err(ActorError::Ipc)?;
    let listener = pwake
        .listener_builder()
        .create()
        .map_err(|e| ipc("listener")(&e))?;

    let form = cfg.form();
    let ask = if form == Intrinsic::Count {
        Ask::Visit
    } else {
        Ask::Lookup
    };
    let mut client = if cfg.empowerment {
        match connect(namespace, world, stop)? {
            Some(c) => Some(c),
            None => return Ok(()),
        }
    } else {
        None
    };

    let wait = WeightsIn {
        sub: &weights,
        listener: &listener,
        run,
        world_hash,
        stop,
    };
    let Some(v0) = wait.take(&mut policy, None, true)? else {
        return Ok(());
    };
    let mut version = v0;

    // Worlds: from the checkpoint when it was taken at this policy version.
    let mut envs: Vec<EnvRecord> = (0..m).map(|_| EnvRecord::new(world.reset())).collect();
    if let Some(recs) = resume_records(checkpoint_path, shape, id.index, v0, m, world) {
        envs = recs;
        tracing::info!(
            actor = id.index,
            version = v0,
            "worlds resumed from checkpoint"
        );
    }

    // Potential shaping needs E(s_t) of each world's current state and of the initial
    // state (where worlds reset); both come from the service, so a resumed actor gets
    // the same values as the one that stopped.
    let mut phi = vec![0.0f32; m];
    let mut phi_reset = 0.0f32;
    if form.is_potential() {
        let mut ask_states: Vec<State> = envs.iter().map(|r| r.episode.state).collect();
        ask_states.push(world.reset().state);
        let mut vals = vec![0.0f32; ask_states.len()];
        while let Some(cl) = client.as_mut() {
            let (mut sent, mut got) = (0, 0);
            let mut result = Ok(());
            while got < ask_states.len() && result.is_ok() {
                result = pump(
                    cl,
                    ask,
                    &ask_states,
                    &mut sent,
                    &mut got,
                    &mut vals,
                    MAX_BATCH,
                );
            }
            match result {
                Ok(()) => break,
                Err(e) => {
                    tracing::warn!(actor = id.index, "empowerment service: {e}");
                    match connect(namespace, world, stop)? {
                        Some(new) => *cl = new,
                        None => return Ok(()),
                    }
                }
            }
        }
        phi.copy_from_slice(&vals[..m]);
        phi_reset = vals[m];
    }

    let mut cur_g = vec![0u8; m * c];
    let mut cur_f = vec![0u8; m * f];
    for (e, r) in envs.iter().enumerate() {
        world.observe(
            &r.episode.state,
            &mut cur_g[e * c..(e + 1) * c],
            &mut cur_f[e * f..(e + 1) * f],
        );
    }
    // First-visit: each world's current inventory and whether it has been paid.
    let mut inv: Vec<u16> = envs.iter().map(|r| r.episode.state.inventory).collect();
    let mut paid: Vec<bool> = envs.iter().map(|r| r.paid).collect();
    let mut next_inv: Vec<u16> = Vec::with_capacity(n);
    let mut seq = 0u64;
    let mut per_version = 0u64;
    let mut next_states: Vec<State> = Vec::with_capacity(n);
    let mut intrinsic = vec![0.0f32; n];
    let mut bonus = vec![0.0f32; n];
    let mut finals: Vec<(usize, Vec<u8>, Vec<u8>)> = Vec::new();
    let sub_batch = MAX_BATCH.min(n.div_ceil(MAX_IN_FLIGHT).max(m));
    let (mut acts, mut lps, mut vals) = (vec![0u8; m], vec![0.0f32; m], vec![0.0f32; m]);
    let mut last = vec![0.0f32; m];
    // Intrinsic values (empty without the intrinsic value head: nothing is computed).
    let int_len = if cfg.intrinsic_value_head { m } else { 0 };
    let (mut vals_int, mut last_int) = (vec![0.0f32; int_len], vec![0.0f32; int_len]);
    while !stop.load(Ordering::Relaxed) {
        let v = version;
        let mut rng = ChaCha8Rng::seed_from_u64(chunk_seed(cfg.seed, id.index, v, per_version));
        let mut sample_mut = publisher
            .loan_slice(layout.bytes())
            .map_err(|e| ipc("loan chunk")(&e))?;
        let mut h = ChunkHeader {
            run,
            world_hash,
            seq,
            policy_version: v,
            actor: id.index,
            incarnation: id.incarnation,
            envs: m as u32,
            steps: t_len as u32,
            cells: c as u32,
            flags: f as u32,
            actions: world.num_actions() as u32,
            len: layout.bytes() as u64,
            ..ChunkHeader::default()
        };
        next_states.clear();
        finals.clear();
        let carry: Vec<f32> = envs.iter().map(|r| r.int_return).collect();
        let mut sent_states = 0usize;
        let mut answered = 0usize;
        let mut service_failed = false;
        {
            let buf: &mut [u8] = sample_mut.payload_mut();
            for t in 0..t_len {
                let base = t * m;
                let gr = layout.range(Section::Glyphs);
                let fr = layout.range(Section::Flags);
                let g_slot = gr.start + base * c..gr.start + (base + m) * c;
                let f_slot = fr.start + base * f..fr.start + (base + m) * f;
                buf[g_slot.clone()].copy_from_slice(&cur_g);
                buf[f_slot.clone()].copy_from_slice(&cur_f);
                policy.act_all(
                    &buf[g_slot],
                    &buf[f_slot],
                    &mut rng,
                    &mut acts,
                    &mut lps,
                    &mut vals,
                    &mut vals_int,
                );
                for (e, v) in vals_int.iter().enumerate() {
                    put_f32(&mut buf[layout.range(Section::ValueInt)], base + e, *v);
                }
                for e in 0..m {
                    let i = base + e;
                    let rec = &mut envs[e];
                    let prev = rec.episode.state;
                    let out = world.env_step(&mut rec.episode, acts[e]);
                    let next = rec.episode.state;
                    next_states.push(next);
                    rec.ext_return += out.reward;
                    rec.picked |= next.inventory != 0 && prev.inventory != next.inventory;
                    buf[layout.range(Section::Actions).start + i] = acts[e];
                    buf[layout.range(Section::Terminated).start + i] = out.terminated as u8;
                    buf[layout.range(Section::Truncated).start + i] = out.truncated as u8;
                    put_f32(&mut buf[layout.range(Section::Logprob)], i, lps[e]);
                    put_f32(&mut buf[layout.range(Section::Value)], i, vals[e]);
                    put_f32(&mut buf[layout.range(Section::ExtReward)], i, out.reward);
                    let (ge, fe) = (e * c..(e + 1) * c, e * f..(e + 1) * f);
                    if out.terminated || out.truncated {
                        if out.truncated {
                            let mut gg = vec![0u8; c];
                            let mut ff = vec![0u8; f];
                            world.observe(&next, &mut gg, &mut ff);
                            finals.push((i, gg, ff));
                        }
                        h.episodes += 1;
                        h.successes += out.terminated as u32;
                        h.pickups += rec.picked as u32;
                        h.ext_return_sum += rec.ext_return as f64;
                        h.length_sum += rec.episode.t as f64;
                        *rec = EnvRecord::new(world.reset());
                        world.observe(&rec.episode.state, &mut cur_g[ge], &mut cur_f[fe]);
                    } else {
                        world.observe_update(&prev, &next, &mut cur_g[ge], &mut cur_f[fe]);
                    }
                }
                // Pipelined lookups: send what is collected, collect what has come back.
                if let Some(cl) = client.as_mut().filter(|_| !service_failed) {
                    let ready = next_states.len() - sent_states;
                    if ready >= sub_batch || (t + 1 == t_len && ready > 0) {
                        if let Err(e) = pump(
                            cl,
                            ask,
                            &next_states,
                            &mut sent_states,
                            &mut answered,
                            &mut intrinsic,
                            sub_batch,
                        ) {
                            tracing::warn!(actor = id.index, "empowerment service: {e}");
                            service_failed = true;
                        }
                    }
                }
            }
            // Values after the chunk, and of truncated episodes' final observations.
            policy.values_all(&cur_g, &cur_f, &mut last, &mut last_int);
            for (e, v) in last.iter().enumerate() {
                put_f32(&mut buf[layout.range(Section::LastValue)], e, *v);
            }
            for (e, v) in last_int.iter().enumerate() {
                put_f32(&mut buf[layout.range(Section::LastValueInt)], e, *v);
            }
            if !finals.is_empty() {
                let fg: Vec<u8> = finals.iter().flat_map(|x| x.1.iter().copied()).collect();
                let ff: Vec<u8> = finals.iter().flat_map(|x| x.2.iter().copied()).collect();
                let mut fv = vec![0.0f32; finals.len()];
                let mut fvi = vec![0.0f32; if int_len > 0 { finals.len() } else { 0 }];
                policy.values_all(&fg, &ff, &mut fv, &mut fvi);
                for ((i, _, _), v) in finals.iter().zip(fv) {
                    put_f32(&mut buf[layout.range(Section::TruncValue)], *i, v);
                }
                for ((i, _, _), v) in finals.iter().zip(fvi) {
                    put_f32(&mut buf[layout.range(Section::TruncValueInt)], *i, v);
                }
            }
        }
        // Intrinsic rewards: finish the lookups; on failure hold the chunk and retry.
        if let Some(cl) = client.as_mut() {
            let mut failed = service_failed;
            loop {
                if !failed {
                    while answered < n {
                        if let Err(e) = pump(
                            cl,
                            ask,
                            &next_states,
                            &mut sent_states,
                            &mut answered,
                            &mut intrinsic,
                            sub_batch,
                        ) {
                            tracing::warn!(actor = id.index, "empowerment service: {e}");
                            failed = true;
                            break;
                        }
                    }
                    if !failed {
                        break;
                    }
                }
                // Reconnect and ask for the whole chunk again.
                match connect(namespace, world, stop)? {
                    Some(new) => *cl = new,
                    None => return Ok(()),
                }
                sent_states = 0;
                answered = 0;
                failed = false;
            }
        }
        // Intrinsic rewards into the chunk (the form's b_t from the service's values);
        // intrinsic returns of the episodes that ended (they may have begun in earlier
        // chunks: `carry`).
        {
            let buf: &mut [u8] = sample_mut.payload_mut();
            let term = layout.range(Section::Terminated).start;
            let trunc = layout.range(Section::Truncated).start;
            let ir = layout.range(Section::IntReward);
            if form.uses_empowerment() {
                h.e_positive = intrinsic.iter().filter(|&&v| v > 0.0).count() as u32;
            }
            let shaping = fulcrum_shared::intrinsic::Shaping {
                form,
                gamma: cfg.ppo.gamma,
                phi_reset,
                inventory_reset: world.initial.inventory,
            };
            next_inv.clear();
            next_inv.extend(next_states.iter().map(|s| s.inventory));
            shaping.chunk(
                &intrinsic,
                &next_inv,
                &buf[term..term + n],
                &buf[trunc..trunc + n],
                &mut phi,
                &mut inv,
                &mut paid,
                &mut bonus,
            );
            let mut acc = carry.clone();
            for t in 0..t_len {
                for (e, a) in acc.iter_mut().enumerate() {
                    let i = t * m + e;
                    let val = bonus[i];
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
            for (e, r) in envs.iter_mut().enumerate() {
                r.int_return = acc[e];
                r.paid = paid[e];
                buf[er + e * ENV_BYTES..er + (e + 1) * ENV_BYTES].copy_from_slice(&r.to_bytes());
            }
        }
        *sample_mut.user_header_mut() = h;
        match sample_mut.send() {
            Ok(_) => {}
            Err(e) if stop.load(Ordering::Relaxed) => {
                tracing::debug!(?e, "chunk not sent: stopping");
                return Ok(());
            }
            Err(e) => return Err(ipc("send chunk")(&e)),
        }
        let _ = notifier.notify();
        seq += 1;
        per_version += 1;
        // Weights for the next chunk.
        let blocking = cfg.max_policy_lag == 0;
        match wait.take(&mut policy, Some(version), blocking)? {
            Some(v) => {
                version = v;
                per_version = 0;
            }
            None if blocking => return Ok(()), // stopping
            None => {}
        }
    }
    Ok(())
}

/// Send pending states and collect answers until either everything collected is
/// sent or the pipe is full; then collect one answer.
fn pump(
    cl: &mut Client,
    ask: Ask,
    states: &[State],
    sent: &mut usize,
    answered: &mut usize,
    out: &mut [f32],
    sub_batch: usize,
) -> Result<(), ClientError> {
    while *sent < states.len() && cl.in_flight() < MAX_IN_FLIGHT {
        let end = (*sent + sub_batch).min(states.len());
        cl.submit(ask, &states[*sent..end])?;
        *sent = end;
    }
    if cl.in_flight() > 0 && (cl.in_flight() >= MAX_IN_FLIGHT || *sent == states.len()) {
        let b = cl.recv()?;
        if let Some(bad) = b.status.iter().position(|&s| s != item::OK) {
            return Err(ClientError::Ipc(format!(
                "state {} of a chunk is not in the world's state space",
                *answered + bad
            )));
        }
        out[*answered..*answered + b.values.len()].copy_from_slice(&b.values);
        *answered += b.values.len();
    }
    Ok(())
}

/// Connect to the run's empowerment service, retrying until it answers or `stop`.
fn connect(
    namespace: &str,
    world: &World,
    stop: &'static AtomicBool,
) -> Result<Option<Client>, ActorError> {
    let t0 = Instant::now();
    loop {
        if stop.load(Ordering::Relaxed) {
            return Ok(None);
        }
        match Client::connect(namespace, world, Duration::from_secs(2)) {
            Ok(c) => return Ok(Some(c)),
            Err(e @ ClientError::WrongWorld { .. }) => {
                return Err(ActorError::Service(e.to_string()))
            }
            Err(e) => {
                if t0.elapsed() > Duration::from_secs(120) {
                    return Err(ActorError::Service(e.to_string()));
                }
                tracing::info!("waiting for the empowerment service: {e}");
            }
        }
    }
}

/// The worlds of actor `index` from the checkpoint, if it was taken at `version`.
fn resume_records(
    path: &Path,
    shape: NetShape,
    index: u32,
    version: u64,
    m: usize,
    world: &World,
) -> Option<Vec<EnvRecord>> {
    if !path.exists() {
        return None;
    }
    // The whole file is checked against the network's layout, as the learner checks it.
    let extra = checkpoint::read(path, &shape.params()).ok()?.extra;
    if extra.counters.get("update") != Some(&version) {
        return None;
    }
    let b = extra.blobs.get(&format!("env/{index}"))?;
    if b.len() != m * ENV_BYTES {
        return None;
    }
    let recs: Vec<EnvRecord> = b
        .chunks_exact(ENV_BYTES)
        .map(EnvRecord::from_bytes)
        .collect::<Option<_>>()?;
    // Never start from a record whose agent is off the map (another world's file).
    recs.iter()
        .all(|x| {
            (x.episode.state.x as usize) < world.width
                && (x.episode.state.y as usize) < world.height
        })
        .then_some(recs)
}

/// Where new weights come from.
struct WeightsIn<'a> {
    sub: &'a traj::WeightsSubscriber,
    listener: &'a iceoryx2::port::listener::Listener<ipc::Service>,
    run: u64,
    world_hash: u64,
    stop: &'static AtomicBool,
}

impl WeightsIn<'_> {
    /// Take the newest weights newer than `after` into `policy`; with `block`, wait for
    /// them (until stopped). Returns their version.
    fn take(
        &self,
        policy: &mut Policy,
        after: Option<u64>,
        block: bool,
    ) -> Result<Option<u64>, ActorError> {
        loop {
            let mut newest: Option<u64> = None;
            while let Some(s) = self.sub.receive().map_err(|e| ipc("receive weights")(&e))? {
                let h = *s.user_header();
                if h.run != self.run || h.world_hash != self.world_hash {
                    tracing::warn!("ignored weights of another run");
                    continue;
                }
                if after.is_some_and(|a| h.version <= a) || newest.is_some_and(|v| h.version < v) {
                    continue;
                }
                if !policy.set(s.payload()) {
                    tracing::warn!("ignored weights of another shape");
                    continue;
                }
                newest = Some(h.version);
            }
            if newest.is_some() {
                return Ok(newest);
            }
            if !block || self.stop.load(Ordering::Relaxed) {
                return Ok(None);
            }
            let _ = self.listener.timed_wait(|_| {}, Duration::from_millis(50));
        }
    }
}
