//! The built-in worlds, embedded in the binary under their names.
//!
//! The files in `worlds/`: the paper's four worlds and `room`
//! ([`NAMES`](crate::builtin::NAMES), all deterministic), and two of them with chance
//! ([`STOCHASTIC`](crate::builtin::STOCHASTIC): moves slip, rules act with a
//! probability; `docs/world.md`, "Stochastic worlds").

/// Names of the deterministic built-in worlds (the paper's four and `room`).
pub const NAMES: [&str; 5] = ["exp1-tree", "exp1-wall", "exp2", "exp3", "room"];

/// Names of the stochastic built-in worlds: exp1-tree and exp2 with slip 0.1 and every
/// rule of their tools at p = 0.8.
pub const STOCHASTIC: [&str; 2] = ["exp1-tree-slip", "exp2-slip"];

/// Names of the built-in world families (`docs/world.md`, "World families"): `toolbox`
/// (one room, a task object and three tools) and `two-rooms` (the task object behind a
/// locked door).
pub const FAMILIES: [&str; 2] = ["toolbox", "two-rooms"];

/// The text of a built-in family.
pub fn family_source(name: &str) -> Option<&'static str> {
    Some(match name {
        "toolbox" => include_str!("../../worlds/toolbox.toml"),
        "two-rooms" => include_str!("../../worlds/two-rooms.toml"),
        _ => return None,
    })
}

/// Every built-in name: [`NAMES`], then [`STOCHASTIC`].
pub fn all_names() -> impl Iterator<Item = &'static str> {
    NAMES.into_iter().chain(STOCHASTIC)
}

/// The text of a built-in world.
pub fn source(name: &str) -> Option<&'static str> {
    Some(match name {
        "exp1-tree" => include_str!("../../worlds/exp1-tree.toml"),
        "exp1-wall" => include_str!("../../worlds/exp1-wall.toml"),
        "exp2" => include_str!("../../worlds/exp2.toml"),
        "exp3" => include_str!("../../worlds/exp3.toml"),
        "room" => include_str!("../../worlds/room.toml"),
        "exp1-tree-slip" => include_str!("../../worlds/exp1-tree-slip.toml"),
        "exp2-slip" => include_str!("../../worlds/exp2-slip.toml"),
        _ => return None,
    })
}
