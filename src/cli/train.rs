//! `fulcrum train`'s flags, and the request they make (`TrainArgs::request`).

use std::path::PathBuf;

use clap::Args;
use fulcrum_run::plan::TrainRequest;
use fulcrum_run::settings::{Fixed, Resumable};
use fulcrum_run::BadRequest;

use super::zenoh::ZenohArgs;

/// `fulcrum train`
#[derive(Debug, Args)]
pub struct TrainArgs {
    /// A world file, or a built-in world (exp1-tree, exp1-wall, exp2, exp3, room).
    #[arg(required_unless_present = "resume")]
    pub world: Option<String>,
    #[command(flatten)]
    pub fixed: Fixed,
    #[command(flatten)]
    pub resumable: Resumable,
    /// Run directory [default: runs/<world>-<time>-<seed>].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Continue the run in this directory from its last checkpoint (its config.toml
    /// holds the settings; only --steps may raise the budget).
    #[arg(long, conflicts_with = "out")]
    pub resume: Option<PathBuf>,
    /// Stop (with a checkpoint, resumable) after this many updates in this session.
    #[arg(long, hide = true)]
    pub stop_after_updates: Option<u64>,
    /// Restarts each child (each actor slot, the empowerment service, the bridge) may
    /// have within --restart-window seconds; one more stop ends the run. Restarts wait
    /// a back-off of 100 ms doubling to 10 s.
    #[arg(long, default_value_t = fulcrum_run::restart::DEFAULT_MAX_RESTARTS)]
    pub max_restarts: u32,
    /// The window of --max-restarts, seconds.
    #[arg(long, value_name = "SECS", default_value_t = fulcrum_run::restart::DEFAULT_WINDOW_S)]
    pub restart_window: f64,
    /// End the run (exit 1, naming who stalled) when no update came for this many
    /// seconds and 20 times the recent update time.
    #[arg(long, value_name = "SECS", default_value_t = fulcrum_run::watchdog::DEFAULT_FLOOR_S)]
    pub hang_timeout: f64,
    /// At the end, play N episodes of the final policy and draw each as a strip of
    /// frames in RUN/episodes/ (as `fulcrum record`).
    #[arg(long)]
    pub record: Option<usize>,
    /// Let actors on other hosts join (`fulcrum actor-host --connect ADDR` there):
    /// listen for zenoh peers on ADDR (`host:port` or a zenoh locator such as
    /// `tcp/0.0.0.0:7447`). Needs the `multihost` feature.
    #[arg(long, value_name = "ADDR")]
    #[cfg_attr(not(feature = "multihost"), arg(hide = true))]
    pub listen: Option<String>,
    /// With --listen: seconds the learner waits for a remote actor's chunk before it
    /// goes on without it [default: 10].
    #[arg(long, value_name = "SECS")]
    #[cfg_attr(not(feature = "multihost"), arg(hide = true))]
    pub stall_timeout: Option<f64>,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
}

impl TrainArgs {
    /// The run this command line asks for, with the mistakes only flags can make
    /// (contradicting flags, a setting that a resume cannot change) refused, each
    /// naming its flags.
    pub fn request(&self) -> Result<TrainRequest, BadRequest> {
        let r = TrainRequest {
            world: self.world.clone(),
            fixed: self.fixed.clone(),
            resumable: self.resumable.clone(),
            out: self.out.clone(),
            resume: self.resume.clone(),
            remote: self.listen.is_some(),
            stall_timeout: self.stall_timeout,
        };
        r.check()?;
        Ok(r)
    }
}

impl TrainArgs {
    /// The supervisor's restart policy and watchdog floor, from --max-restarts,
    /// --restart-window and --hang-timeout.
    pub fn supervision(
        &self,
    ) -> Result<(fulcrum_run::restart::RestartPolicy, std::time::Duration), BadRequest> {
        let secs = |v: f64, flag: &str| {
            if v.is_finite() && v > 0.0 && v < 1e9 {
                Ok(std::time::Duration::from_secs_f64(v))
            } else {
                Err(BadRequest(format!(
                    "{flag} {v} must be a positive number of seconds"
                )))
            }
        };
        let policy = fulcrum_run::restart::RestartPolicy {
            max: self.max_restarts,
            window: secs(self.restart_window, "--restart-window")?,
        };
        Ok((policy, secs(self.hang_timeout, "--hang-timeout")?))
    }
}
