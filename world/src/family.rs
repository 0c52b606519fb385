//! World families: a distribution of layouts of one size, drawn by seed.
//!
//! A family file is a world file with a `[family]` table instead of a `map`
//! (`docs/world.md`, "World families"). A layout is a pure function of the family and a
//! layout seed: [`Family::layout_text`](crate::family::Family::layout_text) writes it as an ordinary world file, which
//! [`Family::layout`](crate::family::Family::layout) parses like any other. Every layout of a family has the same
//! width and height, the same tools in the same order (so the same actions and the same
//! glyph alphabet) and the same number of objects, so the observation's shape and the
//! action space are the family's, not the layout's.
//!
//! A layout is drawn as follows, from a ChaCha8 generator seeded with the layout seed:
//! the room (a rock border; with `divider`, a rock wall across the room at a random
//! column, with a closed door at a random row, the agent's room on its west), inner
//! rock (each cell of a room with probability `rock`), the task object's kind (uniform
//! over `objects`), then the agent, each tool in `tools` order and the task object on
//! distinct floor cells drawn uniformly (with `divider`: the agent and the tools in the
//! west room, the task object in the east room). The task is to destroy the task
//! object. A draw whose task cannot be done within `max_steps` (a breadth-first search
//! with the world's own step, [`fewest_steps_to_task`](crate::generate::fewest_steps_to_task),
//! answered first by a short plan where one does it:
//! [`task_doable_within`](crate::generate::task_doable_within), the same answer) is drawn
//! again from the same generator, so the layout of a seed is the first solvable draw.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Deserialize;
use toml::Spanned;

use crate::generate::task_doable_within;
pub use crate::parse::is_family_text;
use crate::parse::{parse_world, Ctx, WorldError, MAX_HORIZON};
use crate::state::MAX_TOOLS;
use crate::world::{default_rules, ObjectKind, World, MAX_SIDE};

/// Draws of one layout seed before the family is called unsolvable at that seed.
pub const MAX_DRAWS: u32 = 1000;

/// A world family (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Family {
    /// `[a-z0-9-]+`; layout `n` is named `<name>-<n>`.
    pub name: String,
    /// Episode truncation of every layout.
    pub max_steps: u32,
    /// Map width, rock border included.
    pub width: usize,
    /// Map height, rock border included.
    pub height: usize,
    /// Tool kinds, one of each on every layout, in tool-index order.
    pub tools: Vec<String>,
    /// The kinds the task object is drawn from.
    pub objects: Vec<ObjectKind>,
    /// The probability that an inner cell of a room is rock.
    pub rock: f64,
    /// Two rooms: a rock wall across the map with a closed door in it.
    pub divider: bool,
    /// `[empowerment]` of every layout: the tool (`auto`, `all` or a kind).
    pub emp_tool: String,
    /// Horizon where the tool is not held.
    pub horizon_unequipped: u32,
    /// Horizon where the tool is held.
    pub horizon_equipped: u32,
    /// The intrinsic reward's weight of the file.
    pub beta: f64,
    /// The file's text.
    pub source: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFile {
    name: Spanned<String>,
    max_steps: Option<Spanned<i64>>,
    family: Spanned<RawFamily>,
    empowerment: Option<RawEmpowerment>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFamily {
    width: Spanned<i64>,
    height: Spanned<i64>,
    tools: Spanned<Vec<Spanned<String>>>,
    objects: Spanned<Vec<Spanned<String>>>,
    rock: Option<Spanned<f64>>,
    divider: Option<bool>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEmpowerment {
    tool: Option<Spanned<String>>,
    horizon_unequipped: Option<Spanned<i64>>,
    horizon_equipped: Option<Spanned<i64>>,
    beta: Option<Spanned<f64>>,
}

/// Whether `name_or_path` names a family: a built-in family or a family file.
pub fn is_family(name_or_path: &str) -> bool {
    let path = std::path::Path::new(name_or_path);
    if path.is_file() {
        return std::fs::read_to_string(path)
            .map(|t| is_family_text(&t))
            .unwrap_or(false);
    }
    crate::builtin::family_source(name_or_path).is_some()
}

/// Load a family by built-in name or path.
pub fn load_family(name_or_path: &str) -> Result<Family, WorldError> {
    let path = std::path::Path::new(name_or_path);
    if path.is_file() {
        let text = std::fs::read_to_string(path).map_err(|e| WorldError::Io {
            path: name_or_path.to_string(),
            msg: e.to_string(),
        })?;
        return parse_family(&text, name_or_path);
    }
    match crate::builtin::family_source(name_or_path) {
        Some(text) => parse_family(text, name_or_path),
        None => Err(WorldError::Unknown(name_or_path.to_string())),
    }
}

/// What a run on `name_or_path` stands on: for a family, its [`Family::run_world`] and
/// the family; for a world, the world.
pub fn load_world_or_family(name_or_path: &str) -> Result<(World, Option<Family>), WorldError> {
    if is_family(name_or_path) {
        let f = load_family(name_or_path)?;
        Ok((f.run_world()?, Some(f)))
    } else {
        Ok((crate::parse::load_world(name_or_path)?, None))
    }
}

/// The tool kinds whose default rules destroy an object of `kind` from its start
/// condition (intact, or a closed door).
pub fn destroyers(kind: ObjectKind) -> Vec<String> {
    let mut v: Vec<String> = default_rules()
        .into_iter()
        .filter(|r| r.destroys_from_start(kind))
        .map(|r| r.tool)
        .collect();
    v.dedup();
    v
}

/// Parse and check a family file's text (`file` names it in errors). A family no
/// layout of which can be solved is refused here: layout 0 is drawn.
pub fn parse_family(text: &str, file: &str) -> Result<Family, WorldError> {
    let cx = Ctx { text, file };
    let raw: RawFile = cx.toml()?;
    let name = cx.name("family", &raw.name)?;
    let max_steps = cx.max_steps(&raw.max_steps)?;
    let fam = raw.family.get_ref();
    let side = |v: &Spanned<i64>, what: &str| {
        let x = *v.get_ref();
        if (5..=MAX_SIDE as i64).contains(&x) {
            Ok(x as usize)
        } else {
            Err(cx.at(
                v.span().start,
                format!("[family] {what} {x} must be 5 to {MAX_SIDE} (the border is rock)"),
            ))
        }
    };
    let width = side(&fam.width, "width")?;
    let height = side(&fam.height, "height")?;
    let mut tools: Vec<String> = Vec::new();
    for t in fam.tools.get_ref() {
        let k = t.get_ref();
        if k.is_empty()
            || !k
                .bytes()
                .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_')
        {
            return Err(cx.at(
                t.span().start,
                format!("tool kind '{k}' must be made of a-z, 0-9 and '_'"),
            ));
        }
        if tools.contains(k) {
            return Err(cx.at(
                t.span().start,
                format!("tool kind '{k}' is listed twice: a layout holds one of each kind"),
            ));
        }
        tools.push(k.clone());
    }
    if tools.is_empty() || tools.len() > MAX_TOOLS {
        return Err(cx.at(
            fam.tools.span().start,
            format!(
                "[family] tools lists {} kinds: a family has 1 to {MAX_TOOLS}",
                tools.len()
            ),
        ));
    }
    let divider = fam.divider.unwrap_or(false);
    let mut objects = Vec::new();
    for o in fam.objects.get_ref() {
        let Some(k) = ObjectKind::from_name(o.get_ref()) else {
            return Err(cx.at(
                o.span().start,
                format!(
                    "unknown object kind '{}' (kinds: tree, wall, door, boulder)",
                    o.get_ref()
                ),
            ));
        };
        if objects.contains(&k) {
            return Err(cx.at(
                o.span().start,
                format!("object kind '{}' is listed twice", k.name()),
            ));
        }
        if divider && k == ObjectKind::Door {
            return Err(cx.at(
                o.span().start,
                "with divider the door between the rooms is not a task object: list tree, wall or boulder",
            ));
        }
        // A task no layout can solve: no tool of the family destroys the object.
        if !destroyers(k).iter().any(|d| tools.contains(d)) {
            return Err(cx.at(
                o.span().start,
                format!(
                    "no tool of [family] tools destroys a {} (tools that do: {}): no layout with it as the task object could be solved",
                    k.name(),
                    destroyers(k).join(", ")
                ),
            ));
        }
        objects.push(k);
    }
    if objects.is_empty() {
        return Err(cx.at(
            fam.objects.span().start,
            "[family] objects lists no object kind: give the kinds the task object is drawn from",
        ));
    }
    if divider && !tools.iter().any(|t| passes_door(t)) {
        return Err(cx.at(
            raw.family.span().start,
            "with divider no tool of [family] tools opens or breaks the door (key, axe, pickaxe, wand): no layout could be solved",
        ));
    }
    if divider && width < 7 {
        return Err(cx.at(
            fam.width.span().start,
            format!("[family] width {width} leaves no room for two rooms: with divider it must be at least 7"),
        ));
    }
    let rock = match &fam.rock {
        None => 0.0,
        Some(r) if (0.0..0.5).contains(r.get_ref()) => *r.get_ref(),
        Some(r) => {
            return Err(cx.at(
                r.span().start,
                format!("[family] rock {} must be in [0, 0.5)", r.get_ref()),
            ))
        }
    };
    // The agent's room must hold the agent and every tool; the task object's, itself.
    let west_columns = if divider { 2 } else { width - 2 };
    if west_columns * (height - 2) < 1 + tools.len() + usize::from(!divider) {
        return Err(cx.at(
            raw.family.span().start,
            format!(
                "a {width}x{height} room is too small for the agent, {} tools and the task object",
                tools.len()
            ),
        ));
    }
    let (mut emp_tool, mut hu, mut he, mut beta) = ("auto".to_string(), 8, 3, 0.0);
    if let Some(e) = &raw.empowerment {
        if let Some(t) = &e.tool {
            let v = t.get_ref();
            if v != "auto" && v != "all" && !tools.contains(v) {
                return Err(cx.at(
                    t.span().start,
                    format!(
                        "[empowerment] tool '{v}' is not a kind of [family] tools ({}), auto or all",
                        tools.join(", ")
                    ),
                ));
            }
            emp_tool = v.clone();
        }
        let horizon = |h: &Spanned<i64>, what: &str| {
            let v = *h.get_ref();
            if (0..=MAX_HORIZON as i64).contains(&v) {
                Ok(v as u32)
            } else {
                Err(cx.at(
                    h.span().start,
                    format!("[empowerment] {what} {v} must be 0 to {MAX_HORIZON}"),
                ))
            }
        };
        let u = e
            .horizon_unequipped
            .as_ref()
            .map(|h| horizon(h, "horizon_unequipped"))
            .transpose()?;
        let q = e
            .horizon_equipped
            .as_ref()
            .map(|h| horizon(h, "horizon_equipped"))
            .transpose()?;
        // One horizon given serves both, as in a world file.
        (hu, he) = match (u, q) {
            (Some(u), Some(q)) => (u, q),
            (Some(x), None) | (None, Some(x)) => (x, x),
            (None, None) => (hu, he),
        };
        if let Some(b) = &e.beta {
            if !(b.get_ref().is_finite() && *b.get_ref() >= 0.0) {
                return Err(cx.at(
                    b.span().start,
                    format!(
                        "[empowerment] beta {} must be a finite number >= 0",
                        b.get_ref()
                    ),
                ));
            }
            beta = *b.get_ref();
        }
    }
    let family = Family {
        name,
        max_steps,
        width,
        height,
        tools,
        objects,
        rock,
        divider,
        emp_tool,
        horizon_unequipped: hu,
        horizon_equipped: he,
        beta,
        source: text.to_string(),
    };
    // A range no layout can satisfy is found here, not at the first episode.
    family.layout_text(0).map_err(|e| match e {
        WorldError::File { msg, .. } => cx.file(msg),
        other => other,
    })?;
    Ok(family)
}

/// Whether a tool kind can get the agent through a closed door (open or destroy it).
fn passes_door(kind: &str) -> bool {
    default_rules()
        .iter()
        .any(|r| r.tool == kind && r.target == ObjectKind::Door && r.from == 0)
}

/// The glyph of an object kind on a map.
fn glyph(kind: ObjectKind) -> char {
    match kind {
        ObjectKind::Tree => 'T',
        ObjectKind::Wall => '=',
        ObjectKind::Door => '+',
        ObjectKind::Boulder => '0',
    }
}

impl Family {
    /// Layout `seed` as a world file's text (see the module docs); refused when no draw
    /// of [`MAX_DRAWS`] can be solved within `max_steps`.
    pub fn layout_text(&self, seed: u64) -> Result<String, WorldError> {
        self.draw_solvable(seed).map(|(text, _)| text)
    }

    /// Layout `seed`, parsed.
    pub fn layout(&self, seed: u64) -> Result<World, WorldError> {
        self.draw_solvable(seed).map(|(_, w)| w)
    }

    /// The first draw of layout `seed` whose task can be done within an episode: its
    /// text and the world parsed from it.
    fn draw_solvable(&self, seed: u64) -> Result<(String, World), WorldError> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for _ in 0..MAX_DRAWS {
            let text = self.draw(&mut rng, seed);
            let w = parse_world(&text, &format!("{}-{seed}", self.name))?;
            if task_doable_within(&w, w.max_steps) {
                return Ok((text, w));
            }
        }
        Err(WorldError::File {
            file: self.name.clone(),
            msg: format!(
                "no draw of layout {seed} in {MAX_DRAWS} has a task that can be done within {} steps (too much rock, or a room too small)",
                self.max_steps
            ),
        })
    }

    /// The content hash of the family file (FNV-1a of its text, as
    /// [`World::content_hash`] is of a world's): a run on the family carries it.
    pub fn content_hash(&self) -> u64 {
        crate::hash::text_hash(&self.source)
    }

    /// The world a run on the family stands on where one world is needed (its shape,
    /// actions, glyph alphabet and episode limit, which every layout shares): layout 0,
    /// named after the family and carrying the family's text, so its
    /// [`World::content_hash`] is the family's.
    pub fn run_world(&self) -> Result<World, WorldError> {
        let mut w = self.layout(0)?;
        w.name = self.name.clone();
        w.source = self.source.clone();
        Ok(w)
    }

    /// One draw of a layout's file from `rng`.
    fn draw(&self, rng: &mut ChaCha8Rng, seed: u64) -> String {
        let (w, h) = (self.width, self.height);
        let mut grid = vec![vec!['#'; w]; h];
        for row in grid.iter_mut().take(h - 1).skip(1) {
            for c in row.iter_mut().take(w - 1).skip(1) {
                *c = '.';
            }
        }
        // The divider: a rock column with a closed door, rooms of at least 2 columns.
        let wall_x = if self.divider {
            let x = rng.random_range(3..=w - 4);
            let door_y = rng.random_range(1..h - 1);
            for (y, row) in grid.iter_mut().enumerate() {
                row[x] = if y == door_y { '+' } else { '#' };
            }
            Some(x)
        } else {
            None
        };
        let in_west = |x: usize| wall_x.is_none_or(|d| x < d);
        let mut west = Vec::new();
        let mut east = Vec::new();
        for (y, row) in grid.iter_mut().enumerate().take(h - 1).skip(1) {
            for (x, c) in row.iter_mut().enumerate().take(w - 1).skip(1) {
                if *c != '.' {
                    continue;
                }
                if rng.random_bool(self.rock) {
                    *c = '#';
                } else if in_west(x) {
                    west.push((x, y));
                } else {
                    east.push((x, y));
                }
            }
        }
        let kind = self.objects[rng.random_range(0..self.objects.len())];
        let take = |cells: &mut Vec<(usize, usize)>, rng: &mut ChaCha8Rng| {
            if cells.is_empty() {
                None
            } else {
                Some(cells.swap_remove(rng.random_range(0..cells.len())))
            }
        };
        let mut place = |c: char, cells: &mut Vec<(usize, usize)>, rng: &mut ChaCha8Rng| {
            if let Some((x, y)) = take(cells, rng) {
                grid[y][x] = c;
            }
        };
        place('@', &mut west, rng);
        for k in 0..self.tools.len() {
            place((b'a' + k as u8) as char, &mut west, rng);
        }
        if self.divider {
            place(glyph(kind), &mut east, rng);
        } else {
            place(glyph(kind), &mut west, rng);
        }
        let map: String = grid
            .iter()
            .map(|r| r.iter().collect::<String>() + "\n")
            .collect();
        let tools: String = self
            .tools
            .iter()
            .enumerate()
            .map(|(k, t)| format!("{} = \"{t}\"\n", (b'a' + k as u8) as char))
            .collect();
        format!(
            "# Layout {seed} of the family `{family}` (`fulcrum world show {family} --layout {seed} --toml`).\n\
             name = \"{family}-{seed}\"\nmax_steps = {steps}\nmap = \"\"\"\n{map}\"\"\"\n\n[tools]\n{tools}\n\
             [task]\nkind = \"destroy\"\nobjects = [\"{obj}\"]\n\n[empowerment]\ntool = \"{tool}\"\nobjects = [\"{obj}\"]\n\
             horizon_unequipped = {hu}\nhorizon_equipped = {he}\nbeta = {beta:?}\n",
            family = self.name,
            steps = self.max_steps,
            obj = kind.name(),
            tool = self.emp_tool,
            hu = self.horizon_unequipped,
            he = self.horizon_equipped,
            beta = self.beta,
        )
    }
}
