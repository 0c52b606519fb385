//! `fulcrum.World`: a tool world, from a built-in name or a file.
//!
//! States cross into Python as their text description (`agent=2,4 holding=axe mode=normal
//! tree=intact`, the command line's form) or as 38 packed bytes (`bytes`, or a numpy
//! `uint8` row), the form the empowerment service takes. Every state that comes in is
//! checked against the world before it is used.

use std::sync::{Arc, OnceLock};

use fulcrum_contracts::msg::STATE_BYTES;
use fulcrum_empowerment::{request, Engine};
use fulcrum_world::{builtin, load_world, parse_world, State, World};
use numpy::PyArrayMethods;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList, PyString};

use crate::errors::{value_error, IntoPy};

/// A world and, once asked for, its enumerated state space.
#[derive(Debug)]
#[pyclass(name = "World", module = "fulcrum", frozen)]
pub struct PyWorld {
    pub(crate) world: Arc<World>,
    engine: OnceLock<Cached>,
}

/// An engine over the world it borrows, kept together.
#[derive(Debug)]
struct Cached {
    // Declared before `_world`: dropped first, while the world it borrows still lives.
    engine: Engine<'static>,
    _world: Arc<World>,
}

impl PyWorld {
    pub(crate) fn from_world(world: World) -> PyWorld {
        PyWorld {
            world: Arc::new(world),
            engine: OnceLock::new(),
        }
    }

    /// The world's engine (its state space enumerated on first use, with the command
    /// line's memory limits).
    pub(crate) fn engine(&self, py: Python<'_>) -> PyResult<&Engine<'_>> {
        if let Some(c) = self.engine.get() {
            return Ok(&c.engine);
        }
        let world = Arc::clone(&self.world);
        // SAFETY: the engine borrows the world behind the Arc, whose heap address never
        // changes and which is never mutated. The Arc is stored beside the engine in
        // `Cached`, whose field order drops the engine first, and the engine is only ever
        // lent out borrowed from `self`, so the `'static` never outlives the world.
        let w: &'static World = unsafe { &*Arc::as_ptr(&world) };
        let engine = py.detach(|| request::engine(w)).py_err()?;
        let _ = self.engine.set(Cached {
            engine,
            _world: world,
        });
        Ok(&self.engine.get().expect("set above").engine)
    }

    /// A state from its text description, 38 packed bytes, or a numpy row of them,
    /// checked against the world.
    pub(crate) fn state_arg(&self, arg: &Bound<'_, PyAny>) -> PyResult<State> {
        let w = &self.world;
        let s = if let Ok(text) = arg.cast::<PyString>() {
            w.parse_state(text.to_str()?).py_err()?
        } else {
            let bytes: Vec<u8> = if let Ok(b) = arg.cast::<PyBytes>() {
                b.as_bytes().to_vec()
            } else if let Ok(a) = arg.cast::<numpy::PyArray1<u8>>() {
                a.to_vec()?
            } else {
                return Err(value_error(format!(
                    "a state is a description like 'agent=1,1 mode=normal' or {STATE_BYTES} packed bytes, not a {}",
                    arg.get_type().name()?
                )));
            };
            let packed: &[u8; STATE_BYTES] = bytes.as_slice().try_into().map_err(|_| {
                value_error(format!(
                    "a packed state has {STATE_BYTES} bytes, not {}",
                    bytes.len()
                ))
            })?;
            let s = State::from_bytes(packed);
            w.check_state(&s).map_err(|e| {
                value_error(format!(
                    "the packed bytes are not a state of world '{}': {e}",
                    w.name
                ))
            })?;
            s
        };
        Ok(s)
    }
}

/// A world argument: a `World`, a built-in name or a file path.
pub(crate) fn world_arg(arg: &Bound<'_, PyAny>) -> PyResult<Py<PyWorld>> {
    if let Ok(w) = arg.cast::<PyWorld>() {
        return Ok(w.clone().unbind());
    }
    let name: String = arg
        .extract()
        .map_err(|_| value_error("a world is a fulcrum.World, a built-in name or a file path"))?;
    Py::new(arg.py(), PyWorld::from_world(load_world(&name).py_err()?))
}

#[pymethods]
impl PyWorld {
    /// `World("exp1-tree")` or `World("path/to/world.toml")`.
    #[new]
    fn new(name_or_path: &str) -> PyResult<Self> {
        Ok(PyWorld::from_world(load_world(name_or_path).py_err()?))
    }

    /// A world from the text of a world file; `file` names it in error messages.
    #[staticmethod]
    #[pyo3(signature = (text, file = "<text>"))]
    fn from_text(text: &str, file: &str) -> PyResult<Self> {
        Ok(PyWorld::from_world(parse_world(text, file).py_err()?))
    }

    /// Layout `seed` of a world family (a built-in family such as `"toolbox"`, or a file
    /// with a `[family]` table): the same family and seed give the same world on every
    /// machine, as `fulcrum world show FAMILY --layout SEED`.
    #[staticmethod]
    fn layout(family: &str, seed: u64) -> PyResult<Self> {
        let f = fulcrum_world::family::load_family(family).py_err()?;
        Ok(PyWorld::from_world(f.layout(seed).py_err()?))
    }

    /// The world's name.
    #[getter]
    fn name(&self) -> &str {
        &self.world.name
    }

    /// Map width in cells.
    #[getter]
    fn width(&self) -> usize {
        self.world.width
    }

    /// Map height in cells.
    #[getter]
    fn height(&self) -> usize {
        self.world.height
    }

    /// Steps after which an episode is truncated.
    #[getter]
    fn max_steps(&self) -> u32 {
        self.world.max_steps
    }

    /// The map of the initial state, one string per row.
    #[getter]
    fn map(&self) -> Vec<String> {
        self.world
            .render(&self.world.initial)
            .lines()
            .map(str::to_string)
            .collect()
    }

    /// Tools in file order: dicts of name, kind, letter and cell (x, y).
    #[getter]
    fn tools<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let list = PyList::empty(py);
        for t in &self.world.tools {
            let d = PyDict::new(py);
            d.set_item("name", &t.name)?;
            d.set_item("kind", &t.kind)?;
            d.set_item("letter", t.letter.to_string())?;
            d.set_item("pos", t.pos)?;
            list.append(d)?;
        }
        Ok(list)
    }

    /// Objects in reading order: dicts of name, kind and initial cell (x, y).
    #[getter]
    fn objects<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let list = PyList::empty(py);
        for o in &self.world.objects {
            let d = PyDict::new(py);
            d.set_item("name", &o.name)?;
            d.set_item("kind", o.kind.name())?;
            d.set_item("pos", o.pos)?;
            list.append(d)?;
        }
        Ok(list)
    }

    /// Action names by index: N, E, S, W, apply, then one select per tool.
    #[getter]
    fn actions(&self) -> Vec<String> {
        (0..self.world.num_actions() as u8)
            .map(|a| self.world.action_name(a))
            .collect()
    }

    /// The task, in words.
    #[getter]
    fn task(&self) -> String {
        self.world.task_text()
    }

    /// The `[empowerment]` defaults: tool, objects, horizons and beta.
    #[getter]
    fn empowerment_defaults<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let w = &self.world;
        let e = &w.empowerment;
        let d = PyDict::new(py);
        d.set_item(
            "tool",
            match &e.tool {
                fulcrum_world::ToolChoice::Auto => "auto".to_string(),
                fulcrum_world::ToolChoice::All => "all".to_string(),
                fulcrum_world::ToolChoice::Tool(k) => w.tools[*k].name.clone(),
            },
        )?;
        d.set_item(
            "objects",
            e.objects
                .as_ref()
                .map(|s| fulcrum_empowerment::set_name(w, s)),
        )?;
        d.set_item("horizon_unequipped", e.horizon_unequipped)?;
        d.set_item("horizon_equipped", e.horizon_equipped)?;
        d.set_item("beta", e.beta)?;
        Ok(d)
    }

    /// Number of states reachable from the initial one (every mode).
    #[getter]
    fn state_count(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(self.engine(py)?.space.len())
    }

    /// Number of normal-mode states (those the matrix averages over).
    #[getter]
    fn normal_state_count(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(self.engine(py)?.normal_states())
    }

    /// The initial state, packed (38 bytes).
    #[getter]
    fn initial_state<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        PyBytes::new(py, &self.world.initial.to_bytes())
    }

    /// The text description of a state (description or packed bytes).
    fn describe(&self, state: &Bound<'_, PyAny>) -> PyResult<String> {
        Ok(self.world.describe(&self.state_arg(state)?))
    }

    /// The packed bytes of a state given by its description.
    fn pack<'py>(
        &self,
        py: Python<'py>,
        state: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyBytes>> {
        Ok(PyBytes::new(py, &self.state_arg(state)?.to_bytes()))
    }

    /// The outcomes of `action` in `state` with their probabilities, as (packed state,
    /// probability) pairs summing to 1; one pair in a deterministic world.
    fn outcomes<'py>(
        &self,
        py: Python<'py>,
        state: &Bound<'py, PyAny>,
        action: &Bound<'py, PyAny>,
    ) -> PyResult<Vec<(Bound<'py, PyBytes>, f64)>> {
        let s = self.state_arg(state)?;
        let a = action_arg(&self.world, action)?;
        let mut out = Vec::new();
        self.world.outcomes(&s, a, &mut out);
        Ok(out
            .into_iter()
            .map(|(t, p)| (PyBytes::new(py, &t.to_bytes()), p))
            .collect())
    }

    /// Whether anything is left to chance (a slip above 0 or a rule with p below 1).
    #[getter]
    fn stochastic(&self) -> bool {
        self.world.is_stochastic()
    }

    /// The state after `action` (an index or a name: N, E, S, W, apply, a tool), packed;
    /// in a stochastic world the intended outcome (no slip, the rule acting): its
    /// distribution is `outcomes`.
    fn step<'py>(
        &self,
        py: Python<'py>,
        state: &Bound<'py, PyAny>,
        action: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyBytes>> {
        let s = self.state_arg(state)?;
        let a = action_arg(&self.world, action)?;
        Ok(PyBytes::new(py, &self.world.step(&s, a).to_bytes()))
    }

    /// The map a state shows, one string per row.
    fn render_text(&self, state: &Bound<'_, PyAny>) -> PyResult<Vec<String>> {
        let s = self.state_arg(state)?;
        Ok(self.world.render(&s).lines().map(str::to_string).collect())
    }

    /// The state as an RGB picture, `tile` pixels per cell: uint8 (H * tile, W * tile, 3).
    #[pyo3(signature = (state = None, tile = 16))]
    fn render<'py>(
        &self,
        py: Python<'py>,
        state: Option<&Bound<'py, PyAny>>,
        tile: usize,
    ) -> PyResult<Bound<'py, numpy::PyArray3<u8>>> {
        let s = match state {
            Some(s) => self.state_arg(s)?,
            None => self.world.initial,
        };
        crate::render::rgb(py, &self.world, &s, tile)
    }

    fn __repr__(&self) -> String {
        let w = &self.world;
        format!(
            "World('{}': {}x{}, tools {}, objects {}, {} actions)",
            w.name,
            w.width,
            w.height,
            if w.tools.is_empty() {
                "none".into()
            } else {
                w.tool_list()
            },
            if w.objects.is_empty() {
                "none".into()
            } else {
                w.object_list()
            },
            w.num_actions()
        )
    }
}

/// An action by index or name, checked against the world.
pub(crate) fn action_arg(w: &World, arg: &Bound<'_, PyAny>) -> PyResult<u8> {
    let n = w.num_actions();
    if let Ok(i) = arg.extract::<i64>() {
        if (0..n as i64).contains(&i) {
            return Ok(i as u8);
        }
        return Err(value_error(format!(
            "action {i} is out of range: world '{}' has actions 0..{}",
            w.name,
            n - 1
        )));
    }
    let name: String = arg
        .extract()
        .map_err(|_| value_error("an action is an index or a name (N, E, S, W, apply, a tool)"))?;
    w.parse_action(&name).ok_or_else(|| {
        value_error(format!(
            "unknown action '{name}' (N, E, S, W, apply, or a tool: {})",
            w.tool_list()
        ))
    })
}

/// The names of the built-in worlds.
#[pyfunction]
pub fn builtin_worlds() -> Vec<&'static str> {
    builtin::NAMES.to_vec()
}

/// The names of the built-in world families (`World.layout(name, seed)`).
#[pyfunction]
pub fn builtin_families() -> Vec<&'static str> {
    builtin::FAMILIES.to_vec()
}
