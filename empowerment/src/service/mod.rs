//! The empowerment service and its client, over iceoryx2 request-response.
//!
//! One service process owns one world's engine. It precomputes the table of its
//! configuration (tool j, objects D, horizons h_u / h_e) and answers:
//!
//! - LOOKUP: a batch of packed states -> `E^{h(s)}_{j,D}(s)` as `f32`, with `h(s) = h_e`
//!   where j is held and `h_u` elsewhere;
//! - QUERY: any tool, object set and horizon, computed on demand and cached within a
//!   memory bound;
//! - DESCRIBE: the world and the configuration;
//! - VISIT: count one visit of each state and answer its visit count so far, shared by
//!   all clients (the count-based novelty bonus of `train --intrinsic count`).
//!
//! Wake-ups: pub/sub and request-response ports have no file descriptor, so requests
//! and responses are paired with event services (iceoryx2's request-response and
//! pub/sub ports cannot be waited on by themselves). Each side first polls a short
//! bounded while for the answer, then blocks on its listener: a fast answer costs no
//! wake-up, an idle process burns no core. The poll yields the core between looks
//! rather than spinning: on small machines the scheduler often wakes the service on the
//! very core its client polls on, and a spinning client would hold the service off until
//! its poll ran out (BENCHMARKS.md, "The empowerment service", has the figures and the
//! variants tried).
//!
//! A bad request never stops the service: it gets an error status (see
//! [`fulcrum_contracts::msg::status`]), and states that are not in the state space get
//! [`fulcrum_contracts::msg::item::NOT_IN_SPACE`].
//!
//! # Contents
//!
//! - `server`: the serving loop ([`serve`], [`serve_with`], the [`Answer`] trait);
//! - `client`: the [`Client`] and what it asks ([`Ask`]) and gets ([`Batch`]);
//! - `tables`: what a service answers from ([`Tables`], configured by [`ServeConfig`]);
//! - `family`: what the service of a world family answers from: a table per layout,
//!   made on first sight ([`FamilyTables`], configured by [`FamilyConfig`]);
//! - `codes`: tools and object sets as requests name them ([`object_mask`],
//!   [`mask_set`]) and the DESCRIBE answer ([`describe()`]);
//! - `signal`: the stop flag (SIGINT, SIGTERM, [`request_stop`]);
//! - `ports`: the iceoryx2 services every process opens the same way, and
//!   [`clean_dead_nodes`];
//! - `error`: [`ServiceError`] and [`ClientError`].

mod answer;
mod client;
mod codes;
mod config;
mod error;
mod family;
mod ports;
mod server;
mod signal;
mod tables;

pub use answer::Answer;
pub use client::{Ask, Batch, Client};
pub use codes::{describe, mask_set, object_mask};
pub use config::ServeConfig;
pub use error::{ClientError, ServiceError};
pub use family::{FamilyConfig, FamilyStats, FamilyTables};
pub use ports::{clean_dead_nodes, quiet_ipc_logs};
pub use server::{serve, serve_with, ServeExit, ServeStats};
pub use signal::{request_stop, stop_requested};
pub use tables::Tables;
