//! The service's stop flag: SIGINT and SIGTERM, and [`request_stop`] from within.
//!
//! iceoryx2 keeps only the last signal in one global that some of its calls reset (its
//! `call_and_fetch` around shared-memory writes), and a signal delivered to another
//! thread does not interrupt the wait-set's epoll: either way a Ctrl-C could be lost
//! and the service would never stop. So our own handler records the signal in a flag
//! of ours, then calls iceoryx2's; the serving loop checks the flag every 100 ms.

use std::sync::atomic::{AtomicI32, Ordering};
use std::sync::OnceLock;

/// The termination signal the service saw (0 = none), set by [`chain_signal`].
static STOP_SIGNAL: AtomicI32 = AtomicI32::new(0);
/// The handlers iceoryx2 installed for SIGINT and SIGTERM, called after ours.
static PREVIOUS: OnceLock<[libc::sigaction; 2]> = OnceLock::new();

/// Make a running [`serve`](super::serve) / [`serve_with`](super::serve_with) return as
/// if it got SIGTERM (within 100 ms), from any thread.
pub fn request_stop() {
    STOP_SIGNAL.store(libc::SIGTERM, Ordering::SeqCst);
}

/// Whether SIGINT or SIGTERM reached a process that serves (or [`request_stop`] was
/// called).
pub fn stop_requested() -> bool {
    stop_signal() != 0
}

/// The termination signal seen so far: `SIGINT`, `SIGTERM`, or 0 for none.
pub(super) fn stop_signal() -> i32 {
    STOP_SIGNAL.load(Ordering::SeqCst)
}

extern "C" fn chain_signal(sig: libc::c_int) {
    STOP_SIGNAL.store(sig, Ordering::SeqCst);
    if let Some(prev) = PREVIOUS.get() {
        let p = &prev[usize::from(sig != libc::SIGINT)];
        if p.sa_sigaction != libc::SIG_DFL && p.sa_sigaction != libc::SIG_IGN {
            // SAFETY: the previous handler is iceoryx2's plain `fn(c_int)` handler, installed
            // without SA_SIGINFO; calling it from a handler is what the kernel would do.
            let f: extern "C" fn(libc::c_int) = unsafe { std::mem::transmute(p.sa_sigaction) };
            f(sig);
        }
    }
}

/// Records SIGINT and SIGTERM in our own flag as well as in iceoryx2's (see the
/// module's documentation for why).
pub(super) fn chain_termination_signals() {
    // iceoryx2 installs its handlers the first time its SignalHandler is used: make that
    // happen now, so that ours goes on top (and keep a signal that came before).
    use iceoryx2_bb_posix::signal::{NonFatalFetchableSignal, SignalHandler};
    match SignalHandler::last_signal() {
        Some(NonFatalFetchableSignal::Interrupt) => {
            STOP_SIGNAL.store(libc::SIGINT, Ordering::SeqCst)
        }
        Some(NonFatalFetchableSignal::Terminate) => {
            STOP_SIGNAL.store(libc::SIGTERM, Ordering::SeqCst)
        }
        _ => {}
    }
    PREVIOUS.get_or_init(|| {
        // SAFETY: sigaction with a zeroed struct, our handler and an empty mask; the old
        // actions are read into zeroed structs we own.
        unsafe {
            let mut old: [libc::sigaction; 2] = std::mem::zeroed();
            for (i, sig) in [libc::SIGINT, libc::SIGTERM].into_iter().enumerate() {
                let mut act: libc::sigaction = std::mem::zeroed();
                act.sa_sigaction = chain_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
                act.sa_flags = libc::SA_RESTART;
                libc::sigemptyset(&mut act.sa_mask);
                libc::sigaction(sig, &act, &mut old[i]);
            }
            old
        }
    });
}
