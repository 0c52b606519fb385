//! An actor host's supervision (`fulcrum actor-host`): its bridge and its K actors,
//! beside the run's own supervisor and with the same restart policy
//! ([`crate::restart`]). It waits on events, as the supervisor does: a child's exit
//! (`send_on_exit`), the bridge's lines (the run is over), the stop flag, the next
//! restart whose back-off has passed. An actor that stops is restarted after its
//! back-off while its budget lasts; one over its budget, or a bridge that fails, ends
//! the host with an error; a bridge that says the run is over ends it cleanly.

use std::process::Child;
use std::time::Instant;

use crate::error::Result;
use crossbeam_channel::{after, never, select, Receiver};
use fulcrum_contracts::lines::ChildLine;

use crate::process::{send_on_exit, stop_children, stop_events};
use crate::restart::{Budget, RestartPolicy};

/// Who exited.
#[derive(Debug, Clone, Copy)]
enum Exit {
    Bridge,
    /// Actor index and incarnation.
    Actor(usize, u32),
}

/// What an actor host supervises.
pub struct HostRun<'a> {
    /// The bridge, already joined.
    pub bridge: Child,
    /// The bridge's stdout lines after its `ready` line.
    pub bridge_lines: Receiver<String>,
    /// Actor processes on this host.
    pub actors: usize,
    /// The restart policy of every actor.
    pub policy: RestartPolicy,
    /// Starts actor `j` in its incarnation `inc`.
    pub start: Box<dyn FnMut(usize, u32) -> Result<Child> + 'a>,
}

impl std::fmt::Debug for HostRun<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HostRun")
            .field("actors", &self.actors)
            .field("policy", &self.policy)
            .finish_non_exhaustive()
    }
}

/// Runs the host until the run is over (Ok), the stop flag is raised (Ok), or an actor
/// goes over its budget or the bridge fails (Err); then stops every child.
pub fn supervise_host(h: HostRun<'_>) -> Result<()> {
    let HostRun {
        mut bridge,
        bridge_lines,
        actors: k,
        policy,
        mut start,
    } = h;
    let (exits_tx, exits) = crossbeam_channel::unbounded();
    let stop = stop_events()?;
    send_on_exit(&bridge, exits_tx.clone(), Exit::Bridge);
    let mut actors: Vec<(Child, u32)> = Vec::with_capacity(k);
    let mut result = Ok(());
    for j in 0..k {
        match start(j, 0) {
            Ok(c) => {
                send_on_exit(&c, exits_tx.clone(), Exit::Actor(j, 0));
                actors.push((c, 0));
            }
            Err(e) => {
                result = Err(e);
                break;
            }
        }
    }
    let mut budgets = vec![Budget::default(); k];
    // An actor that stopped and waits for its back-off: when to restart it.
    let mut due: Vec<Option<Instant>> = vec![None; k];
    let mut lines = bridge_lines;
    let mut over = false;
    while result.is_ok() {
        let wake = match due.iter().flatten().min() {
            Some(t) => after(t.saturating_duration_since(Instant::now())),
            None => never(),
        };
        select! {
            recv(lines) -> l => match l {
                Ok(l) => over |= ChildLine::parse(&l) == Some(ChildLine::RunOver),
                Err(_) => lines = never(),
            },
            recv(stop) -> _ => break,
            recv(wake) -> _ => {
                let now = Instant::now();
                for j in 0..k {
                    if due[j].is_some_and(|t| t <= now) {
                        due[j] = None;
                        let inc = actors[j].1 + 1;
                        match start(j, inc) {
                            Ok(c) => {
                                send_on_exit(&c, exits_tx.clone(), Exit::Actor(j, inc));
                                // The old process was reaped when it stopped.
                                actors[j] = (c, inc);
                            }
                            Err(e) => {
                                result = Err(e);
                                break;
                            }
                        }
                    }
                }
            },
            recv(exits) -> e => match e {
                Ok(Exit::Bridge) => {
                    let s = bridge.wait()?;
                    // Its last lines are in the channel, or about to be.
                    while let Ok(l) = lines.recv_timeout(std::time::Duration::from_millis(100)) {
                        over |= ChildLine::parse(&l) == Some(ChildLine::RunOver);
                    }
                    if over || s.success() {
                        eprintln!("fulcrum actor-host: the run is over");
                    } else {
                        result = Err(crate::failure!("the bridge stopped ({s})"));
                    }
                    break;
                }
                Ok(Exit::Actor(j, inc)) if actors[j].1 == inc && due[j].is_none() => {
                    let s = actors[j].0.wait()?;
                    let now = Instant::now();
                    match budgets[j].stopped(&policy, now) {
                        Ok(r) => {
                            eprintln!(
                                "fulcrum actor-host: actor {j} stopped ({s}); restarting it after {:.1} s (restart {} of {} allowed in {} s)",
                                r.delay.as_secs_f64(),
                                r.n,
                                policy.max,
                                policy.window.as_secs_f64()
                            );
                            due[j] = Some(now + r.delay);
                        }
                        Err(o) => {
                            result = Err(crate::failure!(
                                "actor {j} stopped ({s}), its stop number {} within {} s: over its budget of {} restarts in {} s",
                                o.n,
                                policy.window.as_secs_f64(),
                                policy.max,
                                policy.window.as_secs_f64()
                            ));
                        }
                    }
                }
                // An earlier incarnation's exit, already handled.
                Ok(Exit::Actor(..)) => {}
                Err(_) => break,
            },
        }
    }
    let mut all: Vec<Child> = actors.into_iter().map(|(c, _)| c).collect();
    all.push(bridge);
    stop_children(all);
    fulcrum_empowerment::service::clean_dead_nodes();
    result
}
