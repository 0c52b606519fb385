//! New weights from the learner: the newest version of this run and world, into the
//! actor's policy.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use fulcrum_contracts::traj::WeightsSubscriber;
use iceoryx2::port::listener::Listener;
use iceoryx2::prelude::*;

use crate::error::ActorError;
use crate::policy::Policy;
use fulcrum_contracts::IpcError;

/// Where new weights come from.
pub(crate) struct WeightsIn {
    pub(crate) sub: WeightsSubscriber,
    pub(crate) listener: Listener<ipc::Service>,
    pub(crate) run: u64,
    pub(crate) world_hash: u64,
    pub(crate) stop: &'static AtomicBool,
}

impl WeightsIn {
    /// Take the newest weights newer than `after` into `policy`; with `block`, wait for
    /// them (until stopped). Returns their version.
    pub(crate) fn take(
        &self,
        policy: &mut Policy,
        after: Option<u64>,
        block: bool,
    ) -> Result<Option<u64>, ActorError> {
        loop {
            let mut newest: Option<u64> = None;
            while let Some(s) = self
                .sub
                .receive()
                .map_err(|e| IpcError::new("receive weights", e))?
            {
                let h = *s.user_header();
                if h.run != self.run || h.world_hash != self.world_hash {
                    tracing::warn!("ignored weights of another run");
                    continue;
                }
                if after.is_some_and(|a| h.version <= a) || newest.is_some_and(|v| h.version < v) {
                    continue;
                }
                if !policy.set(s.payload()) {
                    tracing::warn!("ignored weights of another shape");
                    continue;
                }
                newest = Some(h.version);
            }
            if newest.is_some() {
                return Ok(newest);
            }
            if !block || self.stop.load(Ordering::Relaxed) {
                return Ok(None);
            }
            let _ = self.listener.timed_wait(|_| {}, Duration::from_millis(50));
        }
    }
}
