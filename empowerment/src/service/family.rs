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
//! Tables are made several at a time: the serving loop gathers every request waiting
//! when it wakes and [`Answer::prepare`] makes the tables of all the new layouts they
//! name at once, one layout a thread of rayon's pool (a layout's own propagation takes
//! the other threads when it is the last left), before the requests are answered in
//! their order. An actor playing a chunk sends its lookups as it steps and collects
//! only the answers already there, so on a run with a fresh layout every episode the
//! requests of a chunk wait together and the machine's cores make its new layouts side
//! by side. Answers are the same either way (values do not depend on the order tables
//! are made in).
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

use rayon::prelude::*;

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

/// Layout `seed`'s table under `cfg`: the values of every state, in the layout's own
/// state ids.
fn make_table(family: &Family, cfg: &FamilyConfig, seed: u64) -> Result<LayoutTable, String> {
    let w = family.layout(seed).map_err(|e| e.to_string())?;
    let engine = Engine::new(&w, Limits::default()).map_err(|e| e.to_string())?;
    let set = potential_objects(&w, None, cfg.task_conditions).map_err(|e| e.to_string())?;
    let (_, values) = lookup_table(
        &w,
        &engine,
        cfg.tool.as_deref(),
        &set,
        cfg.horizon_unequipped,
        cfg.horizon_equipped,
        cfg.horizon_sum,
    )
    .map_err(|e| format!("layout {seed}: {e}"))?;
    Ok(LayoutTable {
        index: engine.into_space().into_index(),
        values,
        visits: Vec::new(),
    })
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
    /// The value of `s` (`None`: not a state of this layout).
    fn value(&self, s: &State) -> Option<f32> {
        Some(self.values[self.index.id(s)? as usize])
    }

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
        let kept: Vec<u64> = (0..t.cfg.keep).collect();
        for (seed, table) in t.make_all(&kept) {
            let table = table?;
            t.describe.states += table.values.len() as u64;
            t.tables.insert(seed, Some(table));
        }
        Ok(t)
    }

    /// The family.
    pub fn family(&self) -> &Family {
        &self.family
    }

    /// Make the tables of `seeds` (distinct, none made yet), several at once: one layout
    /// a thread of rayon's pool, and each layout's own propagation free to take the
    /// other threads when it is the last one left. Returned in the order of `seeds`.
    fn make_all(&mut self, seeds: &[u64]) -> Vec<(u64, Result<LayoutTable, String>)> {
        let (family, cfg) = (&self.family, &self.cfg);
        let t0 = Instant::now();
        let made: Vec<_> = seeds
            .par_iter()
            .map(|&seed| (seed, make_table(family, cfg, seed)))
            .collect();
        let ok = made.iter().filter(|(_, t)| t.is_ok()).count();
        self.stats.made += ok as u64;
        self.stats.made_us += t0.elapsed().as_micros() as u64;
        made
    }

    /// The table of layout `seed`, made now if it is not there (`None`: no table can be
    /// made for it).
    fn table(&mut self, seed: u64) -> Option<&mut LayoutTable> {
        if !self.tables.contains_key(&seed) {
            let made = self.make_all(&[seed]);
            self.keep_made(made);
        }
        self.tables.get_mut(&seed).and_then(Option::as_mut)
    }

    /// Keep tables just made (a layout none could be made for is kept as `None`, so it
    /// is not tried again), dropping the oldest beyond the kept layouts while the cache
    /// holds more than `cache_bytes`.
    fn keep_made(&mut self, made: Vec<(u64, Result<LayoutTable, String>)>) {
        for (seed, made) in made {
            let made = match made {
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
    }

    /// The largest value of layout `seed`'s table (`None`: no table can be made for it).
    pub fn max_value(&mut self, seed: u64) -> Option<f32> {
        let t = self.table(seed)?;
        Some(t.values.iter().copied().fold(0.0f32, f32::max))
    }

    /// LOOKUP's answer for one state of layout `seed`; `None` where the state is not one of
    /// the layout's.
    pub fn lookup(&mut self, seed: u64, s: &State) -> Option<f32> {
        // A layout met before: one probe of the map (`table` takes two).
        if let Some(made) = self.tables.get(&seed) {
            return made.as_ref()?.value(s);
        }
        self.table(seed)?.value(s)
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

    fn prepares(&self) -> bool {
        true
    }

    /// Make the tables of every layout the waiting requests name that has none yet, all
    /// at once (see the module docs).
    fn prepare(&mut self, reqs: &[&EmpRequest]) {
        let mut seeds: Vec<u64> = Vec::new();
        for req in reqs {
            let admitted = req.world_hash == self.describe.world_hash
                && (req.count as usize) <= msg::MAX_BATCH
                && matches!(req.kind, kind::LOOKUP | kind::VISIT);
            if !admitted {
                continue;
            }
            for &seed in &req.layouts[..req.count as usize] {
                if !self.tables.contains_key(&seed) {
                    seeds.push(seed);
                }
            }
        }
        seeds.sort_unstable();
        seeds.dedup();
        if !seeds.is_empty() {
            let made = self.make_all(&seeds);
            self.keep_made(made);
        }
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
