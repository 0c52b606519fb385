//! fulcrum-empowerment: exact object empowerment over an enumerated state space.
//!
//! For a tool j, objects D and horizon h (`docs/world.md`, the paper's equations 4 and 5):
//!
//! ```text
//! E^h_{j,D}(s) = log2 | { proj_D(T^h(s, a)) : a in (A^{T_j})^h } |     bits
//! ```
//!
//! [`Engine`] enumerates the states once, then answers by set propagation
//! ([`propagate`]), with the paper's sequence enumeration ([`enumerate`]) as the
//! reference. In a stochastic world E is the capacity of the channel from action
//! sequences to the objects' projection, computed by distribution propagation
//! ([`stochastic`]) and [`capacity`].
//!
//! ```
//! use fulcrum_empowerment::{Engine, Limits, Method};
//! use fulcrum_world::{load_world, ObjectSet};
//! let world = load_world("exp1-tree").unwrap();
//! let engine = Engine::new(&world, Limits::default()).unwrap();
//! let tree = ObjectSet::Objects(vec![world.object_index("tree").unwrap()]);
//! let m = engine.matrix(&[tree], 8, 3, Method::Dp).unwrap();
//! assert_eq!(m.selection[0], Some(0)); // the axe
//! ```
//!
//! # Contents
//!
//! - [`engine`]: the engine: values, matrix, tool selection, landscapes, traces, queries;
//! - [`space`]: state-space enumeration and the successor table;
//! - [`propagate`]: set propagation, the fast exact method;
//! - [`auto`]: tool selection and the selected tool's table in one propagation (every
//!   tool's sets side by side), what a family's service makes per layout;
//! - [`stochastic`]: distribution propagation, the exact method of stochastic worlds;
//! - [`capacity`]: channel capacity in bits (closed form of two outputs, Blahut-Arimoto);
//! - [`enumerate`]: the reference method, every action sequence;
//! - [`limits`]: memory limits, checked before a computation starts;
//! - [`dataset`]: datasets of exact E with observations and sampled action sequences,
//!   for learned estimators; [`npz`] writes and reads them as NumPy files;
//! - [`estimates`]: a LOOKUP table from someone's estimates of E (training on them);
//! - [`score`]: estimates against the exact values (MAE, bias, Spearman, by bin and
//!   horizon);
//! - [`request`]: reading what a request names (object sets, tools, inventories);
//! - [`error`]: the engine's errors;
//! - [`service`]: the empowerment service and its client (iceoryx2 request-response);
//!   for a world family, a table per layout made the first time it is asked about
//!   ([`service::FamilyTables`]).

pub mod auto;
pub mod capacity;
pub mod dataset;
pub mod engine;
pub mod enumerate;
pub mod error;
pub mod estimates;
pub mod limits;
pub mod npz;
pub mod propagate;
pub mod request;
pub mod score;
pub mod service;
pub mod space;
pub mod stochastic;

pub use capacity::Capacity;
pub use engine::{
    select, set_name, set_objects, Engine, Landscape, Matrix, Method, ToolSel, TraceStep,
};
pub use error::EngineError;
pub use limits::Limits;
pub use space::{StateIndex, StateSpace};
