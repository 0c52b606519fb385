//! `fulcrum empowerment matrix|landscape|trace|query|dataset|score`.

mod dataset;

use std::io::IsTerminal;
use std::time::Instant;

use anyhow::Result;
use fulcrum_empowerment::{set_name, set_objects, Engine, Method, ToolSel};
use fulcrum_world::{ObjectKind, ObjectSet, State, World};
use serde_json::json;

use crate::cli::{Channel, EmpCmd, LandscapeArgs, MatrixArgs, QueryArgs, TraceArgs};
use crate::commands::bad;
use fulcrum_empowerment::request::{
    engine, holding_mask, matrix_columns, matrix_horizons, object_set, objects_or_default, tool_sel,
};
use fulcrum_run::BadRequest;
use fulcrum_world::load_world as world;

/// Run an `empowerment` subcommand.
pub fn run(cmd: EmpCmd) -> Result<()> {
    match cmd {
        EmpCmd::Matrix(a) => matrix(&a),
        EmpCmd::Landscape(a) => landscape(&a),
        EmpCmd::Trace(a) => trace(&a),
        EmpCmd::Query(a) => query(&a),
        EmpCmd::Dataset(a) => dataset::dataset(&a),
        EmpCmd::Score(a) => dataset::score(&a),
    }
}

fn fmt_bits(v: f64) -> String {
    if v == 0.0 {
        "0".to_string()
    } else {
        format!("{v:.6}")
    }
}

fn matrix(a: &MatrixArgs) -> Result<()> {
    let w = world(&a.world)?;
    let (hu, he) = matrix_horizons(&w, a.horizon, a.horizon_unequipped, a.horizon_equipped);
    let horizons = if hu == he {
        format!("h = {hu}")
    } else {
        format!("h = {hu} unequipped / {he} equipped")
    };
    let columns = matrix_columns(&w, a.objects.as_deref(), &a.joint)?;
    let t0 = Instant::now();
    let e = engine(&w)?;
    let m = e.matrix(&columns, hu, he, a.method.into())?;
    let elapsed_ms = t0.elapsed().as_secs_f64() * 1e3;
    if let Some(path) = &a.png {
        let pic = fulcrum_plot::MatrixPicture {
            title: format!("{}: tool-object empowerment, {horizons}", w.name),
            rows: m.tools.clone(),
            columns: m.columns.clone(),
            values: m.values.clone(),
            selected: m.selection.clone(),
        };
        fulcrum_plot::matrix_png(path, &pic)?;
        eprintln!("wrote {}", path.display());
    }
    if a.json {
        let selection: serde_json::Map<String, serde_json::Value> = m
            .columns
            .iter()
            .zip(&m.selection)
            .map(|(c, s)| {
                (
                    c.clone(),
                    s.map_or(serde_json::Value::Null, |j| json!(m.tools[j])),
                )
            })
            .collect();
        let v = json!({
            "world": w.name,
            "states": e.space.len(),
            "normal_states": m.normal_states,
            "horizon_unequipped": hu,
            "horizon_equipped": he,
            "method": format!("{:?}", Method::from(a.method)).to_lowercase(),
            "tools": m.tools,
            "columns": m.columns,
            "matrix": m.values,
            "selection": selection,
            "gap_bits": m.gap,
            "elapsed_ms": elapsed_ms,
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    println!(
        "{}: {} states ({} normal-mode averaged), {horizons}, {elapsed_ms:.1} ms",
        w.name,
        e.space.len(),
        m.normal_states
    );
    println!("tool-object empowerment matrix, bits (* = selected tool)\n");
    let tw = m.tools.iter().map(|t| t.len()).max().unwrap_or(4).max(4) + 2;
    let cw: Vec<usize> = m.columns.iter().map(|c| c.len().max(10) + 2).collect();
    let mut line = format!("{:<tw$}", "tool");
    for (c, name) in m.columns.iter().enumerate() {
        line.push_str(&format!("{:>width$}", name, width = cw[c]));
    }
    println!("{}", line.trim_end());
    for (j, t) in m.tools.iter().enumerate() {
        let mut line = format!("{t:<tw$}");
        for (c, v) in m.values[j].iter().enumerate() {
            let mark = if m.selection[c] == Some(j) { "*" } else { " " };
            line.push_str(&format!(
                "{:>width$}{mark}",
                fmt_bits(*v),
                width = cw[c] - 1
            ));
        }
        println!("{}", line.trim_end());
    }
    let sel: Vec<String> = m
        .columns
        .iter()
        .zip(&m.selection)
        .map(|(c, s)| format!("{c} -> {}", s.map_or("none", |j| m.tools[j].as_str())))
        .collect();
    println!("\nselection: {}", sel.join(", "));
    Ok(())
}

/// World, engine, tool and object set of a channel.
struct Resolved<'w> {
    e: Engine<'w>,
    tool: ToolSel,
    set: ObjectSet,
}

fn resolve<'w>(w: &'w World, ch: &Channel) -> Result<Resolved<'w>> {
    let set = objects_or_default(w, ch.objects.as_deref())?;
    let e = engine(w)?;
    let tool = tool_sel(w, &e, ch.tool.as_deref(), &set)?;
    Ok(Resolved { e, tool, set })
}

fn landscape(a: &LandscapeArgs) -> Result<()> {
    let w = world(&a.channel.world)?;
    let r = resolve(&w, &a.channel)?;
    let holding = holding_mask(&w, &a.holding)?;
    let probe = r.e.landscape_state(0, 0, holding);
    let h = fulcrum_empowerment::dataset::row_horizon(&w, a.channel.horizon, r.tool, &probe);
    let l =
        r.e.landscape(r.tool, &r.set, h, holding, a.channel.method.into())?;
    let tool_name = r.tool.name(&w);
    let set = set_name(&w, &r.set);
    if let Some(path) = &a.png {
        let rock: Vec<Vec<bool>> = (0..w.height)
            .map(|y| {
                (0..w.width)
                    .map(|x| w.terrain(x as i32, y as i32) == fulcrum_world::Terrain::Rock)
                    .collect()
            })
            .collect();
        let drawn = probe_initial(&w, holding);
        let glyphs: Vec<Vec<Option<char>>> = (0..w.height)
            .map(|y| {
                (0..w.width)
                    .map(|x| {
                        let g = w.glyph_at(&drawn, x, y);
                        (g != '.' && g != '#' && g != '@').then_some(g)
                    })
                    .collect()
            })
            .collect();
        let title = format!(
            "{}: E^{h} {tool_name} -> {set}, holding {}",
            w.name,
            if a.holding.is_empty() {
                "nothing"
            } else {
                &a.holding
            }
        );
        fulcrum_plot::heatmap_png(
            path,
            &fulcrum_plot::Heatmap {
                title: &title,
                values: &l.values,
                rock: &rock,
                glyphs: Some(&glyphs),
                unit: "bits",
            },
        )?;
        eprintln!("wrote {}", path.display());
    }
    if a.channel.json {
        let v = json!({
            "world": w.name,
            "tool": tool_name,
            "objects": set_objects(&w, &r.set),
            "horizon": h,
            "holding": a.holding.split(',').filter(|t| !t.is_empty()).collect::<Vec<_>>(),
            "width": w.width,
            "height": w.height,
            "values": l.values,
            "gap_bits": l.gap,
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    println!(
        "{}: E^{h} {tool_name} -> {set}, holding {} (bits; a glyph or '..' = no such state)",
        w.name,
        if a.holding.is_empty() {
            "nothing"
        } else {
            &a.holding
        }
    );
    let colour = std::io::stdout().is_terminal();
    let max = l
        .values
        .iter()
        .flatten()
        .flatten()
        .fold(0.0f64, |m, v| m.max(*v));
    let init = probe_initial(&w, holding);
    for (y, row) in l.values.iter().enumerate() {
        let mut line = String::new();
        for (x, v) in row.iter().enumerate() {
            let cell = match v {
                Some(v) => {
                    let txt = format!("{v:>5.2}");
                    if colour {
                        format!("\x1b[38;5;{}m{txt}\x1b[0m", ansi_colour(*v, max))
                    } else {
                        txt
                    }
                }
                None => {
                    let g = w.glyph_at(&init, x, y);
                    if g == '#' {
                        "  ###".to_string()
                    } else if g == '@' || g == '.' {
                        "   ..".to_string()
                    } else {
                        format!("    {g}")
                    }
                }
            };
            line.push_str(&cell);
        }
        println!("{line}");
    }
    Ok(())
}

/// The initial state with an inventory, for drawing what lies where.
fn probe_initial(w: &World, holding: u16) -> State {
    let mut s = w.initial;
    s.inventory = holding;
    // Draw no agent: the landscape is over the agent's cell.
    s.x = u8::MAX;
    s.y = u8::MAX;
    s
}

/// An xterm-256 colour from dark blue (0) to yellow (max).
fn ansi_colour(v: f64, max: f64) -> u8 {
    const RAMP: [u8; 6] = [240, 25, 31, 37, 78, 226];
    if max <= 0.0 || v <= 0.0 {
        return RAMP[0];
    }
    let i = ((v / max) * (RAMP.len() - 1) as f64).round() as usize;
    RAMP[i.clamp(1, RAMP.len() - 1)]
}

fn trace(a: &TraceArgs) -> Result<()> {
    let w = world(&a.channel.world)?;
    let mut actions = Vec::new();
    for name in a
        .actions
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
    {
        match w.parse_action(name) {
            Some(x) => actions.push(x),
            None => {
                return bad(format!(
                    "--actions: unknown action '{name}' (N, E, S, W, apply, or a tool: {})",
                    w.tool_list()
                ))
            }
        }
    }
    let r = resolve(&w, &a.channel)?;
    // With --horizon one table serves; else the held/not-held pair, chosen per step.
    let (hu, he) = match a.channel.horizon {
        Some(h) => (h, h),
        None => (
            w.empowerment.horizon_unequipped,
            w.empowerment.horizon_equipped,
        ),
    };
    let tu = r.e.trace(r.tool, &r.set, hu, &actions)?;
    let te = if he == hu {
        None
    } else {
        Some(r.e.trace(r.tool, &r.set, he, &actions)?)
    };
    let steps: Vec<(Option<u8>, State, f64, u32, f64)> = tu
        .iter()
        .enumerate()
        .map(|(t, s)| match &te {
            Some(te) if r.tool.held(&s.state) => (s.action, s.state, te[t].value, he, te[t].gap),
            _ => (s.action, s.state, s.value, hu, s.gap),
        })
        .collect();
    let tool_name = r.tool.name(&w);
    let set = set_name(&w, &r.set);
    // The first static object of D, drawn per step as in the paper's Fig. 12.
    let cat_obj = r
        .set
        .indices()
        .iter()
        .copied()
        .find(|&i| w.objects[i].kind != ObjectKind::Boulder);
    if let Some(path) = &a.png {
        let values: Vec<f64> = steps.iter().map(|s| s.2).collect();
        let labels: Vec<Option<String>> = steps
            .iter()
            .map(|s| s.0.map(|x| w.action_name(x)))
            .collect();
        let cat = cat_obj.map(|i| {
            let names: Vec<String> = w.objects[i]
                .kind
                .condition_names()
                .iter()
                .map(|s| s.to_string())
                .collect();
            let idx: Vec<usize> = steps
                .iter()
                .map(|s| {
                    let c = w.cond(&s.1, i) as usize;
                    // Conditions are coded 0 intact/closed, 1 open, 2 destroyed; kinds
                    // without an open state list two names.
                    if names.len() == 2 {
                        c.min(1)
                    } else {
                        c
                    }
                })
                .collect();
            (w.objects[i].name.clone(), names, idx)
        });
        let title = format!("{}: E^h {tool_name} -> {set} along the actions", w.name);
        let vlabel = match a.channel.horizon {
            Some(h) => format!("E^{h} (bits)"),
            None => format!("E^{hu}/E^{he} (bits)"),
        };
        fulcrum_plot::trace_png(
            path,
            &fulcrum_plot::Trace {
                title: &title,
                value_label: &vlabel,
                values: &values,
                actions: &labels,
                category: cat
                    .as_ref()
                    .map(|(n, names, idx)| (n.as_str(), names.as_slice(), idx.as_slice())),
            },
        )?;
        eprintln!("wrote {}", path.display());
    }
    if a.channel.json {
        let v = json!({
            "world": w.name,
            "tool": tool_name,
            "objects": set_objects(&w, &r.set),
            "steps": steps.iter().enumerate().map(|(t, s)| json!({
                "t": t,
                "action": s.0.map(|x| w.action_name(x)),
                "value": s.2,
                "horizon": s.3,
                "gap_bits": s.4,
                "state": w.describe(&s.1),
            })).collect::<Vec<_>>(),
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    println!(
        "{}: E^h {tool_name} -> {set} along {} actions",
        w.name,
        actions.len()
    );
    println!(
        "{:>4}  {:<12} {:>3} {:>9}  state",
        "t", "action", "h", "bits"
    );
    for (t, s) in steps.iter().enumerate() {
        let act = s.0.map_or("-".to_string(), |x| w.action_name(x));
        println!(
            "{t:>4}  {act:<12} {:>3} {:>9.6}  {}",
            s.3,
            s.2,
            w.describe(&s.1)
        );
    }
    Ok(())
}

fn query(a: &QueryArgs) -> Result<()> {
    let w = world(&a.channel.world)?;
    let lines: Vec<(String, String)> = match (&a.state, &a.states_file) {
        (Some(s), _) => vec![("--state".to_string(), s.clone())],
        (None, Some(p)) => {
            let text = std::fs::read_to_string(p).map_err(|e| {
                BadRequest(format!("cannot read --states-file {}: {e}", p.display()))
            })?;
            text.lines()
                .enumerate()
                .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'))
                .map(|(i, l)| (format!("{}:{}", p.display(), i + 1), l.to_string()))
                .collect()
        }
        (None, None) => return bad("give --state or --states-file"),
    };
    // Parse every state before any computation: a bad line costs nothing.
    let mut states = Vec::with_capacity(lines.len());
    for (place, text) in &lines {
        let s = w
            .parse_state(text)
            .map_err(|e| BadRequest(format!("{place}: {e}")))?;
        states.push(s);
    }
    if a.service {
        return query_service(&w, a, &states, &lines);
    }
    let r = resolve(&w, &a.channel)?;
    let method: Method = a.channel.method.into();
    let mut values = Vec::with_capacity(states.len());
    // One table per distinct horizon, shared by all states that use it.
    let mut tables: Vec<(u32, Vec<f64>, Vec<f64>)> = Vec::new();
    let stochastic = w.is_stochastic();
    for (s, (place, _)) in states.iter().zip(&lines) {
        let h = fulcrum_empowerment::dataset::row_horizon(&w, a.channel.horizon, r.tool, s);
        let id =
            r.e.state_id(s)
                .map_err(|e| BadRequest(format!("{place}: {e}")))?;
        let (v, gap) = match method {
            // A stochastic world computes each state's channel on its own.
            _ if stochastic => {
                let c = r.e.values_at(r.tool, &r.set, h, &[id], method)?[0];
                (c.bits, c.gap)
            }
            Method::Dp => {
                if !tables.iter().any(|t| t.0 == h) {
                    let (v, g) = r.e.values_gap(r.tool, &r.set, h, method)?;
                    tables.push((h, v, g));
                }
                let t = tables.iter().find(|t| t.0 == h).expect("made above");
                (t.1[id as usize], t.2[id as usize])
            }
            Method::Enumerate => (r.e.query(s, r.tool, &r.set, h, method)?, 0.0),
        };
        values.push((v, h, gap));
    }
    if a.channel.json {
        let v = if a.state.is_some() {
            json!({"value": values[0].0, "horizon": values[0].1, "gap_bits": values[0].2, "tool": r.tool.name(&w), "objects": set_objects(&w, &r.set)})
        } else {
            json!({
                "tool": r.tool.name(&w),
                "objects": set_objects(&w, &r.set),
                "values": values.iter().zip(&states).map(|(v, s)| json!({"state": w.describe(s), "value": v.0, "horizon": v.1, "gap_bits": v.2})).collect::<Vec<_>>(),
            })
        };
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    for ((v, h, _), s) in values.iter().zip(&states) {
        println!(
            "{v:.6} bits  (E^{h} {} -> {})  {}",
            r.tool.name(&w),
            set_name(&w, &r.set),
            w.describe(s)
        );
    }
    Ok(())
}

/// `query --service`: ask a running `fulcrum serve` instead of computing here. With
/// tool, objects and horizon all given it is a QUERY; otherwise the service's own table
/// (LOOKUP), whose configuration it reports.
fn query_service(
    w: &World,
    a: &QueryArgs,
    states: &[State],
    lines: &[(String, String)],
) -> Result<()> {
    use fulcrum_contracts::msg::{self, item, TOOL_ALL};
    use fulcrum_empowerment::service::{mask_set, object_mask, Ask, Client};
    if !msg::valid_namespace(&a.namespace) {
        return bad(format!(
            "--namespace '{}' must be 1 to 64 characters of A-Z, a-z, 0-9, '_', '-', '.'",
            a.namespace
        ));
    }
    let wait = std::time::Duration::from_secs_f64(a.wait.clamp(0.0, 3600.0));
    let mut client = Client::connect(&a.namespace, w, wait)?;
    let d = *client.describe();
    let ch = &a.channel;
    let explicit = ch.tool.is_some() || ch.objects.is_some() || ch.horizon.is_some();
    let (ask, tool_name, set) = if explicit {
        let tool = match ch.tool.as_deref() {
            Some("all") => TOOL_ALL,
            Some("auto") => return bad("--tool auto is not available with --service: name the tool, or leave tool, objects and horizon out to use the service's table"),
            Some(t) => match w.tool_index(t) {
                Some(k) => k as i32,
                None => return bad(format!("unknown tool '{t}' in world '{}' (tools: {}; or all)", w.name, w.tool_list())),
            },
            None => d.tool,
        };
        let set = match &ch.objects {
            Some(o) => object_set(w, o)?,
            None => mask_set(w, d.object_mask).unwrap_or(ObjectSet::Agent),
        };
        let Some(horizon) = ch.horizon else {
            return bad("with --service, give --horizon together with --tool or --objects (or none of them to use the service's table)");
        };
        let name = if tool == TOOL_ALL {
            "all".to_string()
        } else {
            w.tools[tool as usize].name.clone()
        };
        (
            Ask::Query {
                tool,
                objects: object_mask(&set),
                horizon,
            },
            name,
            set,
        )
    } else {
        let set = mask_set(w, d.object_mask).unwrap_or(ObjectSet::Agent);
        let name = if d.tool == TOOL_ALL {
            "all".to_string()
        } else {
            w.tools[d.tool as usize].name.clone()
        };
        (Ask::Lookup, name, set)
    };
    let batch = client.values(ask, states, 256)?;
    for (i, st) in batch.status.iter().enumerate() {
        if *st != item::OK {
            return bad(format!(
                "{}: the state '{}' is not reachable from the initial state of world '{}'",
                lines[i].0,
                w.describe(&states[i]),
                w.name
            ));
        }
    }
    let horizon_of = |s: &State| match ask {
        Ask::Query { horizon, .. } => horizon,
        Ask::Lookup | Ask::Visit => {
            if d.tool >= 0 && s.holds(d.tool as usize) {
                d.horizon_equipped
            } else {
                d.horizon_unequipped
            }
        }
    };
    if ch.json {
        let v = if a.state.is_some() {
            json!({"value": batch.values[0] as f64, "horizon": horizon_of(&states[0]), "tool": tool_name, "objects": set_objects(w, &set), "service": client.namespace()})
        } else {
            json!({
                "tool": tool_name,
                "objects": set_objects(w, &set),
                "service": client.namespace(),
                "values": batch.values.iter().zip(states).map(|(v, s)| json!({"state": w.describe(s), "value": *v as f64, "horizon": horizon_of(s)})).collect::<Vec<_>>(),
            })
        };
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    for (v, s) in batch.values.iter().zip(states) {
        println!(
            "{v:.6} bits  (E^{} {tool_name} -> {}, service {})  {}",
            horizon_of(s),
            set_name(w, &set),
            client.namespace(),
            w.describe(s)
        );
    }
    Ok(())
}
