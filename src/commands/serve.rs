//! `fulcrum serve`: the empowerment service for one world.

use std::io::Write;
use std::time::Duration;

use anyhow::Result;
use fulcrum_contracts::lines::ChildLine;
use fulcrum_contracts::msg;
use fulcrum_empowerment::service::{serve, ServeConfig, Tables};
use fulcrum_empowerment::{set_name, ToolSel};

use crate::cli::ServeArgs;
use crate::commands::bad;
use fulcrum_contracts::config::EmpowermentModel;
use fulcrum_empowerment::request::{engine, potential_objects, tool_sel_with_column};
use fulcrum_learner::paths::RunPaths;
use fulcrum_run::child::load_run;
use fulcrum_run::BadRequest;
use fulcrum_world::load_world as world;
use fulcrum_world::World;

/// The most clients `--max-clients` may ask for (about 1.2 GiB of shared memory).
const MAX_SERVE_CLIENTS: usize = 1024;

/// What the service serves: from the flags, or from a run's `config.toml`.
struct Served {
    world: World,
    tool: Option<String>,
    objects: Option<String>,
    /// A potential form's run counting a destroy task's objects by their conditions.
    task_conditions: bool,
    /// The tool the run's selection gave at its first start: kept at a resume.
    recorded_tool: Option<String>,
    horizon_unequipped: Option<u32>,
    horizon_equipped: Option<u32>,
    horizon_sum: bool,
    model: EmpowermentModel,
    max_clients: usize,
    /// Estimates LOOKUP answers from instead of the exact table.
    estimates: Option<std::path::PathBuf>,
}

impl Served {
    fn from_args(a: &ServeArgs) -> Result<Served> {
        if let Some(dir) = &a.run {
            let paths = RunPaths { dir: dir.clone() };
            let (cfg, w) = load_run(&paths)?;
            return Ok(Served {
                estimates: cfg.empowerment_from.as_ref().map(|_| paths.estimates()),
                world: w,
                tool: cfg.tool.as_request().map(str::to_string),
                objects: (!cfg.objects.is_empty()).then(|| cfg.objects.clone()),
                task_conditions: cfg.task_conditions(),
                recorded_tool: cfg.selected_tool.clone(),
                horizon_unequipped: Some(cfg.horizon_unequipped),
                horizon_equipped: Some(cfg.horizon_equipped),
                horizon_sum: cfg.form().horizon_sum(),
                model: cfg.empowerment_model,
                max_clients: cfg.service_clients(),
            });
        }
        let spec = a.world.as_deref().unwrap_or_default();
        Ok(Served {
            world: world(spec)?,
            tool: a.tool.clone(),
            objects: a.objects.clone(),
            task_conditions: false,
            recorded_tool: None,
            horizon_unequipped: a.horizon_unequipped,
            horizon_equipped: a.horizon_equipped,
            horizon_sum: a.horizon_sum,
            model: a.model.parse().map_err(BadRequest)?,
            max_clients: a.max_clients,
            estimates: a.empowerment_from.clone(),
        })
    }
}

/// Run the service until SIGINT or SIGTERM.
pub fn run(args: &ServeArgs) -> Result<()> {
    if !msg::valid_namespace(&args.namespace) {
        return bad(format!(
            "--namespace '{}' must be 1 to 64 characters of A-Z, a-z, 0-9, '_', '-', '.'",
            args.namespace
        ));
    }
    if let Some(f) = serve_family(args)? {
        return Ok(f);
    }
    let a = Served::from_args(args)?;
    if !(1..=MAX_SERVE_CLIENTS).contains(&a.max_clients) {
        return bad(format!(
            "--max-clients {} must be 1 to {MAX_SERVE_CLIENTS}",
            a.max_clients
        ));
    }
    let world_itself = a.world;
    let model = a.model;
    // The deterministic twin keeps the file's content hash, so the actors of the
    // world itself are answered.
    let w = fulcrum_run::plan::model_world(&world_itself, model);
    let w = &*w;
    let set = potential_objects(w, a.objects.as_deref(), a.task_conditions)?;
    let e = engine(w)?;
    let (mut tool, matrix) = tool_sel_with_column(w, &e, a.tool.as_deref(), &set)?;
    if let Some(name) = &a.recorded_tool {
        // A resumed run keeps the tool its selection gave when it started.
        let Some(k) = w.tool_index(name) else {
            return bad(format!(
                "the run's config.toml records the selected tool '{name}', which is not a tool of world '{}' (tools: {})",
                w.name,
                w.tool_list()
            ));
        };
        if tool != ToolSel::Tool(k) {
            eprintln!(
                "the run selected {name} when it started; the selection gives {} now: keeping {name}",
                tool.name(w)
            );
            tool = ToolSel::Tool(k);
        }
    }
    let hu = a
        .horizon_unequipped
        .unwrap_or(w.empowerment.horizon_unequipped);
    let he = a.horizon_equipped.unwrap_or(w.empowerment.horizon_equipped);
    for h in [hu, he] {
        if h > fulcrum_world::MAX_HORIZON {
            return bad(format!(
                "horizon {h} is too large: at most {}",
                fulcrum_world::MAX_HORIZON
            ));
        }
    }
    if let Some(m) = matrix {
        // The column the selection came from (at the world's horizons).
        let col: Vec<String> = m
            .tools
            .iter()
            .zip(&m.values)
            .map(|(t, v)| format!("{t} {:.6}", v[0]))
            .collect();
        eprintln!(
            "tool selection for {}: {} ({})",
            set_name(w, &set),
            tool.name(w),
            col.join(", ")
        );
    }
    let cfg = ServeConfig {
        horizon_sum: a.horizon_sum,
        namespace: args.namespace.clone(),
        tool,
        objects: set.clone(),
        horizon_unequipped: hu,
        horizon_equipped: he,
        cache_bytes: args.cache_mib << 20,
        spin: Duration::from_micros(100),
        max_clients: a.max_clients,
    };
    let mut tables = match &a.estimates {
        None => Tables::new(e, cfg)?,
        Some(file) => {
            let text = std::fs::read_to_string(file).map_err(|err| {
                BadRequest(format!(
                    "cannot read the estimates {}: {err}",
                    file.display()
                ))
            })?;
            let values = fulcrum_empowerment::estimates::lookup_from_estimates(
                &e,
                tool,
                hu,
                he,
                a.horizon_sum,
                &text,
                &file.display().to_string(),
            )?;
            eprintln!("LOOKUP answers from the estimates in {}", file.display());
            Tables::with_values(e, cfg, values)
        }
    };
    let (_, stats) = serve(&mut tables, |d| {
        let about = format!(
            "world {} (hash {:016x}){}, {} states, {} -> {}, h = {hu} unequipped / {he} equipped, service fulcrum/{}/empowerment",
            w.name,
            d.world_hash,
            if model == EmpowermentModel::Deterministic {
                " computed as if deterministic"
            } else {
                ""
            },
            d.states,
            match tool {
                ToolSel::All => "all".to_string(),
                ToolSel::Tool(j) => w.tools[j].name.clone(),
            },
            set_name(w, &set),
            args.namespace
        );
        let _ = writeln!(std::io::stdout(), "{}", ChildLine::ServiceReady { about });
        let _ = std::io::stdout().flush();
    })?;
    // The reader of our output may be gone (a supervisor that only waited for "ready"):
    // a failed write must not turn a clean stop into a panic.
    let _ = writeln!(
        std::io::stdout(),
        "fulcrum serve: stopped: {} requests, {} states, {} refused",
        stats.requests,
        stats.states,
        stats.refused
    );
    Ok(())
}

/// The service of a world family (a run on one, or `serve FAMILY`): a table per layout,
/// made on first sight, the run's training layouts before it says it is ready.
/// Training layouts whose tables a family run's service makes before it is ready and
/// never drops (about 330 MB for `toolbox`, ~28 bytes a state); beyond them tables are
/// made on first sight and kept within `--cache-mib`.
const KEEP_LAYOUTS: u64 = 1024;

/// `None` when the world is not a family.
fn serve_family(args: &ServeArgs) -> Result<Option<()>> {
    use fulcrum_empowerment::service::{serve_with, FamilyConfig, FamilyTables};
    use fulcrum_world::family::{is_family, load_family};
    use fulcrum_world::Layouts;
    let (family, cfg, churns) = if let Some(dir) = &args.run {
        let (cfg, _) = load_run(&RunPaths { dir: dir.clone() })?;
        let Some(layouts) = cfg.layouts else {
            return Ok(None);
        };
        let churns = !matches!(layouts, Layouts::First(n) if n <= KEEP_LAYOUTS);
        let family = load_family(&cfg.world)?;
        let fc = FamilyConfig {
            tool: cfg.tool.as_request().map(str::to_string),
            horizon_unequipped: cfg.horizon_unequipped,
            horizon_equipped: cfg.horizon_equipped,
            horizon_sum: cfg.form().horizon_sum(),
            task_conditions: cfg.task_conditions(),
            cache_bytes: args.cache_mib << 20,
            keep: match layouts {
                Layouts::First(n) => n.min(KEEP_LAYOUTS),
                Layouts::All => 0,
            },
        };
        (family, (fc, cfg.service_clients()), churns)
    } else {
        let spec = args.world.as_deref().unwrap_or_default();
        if !is_family(spec) {
            return Ok(None);
        }
        if args.objects.is_some() {
            return bad(format!(
                "--objects does not fit a world family: each layout of '{spec}' names its own task object"
            ));
        }
        if args.empowerment_from.is_some() {
            return bad(format!(
                "--empowerment-from does not fit a world family: estimates name the states of one world, and '{spec}' is many"
            ));
        }
        let family = load_family(spec)?;
        let fc = FamilyConfig {
            tool: args.tool.clone(),
            horizon_unequipped: args.horizon_unequipped.unwrap_or(family.horizon_unequipped),
            horizon_equipped: args.horizon_equipped.unwrap_or(family.horizon_equipped),
            horizon_sum: args.horizon_sum,
            task_conditions: false,
            cache_bytes: args.cache_mib << 20,
            keep: 0,
        };
        (family, (fc, args.max_clients), true)
    };
    if churns {
        ordinary_pages();
    }
    let ((fc, clients), name) = (cfg, family.name.clone());
    let (hu, he, keep) = (fc.horizon_unequipped, fc.horizon_equipped, fc.keep);
    let mut tables = FamilyTables::new(family, fc).map_err(BadRequest)?;
    let (_, stats) = serve_with(
        &mut tables,
        &args.namespace,
        Duration::from_micros(100),
        clients,
        |d| {
            let about = format!(
                "world family {name} (hash {:016x}), {keep} layouts made, the others on first sight, h = {hu} unequipped / {he} equipped, service fulcrum/{}/empowerment",
                d.world_hash, args.namespace
            );
            let _ = writeln!(std::io::stdout(), "{}", ChildLine::ServiceReady { about });
            let _ = std::io::stdout().flush();
        },
    )?;
    let f = tables.stats;
    let _ = writeln!(
        std::io::stdout(),
        "fulcrum serve: stopped: {} requests, {} states, {} refused; {} layout tables made ({:.2} ms each on average), {} dropped",
        stats.requests,
        stats.states,
        stats.refused,
        f.made,
        f.made_us as f64 / 1e3 / f.made.max(1) as f64,
        f.dropped
    );
    Ok(Some(()))
}

/// Ask the kernel for ordinary pages only (no transparent huge pages) in this process.
/// A family service that meets layouts on first sight makes and drops a table's working
/// memory for each (several MB for a boulder layout); with huge pages each fresh touch of
/// that memory zeroes 2 MB (a `perf record` of a fresh-layout run: 8% of its samples in
/// the kernel's page clearing, most of them the service's). With ordinary pages only
/// what is touched is zeroed: side by side, `train toolbox --layouts all` took a tenth
/// less time and 6% less CPU (BENCHMARKS.md, "Training on a family"). A service
/// whose tables are all made at its start keeps huge pages, which spare its look-ups
/// TLB misses. Best effort: a kernel without the setting leaves things as they were.
fn ordinary_pages() {
    // SAFETY: PR_SET_THP_DISABLE sets one flag of this process and touches no memory.
    let rc = unsafe { libc::prctl(libc::PR_SET_THP_DISABLE, 1, 0, 0, 0) };
    if rc != 0 {
        tracing::debug!(
            error = %std::io::Error::last_os_error(),
            "transparent huge pages stay on"
        );
    }
}

/// `fulcrum __visit`: count `times` visits of one state, one request each, and print
/// every count the service answers (a test of counts shared between processes).
pub fn visit_process(ns: &str, world: &str, state: &str, times: usize) -> Result<()> {
    use fulcrum_empowerment::service::{Ask, Client};
    let w = fulcrum_world::load_world(world)?;
    let s = w.parse_state(state)?;
    let mut c = Client::connect(ns, &w, std::time::Duration::from_secs(30))?;
    let mut out = String::new();
    for _ in 0..times {
        c.submit(Ask::Visit, std::slice::from_ref(&s))?;
        let b = c.recv()?;
        anyhow::ensure!(
            b.status.first() == Some(&fulcrum_contracts::msg::item::OK),
            "the service refused the state"
        );
        out.push_str(&format!("{}\n", b.values[0]));
    }
    print!("{out}");
    Ok(())
}
