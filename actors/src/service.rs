//! The actor's side of the empowerment service: connecting (and reconnecting after a
//! failure), and the pipelined lookups of a chunk's states.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use fulcrum_contracts::msg::{item, MAX_BATCH, MAX_IN_FLIGHT};
use fulcrum_empowerment::service::{Ask, Client, ClientError};
use fulcrum_world::{State, World};

use crate::error::ActorError;

/// How long the empowerment service may take to start (build its table): the
/// supervisor gives a (re)started service this long before it ends the run.
pub const SERVICE_START_LIMIT: Duration = Duration::from_secs(600);

/// How long an actor waits for the empowerment service before it gives up: the
/// service's start limit and a margin that covers the supervisor's longest restart
/// back-off (10 s), so an actor never gives up on a service the supervisor is still
/// restarting.
pub const SERVICE_WAIT: Duration = Duration::from_secs(600 + 30);

/// The states an actor asks about, and on a world family the layout of each.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Asked<'a> {
    pub(crate) states: &'a [State],
    pub(crate) layouts: Option<&'a [u64]>,
}

/// Send pending states and collect answers until either everything collected is
/// sent or the pipe is full; then collect one answer, waiting for it where the pipe is
/// full or `wait` (everything is sent and nothing more is coming), and else only the
/// answers that have come (a chunk still being played goes on stepping while the
/// service works: on a family run it may be making several new layouts' tables).
#[allow(clippy::too_many_arguments)]
pub(crate) fn pump(
    cl: &mut Client,
    ask: Ask,
    Asked { states, layouts }: Asked<'_>,
    sent: &mut usize,
    answered: &mut usize,
    out: &mut [f32],
    sub_batch: usize,
    wait: bool,
) -> Result<(), ClientError> {
    while *sent < states.len() && cl.in_flight() < MAX_IN_FLIGHT {
        let end = (*sent + sub_batch).min(states.len());
        cl.submit_on(ask, &states[*sent..end], layouts.map(|l| &l[*sent..end]))?;
        *sent = end;
    }
    if cl.in_flight() == 0 {
        return Ok(());
    }
    if cl.in_flight() >= MAX_IN_FLIGHT || (wait && *sent == states.len()) {
        let b = cl.recv()?;
        take(b, answered, out)?;
    } else {
        while let Some(b) = cl.try_recv()? {
            take(b, answered, out)?;
        }
    }
    Ok(())
}

/// One answer into `out` at `answered`.
fn take(
    b: fulcrum_empowerment::service::Batch,
    answered: &mut usize,
    out: &mut [f32],
) -> Result<(), ClientError> {
    if let Some(bad) = b.status.iter().position(|&s| s != item::OK) {
        return Err(ClientError::Ipc(format!(
            "state {} of a chunk is not in the world's state space",
            *answered + bad
        )));
    }
    out[*answered..*answered + b.values.len()].copy_from_slice(&b.values);
    *answered += b.values.len();
    Ok(())
}

/// Connect to the run's empowerment service, retrying until it answers, `stop`, or
/// [`SERVICE_WAIT`] has passed.
pub(crate) fn connect(
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
                if t0.elapsed() > SERVICE_WAIT {
                    return Err(ActorError::Service(e.to_string()));
                }
                tracing::info!("waiting for the empowerment service: {e}");
            }
        }
    }
}

/// The potentials of the initial states of the episodes begun in a chunk (a family's
/// layouts, potential forms), into `vals`; asked after the chunk's own lookups.
pub(crate) fn look_up_resets(
    cl: &mut Client,
    ask: Ask,
    resets: &[(usize, State, u64)],
    vals: &mut Vec<f32>,
) -> Result<(), fulcrum_empowerment::service::ClientError> {
    vals.clear();
    vals.resize(resets.len(), 0.0);
    if resets.is_empty() {
        return Ok(());
    }
    let states: Vec<State> = resets.iter().map(|r| r.1).collect();
    let layouts: Vec<u64> = resets.iter().map(|r| r.2).collect();
    let (mut sent, mut got) = (0, 0);
    while got < states.len() {
        pump(
            cl,
            ask,
            Asked {
                states: &states,
                layouts: Some(&layouts),
            },
            &mut sent,
            &mut got,
            vals,
            MAX_BATCH,
            true,
        )?;
    }
    Ok(())
}

/// A lookup that failed: a warning, unless the actor is stopping (the end of a run
/// stops the actors and the service together, and a request in flight then finds the
/// service gone).
pub(crate) fn service_trouble(stop: &AtomicBool, actor: u32, e: &dyn std::fmt::Display) {
    if stop.load(Ordering::Relaxed) {
        tracing::debug!(actor, "empowerment service while stopping: {e}");
    } else {
        tracing::warn!(actor, "empowerment service: {e}");
    }
}
