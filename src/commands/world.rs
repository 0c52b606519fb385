//! `fulcrum world show` and `fulcrum world generate`.

use std::time::Instant;

use anyhow::{Context, Result};
use fulcrum_world::family::{is_family, load_family};
use fulcrum_world::generate::{generate, GenParams};
use fulcrum_world::{parse_world, ObjectSet, ToolChoice};
use serde_json::json;

use crate::cli::{GenerateArgs, WorldCmd};
use fulcrum_contracts::fsio::write_atomic;
use fulcrum_empowerment::request::engine;
use fulcrum_world::load_world as world;

/// Run a `world` subcommand.
pub fn run(cmd: WorldCmd) -> Result<()> {
    match cmd {
        WorldCmd::Show {
            world: name,
            layout,
            json,
            toml,
        } => show(&name, layout, json, toml),
        WorldCmd::Generate(a) => gen(&a),
    }
}

fn show(name: &str, layout: Option<u64>, as_json: bool, as_toml: bool) -> Result<()> {
    let (w, family) = if is_family(name) {
        let f = load_family(name)?;
        let n = layout.unwrap_or(0);
        let text = f.layout_text(n)?;
        if as_toml {
            print!("{text}");
            return Ok(());
        }
        (
            parse_world(&text, &format!("{}-{n}", f.name))?,
            Some((f, n)),
        )
    } else {
        if layout.is_some() {
            return Err(fulcrum_run::BadRequest(format!(
                "--layout names a layout of a world family, and '{name}' is one world"
            ))
            .into());
        }
        let w = world(name)?;
        if as_toml {
            print!("{}", w.source);
            return Ok(());
        }
        (w, None)
    };
    let t0 = Instant::now();
    let e = engine(&w)?;
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    let actions: Vec<String> = (0..w.num_actions() as u8)
        .map(|a| w.action_name(a))
        .collect();
    let emp = &w.empowerment;
    let tool = match emp.tool {
        ToolChoice::Auto => "auto".to_string(),
        ToolChoice::All => "all".to_string(),
        ToolChoice::Tool(k) => w.tools[k].name.clone(),
    };
    let objects = emp.objects.as_ref().map(|s| match s {
        ObjectSet::Agent => "agent".to_string(),
        s => fulcrum_empowerment::set_name(&w, s),
    });
    // The rules of the tools in play that act with a probability below 1.
    let chancy: Vec<&fulcrum_world::Rule> = w
        .rules
        .iter()
        .filter(|r| r.p < 1.0 && w.tools.iter().any(|t| t.kind == r.tool))
        .collect();
    let rule_text = |r: &fulcrum_world::Rule| {
        format!(
            "{} {} {} -> {}",
            r.tool,
            r.target.name(),
            fulcrum_world::world::cond_name(r.target, r.from),
            fulcrum_world::world::cond_name(r.target, r.to)
        )
    };
    if as_json {
        let v = json!({
            "world": w.name,
            "width": w.width,
            "height": w.height,
            "max_steps": w.max_steps,
            "map": w.render(&w.initial),
            "tools": w.tools.iter().map(|t| json!({"name": t.name, "kind": t.kind, "letter": t.letter.to_string(), "x": t.pos.0, "y": t.pos.1})).collect::<Vec<_>>(),
            "objects": w.objects.iter().map(|o| json!({"name": o.name, "kind": o.kind.name(), "x": o.pos.0, "y": o.pos.1})).collect::<Vec<_>>(),
            "actions": actions,
            "task": w.task_text(),
            "stochastic": w.is_stochastic(),
            "slip": w.slip,
            "rule_p": chancy.iter().map(|r| json!({"rule": rule_text(r), "p": r.p})).collect::<Vec<_>>(),
            "empowerment": {"tool": tool, "objects": objects, "horizon_unequipped": emp.horizon_unequipped, "horizon_equipped": emp.horizon_equipped, "beta": emp.beta},
            "states": e.space.len(),
            "normal_states": e.normal_states(),
            "hash": format!("{:016x}", w.content_hash()),
            "fitting_tools": w.fitting_tools().map(|v| v.iter().map(|&k| w.tools[k].name.clone()).collect::<Vec<_>>()),
            "family": family.as_ref().map(|(f, n)| json!({"name": f.name, "layout": n})),
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    println!(
        "world {} ({}x{}, episodes of at most {} steps)",
        w.name, w.width, w.height, w.max_steps
    );
    if let Some((f, n)) = &family {
        let fits: Vec<String> = w
            .fitting_tools()
            .unwrap_or_default()
            .iter()
            .map(|&k| w.tools[k].name.clone())
            .collect();
        println!(
            "family       {}, layout {n} (task objects drawn from {}; tools that fit this one: {})",
            f.name,
            f.objects
                .iter()
                .map(|o| o.name())
                .collect::<Vec<_>>()
                .join(", "),
            fits.join(", ")
        );
    }
    print!("{}", w.render(&w.initial));
    let tools: Vec<String> = w
        .tools
        .iter()
        .map(|t| format!("{} {} ({},{})", t.letter, t.name, t.pos.0, t.pos.1))
        .collect();
    let objs: Vec<String> = w
        .objects
        .iter()
        .map(|o| format!("{} ({},{})", o.name, o.pos.0, o.pos.1))
        .collect();
    println!(
        "tools        {}",
        if tools.is_empty() {
            "none".into()
        } else {
            tools.join(", ")
        }
    );
    println!(
        "objects      {}",
        if objs.is_empty() {
            "none".into()
        } else {
            objs.join(", ")
        }
    );
    println!(
        "actions      {} (|A| = {})",
        actions.join(" "),
        actions.len()
    );
    println!("task         {}", w.task_text());
    if w.is_stochastic() {
        let mut parts = Vec::new();
        if w.slip > 0.0 {
            parts.push(format!("moves slip with probability {}", w.slip));
        }
        if !chancy.is_empty() {
            let rules: Vec<String> = chancy
                .iter()
                .map(|r| format!("{} (p {})", rule_text(r), r.p))
                .collect();
            parts.push(format!(
                "rules act with a probability: {}",
                rules.join(", ")
            ));
        }
        println!("chance       {}", parts.join("; "));
    } else {
        println!("chance       none (deterministic)");
    }
    println!(
        "empowerment  tool {tool}, objects {}, h = {} unequipped / {} equipped, beta {}",
        objects.unwrap_or_else(|| "none".into()),
        emp.horizon_unequipped,
        emp.horizon_equipped,
        emp.beta
    );
    println!(
        "states       {} ({} normal-mode), enumerated in {ms:.1} ms",
        e.space.len(),
        e.normal_states()
    );
    Ok(())
}

fn gen(a: &GenerateArgs) -> Result<()> {
    let text = generate(&GenParams {
        width: a.width,
        height: a.height,
        tools: a.tools,
        objects: a.objects,
        rock: a.rock,
        seed: a.seed,
    })?;
    // A generated file must always load: check before handing it out.
    parse_world(&text, "generated")
        .context("the generator made a world that does not parse (a bug)")?;
    match &a.out {
        Some(p) => {
            write_atomic(p, text.as_bytes())
                .with_context(|| format!("cannot write {}", p.display()))?;
            eprintln!("wrote {}", p.display());
        }
        None => print!("{text}"),
    }
    Ok(())
}
