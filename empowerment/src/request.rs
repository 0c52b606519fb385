//! Reading what a request names: an object set, a tool (or the tool selection of the
//! matrix), an inventory. Each mistake is an [`EngineError::Request`] naming what was
//! not understood and what would be. The command line and the Python package read
//! their arguments here, so both say the same sentence.

use fulcrum_world::{ObjectKind, ObjectSet, Task, ToolChoice, World};

use crate::auto::AutoHorizons;
use crate::engine::{Engine, Matrix, Method, ToolSel};
use crate::error::EngineError;
use crate::limits::Limits;

type Result<T> = std::result::Result<T, EngineError>;

fn bad<T>(msg: impl Into<String>) -> Result<T> {
    Err(EngineError::Request(msg.into()))
}

/// Enumerate a world's state space with the default limits.
pub fn engine(world: &World) -> Result<Engine<'_>> {
    Engine::new(world, Limits::default())
}

/// Parse an object set: `agent`, or names joined by `,` or `+`, or `conditions:` and
/// names (the objects by their conditions only: a boulder intact or destroyed).
pub fn object_set(world: &World, text: &str) -> Result<ObjectSet> {
    if text == "agent" {
        return Ok(ObjectSet::Agent);
    }
    if let Some(rest) = text.strip_prefix("conditions:") {
        if rest.trim() == "agent" {
            return bad(format!(
                "'{text}': the agent has no condition; write conditions: and object names"
            ));
        }
        return Ok(object_set(world, rest)?.conditions(world));
    }
    let mut v = Vec::new();
    for name in text.split([',', '+']).map(str::trim) {
        if name.is_empty() {
            return bad(format!(
                "'{text}' is not an object list: write names like tree,wall or door+boulder"
            ));
        }
        match world.object_index(name) {
            Some(i) if !v.contains(&i) => v.push(i),
            Some(_) => {}
            None => {
                let list = if world.objects.is_empty() {
                    "none".to_string()
                } else {
                    world.object_list()
                };
                return bad(format!(
                    "unknown object '{name}' in world '{}' (objects: {list}; or agent)",
                    world.name
                ));
            }
        }
    }
    v.sort_unstable();
    Ok(ObjectSet::Objects(v))
}

/// The object set asked for, or the world's `[empowerment]` objects.
pub fn objects_or_default(world: &World, text: Option<&str>) -> Result<ObjectSet> {
    match text {
        Some(t) => object_set(world, t),
        None => match &world.empowerment.objects {
            Some(s) => Ok(s.clone()),
            None => bad(format!(
                "world '{}' names no [empowerment] objects: name some (objects: {})",
                world.name,
                world.object_list()
            )),
        },
    }
}

/// The object set a potential form counts: the one asked for, or with `task_conditions`
/// and none asked for, the world's own objects by their conditions only when its task
/// is to destroy them and one of them is a boulder (a destroy task asks for a change of
/// condition, and a boulder's cell would otherwise make most of the potential:
/// `docs/world.md`, "What the potential counts"; the other kinds have no cell, so their
/// set is left as it is); otherwise [`objects_or_default`].
pub fn potential_objects(
    world: &World,
    text: Option<&str>,
    task_conditions: bool,
) -> Result<ObjectSet> {
    let set = objects_or_default(world, text)?;
    let boulder = set
        .indices()
        .iter()
        .any(|&i| world.objects[i].kind == ObjectKind::Boulder);
    Ok(
        if text.is_none() && task_conditions && boulder && matches!(world.task, Task::Destroy(_)) {
            set.conditions(world)
        } else {
            set
        },
    )
}

/// Parse a tool name (`all`, `auto`, a name, kind or letter); `None`: the world's
/// `[empowerment]` tool.
pub fn tool_choice(world: &World, text: Option<&str>) -> Result<ToolChoice> {
    Ok(match text {
        None => world.empowerment.tool.clone(),
        Some("auto") => ToolChoice::Auto,
        Some("all") => ToolChoice::All,
        Some(t) => match world.tool_index(t) {
            Some(k) => ToolChoice::Tool(k),
            None => {
                return bad(format!(
                    "unknown tool '{t}' in world '{}' (tools: {}; or all, auto)",
                    world.name,
                    if world.tools.is_empty() {
                        "none".to_string()
                    } else {
                        world.tool_list()
                    }
                ))
            }
        },
    })
}

/// The one horizon of the tool selection (`tool = "auto"`, equation 6): the world's
/// horizon where the tool is not held, for every state and every row.
///
/// One horizon for every row keeps the rows comparable: a tool that can do to an object
/// everything another can do, and more, then never gets the smaller row. Horizons that
/// switch by whether the row's own tool is held lose that (a row gets the short horizon
/// in the states holding its tool, so the tool held in fewer states is favoured); on a
/// boulder, which every tool pushes, that selected a tool with no rule for boulders over
/// one that destroys them (`docs/world.md`, "Object empowerment").
pub fn selection_horizon(world: &World) -> u32 {
    world.empowerment.horizon_unequipped
}

/// The horizons (not held, held) of a matrix asked for with these options: `horizon`
/// for both; else `horizon_unequipped` (or the world's [`selection_horizon`]) for both
/// unless `horizon_equipped` is given, which asks for the matrix whose rows switch
/// horizon where their tool is held. With no option the matrix is the selection's.
pub fn matrix_horizons(
    world: &World,
    horizon: Option<u32>,
    horizon_unequipped: Option<u32>,
    horizon_equipped: Option<u32>,
) -> (u32, u32) {
    match horizon {
        Some(h) => (h, h),
        None => {
            let hu = horizon_unequipped.unwrap_or_else(|| selection_horizon(world));
            (hu, horizon_equipped.unwrap_or(hu))
        }
    }
}

/// The error of a tool selection that selects nothing.
fn no_tool<T>(world: &World, set: &ObjectSet) -> Result<T> {
    bad(format!(
        "tool selection: no tool of world '{}' has empowerment over {}; name one",
        world.name,
        crate::engine::set_name(world, set)
    ))
}

/// Parse a tool name (`all`, `auto`, a name, kind or letter); `auto` selects by the
/// matrix column of `set` at the world's [`selection_horizon`].
pub fn tool_sel(
    world: &World,
    engine: &Engine,
    text: Option<&str>,
    set: &ObjectSet,
) -> Result<ToolSel> {
    Ok(tool_sel_with_column(world, engine, text, set)?.0)
}

/// [`tool_sel`], and with `auto` the matrix (one column, `set`'s, at the world's
/// [`selection_horizon`]) the selection came from, for saying why.
pub fn tool_sel_with_column(
    world: &World,
    engine: &Engine,
    text: Option<&str>,
    set: &ObjectSet,
) -> Result<(ToolSel, Option<Matrix>)> {
    resolve(world, engine, tool_choice(world, text)?, set)
}

/// The tool a choice names, and with `auto` the matrix it came from (see
/// [`tool_sel_with_column`]).
fn resolve(
    world: &World,
    engine: &Engine,
    choice: ToolChoice,
    set: &ObjectSet,
) -> Result<(ToolSel, Option<Matrix>)> {
    Ok(match choice {
        ToolChoice::All => (ToolSel::All, None),
        ToolChoice::Tool(k) => (ToolSel::Tool(k), None),
        ToolChoice::Auto => {
            let h = selection_horizon(world);
            let m = engine.matrix(std::slice::from_ref(set), h, h, Method::Dp)?;
            match m.selection[0] {
                Some(k) => {
                    tracing::info!(tool = %m.tools[k], "tool selection");
                    (ToolSel::Tool(k), Some(m))
                }
                None => return no_tool(world, set),
            }
        }
    })
}

/// LOOKUP's table: the tool `text` names (as [`tool_sel`]) and its value in every
/// state (as [`Engine::lookup_values`]). With `auto`, the selection and the table come
/// from one propagation where [`Engine::auto_table`] applies (the same numbers, about
/// half the time); elsewhere one after the other.
pub fn lookup_table(
    world: &World,
    engine: &Engine,
    text: Option<&str>,
    set: &ObjectSet,
    horizon_unequipped: u32,
    horizon_equipped: u32,
    horizon_sum: bool,
) -> Result<(ToolSel, Vec<f32>)> {
    let choice = tool_choice(world, text)?;
    if choice == ToolChoice::Auto {
        let hz = AutoHorizons {
            select: selection_horizon(world),
            unequipped: horizon_unequipped,
            equipped: horizon_equipped,
            horizon_sum,
        };
        if let Some(a) = engine.auto_table(set, hz) {
            return match a.tool {
                Some(k) => Ok((ToolSel::Tool(k), a.values)),
                None => no_tool(world, set),
            };
        }
    }
    let (tool, _) = resolve(world, engine, choice, set)?;
    let values =
        engine.lookup_values(tool, set, horizon_unequipped, horizon_equipped, horizon_sum)?;
    Ok((tool, values))
}

/// Parse a comma-separated inventory into a bit mask.
pub fn holding_mask(world: &World, text: &str) -> Result<u16> {
    let mut m = 0u16;
    for t in text.split(',').map(str::trim).filter(|t| !t.is_empty()) {
        match world.tool_index(t) {
            Some(k) => m |= 1 << k,
            None => {
                return bad(format!(
                    "unknown tool '{t}' in the inventory for world '{}' (tools: {})",
                    world.name,
                    world.tool_list()
                ))
            }
        }
    }
    Ok(m)
}

/// The matrix's columns: each name of `objects` (comma separated) as a single-object
/// column (default: every object of the world), then each joint set of `joint`; refused
/// when there is no column or the world has no tool for a row.
pub fn matrix_columns(
    world: &World,
    objects: Option<&str>,
    joint: &[String],
) -> Result<Vec<ObjectSet>> {
    let mut columns: Vec<ObjectSet> = match objects {
        Some(list) => list
            .split(',')
            .map(|n| object_set(world, n.trim()))
            .collect::<Result<_>>()?,
        None => (0..world.objects.len())
            .map(|i| ObjectSet::Objects(vec![i]))
            .collect(),
    };
    for j in joint {
        columns.push(object_set(world, j)?);
    }
    if columns.is_empty() {
        return bad(format!(
            "world '{}' has no objects: nothing to put in the matrix's columns",
            world.name
        ));
    }
    if world.tools.is_empty() {
        return bad(format!(
            "world '{}' has no tools: the matrix has no rows",
            world.name
        ));
    }
    Ok(columns)
}
