//! The command lines of fulcrum's own child processes: one typed builder per
//! subcommand, the one place outside the binary's `cli` module that spells its flags.
//! The binary's tests parse what each builder makes with its clap types and compare
//! the result with what was built from (`src/cli/argv_tests.rs`), so a renamed flag
//! fails a test instead of a child.
//!
//! Each builder returns the arguments after the executable, the subcommand first.

use std::path::{Path, PathBuf};

/// What the supervisor tells a child process.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChildRequest {
    /// The run directory.
    pub run: PathBuf,
    /// The run's iceoryx2 namespace.
    pub namespace: String,
    /// The supervisor's pid: the child dies with it.
    pub parent: u32,
    /// The actor's index.
    pub index: u32,
    /// How often this actor has been restarted.
    pub incarnation: u32,
    /// The learner stops after this many updates (exit code 3).
    pub stop_after_updates: Option<u64>,
    /// The run's tag, hex (actors on other hosts).
    pub run_tag: Option<String>,
}

/// Which hidden child process.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChildKind {
    /// `__learner`.
    Learner,
    /// `__actor`.
    Actor,
}

/// `__learner` / `__actor`: a child of a run, everything else from its run directory.
pub fn child(kind: ChildKind, r: &ChildRequest) -> Vec<String> {
    let mut v = vec![
        match kind {
            ChildKind::Learner => "__learner",
            ChildKind::Actor => "__actor",
        }
        .to_string(),
        "--run".into(),
        r.run.display().to_string(),
        "--namespace".into(),
        r.namespace.clone(),
        "--parent".into(),
        r.parent.to_string(),
    ];
    if kind == ChildKind::Actor {
        v.extend([
            "--index".into(),
            r.index.to_string(),
            "--incarnation".into(),
            r.incarnation.to_string(),
        ]);
    }
    if let Some(n) = r.stop_after_updates {
        v.extend(["--stop-after-updates".into(), n.to_string()]);
    }
    if let Some(t) = &r.run_tag {
        v.extend(["--run-tag".into(), t.clone()]);
    }
    v
}

/// `serve --run DIR --namespace NS`: the service of a run, as its `config.toml` says.
pub fn serve_run(run: &Path, namespace: &str) -> Vec<String> {
    vec![
        "serve".into(),
        "--run".into(),
        run.display().to_string(),
        "--namespace".into(),
        namespace.to_string(),
    ]
}

/// The zenoh settings every bridge takes.
#[derive(Debug, Clone, PartialEq)]
pub struct Zenoh {
    /// Seconds without a word before a session is closed.
    pub session_timeout: f64,
    /// A zenoh configuration file, if any.
    pub config: Option<PathBuf>,
}

impl Zenoh {
    fn extend(&self, v: &mut Vec<String>) {
        v.extend(["--session-timeout".into(), self.session_timeout.to_string()]);
        if let Some(c) = &self.config {
            v.extend(["--zenoh-config".into(), c.display().to_string()]);
        }
    }
}

/// The learner host's bridge: listens for actor hosts.
#[derive(Debug, Clone, PartialEq)]
pub struct BridgeListen {
    /// Where to listen.
    pub addr: String,
    /// The run directory.
    pub run: PathBuf,
    /// The run's namespace.
    pub namespace: String,
    /// The supervisor's pid.
    pub parent: u32,
    /// Zenoh's settings.
    pub zenoh: Zenoh,
}

/// `bridge --listen ...`.
pub fn bridge_listen(b: &BridgeListen) -> Vec<String> {
    let mut v = vec![
        "bridge".into(),
        "--listen".into(),
        b.addr.clone(),
        "--run".into(),
        b.run.display().to_string(),
        "--namespace".into(),
        b.namespace.clone(),
        "--parent".into(),
        b.parent.to_string(),
    ];
    b.zenoh.extend(&mut v);
    v
}

/// An actor host's bridge: joins a run.
#[derive(Debug, Clone, PartialEq)]
pub struct BridgeConnect {
    /// The learner host's address.
    pub connect: String,
    /// This host's run directory.
    pub run: PathBuf,
    /// This host's name.
    pub name: String,
    /// Seconds to keep asking before giving up.
    pub give_up: f64,
    /// The actor host's pid.
    pub parent: u32,
    /// The world the host expects, if it names one.
    pub world: Option<String>,
    /// The run id the host expects, if it names one.
    pub run_id: Option<String>,
    /// Zenoh's settings.
    pub zenoh: Zenoh,
}

/// `bridge --connect ...`.
pub fn bridge_connect(b: &BridgeConnect) -> Vec<String> {
    let mut v = vec![
        "bridge".into(),
        "--connect".into(),
        b.connect.clone(),
        "--run".into(),
        b.run.display().to_string(),
        "--name".into(),
        b.name.clone(),
        "--give-up".into(),
        b.give_up.to_string(),
        "--parent".into(),
        b.parent.to_string(),
    ];
    if let Some(w) = &b.world {
        v.extend(["--world".into(), w.clone()]);
    }
    if let Some(r) = &b.run_id {
        v.extend(["--run-id".into(), r.clone()]);
    }
    b.zenoh.extend(&mut v);
    v
}

/// A new run, as `fulcrum train` takes it (`None`: train's default).
#[derive(Debug, Clone, PartialEq)]
pub struct NewRun {
    /// The world.
    pub world: String,
    /// Its seed.
    pub seed: Option<u64>,
    /// Env steps.
    pub steps: Option<u64>,
    /// Actor processes.
    pub actors: Option<usize>,
    /// Worlds per actor.
    pub envs_per_actor: Option<usize>,
    /// Updates between checkpoints.
    pub checkpoint_every: Option<u64>,
    /// The run directory.
    pub out: Option<PathBuf>,
    /// More `train` flags: an arm's own ([`arm_flags`]), and an experiment's, as given.
    pub flags: Vec<String>,
}

impl NewRun {
    /// A run of `world` with train's defaults but for the steps and the directory.
    pub fn new(world: &str, steps: u64, out: &Path) -> NewRun {
        NewRun {
            world: world.to_string(),
            seed: None,
            steps: Some(steps),
            actors: None,
            envs_per_actor: None,
            checkpoint_every: None,
            out: Some(out.to_path_buf()),
            flags: Vec::new(),
        }
    }
}

/// One run, as `fulcrum train` takes it.
#[derive(Debug, Clone, PartialEq)]
pub enum TrainJob {
    /// Continue the run in this directory.
    Resume(PathBuf),
    /// A new run.
    New(NewRun),
}

/// `train ...`.
pub fn train(job: &TrainJob) -> Vec<String> {
    match job {
        TrainJob::Resume(dir) => vec!["train".into(), "--resume".into(), dir.display().to_string()],
        TrainJob::New(NewRun {
            world,
            seed,
            steps,
            actors,
            envs_per_actor,
            checkpoint_every,
            out,
            flags,
        }) => {
            let mut v = vec!["train".into(), world.clone()];
            let mut opt = |flag: &str, value: Option<String>| {
                if let Some(x) = value {
                    v.extend([flag.to_string(), x]);
                }
            };
            opt("--seed", seed.map(|s| s.to_string()));
            opt("--steps", steps.map(|s| s.to_string()));
            opt("--actors", actors.map(|s| s.to_string()));
            opt("--envs-per-actor", envs_per_actor.map(|s| s.to_string()));
            opt(
                "--checkpoint-every",
                checkpoint_every.map(|s| s.to_string()),
            );
            if let Some(o) = out {
                v.extend(["--out".into(), o.display().to_string()]);
            }
            v.extend(flags.iter().cloned());
            v
        }
    }
}

/// `experiment --worlds SET ...`: an experiment over a set of generated worlds.
#[derive(Debug, Clone, PartialEq)]
pub struct ExperimentWorlds {
    /// The set, as `--worlds` takes it (`gen:N[:params]`).
    pub worlds: String,
    /// Seeds per world.
    pub seeds: u64,
    /// The arms, by name ([`ARMS`]).
    pub arms: Vec<String>,
    /// Env steps per run.
    pub steps: u64,
    /// The experiment's directory.
    pub out: PathBuf,
}

/// `experiment --worlds ...`.
pub fn experiment_worlds(e: &ExperimentWorlds) -> Vec<String> {
    vec![
        "experiment".into(),
        "--worlds".into(),
        e.worlds.clone(),
        "--seeds".into(),
        e.seeds.to_string(),
        "--arms".into(),
        e.arms.join(","),
        "--steps".into(),
        e.steps.to_string(),
        "--out".into(),
        e.out.display().to_string(),
    ]
}

/// `serve WORLD --namespace NS`: a service of a world with its file's settings.
pub fn serve_world(world: &str, namespace: &str) -> Vec<String> {
    vec![
        "serve".into(),
        world.to_string(),
        "--namespace".into(),
        namespace.to_string(),
    ]
}

/// `__bench-client`: a process that looks states up at a service for a while.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchClient {
    /// The service's namespace.
    pub namespace: String,
    /// The world it serves.
    pub world: String,
    /// How long to ask, seconds.
    pub seconds: f64,
    /// States per request.
    pub batch: usize,
}

/// `__bench-client ...`.
pub fn bench_client(b: &BenchClient) -> Vec<String> {
    vec![
        "__bench-client".into(),
        "--namespace".into(),
        b.namespace.clone(),
        "--world".into(),
        b.world.clone(),
        "--seconds".into(),
        b.seconds.to_string(),
        "--batch".into(),
        b.batch.to_string(),
    ]
}

/// `__remote-peer --listen ADDR`: the far end of `bench --remote`.
pub fn remote_peer(listen: &str) -> Vec<String> {
    vec![
        "__remote-peer".into(),
        "--listen".into(),
        listen.to_string(),
    ]
}

/// `__pingpong PATH`: a datagram echo on a socket path.
pub fn pingpong(path: &Path) -> Vec<String> {
    vec!["__pingpong".into(), path.display().to_string()]
}

/// The `train` flags of an intrinsic form with the experiment's beta, if it sets one.
pub fn form_flags(form: &str, beta: Option<f64>) -> Vec<String> {
    let mut v = vec!["--intrinsic".to_string(), form.to_string()];
    if let Some(b) = beta {
        v.extend(["--beta".into(), b.to_string()]);
    }
    v
}

/// The arm names [`arm_flags`] knows.
pub const ARMS: &str = "baseline, empowerment, none, additive, additive-fixed, potential, horizon-potential, horizon-potential-deterministic, first-visit, count, paper, cleanrl, rllib, baseline-unmasked";

/// The `train` flags of an experiment's named arm: `form` is the `empowerment` arm's
/// form, `beta` the experiment's `--beta`. Every arm with an intrinsic reward names its
/// form, so that an arm means the same whatever train's default is. `None` for a name
/// that is not an arm.
pub fn arm_flags(name: &str, form: &str, beta: Option<f64>) -> Option<Vec<String>> {
    let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    Some(match name {
        "baseline" => s(&["--no-empowerment"]),
        "none" => s(&["--intrinsic", "none"]),
        "empowerment" => form_flags(form, beta),
        "additive" | "potential" | "count" | "horizon-potential" | "first-visit" => {
            form_flags(name, beta)
        }
        "baseline-unmasked" => s(&["--no-empowerment", "--no-action-mask"]),
        "paper" => s(&["--paper"]),
        "horizon-potential-deterministic" => {
            let mut v = form_flags("horizon-potential", beta);
            v.extend(s(&["--empowerment-model", "deterministic"]));
            v
        }
        "cleanrl" | "rllib" => s(&["--no-empowerment", "--ppo-preset", name]),
        "additive-fixed" => {
            let mut v = s(&["--horizon-mode", "fixed"]);
            v.extend(form_flags("additive", beta));
            v
        }
        _ => return None,
    })
}

/// The `train` flag of a view (an arm run once per view).
pub fn view_flags(view: &fulcrum_world::View) -> Vec<String> {
    vec!["--view".into(), view.to_string()]
}

/// The `train` flags that choose the intrinsic form: an experiment's stored arguments
/// that name none of them ran `train`'s default form of their day.
pub const FORM_FLAGS: [&str; 3] = ["--intrinsic", "--no-empowerment", "--paper"];

/// `train`'s arguments for the paper's additive bonus (the default form before
/// experiment files had a version).
pub fn additive_form() -> [String; 2] {
    ["--intrinsic".to_string(), "additive".to_string()]
}
