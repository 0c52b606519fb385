//! The learner's shared-memory ports (iceoryx2): trajectory chunks and their wake-up
//! events in, policy weights and theirs out; and publishing a version of the weights.

use fulcrum_contracts::traj::{
    self, ChunkSubscriber, PolicyFactory, TrainNames, TrajFactory, WeightsHeader, WeightsPublisher,
};
use fulcrum_contracts::IpcError;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::event::PortFactory as EventFactory;

use crate::error::LearnerError;
use crate::net::Net;
use crate::watch::ensure_finite;

/// The learner's shared-memory ports: chunks and their wake-ups in, weights and theirs
/// out. The fields drop in the reverse order of their creation.
pub(crate) struct Ports {
    pub(crate) notifier: Notifier<ipc::Service>,
    _policy_wake: EventFactory<ipc::Service>,
    pub(crate) publisher: WeightsPublisher,
    _policy: PolicyFactory,
    pub(crate) listener: Listener<ipc::Service>,
    _chunks_wake: EventFactory<ipc::Service>,
    pub(crate) sub: ChunkSubscriber,
    _chunks: TrajFactory,
    _node: Node<ipc::Service>,
}

impl Ports {
    /// The ports of the run in `namespace`, for weights of `weights` floats and
    /// `subscribers` subscribers of them.
    pub(crate) fn open(
        namespace: &str,
        weights: usize,
        subscribers: usize,
    ) -> Result<Ports, LearnerError> {
        let node = NodeBuilder::new()
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .map_err(|e| IpcError::new("node", e))?;
        let names = TrainNames::new(namespace);
        let tsvc = traj::trajectory_service(&node, &names).map_err(LearnerError::from)?;
        let sub = tsvc
            .subscriber_builder()
            .create()
            .map_err(|e| IpcError::new("subscriber", e))?;
        let twake =
            traj::wake_service(&node, &names.trajectories_wake).map_err(LearnerError::from)?;
        let listener = twake
            .listener_builder()
            .create()
            .map_err(|e| IpcError::new("listener", e))?;
        let psvc = traj::policy_service(&node, &names, subscribers).map_err(LearnerError::from)?;
        let publisher = psvc
            .publisher_builder()
            .initial_max_slice_len(weights)
            .max_loaned_samples(traj::WEIGHTS_LOANED)
            .create()
            .map_err(|e| IpcError::new("publisher", e))?;
        let pwake = traj::wake_service(&node, &names.policy_wake).map_err(LearnerError::from)?;
        let notifier = pwake
            .notifier_builder()
            .create()
            .map_err(|e| IpcError::new("notifier", e))?;
        Ok(Ports {
            notifier,
            _policy_wake: pwake,
            publisher,
            _policy: psvc,
            listener,
            _chunks_wake: twake,
            sub,
            _chunks: tsvc,
            _node: node,
        })
    }

    /// Publish `net`'s weights as `version` and wake the actors.
    pub(crate) fn publish(
        &self,
        net: &Net,
        run: u64,
        world_hash: u64,
        version: u64,
    ) -> Result<(), LearnerError> {
        let flat = net.flat()?;
        ensure_finite(&flat, version)?;
        let mut s = self
            .publisher
            .loan_slice_uninit(flat.len())
            .map_err(|e| IpcError::new("loan weights", e))?;
        *s.user_header_mut() = WeightsHeader {
            run,
            world_hash,
            version,
            len: flat.len() as u64,
        };
        let s = s.write_from_slice(&flat);
        s.send().map_err(|e| IpcError::new("send weights", e))?;
        let _ = self.notifier.notify();
        Ok(())
    }
}
