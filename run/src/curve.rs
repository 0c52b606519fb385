//! A run's learning curve, drawn from its `metrics.csv` when the run ends.

use std::path::PathBuf;

use fulcrum_learner::metrics::read_metrics;
use fulcrum_learner::paths::RunPaths;
use fulcrum_world::World;

/// Draw `plots/learning-curve.png` from metrics.csv (None when there is nothing).
pub fn draw_curve(w: &World, paths: &RunPaths) -> Option<PathBuf> {
    let rows = read_metrics(&paths.metrics()).ok()?;
    if rows.is_empty() {
        return None;
    }
    let pts: Vec<fulcrum_plot::CurvePoint> = rows
        .iter()
        .map(|r| fulcrum_plot::CurvePoint {
            env_steps: r.env_steps,
            success_rate: r.success_rate,
            extrinsic_return: r.extrinsic_return,
            intrinsic_mean: r.intrinsic_mean,
        })
        .collect();
    let path = paths.plots().join("learning-curve.png");
    let _ = std::fs::create_dir_all(paths.plots());
    match fulcrum_plot::learning_curve_png(&path, &format!("{}: PPO", w.name), &pts) {
        Ok(()) => Some(path),
        Err(e) => {
            eprintln!("fulcrum train: the learning curve was not drawn: {e}");
            None
        }
    }
}
