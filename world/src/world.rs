//! The tool world: map, tools, objects, rules, and the exact dynamics of `docs/world.md`.
//!
//! A [`World`] is immutable once parsed; everything that changes lives in a [`State`].
//! [`World::step`] is the deterministic transition function T(s, a): no randomness, no
//! step counter, no task. Episodes (rewards, termination, truncation) are in
//! [`crate::env`].
//!
//! Actions: `N=0, E=1, S=2, W=3, apply=4`, then `select_k = 5 + k`, so |A| = 5 + n.

use crate::state::{Mode, State, BOULDER_DESTROYED};

/// The largest map side a world may have (its tool and object counts are bounded by the
/// packed state: [`crate::state::MAX_TOOLS`], [`crate::state::MAX_OBJECTS`]).
pub const MAX_SIDE: usize = 64;

/// Move north (y - 1).
pub const NORTH: u8 = 0;
/// Move east (x + 1).
pub const EAST: u8 = 1;
/// Move south (y + 1).
pub const SOUTH: u8 = 2;
/// Move west (x - 1).
pub const WEST: u8 = 3;
/// Open the tool prompt.
pub const APPLY: u8 = 4;
/// `select_k` is `SELECT0 + k`.
pub const SELECT0: u8 = 5;

/// (dx, dy) of the four directions, indexed by action.
pub const DIRS: [(i32, i32); 4] = [(0, -1), (1, 0), (0, 1), (-1, 0)];

/// What lies under everything else on a cell. Static.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Terrain {
    /// `#`, `-`, `|` or space: blocks movement and bolts, never changes.
    Rock,
    /// `.`, and what lies under the agent, tools and objects.
    Floor,
    /// `>`: floor that push tasks aim at.
    Goal,
}

/// The four kinds of object (`docs/world.md`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ObjectKind {
    /// `T`: intact / destroyed.
    Tree,
    /// `=`: a diggable wall block, intact / destroyed.
    Wall,
    /// `+`: closed (locked) / open / destroyed.
    Door,
    /// `0`: intact at a position / destroyed.
    Boulder,
}

impl ObjectKind {
    /// The name used in world files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ObjectKind::Tree => "tree",
            ObjectKind::Wall => "wall",
            ObjectKind::Door => "door",
            ObjectKind::Boulder => "boulder",
        }
    }

    /// Parse a kind name.
    pub fn from_name(s: &str) -> Option<Self> {
        Some(match s {
            "tree" => ObjectKind::Tree,
            "wall" => ObjectKind::Wall,
            "door" => ObjectKind::Door,
            "boulder" => ObjectKind::Boulder,
            _ => return None,
        })
    }

    /// The map glyph.
    pub fn glyph(self) -> char {
        match self {
            ObjectKind::Tree => 'T',
            ObjectKind::Wall => '=',
            ObjectKind::Door => '+',
            ObjectKind::Boulder => '0',
        }
    }

    /// The names of the abstract states of this kind, by [`Cond`] code.
    pub fn condition_names(self) -> &'static [&'static str] {
        match self {
            ObjectKind::Door => &["closed", "open", "destroyed"],
            _ => &["intact", "destroyed"],
        }
    }
}

/// The abstract condition of an object, independent of a boulder's position.
/// Codes: 0 = intact (doors: closed), 1 = open (doors only), 2 = destroyed.
pub type Cond = u8;
/// Intact (trees, walls, boulders) or closed (doors).
pub const INTACT: Cond = 0;
/// Open (doors only).
pub const OPEN: Cond = 1;
/// Destroyed: the cell is floor.
pub const DESTROYED: Cond = 2;

/// Parse a condition name for a kind (`closed` only for doors, `intact` for the rest).
pub fn cond_from_name(kind: ObjectKind, s: &str) -> Option<Cond> {
    match (kind, s) {
        (ObjectKind::Door, "closed") => Some(INTACT),
        (ObjectKind::Door, "open") => Some(OPEN),
        (ObjectKind::Door, _) => (s == "destroyed").then_some(DESTROYED),
        (_, "intact") => Some(INTACT),
        (_, "destroyed") => Some(DESTROYED),
        _ => None,
    }
}

/// The name of a condition of a kind.
pub fn cond_name(kind: ObjectKind, c: Cond) -> &'static str {
    match (kind, c) {
        (ObjectKind::Door, INTACT) => "closed",
        (ObjectKind::Door, OPEN) => "open",
        (_, INTACT) => "intact",
        _ => "destroyed",
    }
}

/// A tool lying on the map at the start.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Tool {
    /// The map letter.
    pub letter: char,
    /// The kind (`axe`, `key`, ... or any distractor name).
    pub kind: String,
    /// Its name: the kind, or `kind#i` when the kind occurs more than once.
    pub name: String,
    /// Cell (x, y).
    pub pos: (u8, u8),
}

/// An object of the map.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Object {
    /// Its kind.
    pub kind: ObjectKind,
    /// Its name: the kind, or `kind#i` in reading order when the kind occurs more than once.
    pub name: String,
    /// Its initial cell (x, y). Trees, walls and doors never move.
    pub pos: (u8, u8),
}

/// How far a rule reaches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Range {
    /// The single cell next to the agent.
    Adjacent,
    /// A bolt along the direction (see `docs/world.md`).
    Bolt,
}

/// One line of the rule table: `tool` turns a `target` in condition `from` into `to`,
/// with probability `p` when it would act (1 in a deterministic world).
#[derive(Clone, Debug, PartialEq)]
pub struct Rule {
    /// The tool kind.
    pub tool: String,
    /// The object kind acted on.
    pub target: ObjectKind,
    /// Condition before.
    pub from: Cond,
    /// Condition after.
    pub to: Cond,
    /// Reach.
    pub range: Range,
    /// The probability that the rule acts when it would (`0 < p <= 1`; default 1).
    pub p: f64,
}

impl Rule {
    /// Whether the rule destroys an object of `kind` from the condition it starts in
    /// (intact, or a closed door): what makes a tool fit a destroy task.
    pub fn destroys_from_start(&self, kind: ObjectKind) -> bool {
        self.target == kind && self.from == INTACT && self.to == DESTROYED
    }
}

/// The default rule table (`docs/world.md`, "What tools do").
pub fn default_rules() -> Vec<Rule> {
    use ObjectKind::*;
    let r = |tool: &str, target, from, to, range| Rule {
        tool: tool.to_string(),
        target,
        from,
        to,
        range,
        p: 1.0,
    };
    vec![
        r("axe", Tree, INTACT, DESTROYED, Range::Adjacent),
        r("axe", Door, INTACT, DESTROYED, Range::Adjacent),
        r("pickaxe", Wall, INTACT, DESTROYED, Range::Adjacent),
        r("pickaxe", Door, INTACT, DESTROYED, Range::Adjacent),
        r("pickaxe", Boulder, INTACT, DESTROYED, Range::Adjacent),
        r("key", Door, INTACT, OPEN, Range::Adjacent),
        r("key", Door, OPEN, INTACT, Range::Adjacent),
        r("wand", Boulder, INTACT, DESTROYED, Range::Bolt),
        r("wand", Door, INTACT, DESTROYED, Range::Bolt),
    ]
}

/// What pays the extrinsic reward.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Task {
    /// No extrinsic reward, never terminal.
    None,
    /// +1 for each listed object the first time it is destroyed; terminal once all are.
    Destroy(Vec<usize>),
    /// +1 and terminal when this boulder stands on a goal cell.
    Push(usize),
}

/// The tool named in `[empowerment]`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ToolChoice {
    /// Tool selection by the matrix (equation 6 of the paper).
    Auto,
    /// One tool, by index.
    Tool(usize),
    /// The full action set A.
    All,
}

/// An object set D: real objects, or the pseudo-object `agent` (the agent's position).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum ObjectSet {
    /// The agent's position.
    Agent,
    /// These objects jointly (indices, sorted, distinct, non-empty).
    Objects(Vec<usize>),
    /// These objects jointly by their conditions only (`conditions:boulder` on the
    /// command line): a boulder counts as intact or destroyed whatever its cell; the
    /// other kinds have no cell and count as in [`ObjectSet::Objects`]. `boulders` has
    /// bit i set where object i is a boulder ([`World::conditions_of`] makes it).
    Conditions {
        /// Indices, sorted, distinct, non-empty.
        objects: Vec<usize>,
        /// Bit i: object i is a boulder.
        boulders: u16,
    },
}

impl ObjectSet {
    /// The objects' indices (none for the agent).
    pub fn indices(&self) -> &[usize] {
        match self {
            ObjectSet::Agent => &[],
            ObjectSet::Objects(v) | ObjectSet::Conditions { objects: v, .. } => v,
        }
    }

    /// The same objects by their conditions only (the agent stays the agent).
    pub fn conditions(&self, world: &World) -> ObjectSet {
        match self {
            ObjectSet::Agent => ObjectSet::Agent,
            ObjectSet::Objects(v) | ObjectSet::Conditions { objects: v, .. } => {
                world.conditions_of(v.clone())
            }
        }
    }
}

/// Defaults for the intrinsic reward, from `[empowerment]`.
#[derive(Clone, Debug, PartialEq)]
pub struct EmpowermentDefaults {
    /// Which tool's action subset.
    pub tool: ToolChoice,
    /// The object(s) of interest D, or None when the file names none.
    pub objects: Option<ObjectSet>,
    /// h where the selected tool is not held.
    pub horizon_unequipped: u32,
    /// h where it is held.
    pub horizon_equipped: u32,
    /// Weight of the intrinsic reward.
    pub beta: f64,
}

/// A parsed, validated tool world. Immutable.
#[derive(Clone, Debug)]
pub struct World {
    /// `[a-z0-9-]+`.
    pub name: String,
    /// Episode truncation.
    pub max_steps: u32,
    /// Map width (cells).
    pub width: usize,
    /// Map height (cells).
    pub height: usize,
    /// Base terrain, row-major.
    pub(crate) terrain: Vec<Terrain>,
    /// Tools in `[tools]` order.
    pub tools: Vec<Tool>,
    /// Objects in reading order.
    pub objects: Vec<Object>,
    /// The rule table in force (defaults, then `[[rules]]`).
    pub rules: Vec<Rule>,
    /// The probability that a move slips to one of the three other directions
    /// (`[dynamics] slip`, `0 <= slip < 1`; 0 by default).
    pub slip: f64,
    /// Whether anything is left to chance (a slip above 0 or a rule with p below 1).
    pub(crate) stochastic: bool,
    /// Rules per tool index, in table order.
    pub(crate) tool_rules: Vec<Vec<Rule>>,
    /// Whether a tool has any bolt rule.
    pub(crate) tool_bolt: Vec<bool>,
    /// Cell -> tool index + 1 (0 = none).
    pub(crate) tool_at: Vec<u8>,
    /// Cell -> static object (tree, wall, door) index + 1 (0 = none).
    pub(crate) static_at: Vec<u8>,
    /// Indices of the boulders.
    pub(crate) boulders: Vec<u8>,
    /// The task.
    pub task: Task,
    /// `[empowerment]` defaults.
    pub empowerment: EmpowermentDefaults,
    /// The start state.
    pub initial: State,
    /// The file's text (hashed to identify the world).
    pub source: String,
}

impl World {
    /// |A| = 5 + number of tools.
    pub fn num_actions(&self) -> usize {
        5 + self.tools.len()
    }

    /// The tools that fit the task: for a destroy task, the tools (by index) with a rule
    /// of this world's table that destroys one of the task's objects from the condition it
    /// starts in (intact, or a closed door); `None` for a push task or no task, where no
    /// tool fits by the rule table. What the tool-choice figure of an evaluation counts.
    pub fn fitting_tools(&self) -> Option<Vec<usize>> {
        let Task::Destroy(list) = &self.task else {
            return None;
        };
        Some(
            (0..self.tools.len())
                .filter(|&k| {
                    self.rules.iter().any(|r| {
                        r.tool == self.tools[k].kind
                            && list
                                .iter()
                                .any(|&i| r.destroys_from_start(self.objects[i].kind))
                    })
                })
                .collect(),
        )
    }

    /// The action subset of tool j: {N, E, S, W, apply, select_j}.
    pub fn tool_actions(&self, j: usize) -> [u8; 6] {
        [NORTH, EAST, SOUTH, WEST, APPLY, SELECT0 + j as u8]
    }

    /// The name of an action.
    pub fn action_name(&self, a: u8) -> String {
        match a {
            NORTH => "N".into(),
            EAST => "E".into(),
            SOUTH => "S".into(),
            WEST => "W".into(),
            APPLY => "apply".into(),
            _ => self
                .tools
                .get((a - SELECT0) as usize)
                .map(|t| t.name.clone())
                .unwrap_or_else(|| format!("action{a}")),
        }
    }

    /// Parse an action name: `N E S W apply`, a tool name, kind or letter (= select it),
    /// or a number.
    pub fn parse_action(&self, s: &str) -> Option<u8> {
        match s {
            "N" | "n" | "north" => Some(NORTH),
            "E" | "e" | "east" => Some(EAST),
            "S" | "s" | "south" => Some(SOUTH),
            "W" | "w" | "west" => Some(WEST),
            "apply" => Some(APPLY),
            _ => {
                if let Some(k) = self.tool_index(s) {
                    return Some(SELECT0 + k as u8);
                }
                s.parse::<u8>()
                    .ok()
                    .filter(|&a| (a as usize) < self.num_actions())
            }
        }
    }

    /// Find a tool by name (`key`, `key#1`), or by its map letter.
    pub fn tool_index(&self, s: &str) -> Option<usize> {
        self.tools
            .iter()
            .position(|t| t.name == s)
            .or_else(|| self.tools.iter().position(|t| t.kind == s))
            .or_else(|| {
                let mut c = s.chars();
                match (c.next(), c.next()) {
                    (Some(l), None) => self.tools.iter().position(|t| t.letter == l),
                    _ => None,
                }
            })
    }

    /// Find an object by name (`door`, `door#0`).
    pub fn object_index(&self, s: &str) -> Option<usize> {
        find_object_by_name(&self.objects, s)
    }

    /// Base terrain at (x, y); `Rock` outside the map.
    pub fn terrain(&self, x: i32, y: i32) -> Terrain {
        if x < 0 || y < 0 || x as usize >= self.width || y as usize >= self.height {
            Terrain::Rock
        } else {
            self.terrain[y as usize * self.width + x as usize]
        }
    }

    /// The tool whose start cell is (x, y), if any (held or not).
    pub fn tool_cell(&self, x: usize, y: usize) -> Option<usize> {
        match self.tool_at[y * self.width + x] {
            0 => None,
            t => Some(t as usize - 1),
        }
    }

    /// The tree, wall or door whose cell is (x, y), if any (in any condition).
    pub fn static_object_cell(&self, x: usize, y: usize) -> Option<usize> {
        match self.static_at[y * self.width + x] {
            0 => None,
            o => Some(o as usize - 1),
        }
    }

    /// The boulders' object indices.
    pub fn boulder_indices(&self) -> impl Iterator<Item = usize> + '_ {
        self.boulders.iter().map(|&b| b as usize)
    }

    /// The set of objects `v` (sorted, distinct indices) by their conditions only.
    pub fn conditions_of(&self, v: Vec<usize>) -> ObjectSet {
        let boulders = v
            .iter()
            .filter(|&&i| self.objects[i].kind == ObjectKind::Boulder)
            .fold(0u16, |m, &i| m | 1 << i);
        ObjectSet::Conditions {
            objects: v,
            boulders,
        }
    }

    /// The abstract condition of object `i` in `s`.
    #[inline]
    pub fn cond(&self, s: &State, i: usize) -> Cond {
        let v = s.objects[i];
        if self.objects[i].kind == ObjectKind::Boulder {
            if v == BOULDER_DESTROYED {
                DESTROYED
            } else {
                INTACT
            }
        } else {
            v as Cond
        }
    }

    /// The intact boulder standing on cell index `c`, if any.
    #[inline]
    fn boulder_on(&self, s: &State, c: u16) -> Option<usize> {
        self.boulders
            .iter()
            .map(|&b| b as usize)
            .find(|&b| s.objects[b] == c)
    }

    /// Whether a static object on cell `c` blocks (intact tree/wall, closed door).
    #[inline]
    fn static_blocks(&self, s: &State, c: usize) -> bool {
        match self.static_at[c] {
            0 => false,
            o => s.objects[o as usize - 1] == INTACT as u16,
        }
    }

    /// Cell index of (x, y) if it is inside the map.
    #[inline]
    fn cell(&self, x: i32, y: i32) -> Option<usize> {
        if x < 0 || y < 0 || x as usize >= self.width || y as usize >= self.height {
            None
        } else {
            Some(y as usize * self.width + x as usize)
        }
    }

    /// T(s, a): the next state; actions out of range act as "stay". In a stochastic world
    /// (`crate::chance`) it is the intended outcome: no slip, and a rule that would act
    /// acts, which has positive probability; [`World::outcomes`] gives them all.
    #[inline]
    pub fn step(&self, s: &State, a: u8) -> State {
        let mut n = *s;
        self.step_in_place(&mut n, a);
        n
    }

    /// T(s, a) in place: `n` becomes the next state (same result as [`World::step`],
    /// without copying the state in and out).
    pub fn step_in_place(&self, n: &mut State, a: u8) {
        self.step_inline(n, a);
    }

    /// The body of [`World::step_in_place`], inlined into [`World::env_step`].
    #[inline(always)]
    pub(crate) fn step_inline(&self, n: &mut State, a: u8) {
        match n.mode {
            0 => {
                if a < 4 {
                    self.walk(n, a);
                } else if a == APPLY && n.inventory != 0 {
                    n.set_mode(Mode::ChoosingTool);
                }
            }
            1 => {
                let k = a.wrapping_sub(SELECT0) as usize;
                if a >= SELECT0 && k < self.tools.len() && n.holds(k) {
                    n.set_mode(Mode::ChoosingDirection(k as u8));
                } else {
                    n.set_mode(Mode::Normal);
                }
            }
            m => {
                n.set_mode(Mode::Normal);
                if a < 4 {
                    // The rule's probability matters only to the stochastic dynamics.
                    let _ = self.use_tool(n, (m - 2) as usize, a);
                }
            }
        }
    }

    /// Move one cell in direction `d`, pushing a boulder and picking up a tool.
    #[inline]
    pub(crate) fn walk(&self, n: &mut State, d: u8) {
        let (dx, dy) = DIRS[d as usize];
        let (tx, ty) = (n.x as i32 + dx, n.y as i32 + dy);
        let Some(t) = self.cell(tx, ty) else { return };
        if self.terrain[t] == Terrain::Rock || self.static_blocks(n, t) {
            return;
        }
        if let Some(b) = self.boulder_on(n, t as u16) {
            let Some(beyond) = self.cell(tx + dx, ty + dy) else {
                return;
            };
            let free = self.terrain[beyond] != Terrain::Rock
                && !self.static_blocks(n, beyond)
                && !self.tool_lies(n, beyond)
                && self.boulder_on(n, beyond as u16).is_none();
            if !free {
                return;
            }
            n.objects[b] = beyond as u16;
        }
        n.x = tx as u8;
        n.y = ty as u8;
        if let k @ 1.. = self.tool_at[t] {
            n.inventory |= 1 << (k - 1);
        }
    }

    /// Whether a tool lies (not held) on cell `c`.
    #[inline]
    fn tool_lies(&self, n: &State, c: usize) -> bool {
        match self.tool_at[c] {
            0 => false,
            t => !n.holds(t as usize - 1),
        }
    }

    /// Tool `k` acts in direction `d`: range-1 rules on the next cell, bolt rules along
    /// the line until a rule applies or a cell blocks bolts. Returns the probability of
    /// the rule that acted (1 when none did).
    pub(crate) fn use_tool(&self, n: &mut State, k: usize, d: u8) -> f64 {
        let rules = &self.tool_rules[k];
        if rules.is_empty() {
            return 1.0;
        }
        let (dx, dy) = DIRS[d as usize];
        let (mut x, mut y) = (n.x as i32 + dx, n.y as i32 + dy);
        let mut adjacent = true;
        while let Some(c) = self.cell(x, y) {
            // Objects on this cell, in object order: the static one and intact boulders.
            let mut hit = None;
            for i in self.objects_on(n, c) {
                let cond = self.cond(n, i);
                let kind = self.objects[i].kind;
                let rule = rules.iter().find(|r| {
                    r.target == kind
                        && r.from == cond
                        && (adjacent || r.range == Range::Bolt)
                        && !(self.blocking(kind, r.to) && self.occupied_by_other(n, c, i))
                });
                if let Some(r) = rule {
                    hit = Some((i, r.to, r.p));
                    break;
                }
            }
            if let Some((i, to, p)) = hit {
                n.objects[i] = if self.objects[i].kind == ObjectKind::Boulder {
                    // Rules never restore a destroyed boulder (refused when parsing).
                    if to == DESTROYED {
                        BOULDER_DESTROYED
                    } else {
                        n.objects[i]
                    }
                } else {
                    to as u16
                };
                return p;
            }
            let blocks = self.terrain[c] == Terrain::Rock
                || self.static_blocks(n, c)
                || self.boulder_on(n, c as u16).is_some();
            if blocks || !self.tool_bolt[k] {
                return 1.0;
            }
            adjacent = false;
            x += dx;
            y += dy;
        }
        1.0
    }

    /// Whether condition `to` of `kind` blocks movement (so it may not close on something).
    fn blocking(&self, kind: ObjectKind, to: Cond) -> bool {
        kind != ObjectKind::Boulder && to == INTACT
    }

    /// Whether the agent or a boulder other than object `i` stands on cell `c`.
    fn occupied_by_other(&self, n: &State, c: usize, i: usize) -> bool {
        let agent = n.y as usize * self.width + n.x as usize;
        agent == c
            || self
                .boulders
                .iter()
                .any(|&b| b as usize != i && n.objects[b as usize] == c as u16)
    }

    /// The objects present on cell `c` in `n`, in object order.
    fn objects_on(&self, n: &State, c: usize) -> impl Iterator<Item = usize> + '_ {
        let st = self.static_at[c];
        let n = *n;
        (0..self.objects.len()).filter(move |&i| {
            if self.objects[i].kind == ObjectKind::Boulder {
                n.objects[i] == c as u16
            } else {
                st as usize == i + 1
            }
        })
    }

    /// Whether `s` stands on a goal with boulder `b`.
    pub fn boulder_on_goal(&self, s: &State, b: usize) -> bool {
        let v = s.objects[b];
        v != BOULDER_DESTROYED && self.terrain[v as usize] == Terrain::Goal
    }

    /// A short stable hash of the world's contents (FNV-1a over the source text), used
    /// by services and clients to check they speak about the same world.
    pub fn content_hash(&self) -> u64 {
        crate::hash::text_hash(&self.source)
    }

    /// Render a state as the map it shows (rows joined by newlines).
    pub fn render(&self, s: &State) -> String {
        let mut out = String::with_capacity((self.width + 1) * self.height);
        for y in 0..self.height {
            for x in 0..self.width {
                out.push(self.glyph_at(s, x, y));
            }
            out.push('\n');
        }
        out
    }

    /// The glyph a player would see on (x, y) in `s`.
    pub fn glyph_at(&self, s: &State, x: usize, y: usize) -> char {
        let c = y * self.width + x;
        if (s.x as usize, s.y as usize) == (x, y) {
            return '@';
        }
        if self.boulder_on(s, c as u16).is_some() {
            return '0';
        }
        if let Some(o) = self.static_object_cell(x, y) {
            let kind = self.objects[o].kind;
            match (kind, s.objects[o] as Cond) {
                (ObjectKind::Door, OPEN) => return '\'',
                (_, INTACT) => return kind.glyph(),
                _ => {}
            }
        }
        if let Some(t) = self.tool_cell(x, y) {
            if !s.holds(t) {
                return self.tools[t].letter;
            }
        }
        match self.terrain[c] {
            Terrain::Rock => '#',
            Terrain::Floor => '.',
            Terrain::Goal => '>',
        }
    }
}

/// The object named `n` (`door`, or `kind#k`: the k-th object of that kind).
pub(crate) fn find_object_by_name(objects: &[Object], n: &str) -> Option<usize> {
    objects.iter().position(|o| o.name == n).or_else(|| {
        let (kind, ord) = n.split_once('#')?;
        let ord: usize = ord.parse().ok()?;
        let kind = ObjectKind::from_name(kind)?;
        objects
            .iter()
            .enumerate()
            .filter(|(_, o)| o.kind == kind)
            .nth(ord)
            .map(|(i, _)| i)
    })
}
