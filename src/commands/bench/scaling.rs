//! `fulcrum bench --scaling`: how cost grows with work, and where the knee is.
//!
//! * Training: end-to-end `fulcrum train exp1-tree` (with empowerment) for 1, 2 and 4
//!   actor processes x 16, 64 and 256 worlds per actor, 128 steps per chunk, 8 updates
//!   each; the figure is the median env steps/s of updates 2..8 (the first pays for
//!   start-up), the band its standard deviation.
//! * Empowerment: state enumeration and one lookup table (tool 0 -> object 0, h = 8, as
//!   the service computes it) on generated worlds of about 10^3 .. 10^7 states; time and
//!   time per state.

use std::path::Path;
use std::time::Instant;

use anyhow::{ensure, Context, Result};
use fulcrum_empowerment::{Engine, Limits, Method, ToolSel};
use fulcrum_run::argv::{NewRun, TrainJob};
use fulcrum_world::generate::{generate, GenParams};
use fulcrum_world::{parse_world, ObjectSet};

use super::Figure;
use fulcrum_plot::{band_chart_png, Band, BandChart};

/// Generated worlds near each decade of states (found by a sweep of `world generate`):
/// (width = height, tools, objects, seed).
const WORLDS: [(usize, usize, usize, u64); 5] = [
    (7, 3, 1, 1),  // 1 001 states
    (10, 4, 1, 1), // 9 798
    (10, 3, 1, 0), // 105 718
    (16, 3, 1, 0), // 1 022 216
    (10, 3, 3, 0), // 10 065 080
];

const ACTORS: [usize; 3] = [1, 2, 4];
const ENVS: [usize; 3] = [16, 64, 256];
const UPDATES: u64 = 8;

/// Runs the study; figures go to `figs`, pictures to `plots`.
pub fn run(plots: &Path, max_states: Option<u64>, figs: &mut Vec<Figure>) -> Result<()> {
    std::fs::create_dir_all(plots).with_context(|| format!("cannot create {}", plots.display()))?;
    training(plots, figs)?;
    tables(plots, max_states, figs)?;
    Ok(())
}

fn median_std(mut v: Vec<f64>) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    let (_, s) = fulcrum_run::stats::mean_std(&v);
    (v[v.len() / 2], s)
}

fn training(plots: &Path, figs: &mut Vec<Figure>) -> Result<()> {
    let mut bands = Vec::new();
    for &a in &ACTORS {
        let (mut mean, mut std) = (Vec::new(), Vec::new());
        for &e in &ENVS {
            let dir = std::env::temp_dir().join(format!(
                "fulcrum-bench-scaling-{}-{a}-{e}",
                std::process::id()
            ));
            let steps = UPDATES * (a * e * 128) as u64;
            let t0 = Instant::now();
            let (sps, _) = super::training::train_sps(&TrainJob::New(NewRun {
                actors: Some(a),
                envs_per_actor: Some(e),
                checkpoint_every: Some(1000),
                ..NewRun::new("exp1-tree", steps, &dir)
            }))?;
            let wall = t0.elapsed().as_secs_f64();
            let (m, s) = median_std(sps);
            eprintln!("scaling: {a} actors x {e} worlds: {m:.0} steps/s ({wall:.1} s)");
            figs.push(Figure {
                zero_ok: false,
                name: format!("train exp1-tree, {a} actors x {e} worlds"),
                value: m,
                unit: "steps/s",
                note: format!(
                    "(median of updates 2..{UPDATES}, std {s:.0}; batch {})",
                    a * e * 128
                ),
            });
            mean.push(m);
            std.push(s);
        }
        bands.push(Band {
            name: format!("{a} actor{}", if a == 1 { "" } else { "s" }),
            mean,
            std,
        });
    }
    let chart = BandChart {
        title: "train exp1-tree with empowerment: env steps/s (median, ± std over updates)".into(),
        x_label: "worlds per actor".into(),
        y_label: "env steps/s".into(),
        x: ENVS.iter().map(|&e| e as f64).collect(),
        bands,
        y_range: None,
        x_log: true,
        y_log: false,
    };
    let path = plots.join("scaling-training.png");
    band_chart_png(&path, &chart).with_context(|| format!("cannot draw {}", path.display()))?;
    eprintln!("wrote {}", path.display());
    Ok(())
}

fn tables(plots: &Path, max_states: Option<u64>, figs: &mut Vec<Figure>) -> Result<()> {
    let (mut xs, mut enum_s, mut table_s) = (Vec::new(), Vec::new(), Vec::new());
    for &(side, tools, objects, seed) in &WORLDS {
        let p = GenParams {
            width: side,
            height: side,
            tools,
            objects,
            rock: 0.0,
            seed,
        };
        let w = parse_world(&generate(&p)?, "generated")?;
        let t0 = Instant::now();
        let e = Engine::new(&w, Limits::default())?;
        let n = e.space.len();
        if max_states.is_some_and(|m| n as u64 > m) {
            eprintln!("scaling: leaving out {n} states (over --max-states)");
            continue;
        }
        let en = t0.elapsed().as_secs_f64();
        let set = ObjectSet::Objects(vec![0]);
        let reps = if n < 200_000 { 5 } else { 1 };
        let mut times = Vec::new();
        for _ in 0..reps {
            let t0 = Instant::now();
            let c = e.counts(ToolSel::Tool(0), &set, &[8], Method::Dp)?;
            times.push(t0.elapsed().as_secs_f64());
            ensure!(
                c[0].len() == n && c[0].iter().all(|&k| k >= 1),
                "a table count is wrong"
            );
        }
        let (t, _) = median_std(times);
        let label = format!("gen {side}x{side} t{tools} o{objects} s{seed}");
        eprintln!("scaling: {n} states: enumeration {en:.3} s, table {t:.3} s");
        figs.push(Figure {
            zero_ok: false,
            name: format!("{label}: enumeration"),
            value: en * 1e3,
            unit: "ms",
            note: format!("({n} states, {:.0} ns per state)", en * 1e9 / n as f64),
        });
        figs.push(Figure {
            zero_ok: false,
            name: format!("{label}: table tool 0 -> object 0, h = 8"),
            value: t * 1e3,
            unit: "ms",
            note: format!(
                "({n} states, {:.0} ns per state, median of {reps})",
                t * 1e9 / n as f64
            ),
        });
        xs.push(n as f64);
        enum_s.push(en);
        table_s.push(t);
    }
    let zero = vec![0.0; xs.len()];
    let chart = BandChart {
        title: "exact empowerment on generated worlds: time against states".into(),
        x_label: "states".into(),
        y_label: "seconds".into(),
        x: xs,
        bands: vec![
            Band {
                name: "state enumeration".into(),
                mean: enum_s,
                std: zero.clone(),
            },
            Band {
                name: "table (one tool, one object, h = 8)".into(),
                mean: table_s,
                std: zero,
            },
        ],
        y_range: None,
        x_log: true,
        y_log: true,
    };
    let path = plots.join("scaling-empowerment.png");
    band_chart_png(&path, &chart).with_context(|| format!("cannot draw {}", path.display()))?;
    eprintln!("wrote {}", path.display());
    Ok(())
}
