//! The lines fulcrum's child processes print for their parents: one type,
//! [`ChildLine`](crate::lines::ChildLine), written with `Display` and read back with
//! `FromStr` by the same code, so that no parent matches a child's output by substring.
//!
//! | line | who prints it | who reads it |
//! |---|---|---|
//! | `fulcrum serve: ready: ABOUT` | `fulcrum serve`, once it answers | the supervisor, tests, the bench |
//! | `fulcrum bridge: ready, listening on ENDPOINT for run NS` | a learner host's bridge | the supervisor |
//! | `fulcrum bridge: ready NS TAG HOST` | an actor host's bridge, once joined | `fulcrum actor-host` |
//! | `fulcrum bridge: the run is over` | an actor host's bridge | `fulcrum actor-host` |
//! | `fulcrum remote peer: ready on ENDPOINT` | `fulcrum bench --remote`'s peer | the bench |
//! | `progress U N STEPS SUCCESS RETURN SPS` | the learner, after each update | the supervisor's progress line |
//! | `waiting SECS ACTORS` | the learner, once a second while it waits for chunks | the watchdog |
//! | `stalled ACTOR SECS late\|refused` | the learner, going on without an actor | the supervisor |
//! | `trap LIMIT SINCE LENGTH SHARE BONUS WORTH DWELL` | the learner, at the beacon-trap detector's first mark | the supervisor's warning |
//!
//! A line that is none of these (a child's log, a person's words) reads as an error,
//! never as a near miss: "already" is not "ready".

use std::fmt;
use std::str::FromStr;

/// What the learner tells its supervisor besides its metrics rows.
#[derive(Debug, Clone, PartialEq)]
pub enum Notice {
    /// The learner has waited `waited_s` for this update's chunks and still waits for
    /// these actors (empty: for any chunk at all).
    Waiting {
        /// Seconds since this update's gathering began.
        waited_s: f64,
        /// The actors whose chunks are missing.
        actors: Vec<u32>,
    },
    /// The learner goes on without a local actor: its chunk did not come within the
    /// deadline (`refused` false) or was refused (`refused` true).
    Stalled {
        /// The actor.
        actor: u32,
        /// Seconds waited for it.
        waited_s: f64,
        /// Whether its chunk was refused rather than late.
        refused: bool,
    },
    /// The beacon-trap detector marked an update for the first time in this session.
    Trap(TrapSigns),
}

/// What the beacon-trap detector's window shows when it marks an update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrapSigns {
    /// The world's episode limit.
    pub max_steps: u32,
    /// Env steps since which no episode succeeded (the window's start).
    pub since_step: u64,
    /// Mean episode length over the window.
    pub episode_length: f64,
    /// beta * intrinsic return / (beta * intrinsic return + task return), per episode.
    pub intrinsic_share: f64,
    /// beta * intrinsic return per episode.
    pub bonus: f64,
    /// `bonus` as a fraction of the task's reward.
    pub worth: f64,
    /// Fraction of the window's steps with E(s') > 0.
    pub e_positive_frac: f64,
}

/// The learner's progress after an update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LearnerProgress {
    /// The update just made.
    pub update: u64,
    /// The updates the run will make (runs with actors on other hosts re-plan it).
    pub total: u64,
    /// Env steps so far.
    pub env_steps: u64,
    /// The update's success rate (printed to 3 decimals).
    pub success_rate: f64,
    /// The update's mean extrinsic return (printed to 3 decimals).
    pub extrinsic_return: f64,
    /// Env steps per second (printed whole).
    pub sps: f64,
}

/// What an actor host needs to start its actors (printed by its bridge once joined).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Joined {
    /// The namespace of this host's shared-memory services.
    pub local_ns: String,
    /// The run's tag, for the actors' chunks.
    pub run_tag: u64,
    /// This host's index.
    pub host: u32,
}

/// One line of a child process to its parent.
#[derive(Debug, Clone, PartialEq)]
pub enum ChildLine {
    /// The empowerment service answers; `about` says what it serves (for people).
    ServiceReady {
        /// World, hash, states, channel and service name, as one phrase.
        about: String,
    },
    /// A learner host's bridge listens for actor hosts.
    BridgeListening {
        /// Where it listens.
        endpoint: String,
        /// The run's namespace.
        run: String,
    },
    /// An actor host's bridge has joined the run.
    BridgeJoined(Joined),
    /// An actor host's bridge: the learner ended the run.
    RunOver,
    /// The remote bench's peer listens.
    PeerReady {
        /// Where it listens.
        endpoint: String,
    },
    /// The learner made an update.
    Progress(LearnerProgress),
    /// The learner's news for the watchdog and the person watching.
    Notice(Notice),
}

impl ChildLine {
    /// Whether the child is now ready for what it was started for.
    pub fn is_ready(&self) -> bool {
        matches!(
            self,
            ChildLine::ServiceReady { .. }
                | ChildLine::BridgeListening { .. }
                | ChildLine::BridgeJoined(_)
                | ChildLine::PeerReady { .. }
        )
    }

    /// The line read back, `None` where it is not one of fulcrum's (a log line).
    pub fn parse(line: &str) -> Option<ChildLine> {
        line.parse().ok()
    }

    /// Whether `line` is a child's line saying it is ready.
    pub fn says_ready(line: &str) -> bool {
        ChildLine::parse(line).is_some_and(|c| c.is_ready())
    }
}

const SERVICE_READY: &str = "fulcrum serve: ready: ";
const BRIDGE_LISTENING: &str = "fulcrum bridge: ready, listening on ";
const BRIDGE_JOINED: &str = "fulcrum bridge: ready ";
const RUN_OVER: &str = "fulcrum bridge: the run is over";
const PEER_READY: &str = "fulcrum remote peer: ready on ";

impl fmt::Display for ChildLine {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ChildLine::ServiceReady { about } => write!(f, "{SERVICE_READY}{about}"),
            ChildLine::BridgeListening { endpoint, run } => {
                write!(f, "{BRIDGE_LISTENING}{endpoint} for run {run}")
            }
            ChildLine::BridgeJoined(j) => write!(
                f,
                "{BRIDGE_JOINED}{} {:016x} {}",
                j.local_ns, j.run_tag, j.host
            ),
            ChildLine::RunOver => f.write_str(RUN_OVER),
            ChildLine::PeerReady { endpoint } => write!(f, "{PEER_READY}{endpoint}"),
            ChildLine::Progress(p) => write!(
                f,
                "progress {} {} {} {:.3} {:.3} {:.0}",
                p.update, p.total, p.env_steps, p.success_rate, p.extrinsic_return, p.sps
            ),
            ChildLine::Notice(Notice::Waiting { waited_s, actors }) => {
                let list: Vec<String> = actors.iter().map(u32::to_string).collect();
                let list = if list.is_empty() {
                    "-".to_string()
                } else {
                    list.join(",")
                };
                write!(f, "waiting {waited_s:.1} {list}")
            }
            ChildLine::Notice(Notice::Stalled {
                actor,
                waited_s,
                refused,
            }) => write!(
                f,
                "stalled {actor} {waited_s:.1} {}",
                if *refused { "refused" } else { "late" }
            ),
            ChildLine::Notice(Notice::Trap(t)) => write!(
                f,
                "trap {} {} {} {} {} {} {}",
                t.max_steps,
                t.since_step,
                t.episode_length,
                t.intrinsic_share,
                t.bonus,
                t.worth,
                t.e_positive_frac
            ),
        }
    }
}

/// A line that is none of [`ChildLine`]'s.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NotAChildLine(pub String);

impl fmt::Display for NotAChildLine {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "not a line of fulcrum's child processes: '{}'", self.0)
    }
}

impl std::error::Error for NotAChildLine {}

impl FromStr for ChildLine {
    type Err = NotAChildLine;
    fn from_str(line: &str) -> Result<ChildLine, NotAChildLine> {
        parse_line(line.trim_end_matches(['\n', '\r'])).ok_or_else(|| NotAChildLine(line.into()))
    }
}

fn parse_line(line: &str) -> Option<ChildLine> {
    if let Some(about) = line.strip_prefix(SERVICE_READY) {
        return Some(ChildLine::ServiceReady {
            about: about.to_string(),
        });
    }
    if let Some(rest) = line.strip_prefix(BRIDGE_LISTENING) {
        let (endpoint, run) = rest.rsplit_once(" for run ")?;
        return Some(ChildLine::BridgeListening {
            endpoint: endpoint.to_string(),
            run: run.to_string(),
        });
    }
    if line == RUN_OVER {
        return Some(ChildLine::RunOver);
    }
    if let Some(rest) = line.strip_prefix(BRIDGE_JOINED) {
        let w: Vec<&str> = rest.split(' ').collect();
        let [ns, tag, host] = w.as_slice() else {
            return None;
        };
        return Some(ChildLine::BridgeJoined(Joined {
            local_ns: ns.to_string(),
            run_tag: u64::from_str_radix(tag, 16).ok()?,
            host: host.parse().ok()?,
        }));
    }
    if let Some(endpoint) = line.strip_prefix(PEER_READY) {
        return Some(ChildLine::PeerReady {
            endpoint: endpoint.to_string(),
        });
    }
    let v: Vec<&str> = line.split(' ').collect();
    Some(match v.as_slice() {
        ["progress", u, n, steps, success, ret, sps] => ChildLine::Progress(LearnerProgress {
            update: u.parse().ok()?,
            total: n.parse().ok()?,
            env_steps: steps.parse().ok()?,
            success_rate: success.parse().ok()?,
            extrinsic_return: ret.parse().ok()?,
            sps: sps.parse().ok()?,
        }),
        ["waiting", s, list] => ChildLine::Notice(Notice::Waiting {
            waited_s: s.parse().ok()?,
            actors: if *list == "-" {
                Vec::new()
            } else {
                list.split(',')
                    .map(str::parse)
                    .collect::<Result<_, _>>()
                    .ok()?
            },
        }),
        ["stalled", a, s, how @ ("late" | "refused")] => ChildLine::Notice(Notice::Stalled {
            actor: a.parse().ok()?,
            waited_s: s.parse().ok()?,
            refused: *how == "refused",
        }),
        ["trap", limit, since, len, share, bonus, worth, dwell] => {
            ChildLine::Notice(Notice::Trap(TrapSigns {
                max_steps: limit.parse().ok()?,
                since_step: since.parse().ok()?,
                episode_length: len.parse().ok()?,
                intrinsic_share: share.parse().ok()?,
                bonus: bonus.parse().ok()?,
                worth: worth.parse().ok()?,
                e_positive_frac: dwell.parse().ok()?,
            }))
        }
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every kind of line, as its writer prints it (spelled out here by hand, so that a
    /// change of format shows), and back.
    #[test]
    fn every_line_reads_back_as_what_was_written() {
        let cases = [
            (
                ChildLine::ServiceReady {
                    about: "world room (hash 00ff), 120 states".into(),
                },
                "fulcrum serve: ready: world room (hash 00ff), 120 states",
            ),
            (
                ChildLine::BridgeListening {
                    endpoint: "tcp/0.0.0.0:7447".into(),
                    run: "t1f".into(),
                },
                "fulcrum bridge: ready, listening on tcp/0.0.0.0:7447 for run t1f",
            ),
            (
                ChildLine::BridgeJoined(Joined {
                    local_ns: "t1f.h3".into(),
                    run_tag: 0xabcdef01234567,
                    host: 3,
                }),
                "fulcrum bridge: ready t1f.h3 00abcdef01234567 3",
            ),
            (ChildLine::RunOver, "fulcrum bridge: the run is over"),
            (
                ChildLine::PeerReady {
                    endpoint: "tcp/10.0.0.2:7450".into(),
                },
                "fulcrum remote peer: ready on tcp/10.0.0.2:7450",
            ),
            (
                ChildLine::Progress(LearnerProgress {
                    update: 7,
                    total: 196,
                    env_steps: 7168,
                    success_rate: 0.25,
                    extrinsic_return: 0.5,
                    sps: 1234.0,
                }),
                "progress 7 196 7168 0.250 0.500 1234",
            ),
            (
                ChildLine::Notice(Notice::Waiting {
                    waited_s: 2.5,
                    actors: vec![0, 2],
                }),
                "waiting 2.5 0,2",
            ),
            (
                ChildLine::Notice(Notice::Waiting {
                    waited_s: 1.0,
                    actors: vec![],
                }),
                "waiting 1.0 -",
            ),
            (
                ChildLine::Notice(Notice::Stalled {
                    actor: 1,
                    waited_s: 12.5,
                    refused: true,
                }),
                "stalled 1 12.5 refused",
            ),
            (
                ChildLine::Notice(Notice::Trap(TrapSigns {
                    max_steps: 100,
                    since_step: 200704,
                    episode_length: 99.5,
                    intrinsic_share: 0.75,
                    bonus: 0.0625,
                    worth: 0.0625,
                    e_positive_frac: 0.5,
                })),
                "trap 100 200704 99.5 0.75 0.0625 0.0625 0.5",
            ),
        ];
        for (line, text) in cases {
            assert_eq!(line.to_string(), text);
            assert_eq!(text.parse::<ChildLine>(), Ok(line.clone()), "{text}");
            assert_eq!(
                line.is_ready(),
                text.contains(": ready"),
                "{text}: readiness by kind"
            );
        }
    }

    /// Words that contain a line's key word are not that line.
    #[test]
    fn near_misses_are_not_lines() {
        for text in [
            "fulcrum serve: the service is already running",
            "already ready",
            "ready",
            "fulcrum serve: ready",
            "fulcrum bridge: ready t1f.h3 zz 3",
            "fulcrum bridge: ready t1f.h3 00ab 3 extra",
            "fulcrum bridge: the run is over, or not",
            "progress 1 2 3",
            "progress 1 2 3 0.5 0.5 fast",
            "stalled 1 2.0 sleepy",
            "waiting 1.0 0,x",
            "trap 100 1 2 3",
            "",
        ] {
            assert!(text.parse::<ChildLine>().is_err(), "{text:?}");
        }
    }
}
