//! `fulcrum bench`: the throughput suite. Every figure is printed next to the machine it
//! ran on and a correctness count, and written as JSON with `--json FILE`.
//!
//! Figures are medians of repeated runs in one process. Nothing here asserts a speed:
//! the command fails only when a benchmark breaks (an error, a wrong count, a zero).
//!
//! The suite runs in groups, in this order ([`BenchGroup`], `--only` picks some):
//! `empowerment` and `layouts` (`engine`), `service` (`service`), `training` and
//! `solve` (`training`), `python` (`python`); `--scaling` (`scaling`) and `--remote`
//! (`remote`) are runs of their own.

use std::time::Instant;

use anyhow::{ensure, Context, Result};
use serde_json::json;

use crate::cli::{BenchArgs, BenchGroup};

mod engine;
mod python;
#[cfg(feature = "multihost")]
pub mod remote;
mod scaling;
mod service;
mod training;

use fulcrum_contracts::fsio::write_atomic;

use engine::{empowerment_big, empowerment_exp2, family_layouts};
use service::service_figures;
pub use service::{client_process, pingpong_echo};
use training::{
    chunk_transport, end_to_end, family_end_to_end, robustness, time_to_solve, training_figures,
};

/// One measured figure.
pub(super) struct Figure {
    /// Zero is a valid reading (e.g. CPU while idle), not a broken benchmark.
    zero_ok: bool,
    name: String,
    value: f64,
    unit: &'static str,
    note: String,
}

/// Median wall time in milliseconds of `reps` runs of `f` (after one warm-up run).
pub(super) fn median_ms<T>(reps: usize, mut f: impl FnMut() -> Result<T>) -> Result<(f64, T)> {
    let mut out = f()?;
    let mut times = Vec::with_capacity(reps);
    for _ in 0..reps {
        let t0 = Instant::now();
        out = f()?;
        times.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(|a, b| a.total_cmp(b));
    Ok((times[times.len() / 2], out))
}

/// Peak resident memory of this process so far (VmHWM), in MiB.
pub(super) fn peak_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|kb| kb.parse::<f64>().ok())
        })
        .map_or(0.0, |kb| kb / 1024.0)
}

/// CPU model, cores, memory, OS and compiler.
pub fn machine() -> serde_json::Value {
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let cpu = cpuinfo
        .lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split(':').nth(1))
        .map_or("unknown".to_string(), |s| s.trim().to_string());
    let mem_gib = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("MemTotal:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|kb| kb.parse::<f64>().ok())
        })
        .map_or(0.0, |kb| kb / 1024.0 / 1024.0);
    let os = std::fs::read_to_string("/etc/os-release")
        .ok()
        .and_then(|t| {
            t.lines().find(|l| l.starts_with("PRETTY_NAME=")).map(|l| {
                l.trim_start_matches("PRETTY_NAME=")
                    .trim_matches('"')
                    .to_string()
            })
        })
        .unwrap_or_else(|| std::env::consts::OS.to_string());
    json!({
        "cpu": cpu,
        "cores": std::thread::available_parallelism().map_or(1, |n| n.get()),
        "memory_gib": (mem_gib * 10.0).round() / 10.0,
        "os": os,
        "rustc": env!("FULCRUM_RUSTC"),
        "fulcrum": env!("CARGO_PKG_VERSION"),
    })
}

/// Run the suite.
pub fn run(a: BenchArgs) -> Result<()> {
    let reps = if a.quick { 5 } else { 21 };
    let mut figs: Vec<Figure> = Vec::new();
    let m = machine();
    eprintln!(
        "fulcrum bench{}: {}",
        if a.quick { " --quick" } else { "" },
        m
    );

    if let Some(addr) = &a.remote {
        #[cfg(feature = "multihost")]
        remote::run(
            (!addr.is_empty()).then_some(addr.as_str()),
            a.quick,
            &mut figs,
        )?;
        #[cfg(not(feature = "multihost"))]
        {
            let _ = addr;
            return crate::commands::bad(super::NO_MULTIHOST.replace("{}", "bench --remote"));
        }
    } else if a.scaling {
        scaling::run(&a.plots, a.max_states, &mut figs)?;
    } else {
        let runs = |g: BenchGroup| a.only.is_empty() || a.only.contains(&g);
        if runs(BenchGroup::Empowerment) {
            empowerment_exp2(reps, a.quick, &mut figs)?;
            empowerment_big(a.quick, &mut figs)?;
        }
        if runs(BenchGroup::Layouts) {
            family_layouts(a.quick, &mut figs)?;
        }
        if runs(BenchGroup::Service) {
            service_figures(a.quick, &mut figs)?;
        }
        if runs(BenchGroup::Training) {
            training_figures(a.quick, &mut figs)?;
            chunk_transport(a.quick, &mut figs)?;
            end_to_end(a.quick, &mut figs)?;
            family_end_to_end(a.quick, &mut figs)?;
        }
        if runs(BenchGroup::Solve) {
            time_to_solve(&mut figs)?;
            if !a.quick {
                robustness(&mut figs)?;
            }
        }
        if runs(BenchGroup::Python) {
            python::python_figures(a.quick, !a.only.is_empty(), &mut figs)?;
        }
    }

    let only: Vec<String> = a
        .only
        .iter()
        .filter_map(clap::ValueEnum::to_possible_value)
        .map(|v| v.get_name().to_owned())
        .collect();
    println!(
        "fulcrum bench{}{} on {} ({} cores, {} GiB, {}, {})",
        if a.remote.is_some() {
            " --remote"
        } else if a.quick {
            " --quick"
        } else if a.scaling {
            " --scaling"
        } else {
            ""
        },
        if only.is_empty() {
            String::new()
        } else {
            format!(" --only {}", only.join(","))
        },
        m["cpu"].as_str().unwrap_or("?"),
        m["cores"],
        m["memory_gib"],
        m["os"].as_str().unwrap_or("?"),
        m["rustc"].as_str().unwrap_or("?")
    );
    let w = figs.iter().map(|f| f.name.len()).max().unwrap_or(10);
    for f in &figs {
        println!(
            "{:<w$}  {:>14} {:<10} {}",
            f.name,
            fmt_value(f.value),
            f.unit,
            f.note
        );
    }
    for f in &figs {
        ensure!(
            f.value.is_finite() && (f.value > 0.0 || (f.zero_ok && f.value == 0.0)),
            "benchmark '{}' gave {} {}: broken",
            f.name,
            f.value,
            f.unit
        );
    }
    if let Some(path) = &a.json {
        let v = json!({
            "machine": m,
            "quick": a.quick,
            "scaling": a.scaling,
            "only": only,
            "figures": figs.iter().map(|f| json!({"name": f.name, "value": f.value, "unit": f.unit, "note": f.note})).collect::<Vec<_>>(),
        });
        write_atomic(path, serde_json::to_string_pretty(&v)?.as_bytes())
            .with_context(|| format!("cannot write {}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

pub(super) fn fmt_value(v: f64) -> String {
    if v >= 100.0 {
        format!("{v:.0}")
    } else if v >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.4}")
    }
}

pub(super) fn percentile(sorted: &[f64], q: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

/// User + system CPU seconds of a process so far (/proc/PID/stat).
pub(super) fn cpu_seconds(pid: u32) -> f64 {
    let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else {
        return 0.0;
    };
    // Fields after the command name (which is in parentheses and may hold spaces).
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|x| x.parse::<f64>().ok()).unwrap_or(0.0);
    // utime and stime are fields 14 and 15 of stat, i.e. 11 and 12 after ')'; 100 Hz.
    (ticks(11) + ticks(12)) / 100.0
}
