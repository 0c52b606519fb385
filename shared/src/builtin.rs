//! The paper's four worlds, embedded in the binary under their names.
//!
//! The files in `worlds/` are the paper's four worlds and `room`, embedded in the binary.

/// Names of the built-in worlds.
pub const NAMES: [&str; 5] = ["exp1-tree", "exp1-wall", "exp2", "exp3", "room"];

/// The text of a built-in world.
pub fn source(name: &str) -> Option<&'static str> {
    Some(match name {
        "exp1-tree" => include_str!("../../worlds/exp1-tree.toml"),
        "exp1-wall" => include_str!("../../worlds/exp1-wall.toml"),
        "exp2" => include_str!("../../worlds/exp2.toml"),
        "exp3" => include_str!("../../worlds/exp3.toml"),
        "room" => include_str!("../../worlds/room.toml"),
        _ => return None,
    })
}
