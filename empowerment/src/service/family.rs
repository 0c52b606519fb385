//! What the service of a world family answers from: one table per layout.
//!
//! A request names the layout of each state (`EmpRequest::layouts`). The table of a
//! layout is LOOKUP's answer in every state of that layout: E^{h(s)}_{j,D}(s) (or Phi(s)
//! = sum over h <= H of E^h(s) with `horizon_sum`), D the layout's own task object and j
//! the configured tool (`auto`: the layout's own tool selection, the paper's equation 6,
//! made per layout). It is made the first time a state of the layout is asked for, by
//! exact set propagation over the layout's whole state space (with `auto`, the selection
//! and the table in one propagation: [`crate::auto`]; a few ms for the median `toolbox`
//! layout, tens of ms for one with a pushable boulder; `BENCHMARKS.md`), and kept: the
//! values (4 bytes a state) and the index from states to ids
//! ([`crate::StateIndex::bytes`]), nothing else. The training
//! layouts of a run on N layouts are made before the service says it is ready and never
//! dropped, so actors never wait on a table; other layouts (a run on every layout,
//! held-out layouts) are dropped oldest first once the tables outgrow `cache_bytes`.
//!
//! The service answers LOOKUP, VISIT (counts per layout and state) and DESCRIBE; QUERY,
//! which names tools and objects by index, is for the service of one world
//! ([`super::Tables`]) and is refused with `BAD_KIND`.

use std::collections::VecDeque;
use std::time::Instant;

use fulcrum_contracts::msg::{self, item, kind, status, Describe, EmpRequest, EmpResponse};
use fulcrum_world::family::Family;
use fulcrum_world::hash::FastMap;
use fulcrum_world::State;

use super::answer::Answer;
use crate::limits::Limits;
use crate::request::{lookup_table, potential_objects};
use crate::space::StateIndex;
use crate::Engine;

/// What a family's service computes for each layout.
#[derive(Debug, Clone)]
pub struct FamilyConfig {
    /// The tool (`auto`, `all` or a name); `None`: the family's `[empowerment]` tool.
    pub tool: Option<String>,
    /// Horizon where the tool is not held.
    pub horizon_unequipped: u32,
    /// Horizon where it is held.
    pub horizon_equipped: u32,
    /// LOOKUP answers Phi instead of E (see the module docs).
    pub horizon_sum: bool,
    /// A layout whose task is to destroy its objects counts them by their conditions
    /// only ([`potential_objects`]: a potential form's run).
    pub task_conditions: bool,
    /// Bytes the tables of layouts beyond the kept ones may hold.
    pub cache_bytes: usize,
    /// Layouts whose tables are made first and never dropped: the seeds `0..keep`.
    pub keep: u64,
}

/// One layout's table.
#[derive(Debug)]
struct LayoutTable {
    index: StateIndex,
    values: Vec<f32>,
    /// VISIT counts per state id (allocated at the first VISIT).
    visits: Vec<u32>,
}

impl LayoutTable {
    fn bytes(&self) -> usize {
        self.values.len() * 4 + self.index.bytes() + self.visits.len() * 4
    }
}

/// Counters of a family's service.
#[derive(Debug, Default, Clone, Copy, PartialEq)]
pub struct FamilyStats {
    /// Tables made.
    pub made: u64,
    /// Microseconds spent making them.
    pub made_us: u64,
    /// Tables dropped to stay within the cache's bytes.
    pub dropped: u64,
    /// Layouts no draw could make (their states are answered `NOT_IN_SPACE`).
    pub failed: u64,
}

/// A family's tables (see the module docs).
#[derive(Debug)]
pub struct FamilyTables {
    family: Family,
    cfg: FamilyConfig,
    tables: FastMap<u64, Option<LayoutTable>>,
    /// Layouts beyond the kept ones, oldest first, and the bytes of their tables.
    order: VecDeque<u64>,
    cached_bytes: usize,
    describe: Describe,
    /// What the service has done so far.
    pub stats: FamilyStats,
}

impl FamilyTables {
    /// The tables of `family` under `cfg`, the kept layouts' made now. Refused when a
    /// kept layout's table cannot be made (its tool or objects do not fit).
    pub fn new(family: Family, cfg: FamilyConfig) -> Result<Self, String> {
        let w = family.run_world().map_err(|e| e.to_string())?;
        let mut d = Describe {
            world_hash: family.content_hash(),
            n_tools: w.tools.len() as u32,
            n_objects: w.objects.len() as u32,
            tool: msg::TOOL_ALL,
            horizon_unequipped: cfg.horizon_unequipped,
            horizon_equipped: cfg.horizon_equipped,
            ..Describe::empty()
        };
        msg::put_name(&mut d.world, &family.name);
        for (k, t) in w.tools.iter().enumerate() {
            msg::put_name(&mut d.tools[k], &t.name);
        }
        let mut t = FamilyTables {
            family,
            cfg,
            tables: FastMap::default(),
            order: VecDeque::new(),
            cached_bytes: 0,
            describe: d,
            stats: FamilyStats::default(),
        };
        for seed in 0..t.cfg.keep {
            let table = t.make(seed)?;
            t.describe.states += table.values.len() as u64;
            t.tables.insert(seed, Some(table));
        }
        Ok(t)
    }

    /// The family.
    pub fn family(&self) -> &Family {
        &self.family
    }

    /// Layout `seed`'s table: the values of every state, in the layout's own state ids.
    fn make(&mut self, seed: u64) -> Result<LayoutTable, String> {
        let t0 = Instant::now();
        let w = self.family.layout(seed).map_err(|e| e.to_string())?;
        let engine = Engine::new(&w, Limits::default()).map_err(|e| e.to_string())?;
        let set =
            potential_objects(&w, None, self.cfg.task_conditions).map_err(|e| e.to_string())?;
        let (_, values) = lookup_table(
            &w,
            &engine,
            self.cfg.tool.as_deref(),
            &set,
            self.cfg.horizon_unequipped,
            self.cfg.horizon_equipped,
            self.cfg.horizon_sum,
        )
        .map_err(|e| format!("layout {seed}: {e}"))?;
        self.stats.made += 1;
        self.stats.made_us += t0.elapsed().as_micros() as u64;
        Ok(LayoutTable {
            index: engine.into_space().into_index(),
            values,
            visits: Vec::new(),
        })
    }

    /// The table of layout `seed`, made now if it is not there (`None`: no table can be
    /// made for it).
    fn table(&mut self, seed: u64) -> Option<&mut LayoutTable> {
        if !self.tables.contains_key(&seed) {
            let made = match self.make(seed) {
                Ok(t) => Some(t),
                Err(e) => {
                    tracing::warn!(layout = seed, "no table for the layout: {e}");
                    self.stats.failed += 1;
                    None
                }
            };
            let bytes = made.as_ref().map_or(0, LayoutTable::bytes);
            while self.cached_bytes + bytes > self.cfg.cache_bytes {
                let Some(old) = self.order.pop_front() else {
                    break;
                };
                if let Some(Some(t)) = self.tables.remove(&old) {
                    self.cached_bytes -= t.bytes();
                    self.stats.dropped += 1;
                }
            }
            self.cached_bytes += bytes;
            self.order.push_back(seed);
            self.tables.insert(seed, made);
        }
        self.tables.get_mut(&seed).and_then(Option::as_mut)
    }

    /// The largest value of layout `seed`'s table (`None`: no table can be made for it).
    pub fn max_value(&mut self, seed: u64) -> Option<f32> {
        let t = self.table(seed)?;
        Some(t.values.iter().copied().fold(0.0f32, f32::max))
    }

    /// LOOKUP's answer for one state of layout `seed`; `None` where the state is not one of
    /// the layout's.
    pub fn lookup(&mut self, seed: u64, s: &State) -> Option<f32> {
        let t = self.table(seed)?;
        Some(t.values[t.index.id(s)? as usize])
    }

    fn answer_items(&mut self, req: &EmpRequest, out: &mut EmpResponse, visit: bool) {
        let n = req.count as usize;
        for i in 0..n {
            let s = State::from_bytes(&req.states[i]);
            let Some(t) = self.table(req.layouts[i]) else {
                out.item_status[i] = item::NOT_IN_SPACE;
                continue;
            };
            match t.index.id(&s) {
                Some(id) if visit => {
                    let before = t.bytes();
                    if t.visits.is_empty() {
                        t.visits = vec![0; t.values.len()];
                    }
                    let c = &mut t.visits[id as usize];
                    *c = c.saturating_add(1);
                    out.values[i] = *c as f32;
                    let grown = t.bytes() - before;
                    if req.layouts[i] >= self.cfg.keep {
                        self.cached_bytes += grown;
                    }
                }
                Some(id) => out.values[i] = t.values[id as usize],
                None => out.item_status[i] = item::NOT_IN_SPACE,
            }
        }
        out.count = n as u32;
    }
}

impl Answer for FamilyTables {
    fn describe(&self) -> &Describe {
        &self.describe
    }

    fn answer(&mut self, req: &EmpRequest, out: &mut EmpResponse) {
        if !super::answer::admit(&self.describe, req, out) {
            return;
        }
        match req.kind {
            kind::DESCRIBE => {}
            kind::LOOKUP => self.answer_items(req, out, false),
            kind::VISIT => self.answer_items(req, out, true),
            _ => out.status = status::BAD_KIND,
        }
    }
}
