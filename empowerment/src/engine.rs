//! The engine: one world's state space, and the questions asked of it: values, the
//! tool-object matrix and tool selection, landscapes, traces and single queries.
//!
//! The matrix entry `[j, i]` is the mean of `E^h_{j,{i}}(s)` over the normal-mode states
//! of the space, with `h = horizon_equipped` where tool j is held and
//! `horizon_unequipped` elsewhere; tool selection (`tool = "auto"`) asks for one horizon,
//! [`crate::request::selection_horizon`], for both, which keeps the rows comparable
//! (`docs/world.md`). Selection for a column is its argmax, ties to the lower tool index,
//! a column of zeros selects no tool (equation 6).
//!
//! In a stochastic world every value is a channel capacity ([`crate::stochastic`]) and
//! comes with a gap: the capacity lies in `[value, value + gap]`; the gap is 0 wherever
//! the value is exact (deterministic worlds, the closed form of two outputs).

use fulcrum_world::{Mode, ObjectSet, State, World};
use rayon::prelude::*;

use crate::capacity::Capacity;
use crate::enumerate;
use crate::error::EngineError;
use crate::limits::Limits;
use crate::propagate::{check_table, reachable_counts, Projection};
use crate::space::StateSpace;
use crate::stochastic::Chance;

/// Whose actions drive the channel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ToolSel {
    /// Tool j's subset {N, E, S, W, apply, select_j}.
    Tool(usize),
    /// The full action set A.
    All,
}

impl ToolSel {
    /// The action subset.
    pub fn actions(&self, world: &World) -> Vec<u8> {
        match *self {
            ToolSel::Tool(j) => world.tool_actions(j).to_vec(),
            ToolSel::All => (0..world.num_actions() as u8).collect(),
        }
    }

    /// Its name (`axe`, `all`).
    pub fn name(&self, world: &World) -> String {
        match *self {
            ToolSel::Tool(j) => world.tools[j].name.clone(),
            ToolSel::All => "all".to_string(),
        }
    }

    /// Whether this tool is held in `s` (`all` counts as never held).
    pub fn held(&self, s: &State) -> bool {
        matches!(*self, ToolSel::Tool(j) if s.holds(j))
    }
}

/// How values are computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Method {
    /// Set propagation over the state space (fast, exact).
    #[default]
    Dp,
    /// Enumerate every action sequence (the paper's method; the reference).
    Enumerate,
}

/// The name of an object set: `tree`, `boulder+door`, `agent`, `conditions:boulder`.
pub fn set_name(world: &World, set: &ObjectSet) -> String {
    let names = |v: &[usize]| {
        v.iter()
            .map(|&i| world.objects[i].name.as_str())
            .collect::<Vec<_>>()
            .join("+")
    };
    match set {
        ObjectSet::Agent => "agent".to_string(),
        ObjectSet::Objects(v) => names(v),
        ObjectSet::Conditions { objects, .. } => format!("conditions:{}", names(objects)),
    }
}

/// The objects of a set, one name each, as the `--json` outputs and the Python package
/// list them: `agent`; an object's name; `conditions:NAME` for an object counted by its
/// condition only.
pub fn set_objects(world: &World, set: &ObjectSet) -> Vec<String> {
    match set {
        ObjectSet::Agent => vec!["agent".to_string()],
        ObjectSet::Objects(v) => v.iter().map(|&i| world.objects[i].name.clone()).collect(),
        ObjectSet::Conditions { objects, .. } => objects
            .iter()
            .map(|&i| format!("conditions:{}", world.objects[i].name))
            .collect(),
    }
}

/// The tool-object empowerment matrix and the selection it makes.
#[derive(Clone, Debug, PartialEq)]
pub struct Matrix {
    /// Row names (tools in file order).
    pub tools: Vec<String>,
    /// Column names.
    pub columns: Vec<String>,
    /// `values[j][c]`, bits.
    pub values: Vec<Vec<f64>>,
    /// Selected tool per column (None: every entry is zero).
    pub selection: Vec<Option<usize>>,
    /// Normal-mode states averaged over.
    pub normal_states: usize,
    /// The largest gap of the values averaged (bits; 0 in a deterministic world).
    pub gap: f64,
}

/// argmax with ties to the lower index; all zero -> None.
pub fn select(column: impl IntoIterator<Item = f64>) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for (j, v) in column.into_iter().enumerate() {
        if v > 0.0 && best.is_none_or(|(_, b)| v > b) {
            best = Some((j, v));
        }
    }
    best.map(|(j, _)| j)
}

/// A matrix entry from its values over the normal states, in their order: their mean
/// (summed in that order), 0 where there is none.
pub(crate) fn normal_mean(values: impl ExactSizeIterator<Item = f64>) -> f64 {
    let n = values.len();
    let sum: f64 = values.sum();
    if n == 0 {
        0.0
    } else {
        sum / n as f64
    }
}

/// Values over the map for one inventory: `values[y][x]`, None where that state does not
/// exist.
#[derive(Clone, Debug, PartialEq)]
pub struct Landscape {
    /// `values[y][x]`.
    pub values: Vec<Vec<Option<f64>>>,
    /// The largest gap of the values (bits; 0 in a deterministic world).
    pub gap: f64,
}

/// One step of a trace.
#[derive(Clone, Debug, PartialEq)]
pub struct TraceStep {
    /// The action that led here (None at t = 0).
    pub action: Option<u8>,
    /// The state after it.
    pub state: State,
    /// E at that state.
    pub value: f64,
    /// Its gap (bits; 0 in a deterministic world).
    pub gap: f64,
}

/// One world's state space and the questions asked of it.
#[derive(Debug)]
pub struct Engine<'w> {
    /// The world.
    pub world: &'w World,
    /// Its enumerated state space.
    pub space: StateSpace,
    /// Memory limits for tables.
    pub limits: Limits,
}

impl<'w> Engine<'w> {
    /// Enumerate the world's state space.
    pub fn new(world: &'w World, limits: Limits) -> Result<Self, EngineError> {
        let space = StateSpace::enumerate(world, &limits)?;
        Ok(Engine {
            world,
            space,
            limits,
        })
    }

    /// The state space, the engine given up.
    pub fn into_space(self) -> StateSpace {
        self.space
    }

    /// Number of normal-mode states.
    pub fn normal_states(&self) -> usize {
        self.space.normal_ids().count()
    }

    /// `counts[k][s] = |R_{horizons[k]}(s)|` for every state.
    pub fn counts(
        &self,
        tool: ToolSel,
        set: &ObjectSet,
        horizons: &[u32],
        method: Method,
    ) -> Result<Vec<Vec<u32>>, EngineError> {
        if self.world.is_stochastic() {
            return Err(EngineError::Deterministic(format!(
                "world '{}' is stochastic: its empowerment is a channel capacity, not a count of outcomes",
                self.world.name
            )));
        }
        let actions = tool.actions(self.world);
        let hmax = horizons.iter().copied().max().unwrap_or(0);
        match method {
            Method::Dp => {
                let proj = Projection::new(&self.space, set);
                let what = format!("{} -> {}", tool.name(self.world), set_name(self.world, set));
                check_table(&self.space, &proj, hmax, &what, &self.limits)?;
                Ok(reachable_counts(&self.space, &proj, &actions, horizons))
            }
            Method::Enumerate => {
                let ids: Vec<u32> = (0..self.space.len() as u32).collect();
                let per = self.enumerate_counts(&ids, &actions, set, horizons)?;
                Ok(per)
            }
        }
    }

    /// Enumerate counts at the given states, for each horizon.
    fn enumerate_counts(
        &self,
        ids: &[u32],
        actions: &[u8],
        set: &ObjectSet,
        horizons: &[u32],
    ) -> Result<Vec<Vec<u32>>, EngineError> {
        check_enumerable(actions.len(), horizons, ids.len())?;
        Ok(horizons
            .iter()
            .map(|&h| {
                ids.par_iter()
                    .map(|&i| {
                        enumerate::reachable_count(self.world, self.space.state(i), actions, set, h)
                            as u32
                    })
                    .collect()
            })
            .collect())
    }

    /// E^h(s) in bits for every state.
    pub fn values(
        &self,
        tool: ToolSel,
        set: &ObjectSet,
        h: u32,
        method: Method,
    ) -> Result<Vec<f64>, EngineError> {
        if self.world.is_stochastic() {
            return Ok(self.values_gap(tool, set, h, method)?.0);
        }
        let c = self.counts(tool, set, &[h], method)?;
        Ok(c[0].iter().map(|&n| (n as f64).log2()).collect())
    }

    /// E^h(s) in bits for every state, and each value's gap (all 0 in a deterministic
    /// world).
    pub fn values_gap(
        &self,
        tool: ToolSel,
        set: &ObjectSet,
        h: u32,
        method: Method,
    ) -> Result<(Vec<f64>, Vec<f64>), EngineError> {
        if !self.world.is_stochastic() {
            let v = self.values(tool, set, h, method)?;
            let n = v.len();
            return Ok((v, vec![0.0; n]));
        }
        let ids: Vec<u32> = (0..self.space.len() as u32).collect();
        let c = self.values_at(tool, set, h, &ids, method)?;
        Ok(c.iter().map(|c| (c.bits, c.gap)).unzip())
    }

    /// E^h at the states `ids`, with their gaps. A stochastic world computes only
    /// these states; a deterministic one reads them from its table.
    pub fn values_at(
        &self,
        tool: ToolSel,
        set: &ObjectSet,
        h: u32,
        ids: &[u32],
        method: Method,
    ) -> Result<Vec<Capacity>, EngineError> {
        if !self.world.is_stochastic() {
            let v = self.values(tool, set, h, method)?;
            return Ok(ids
                .iter()
                .map(|&i| Capacity {
                    bits: v[i as usize],
                    gap: 0.0,
                })
                .collect());
        }
        if h > fulcrum_world::MAX_HORIZON {
            return Err(EngineError::HorizonTooLarge {
                h,
                max: fulcrum_world::MAX_HORIZON,
            });
        }
        let actions = tool.actions(self.world);
        match method {
            Method::Dp => {
                let proj = Projection::new(&self.space, set);
                Chance::new(
                    &self.space,
                    &proj,
                    &actions,
                    h,
                    self.limits.max_bytes.saturating_sub(self.space.bytes()),
                )
                .values(ids, h)
            }
            Method::Enumerate => {
                check_enumerable(actions.len(), &[h], ids.len())?;
                Ok(ids
                    .par_iter()
                    .map(|&i| {
                        enumerate::stochastic_value(
                            self.world,
                            self.space.state(i),
                            &actions,
                            set,
                            h,
                        )
                    })
                    .collect())
            }
        }
    }

    /// E at the states `ids` of a stochastic world with the horizon by inventory:
    /// `he` where `tool` is held, `hu` elsewhere.
    fn chance_by_inventory(
        &self,
        tool: ToolSel,
        set: &ObjectSet,
        hu: u32,
        he: u32,
        ids: &[u32],
        method: Method,
    ) -> Result<Vec<Capacity>, EngineError> {
        let (held, free): (Vec<usize>, Vec<usize>) =
            (0..ids.len()).partition(|&k| tool.held(self.space.state(ids[k])));
        let mut out = vec![Capacity::default(); ids.len()];
        for (part, h) in [(free, hu), (held, he)] {
            if part.is_empty() {
                continue;
            }
            let sub: Vec<u32> = part.iter().map(|&k| ids[k]).collect();
            for (k, c) in part.iter().zip(self.values_at(tool, set, h, &sub, method)?) {
                out[*k] = c;
            }
        }
        Ok(out)
    }

    /// The matrix over every tool of the world and the given columns.
    pub fn matrix(
        &self,
        columns: &[ObjectSet],
        horizon_unequipped: u32,
        horizon_equipped: u32,
        method: Method,
    ) -> Result<Matrix, EngineError> {
        let normal: Vec<u32> = self.space.normal_ids().collect();
        if self.world.is_stochastic() {
            return self.chance_matrix(
                columns,
                horizon_unequipped,
                horizon_equipped,
                method,
                &normal,
            );
        }
        let n_tools = self.world.tools.len();
        let pairs: Vec<(usize, usize)> = (0..n_tools)
            .flat_map(|j| (0..columns.len()).map(move |c| (j, c)))
            .collect();
        let horizons = [horizon_unequipped, horizon_equipped];
        let mut values = vec![vec![0.0; columns.len()]; n_tools];
        // Projections depend on the column only: make each once.
        let projs: Vec<Projection> = match method {
            Method::Dp => columns
                .iter()
                .map(|c| Projection::new(&self.space, c))
                .collect(),
            Method::Enumerate => Vec::new(),
        };
        let entry = |&(j, c): &(usize, usize)| -> Result<f64, EngineError> {
            let tool = ToolSel::Tool(j);
            let actions = tool.actions(self.world);
            let counts = match method {
                Method::Dp => {
                    let what = format!(
                        "{} -> {}",
                        tool.name(self.world),
                        set_name(self.world, &columns[c])
                    );
                    check_table(
                        &self.space,
                        &projs[c],
                        horizon_unequipped.max(horizon_equipped),
                        &what,
                        &self.limits,
                    )?;
                    let all = reachable_counts(&self.space, &projs[c], &actions, &horizons);
                    // Keep only the normal states, in `normal` order.
                    all.into_iter()
                        .map(|v| normal.iter().map(|&i| v[i as usize]).collect::<Vec<u32>>())
                        .collect::<Vec<_>>()
                }
                Method::Enumerate => {
                    self.enumerate_counts(&normal, &actions, &columns[c], &horizons)?
                }
            };
            Ok(normal_mean(normal.iter().enumerate().map(|(k, &i)| {
                let held = tool.held(self.space.state(i));
                (counts[held as usize][k] as f64).log2()
            })))
        };
        // Small spaces: one entry per thread beats splitting each propagation step (whose
        // fork-join costs more than the step). Large ones: one table at a time, each step
        // split across the threads, so memory holds a single table.
        let results: Vec<f64> = if self.space.len() <= SMALL_SPACE && method == Method::Dp {
            pairs.par_iter().map(entry).collect::<Result<_, _>>()?
        } else {
            pairs.iter().map(entry).collect::<Result<_, _>>()?
        };
        for (&(j, c), v) in pairs.iter().zip(results) {
            values[j][c] = v;
        }
        let selection = (0..columns.len())
            .map(|c| select(values.iter().map(|row| row[c])))
            .collect();
        Ok(Matrix {
            tools: self.world.tools.iter().map(|t| t.name.clone()).collect(),
            columns: columns.iter().map(|c| set_name(self.world, c)).collect(),
            values,
            selection,
            normal_states: normal.len(),
            gap: 0.0,
        })
    }

    /// [`Engine::matrix`] of a stochastic world: each entry the mean capacity over the
    /// normal states, one entry after another (each is parallel over states).
    fn chance_matrix(
        &self,
        columns: &[ObjectSet],
        hu: u32,
        he: u32,
        method: Method,
        normal: &[u32],
    ) -> Result<Matrix, EngineError> {
        let n_tools = self.world.tools.len();
        let mut values = vec![vec![0.0; columns.len()]; n_tools];
        let mut gap: f64 = 0.0;
        for (j, row) in values.iter_mut().enumerate() {
            for (c, set) in columns.iter().enumerate() {
                let caps =
                    self.chance_by_inventory(ToolSel::Tool(j), set, hu, he, normal, method)?;
                gap = caps.iter().fold(gap, |g, c| g.max(c.gap));
                let sum: f64 = caps.iter().map(|c| c.bits).sum();
                row[c] = if normal.is_empty() {
                    0.0
                } else {
                    sum / normal.len() as f64
                };
            }
        }
        let selection = (0..columns.len())
            .map(|c| select(values.iter().map(|row| row[c])))
            .collect();
        Ok(Matrix {
            tools: self.world.tools.iter().map(|t| t.name.clone()).collect(),
            columns: columns.iter().map(|c| set_name(self.world, c)).collect(),
            values,
            selection,
            normal_states: normal.len(),
            gap,
        })
    }

    /// The state with the agent on (x, y), mode normal, inventory `holding`, every object
    /// in its initial state.
    pub fn landscape_state(&self, x: usize, y: usize, holding: u16) -> State {
        let mut s = self.world.initial;
        s.x = x as u8;
        s.y = y as u8;
        s.set_mode(Mode::Normal);
        s.inventory = holding;
        s
    }

    /// The landscape of (tool, set, h) for inventory `holding` (bit per tool).
    pub fn landscape(
        &self,
        tool: ToolSel,
        set: &ObjectSet,
        h: u32,
        holding: u16,
        method: Method,
    ) -> Result<Landscape, EngineError> {
        let (w, hgt) = (self.world.width, self.world.height);
        let cells: Vec<Option<u32>> = (0..w * hgt)
            .map(|c| self.space.id(&self.landscape_state(c % w, c / w, holding)))
            .collect();
        if self.world.is_stochastic() {
            let ids: Vec<u32> = cells.iter().flatten().copied().collect();
            let caps = self.values_at(tool, set, h, &ids, method)?;
            let gap = caps.iter().fold(0.0f64, |g, c| g.max(c.gap));
            let mut it = caps.iter();
            let vals: Vec<Option<f64>> = cells
                .iter()
                .map(|c| c.map(|_| it.next().expect("one value per id").bits))
                .collect();
            return Ok(Landscape {
                values: vals.chunks(w).map(|r| r.to_vec()).collect(),
                gap,
            });
        }
        let vals: Vec<Option<f64>> = match method {
            Method::Dp => {
                let v = self.values(tool, set, h, method)?;
                cells.iter().map(|c| c.map(|i| v[i as usize])).collect()
            }
            Method::Enumerate => {
                let ids: Vec<u32> = cells.iter().flatten().copied().collect();
                let counts = self.enumerate_counts(&ids, &tool.actions(self.world), set, &[h])?;
                let mut it = counts[0].iter();
                cells
                    .iter()
                    .map(|c| c.map(|_| (*it.next().expect("one count per id") as f64).log2()))
                    .collect()
            }
        };
        Ok(Landscape {
            values: vals.chunks(w).map(|r| r.to_vec()).collect(),
            gap: 0.0,
        })
    }

    /// E^h along an action sequence from the initial state (t = 0 is before any action).
    pub fn trace(
        &self,
        tool: ToolSel,
        set: &ObjectSet,
        h: u32,
        actions: &[u8],
    ) -> Result<Vec<TraceStep>, EngineError> {
        if self.world.is_stochastic() {
            // The intended outcome of each action ([`World::step`]), valued there only.
            let mut states = vec![self.world.initial];
            for &a in actions {
                let s = self.world.step(states.last().expect("not empty"), a);
                states.push(s);
            }
            let ids: Vec<u32> = states
                .iter()
                .map(|s| self.state_id(s))
                .collect::<Result<_, _>>()?;
            let caps = self.values_at(tool, set, h, &ids, Method::Dp)?;
            return Ok(states
                .iter()
                .zip(caps)
                .enumerate()
                .map(|(t, (s, c))| TraceStep {
                    action: t.checked_sub(1).map(|k| actions[k]),
                    state: *s,
                    value: c.bits,
                    gap: c.gap,
                })
                .collect());
        }
        let v = self.values(tool, set, h, Method::Dp)?;
        let mut s = self.world.initial;
        let mut out = Vec::with_capacity(actions.len() + 1);
        let id = |s: &State| {
            self.space
                .id(s)
                .expect("every state reached from the start is in the space")
        };
        out.push(TraceStep {
            action: None,
            state: s,
            value: v[id(&s) as usize],
            gap: 0.0,
        });
        for &a in actions {
            s = self.world.step(&s, a);
            out.push(TraceStep {
                action: Some(a),
                state: s,
                value: v[id(&s) as usize],
                gap: 0.0,
            });
        }
        Ok(out)
    }

    /// The value of every state for a LOOKUP table, by state id, in bits (`f32`):
    /// `E^{h(s)}_{tool,set}(s)` with `h(s) = horizon_equipped` where the tool is held and
    /// `horizon_unequipped` elsewhere; or, with `horizon_sum`, the potential
    /// `Phi(s) = sum over h = 1..H of E^h(s)`, `H` the larger of the two, in every state.
    /// The empowerment service answers from this table, and so does the Python package's
    /// reward wrapper.
    pub fn lookup_values(
        &self,
        tool: ToolSel,
        set: &ObjectSet,
        horizon_unequipped: u32,
        horizon_equipped: u32,
        horizon_sum: bool,
    ) -> Result<Vec<f32>, EngineError> {
        if self.world.is_stochastic() {
            return self.chance_lookup(
                tool,
                set,
                horizon_unequipped,
                horizon_equipped,
                horizon_sum,
            );
        }
        if horizon_sum {
            // Every horizon 1..=H in one propagation; Phi is their sum (f64, then f32).
            let h = horizon_unequipped.max(horizon_equipped);
            let hs: Vec<u32> = (1..=h).collect();
            let counts = self.counts(tool, set, &hs, Method::Dp)?;
            return Ok((0..self.space.len())
                .map(|i| counts.iter().map(|c| (c[i] as f64).log2()).sum::<f64>() as f32)
                .collect());
        }
        let counts = self.counts(
            tool,
            set,
            &[horizon_unequipped, horizon_equipped],
            Method::Dp,
        )?;
        Ok(self
            .space
            .states()
            .iter()
            .enumerate()
            .map(|(i, s)| (counts[tool.held(s) as usize][i] as f64).log2() as f32)
            .collect())
    }

    /// [`Engine::lookup_values`] of a stochastic world.
    fn chance_lookup(
        &self,
        tool: ToolSel,
        set: &ObjectSet,
        hu: u32,
        he: u32,
        horizon_sum: bool,
    ) -> Result<Vec<f32>, EngineError> {
        let ids: Vec<u32> = (0..self.space.len() as u32).collect();
        if horizon_sum {
            let h = hu.max(he);
            if h > fulcrum_world::MAX_HORIZON {
                return Err(EngineError::HorizonTooLarge {
                    h,
                    max: fulcrum_world::MAX_HORIZON,
                });
            }
            let actions = tool.actions(self.world);
            let proj = Projection::new(&self.space, set);
            let chance = Chance::new(
                &self.space,
                &proj,
                &actions,
                h,
                self.limits.max_bytes.saturating_sub(self.space.bytes()),
            );
            let mut phi = vec![0.0f64; ids.len()];
            for k in 1..=h {
                for (p, c) in phi.iter_mut().zip(chance.values(&ids, k)?) {
                    *p += c.bits;
                }
            }
            return Ok(phi.into_iter().map(|v| v as f32).collect());
        }
        Ok(self
            .chance_by_inventory(tool, set, hu, he, &ids, Method::Dp)?
            .into_iter()
            .map(|c| c.bits as f32)
            .collect())
    }

    /// The id of a state, or why it is not in the state space.
    pub fn state_id(&self, s: &State) -> Result<u32, EngineError> {
        self.space.id(s).ok_or_else(|| {
            EngineError::NotInSpace(format!(
                "the state '{}' is not reachable from the initial state of world '{}'",
                self.world.describe(s),
                self.world.name
            ))
        })
    }

    /// E^h at one state.
    pub fn query(
        &self,
        s: &State,
        tool: ToolSel,
        set: &ObjectSet,
        h: u32,
        method: Method,
    ) -> Result<f64, EngineError> {
        let id = self.state_id(s)?;
        if self.world.is_stochastic() {
            return Ok(self.values_at(tool, set, h, &[id], method)?[0].bits);
        }
        match method {
            Method::Dp => Ok(self.values(tool, set, h, method)?[id as usize]),
            Method::Enumerate => {
                check_enumerable(tool.actions(self.world).len(), &[h], 1)?;
                Ok(enumerate::value(
                    self.world,
                    s,
                    &tool.actions(self.world),
                    set,
                    h,
                ))
            }
        }
    }
}

/// Spaces up to this many states compute matrix entries in parallel, one per thread.
const SMALL_SPACE: usize = 100_000;

/// Refuse enumeration beyond about 2 * 10^9 steps (minutes of work).
fn check_enumerable(actions: usize, horizons: &[u32], states: usize) -> Result<(), EngineError> {
    let h = horizons.iter().copied().max().unwrap_or(0);
    let per_state = (actions as f64).powi(h as i32);
    if per_state * states.max(1) as f64 > 2e9 || h > fulcrum_world::MAX_HORIZON {
        return Err(EngineError::EnumerationTooLong {
            h,
            actions,
            states,
            per_state,
        });
    }
    Ok(())
}
