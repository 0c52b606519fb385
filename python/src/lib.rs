//! fulcrum's Python extension module, `fulcrum._native`. The Python package `fulcrum`
//! (beside this crate, in `python/fulcrum/`) is the API researchers use; this module is
//! the Rust core it stands on, the same crates as the command line:
//!
//! | module | what it holds |
//! |---|---|
//! | `world` | `PyWorld`: a tool world (map, tools, objects, actions, states as text) |
//! | `venv` | `VecCore`: N episodes stepped in Rust with the GIL released, writing observations, rewards, flags and action masks into numpy arrays in place |
//! | `shaper` | the intrinsic reward of equation (1) and the other forms, from the exact table, beside a `VecCore` |
//! | `emp` | exact empowerment: matrix, landscape, trace, value |
//! | `client` | `PyServiceClient`: lookups from a running `fulcrum serve` over iceoryx2 |
//! | `render` | a state as an RGB picture |
//! | `errors` | Rust errors as Python exceptions: `ValueError` for bad input, the client's typed errors |
//!
//! No panic crosses into Python: every fallible call returns a `PyResult`, and PyO3 turns
//! a panic that slipped through into `pyo3_runtime.PanicException` rather than an abort.

use pyo3::prelude::*;

mod bufs;
mod client;
mod emp;
mod errors;
mod layouts;
mod render;
mod shaper;
mod venv;
mod world;

/// The extension module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<world::PyWorld>()?;
    m.add_class::<venv::VecCore>()?;
    m.add_class::<client::PyServiceClient>()?;
    m.add_function(wrap_pyfunction!(emp::matrix, m)?)?;
    m.add_function(wrap_pyfunction!(emp::landscape, m)?)?;
    m.add_function(wrap_pyfunction!(emp::trace, m)?)?;
    m.add_function(wrap_pyfunction!(emp::value, m)?)?;
    m.add_function(wrap_pyfunction!(emp::dataset, m)?)?;
    m.add_function(wrap_pyfunction!(emp::score, m)?)?;
    m.add_function(wrap_pyfunction!(world::builtin_worlds, m)?)?;
    m.add_function(wrap_pyfunction!(world::builtin_families, m)?)?;
    errors::register(m)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("STATE_BYTES", fulcrum_contracts::msg::STATE_BYTES)?;
    Ok(())
}
