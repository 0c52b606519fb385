//! `fulcrum.ServiceClient`: lookups from a running `fulcrum serve` (or a training run's
//! service) over iceoryx2 shared memory, with the Rust client's batching and pipelining.
//!
//! States go in as packed rows (uint8 (N, 38), e.g. a vector environment's `states`), a
//! list of descriptions, or a list of packed `bytes`; values come back as float32 (N,)
//! with a uint8 (N,) status per state (0 ok, 1 not a state of the world's state space).
//! Batches larger than the service's limit are split and pipelined.

use std::time::Duration;

use fulcrum_contracts::msg::{get_name, MAX_BATCH, MAX_IN_FLIGHT, STATE_BYTES, TOOL_ALL};
use fulcrum_empowerment::service::{object_mask, Ask, Client, ClientError};
use fulcrum_world::State;
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::{value_error, IntoPy};
use crate::world::{world_arg, PyWorld};

/// Values (float32) and per-state statuses (uint8) of one ask.
type Answer<'py> = (Bound<'py, PyArray1<f32>>, Bound<'py, PyArray1<u8>>);

/// A connection to one namespace's empowerment service.
#[derive(Debug)]
#[pyclass(name = "ServiceClient", module = "fulcrum", unsendable)]
pub struct PyServiceClient {
    client: Client,
    world: Py<PyWorld>,
}

/// Moves a value into a closure that runs with the GIL released. `Python::detach` runs
/// its closure on the calling thread, so a value that may not cross threads is sound to
/// carry there; PyO3 cannot know that and asks for `Send`.
struct SameThread<T>(T);
// SAFETY: only ever moved into `Python::detach`, which runs the closure on this thread.
unsafe impl<T> Send for SameThread<T> {}

impl PyServiceClient {
    /// The states of an argument (packed rows, descriptions or packed bytes), checked
    /// to be this world's states.
    fn states_arg(&self, py: Python<'_>, states: &Bound<'_, PyAny>) -> PyResult<Vec<State>> {
        let pw = self.world.get();
        if let Ok(a) = states.cast::<PyArray2<u8>>() {
            if a.shape()[1] != STATE_BYTES {
                return Err(value_error(format!(
                    "packed states are rows of {STATE_BYTES} bytes, not {}",
                    a.shape()[1]
                )));
            }
            let ro = a.readonly();
            let v = ro.as_array();
            return v
                .rows()
                .into_iter()
                .map(|r| {
                    let row = numpy::PyArray1::from_iter(py, r.iter().copied());
                    pw.state_arg(row.as_any())
                })
                .collect();
        }
        states
            .try_iter()
            .map_err(|_| {
                value_error("states are packed rows (uint8, (N, 38)), or a list of descriptions or packed bytes")
            })?
            .map(|s| pw.state_arg(&s?))
            .collect()
    }

    /// Ask `ask` for every state, in pipelined batches.
    fn ask<'py>(
        &mut self,
        py: Python<'py>,
        ask: Ask,
        states: &Bound<'py, PyAny>,
    ) -> PyResult<Answer<'py>> {
        let states = self.states_arg(py, states)?;
        let n = states.len();
        let mut values = vec![0f32; n];
        let mut status = vec![0u8; n];
        let job = SameThread((&mut self.client, &states, &mut values, &mut status));
        py.detach(move || {
            let job = job;
            let SameThread((client, states, values, status)) = job;
            let batches: Vec<&[State]> = states.chunks(MAX_BATCH).collect();
            let mut sent = 0;
            let mut got = 0;
            while got < batches.len() {
                while sent < batches.len() && sent - got < MAX_IN_FLIGHT {
                    client.submit(ask, batches[sent])?;
                    sent += 1;
                }
                let at = got * MAX_BATCH;
                let len = batches[got].len();
                client.recv_into(&mut values[at..at + len], &mut status[at..at + len])?;
                got += 1;
            }
            Ok::<(), ClientError>(())
        })
        .py_err()?;
        Ok((
            PyArray1::from_vec(py, values),
            PyArray1::from_vec(py, status),
        ))
    }
}

#[pymethods]
impl PyServiceClient {
    /// Connect to the service of `namespace` for `world` (a `World`, name or path),
    /// waiting up to `timeout` seconds for it to appear.
    #[new]
    #[pyo3(signature = (namespace, world, timeout = 5.0))]
    fn new(
        py: Python<'_>,
        namespace: &str,
        world: &Bound<'_, PyAny>,
        timeout: f64,
    ) -> PyResult<Self> {
        if !(timeout.is_finite() && timeout > 0.0 && timeout <= 86_400.0) {
            return Err(value_error(format!(
                "timeout is {timeout} seconds: give a number in (0, 86400]"
            )));
        }
        if !fulcrum_contracts::msg::valid_namespace(namespace) {
            return Err(value_error(format!(
                "namespace '{namespace}' is not usable: 1 to 64 of A-Z a-z 0-9 _ . -"
            )));
        }
        let world = world_arg(world)?;
        let w = std::sync::Arc::clone(&world.get().world);
        let deadline = Duration::from_secs_f64(timeout);
        let client = py
            .detach(|| Client::connect(namespace, &w, deadline).map(SameThread))
            .py_err()?
            .0;
        Ok(PyServiceClient { client, world })
    }

    /// The service's configured table for each state: (values float32 (N,), status uint8
    /// (N,)).
    fn lookup<'py>(
        &mut self,
        py: Python<'py>,
        states: &Bound<'py, PyAny>,
    ) -> PyResult<Answer<'py>> {
        self.ask(py, Ask::Lookup, states)
    }

    /// Count one visit of each state; each value is that state's visit count so far, all
    /// clients together.
    fn visit<'py>(&mut self, py: Python<'py>, states: &Bound<'py, PyAny>) -> PyResult<Answer<'py>> {
        self.ask(py, Ask::Visit, states)
    }

    /// E^horizon of `tool` (a name or 'all') over `objects` at each state, computed by the
    /// service on demand (and cached there).
    fn query<'py>(
        &mut self,
        py: Python<'py>,
        states: &Bound<'py, PyAny>,
        tool: &str,
        objects: &str,
        horizon: u32,
    ) -> PyResult<Answer<'py>> {
        let pw = self.world.get();
        let w = &*pw.world;
        let tool = if tool == "all" {
            TOOL_ALL
        } else {
            w.tool_index(tool).ok_or_else(|| {
                value_error(format!(
                    "unknown tool '{tool}' in world '{}' (tools: {}; or all)",
                    w.name,
                    w.tool_list()
                ))
            })? as i32
        };
        let set = fulcrum_empowerment::request::object_set(w, objects).py_err()?;
        if horizon > fulcrum_world::MAX_HORIZON {
            return Err(value_error(format!(
                "horizon {horizon} is too large: at most {}",
                fulcrum_world::MAX_HORIZON
            )));
        }
        let ask = Ask::Query {
            tool,
            objects: object_mask(&set),
            horizon,
        };
        self.ask(py, ask, states)
    }

    /// What the service serves: world, states, tool, objects, horizons.
    fn describe<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = self.client.describe();
        let out = PyDict::new(py);
        let tools: Vec<String> = d.tools[..d.n_tools as usize]
            .iter()
            .map(|t| get_name(t))
            .collect();
        let objects: Vec<String> = d.objects[..d.n_objects as usize]
            .iter()
            .map(|o| get_name(o))
            .collect();
        out.set_item("world", get_name(&d.world))?;
        out.set_item("world_hash", d.world_hash)?;
        out.set_item("states", d.states)?;
        out.set_item("normal_states", d.normal_states)?;
        out.set_item(
            "tool",
            if d.tool == TOOL_ALL {
                "all".to_string()
            } else {
                tools.get(d.tool as usize).cloned().unwrap_or_default()
            },
        )?;
        let w = &*self.world.get().world;
        out.set_item(
            "objects",
            fulcrum_empowerment::service::mask_set(w, d.object_mask)
                .map(|s| fulcrum_empowerment::set_name(w, &s)),
        )?;
        out.set_item("horizon_unequipped", d.horizon_unequipped)?;
        out.set_item("horizon_equipped", d.horizon_equipped)?;
        out.set_item("tools", tools)?;
        out.set_item("objects_all", objects)?;
        Ok(out)
    }

    fn __repr__(&self) -> String {
        let d = self.client.describe();
        format!("ServiceClient(world '{}')", get_name(&d.world))
    }
}
