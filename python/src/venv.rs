//! `VecCore`: N episodes of one world stepped together in Rust.
//!
//! Shapes, for N environments of a `W x H` world with `n` tools (|A| = 5 + n), seen in
//! full (`view = "full"`) or through the `S x S` window around the agent, `S = 2R + 1`
//! (`view = "crop:R"`, cells beyond the map as rock; `fulcrum_world::view`):
//!
//! | array | dtype | shape | what |
//! |---|---|---|---|
//! | `glyphs` | uint8 | (N, H, W) or (N, S, S) | glyph id per cell (`docs/world.md`, "Episodes and what the learner sees") |
//! | `flags` | uint8 | (N, 2n + 2) | held tools, then the mode one-hot |
//! | `action_mask` | int8 | (N, |A|) | 1 where the action can do something (training's mask) |
//! | `reward` | float32 | (N,) | the task reward R of the last step |
//! | `terminated`, `truncated` | bool | (N,) | the task ended / the time limit ran out |
//! | `states` | uint8 | (N, 38) | the packed states (for the empowerment service) |
//!
//! The arrays are allocated once, as numpy arrays, and every step writes them in place:
//! a step makes no Python object. Autoreset is gymnasium's next-step mode: the step after
//! an episode ends resets that environment (its action is ignored) and reports reward 0,
//! not terminated, not truncated, and the initial observation. The step itself runs with
//! the GIL released; other threads must not touch these arrays while it runs.
//!
//! In a stochastic world each environment draws its outcomes from its own ChaCha8
//! generator, seeded by [`VecCore::seed`] (environment e's stream depends on its seed
//! alone, so one environment seeded s replays environment e of a vector seeded s - e);
//! a deterministic world draws nothing.
//!
//! On a world family (`layouts`, [`crate::layouts`]) each environment plays one layout
//! per episode, drawn from the same generator when the episode starts (at `reset` and
//! at each autoreset); `layout` (uint64, (N,)) holds each environment's layout seed. The
//! shapes are the family's, the same for every layout.

use std::sync::Arc;

use fulcrum_world::family::{is_family, load_family};
use fulcrum_world::mask::action_mask;
use fulcrum_world::{Episode, ObsSpec, View, World};
use numpy::{
    PyArray1, PyArray2, PyArray3, PyArrayMethods, PyReadonlyArray1, PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::bufs::{Bufs, Views};
use crate::errors::{value_error, IntoPy};
use crate::layouts::FamilyEnvs;
use crate::shaper::{Shaper, ShaperBufs, ShaperViews};
use crate::world::PyWorld;

/// The most environments one `VecCore` steps.
const MAX_ENVS: usize = 1 << 20;

/// The most intrinsic rewards (`EmpowermentReward` wrappers) on one `VecCore`.
const MAX_SHAPERS: usize = 4;

/// N episodes of one world, their observation and step buffers.
#[derive(Debug)]
#[pyclass(module = "fulcrum._native")]
pub struct VecCore {
    pyworld: Py<PyWorld>,
    /// The world (on a family, the family's shape: `Family::run_world`).
    world: Arc<World>,
    /// On a family: its layouts, and each environment's current one.
    family: Option<FamilyEnvs>,
    env_worlds: Vec<Arc<World>>,
    layout: Py<PyArray1<u64>>,
    view: View,
    spec: ObsSpec,
    eps: Vec<Episode>,
    /// The last step ended episode e: the next step resets it.
    ended: Vec<bool>,
    /// The last step was a reset step for episode e.
    was_reset: Vec<bool>,
    /// The last step's actions, checked.
    acts: Vec<u8>,
    glyphs: Py<PyArray3<u8>>,
    flags: Py<PyArray2<u8>>,
    mask: Py<PyArray2<i8>>,
    reward: Py<PyArray1<f32>>,
    terminated: Py<PyArray1<bool>>,
    truncated: Py<PyArray1<bool>>,
    states: Py<PyArray2<u8>>,
    shapers: Vec<Shaper>,
    steps: u64,
    /// Environment e's generator for a stochastic world's outcomes.
    rngs: Vec<ChaCha8Rng>,
}

impl VecCore {
    fn bufs<'py>(&self, py: Python<'py>) -> Bufs<'py> {
        Bufs {
            glyphs: self.glyphs.bind(py).clone(),
            flags: self.flags.bind(py).clone(),
            mask: self.mask.bind(py).clone(),
            reward: self.reward.bind(py).clone(),
            terminated: self.terminated.bind(py).clone(),
            truncated: self.truncated.bind(py).clone(),
            states: self.states.bind(py).clone(),
            layout: self.layout.bind(py).clone(),
        }
    }

    /// The actions of one step, checked: any integer array (or sequence) of length N with
    /// values in 0..|A|.
    fn read_actions(&mut self, actions: &Bound<'_, PyAny>) -> PyResult<()> {
        // The common case, a contiguous int64 array: read in place. Anything else goes
        // through numpy (lists, other integer dtypes, strided views) once.
        if let Ok(a) = actions.cast::<PyArray1<i64>>() {
            if a.is_contiguous() {
                // SAFETY: read and copied at once while this thread holds the GIL.
                let s = unsafe { a.as_slice() }
                    .map_err(|_| value_error("actions must be contiguous"))?;
                return self.copy_actions(s);
            }
        }
        let np = actions.py().import("numpy")?;
        let arr = np
            .call_method1("asarray", (actions,))
            .map_err(|_| value_error("actions must be integers, one per environment"))?;
        let kind: String = arr.getattr("dtype")?.getattr("kind")?.extract()?;
        if kind != "i" && kind != "u" {
            return Err(value_error(format!(
                "actions must be integers, not {}",
                arr.getattr("dtype")?.str()?
            )));
        }
        let arr = np.call_method1("ascontiguousarray", (arr, "int64"))?;
        let a = arr.cast::<PyArray1<i64>>().map_err(|_| {
            value_error(format!(
                "actions must be a one-dimensional array of {} integers",
                self.eps.len()
            ))
        })?;
        // SAFETY: as above; the array is our own conversion.
        let s = unsafe { a.as_slice() }.map_err(|_| value_error("actions must be contiguous"))?;
        self.copy_actions(s)
    }

    /// Checks `a` (one action per environment, each in 0..|A|) into `acts`.
    fn copy_actions(&mut self, a: &[i64]) -> PyResult<()> {
        let n = self.eps.len();
        let na = self.world.num_actions() as i64;
        if a.len() != n {
            return Err(value_error(format!(
                "{} actions for {n} environments: give one per environment",
                a.len()
            )));
        }
        for (e, (&x, out)) in a.iter().zip(self.acts.iter_mut()).enumerate() {
            if !(0..na).contains(&x) {
                return Err(value_error(format!(
                    "action {x} of environment {e} is out of range: world '{}' has actions 0..{}",
                    self.world.name,
                    na - 1
                )));
            }
            *out = x as u8;
        }
        Ok(())
    }
}

/// Writes episode `e`'s observation of its state (from scratch), mask and packed state.
fn observe_all(w: &World, view: View, spec: &ObsSpec, ep: &Episode, e: usize, v: &mut Views<'_>) {
    let (c, f, a) = (spec.cells(), spec.flags, w.num_actions());
    let g = &mut v.glyphs[e * c..(e + 1) * c];
    let fl = &mut v.flags[e * f..(e + 1) * f];
    view.observe(w, &ep.state, g, fl);
    write_mask(fl, &mut v.mask[e * a..(e + 1) * a]);
    write_state(ep, &mut v.states[e * 38..(e + 1) * 38]);
}

#[inline]
fn write_mask(flags: &[u8], out: &mut [i8]) {
    let m = action_mask(flags);
    for (k, o) in out.iter_mut().enumerate() {
        *o = ((m >> k) & 1) as i8;
    }
}

#[inline]
fn write_state(ep: &Episode, out: &mut [u8]) {
    out.copy_from_slice(&ep.state.to_bytes());
}

#[pymethods]
impl VecCore {
    /// `num_envs` episodes of `world`, each at the initial state, seen through `view`
    /// (`"full"` or `"crop:R"`); on a world family (a built-in family's name or a file
    /// with a `[family]` table), a layout per episode drawn from `layouts` (`N`, `"all"`,
    /// the default, `"test:K"`, `"test:A..B"` or `"train:K"`; [`crate::layouts`]).
    #[new]
    #[pyo3(signature = (world, num_envs, view = "full", layouts = None))]
    fn new(
        py: Python<'_>,
        world: &Bound<'_, PyAny>,
        num_envs: usize,
        view: &str,
        layouts: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        if !(1..=MAX_ENVS).contains(&num_envs) {
            return Err(value_error(format!(
                "num_envs is {num_envs}: give 1 to {MAX_ENVS}"
            )));
        }
        let view: View = view.parse().map_err(value_error)?;
        let layouts: Option<String> = match layouts {
            None => None,
            Some(l) if l.is_none() => None,
            Some(l) => Some(match l.extract::<u64>() {
                Ok(n) => n.to_string(),
                Err(_) => l.extract::<String>().map_err(|_| {
                    value_error(
                        "layouts is a number of layouts, 'all', 'test:K', 'test:A..B' or 'train:K'",
                    )
                })?,
            }),
        };
        let name: Option<String> = world.extract().ok();
        let family = match (name.as_deref().filter(|n| is_family(n)), layouts) {
            (Some(n), l) => Some(
                FamilyEnvs::new(load_family(n).py_err()?, l.as_deref().unwrap_or("all"))
                    .map_err(value_error)?,
            ),
            (None, None) => None,
            (None, Some(l)) => {
                return Err(value_error(format!(
                    "layouts={l:?} needs a world family, and {} is one world (families: {})",
                    name.map_or("this".to_string(), |n| format!("'{n}'")),
                    fulcrum_world::builtin::FAMILIES.join(", ")
                )))
            }
        };
        let pyworld = match (&family, &name) {
            (Some(_), Some(n)) => Py::new(
                py,
                PyWorld::from_world(load_family(n).py_err()?.run_world().py_err()?),
            )?,
            _ => crate::world::world_arg(world)?,
        };
        let w = Arc::clone(&pyworld.get().world);
        let spec = view.spec(&w);
        let n = num_envs;
        let na = w.num_actions();
        let core = VecCore {
            glyphs: PyArray3::zeros(py, [n, spec.height, spec.width], false).unbind(),
            flags: PyArray2::zeros(py, [n, spec.flags], false).unbind(),
            mask: PyArray2::zeros(py, [n, na], false).unbind(),
            reward: PyArray1::zeros(py, [n], false).unbind(),
            terminated: PyArray1::zeros(py, [n], false).unbind(),
            truncated: PyArray1::zeros(py, [n], false).unbind(),
            states: PyArray2::zeros(py, [n, fulcrum_contracts::msg::STATE_BYTES], false).unbind(),
            layout: PyArray1::zeros(py, [n], false).unbind(),
            env_worlds: vec![Arc::clone(&w); n],
            family,
            eps: vec![w.reset(); n],
            ended: vec![false; n],
            was_reset: vec![true; n],
            acts: vec![0; n],
            view,
            spec,
            world: w,
            pyworld,
            shapers: Vec::new(),
            steps: 0,
            rngs: (0..n as u64).map(ChaCha8Rng::seed_from_u64).collect(),
        };
        let mut me = core;
        me.reset(py, None)?;
        Ok(me)
    }

    /// Seed environment e's generator (a stochastic world's outcomes) with `seeds[e]`;
    /// one seed per environment.
    fn seed(&mut self, seeds: Vec<u64>) -> PyResult<()> {
        if seeds.len() != self.rngs.len() {
            return Err(value_error(format!(
                "{} seeds for {} environments: give one per environment",
                seeds.len(),
                self.rngs.len()
            )));
        }
        for (r, s) in self.rngs.iter_mut().zip(seeds) {
            *r = ChaCha8Rng::seed_from_u64(s);
        }
        Ok(())
    }

    /// Reset every episode, or those where `mask` is true.
    #[pyo3(signature = (mask = None))]
    fn reset(&mut self, py: Python<'_>, mask: Option<PyReadonlyArray1<bool>>) -> PyResult<()> {
        let n = self.eps.len();
        let which: Vec<bool> = match &mask {
            Some(m) => {
                let m = m
                    .as_slice()
                    .map_err(|_| value_error("reset_mask must be contiguous"))?;
                if m.len() != n {
                    return Err(value_error(format!(
                        "reset_mask has {} entries for {n} environments",
                        m.len()
                    )));
                }
                m.to_vec()
            }
            None => vec![true; n],
        };
        let bufs = self.bufs(py);
        // SAFETY: the arrays are only read by Python between calls (see `views`).
        let mut v = unsafe { bufs.views(n, &self.spec, self.world.num_actions())? };
        for e in (0..n).filter(|&e| which[e]) {
            if let Some(f) = self.family.as_mut() {
                let (seed, w) = f.draw(self.rngs[e].next_u64()).map_err(value_error)?;
                v.layout[e] = seed;
                self.env_worlds[e] = w;
            }
            self.eps[e] = self.env_worlds[e].reset();
            self.ended[e] = false;
            self.was_reset[e] = true;
            observe_all(
                &self.env_worlds[e],
                self.view,
                &self.spec,
                &self.eps[e],
                e,
                &mut v,
            );
            v.reward[e] = 0.0;
            v.terminated[e] = false;
            v.truncated[e] = false;
        }
        for sh in &mut self.shapers {
            sh.reset(py, &which, &self.eps, v.layout)?;
        }
        Ok(())
    }

    /// One step of every environment with `actions` (N integers in 0..|A|).
    fn step(&mut self, py: Python<'_>, actions: &Bound<'_, PyAny>) -> PyResult<()> {
        self.read_actions(actions)?;
        let pw = self.pyworld.clone_ref(py);
        let engine = if self.shapers.is_empty() {
            None
        } else {
            Some(pw.get().engine(py)?)
        };
        let n = self.eps.len();
        let bufs = self.bufs(py);
        // SAFETY: as in `reset`.
        let v = unsafe { bufs.views(n, &self.spec, self.world.num_actions())? };
        // At most MAX_SHAPERS, on the stack: a step allocates nothing.
        let sbufs: [Option<ShaperBufs<'_>>; MAX_SHAPERS] =
            std::array::from_fn(|i| self.shapers.get(i).map(|sh| sh.bufs(py)));
        let mut sv: [Option<ShaperViews<'_>>; MAX_SHAPERS] = Default::default();
        for (b, out) in sbufs.iter().zip(sv.iter_mut()) {
            if let Some(b) = b {
                // SAFETY: as above; each shaper's arrays are its own.
                *out = Some(unsafe { b.views(n)? });
            }
        }
        let (view, spec, na) = (self.view, &self.spec, self.world.num_actions());
        let (eps, ended, was_reset, acts, shapers, rngs, family, worlds) = (
            &mut self.eps,
            &mut self.ended,
            &mut self.was_reset,
            &self.acts,
            &mut self.shapers,
            &mut self.rngs,
            &mut self.family,
            &mut self.env_worlds,
        );
        let failed = py.detach(|| {
            let (c, f) = (spec.cells(), spec.flags);
            for e in 0..eps.len() {
                let g = &mut v.glyphs[e * c..(e + 1) * c];
                let fl = &mut v.flags[e * f..(e + 1) * f];
                let prev = eps[e].state;
                // A new layout: the whole observation is drawn afresh.
                let mut fresh = false;
                if ended[e] {
                    if let Some(fam) = family.as_mut() {
                        match fam.draw(rngs[e].next_u64()) {
                            Ok((seed, w)) => {
                                v.layout[e] = seed;
                                worlds[e] = w;
                                fresh = true;
                            }
                            Err(msg) => return Some(msg),
                        }
                    }
                    let w = &worlds[e];
                    eps[e] = w.reset();
                    ended[e] = false;
                    was_reset[e] = true;
                    v.reward[e] = 0.0;
                    v.terminated[e] = false;
                    v.truncated[e] = false;
                } else {
                    let r = &mut rngs[e];
                    let o = worlds[e].env_step_drawn(&mut eps[e], acts[e], || r.next_u64());
                    ended[e] = o.terminated || o.truncated;
                    was_reset[e] = false;
                    v.reward[e] = o.reward;
                    v.terminated[e] = o.terminated;
                    v.truncated[e] = o.truncated;
                }
                if fresh {
                    view.observe(&worlds[e], &eps[e].state, g, fl);
                } else {
                    view.update(&worlds[e], &prev, &eps[e].state, g, fl);
                }
                write_mask(fl, &mut v.mask[e * na..(e + 1) * na]);
                write_state(&eps[e], &mut v.states[e * 38..(e + 1) * 38]);
            }
            if let Some(engine) = engine {
                for (sh, out) in shapers.iter_mut().zip(sv.iter_mut().flatten()) {
                    sh.after_step(engine, eps, acts, was_reset, &v, out);
                }
            }
            None
        });
        if let Some(msg) = failed {
            return Err(value_error(msg));
        }
        self.steps += self.eps.len() as u64;
        Ok(())
    }

    /// Attach an intrinsic reward (`EmpowermentReward`): after each step its arrays hold
    /// the total reward R + beta * b, the intrinsic part beta * b and the value looked up
    /// (E, Phi, or the visit count). Returns them as `(total, intrinsic, value)`.
    #[pyo3(signature = (form, beta, tool, objects, horizon_unequipped, horizon_equipped, gamma, potential_objects="task"))]
    #[allow(clippy::too_many_arguments)]
    fn attach_intrinsic(
        &mut self,
        py: Python<'_>,
        form: &str,
        beta: Option<f64>,
        tool: Option<&str>,
        objects: Option<&str>,
        horizon_unequipped: Option<u32>,
        horizon_equipped: Option<u32>,
        gamma: f64,
        potential_objects: &str,
    ) -> PyResult<crate::shaper::Outputs> {
        if self.shapers.len() == MAX_SHAPERS {
            return Err(value_error(format!(
                "this environment has {MAX_SHAPERS} intrinsic rewards attached already: at most {MAX_SHAPERS}"
            )));
        }
        let settings = crate::shaper::Settings {
            form,
            beta,
            tool,
            objects,
            horizon_unequipped,
            horizon_equipped,
            gamma,
            potential_objects,
        };
        if let Some(f) = &self.family {
            let layouts = self.layout.bind(py).readonly().as_slice()?.to_vec();
            let sh = Shaper::for_family(py, f.family(), f.seeds(), settings, &self.eps, &layouts)?;
            let arrays = sh.arrays(py);
            self.shapers.push(sh);
            return Ok(arrays);
        }
        let pw = self.pyworld.clone_ref(py);
        let engine = pw.get().engine(py)?;
        let mut sh = Shaper::new(py, engine, self.eps.len(), settings)?;
        // Start from where the episodes are now.
        sh.sync(engine, &self.eps)?;
        let arrays = sh.arrays(py);
        self.shapers.push(sh);
        Ok(arrays)
    }

    /// The settings of the attached intrinsic rewards, in order.
    #[getter]
    fn intrinsic_settings(&self) -> Vec<String> {
        self.shapers.iter().map(|s| s.summary()).collect()
    }

    /// The view, as given (`"full"` or `"crop:R"`).
    #[getter]
    fn view(&self) -> String {
        self.view.to_string()
    }

    /// uint8 (N, H, W), or (N, S, S) with a crop: the glyph grids.
    #[getter]
    fn glyphs(&self, py: Python<'_>) -> Py<PyArray3<u8>> {
        self.glyphs.clone_ref(py)
    }

    /// uint8 (N, 2n + 2): the flags.
    #[getter]
    fn flags(&self, py: Python<'_>) -> Py<PyArray2<u8>> {
        self.flags.clone_ref(py)
    }

    /// int8 (N, |A|): the per-mode action masks.
    #[getter]
    fn action_mask(&self, py: Python<'_>) -> Py<PyArray2<i8>> {
        self.mask.clone_ref(py)
    }

    /// float32 (N,): the last step's task rewards.
    #[getter]
    fn reward(&self, py: Python<'_>) -> Py<PyArray1<f32>> {
        self.reward.clone_ref(py)
    }

    /// bool (N,): the last step reached the task's end.
    #[getter]
    fn terminated(&self, py: Python<'_>) -> Py<PyArray1<bool>> {
        self.terminated.clone_ref(py)
    }

    /// bool (N,): the last step ran out of time.
    #[getter]
    fn truncated(&self, py: Python<'_>) -> Py<PyArray1<bool>> {
        self.truncated.clone_ref(py)
    }

    /// uint8 (N, 38): the packed states.
    #[getter]
    fn states(&self, py: Python<'_>) -> Py<PyArray2<u8>> {
        self.states.clone_ref(py)
    }

    /// uint64 (N,): each environment's layout seed on a family (0 on one world).
    #[getter]
    fn layout(&self, py: Python<'_>) -> Py<PyArray1<u64>> {
        self.layout.clone_ref(py)
    }

    /// The layouts episodes are drawn from, as given (`None` on one world).
    #[getter]
    fn layouts(&self) -> Option<String> {
        self.family.as_ref().map(|f| f.label().to_string())
    }

    /// The steps of each episode so far, (N,) uint32.
    #[getter]
    fn episode_steps<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u32>> {
        PyArray1::from_iter(py, self.eps.iter().map(|e| e.t))
    }

    /// Environment steps taken in all (reset steps included).
    #[getter]
    fn total_steps(&self) -> u64 {
        self.steps
    }

    /// Number of environments.
    #[getter]
    fn num_envs(&self) -> usize {
        self.eps.len()
    }

    /// The world.
    #[getter]
    fn world(&self, py: Python<'_>) -> Py<PyWorld> {
        self.pyworld.clone_ref(py)
    }

    /// Environment `e`'s state as an RGB picture (uint8, (H * tile, W * tile, 3)).
    #[pyo3(signature = (e, tile = 16))]
    fn render<'py>(
        &self,
        py: Python<'py>,
        e: usize,
        tile: usize,
    ) -> PyResult<Bound<'py, PyArray3<u8>>> {
        let ep = self.eps.get(e).ok_or_else(|| {
            value_error(format!(
                "environment {e} does not exist (there are {})",
                self.eps.len()
            ))
        })?;
        crate::render::rgb(py, &self.env_worlds[e], &ep.state, tile)
    }

    /// Environment `e`'s map as text, one string per row (its own layout's map).
    fn render_text(&self, e: usize) -> PyResult<Vec<String>> {
        let ep = self.eps.get(e).ok_or_else(|| {
            value_error(format!(
                "environment {e} does not exist (there are {})",
                self.eps.len()
            ))
        })?;
        Ok(self.env_worlds[e]
            .render(&ep.state)
            .lines()
            .map(str::to_string)
            .collect())
    }

    /// The text description of environment `e`'s state.
    fn describe(&self, e: usize) -> PyResult<String> {
        let ep = self.eps.get(e).ok_or_else(|| {
            value_error(format!(
                "environment {e} does not exist (there are {})",
                self.eps.len()
            ))
        })?;
        Ok(self.env_worlds[e].describe(&ep.state))
    }

    fn __repr__(&self) -> String {
        format!("VecCore('{}' x {})", self.world.name, self.eps.len())
    }
}
