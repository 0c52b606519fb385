//! One process toolkit for the supervisor, its children and the helpers around them:
//! the stop flag that SIGINT/SIGTERM raise, dying with the parent, starting a child and
//! waiting for its `ready` line, stopping children, and the machine's cores.
//!
//! Every fulcrum process has exactly one stop flag, [`STOP`] (`fulcrum_contracts::stop`):
//! signal handlers raise it, loops poll it between phases and leave cleanly (writing
//! what they must first).

use std::io::{BufRead, BufReader};
use std::os::unix::process::ExitStatusExt;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use crate::error::{Context, Result};
use crossbeam_channel::{after, never, select, Receiver, Sender};
use fulcrum_contracts::lines::ChildLine;

pub use fulcrum_contracts::stop::{request_stop, signalled, stopping, STOP};

/// A channel that receives one message when a signal raises the stop flag (and at
/// once if it is already up): the stop flag as an event a `select!` can wait on.
///
/// The signal handler writes a byte to a pipe (async-signal-safe); a thread turns it
/// into a message.
pub fn stop_events() -> Result<Receiver<()>> {
    let (tx, rx) = crossbeam_channel::bounded(1);
    if stopping() {
        let _ = tx.try_send(());
        return Ok(rx);
    }
    let mut fds = [0 as libc::c_int; 2];
    // SAFETY: pipe2 fills the two descriptors we own.
    if unsafe { libc::pipe2(fds.as_mut_ptr(), libc::O_CLOEXEC | libc::O_NONBLOCK) } != 0 {
        return Ok(Err(std::io::Error::last_os_error()).context("cannot create the stop pipe")?);
    }
    let (read, write) = (fds[0], fds[1]);
    // The read end blocks; the write end stays non-blocking for the handler.
    // SAFETY: fcntl on our own descriptor.
    unsafe {
        libc::fcntl(read, libc::F_SETFL, 0);
    }
    let old = fulcrum_contracts::stop::set_wake_fd(write);
    if old >= 0 {
        // SAFETY: the previous write end is ours and no longer published.
        unsafe {
            libc::close(old);
        }
    }
    std::thread::spawn(move || {
        let mut b = [0u8; 1];
        // SAFETY: read(2) into our buffer from our descriptor.
        while unsafe { libc::read(read, b.as_mut_ptr().cast(), 1) } < 0 {}
        let _ = tx.try_send(());
    });
    if stopping() {
        // Raised before the pipe was published: wake the thread ourselves.
        // SAFETY: write(2) to our own descriptor.
        unsafe {
            libc::write(write, [1u8].as_ptr().cast(), 1);
        }
    }
    Ok(rx)
}

/// Sends `message` on `tx` when `child` has exited, from a thread of its own (the child
/// is not reaped: `try_wait` still gives its status).
pub fn send_on_exit<T: Send + 'static>(child: &Child, tx: Sender<T>, message: T) {
    let pid = child.id() as libc::id_t;
    std::thread::spawn(move || {
        loop {
            // SAFETY: waitid fills the zeroed siginfo we own; WNOWAIT leaves the
            // child to be reaped by its owner.
            let r = unsafe {
                let mut info: libc::siginfo_t = std::mem::zeroed();
                libc::waitid(libc::P_PID, pid, &mut info, libc::WEXITED | libc::WNOWAIT)
            };
            if r == 0 || std::io::Error::last_os_error().raw_os_error() != Some(libc::EINTR) {
                break;
            }
        }
        let _ = tx.send(message);
    });
}

/// SIGINT and SIGTERM raise [`STOP`].
pub fn install_signal_handlers() {
    fulcrum_contracts::stop::install();
}

/// A child: stop when the process `parent` dies (and if it already has, stop now).
pub fn die_with_parent(parent: u32) {
    // SAFETY: prctl with PR_SET_PDEATHSIG takes a signal number; getppid is always safe.
    unsafe {
        libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM);
        if libc::getppid() as u32 != parent {
            request_stop();
        }
    }
}

/// Cores this machine offers (at least 1).
pub fn cores() -> usize {
    std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
}

/// The CPUs this process may run on (its affinity set).
pub fn allowed_cpus() -> Vec<usize> {
    // SAFETY: sched_getaffinity fills the zeroed set we own.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        if libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set) != 0 {
            return (0..cores()).collect();
        }
        (0..libc::CPU_SETSIZE as usize)
            .filter(|&c| libc::CPU_ISSET(c, &set))
            .collect()
    }
}

pub use fulcrum_contracts::host::hostname;

/// `YYYYmmdd-HHMMSS` in UTC, without a date crate: run and experiment names.
pub fn utc_stamp() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    let (days, rem) = (secs / 86_400, secs % 86_400);
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + (m <= 2) as i64;
    format!(
        "{y:04}{m:02}{d:02}-{:02}{:02}{:02}",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

/// A child's exit status in words: `exit code 1`, `signal 9`.
pub fn describe_status(s: ExitStatus) -> String {
    match (s.code(), s.signal()) {
        (Some(c), _) => format!("exit code {c}"),
        (None, Some(sig)) => format!("signal {sig}"),
        _ => "unknown status".into(),
    }
}

/// How a child ended, if it has (`None` also when there is none).
pub fn exited(child: &mut Option<Child>) -> std::io::Result<Option<ExitStatus>> {
    child
        .as_mut()
        .map(|c| c.try_wait())
        .transpose()
        .map(Option::flatten)
}

/// Sends `sig` to a child.
pub fn signal(c: &Child, sig: libc::c_int) {
    // SAFETY: kill(2) on our own child's pid.
    unsafe {
        libc::kill(c.id() as libc::pid_t, sig);
    }
}

/// SIGTERM to every child, then SIGKILL to those still running after 4 s; all reaped.
pub fn stop_children(mut all: Vec<Child>) {
    for c in &all {
        signal(c, libc::SIGTERM);
    }
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(4) {
        if all.iter_mut().all(|c| matches!(c.try_wait(), Ok(Some(_)))) {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    for c in &mut all {
        if !matches!(c.try_wait(), Ok(Some(_))) {
            let _ = c.kill();
        }
        let _ = c.wait();
    }
}

/// The lines a child writes to its stdout (which must be piped), as a channel that
/// closes when the child closes its stdout. Dropping the receiver is fine: the lines
/// are still read (and dropped), so the child never blocks on a full pipe.
pub fn lines(child: &mut Child) -> Result<Receiver<String>> {
    let out = child
        .stdout
        .take()
        .context("the child's stdout is not piped")?;
    let (tx, rx) = crossbeam_channel::unbounded();
    std::thread::spawn(move || {
        // Read to the end even when nobody listens any more: a child must never block
        // on a full pipe.
        for line in BufReader::new(out).lines().map_while(|l| l.ok()) {
            let _ = tx.send(line);
        }
    });
    Ok(rx)
}

/// How [`spawn_until`] ended.
#[derive(Debug)]
pub enum Ready<T> {
    /// The child printed the line it was waited for, read as `T`, and runs on; its
    /// later lines follow in the receiver.
    Ready(Child, T, Receiver<String>),
    /// The stop flag was raised first: the child was killed.
    Stopped,
    /// The child exited before it was ready.
    Exited(ExitStatus),
}

/// Starts `cmd` with its stdout piped and waits until the child prints a line of the
/// child protocol that says it is ready ([`ChildLine::is_ready`]); see [`spawn_until`].
pub fn spawn_until_ready(
    cmd: Command,
    what: &str,
    deadline: Option<Duration>,
) -> Result<Ready<()>> {
    spawn_until(cmd, what, deadline, |l| {
        ChildLine::says_ready(l).then_some(())
    })
}

/// Starts `cmd` with its stdout piped and waits until the child prints a line that
/// `ready` reads as a `T`, exits, the stop flag is raised, or `deadline` passes (an
/// error naming `what`; the child is killed).
pub fn spawn_until<T>(
    mut cmd: Command,
    what: &str,
    deadline: Option<Duration>,
    mut ready: impl FnMut(&str) -> Option<T>,
) -> Result<Ready<T>> {
    cmd.stdout(Stdio::piped());
    let mut child = cmd
        .spawn()
        .with_context(|| format!("cannot start {what}"))?;
    let rx = lines(&mut child)?;
    let t0 = Instant::now();
    let timeout = deadline.map(after).unwrap_or_else(never);
    loop {
        // The child's exit and the stop flag have no channel here: look every 50 ms.
        select! {
            recv(rx) -> line => match line {
                Ok(l) => {
                    if let Some(t) = ready(&l) {
                        return Ok(Ready::Ready(child, t, rx));
                    }
                }
                Err(_) => {
                    // stdout closed: the child is exiting.
                    let s = child.wait().with_context(|| format!("cannot wait for {what}"))?;
                    return Ok(Ready::Exited(s));
                }
            },
            recv(timeout) -> _ => {
                let _ = child.kill();
                let _ = child.wait();
                crate::fail!(
                    "{what} was not ready after {:.0} s",
                    t0.elapsed().as_secs_f64()
                );
            },
            default(Duration::from_millis(50)) => {}
        }
        if let Some(s) = child.try_wait()? {
            return Ok(Ready::Exited(s));
        }
        if stopping() {
            let _ = child.kill();
            let _ = child.wait();
            return Ok(Ready::Stopped);
        }
    }
}
