//! Training's figures: update speed, chunk transport, end-to-end steps per second and
//! the time to solve exp1-tree.

use std::time::Instant;

use anyhow::{ensure, Context, Result};
use fulcrum_run::argv::{self, NewRun, TrainJob};
use fulcrum_world::{load_world, View, World};

use super::{median_ms, Figure};

/// `steps` steps of `w` with `actions` (cycled), the observation in `view` kept up to
/// date: the seconds taken and the episodes finished.
fn world_steps(w: &World, view: View, actions: &[u8], steps: usize) -> Result<(f64, u64)> {
    let spec = view.spec(w);
    let (mut g, mut f) = (vec![0u8; spec.cells()], vec![0u8; spec.flags]);
    let mut ep = w.reset();
    view.observe(w, &ep.state, &mut g, &mut f);
    let mut done = 0u64;
    let t0 = Instant::now();
    for i in 0..steps {
        let prev = ep.state;
        let out = w.env_step(&mut ep, actions[i % actions.len()]);
        view.update(w, &prev, &ep.state, &mut g, &mut f);
        if out.terminated || out.truncated {
            done += 1;
            let last = ep.state;
            ep = w.reset();
            view.update(w, &last, &ep.state, &mut g, &mut f);
        }
    }
    let secs = t0.elapsed().as_secs_f64();
    ensure!(
        done > 0 && g.iter().any(|&x| x != 0),
        "the world did not run"
    );
    Ok((secs, done))
}

/// Training pieces: world steps per second on one core (with observation encoding) and
/// learner samples x epochs per second (one PPO update, CleanRL's defaults).
pub(super) fn training_figures(quick: bool, figs: &mut Vec<Figure>) -> Result<()> {
    use rand::{Rng, SeedableRng};
    let w = load_world("exp1-tree")?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let actions: Vec<u8> = (0..4096)
        .map(|_| rng.random_range(0..w.num_actions() as u8))
        .collect();
    let steps = if quick { 2_000_000 } else { 20_000_000 };
    let (secs, done) = world_steps(&w, View::Full, &actions, steps)?;
    figs.push(Figure {
        zero_ok: false,
        name: "world steps/s, one core, with observation".into(),
        value: steps as f64 / secs,
        unit: "steps/s",
        note: format!(
            "(exp1-tree, random actions, {done} episodes, incremental observation; goal >= 20M)"
        ),
    });
    let (secs, done) = world_steps(&w, View::Crop(4), &actions, steps)?;
    figs.push(Figure {
        zero_ok: false,
        name: "world steps/s, one core, with the crop:4 observation".into(),
        value: steps as f64 / secs,
        unit: "steps/s",
        note: format!(
            "(exp1-tree, the same actions, {done} episodes, the 9x9 window around the agent redrawn when it changes)"
        ),
    });
    // One PPO update on a batch of 1024 samples (8 envs x 128 steps).
    let shape = fulcrum_contracts::layout::shape_for(&w, View::Full, 64);
    let spec = w.obs_spec();
    let net = fulcrum_learner::net::Net::new(shape, 1, &candle_core::Device::Cpu)?;
    let mut adam = fulcrum_learner::adam::Adam::new(&net)?;
    let n = 1024;
    let mut glyphs = vec![0u8; n * spec.cells()];
    let mut flags = vec![0u8; n * spec.flags];
    let mut ep = w.reset();
    for i in 0..n {
        w.env_step(&mut ep, actions[i]);
        w.observe(
            &ep.state,
            &mut glyphs[i * spec.cells()..(i + 1) * spec.cells()],
            &mut flags[i * spec.flags..(i + 1) * spec.flags],
        );
    }
    let acts: Vec<u32> = actions[..n].iter().map(|&a| a as u32).collect();
    let lp = vec![-(w.num_actions() as f32).ln(); n];
    let vals = vec![0.0f32; n];
    let adv: Vec<f32> = (0..n)
        .map(|i| ((i * 37) % 11) as f32 / 10.0 - 0.5)
        .collect();
    let ret: Vec<f32> = adv.clone();
    let cfg = fulcrum_contracts::ppo_config::PpoConfig::default();
    let data = fulcrum_learner::local::UpdateData {
        glyphs: &glyphs,
        flags: &flags,
        actions: &acts,
        logprobs: &lp,
        values: &vals,
        advantages: &adv,
        returns: &ret,
        action_mask: false,
        int: None,
    };
    let reps = if quick { 3 } else { 11 };
    let (ms, stats) = median_ms(reps, || {
        Ok(fulcrum_learner::local::update(
            &net, &mut adam, &cfg, 2.5e-4, &mut rng, &data,
        )?)
    })?;
    ensure!(stats.value_loss.is_finite(), "the update diverged");
    figs.push(Figure {
        zero_ok: false,
        name: "learner samples x epochs/s".into(),
        value: (n * cfg.epochs) as f64 / (ms / 1e3),
        unit: "samples/s",
        note: format!("(PPO update: {n} samples, {} epochs x {} minibatches, hidden 64, exp1-tree obs; goal >= 200k)", cfg.epochs, cfg.minibatches),
    });
    Ok(())
}

/// Trajectory chunks through iceoryx2 shared memory, with the run's own service
/// builders: loan a chunk, write every byte of it (as an actor does), send it, receive
/// it on a second node and copy it out (as the learner does). One thread alternates
/// the two sides, so the figure is the cost of the path itself, not of waiting on a
/// full queue (a full queue makes a publisher back off, by design).
pub(super) fn chunk_transport(quick: bool, figs: &mut Vec<Figure>) -> Result<()> {
    use fulcrum_contracts::traj::{self, ChunkHeader, ChunkLayout, TrainNames};
    use iceoryx2::prelude::*;
    let w = load_world("exp1-tree")?;
    let spec = w.obs_spec();
    let node = || {
        NodeBuilder::new()
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
    };
    let (pn, sn) = (node()?, node()?);
    let mut notes = Vec::new();
    let mut best = 0.0f64;
    // The default chunk of `fulcrum train exp1-tree` (8 worlds x 128 steps), and a big one.
    for (envs, steps) in [(8usize, 128usize), (64, 128)] {
        let layout = ChunkLayout {
            envs,
            steps,
            cells: spec.cells(),
            flags: spec.flags,
        };
        let bytes = layout.bytes();
        let names = TrainNames::new(&format!("bench-chunks-{}-{envs}", std::process::id()));
        let psvc = traj::trajectory_service(&pn, &names).map_err(anyhow::Error::msg)?;
        let ssvc = traj::trajectory_service(&sn, &names).map_err(anyhow::Error::msg)?;
        let publisher = psvc
            .publisher_builder()
            .initial_max_slice_len(bytes)
            .max_loaned_samples(2)
            .create()?;
        let sub = ssvc.subscriber_builder().create()?;
        let mut buf: Vec<u8> = Vec::with_capacity(bytes);
        let mut one = |k: u64| -> Result<u8> {
            let mut s = publisher.loan_slice(bytes)?;
            let b: &mut [u8] = s.payload_mut();
            b.fill(k as u8);
            *s.user_header_mut() = ChunkHeader {
                seq: k,
                len: bytes as u64,
                ..ChunkHeader::default()
            };
            s.send()?;
            let r = sub.receive()?.context("a sent chunk did not arrive")?;
            buf.clear();
            buf.extend_from_slice(r.payload());
            Ok(buf[bytes / 2])
        };
        for k in 0..10 {
            one(k)?;
        }
        let target = if quick { 0.3 } else { 1.0 };
        let t0 = Instant::now();
        let mut k = 0u64;
        while t0.elapsed().as_secs_f64() < target {
            ensure!(one(k)? == k as u8, "a chunk arrived with other bytes");
            k += 1;
        }
        let gbs = k as f64 * bytes as f64 / t0.elapsed().as_secs_f64() / 1e9;
        if envs == 8 {
            best = gbs;
        }
        notes.push(format!("{} KiB: {gbs:.2} GB/s", bytes / 1024));
    }
    figs.push(Figure {
        zero_ok: false,
        name: "chunk transport".into(),
        value: best,
        unit: "GB/s",
        note: format!(
            "(exp1-tree chunks, loan + write every byte + send + receive + copy out; {})",
            notes.join(", ")
        ),
    });
    Ok(())
}

/// `fulcrum train ...` as the job says, no input, output to nowhere.
pub(super) fn train_command(job: &TrainJob) -> Result<std::process::Command> {
    let mut c = std::process::Command::new(std::env::current_exe()?);
    c.args(argv::train(job))
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null());
    Ok(c)
}

/// Runs the job (a new run in DIR, then removes DIR) and returns the env steps per
/// second of each update after the first (which pays for start-up), and the run's
/// resolved configuration.
pub(super) fn train_sps(
    job: &TrainJob,
) -> Result<(Vec<f64>, fulcrum_contracts::config::RunConfig)> {
    let TrainJob::New(NewRun { out: Some(dir), .. }) = job else {
        anyhow::bail!("a bench run needs a new run directory");
    };
    let dir = dir.as_path();
    let _ = std::fs::remove_dir_all(dir);
    let out = train_command(job)?
        .stderr(std::process::Stdio::piped())
        .output()?;
    ensure!(
        out.status.success(),
        "fulcrum {} failed: {}",
        argv::train(job).join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    let rows = fulcrum_learner::metrics::read_metrics(&dir.join("metrics.csv"))?;
    let cfg = fulcrum_contracts::config::RunConfig::load(&dir.join("config.toml"))?;
    let _ = std::fs::remove_dir_all(dir);
    let sps: Vec<f64> = rows.iter().skip(1).map(|r| r.sps).collect();
    ensure!(!sps.is_empty(), "the run made too few updates");
    Ok((sps, cfg))
}

/// End-to-end `fulcrum train exp1-tree` with empowerment: env steps per second of the
/// learner's updates (median over updates after the first), defaults for this machine;
/// and the same on exp1-tree-slip (its outcomes drawn by the actors, its table the
/// capacities of the noisy channel), the two worlds' runs alternating so that both see
/// the same machine.
pub(super) fn end_to_end(quick: bool, figs: &mut Vec<Figure>) -> Result<()> {
    let dir = std::env::temp_dir().join(format!("fulcrum-bench-train-{}", std::process::id()));
    // Whole updates of this machine's default batch (actors = cores - 1, 8 worlds, 128 steps).
    let batch = (fulcrum_run::process::cores().saturating_sub(1).max(1) * 8 * 128) as u64;
    let steps = if quick { 16 } else { 100 } * batch;
    let pairs = if quick { 1 } else { 3 };
    let (mut plain, mut noisy) = (Vec::new(), Vec::new());
    let mut cfg = None;
    for _ in 0..pairs {
        let (sps, c) = train_sps(&TrainJob::New(NewRun::new("exp1-tree", steps, &dir)))?;
        plain.extend(sps);
        cfg = Some(c);
        noisy.extend(train_sps(&TrainJob::New(NewRun::new("exp1-tree-slip", steps, &dir)))?.0);
    }
    let cfg = cfg.context("no run")?;
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (p, n) = (median(&mut plain), median(&mut noisy));
    figs.push(Figure {
        zero_ok: false,
        name: "end-to-end training env steps/s".into(),
        value: p,
        unit: "steps/s",
        note: format!(
            "(train exp1-tree, beta {}, {} actor(s) x {} worlds, {} learner thread(s), median of {} updates; goal >= 50k)",
            cfg.beta,
            cfg.actors,
            cfg.envs_per_actor,
            cfg.learner_threads,
            plain.len()
        ),
    });
    figs.push(Figure {
        zero_ok: false,
        name: "end-to-end training env steps/s, exp1-tree-slip".into(),
        value: n,
        unit: "steps/s",
        note: format!(
            "(train exp1-tree-slip, the same settings, median of {} updates; {:.2} of exp1-tree's, goal >= 0.90)",
            noisy.len(),
            n / p
        ),
    });
    Ok(())
}

/// End-to-end `fulcrum train toolbox` (horizon-potential, this machine's defaults) with a
/// fresh layout every episode (`--layouts all`: the service makes each layout's table on
/// first sight) against the same run on one fixed layout (`--layouts 1`: its table made
/// before the run starts), the two alternating: median env steps per second of the
/// updates after the first, and their ratio.
pub(super) fn family_end_to_end(quick: bool, figs: &mut Vec<Figure>) -> Result<()> {
    let dir = std::env::temp_dir().join(format!("fulcrum-bench-family-{}", std::process::id()));
    let batch = (fulcrum_run::process::cores().saturating_sub(1).max(1) * 8 * 128) as u64;
    let steps = if quick { 16 } else { 100 } * batch;
    let pairs = if quick { 1 } else { 3 };
    let job = |layouts: &str| {
        let mut run = NewRun::new("toolbox", steps, &dir);
        run.flags = vec!["--layouts".into(), layouts.into()];
        TrainJob::New(run)
    };
    let (mut fixed, mut fresh) = (Vec::new(), Vec::new());
    for _ in 0..pairs {
        fixed.extend(train_sps(&job("1"))?.0);
        fresh.extend(train_sps(&job("all"))?.0);
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (a, b) = (median(&mut fixed), median(&mut fresh));
    figs.push(Figure {
        zero_ok: false,
        name: "end-to-end training env steps/s, toolbox, one layout".into(),
        value: a,
        unit: "steps/s",
        note: format!(
            "(train toolbox --layouts 1, horizon-potential, median of {} updates)",
            fixed.len()
        ),
    });
    figs.push(Figure {
        zero_ok: false,
        name: "end-to-end training env steps/s, toolbox, a fresh layout each episode".into(),
        value: b,
        unit: "steps/s",
        note: format!(
            "(train toolbox --layouts all, the same settings, median of {} updates; {:.2} of one layout's, goal >= 0.70)",
            fresh.len(),
            b / a
        ),
    });
    Ok(())
}

/// Seconds from `fulcrum train exp1-tree` being started to the first update at which the
/// success rate, pooled over 10 updates as `fulcrum experiment` pools it, reaches 0.9;
/// and the env steps by then. The run is then stopped (SIGINT, as a user would). `None`
/// when the budget ends first.
pub(super) fn solve_once(job: &TrainJob) -> Result<Option<(f64, f64)>> {
    use fulcrum_run::stats::{smooth, steps_to, Point};
    let TrainJob::New(NewRun { out: Some(dir), .. }) = job else {
        anyhow::bail!("a bench run needs a new run directory");
    };
    let dir = dir.as_path();
    let _ = std::fs::remove_dir_all(dir);
    let t0 = Instant::now();
    let mut child = train_command(job)?
        .stderr(std::process::Stdio::null())
        .spawn()?;
    let metrics = dir.join("metrics.csv");
    let solved = loop {
        let done = child.try_wait()?;
        let rows = fulcrum_learner::metrics::read_metrics(&metrics).unwrap_or_default();
        let pts: Vec<Point> = rows.iter().map(Point::from).collect();
        if let Some(steps) = steps_to(&smooth(&pts, 10), 0.9) {
            break Some((t0.elapsed().as_secs_f64(), steps));
        }
        if let Some(status) = done {
            ensure!(
                status.success(),
                "fulcrum {} failed",
                argv::train(job).join(" ")
            );
            break None;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    };
    // SAFETY: kill(2) on our own child's pid.
    unsafe {
        libc::kill(child.id() as libc::pid_t, libc::SIGINT);
    }
    child.wait()?;
    let _ = std::fs::remove_dir_all(dir);
    Ok(solved)
}

/// Time to solve exp1-tree with train's defaults (horizon-potential shaping, masking
/// on) and one actor of 8 worlds (so that the batch, and with it the env steps to
/// solve, is the same on every machine), five seeds: median wall seconds and env steps
/// to a success rate of 0.9. A seed that does not get there within the budget counts at
/// the budget.
pub(super) fn time_to_solve(figs: &mut Vec<Figure>) -> Result<()> {
    let dir = std::env::temp_dir().join(format!("fulcrum-bench-solve-{}", std::process::id()));
    let budget = 499_712u64;
    let batch = 8 * 128u64;
    let steps = budget.div_ceil(batch) * batch;
    let (mut secs, mut env) = (Vec::new(), Vec::new());
    let mut solved = 0;
    for seed in 1..=5 {
        let t0 = Instant::now();
        let job = TrainJob::New(NewRun {
            seed: Some(seed),
            actors: Some(1),
            ..NewRun::new("exp1-tree", steps, &dir)
        });
        match solve_once(&job)? {
            Some((s, e)) => {
                solved += 1;
                secs.push(s);
                env.push(e);
            }
            None => {
                secs.push(t0.elapsed().as_secs_f64());
                env.push(budget as f64);
            }
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let list =
        |v: &[f64], f: fn(f64) -> String| v.iter().map(|&x| f(x)).collect::<Vec<_>>().join(" ");
    let note = format!(
        "(train exp1-tree defaults, one actor, seeds 1-5, {solved}/5 solved; sorted: {} s, {} steps; goal <= 10 s)",
        list(&{ let mut v = secs.clone(); v.sort_by(f64::total_cmp); v }, |x| format!("{x:.1}")),
        list(&{ let mut v = env.clone(); v.sort_by(f64::total_cmp); v }, |x| format!("{:.0}k", x / 1e3)),
    );
    figs.push(Figure {
        zero_ok: false,
        name: "exp1-tree time to 0.9 success, wall clock".into(),
        value: median(&mut secs),
        unit: "s",
        note: note.clone(),
    });
    figs.push(Figure {
        zero_ok: false,
        name: "exp1-tree env steps to 0.9 success".into(),
        value: median(&mut env),
        unit: "steps",
        note: "(the same runs: steps of the first update whose success, pooled over 10 updates, reached 0.9)".into(),
    });
    Ok(())
}

/// The set of generated worlds the robustness figure trains on (RESULTS.md, "Worlds
/// nobody wrote", with its first seed only) and its budget, within 1M env steps.
pub(super) const ROBUST_SET: &str = "gen:20";
/// The budget of each run: 976 updates of 1024 steps (244 of RLlib's 4096).
pub(super) const ROBUST_STEPS: u64 = 999_424;

/// Share of generated worlds train's defaults solve: `fulcrum experiment --worlds
/// gen:20 --seeds 1 --arms horizon-potential` (the default form named, so the figure
/// keeps its meaning), each run one actor of 8 worlds within 999,424 env steps; a world
/// counts as solved when its success rate, pooled over 10 updates, reaches 0.9.
pub(super) fn robustness(figs: &mut Vec<Figure>) -> Result<()> {
    let dir = std::env::temp_dir().join(format!("fulcrum-bench-robust-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let t0 = Instant::now();
    let status = std::process::Command::new(std::env::current_exe()?)
        .args(argv::experiment_worlds(&argv::ExperimentWorlds {
            worlds: ROBUST_SET.into(),
            seeds: 1,
            arms: vec!["horizon-potential".into()],
            steps: ROBUST_STEPS,
            out: dir.clone(),
        }))
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()?;
    ensure!(status.success(), "the robustness experiment failed");
    let secs = t0.elapsed().as_secs_f64();
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json"))?)?;
    let arm = &summary["arms"][0];
    let (solved, pairs) = (
        arm["solved"].as_u64().unwrap_or(0),
        arm["pairs"].as_u64().unwrap_or(0),
    );
    let trapped = arm["trapped"].as_u64().unwrap_or(0);
    let _ = std::fs::remove_dir_all(&dir);
    figs.push(Figure {
        zero_ok: true,
        name: "generated worlds solved by train's defaults".into(),
        value: solved as f64 / pairs.max(1) as f64,
        unit: "share",
        note: format!(
            "({solved}/{pairs}: experiment --worlds {ROBUST_SET} --seeds 1 --arms horizon-potential --steps {ROBUST_STEPS}; {trapped} marked as trapped; {secs:.0} s)"
        ),
    });
    Ok(())
}
