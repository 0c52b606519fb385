//! `fulcrum empowerment dataset` and `fulcrum empowerment score`: exact E as ground
//! truth for learned estimators (`fulcrum_empowerment::dataset`, `::score`).

use anyhow::Result;
use fulcrum_empowerment::dataset::{self, Spec};
use fulcrum_empowerment::score::{Errors, Score};
use fulcrum_empowerment::{npz, set_name};
use fulcrum_world::load_world as world;
use serde_json::json;

use super::resolve;
use crate::cli::{DatasetArgs, ScoreArgs};
use crate::commands::bad;

pub(super) fn dataset(a: &DatasetArgs) -> Result<()> {
    let w = world(&a.channel.world)?;
    let r = resolve(&w, &a.channel)?;
    let spec = Spec {
        tool: r.tool,
        set: r.set.clone(),
        horizon: a.channel.horizon,
        rows: a.states,
        seed: a.seed,
        view: a.view,
        sequences: a.sequences,
    };
    let d = dataset::build(&r.e, &spec, a.channel.method.into())?;
    let normal: Vec<f64> =
        d.e.iter()
            .zip(&d.normal)
            .filter(|(_, &n)| n)
            .map(|(e, _)| *e)
            .collect();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let mut hs = d.horizon.clone();
    hs.sort_unstable();
    hs.dedup();
    let (rows, sequences, projections, mean_e) = (
        d.len(),
        d.seq_row.len(),
        d.proj_key.len() / d.key_len.max(1),
        mean(&d.e),
    );
    let bytes = npz::to_npz(&d.into_arrays(&w, &spec))?;
    fulcrum_contracts::fsio::write_atomic(&a.out, &bytes).map_err(|e| {
        fulcrum_run::BadRequest(format!("cannot write --out {}: {e}", a.out.display()))
    })?;
    if a.channel.json {
        let v = json!({
            "out": a.out.display().to_string(),
            "world": w.name,
            "tool": r.tool.name(&w),
            "objects": set_name(&w, &r.set),
            "states": rows,
            "space": r.e.space.len(),
            "normal": normal.len(),
            "horizons": hs,
            "sequences": sequences,
            "projections": projections,
            "mean_E": mean_e,
            "mean_E_normal": mean(&normal),
            "bytes": bytes.len(),
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    println!(
        "wrote {}: {} of {} states of {} ({} normal-mode), E^{} {} -> {}, {} sequences",
        a.out.display(),
        rows,
        r.e.space.len(),
        w.name,
        normal.len(),
        hs.iter().map(u32::to_string).collect::<Vec<_>>().join("/"),
        r.tool.name(&w),
        set_name(&w, &r.set),
        sequences
    );
    println!(
        "mean E {:.6} bits; over normal-mode states {:.6} bits",
        mean_e,
        mean(&normal)
    );
    Ok(())
}

/// A dataset's `E` and `horizon`, read from its file.
fn truth(path: &std::path::Path) -> Result<(Vec<f64>, Vec<u32>)> {
    let place = path.display();
    let bytes = std::fs::read(path)
        .map_err(|e| fulcrum_run::BadRequest(format!("cannot read {place}: {e}")))?;
    let arrays =
        npz::read_npz(&bytes).map_err(|e| fulcrum_run::BadRequest(format!("{place}: {e}")))?;
    let get = |name: &str| -> Result<Vec<f64>> {
        let Some((_, raw)) = arrays.iter().find(|(n, _)| n == name) else {
            return bad(format!(
                "{place} has no array '{name}': is it a dataset of `fulcrum empowerment dataset`?"
            ));
        };
        if raw.shape.len() != 1 {
            return bad(format!(
                "{place}: '{name}' has shape {:?}, not one value per state",
                raw.shape
            ));
        }
        raw.to_f64()
            .map_err(|e| fulcrum_run::BadRequest(format!("{place}: '{name}': {e}")).into())
    };
    let e = get("E")?;
    let h = get("horizon")?;
    if h.len() != e.len() {
        return bad(format!(
            "{place}: 'E' has {} states and 'horizon' {}",
            e.len(),
            h.len()
        ));
    }
    Ok((e, h.iter().map(|&x| x as u32).collect()))
}

/// Estimates from a CSV: `(row, estimate)` pairs, rows in order where the file has no
/// `row` column.
fn estimates(path: &std::path::Path, rows: usize) -> Result<Vec<(usize, f64)>> {
    let place = path.display();
    let text = std::fs::read_to_string(path)
        .map_err(|e| fulcrum_run::BadRequest(format!("cannot read {place}: {e}")))?;
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let Some((_, header)) = lines.next() else {
        return bad(format!(
            "{place} is empty: it needs a header with a column 'estimate'"
        ));
    };
    let cols: Vec<&str> = header.split(',').map(str::trim).collect();
    let Some(ei) = cols.iter().position(|c| *c == "estimate") else {
        return bad(format!(
            "{place}:1: the header has no column 'estimate' (found: {})",
            cols.join(", ")
        ));
    };
    let ri = cols.iter().position(|c| *c == "row");
    let mut out = Vec::new();
    let mut seen = vec![false; rows];
    for (k, (i, line)) in lines.enumerate() {
        let at = format!("{place}:{}", i + 1);
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != cols.len() {
            return bad(format!(
                "{at}: {} fields where the header has {}",
                f.len(),
                cols.len()
            ));
        }
        let x: f64 = f[ei]
            .parse()
            .ok()
            .filter(|x: &f64| x.is_finite())
            .ok_or_else(|| {
                fulcrum_run::BadRequest(format!(
                    "{at}: estimate '{}' is not a finite number of bits",
                    f[ei]
                ))
            })?;
        let row = match ri {
            Some(ri) => f[ri].parse::<usize>().map_err(|_| {
                fulcrum_run::BadRequest(format!("{at}: row '{}' is not a row number", f[ri]))
            })?,
            None => k,
        };
        if row >= rows {
            return bad(format!(
                "{at}: row {row} is past the dataset's {rows} states"
            ));
        }
        if std::mem::replace(&mut seen[row], true) {
            return bad(format!("{at}: row {row} is estimated twice"));
        }
        out.push((row, x));
    }
    if ri.is_none() && out.len() != rows {
        return bad(format!(
            "{place} has {} estimates for a dataset of {rows} states (add a column 'row' to score a subset)",
            out.len()
        ));
    }
    if out.is_empty() {
        return bad(format!("{place} has no estimates"));
    }
    Ok(out)
}

fn errors_json(e: &Errors) -> serde_json::Value {
    json!({"n": e.n, "mae": e.mae, "bias": e.bias, "rmse": e.rmse, "spearman": e.spearman})
}

/// A score as the JSON both the command line and Python give.
pub fn score_json(s: &Score) -> serde_json::Value {
    let mut v = errors_json(&s.all);
    v["by_bin"] = s
        .by_bin
        .iter()
        .map(|b| {
            let mut e = errors_json(&b.errors);
            e["lo"] = json!(b.lo);
            e["hi"] = json!(b.lo + 1.0);
            e
        })
        .collect();
    v["by_horizon"] = s
        .by_horizon
        .iter()
        .map(|(h, b)| {
            let mut e = errors_json(b);
            e["horizon"] = json!(h);
            e
        })
        .collect();
    v
}

pub(super) fn score(a: &ScoreArgs) -> Result<()> {
    let (e, h) = truth(&a.dataset)?;
    let est = estimates(&a.estimates, e.len())?;
    let x: Vec<f64> = est.iter().map(|p| p.1).collect();
    let y: Vec<f64> = est.iter().map(|p| e[p.0]).collect();
    let hh: Vec<u32> = est.iter().map(|p| h[p.0]).collect();
    let s = fulcrum_empowerment::score::score(&x, &y, &hh).map_err(fulcrum_run::BadRequest)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&score_json(&s))?);
        return Ok(());
    }
    let rho = |r: Option<f64>| r.map_or("-".to_string(), |r| format!("{r:.4}"));
    println!(
        "{} estimates: MAE {:.4} bits, bias {:+.4} bits, RMSE {:.4} bits, Spearman {}",
        s.all.n,
        s.all.mae,
        s.all.bias,
        s.all.rmse,
        rho(s.all.spearman)
    );
    println!(
        "\n{:<14}{:>7}{:>10}{:>10}",
        "true E (bits)", "n", "MAE", "bias"
    );
    for b in &s.by_bin {
        println!(
            "{:<14}{:>7}{:>10.4}{:>+10.4}",
            format!("[{}, {})", b.lo, b.lo + 1.0),
            b.errors.n,
            b.errors.mae,
            b.errors.bias
        );
    }
    println!(
        "\n{:<14}{:>7}{:>10}{:>10}{:>10}",
        "horizon", "n", "MAE", "bias", "Spearman"
    );
    for (hz, b) in &s.by_horizon {
        println!(
            "{:<14}{:>7}{:>10.4}{:>+10.4}{:>10}",
            hz,
            b.n,
            b.mae,
            b.bias,
            rho(b.spearman)
        );
    }
    Ok(())
}
