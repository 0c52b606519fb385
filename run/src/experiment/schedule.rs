//! Running the pairs: `parallel` `fulcrum train` processes at a time, each pinned to
//! its share of the cores, interrupted together, their progress in one bar.

use std::io::{Read, Seek, SeekFrom};
use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use crate::error::{bad, Context, Result};
use fulcrum_learner::paths::RunPaths;

use super::{state, train_args, Job, Spec, State};
use crate::error::Interrupted;
use crate::lock::DirLock;
use crate::process::{install_signal_handlers, stopping};
use crate::progress::Progress;

/// Runs the pairs in `todo`, `parallel` at a time; returns the names of failed pairs.
pub(super) fn schedule(
    spec: &Spec,
    jobs: &[Job],
    todo: &[&Job],
    cpus: &[usize],
    parallel: usize,
    share: usize,
) -> Result<Vec<String>> {
    install_signal_handlers();
    let exe = std::env::current_exe().context("cannot find the fulcrum executable")?;
    let total = jobs.len() as u64 * spec.steps;
    let mut progress = Progress::new(
        "fulcrum experiment",
        total,
        "{elapsed_precise} [{bar:30}] {percent:>3}% env steps  {msg}  eta {eta}",
        Duration::from_secs(10),
    )
    .clear_when_finished();
    let mut queue: std::collections::VecDeque<&Job> = todo.iter().copied().collect();
    let mut running: Vec<(usize, &Job, Child)> = Vec::new(); // (slot, job, child)
    let mut failed = Vec::new();
    let mut finished_steps: u64 = (jobs.len() - todo.len()) as u64 * spec.steps;
    let name = |j: &Job| format!("{}/seed-{}", spec.arms[j.arm].name, j.seed);
    loop {
        let interrupted = stopping();
        // Start runs in free slots.
        while !interrupted && running.len() < parallel {
            let Some(job) = queue.pop_front() else { break };
            let slot = (0..parallel)
                .find(|s| !running.iter().any(|(r, _, _)| r == s))
                .unwrap_or(0);
            let set: Vec<usize> = cpus
                .iter()
                .copied()
                .cycle()
                .skip(slot * share)
                .take(share)
                .collect();
            let st = state(&job.dir, spec.steps);
            if st == State::Fresh && job.dir.exists() {
                // A run that never wrote a checkpoint has nothing to continue from;
                // cleared under its lock, never while another invocation holds it.
                if let Err(e) = clear_fresh(job) {
                    progress.note(&format!("{} not started: {e}", name(job)));
                    failed.push(name(job));
                    continue;
                }
            }
            let mut cmd = train_command(&exe, spec, job, st == State::Partial)?;
            cmd.process_group(0);
            let parent = std::process::id();
            // SAFETY: only async-signal-safe calls (sched_setaffinity, prctl, getppid,
            // _exit-free checks) between fork and exec.
            unsafe {
                cmd.pre_exec(move || {
                    let mut mask: libc::cpu_set_t = std::mem::zeroed();
                    for &c in &set {
                        libc::CPU_SET(c, &mut mask);
                    }
                    libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mask);
                    libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM);
                    if libc::getppid() as u32 != parent {
                        libc::raise(libc::SIGTERM);
                    }
                    Ok(())
                });
            }
            let child = cmd
                .spawn()
                .with_context(|| format!("cannot start the run {}", name(job)))?;
            progress.note(&format!(
                "{} {} (log {})",
                if st == State::Partial {
                    "resuming"
                } else {
                    "starting"
                },
                name(job),
                job.log.display()
            ));
            running.push((slot, job, child));
        }
        if interrupted {
            for (_, _, c) in &running {
                // SAFETY: kill(2) on our own child's pid.
                unsafe {
                    libc::kill(c.id() as libc::pid_t, libc::SIGINT);
                }
            }
        }
        // Reap.
        let mut i = 0;
        while i < running.len() {
            match running[i].2.try_wait() {
                Ok(Some(status)) => {
                    let (_, job, _) = running.swap_remove(i);
                    if status.success() && state(&job.dir, spec.steps) == State::Done {
                        finished_steps += spec.steps;
                        progress.note(&format!("finished {}", name(job)));
                    } else if !interrupted {
                        progress.note(&format!(
                            "{} failed ({status}); see {}",
                            name(job),
                            job.log.display()
                        ));
                        failed.push(name(job));
                    }
                }
                Ok(None) => i += 1,
                Err(e) => return Ok(Err(e).context("cannot wait for a run")?),
            }
        }
        let live: u64 = running
            .iter()
            .map(|(_, j, _)| last_steps(&j.dir).min(spec.steps))
            .sum();
        let pos = finished_steps + live;
        let done = jobs.len() - todo.len() + (todo.len() - queue.len() - running.len());
        let share = 100.0 * pos as f64 / progress.total().max(1) as f64;
        progress.set(pos, format!("{done}/{} runs done", jobs.len()), |m| {
            format!("{share:.0}% of env steps, {m}")
        });
        if running.is_empty() && (queue.is_empty() || interrupted) {
            break;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    progress.finish();
    if stopping() {
        return Err(Interrupted(
            "experiment interrupted; every run kept its checkpoint: run the same command again to resume"
                .into(),
        )
        .into());
    }
    Ok(failed)
}

/// The `train` command of a pair (new, or resuming from its checkpoint), its output
/// appended to the pair's log; the run's parent and log directories made.
pub(super) fn train_command(exe: &Path, spec: &Spec, job: &Job, resume: bool) -> Result<Command> {
    for d in [job.dir.parent(), job.log.parent()].into_iter().flatten() {
        std::fs::create_dir_all(d).with_context(|| format!("cannot create {}", d.display()))?;
    }
    let log = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&job.log)
        .with_context(|| format!("cannot open {}", job.log.display()))?;
    let mut cmd = Command::new(exe);
    cmd.args(train_args(spec, &spec.arms[job.arm], job, resume))
        .stdin(Stdio::null())
        .stdout(log.try_clone().context("cannot share the log file")?)
        .stderr(log);
    Ok(cmd)
}

/// Env steps of a run's last metrics row (reads only the file's tail).
pub(super) fn last_steps(dir: &Path) -> u64 {
    let path = RunPaths {
        dir: dir.to_path_buf(),
    }
    .metrics();
    let Ok(mut f) = std::fs::File::open(&path) else {
        return 0;
    };
    let len = f.metadata().map(|m| m.len()).unwrap_or(0);
    let _ = f.seek(SeekFrom::Start(len.saturating_sub(2048)));
    let mut tail = String::new();
    let _ = f.read_to_string(&mut tail);
    tail.lines()
        .rev()
        .filter_map(fulcrum_learner::metrics::MetricsRow::parse)
        .map(|r| r.env_steps)
        .next()
        .unwrap_or(0)
}

/// A pair that never wrote a checkpoint cleared (under its lock) so that it starts over.
pub(super) fn clear_fresh(j: &Job) -> Result<()> {
    match DirLock::acquire(&j.dir) {
        Ok(_held) => Ok(std::fs::remove_dir_all(&j.dir)
            .with_context(|| format!("cannot clear {}", j.dir.display()))?),
        Err(e) => bad(e.to_string()),
    }
}
