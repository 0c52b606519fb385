//! The text form of a state: [`World::describe`] writes it and [`World::parse_state`]
//! reads it back (`docs/world.md`, "The state").

use std::fmt::Write as _;

use crate::state::{Mode, State, BOULDER_DESTROYED};
use crate::world::{cond_from_name, cond_name, ObjectKind, Task, Terrain, World, INTACT};

/// Why a state description was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct DescribeError(pub String);

impl World {
    /// The text form of a state: `agent=X,Y holding=a,b mode=M obj=cond ...`.
    pub fn describe(&self, s: &State) -> String {
        let mut out = format!("agent={},{}", s.x, s.y);
        let held: Vec<&str> = (0..self.tools.len())
            .filter(|&k| s.holds(k))
            .map(|k| self.tools[k].name.as_str())
            .collect();
        if !held.is_empty() {
            let _ = write!(out, " holding={}", held.join(","));
        }
        let mode = match s.mode() {
            Mode::Normal => "normal".to_string(),
            Mode::ChoosingTool => "choosing-tool".to_string(),
            Mode::ChoosingDirection(k) => format!(
                "choosing-direction:{}",
                self.tools.get(k as usize).map_or("?", |t| t.name.as_str())
            ),
        };
        let _ = write!(out, " mode={mode}");
        for (i, o) in self.objects.iter().enumerate() {
            let v = s.objects[i];
            if o.kind == ObjectKind::Boulder {
                if v == BOULDER_DESTROYED {
                    let _ = write!(out, " {}=destroyed", o.name);
                } else {
                    let (x, y) = (v as usize % self.width, v as usize / self.width);
                    let _ = write!(out, " {}={},{}", o.name, x, y);
                }
            } else {
                let _ = write!(out, " {}={}", o.name, cond_name(o.kind, v as u8));
            }
        }
        out
    }

    /// The task in words: `none`, `destroy tree, wall`, `push boulder onto a goal`.
    pub fn task_text(&self) -> String {
        match &self.task {
            Task::None => "none".to_string(),
            Task::Destroy(v) => format!(
                "destroy {}",
                v.iter()
                    .map(|&i| self.objects[i].name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            Task::Push(b) => format!("push {} onto a goal", self.objects[*b].name),
        }
    }

    /// Parse a state description (`docs/world.md`, "The state"). Objects not named keep their initial
    /// state. Checks only form and plain impossibilities (agent inside a wall, a held
    /// tool's cell under the agent, ...); membership in the reachable state space is the
    /// caller's check, since it needs the enumerated space.
    pub fn parse_state(&self, text: &str) -> Result<State, DescribeError> {
        let err = |m: String| Err(DescribeError(m));
        let mut s = self.initial;
        s.set_mode(Mode::Normal);
        s.inventory = 0;
        let mut agent = None;
        let mut mode_text = None;
        for item in text.split_whitespace() {
            let Some((key, value)) = item.split_once('=') else {
                return err(format!(
                    "'{item}' in the state description is not of the form key=value"
                ));
            };
            match key {
                "agent" => agent = Some(self.parse_cell(value, "agent")?),
                "holding" => {
                    for t in value.split(',').filter(|t| !t.is_empty()) {
                        match self.tool_index(t) {
                            Some(k) => s.inventory |= 1 << k,
                            None => {
                                return err(format!(
                                "holding={value}: '{t}' is not a tool of world '{}' (tools: {})",
                                self.name, self.tool_list()
                            ))
                            }
                        }
                    }
                }
                "mode" => mode_text = Some(value),
                _ => {
                    let Some(i) = self.object_index(key) else {
                        return err(format!(
                            "'{key}' is neither agent, holding, mode nor an object of world '{}' (objects: {})",
                            self.name, self.object_list()
                        ));
                    };
                    let kind = self.objects[i].kind;
                    if kind == ObjectKind::Boulder && value == "destroyed" {
                        // A destroyed boulder has no cell: its slot is the sentinel.
                        s.objects[i] = BOULDER_DESTROYED;
                    } else if kind == ObjectKind::Boulder {
                        let (x, y) = self.parse_cell(value, key)?;
                        s.objects[i] = (y * self.width + x) as u16;
                    } else {
                        match cond_from_name(kind, value) {
                            Some(c) => s.objects[i] = c as u16,
                            None => {
                                return err(format!(
                                    "{key}={value}: a {} is {}",
                                    kind.name(),
                                    if kind == ObjectKind::Boulder {
                                        "X,Y or destroyed".to_string()
                                    } else {
                                        kind.condition_names().join(", ")
                                    }
                                ))
                            }
                        }
                    }
                }
            }
        }
        let Some((x, y)) = agent else {
            return err("the state description has no agent=X,Y".to_string());
        };
        s.x = x as u8;
        s.y = y as u8;
        if let Some(m) = mode_text {
            let mode = match m {
                "normal" => Mode::Normal,
                "choosing-tool" => Mode::ChoosingTool,
                _ => match m.strip_prefix("choosing-direction:") {
                    Some(t) => match self.tool_index(t) {
                        Some(k) => Mode::ChoosingDirection(k as u8),
                        None => {
                            return err(format!(
                                "mode={m}: '{t}' is not a tool of world '{}'",
                                self.name
                            ))
                        }
                    },
                    None => {
                        return err(format!(
                            "mode={m}: expected normal, choosing-tool or choosing-direction:TOOL"
                        ))
                    }
                },
            };
            s.set_mode(mode);
        }
        self.check_plausible(&s)?;
        Ok(s)
    }

    fn parse_cell(&self, value: &str, key: &str) -> Result<(usize, usize), DescribeError> {
        let bad = || {
            DescribeError(format!(
                "{key}={value}: expected X,Y inside the {}x{} map",
                self.width, self.height
            ))
        };
        let (x, y) = value.split_once(',').ok_or_else(bad)?;
        let (x, y): (usize, usize) = (
            x.trim().parse().map_err(|_| bad())?,
            y.trim().parse().map_err(|_| bad())?,
        );
        if x >= self.width || y >= self.height {
            return Err(bad());
        }
        Ok((x, y))
    }

    /// Names of the tools, comma separated.
    pub fn tool_list(&self) -> String {
        self.tools
            .iter()
            .map(|t| t.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// Names of the objects, comma separated.
    pub fn object_list(&self) -> String {
        self.objects
            .iter()
            .map(|o| o.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// Plain impossibilities, with the reason.
    pub(crate) fn check_plausible(&self, s: &State) -> Result<(), DescribeError> {
        let err = |m: String| Err(DescribeError(m));
        let (x, y) = (s.x as usize, s.y as usize);
        let c = y * self.width + x;
        if self.terrain[c] == Terrain::Rock {
            return err(format!(
                "the agent cannot stand at {x},{y}: that cell is rock"
            ));
        }
        if let Some(o) = self.static_object_cell(x, y) {
            if s.objects[o] == INTACT as u16 {
                let ob = &self.objects[o];
                return err(format!(
                    "the agent cannot stand at {x},{y}: the {} there is {}",
                    ob.name,
                    cond_name(ob.kind, INTACT)
                ));
            }
        }
        if let Some(t) = self.tool_cell(x, y) {
            if !s.holds(t) {
                return err(format!(
                    "the agent cannot stand at {x},{y} without holding the {}: it lies there and would be picked up",
                    self.tools[t].name
                ));
            }
        }
        match s.mode() {
            Mode::ChoosingTool if s.inventory == 0 => {
                return err("mode=choosing-tool needs a held tool".to_string())
            }
            Mode::ChoosingDirection(k) if !s.holds(k as usize) => {
                return err(format!(
                    "mode=choosing-direction:{0} needs the {0} held",
                    self.tools[k as usize].name
                ))
            }
            _ => {}
        }
        for b in self.boulder_indices() {
            let v = s.objects[b];
            if v == BOULDER_DESTROYED {
                continue;
            }
            let (bx, by) = (v as usize % self.width, v as usize / self.width);
            let name = &self.objects[b].name;
            if (bx, by) == (x, y) {
                return err(format!(
                    "the agent and the {name} cannot both stand at {x},{y}"
                ));
            }
            if self.terrain[v as usize] == Terrain::Rock {
                return err(format!(
                    "the {name} cannot stand at {bx},{by}: that cell is rock"
                ));
            }
            if let Some(o) = self.static_object_cell(bx, by) {
                if s.objects[o] == INTACT as u16 {
                    return err(format!(
                        "the {name} cannot stand at {bx},{by}: the {} there is {}",
                        self.objects[o].name,
                        cond_name(self.objects[o].kind, INTACT)
                    ));
                }
            }
            if let Some(t) = self.tool_cell(bx, by) {
                if !s.holds(t) {
                    return err(format!(
                        "the {name} cannot stand at {bx},{by}: the {} lies there",
                        self.tools[t].name
                    ));
                }
            }
            if self.boulder_indices().any(|o| o != b && s.objects[o] == v) {
                return err(format!("two boulders cannot both stand at {bx},{by}"));
            }
        }
        Ok(())
    }
}
