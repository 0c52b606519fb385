//! What a service answers from: the precomputed table of its configuration (LOOKUP),
//! the bounded cache of QUERY results and the VISIT counts.

use std::collections::VecDeque;

use fulcrum_contracts::msg::TOOL_ALL;
use fulcrum_contracts::msg::{item, kind, status, Describe, EmpRequest, EmpResponse};
use fulcrum_world::{ObjectSet, State, MAX_HORIZON};

use super::answer::Answer;
use super::codes::{describe, mask_set};
use super::config::ServeConfig;
use super::error::ServiceError;
use crate::engine::{Engine, Method, ToolSel};

/// A QUERY's key in the cache: tool code, object mask, horizon.
type QueryKey = (i32, u32, u32);

/// The service's tables and cache: everything but the ports.
#[derive(Debug)]
pub struct Tables<'w> {
    engine: Engine<'w>,
    pub(super) cfg: ServeConfig,
    /// LOOKUP's answer per state id ([`Engine::lookup_values`]).
    values: Vec<f32>,
    /// QUERY results, oldest first, within `cfg.cache_bytes`.
    cache: VecDeque<(QueryKey, Vec<f32>)>,
    describe: Describe,
    /// VISIT counts per state id (allocated at the first VISIT).
    visits: Vec<u32>,
}

impl<'w> Tables<'w> {
    /// Precompute the configuration's tables.
    pub fn new(engine: Engine<'w>, cfg: ServeConfig) -> Result<Self, ServiceError> {
        let values = engine.lookup_values(
            cfg.tool,
            &cfg.objects,
            cfg.horizon_unequipped,
            cfg.horizon_equipped,
            cfg.horizon_sum,
        )?;
        Ok(Self::with_values(engine, cfg, values))
    }

    /// Serve LOOKUP from `values` (one per state id: E, or Phi with `horizon_sum`)
    /// instead of the exact table, e.g. [`crate::estimates::lookup_from_estimates`];
    /// QUERY still computes exactly.
    pub fn with_values(engine: Engine<'w>, cfg: ServeConfig, values: Vec<f32>) -> Self {
        assert_eq!(values.len(), engine.space.len(), "one value per state");
        let describe = describe(&engine, &cfg);
        Tables {
            values,
            engine,
            cfg,
            cache: VecDeque::new(),
            describe,
            visits: Vec::new(),
        }
    }

    /// The DESCRIBE answer.
    pub fn describe(&self) -> &Describe {
        &self.describe
    }

    /// LOOKUP's answer for one state: E (or Phi with `horizon_sum`) in bits; `None` for a
    /// state outside the state space.
    pub fn lookup(&self, s: &State) -> Option<f32> {
        let id = self.engine.space.id(s)?;
        Some(self.values[id as usize])
    }

    /// Answer one request into `out` (all-zero on entry).
    pub fn answer(&mut self, req: &EmpRequest, out: &mut EmpResponse) {
        if !super::answer::admit(&self.describe, req, out) {
            return;
        }
        match req.kind {
            kind::DESCRIBE => {}
            kind::LOOKUP => self.answer_lookup(req, out),
            kind::VISIT => self.answer_visit(req, out),
            kind::QUERY => self.answer_query(req, out),
            _ => out.status = status::BAD_KIND,
        }
    }

    /// LOOKUP: the configured table's value of each state.
    fn answer_lookup(&self, req: &EmpRequest, out: &mut EmpResponse) {
        let n = req.count as usize;
        let space = &self.engine.space;
        for i in 0..n {
            let s = State::from_bytes(&req.states[i]);
            match space.id(&s) {
                Some(id) => out.values[i] = self.values[id as usize],
                None => out.item_status[i] = item::NOT_IN_SPACE,
            }
        }
        out.count = n as u32;
    }

    /// VISIT: count one visit of each state and answer its count so far.
    fn answer_visit(&mut self, req: &EmpRequest, out: &mut EmpResponse) {
        let n = req.count as usize;
        let space = &self.engine.space;
        if self.visits.is_empty() {
            self.visits = vec![0; space.len()];
        }
        for i in 0..n {
            let s = State::from_bytes(&req.states[i]);
            match space.id(&s) {
                Some(id) => {
                    let c = &mut self.visits[id as usize];
                    *c = c.saturating_add(1);
                    out.values[i] = *c as f32;
                }
                None => out.item_status[i] = item::NOT_IN_SPACE,
            }
        }
        out.count = n as u32;
    }

    /// QUERY: any tool, object set and horizon, from the cache or computed into it.
    fn answer_query(&mut self, req: &EmpRequest, out: &mut EmpResponse) {
        let w = self.engine.world;
        let tool = match req.tool {
            TOOL_ALL => ToolSel::All,
            t if t >= 0 && (t as usize) < w.tools.len() => ToolSel::Tool(t as usize),
            _ => {
                out.status = status::BAD_TOOL;
                return;
            }
        };
        let Some(set) = mask_set(w, req.objects) else {
            out.status = status::BAD_OBJECTS;
            return;
        };
        if req.horizon > MAX_HORIZON {
            out.status = status::BAD_HORIZON;
            return;
        }
        let key = (req.tool, req.objects, req.horizon);
        if !self.cache_query(key, tool, &set) {
            out.status = status::TOO_LARGE;
            return;
        }
        let (_, table) = self
            .cache
            .iter()
            .find(|(k, _)| *k == key)
            .expect("cached above");
        let space = &self.engine.space;
        let n = req.count as usize;
        for i in 0..n {
            match space.id(&State::from_bytes(&req.states[i])) {
                Some(id) => out.values[i] = table[id as usize],
                None => out.item_status[i] = item::NOT_IN_SPACE,
            }
        }
        out.count = n as u32;
    }

    /// Make sure the QUERY table of `key` is in the cache, computing it (and dropping
    /// the oldest tables to stay within the cache's bytes) if it is not there yet;
    /// `false` if it cannot fit or the engine refuses it.
    fn cache_query(&mut self, key: QueryKey, tool: ToolSel, set: &ObjectSet) -> bool {
        if self.cache.iter().any(|(k, _)| *k == key) {
            return true;
        }
        let table_bytes = self.engine.space.len() * 4;
        if table_bytes > self.cfg.cache_bytes {
            return false;
        }
        let v = match self.engine.values(tool, set, key.2, Method::Dp) {
            Ok(v) => v.iter().map(|&x| x as f32).collect(),
            Err(_) => return false,
        };
        while (self.cache.len() + 1) * table_bytes > self.cfg.cache_bytes {
            self.cache.pop_front();
        }
        self.cache.push_back((key, v));
        true
    }
}

impl Answer for Tables<'_> {
    fn describe(&self) -> &Describe {
        Tables::describe(self)
    }
    fn answer(&mut self, req: &EmpRequest, out: &mut EmpResponse) {
        Tables::answer(self, req, out)
    }
}
