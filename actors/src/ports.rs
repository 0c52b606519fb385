//! The actor's shared-memory ports: chunks and their wake-ups out to the learner, and
//! the services the weights come in by.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use fulcrum_contracts::traj::{
    self, ChunkPublisher, PolicyFactory, TrainNames, TrajFactory, WeightsSubscriber,
};
use fulcrum_contracts::IpcError;
use fulcrum_empowerment::service::clean_dead_nodes;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::BackpressureAction;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::event::PortFactory as EventFactory;

use crate::error::ActorError;

/// The actor's shared-memory ports: chunks and their wake-ups out, and the services
/// the weights come in by ([`crate::weights::WeightsIn`] holds their ports). The fields drop in the
/// reverse order of their creation.
pub(crate) struct Ports {
    _policy_wake: EventFactory<ipc::Service>,
    _policy: PolicyFactory,
    pub(crate) notifier: Notifier<ipc::Service>,
    _chunks_wake: EventFactory<ipc::Service>,
    pub(crate) publisher: ChunkPublisher,
    _chunks: TrajFactory,
    _node: Node<ipc::Service>,
}

impl Ports {
    /// The ports of the run in `namespace`, for chunks of `bytes` bytes, and the weights'
    /// subscriber and wake-up listener (the weights service made for `subscribers`).
    /// Sending blocks while the learner's queue is full (until `stop`).
    pub(crate) fn open(
        namespace: &str,
        bytes: usize,
        subscribers: usize,
        stop: &'static AtomicBool,
    ) -> Result<(Ports, WeightsSubscriber, Listener<ipc::Service>), ActorError> {
        let node = NodeBuilder::new()
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .map_err(|e| IpcError::new("node", e))?;
        let names = TrainNames::new(namespace);
        let tsvc = traj::trajectory_service(&node, &names).map_err(ActorError::from)?;
        let publisher = tsvc
            .publisher_builder()
            .initial_max_slice_len(bytes)
            .max_loaned_samples(traj::CHUNKS_LOANED)
            .backpressure_strategy(BackpressureStrategy::RetryUntilDelivered)
            .set_backpressure_handler(move |info: &iceoryx2::port::BackpressureInfo| {
                // The learner's queue is full: wait without burning a core, clean up after
                // a dead learner now and then, and give up when asked to stop.
                if stop.load(Ordering::Relaxed) {
                    return BackpressureAction::DiscardDataAndFail;
                }
                if info.retries % 200 == 199 {
                    clean_dead_nodes();
                }
                std::thread::sleep(Duration::from_micros(500));
                BackpressureAction::Retry
            })
            .create()
            .map_err(|e| IpcError::new("publisher", e))?;
        let twake =
            traj::wake_service(&node, &names.trajectories_wake).map_err(ActorError::from)?;
        let notifier = twake
            .notifier_builder()
            .create()
            .map_err(|e| IpcError::new("notifier", e))?;
        let psvc = traj::policy_service(&node, &names, subscribers).map_err(ActorError::from)?;
        let sub = psvc
            .subscriber_builder()
            .create()
            .map_err(|e| IpcError::new("subscriber", e))?;
        let pwake = traj::wake_service(&node, &names.policy_wake).map_err(ActorError::from)?;
        let listener = pwake
            .listener_builder()
            .create()
            .map_err(|e| IpcError::new("listener", e))?;

        let ports = Ports {
            _policy_wake: pwake,
            _policy: psvc,
            notifier,
            _chunks_wake: twake,
            publisher,
            _chunks: tsvc,
            _node: node,
        };
        Ok((ports, sub, listener))
    }
}
