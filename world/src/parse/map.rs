//! The map of a world file: its rows checked, its glyphs read, each cell placed back
//! in the file for errors.

use toml::Spanned;

use super::{Ctx, WorldError};
use crate::state::MAX_OBJECTS;
use crate::world::{ObjectKind, Terrain, MAX_SIDE};

/// The map string's rows, and where its cells sit in the file.
pub(super) struct MapText<'a> {
    /// The file.
    text: &'a str,
    /// The map value's span in the file, and where its first character sits.
    span: std::ops::Range<usize>,
    content_start: usize,
    /// Whether the literal has no escapes (only then are cells placed exactly).
    plain: bool,
    /// The value, and its rows.
    value: &'a str,
    rows: Vec<&'a str>,
}

impl<'a> MapText<'a> {
    pub(super) fn new(text: &'a str, map: &'a Spanned<String>) -> MapText<'a> {
        let map_span = map.span();
        let map_text = map.get_ref();
        // Where the string's first character sits: after `"""` and its trimmed newline.
        let raw_lit = &text[map_span.start.min(text.len())..map_span.end.min(text.len())];
        let (content_start, plain) = if raw_lit.starts_with("\"\"\"") || raw_lit.starts_with("'''")
        {
            let mut s = map_span.start + 3;
            if text[s..].starts_with("\r\n") {
                s += 2;
            } else if text[s..].starts_with('\n') {
                s += 1;
            }
            (s, !raw_lit.contains('\\') || raw_lit.starts_with("'''"))
        } else {
            (
                map_span.start + 1,
                !raw_lit.contains('\\') || raw_lit.starts_with('\''),
            )
        };
        let map_lines = map_text.strip_suffix('\n').unwrap_or(map_text);
        let map_lines = map_lines.strip_suffix('\r').unwrap_or(map_lines);
        let rows: Vec<&str> = map_lines
            .split('\n')
            .map(|r| r.strip_suffix('\r').unwrap_or(r))
            .collect();
        MapText {
            text,
            span: map_span,
            content_start,
            plain,
            value: map_text,
            rows,
        }
    }

    /// Place map cell (row, col) in the file when the literal has no escapes.
    fn cell_at(&self, row: usize, col: usize) -> usize {
        if !self.plain {
            return self.span.start;
        }
        let mut off = self.content_start;
        for r in self.rows.iter().take(row) {
            // The value's rows may end in "\n" where the file has "\r\n" (TOML
            // normalises newlines in strings): step over what the file has.
            off += r.len();
            let crlf = self.text.get(off..).is_some_and(|t| t.starts_with("\r\n"));
            off += if crlf { 2 } else { 1 };
        }
        off + self.rows[row].char_indices().nth(col).map_or(0, |(i, _)| i)
    }

    /// (width, height): rows of one width, neither side 0 nor over [`MAX_SIDE`].
    pub(super) fn size(&self, cx: &Ctx) -> Result<(usize, usize), WorldError> {
        let rows = &self.rows;
        if self.value.trim().is_empty() {
            return Err(cx.at(self.span.start, "the map is empty"));
        }
        let height = rows.len();
        if height > MAX_SIDE {
            return Err(cx.at(
                self.cell_at(MAX_SIDE, 0),
                format!("the map is {height} rows tall; at most {MAX_SIDE} are allowed"),
            ));
        }
        let width = rows[0].chars().count();
        for (y, r) in rows.iter().enumerate() {
            let w = r.chars().count();
            if w > MAX_SIDE {
                return Err(cx.at(
                    self.cell_at(y, MAX_SIDE),
                    format!(
                        "map row {} is {w} cells wide; at most {MAX_SIDE} are allowed",
                        y + 1
                    ),
                ));
            }
            if w != width {
                return Err(cx.at(self.cell_at(y, 0), format!("map row {} is {w} cells wide but row 1 is {width}; pad rows with spaces (solid rock) to one width", y + 1)));
            }
        }
        if width == 0 {
            return Err(cx.at(self.span.start, "the map's rows are empty"));
        }
        Ok((width, height))
    }
}

/// What the map's cells say.
pub(super) struct Cells {
    pub(super) terrain: Vec<Terrain>,
    pub(super) agent: (u8, u8),
    /// Each declared tool's cell.
    pub(super) tools: Vec<(u8, u8)>,
    /// The objects in map order.
    pub(super) objects: Vec<(ObjectKind, (u8, u8))>,
}

/// Read the map's glyphs: terrain, the agent, the tools (each declared one exactly
/// once) and the objects.
pub(super) fn read_map(
    cx: &Ctx,
    map: &MapText,
    width: usize,
    tool_decl: &[(char, String, usize)],
) -> Result<Cells, WorldError> {
    let height = map.rows.len();
    let mut terrain = vec![Terrain::Rock; width * height];
    let mut agent = None;
    let mut tools: Vec<Option<(u8, u8)>> = vec![None; tool_decl.len()];
    let mut objects: Vec<(ObjectKind, (u8, u8))> = Vec::new();
    for (y, r) in map.rows.iter().enumerate() {
        for (x, ch) in r.chars().enumerate() {
            let c = y * width + x;
            let pos = (x as u8, y as u8);
            let here = || map.cell_at(y, x);
            terrain[c] = match ch {
                '#' | '-' | '|' | ' ' => Terrain::Rock,
                '.' => Terrain::Floor,
                '>' => Terrain::Goal,
                '@' => {
                    if let Some((ax, ay)) = agent {
                        return Err(cx.at(here(), format!("a second agent '@' at {x},{y}; the first is at {ax},{ay}")));
                    }
                    agent = Some(pos);
                    Terrain::Floor
                }
                'T' | '=' | '+' | '0' => {
                    let kind = match ch {
                        'T' => ObjectKind::Tree,
                        '=' => ObjectKind::Wall,
                        '+' => ObjectKind::Door,
                        _ => ObjectKind::Boulder,
                    };
                    if objects.len() == MAX_OBJECTS {
                        return Err(cx.at(here(), format!("a world has at most {MAX_OBJECTS} objects; this {} at {x},{y} is number {}", kind.name(), MAX_OBJECTS + 1)));
                    }
                    objects.push((kind, pos));
                    Terrain::Floor
                }
                l if l.is_ascii_lowercase() => {
                    let Some(k) = tool_decl.iter().position(|t| t.0 == l) else {
                        return Err(cx.at(here(), format!("map letter '{l}' at {x},{y} is not listed in [tools]")));
                    };
                    if let Some((px, py)) = tools[k] {
                        return Err(cx.at(here(), format!("tool letter '{l}' appears twice on the map (at {px},{py} and {x},{y}); give each tool its own letter")));
                    }
                    tools[k] = Some(pos);
                    Terrain::Floor
                }
                other => {
                    return Err(cx.at(here(), format!("unknown glyph '{}' at {x},{y} (known: # - | space . > @ T = + 0 and tool letters)", other.escape_default())))
                }
            };
        }
    }
    let Some(agent) = agent else {
        return Err(cx.at(map.span.start, "the map has no agent '@'"));
    };
    let mut placed = Vec::with_capacity(tools.len());
    for (k, t) in tools.iter().enumerate() {
        match t {
            Some(p) => placed.push(*p),
            None => {
                return Err(cx.at(
                    tool_decl[k].2,
                    format!(
                        "tool letter '{}' ({}) is listed in [tools] but not on the map",
                        tool_decl[k].0, tool_decl[k].1
                    ),
                ))
            }
        }
    }
    Ok(Cells {
        terrain,
        agent,
        tools: placed,
        objects,
    })
}
