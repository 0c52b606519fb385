//! The one stop flag of a fulcrum process.
//!
//! SIGINT and SIGTERM raise it (after [`install`]), and so can the process itself
//! ([`request_stop`]); every loop of every process (supervisor, learner, actors,
//! service, bridge) polls it between phases and leaves cleanly, writing what it must
//! first. A process that waits on events rather than polling gets a byte on a pipe
//! ([`set_wake_fd`]) when a signal arrives.
//!
//! [`install`]: crate::stop::install
//! [`request_stop`]: crate::stop::request_stop
//! [`set_wake_fd`]: crate::stop::set_wake_fd
//!
//! The handler keeps any handler installed before it (iceoryx2 installs its own for the
//! service's wait set) and calls it after recording the signal: iceoryx2 keeps only the
//! last signal in one global that some of its calls reset, so a Ctrl-C seen only there
//! could be lost.

use std::sync::atomic::{AtomicBool, AtomicI32, AtomicUsize, Ordering};

/// Raised by SIGINT / SIGTERM or by [`request_stop`].
pub static STOP: AtomicBool = AtomicBool::new(false);
/// Which signal raised [`STOP`] (0 = none: the process raised it itself).
static SIGNAL: AtomicI32 = AtomicI32::new(0);
/// A descriptor the handler writes a byte to (-1 = none).
static WAKE_FD: AtomicI32 = AtomicI32::new(-1);
/// The handlers that were installed before ours, for SIGINT and SIGTERM (0 = none).
static PREVIOUS: [AtomicUsize; 2] = [AtomicUsize::new(0), AtomicUsize::new(0)];

/// Whether the stop flag is up.
pub fn stopping() -> bool {
    STOP.load(Ordering::SeqCst)
}

/// The signal that raised the flag: `SIGINT`, `SIGTERM`, or 0 (none, or raised from
/// within).
pub fn signal() -> i32 {
    SIGNAL.load(Ordering::SeqCst)
}

/// Whether a signal (rather than the process itself) raised the flag.
pub fn signalled() -> bool {
    signal() != 0
}

/// Raises the flag from within (any thread).
pub fn request_stop() {
    STOP.store(true, Ordering::SeqCst);
    wake();
}

/// Records `sig` as if it had been delivered (a signal that came before [`install`]).
pub fn record_signal(sig: i32) {
    SIGNAL.store(sig, Ordering::SeqCst);
    request_stop();
}

/// The descriptor a signal writes one byte to (non-blocking; -1 for none). Returns
/// the one it replaces.
pub fn set_wake_fd(fd: i32) -> i32 {
    WAKE_FD.swap(fd, Ordering::SeqCst)
}

fn wake() {
    let fd = WAKE_FD.load(Ordering::SeqCst);
    if fd >= 0 {
        // SAFETY: write(2) is async-signal-safe; a full pipe only drops the byte.
        unsafe {
            libc::write(fd, [1u8].as_ptr().cast(), 1);
        }
    }
}

extern "C" fn on_signal(sig: libc::c_int) {
    SIGNAL.store(sig, Ordering::SeqCst);
    STOP.store(true, Ordering::SeqCst);
    wake();
    let prev = PREVIOUS[usize::from(sig != libc::SIGINT)].load(Ordering::SeqCst);
    if prev != 0 {
        // SAFETY: a previous handler is a plain `fn(c_int)` handler (installed without
        // SA_SIGINFO, as iceoryx2's are); calling it is what the kernel would have done.
        let f: extern "C" fn(libc::c_int) = unsafe { std::mem::transmute(prev) };
        f(sig);
    }
}

/// SIGINT and SIGTERM raise the flag. Idempotent; when another handler was installed
/// since (or before), ours goes on top and calls it.
pub fn install() {
    let ours = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
    for (i, sig) in [libc::SIGINT, libc::SIGTERM].into_iter().enumerate() {
        // SAFETY: sigaction with zeroed structs we own, our handler and an empty mask.
        unsafe {
            let mut old: libc::sigaction = std::mem::zeroed();
            libc::sigaction(sig, std::ptr::null(), &mut old);
            if old.sa_sigaction == ours {
                continue;
            }
            let keep = old.sa_flags & libc::SA_SIGINFO == 0
                && old.sa_sigaction != libc::SIG_DFL
                && old.sa_sigaction != libc::SIG_IGN;
            PREVIOUS[i].store(if keep { old.sa_sigaction } else { 0 }, Ordering::SeqCst);
            let mut act: libc::sigaction = std::mem::zeroed();
            act.sa_sigaction = ours;
            act.sa_flags = libc::SA_RESTART;
            libc::sigemptyset(&mut act.sa_mask);
            libc::sigaction(sig, &act, std::ptr::null_mut());
        }
    }
}
