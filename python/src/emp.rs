//! Exact object empowerment from Python, with the command line's meaning
//! (`fulcrum empowerment matrix|landscape|trace|query`): the same defaults (the world's
//! `[empowerment]` tool, objects and horizons), the same names, the same sentences when a
//! request is wrong, and the same numbers (`E^h_{j,D}(s) = log2 |R_h(s)|` bits, exact).
//! The work runs with the GIL released; a world's state space is enumerated once per
//! `World` object and kept.

use fulcrum_empowerment::{request, set_objects, Engine, Method, ToolSel};
use fulcrum_world::{ObjectSet, State, World, MAX_HORIZON};
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::errors::{value_error, IntoPy};
use crate::world::{action_arg, world_arg, PyWorld};

fn method_arg(m: &str) -> PyResult<Method> {
    match m {
        "dp" => Ok(Method::Dp),
        "enumerate" => Ok(Method::Enumerate),
        _ => Err(value_error(format!(
            "unknown method '{m}' (dp or enumerate)"
        ))),
    }
}

fn horizon_arg(h: Option<u32>) -> PyResult<Option<u32>> {
    match h {
        Some(h) if h > MAX_HORIZON => Err(value_error(format!(
            "horizon {h} is too large: at most {MAX_HORIZON}"
        ))),
        h => Ok(h),
    }
}

/// An inventory: a comma-separated string or a list of tool names.
fn holding_arg(w: &World, h: Option<&Bound<'_, PyAny>>) -> PyResult<(u16, Vec<String>)> {
    let names: Vec<String> = match h {
        None => Vec::new(),
        Some(h) if h.is_none() => Vec::new(),
        Some(h) => match h.extract::<String>() {
            Ok(s) => s
                .split(',')
                .map(str::trim)
                .filter(|t| !t.is_empty())
                .map(str::to_string)
                .collect(),
            Err(_) => h
                .extract()
                .map_err(|_| value_error("holding is a list of tool names or 'a,b'"))?,
        },
    };
    let mask = request::holding_mask(w, &names.join(",")).py_err()?;
    Ok((mask, names))
}

/// Resolve a channel: engine, object set and tool, as the command line does.
fn channel<'e>(
    py: Python<'_>,
    pw: &'e PyWorld,
    tool: Option<&str>,
    objects: Option<&str>,
) -> PyResult<(&'e Engine<'e>, ObjectSet, ToolSel)> {
    let e = pw.engine(py)?;
    let w = &*pw.world;
    let set = request::objects_or_default(w, objects).py_err()?;
    let t = py.detach(|| request::tool_sel(w, e, tool, &set)).py_err()?;
    Ok((e, set, t))
}

/// The tool-object matrix and the tool selection (the command line's `--json`, as a
/// dict; `matrix` is a float64 array, rows tools, columns the object sets).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (world, objects = None, joint = Vec::new(), horizon = None, horizon_unequipped = None, horizon_equipped = None, method = "dp"))]
pub fn matrix<'py>(
    py: Python<'py>,
    world: &Bound<'py, PyAny>,
    objects: Option<&str>,
    joint: Vec<String>,
    horizon: Option<u32>,
    horizon_unequipped: Option<u32>,
    horizon_equipped: Option<u32>,
    method: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let pw = world_arg(world)?;
    let pw = pw.get();
    let w = &*pw.world;
    let method = method_arg(method)?;
    let (hu, he) = request::matrix_horizons(
        w,
        horizon_arg(horizon)?,
        horizon_arg(horizon_unequipped)?,
        horizon_arg(horizon_equipped)?,
    );
    let columns = request::matrix_columns(w, objects, &joint).py_err()?;
    let e = pw.engine(py)?;
    let m = py.detach(|| e.matrix(&columns, hu, he, method)).py_err()?;
    let d = PyDict::new(py);
    d.set_item("world", &w.name)?;
    d.set_item("states", e.space.len())?;
    d.set_item("normal_states", m.normal_states)?;
    d.set_item("horizon_unequipped", hu)?;
    d.set_item("horizon_equipped", he)?;
    d.set_item(
        "method",
        match method {
            Method::Dp => "dp",
            Method::Enumerate => "enumerate",
        },
    )?;
    d.set_item("tools", &m.tools)?;
    d.set_item("columns", &m.columns)?;
    let flat: Vec<f64> = m.values.iter().flatten().copied().collect();
    let arr = PyArray1::from_vec(py, flat).reshape([m.tools.len(), m.columns.len()])?;
    d.set_item("matrix", arr)?;
    let sel = PyDict::new(py);
    for (c, s) in m.columns.iter().zip(&m.selection) {
        sel.set_item(c, s.map(|j| m.tools[j].clone()))?;
    }
    d.set_item("selection", sel)?;
    Ok(d)
}

/// Values over the map for one inventory (the agent on each cell, mode normal, objects
/// as at the start): `values` is float64 (H, W), NaN where no such state exists.
#[pyfunction]
#[pyo3(signature = (world, tool = None, objects = None, horizon = None, holding = None, method = "dp"))]
pub fn landscape<'py>(
    py: Python<'py>,
    world: &Bound<'py, PyAny>,
    tool: Option<&str>,
    objects: Option<&str>,
    horizon: Option<u32>,
    holding: Option<&Bound<'py, PyAny>>,
    method: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let pw = world_arg(world)?;
    let pw = pw.get();
    let w = &*pw.world;
    let method = method_arg(method)?;
    let horizon = horizon_arg(horizon)?;
    let (mask, names) = holding_arg(w, holding)?;
    let (e, set, t) = channel(py, pw, tool, objects)?;
    let probe = e.landscape_state(0, 0, mask);
    let h = fulcrum_empowerment::dataset::row_horizon(w, horizon, t, &probe);
    let l = py
        .detach(|| e.landscape(t, &set, h, mask, method))
        .py_err()?;
    let flat: Vec<f64> = l
        .values
        .iter()
        .flatten()
        .map(|v| v.unwrap_or(f64::NAN))
        .collect();
    let d = PyDict::new(py);
    d.set_item("world", &w.name)?;
    d.set_item("tool", t.name(w))?;
    d.set_item("objects", set_objects(w, &set))?;
    d.set_item("horizon", h)?;
    d.set_item("holding", names)?;
    d.set_item("width", w.width)?;
    d.set_item("height", w.height)?;
    d.set_item(
        "values",
        PyArray1::from_vec(py, flat).reshape([w.height, w.width])?,
    )?;
    Ok(d)
}

/// Values along an action sequence from the initial state (t = 0 before any action):
/// `values` float64 (T + 1,), and `steps`, one dict per step (t, action, value,
/// horizon, state), as the command line's `--json`.
#[pyfunction]
#[pyo3(signature = (world, actions, tool = None, objects = None, horizon = None))]
pub fn trace<'py>(
    py: Python<'py>,
    world: &Bound<'py, PyAny>,
    actions: &Bound<'py, PyAny>,
    tool: Option<&str>,
    objects: Option<&str>,
    horizon: Option<u32>,
) -> PyResult<Bound<'py, PyDict>> {
    let pw = world_arg(world)?;
    let pw = pw.get();
    let w = &*pw.world;
    let horizon = horizon_arg(horizon)?;
    let mut acts = Vec::new();
    let items: Vec<Bound<'py, PyAny>> = if let Ok(s) = actions.extract::<String>() {
        s.split(',')
            .map(str::trim)
            .filter(|x| !x.is_empty())
            .map(|x| pyo3::types::PyString::new(py, x).into_any())
            .collect()
    } else {
        actions
            .try_iter()
            .map_err(|_| value_error("actions are a list of names or indices, or 'N,E,apply'"))?
            .collect::<PyResult<_>>()?
    };
    for a in &items {
        acts.push(action_arg(w, a)?);
    }
    let (e, set, t) = channel(py, pw, tool, objects)?;
    let (hu, he) = match horizon {
        Some(h) => (h, h),
        None => (
            w.empowerment.horizon_unequipped,
            w.empowerment.horizon_equipped,
        ),
    };
    let (tu, te) = py
        .detach(|| -> Result<_, fulcrum_empowerment::EngineError> {
            let tu = e.trace(t, &set, hu, &acts)?;
            let te = if he == hu {
                None
            } else {
                Some(e.trace(t, &set, he, &acts)?)
            };
            Ok((tu, te))
        })
        .py_err()?;
    let steps = PyList::empty(py);
    let mut values = Vec::with_capacity(tu.len());
    for (k, s) in tu.iter().enumerate() {
        let (v, h) = match &te {
            Some(te) if t.held(&s.state) => (te[k].value, he),
            _ => (s.value, hu),
        };
        values.push(v);
        let d = PyDict::new(py);
        d.set_item("t", k)?;
        d.set_item("action", s.action.map(|x| w.action_name(x)))?;
        d.set_item("value", v)?;
        d.set_item("horizon", h)?;
        d.set_item("state", w.describe(&s.state))?;
        steps.append(d)?;
    }
    let d = PyDict::new(py);
    d.set_item("world", &w.name)?;
    d.set_item("tool", t.name(w))?;
    d.set_item("objects", set_objects(w, &set))?;
    d.set_item("values", PyArray1::from_vec(py, values))?;
    d.set_item("steps", steps)?;
    Ok(d)
}

/// E at one state (a description or packed bytes), or at each of a list of them (a
/// float64 array), with the horizon by whether the tool is held unless one is given.
#[pyfunction]
#[pyo3(signature = (world, state, tool = None, objects = None, horizon = None, method = "dp"))]
pub fn value<'py>(
    py: Python<'py>,
    world: &Bound<'py, PyAny>,
    state: &Bound<'py, PyAny>,
    tool: Option<&str>,
    objects: Option<&str>,
    horizon: Option<u32>,
    method: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let pw = world_arg(world)?;
    let pw = pw.get();
    let w = &*pw.world;
    let method = method_arg(method)?;
    let horizon = horizon_arg(horizon)?;
    // One state (a str, bytes, or a 1-d uint8 row), or many (a list, or a 2-d array).
    let single = state.cast::<pyo3::types::PyString>().is_ok()
        || state.cast::<pyo3::types::PyBytes>().is_ok()
        || state.cast::<numpy::PyArray1<u8>>().is_ok();
    let states: Vec<State> = if single {
        vec![pw.state_arg(state)?]
    } else if let Ok(a) = state.cast::<PyArray2<u8>>() {
        let a = a.to_owned_array();
        a.rows()
            .into_iter()
            .map(|r| pw.state_arg(numpy::PyArray1::from_iter(py, r.iter().copied()).as_any()))
            .collect::<PyResult<_>>()?
    } else {
        state
            .try_iter()
            .map_err(|_| {
                value_error(
                    "a state is a description or packed bytes; many states are a list of them",
                )
            })?
            .map(|s| pw.state_arg(&s?))
            .collect::<PyResult<_>>()?
    };
    let (e, set, t) = channel(py, pw, tool, objects)?;
    for s in &states {
        e.state_id(s).py_err()?;
    }
    let out: Vec<f64> = py
        .detach(|| -> Result<Vec<f64>, fulcrum_empowerment::EngineError> {
            // One table per distinct horizon, shared by every state that uses it.
            let mut tables: Vec<(u32, Vec<f64>)> = Vec::new();
            let mut out = Vec::with_capacity(states.len());
            for s in &states {
                let h = fulcrum_empowerment::dataset::row_horizon(w, horizon, t, s);
                let v = match method {
                    Method::Dp => {
                        let id = e.state_id(s)? as usize;
                        if let Some((_, tab)) = tables.iter().find(|(hh, _)| *hh == h) {
                            tab[id]
                        } else {
                            let tab = e.values(t, &set, h, method)?;
                            let v = tab[id];
                            tables.push((h, tab));
                            v
                        }
                    }
                    Method::Enumerate => e.query(s, t, &set, h, method)?,
                };
                out.push(v);
            }
            Ok(out)
        })
        .py_err()?;
    if single {
        Ok(out[0].into_pyobject(py)?.into_any())
    } else {
        Ok(PyArray1::from_vec(py, out).into_any())
    }
}

/// A dataset of exact E for learned estimators (the command line's `empowerment
/// dataset`, as a dict of numpy arrays with the `.npz` file's names; `world`, `tool`,
/// `view` are str, `objects` and `actions` lists, `seed` an int).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (world, tool = None, objects = None, horizon = None, states = "all", seed = 0, view = "full", sequences = 16, method = "dp"))]
pub fn dataset<'py>(
    py: Python<'py>,
    world: &Bound<'py, PyAny>,
    tool: Option<&str>,
    objects: Option<&str>,
    horizon: Option<u32>,
    states: &str,
    seed: u64,
    view: &str,
    sequences: usize,
    method: &str,
) -> PyResult<Bound<'py, PyDict>> {
    use fulcrum_empowerment::dataset::{build, Rows, Spec};
    use fulcrum_empowerment::npz::Data;
    let pw = world_arg(world)?;
    let pw = pw.get();
    let w = &*pw.world;
    let method = method_arg(method)?;
    let horizon = horizon_arg(horizon)?;
    let rows: Rows = states
        .parse()
        .map_err(|e: String| value_error(format!("states: {e}")))?;
    let view: fulcrum_world::View = view
        .parse()
        .map_err(|e| value_error(format!("view: {e}")))?;
    let (e, set, t) = channel(py, pw, tool, objects)?;
    let spec = Spec {
        tool: t,
        set,
        horizon,
        rows,
        seed,
        view,
        sequences,
    };
    let ds = py.detach(|| build(e, &spec, method)).py_err()?;
    let d = PyDict::new(py);
    for a in ds.into_arrays(w, &spec) {
        let shape = a.shape.clone();
        let name = a.name.as_str();
        match a.data {
            Data::Str(v) if shape.is_empty() => d.set_item(name, &v[0])?,
            Data::Str(v) => d.set_item(name, v)?,
            Data::U64(v) if shape.is_empty() => d.set_item(name, v[0])?,
            Data::U8(v) => d.set_item(name, PyArray1::from_vec(py, v).reshape(shape)?)?,
            Data::Bool(v) => d.set_item(name, PyArray1::from_vec(py, v).reshape(shape)?)?,
            Data::U16(v) => d.set_item(name, PyArray1::from_vec(py, v).reshape(shape)?)?,
            Data::U32(v) => d.set_item(name, PyArray1::from_vec(py, v).reshape(shape)?)?,
            Data::U64(v) => d.set_item(name, PyArray1::from_vec(py, v).reshape(shape)?)?,
            Data::I64(v) => d.set_item(name, PyArray1::from_vec(py, v).reshape(shape)?)?,
            Data::F32(v) => d.set_item(name, PyArray1::from_vec(py, v).reshape(shape)?)?,
            Data::F64(v) => d.set_item(name, PyArray1::from_vec(py, v).reshape(shape)?)?,
        }
    }
    Ok(d)
}

fn errors_dict<'py>(
    py: Python<'py>,
    e: &fulcrum_empowerment::score::Errors,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("n", e.n)?;
    d.set_item("mae", e.mae)?;
    d.set_item("bias", e.bias)?;
    d.set_item("rmse", e.rmse)?;
    d.set_item("spearman", e.spearman)?;
    Ok(d)
}

/// Estimates `x` of true values `y` at horizons `h` (float64, float64, uint32 arrays of
/// one length), scored as `fulcrum empowerment score --json` scores them.
#[pyfunction]
pub fn score<'py>(
    py: Python<'py>,
    x: Vec<f64>,
    y: Vec<f64>,
    h: Vec<u32>,
) -> PyResult<Bound<'py, PyDict>> {
    let s = fulcrum_empowerment::score::score(&x, &y, &h).map_err(value_error)?;
    let d = errors_dict(py, &s.all)?;
    let bins = PyList::empty(py);
    for b in &s.by_bin {
        let e = errors_dict(py, &b.errors)?;
        e.set_item("lo", b.lo)?;
        e.set_item("hi", b.lo + 1.0)?;
        bins.append(e)?;
    }
    d.set_item("by_bin", bins)?;
    let hs = PyList::empty(py);
    for (hz, b) in &s.by_horizon {
        let e = errors_dict(py, b)?;
        e.set_item("horizon", hz)?;
        hs.append(e)?;
    }
    d.set_item("by_horizon", hs)?;
    Ok(d)
}
