//! How requests and the DESCRIBE answer name tools and object sets: a tool is its
//! index or [`TOOL_ALL`], an object set is a bit mask ([`AGENT_BIT`] for the agent).

use fulcrum_contracts::msg::{self, Describe, AGENT_BIT, CONDITIONS_BIT, TOOL_ALL};
use fulcrum_world::{ObjectSet, World};

use super::config::ServeConfig;
use crate::engine::{Engine, ToolSel};

/// Object mask of a set (bit per object; [`AGENT_BIT`] for the agent, and
/// [`CONDITIONS_BIT`] with the objects' bits for their conditions).
pub fn object_mask(set: &ObjectSet) -> u32 {
    let bits = |v: &[usize]| v.iter().fold(0, |m, &i| m | 1 << i);
    match set {
        ObjectSet::Agent => AGENT_BIT,
        ObjectSet::Objects(v) => bits(v),
        ObjectSet::Conditions { objects, .. } => bits(objects) | CONDITIONS_BIT,
    }
}

/// The object set of a mask, if the world has those objects.
pub fn mask_set(world: &World, mask: u32) -> Option<ObjectSet> {
    if mask == AGENT_BIT {
        return Some(ObjectSet::Agent);
    }
    let conditions = mask & CONDITIONS_BIT != 0;
    let mask = mask & !CONDITIONS_BIT;
    if mask == 0 || mask & AGENT_BIT != 0 || mask >> world.objects.len() != 0 {
        return None;
    }
    let v: Vec<usize> = (0..world.objects.len())
        .filter(|&i| mask >> i & 1 == 1)
        .collect();
    Some(if conditions {
        world.conditions_of(v)
    } else {
        ObjectSet::Objects(v)
    })
}

/// A tool selection's code in requests and in [`Describe`].
fn tool_code(t: ToolSel) -> i32 {
    match t {
        ToolSel::All => TOOL_ALL,
        ToolSel::Tool(j) => j as i32,
    }
}

/// The DESCRIBE answer for an engine and configuration.
pub fn describe(engine: &Engine, cfg: &ServeConfig) -> Describe {
    let w = engine.world;
    let mut d = Describe {
        world_hash: w.content_hash(),
        states: engine.space.len() as u64,
        normal_states: engine.normal_states() as u64,
        n_tools: w.tools.len() as u32,
        n_objects: w.objects.len() as u32,
        tool: tool_code(cfg.tool),
        object_mask: object_mask(&cfg.objects),
        horizon_unequipped: cfg.horizon_unequipped,
        horizon_equipped: cfg.horizon_equipped,
        ..Describe::empty()
    };
    msg::put_name(&mut d.world, &w.name);
    for (k, t) in w.tools.iter().enumerate() {
        msg::put_name(&mut d.tools[k], &t.name);
    }
    for (i, o) in w.objects.iter().enumerate() {
        msg::put_name(&mut d.objects[i], &o.name);
    }
    d
}
