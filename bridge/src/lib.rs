//! fulcrum-bridge: one run across hosts, through zenoh (the binary's `multihost`
//! feature). On each host the run's
//! processes talk through iceoryx2 shared memory as on one machine; the bridge forwards
//! between that host's services and zenoh, under key expressions that carry the run's
//! namespace:
//!
//! ```text
//! learner's host (train --listen ADDR)          actor host (actor-host --connect ADDR)
//!  learner <-shm- bridge --listen  <== zenoh ==>  bridge --connect -shm-> actors
//!
//! fulcrum/hello                     queryable   join: run, world, config, host index
//! fulcrum/<run>/chunks/<host>       put         chunks (header + payload), host -> learner
//! fulcrum/<run>/policy              put         weights (header + f32s), learner -> hosts
//! fulcrum/<run>/empowerment         queryable   lookups (msg::wire), host -> service
//! fulcrum/<run>/done                put         the run is over: actor hosts stop
//! ```
//!
//! Who may join: every host presents the run's secret (zenoh's user/password
//! authentication, [`secret`]); an actor host listens on nothing and scouts for no
//! one, so it accepts no connection; the learner's side checks everything a host
//! sends ([`guard`]) and counts what it refuses.
//!
//! Backpressure end to end: chunks travel with zenoh's blocking congestion control,
//! and the learner's side hands each chunk to the learner through an iceoryx2
//! publisher that waits while the learner's queue is full. A learner that stops
//! reading therefore stops the bridge, the link, the remote bridge, and the remote
//! actors in turn; nothing is dropped to make room. A chunk sent while no learner
//! listens (the link is down) is lost, and the learner counts it from the gap in the
//! actor's sequence numbers. A put that waits longer than the session timeout for room
//! in the link closes the session (zenoh's `wait_before_close`); the host reconnects.
//!
//! An actor host's bridge is also its actors' empowerment service: it answers DESCRIBE
//! itself and forwards every other request to the learner's host, where the bridge
//! asks the run's service (pipelined, up to `MAX_IN_FLIGHT` at once). When the link is
//! down the answer is `UNAVAILABLE`, and actors hold their chunk and ask again.
//!
//! | module | what it owns |
//! |---|---|
//! | [`secret`] | the run's secret and zenoh's user/password authentication (why this one) |
//! | [`guard`] | what the learner's side lets through from other hosts |
//! | [`session`] | the zenoh session and its settings; the bridge's iceoryx2 node |
//! | [`hello`] | joining: the hello, the hosts file, actor ids, an actor host's directory |
//! | [`mod@listen`] | the learner's side |
//! | [`mod@connect`] | an actor host's side |
//! | [`forward`] | an actor host's empowerment service |
//! | [`stats`] | counters logged when a bridge stops |
//! | [`error`] | zenoh failures, typed |

pub mod connect;
pub mod error;
pub mod forward;
pub mod guard;
pub mod hello;
pub mod listen;
pub mod secret;
pub mod session;
pub mod stats;

pub use connect::{connect, Want};
pub use error::{Refused, ZenohError};
pub use forward::Forwarder;
pub use hello::{actor_id, default_dir, joined_line, parse_joined, Hello, Joined};
pub use listen::{listen, serve_lookups};
pub use secret::{Secret, SECRET_ENV, SECRET_FILE};
pub use session::{is_loopback, locator, open_session, Auth, ZenohOptions};
pub use stats::BridgeStats;
/// The zenoh this crate is built with (the binary's remote benchmark uses it directly).
pub use zenoh;

#[cfg(test)]
mod tests;
