//! A LOOKUP table made from someone's estimates of E instead of the exact values: what
//! `fulcrum train --empowerment-from FILE` serves, so that a run on estimated E can be
//! set beside a run on exact E.
//!
//! The file is a CSV with a header naming at least the columns `state` (the packed state,
//! 76 hex digits: `bytes(row).hex()` of a dataset's `state`), `horizon` and `estimate`
//! (bits); other columns (`row`, ...) are ignored. The table is built as
//! [`Engine::lookup_values`] builds the exact one:
//!
//! ```text
//! value(s) = est(s, h(s)),  h(s) = horizon_equipped where the tool is held, else horizon_unequipped
//! Phi(s)   = sum over h = 1..H of est(s, h)     (potential forms; H the larger horizon)
//! ```
//!
//! so every state of the space needs an estimate at the horizons it uses (a dataset made
//! with `--states all` at each of them has them all).

use fulcrum_world::hash::FastMap;
use fulcrum_world::State;

use crate::engine::{Engine, ToolSel};
use crate::error::EngineError;

fn hex_state(s: &str) -> Option<State> {
    if s.len() != 76 || !s.is_ascii() {
        return None;
    }
    let mut b = [0u8; 38];
    for (i, out) in b.iter_mut().enumerate() {
        *out = u8::from_str_radix(&s[2 * i..2 * i + 2], 16).ok()?;
    }
    Some(State::from_bytes(&b))
}

/// The table of estimates in `text` (the file's content; `place` names it in errors).
pub fn lookup_from_estimates(
    e: &Engine<'_>,
    tool: ToolSel,
    horizon_unequipped: u32,
    horizon_equipped: u32,
    horizon_sum: bool,
    text: &str,
    place: &str,
) -> Result<Vec<f32>, EngineError> {
    let bad = |m: String| EngineError::Request(m);
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let (_, header) = lines.next().ok_or_else(|| {
        bad(format!(
            "{place} is empty: it needs a header with the columns state, horizon, estimate"
        ))
    })?;
    let cols: Vec<&str> = header.split(',').map(str::trim).collect();
    let col = |name: &str| {
        cols.iter().position(|c| *c == name).ok_or_else(|| {
            bad(format!(
                "{place}:1: the header has no column '{name}' (it needs state, horizon, estimate; found: {})",
                cols.join(", ")
            ))
        })
    };
    let (si, hi, ei) = (col("state")?, col("horizon")?, col("estimate")?);
    let mut est: FastMap<(u32, u32), f64> = FastMap::default();
    for (i, line) in lines {
        let at = format!("{place}:{}", i + 1);
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != cols.len() {
            return Err(bad(format!(
                "{at}: {} fields where the header has {}",
                f.len(),
                cols.len()
            )));
        }
        let s = hex_state(f[si]).ok_or_else(|| {
            bad(format!(
                "{at}: state '{}' is not a packed state (76 hex digits)",
                f[si]
            ))
        })?;
        let id = e.space.id(&s).ok_or_else(|| {
            bad(format!(
                "{at}: the state is not one of world '{}'",
                e.world.name
            ))
        })?;
        let h: u32 = f[hi]
            .parse()
            .map_err(|_| bad(format!("{at}: horizon '{}' is not a whole number", f[hi])))?;
        let v: f64 = f[ei]
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| {
                bad(format!(
                    "{at}: estimate '{}' is not a finite number of bits",
                    f[ei]
                ))
            })?;
        if est.insert((id, h), v).is_some() {
            return Err(bad(format!(
                "{at}: the state is estimated twice at horizon {h}"
            )));
        }
    }
    let get = |id: u32, h: u32| {
        est.get(&(id, h)).copied().ok_or_else(|| {
            bad(format!(
                "{place} has no estimate at horizon {h} for the state '{}': every state of the space needs one (make the dataset with --states all)",
                e.world.describe(e.space.state(id))
            ))
        })
    };
    (0..e.space.len() as u32)
        .map(|id| {
            Ok(if horizon_sum {
                let top = horizon_unequipped.max(horizon_equipped);
                (1..=top).map(|h| get(id, h)).sum::<Result<f64, _>>()? as f32
            } else {
                let h = if tool.held(e.space.state(id)) {
                    horizon_equipped
                } else {
                    horizon_unequipped
                };
                get(id, h)? as f32
            })
        })
        .collect()
}
