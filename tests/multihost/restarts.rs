//! An actor host restarts its crashed actors as the supervisor restarts its children:
//! after a back-off, within a budget of restarts in a window per actor.

use std::time::Duration;

use super::{host_rows, loopback};
use crate::util::{pids_with, signal, wait_until};

#[test]
fn an_actor_host_restarts_after_back_offs_and_stops_over_its_budget() {
    let mut lb = loopback(
        "host-budget",
        "room --actors 1 --steps 99999872 --stall-timeout 2",
    );
    let mut host = lb.host("far", "--actors 1 --max-restarts 2 --restart-window 60");
    let far_chunks = || {
        host_rows(&lb.dir)
            .iter()
            .filter(|r| r.host == 1)
            .map(|r| r.chunks)
            .sum::<u64>()
    };
    wait_until(Duration::from_secs(60), "the far host joining", || {
        far_chunks() > 2
    });
    let far_s = lb.far.display().to_string();
    // Three quick kills of the far actor: two restarts allowed in 60 s, the third
    // stop is over the budget.
    for kill in 1..=3 {
        let victims = pids_with(&["__actor", &far_s]);
        assert_eq!(victims.len(), 1, "one far actor before kill {kill}");
        signal(victims[0], "-KILL");
        if kill < 3 {
            wait_until(Duration::from_secs(20), "the far actor replaced", || {
                let now = pids_with(&["__actor", &far_s]);
                !now.is_empty() && now != victims
            });
        }
    }
    let status = host.finish(Duration::from_secs(30));
    let text = host.text();
    assert_eq!(status.code(), Some(1), "{text}");
    assert!(
        text.contains("restarting it after 0.1 s (restart 1 of 2 allowed in 60 s)"),
        "{text}"
    );
    assert!(
        text.contains("restarting it after 0.2 s (restart 2 of 2 allowed in 60 s)"),
        "{text}"
    );
    assert!(
        text.contains("its stop number 3 within 60 s: over its budget of 2 restarts in 60 s"),
        "{text}"
    );
    // The host took its actor and bridge with it; the learner goes on without it.
    wait_until(Duration::from_secs(10), "the host's processes gone", || {
        pids_with(&[&far_s]).is_empty()
    });
    signal(lb.learner.child.id(), "-INT");
    assert_eq!(
        lb.learner.finish(Duration::from_secs(60)).code(),
        Some(130),
        "{}",
        lb.learner.text()
    );
}
