//! The intrinsic reward beside a [`VecCore`](crate::venv::VecCore): what the Python
//! wrapper `fulcrum.wrappers.EmpowermentReward` adds to the task reward.
//!
//! For a transition s_t -> s_{t+1} with task reward r_t the total is r_t + beta * b_t,
//! b_t by form exactly as in training (`fulcrum_contracts::intrinsic`, the same code):
//! additive b_t = E(s_{t+1}) (the paper's equation (1)); potential
//! gamma E(s_{t+1}) - E(s_t); horizon-potential the same with Phi = sum over h of E^h;
//! first-visit E(s_{t+1}) once per inventory and episode; count 1 / sqrt(N(s_{t+1})).
//! The potential forms count a destroy task's objects by their conditions only (a
//! boulder intact or destroyed, not its cell) unless `potential_objects="full"` or the
//! objects are named, as in training.
//! E is the exact table of the empowerment service (`request::lookup_table`): E^{h_e}
//! where the tool is held, E^{h_u} elsewhere. Each environment's state id is followed
//! through the state space's successor table, so a lookup is one array read (in a
//! stochastic world the outcome drawn is looked up by its state instead).
//!
//! On a world family each environment's values come from its current layout's table,
//! made the first time the layout is met (the family service's tables,
//! [`FamilyTables`]: the layout's own task object, the tool by the family's
//! `[empowerment]` or `tool`), and a potential form's reset potential from the layout an
//! episode starts in; horizon-potential's default beta is 0.4 over the largest Phi of
//! the first training layouts (at most 16), as `fulcrum train` sets it. The count form is
//! for one world only.
//!
//! Output arrays, float32 (N,): `total` (r + beta b), `intrinsic` (beta b) and `value`
//! (E(s_{t+1}), Phi(s_{t+1}) or N(s_{t+1})). A reset step of the next-step autoreset pays
//! nothing.

use std::str::FromStr;

use fulcrum_contracts::config::PotentialObjects;
use fulcrum_contracts::intrinsic::{bonus, Intrinsic, Shaping};
use fulcrum_empowerment::service::{FamilyConfig, FamilyTables};
use fulcrum_empowerment::{request, Engine, EngineError, ToolSel};
use fulcrum_world::{Episode, MAX_HORIZON};
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;

use crate::bufs::{checked, Views};
use crate::errors::{value_error, IntoPy};

/// What `EmpowermentReward` asks for; `None` takes the world's `[empowerment]` value.
#[derive(Debug)]
pub(crate) struct Settings<'a> {
    pub form: &'a str,
    pub beta: Option<f64>,
    pub tool: Option<&'a str>,
    pub objects: Option<&'a str>,
    pub horizon_unequipped: Option<u32>,
    pub horizon_equipped: Option<u32>,
    pub gamma: f64,
    /// `potential_objects`: `"task"` (a destroy task's objects by their conditions, for
    /// the potential forms) or `"full"`.
    pub potential_objects: &'a str,
}

impl Settings<'_> {
    /// Whether a potential form counts a destroy task's objects by their conditions.
    fn task_conditions(&self, form: Intrinsic) -> PyResult<bool> {
        let p = PotentialObjects::from_str(self.potential_objects).map_err(value_error)?;
        Ok(form.is_potential() && p == PotentialObjects::Task)
    }

    /// Refuses a beta or gamma out of range; the horizons, the defaults where none is
    /// given, refused above [`MAX_HORIZON`].
    fn checked(&self, hu: u32, he: u32) -> PyResult<(u32, u32)> {
        if let Some(beta) = self.beta.filter(|b| !b.is_finite()) {
            return Err(value_error(format!("beta is {beta}: give a finite number")));
        }
        if !(self.gamma.is_finite() && (0.0..=1.0).contains(&self.gamma)) {
            return Err(value_error(format!(
                "gamma is {}: give a number in [0, 1]",
                self.gamma
            )));
        }
        let hu = self.horizon_unequipped.unwrap_or(hu);
        let he = self.horizon_equipped.unwrap_or(he);
        for h in [hu, he] {
            if h > MAX_HORIZON {
                return Err(EngineError::HorizonTooLarge {
                    h,
                    max: MAX_HORIZON,
                })
                .py_err();
            }
        }
        Ok((hu, he))
    }
}

/// One attached intrinsic reward and its per-environment state.
#[derive(Debug)]
pub(crate) struct Shaper {
    shaping: Shaping,
    beta: f32,
    /// E or Phi per state id (empty for the count and none forms).
    values: Vec<f32>,
    /// Visits per state id (the count form).
    visits: Vec<u32>,
    init_id: u32,
    ids: Vec<u32>,
    phi: Vec<f32>,
    inv: Vec<u16>,
    paid: Vec<bool>,
    total: Py<PyArray1<f32>>,
    intrinsic: Py<PyArray1<f32>>,
    value: Py<PyArray1<f32>>,
    summary: String,
    scratch: Scratch,
    /// On a world family: a table per layout; `values` and the ids are unused.
    family: Option<FamilyTables>,
}

/// One step's inputs to [`Shaping::chunk`] and its output, per environment.
#[derive(Debug)]
struct Scratch {
    next: Vec<f32>,
    next_inv: Vec<u16>,
    terminated: Vec<u8>,
    truncated: Vec<u8>,
    bonus: Vec<f32>,
}

/// The output arrays: total reward, intrinsic part, value looked up.
pub(crate) type Outputs = (Py<PyArray1<f32>>, Py<PyArray1<f32>>, Py<PyArray1<f32>>);

/// A shaper's output arrays, bound for one call.
pub(crate) struct ShaperBufs<'py> {
    total: Bound<'py, PyArray1<f32>>,
    intrinsic: Bound<'py, PyArray1<f32>>,
    value: Bound<'py, PyArray1<f32>>,
}

/// A shaper's output arrays as slices.
pub(crate) struct ShaperViews<'a> {
    total: &'a mut [f32],
    intrinsic: &'a mut [f32],
    value: &'a mut [f32],
}

impl ShaperBufs<'_> {
    /// # Safety
    /// As [`crate::venv`]'s views: nothing else uses these arrays' data meanwhile.
    pub(crate) unsafe fn views(&self, n: usize) -> PyResult<ShaperViews<'_>> {
        unsafe {
            Ok(ShaperViews {
                total: checked("total reward", self.total.as_slice_mut(), n)?,
                intrinsic: checked("intrinsic reward", self.intrinsic.as_slice_mut(), n)?,
                value: checked("empowerment", self.value.as_slice_mut(), n)?,
            })
        }
    }
}

impl Shaper {
    pub(crate) fn new(
        py: Python<'_>,
        engine: &Engine<'_>,
        n: usize,
        s: Settings<'_>,
    ) -> PyResult<Shaper> {
        let w = engine.world;
        let form = Intrinsic::from_str(s.form).map_err(value_error)?;
        let (hu, he) = s.checked(
            w.empowerment.horizon_unequipped,
            w.empowerment.horizon_equipped,
        )?;
        let space_len = engine.space.len();
        let beta;
        let (values, summary) = if form.uses_empowerment() {
            let set =
                request::potential_objects(w, s.objects, s.task_conditions(form)?).py_err()?;
            let (tool, values) = py
                .detach(|| {
                    request::lookup_table(w, engine, s.tool, &set, hu, he, form.horizon_sum())
                })
                .py_err()?;
            // The largest potential sets horizon-potential's default beta, as in training.
            let max_phi = values.iter().copied().fold(0.0f32, f32::max) as f64;
            beta = s
                .beta
                .unwrap_or(form.default_beta(w.empowerment.beta, max_phi));
            let what = match tool {
                ToolSel::All => "all".to_string(),
                t => t.name(w),
            };
            let summary = format!(
                "{form}: beta {beta}, {what} -> {}, h {hu} unequipped / {he} equipped, gamma {}",
                fulcrum_empowerment::set_name(w, &set),
                s.gamma
            );
            (values, summary)
        } else {
            beta = s.beta.unwrap_or(form.default_beta(w.empowerment.beta, 0.0));
            (Vec::new(), format!("{form}: beta {beta}"))
        };
        let init_id = engine.state_id(&w.initial).py_err()?;
        let phi_reset = if form.is_potential() {
            values[init_id as usize]
        } else {
            0.0
        };
        Ok(Shaper {
            shaping: Shaping {
                form,
                gamma: s.gamma as f32,
                phi_reset,
                inventory_reset: w.initial.inventory,
            },
            beta: beta as f32,
            visits: if form == Intrinsic::Count {
                vec![0; space_len]
            } else {
                Vec::new()
            },
            values,
            init_id,
            ids: vec![init_id; n],
            phi: vec![phi_reset; n],
            inv: vec![w.initial.inventory; n],
            paid: vec![false; n],
            total: PyArray1::zeros(py, [n], false).unbind(),
            intrinsic: PyArray1::zeros(py, [n], false).unbind(),
            value: PyArray1::zeros(py, [n], false).unbind(),
            summary,
            scratch: Scratch {
                next: vec![0.0; n],
                next_inv: vec![0; n],
                terminated: vec![0; n],
                truncated: vec![0; n],
                bonus: vec![0.0; n],
            },
            family: None,
        })
    }

    /// The shaper of a family's environments, whose episodes play the layouts `seeds`
    /// and are now at `eps` on the layouts `layouts`.
    pub(crate) fn for_family(
        py: Python<'_>,
        family: &fulcrum_world::family::Family,
        seeds: std::ops::Range<u64>,
        s: Settings<'_>,
        eps: &[Episode],
        layouts: &[u64],
    ) -> PyResult<Shaper> {
        let form = Intrinsic::from_str(s.form).map_err(value_error)?;
        if form == Intrinsic::Count {
            return Err(value_error(
                "the count form counts the visits of one world's states: on a family's layouts it is not offered",
            ));
        }
        if s.objects.is_some() {
            return Err(value_error(format!(
                "objects does not fit a world family: each layout of '{}' names its own task object",
                family.name
            )));
        }
        let (hu, he) = s.checked(family.horizon_unequipped, family.horizon_equipped)?;
        let cfg = FamilyConfig {
            tool: s.tool.map(str::to_string),
            horizon_unequipped: hu,
            horizon_equipped: he,
            horizon_sum: form.horizon_sum(),
            task_conditions: s.task_conditions(form)?,
            cache_bytes: 256 << 20,
            keep: 0,
        };
        let mut tables = FamilyTables::new(family.clone(), cfg).map_err(value_error)?;
        // The training layouts' potentials set horizon-potential's default beta (held-out
        // layouts: the first 16 training layouts, as a run on every layout has).
        let top = if seeds.start == 0 {
            seeds.end
        } else {
            u64::MAX
        }
        .min(16);
        let mut max = 0.0f32;
        if form.uses_empowerment() {
            for seed in 0..top {
                max = max.max(py.detach(|| tables.max_value(seed)).ok_or_else(|| {
                    value_error(format!("layout {seed} of '{}' has no table", family.name))
                })?);
            }
        }
        let beta = s.beta.unwrap_or(form.default_beta(family.beta, max as f64));
        let n = eps.len();
        let mut sh = Shaper {
            shaping: Shaping {
                form,
                gamma: s.gamma as f32,
                phi_reset: 0.0,
                inventory_reset: 0,
            },
            beta: beta as f32,
            visits: Vec::new(),
            values: Vec::new(),
            init_id: 0,
            ids: vec![0; n],
            phi: vec![0.0; n],
            inv: vec![0; n],
            paid: vec![false; n],
            total: PyArray1::zeros(py, [n], false).unbind(),
            intrinsic: PyArray1::zeros(py, [n], false).unbind(),
            value: PyArray1::zeros(py, [n], false).unbind(),
            summary: format!(
                "{form}: beta {beta}, {} -> each layout's task object, h {hu} unequipped / {he} equipped, gamma {}",
                s.tool.unwrap_or("the family's tool"),
                s.gamma
            ),
            scratch: Scratch {
                next: vec![0.0; n],
                next_inv: vec![0; n],
                terminated: vec![0; n],
                truncated: vec![0; n],
                bonus: vec![0.0; n],
            },
            family: Some(tables),
        };
        sh.sync_family(eps, layouts);
        Ok(sh)
    }

    /// A family's episodes start (again) where they are now: potential, inventory.
    fn sync_family(&mut self, eps: &[Episode], layouts: &[u64]) {
        let potential = self.shaping.form.is_potential();
        let Some(t) = self.family.as_mut() else {
            return;
        };
        for (e, ep) in eps.iter().enumerate() {
            self.phi[e] = if potential {
                t.lookup(layouts[e], &ep.state).unwrap_or(0.0)
            } else {
                0.0
            };
            self.inv[e] = ep.state.inventory;
            self.paid[e] = false;
        }
    }

    /// Take the episodes' current states as the start (attaching mid-episode).
    pub(crate) fn sync(&mut self, engine: &Engine<'_>, eps: &[Episode]) -> PyResult<()> {
        for (e, ep) in eps.iter().enumerate() {
            let id = engine.state_id(&ep.state).py_err()?;
            self.ids[e] = id;
            self.phi[e] = if self.shaping.form.is_potential() {
                self.values[id as usize]
            } else {
                0.0
            };
            self.inv[e] = ep.state.inventory;
            self.paid[e] = false;
        }
        Ok(())
    }

    /// The episodes where `which` is true start again (at `eps`, on the layouts
    /// `layouts` of a family).
    pub(crate) fn reset(
        &mut self,
        py: Python<'_>,
        which: &[bool],
        eps: &[Episode],
        layouts: &[u64],
    ) -> PyResult<()> {
        let b = self.bufs(py);
        // SAFETY: as in `views`.
        let v = unsafe { b.views(which.len())? };
        let potential = self.shaping.form.is_potential();
        for (e, _) in which.iter().enumerate().filter(|(_, &w)| w) {
            self.ids[e] = self.init_id;
            self.phi[e] = match self.family.as_mut() {
                Some(t) if potential => t.lookup(layouts[e], &eps[e].state).unwrap_or(0.0),
                Some(_) => 0.0,
                None => self.shaping.phi_reset,
            };
            self.inv[e] = match self.family {
                Some(_) => eps[e].state.inventory,
                None => self.shaping.inventory_reset,
            };
            self.paid[e] = false;
            v.total[e] = 0.0;
            v.intrinsic[e] = 0.0;
            v.value[e] = 0.0;
        }
        Ok(())
    }

    pub(crate) fn bufs<'py>(&self, py: Python<'py>) -> ShaperBufs<'py> {
        ShaperBufs {
            total: self.total.bind(py).clone(),
            intrinsic: self.intrinsic.bind(py).clone(),
            value: self.value.bind(py).clone(),
        }
    }

    pub(crate) fn arrays(&self, py: Python<'_>) -> Outputs {
        (
            self.total.clone_ref(py),
            self.intrinsic.clone_ref(py),
            self.value.clone_ref(py),
        )
    }

    pub(crate) fn summary(&self) -> String {
        self.summary.clone()
    }

    /// The intrinsic reward of the step just taken (`v` holds its task rewards and flags).
    pub(crate) fn after_step(
        &mut self,
        engine: &Engine<'_>,
        eps: &[Episode],
        acts: &[u8],
        was_reset: &[bool],
        v: &Views<'_>,
        out: &mut ShaperViews<'_>,
    ) {
        let form = self.shaping.form;
        let n = eps.len();
        if self.family.is_some() {
            self.after_family_step(eps, was_reset, v, out);
            return;
        }
        if form == Intrinsic::Additive {
            // The paper's form, b_t = E(s_{t+1}) (`intrinsic::bonus`): one tight pass.
            let (succ, na) = (engine.space.succ_table(), engine.space.num_actions());
            let (beta, init) = (self.beta, self.init_id);
            let chance = engine.world.is_stochastic();
            let outs = out
                .total
                .iter_mut()
                .zip(out.intrinsic.iter_mut())
                .zip(out.value.iter_mut());
            let ins = self
                .ids
                .iter_mut()
                .zip(acts)
                .zip(was_reset)
                .zip(v.reward.iter())
                .zip(eps);
            for (((((id, &a), &reset), &r), ep), ((total, intrinsic), value)) in ins.zip(outs) {
                if reset {
                    *id = init;
                    (*total, *intrinsic, *value) = (0.0, 0.0, 0.0);
                    continue;
                }
                *id = if chance {
                    drawn_id(engine, &ep.state)
                } else {
                    succ[*id as usize * na + a as usize]
                };
                let e = self.values[*id as usize];
                *intrinsic = beta * e;
                *total = r + beta * e;
                *value = e;
            }
            return;
        }
        if form.is_potential() {
            // The default form, b_t = gamma Phi(s_{t+1}) - Phi(s_t) (0 potential when
            // terminal; `intrinsic::bonus`), and the potential `Shaping::chunk` carries
            // from one step to the next (the start's after an episode ends), in one pass
            // as the additive form's: `Shaping::chunk`'s passes through scratch arrays
            // cost a vector step more than the lookups themselves. The inventories and
            // paid flags are first-visit's alone.
            let (succ, na) = (engine.space.succ_table(), engine.space.num_actions());
            let chance = engine.world.is_stochastic();
            let (shaping, beta, init) = (self.shaping, self.beta, self.init_id);
            let phi_reset = shaping.phi_reset;
            let values = &self.values;
            let outs = out
                .total
                .iter_mut()
                .zip(out.intrinsic.iter_mut())
                .zip(out.value.iter_mut());
            let carried = self.ids.iter_mut().zip(self.phi.iter_mut());
            let ins = acts
                .iter()
                .zip(was_reset)
                .zip(
                    v.reward
                        .iter()
                        .zip(v.terminated.iter().zip(v.truncated.iter())),
                )
                .zip(eps);
            for (
                (((&a, &was), (&r, (&term, &trunc))), ep),
                ((id, phi), ((total, intrinsic), value)),
            ) in ins.zip(carried.zip(outs))
            {
                if was {
                    (*id, *phi) = (init, phi_reset);
                    (*total, *intrinsic, *value) = (r, 0.0, 0.0);
                    continue;
                }
                *id = if chance {
                    drawn_id(engine, &ep.state)
                } else {
                    succ[*id as usize * na + a as usize]
                };
                let next = values[*id as usize];
                let b = beta * shaping.advance(phi, next, term, trunc, phi_reset);
                (*total, *intrinsic, *value) = (r + b, b, next);
            }
            return;
        }
        if form != Intrinsic::FirstVisit {
            // The other forms without per-episode state (count, none): one pass, b_t
            // from s_{t+1} alone.
            for e in 0..n {
                if was_reset[e] {
                    self.ids[e] = self.init_id;
                    out.total[e] = 0.0;
                    out.intrinsic[e] = 0.0;
                    out.value[e] = 0.0;
                    continue;
                }
                let id = next_id(engine, self.ids[e], acts[e], &eps[e]);
                self.ids[e] = id;
                let next = if form == Intrinsic::Count {
                    let c = &mut self.visits[id as usize];
                    *c = c.saturating_add(1);
                    *c as f32
                } else {
                    0.0
                };
                let b = bonus(form, self.shaping.gamma, 0.0, next, v.terminated[e]);
                let intrinsic = self.beta * b;
                out.intrinsic[e] = intrinsic;
                out.total[e] = v.reward[e] + intrinsic;
                out.value[e] = next;
            }
            return;
        }
        let s = &mut self.scratch;
        for e in 0..n {
            if was_reset[e] {
                // The step that started a new episode: no transition (fixed up below).
                self.ids[e] = self.init_id;
                s.next[e] = 0.0;
                s.next_inv[e] = self.shaping.inventory_reset;
                s.terminated[e] = 0;
                s.truncated[e] = 0;
                continue;
            }
            // First-visit, b_t = E(s_{t+1}) once per inventory and episode (the one
            // form left to come here).
            let id = next_id(engine, self.ids[e], acts[e], &eps[e]);
            self.ids[e] = id;
            s.next[e] = self.values[id as usize];
            s.next_inv[e] = eps[e].state.inventory;
            s.terminated[e] = v.terminated[e] as u8;
            s.truncated[e] = v.truncated[e] as u8;
        }
        let (phi, inv) = (self.shaping.phi_reset, self.shaping.inventory_reset);
        self.pay(was_reset, v, out, |_| (phi, inv));
    }

    /// One time step of n worlds from the scratch's inputs (as an actor's chunk is T of
    /// them), then the outputs; an episode that starts again at this step is paid
    /// nothing and starts from `start(e)`: its potential and inventory.
    fn pay(
        &mut self,
        was_reset: &[bool],
        v: &Views<'_>,
        out: &mut ShaperViews<'_>,
        start: impl Fn(usize) -> (f32, u16),
    ) {
        let s = &mut self.scratch;
        self.shaping.chunk(
            &s.next,
            &s.next_inv,
            &s.terminated,
            &s.truncated,
            &mut self.phi,
            &mut self.inv,
            &mut self.paid,
            &mut s.bonus,
        );
        for (e, &reset) in was_reset.iter().enumerate() {
            if reset {
                s.bonus[e] = 0.0;
                (self.phi[e], self.inv[e]) = start(e);
                self.paid[e] = false;
            }
            let intrinsic = self.beta * s.bonus[e];
            out.intrinsic[e] = intrinsic;
            out.total[e] = v.reward[e] + intrinsic;
            out.value[e] = s.next[e];
        }
    }
}

impl Shaper {
    /// [`Shaper::after_step`] on a family: each value from the environment's current
    /// layout's table, each reset potential from the layout the new episode plays.
    fn after_family_step(
        &mut self,
        eps: &[Episode],
        was_reset: &[bool],
        v: &Views<'_>,
        out: &mut ShaperViews<'_>,
    ) {
        let form = self.shaping.form;
        let Some(tables) = self.family.as_mut() else {
            return;
        };
        if form != Intrinsic::FirstVisit {
            // The forms without per-episode inventories (additive, the potentials, none):
            // one pass, as on one world, the potential carried from step to step and a
            // new episode's taken from its own layout (the inventories and paid flags
            // are first-visit's alone).
            let (shaping, beta) = (self.shaping, self.beta);
            let phi_reset = shaping.phi_reset;
            let (uses, potential) = (form.uses_empowerment(), form.is_potential());
            for (e, ep) in eps.iter().enumerate() {
                let value = if uses {
                    tables.lookup(v.layout[e], &ep.state).unwrap_or(0.0)
                } else {
                    0.0
                };
                let r = v.reward[e];
                if was_reset[e] {
                    // The step that started a new episode pays nothing; its value is
                    // the new episode's start potential.
                    self.phi[e] = if potential { value } else { 0.0 };
                    (out.total[e], out.intrinsic[e], out.value[e]) = (r, 0.0, 0.0);
                    continue;
                }
                let (term, trunc) = (v.terminated[e], v.truncated[e]);
                let intrinsic =
                    beta * shaping.advance(&mut self.phi[e], value, term, trunc, phi_reset);
                (out.total[e], out.intrinsic[e], out.value[e]) = (r + intrinsic, intrinsic, value);
            }
            return;
        }
        // First-visit (the one form left): E(s_{t+1}) once per inventory and episode,
        // through `Shaping::chunk`; a new episode starts from nothing paid.
        let s = &mut self.scratch;
        for (e, ep) in eps.iter().enumerate() {
            s.next[e] = if was_reset[e] {
                0.0
            } else {
                tables.lookup(v.layout[e], &ep.state).unwrap_or(0.0)
            };
            s.next_inv[e] = ep.state.inventory;
            s.terminated[e] = (v.terminated[e] && !was_reset[e]) as u8;
            s.truncated[e] = (v.truncated[e] && !was_reset[e]) as u8;
        }
        self.pay(was_reset, v, out, |e| (0.0, eps[e].state.inventory));
    }
}

/// The id of the state an episode stepped to from `id` with `a`: the successor table's
/// entry in a deterministic world; in a stochastic one the outcome drawn is not the
/// table's (the intended one), so it is looked up.
#[inline]
fn next_id(engine: &Engine<'_>, id: u32, a: u8, ep: &Episode) -> u32 {
    if engine.world.is_stochastic() {
        drawn_id(engine, &ep.state)
    } else {
        engine.space.succ(id, a)
    }
}

/// The id of a state a stochastic world's episode reached: in the state space, which
/// holds every state of positive probability from the start.
#[inline]
fn drawn_id(engine: &Engine<'_>, s: &fulcrum_world::State) -> u32 {
    engine.space.id(s).expect(
        "a sampled outcome is in the state space (it holds every state of positive probability)",
    )
}
