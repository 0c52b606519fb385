//! World files (TOML, see `docs/world.md`): parsing and validation.
//!
//! Every error names the file, and the line and column where it can be placed, in one
//! sentence. Arbitrary input never panics (property-tested).

use std::fmt;
use std::path::Path;

use serde::de::{Deserializer, MapAccess, Visitor};
use serde::Deserialize;
use toml::Spanned;

/// The map: its rows, glyphs and cells' places in the file.
mod map;

use map::{read_map, Cells, MapText};

use crate::state::{State, BOULDER_DESTROYED, MAX_TOOLS};
use crate::world::{
    cond_from_name, default_rules, find_object_by_name, EmpowermentDefaults, Object, ObjectKind,
    ObjectSet, Range, Rule, Task, Terrain, Tool, ToolChoice, World, DESTROYED, INTACT,
};

/// A world that could not be loaded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum WorldError {
    /// A mistake placed in the file.
    #[error("{file}:{line}:{col}: {msg}")]
    At {
        /// File name as given.
        file: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        col: usize,
        /// One sentence.
        msg: String,
    },
    /// A mistake about the file as a whole.
    #[error("{file}: {msg}")]
    File {
        /// File name as given.
        file: String,
        /// One sentence.
        msg: String,
    },
    /// The name is neither a file nor a built-in world.
    #[error("unknown world '{0}': no such file, and not a built-in world ({list})", list = crate::builtin::all_names().collect::<Vec<_>>().join(", "))]
    Unknown(String),
    /// The file exists but cannot be read.
    #[error("cannot read world file {path}: {msg}")]
    Io {
        /// The path.
        path: String,
        /// The OS error.
        msg: String,
    },
}

/// Load a world by built-in name or path.
pub fn load_world(name_or_path: &str) -> Result<World, WorldError> {
    let path = Path::new(name_or_path);
    if path.is_file() {
        let text = std::fs::read_to_string(path).map_err(|e| WorldError::Io {
            path: name_or_path.to_string(),
            msg: e.to_string(),
        })?;
        return parse_world(&text, name_or_path);
    }
    match crate::builtin::source(name_or_path).or(crate::builtin::family_source(name_or_path)) {
        Some(text) => parse_world(text, name_or_path),
        None => Err(WorldError::Unknown(name_or_path.to_string())),
    }
}

/// `[tools]` in file order, values with their spans.
#[derive(Debug, Default)]
struct Ordered(Vec<(String, Spanned<String>)>);

impl<'de> Deserialize<'de> for Ordered {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Ordered;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a table of map letter = \"tool kind\"")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut m: A) -> Result<Ordered, A::Error> {
                let mut v = Vec::new();
                while let Some((k, val)) = m.next_entry::<String, Spanned<String>>()? {
                    v.push((k, val));
                }
                Ok(Ordered(v))
            }
        }
        d.deserialize_map(V)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawWorld {
    name: Spanned<String>,
    max_steps: Option<Spanned<i64>>,
    map: Spanned<String>,
    #[serde(default)]
    tools: Ordered,
    task: Option<Spanned<RawTask>>,
    empowerment: Option<Spanned<RawEmpowerment>>,
    #[serde(default)]
    rules: Vec<Spanned<RawRule>>,
    dynamics: Option<Spanned<RawDynamics>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawDynamics {
    slip: Option<Spanned<toml::Value>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTask {
    kind: Spanned<String>,
    objects: Option<Vec<Spanned<String>>>,
    object: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEmpowerment {
    tool: Option<Spanned<String>>,
    objects: Option<Vec<Spanned<String>>>,
    horizon_unequipped: Option<Spanned<i64>>,
    horizon_equipped: Option<Spanned<i64>>,
    beta: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRule {
    tool: Spanned<String>,
    target: Spanned<String>,
    from: Spanned<String>,
    to: Spanned<String>,
    range: Spanned<toml::Value>,
    p: Option<Spanned<toml::Value>>,
}

/// The largest horizon a world file may name.
pub const MAX_HORIZON: u32 = 64;

/// Byte offset -> 1-based (line, column in characters).
fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text[..text.floor_char_boundary_compat(offset)];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

trait FloorBoundary {
    fn floor_char_boundary_compat(&self, i: usize) -> usize;
}
impl FloorBoundary for str {
    fn floor_char_boundary_compat(&self, mut i: usize) -> usize {
        while i > 0 && !self.is_char_boundary(i) {
            i -= 1;
        }
        i
    }
}

pub(crate) struct Ctx<'a> {
    pub(crate) text: &'a str,
    pub(crate) file: &'a str,
}

impl Ctx<'_> {
    pub(crate) fn at(&self, offset: usize, msg: impl Into<String>) -> WorldError {
        let (line, col) = line_col(self.text, offset);
        WorldError::At {
            file: self.file.to_string(),
            line,
            col,
            msg: msg.into(),
        }
    }
    pub(crate) fn file(&self, msg: impl Into<String>) -> WorldError {
        WorldError::File {
            file: self.file.to_string(),
            msg: msg.into(),
        }
    }

    /// The file's text read as TOML into `T`, a mistake placed where toml found it.
    pub(crate) fn toml<T: serde::de::DeserializeOwned>(&self) -> Result<T, WorldError> {
        toml::from_str(self.text).map_err(|e| {
            let msg = e.message().trim().trim_end_matches('.').to_string();
            match e.span() {
                Some(span) => self.at(span.start, msg),
                None => self.file(msg),
            }
        })
    }

    /// A world's or family's name (`what`): `[a-z0-9-]+`.
    pub(crate) fn name(&self, what: &str, name: &Spanned<String>) -> Result<String, WorldError> {
        let n = name.get_ref();
        if n.is_empty()
            || !n
                .bytes()
                .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-')
        {
            return Err(self.at(
                name.span().start,
                format!("{what} name '{n}' must be made of a-z, 0-9 and '-'"),
            ));
        }
        Ok(n.clone())
    }

    /// `max_steps`: 1 to 10^6, 100 when not given.
    pub(crate) fn max_steps(&self, m: &Option<Spanned<i64>>) -> Result<u32, WorldError> {
        match m {
            None => Ok(100),
            Some(m) if (1..=1_000_000).contains(m.get_ref()) => Ok(*m.get_ref() as u32),
            Some(m) => Err(self.at(
                m.span().start,
                format!("max_steps = {} must be between 1 and 1000000", m.get_ref()),
            )),
        }
    }
}

/// Whether a world file's text describes a family (has a `[family]` table).
pub fn is_family_text(text: &str) -> bool {
    text.parse::<toml::Table>()
        .map(|t| t.contains_key("family"))
        .unwrap_or(false)
}

/// Parse and validate a world file's text. `file` names it in errors.
pub fn parse_world(text: &str, file: &str) -> Result<World, WorldError> {
    let cx = Ctx { text, file };
    // A family has no map, so it fails here; only then is it told apart (one TOML read
    // for every world file).
    let raw: RawWorld = cx.toml().map_err(|e| {
        if is_family_text(text) {
            cx.file("this is a world family (a layout per seed), not one world: show a layout with `fulcrum world show FAMILY --layout N`, or write one out with --toml")
        } else {
            e
        }
    })?;
    let name = &cx.name("world", &raw.name)?;
    let max_steps = cx.max_steps(&raw.max_steps)?;
    let tool_decl = tool_decl(&cx, &raw.tools)?;
    let map = MapText::new(text, &raw.map);
    let (width, height) = map.size(&cx)?;
    let cells = read_map(&cx, &map, width, &tool_decl)?;
    let (tools, objects) = name_things(&tool_decl, &cells);
    let tkinds: Vec<String> = tool_decl.iter().map(|t| t.1.clone()).collect();
    let rules = rules(&cx, &raw.rules, &tools, &tkinds)?;
    let slip = slip(&cx, &raw.dynamics)?;
    let task = task(&cx, &raw.task, &objects, &cells.terrain)?;
    let empowerment = empowerment(&cx, &raw.empowerment, &tools, &objects, &tkinds)?;
    Ok(assemble(Parts {
        name: name.clone(),
        max_steps,
        width,
        height,
        terrain: cells.terrain,
        agent: cells.agent,
        tools,
        objects,
        rules,
        slip,
        task,
        empowerment,
        source: text.to_string(),
    }))
}

/// `[tools]`: (letter, kind, offset in the file), in file order.
fn tool_decl(cx: &Ctx, tools: &Ordered) -> Result<Vec<(char, String, usize)>, WorldError> {
    let mut tool_decl: Vec<(char, String, usize)> = Vec::new();
    for (letter, kind) in &tools.0 {
        let off = kind.span().start;
        let mut cs = letter.chars();
        let l = match (cs.next(), cs.next()) {
            (Some(l), None) if l.is_ascii_lowercase() => l,
            _ => {
                return Err(cx.at(
                    off,
                    format!(
                    "[tools] key '{letter}' must be one lowercase letter (the tool's map glyph)"
                ),
                ))
            }
        };
        let k = kind.get_ref();
        if k.is_empty()
            || !k
                .bytes()
                .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_')
        {
            return Err(cx.at(off, format!("unknown tool kind '{k}': a tool kind is a name of a-z, 0-9 and '_' (axe, pickaxe, key, wand, ...)")));
        }
        tool_decl.push((l, k.clone(), off));
    }
    if tool_decl.len() > MAX_TOOLS {
        return Err(cx.at(
            tool_decl[MAX_TOOLS].2,
            format!(
                "a world has at most {MAX_TOOLS} tools; [tools] lists {}",
                tool_decl.len()
            ),
        ));
    }
    Ok(tool_decl)
}

/// The tools and objects with their names: kind, or kind#i when the kind occurs more
/// than once.
fn name_things(tool_decl: &[(char, String, usize)], cells: &Cells) -> (Vec<Tool>, Vec<Object>) {
    let name_of = |kinds: &[String], i: usize| -> String {
        let k = &kinds[i];
        if kinds.iter().filter(|x| *x == k).count() > 1 {
            format!("{k}#{}", kinds[..i].iter().filter(|x| *x == k).count())
        } else {
            k.clone()
        }
    };
    let tkinds: Vec<String> = tool_decl.iter().map(|t| t.1.clone()).collect();
    let tools: Vec<Tool> = tool_decl
        .iter()
        .enumerate()
        .map(|(k, t)| Tool {
            letter: t.0,
            kind: t.1.clone(),
            name: name_of(&tkinds, k),
            pos: cells.tools[k],
        })
        .collect();
    let okinds: Vec<String> = cells
        .objects
        .iter()
        .map(|o| o.0.name().to_string())
        .collect();
    let objects: Vec<Object> = cells
        .objects
        .iter()
        .enumerate()
        .map(|(i, o)| Object {
            kind: o.0,
            name: name_of(&okinds, i),
            pos: o.1,
        })
        .collect();
    (tools, objects)
}

/// The rule table: the defaults, then the file's `[[rules]]`.
fn rules(
    cx: &Ctx,
    raw: &[Spanned<RawRule>],
    tools: &[Tool],
    tkinds: &[String],
) -> Result<Vec<Rule>, WorldError> {
    let mut rules = default_rules();
    let defaults = rules.len();
    for r in raw {
        let rr = r.get_ref();
        let tk = rr.tool.get_ref();
        if !tools.iter().any(|t| &t.kind == tk) {
            return Err(cx.at(rr.tool.span().start, format!("unknown tool kind '{tk}' in [[rules]]: no tool in [tools] is of that kind ({})", tkinds.join(", "))));
        }
        let Some(target) = ObjectKind::from_name(rr.target.get_ref()) else {
            return Err(cx.at(
                rr.target.span().start,
                format!(
                    "unknown object kind '{}' in [[rules]] (tree, wall, door, boulder)",
                    rr.target.get_ref()
                ),
            ));
        };
        let cond = |s: &Spanned<String>| {
            cond_from_name(target, s.get_ref()).ok_or_else(|| {
                cx.at(
                    s.span().start,
                    format!(
                        "'{}' is not a condition of a {} ({})",
                        s.get_ref(),
                        target.name(),
                        target.condition_names().join(", ")
                    ),
                )
            })
        };
        let (from, to) = (cond(&rr.from)?, cond(&rr.to)?);
        if target == ObjectKind::Boulder && from == DESTROYED && to == INTACT {
            return Err(cx.at(
                rr.to.span().start,
                "a rule cannot restore a destroyed boulder (it has no position)",
            ));
        }
        let range = match rr.range.get_ref() {
            toml::Value::Integer(1) => Range::Adjacent,
            toml::Value::String(s) if s == "bolt" => Range::Bolt,
            v => {
                return Err(cx.at(
                    rr.range.span().start,
                    format!("range = {v} must be 1 or \"bolt\""),
                ))
            }
        };
        let p = match &rr.p {
            None => 1.0,
            Some(v) => match number(v.get_ref()) {
                Some(p) if p > 0.0 && p <= 1.0 => p,
                _ => {
                    return Err(cx.at(
                        v.span().start,
                        format!("p = {} must be a number above 0 and at most 1", v.get_ref()),
                    ))
                }
            },
        };
        // An entry with a p that names a default rule only sets that rule's p.
        let default = (rr.p.is_some())
            .then(|| {
                rules[..defaults].iter().position(|d| {
                    d.tool == *tk && d.target == target && d.from == from && d.to == to
                })
            })
            .flatten();
        if let Some(d) = default {
            if rules[d].range != range {
                let name = |r: Range| match r {
                    Range::Adjacent => "1",
                    Range::Bolt => "\"bolt\"",
                };
                return Err(cx.at(
                    rr.range.span().start,
                    format!(
                        "this entry sets p of the default rule {tk} {} {} -> {}, whose range is {}, so it must give range = {}",
                        target.name(),
                        rr.from.get_ref(),
                        rr.to.get_ref(),
                        name(rules[d].range),
                        name(rules[d].range)
                    ),
                ));
            }
            rules[d].p = p;
            continue;
        }
        rules.push(Rule {
            tool: tk.clone(),
            target,
            from,
            to,
            range,
            p,
        });
    }
    Ok(rules)
}

/// A TOML integer or float as a finite `f64`.
fn number(v: &toml::Value) -> Option<f64> {
    match v {
        toml::Value::Integer(i) => Some(*i as f64),
        toml::Value::Float(f) if f.is_finite() => Some(*f),
        _ => None,
    }
}

/// `[dynamics] slip`: 0 when absent.
fn slip(cx: &Ctx, raw: &Option<Spanned<RawDynamics>>) -> Result<f64, WorldError> {
    let Some(v) = raw.as_ref().and_then(|d| d.get_ref().slip.as_ref()) else {
        return Ok(0.0);
    };
    match number(v.get_ref()) {
        Some(q) if (0.0..1.0).contains(&q) => Ok(q),
        _ => Err(cx.at(
            v.span().start,
            format!(
                "slip = {} must be a number at least 0 and below 1",
                v.get_ref()
            ),
        )),
    }
}

/// The object a task or `[empowerment]` (`what`) names.
fn find_object(
    cx: &Ctx,
    objects: &[Object],
    s: &Spanned<String>,
    what: &str,
) -> Result<usize, WorldError> {
    let n = s.get_ref();
    find_object_by_name(objects, n).ok_or_else(|| {
        cx.at(
            s.span().start,
            format!(
                "{what} names object '{n}', which is not on the map (objects: {})",
                list_names(objects)
            ),
        )
    })
}

/// The task: none, destroy objects, or push a boulder onto a goal.
fn task(
    cx: &Ctx,
    raw: &Option<Spanned<RawTask>>,
    objects: &[Object],
    terrain: &[Terrain],
) -> Result<Task, WorldError> {
    let find_object = |s: &Spanned<String>, what: &str| find_object(cx, objects, s, what);
    Ok(match raw {
        None => Task::None,
        Some(t) => {
            let tr = t.get_ref();
            match tr.kind.get_ref().as_str() {
                "destroy" => {
                    let Some(list) = &tr.objects else {
                        return Err(cx.at(t.span().start, "a destroy task needs objects = [...]"));
                    };
                    if list.is_empty() {
                        return Err(
                            cx.at(t.span().start, "a destroy task needs at least one object")
                        );
                    }
                    let mut v = Vec::new();
                    for o in list {
                        let i = find_object(o, "the task")?;
                        if !v.contains(&i) {
                            v.push(i);
                        }
                    }
                    Task::Destroy(v)
                }
                "push" => {
                    let Some(o) = &tr.object else {
                        return Err(cx.at(t.span().start, "a push task needs object = \"boulder\""));
                    };
                    let i = find_object(o, "the task")?;
                    if objects[i].kind != ObjectKind::Boulder {
                        return Err(cx.at(
                            o.span().start,
                            format!(
                                "a push task needs a boulder; '{}' is a {}",
                                o.get_ref(),
                                objects[i].kind.name()
                            ),
                        ));
                    }
                    if !terrain.contains(&Terrain::Goal) {
                        return Err(
                            cx.at(t.span().start, "a push task needs a goal '>' on the map")
                        );
                    }
                    Task::Push(i)
                }
                k => {
                    return Err(cx.at(
                        tr.kind.span().start,
                        format!("unknown task kind '{k}' (destroy or push)"),
                    ))
                }
            }
        }
    })
}

/// The `[empowerment]` defaults: the paper's when the file gives none.
fn empowerment(
    cx: &Ctx,
    raw: &Option<Spanned<RawEmpowerment>>,
    tools: &[Tool],
    objects: &[Object],
    tkinds: &[String],
) -> Result<EmpowermentDefaults, WorldError> {
    let find_object = |s: &Spanned<String>, what: &str| find_object(cx, objects, s, what);
    let mut emp = EmpowermentDefaults {
        tool: ToolChoice::Auto,
        objects: None,
        horizon_unequipped: 8,
        horizon_equipped: 3,
        beta: 0.0,
    };
    if let Some(e) = raw {
        let er = e.get_ref();
        if let Some(t) = &er.tool {
            emp.tool = match t.get_ref().as_str() {
                "auto" => ToolChoice::Auto,
                "all" => ToolChoice::All,
                n => match tools.iter().position(|x| x.name == n || x.kind == n) {
                    Some(k) => ToolChoice::Tool(k),
                    None => return Err(cx.at(t.span().start, format!("[empowerment] tool '{n}' is not a tool of this world ({}; or auto, all)", tkinds.join(", ")))),
                },
            };
        }
        if let Some(list) = &er.objects {
            if list.len() == 1 && list[0].get_ref() == "agent" {
                emp.objects = Some(ObjectSet::Agent);
            } else if !list.is_empty() {
                let mut v = Vec::new();
                for o in list {
                    let i = find_object(o, "[empowerment]")?;
                    if !v.contains(&i) {
                        v.push(i);
                    }
                }
                v.sort_unstable();
                emp.objects = Some(ObjectSet::Objects(v));
            }
        }
        let horizon = |h: &Option<Spanned<i64>>, default: u32| -> Result<u32, WorldError> {
            match h {
                None => Ok(default),
                Some(h) => {
                    let v = *h.get_ref();
                    if !(0..=MAX_HORIZON as i64).contains(&v) {
                        return Err(cx.at(
                            h.span().start,
                            format!("horizon {v} must be between 0 and {MAX_HORIZON}"),
                        ));
                    }
                    Ok(v as u32)
                }
            }
        };
        // Neither given: the paper's 8 and 3. One given: it serves both.
        let (hu, he) = (&er.horizon_unequipped, &er.horizon_equipped);
        let (du, de) = match (hu, he) {
            (Some(_), None) | (None, Some(_)) => {
                let one = horizon(if hu.is_some() { hu } else { he }, 0)?;
                (one, one)
            }
            _ => (8, 3),
        };
        emp.horizon_unequipped = horizon(hu, du)?;
        emp.horizon_equipped = horizon(he, de)?;
        if let Some(b) = &er.beta {
            let v = *b.get_ref();
            if !v.is_finite() || v < 0.0 {
                return Err(cx.at(
                    b.span().start,
                    format!("beta = {v} must be a finite number >= 0"),
                ));
            }
            emp.beta = v;
        }
    }
    Ok(emp)
}

/// A world's parts as the file gives them.
struct Parts {
    name: String,
    max_steps: u32,
    width: usize,
    height: usize,
    terrain: Vec<Terrain>,
    agent: (u8, u8),
    tools: Vec<Tool>,
    objects: Vec<Object>,
    rules: Vec<Rule>,
    slip: f64,
    task: Task,
    empowerment: EmpowermentDefaults,
    source: String,
}

/// The world, with the tables the dynamics look things up in: each tool's rules and
/// whether it fires bolts, the tool and static object on each cell, the boulders, and
/// the initial state.
fn assemble(p: Parts) -> World {
    let Parts {
        name,
        max_steps,
        width,
        height,
        terrain,
        agent,
        tools,
        objects,
        rules,
        slip,
        task,
        empowerment,
        source,
    } = p;
    let mut tool_rules = Vec::with_capacity(tools.len());
    let mut tool_bolt = Vec::with_capacity(tools.len());
    for t in &tools {
        let r: Vec<Rule> = rules.iter().filter(|r| r.tool == t.kind).cloned().collect();
        tool_bolt.push(r.iter().any(|r| r.range == Range::Bolt));
        tool_rules.push(r);
    }
    let mut tool_at = vec![0u8; width * height];
    for (k, t) in tools.iter().enumerate() {
        tool_at[t.pos.1 as usize * width + t.pos.0 as usize] = k as u8 + 1;
    }
    let mut static_at = vec![0u8; width * height];
    let mut boulders = Vec::new();
    let mut initial = State {
        x: agent.0,
        y: agent.1,
        ..State::default()
    };
    for (i, o) in objects.iter().enumerate() {
        let c = o.pos.1 as usize * width + o.pos.0 as usize;
        if o.kind == ObjectKind::Boulder {
            boulders.push(i as u8);
            initial.objects[i] = c as u16;
        } else {
            static_at[c] = i as u8 + 1;
            initial.objects[i] = INTACT as u16;
        }
    }
    debug_assert!(initial.objects.iter().all(|&v| v != BOULDER_DESTROYED));

    let stochastic = slip > 0.0 || tool_rules.iter().flatten().any(|r| r.p < 1.0);
    World {
        name,
        max_steps,
        width,
        height,
        terrain,
        tools,
        objects,
        rules,
        slip,
        stochastic,
        tool_rules,
        tool_bolt,
        tool_at,
        static_at,
        boulders,
        task,
        empowerment,
        initial,
        source,
    }
}

fn list_names(objects: &[Object]) -> String {
    if objects.is_empty() {
        return "none".to_string();
    }
    objects
        .iter()
        .map(|o| o.name.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}
