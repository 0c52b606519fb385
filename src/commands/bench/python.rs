//! The Python package's figures (`python -m fulcrum.bench`), when it is installed: a
//! 64-world `make_vec` stepped from Python, the same through `EmpowermentReward` (the
//! additive bonus, and the wrapper's default form), and MiniGrid stepped the same way
//! when `minigrid` is installed too.
//!
//! The interpreter is `$FULCRUM_PYTHON`, else `python3`. Without the package the suite
//! says so on stderr and goes on: the figures are optional, the rest is not; but
//! `--only python` without it is bad input (exit code 2).

use std::process::Command;

use anyhow::{ensure, Context, Result};

use super::Figure;

/// Adds the Python figures to `figs`, or says why there are none: on stderr, or as the
/// error of bad input where they were asked for by name (`required`: `--only python`).
pub(super) fn python_figures(quick: bool, required: bool, figs: &mut Vec<Figure>) -> Result<()> {
    let python = std::env::var("FULCRUM_PYTHON").unwrap_or_else(|_| "python3".into());
    let found = Command::new(&python)
        .args(["-c", "import fulcrum.bench"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !found {
        let why = format!(
            "no Python figures: '{python}' cannot import fulcrum (pip install ./python, or set FULCRUM_PYTHON to an interpreter that can)"
        );
        if required {
            return crate::commands::bad(why);
        }
        eprintln!("fulcrum bench: {why}");
        return Ok(());
    }
    let mut cmd = Command::new(&python);
    cmd.args(["-m", "fulcrum.bench", "--json"]);
    if quick {
        cmd.arg("--quick");
    }
    let out = cmd
        .output()
        .with_context(|| format!("cannot run {python} -m fulcrum.bench"))?;
    ensure!(
        out.status.success(),
        "{python} -m fulcrum.bench failed: {}",
        String::from_utf8_lossy(&out.stderr).trim()
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout)
        .with_context(|| format!("{python} -m fulcrum.bench printed no JSON"))?;
    let get = |k: &str| v[k].as_f64();
    let n = get("num_envs").unwrap_or(0.0);
    // Every figure but MiniGrid's must be there: a missing one names itself.
    let need = |k: &str| {
        get(k).with_context(|| format!("{python} -m fulcrum.bench: no figure '{k}' in {v}"))
    };
    let (plain, wrapped, over) = (
        need("make_vec_steps_per_s")?,
        need("wrapped_steps_per_s")?,
        need("wrapper_overhead_percent")?,
    );
    let (default, default_over) = (
        need("default_steps_per_s")?,
        need("default_overhead_percent")?,
    );
    let (layouts, fam_plain, fam, fam_over) = (
        need("family_layouts")?,
        need("family_steps_per_s")?,
        need("family_default_steps_per_s")?,
        need("family_overhead_percent")?,
    );
    figs.push(Figure {
        zero_ok: false,
        name: "python make_vec env steps/s".into(),
        value: plain,
        unit: "steps/s",
        note: format!(
            "(exp1-tree x {n}, random actions, stepped from Python, one core; goal >= 2M)"
        ),
    });
    figs.push(Figure {
        zero_ok: false,
        name: "python make_vec + EmpowermentReward".into(),
        value: wrapped,
        unit: "steps/s",
        note: format!("(the same with the additive bonus: +{over:.1}% per step; goal < 10%)"),
    });
    let form = v["default_form"].as_str().unwrap_or("the default form");
    figs.push(Figure {
        zero_ok: false,
        name: "python make_vec + EmpowermentReward, default form".into(),
        value: default,
        unit: "steps/s",
        note: format!(
            "(the same with {form}, the wrapper's default: +{default_over:.1}% per step)"
        ),
    });
    figs.push(Figure {
        zero_ok: false,
        name: "python make_vec toolbox + EmpowermentReward, default form".into(),
        value: fam,
        unit: "steps/s",
        note: format!(
            "({layouts} layouts x {n}, a table per layout: +{fam_over:.1}% per step over the family's {fam_plain:.0} unwrapped)"
        ),
    });
    if let (Some(mg), Some(ratio)) = (get("minigrid_steps_per_s"), get("ratio_to_minigrid")) {
        figs.push(Figure {
            zero_ok: false,
            name: "python MiniGrid DoorKey-5x5 env steps/s".into(),
            value: mg,
            unit: "steps/s",
            note: format!(
                "(x {n}, gymnasium sync vector env, stepped the same way; fulcrum x{ratio:.0})"
            ),
        });
    }
    Ok(())
}
