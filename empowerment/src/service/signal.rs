//! The service's stop flag is the process's one flag, [`fulcrum_contracts::stop`]:
//! SIGINT and SIGTERM, and [`request_stop`] from within.
//!
//! iceoryx2 installs its own SIGINT/SIGTERM handlers for its wait set and keeps only the
//! last signal in one global that some of its calls reset (its `call_and_fetch` around
//! shared-memory writes); a signal delivered to another thread does not interrupt the
//! wait set's epoll either. So our handler goes on top of iceoryx2's, records the signal
//! in our flag and then calls iceoryx2's; the serving loop checks the flag every 100 ms.

use fulcrum_contracts::stop;
pub use fulcrum_contracts::stop::request_stop;

/// Whether SIGINT or SIGTERM reached a process that serves (or [`request_stop`] was
/// called).
pub fn stop_requested() -> bool {
    stop::stopping()
}

/// The termination signal seen so far: `SIGINT`, `SIGTERM` (also for a stop requested
/// from within), or 0 for none.
pub(super) fn stop_signal() -> i32 {
    match stop::signal() {
        0 if stop::stopping() => libc::SIGTERM,
        s => s,
    }
}

/// Records SIGINT and SIGTERM in the process's flag as well as in iceoryx2's (see the
/// module's documentation for why).
pub(super) fn chain_termination_signals() {
    // iceoryx2 installs its handlers the first time its SignalHandler is used: make that
    // happen now, so that ours goes on top (and keep a signal that came before).
    use iceoryx2_bb_posix::signal::{NonFatalFetchableSignal, SignalHandler};
    match SignalHandler::last_signal() {
        Some(NonFatalFetchableSignal::Interrupt) => stop::record_signal(libc::SIGINT),
        Some(NonFatalFetchableSignal::Terminate) => stop::record_signal(libc::SIGTERM),
        _ => {}
    }
    stop::install();
}
