//! The engine's figures: the matrix, landscapes and enumeration on exp2 and on a large
//! generated world; on exp1-tree-slip, distribution propagation against brute force and
//! the service's whole table.

use std::time::Instant;

use anyhow::{ensure, Context, Result};
use fulcrum_empowerment::{enumerate, propagate, Engine, Limits, Method, StateSpace, ToolSel};
use fulcrum_world::generate::{generate, GenParams};
use fulcrum_world::{load_world, parse_world, ObjectSet, World};

use super::{median_ms, peak_mib, Figure};

/// Parameters of the generated world of at least 10^6 states (quick: ~10^5).
pub fn big_world_params(quick: bool) -> GenParams {
    if quick {
        GenParams {
            width: 12,
            height: 12,
            tools: 4,
            objects: 4,
            rock: 0.0,
            seed: 7,
        }
    } else {
        GenParams {
            width: 14,
            height: 14,
            tools: 4,
            objects: 4,
            rock: 0.0,
            seed: 3,
        }
    }
}

pub(super) fn objects(w: &World, names: &[&str]) -> ObjectSet {
    let mut v: Vec<usize> = names.iter().filter_map(|n| w.object_index(n)).collect();
    v.sort_unstable();
    ObjectSet::Objects(v)
}

/// exp2: enumeration, the full matrix, per-state cost, and the ratio to the paper's
/// method at h = 6.
pub(super) fn empowerment_exp2(reps: usize, quick: bool, figs: &mut Vec<Figure>) -> Result<()> {
    let w = load_world("exp2")?;
    let limits = Limits::default();
    let (enum_ms, space) = median_ms(reps, || Ok(StateSpace::enumerate(&w, &limits)?))?;
    let n = space.len();
    figs.push(Figure {
        zero_ok: false,
        name: "exp2 state enumeration".into(),
        value: enum_ms,
        unit: "ms",
        note: format!("({n} states)"),
    });
    let columns = [
        objects(&w, &["boulder"]),
        objects(&w, &["door"]),
        objects(&w, &["boulder", "door"]),
    ];
    let (matrix_ms, mat) = median_ms(reps, || {
        let e = Engine::new(&w, limits)?;
        Ok(e.matrix(&columns, 5, 6, Method::Dp)?)
    })?;
    ensure!(
        (mat.values[0][2] - 0.4859727539794917).abs() < 1e-9,
        "exp2 matrix is wrong: {:?}",
        mat.values
    );
    let entries = mat.tools.len() * columns.len();
    figs.push(Figure {
        zero_ok: false,
        name: "exp2 full matrix incl. enumeration".into(),
        value: matrix_ms,
        unit: "ms",
        note: format!(
            "({} tools x {} columns, h = 5/6; goal <= 20 ms)",
            mat.tools.len(),
            columns.len()
        ),
    });
    figs.push(Figure {
        zero_ok: false,
        name: "exp2 matrix cost per state per entry".into(),
        value: (matrix_ms - enum_ms).max(1e-6) * 1e6 / (n * entries) as f64,
        unit: "ns",
        note: format!("({entries} entries x {n} states, h up to 6)"),
    });

    // The ratio at h = 6: set propagation over every state against enumerating the
    // 6^6 sequences per state on a sample (same tool, objects, horizon).
    let e = Engine::new(&w, limits)?;
    let wand = ToolSel::Tool(w.tool_index("wand").context("exp2 has a wand")?);
    let set = objects(&w, &["boulder", "door"]);
    let (dp_ms, counts) = median_ms(reps, || Ok(e.counts(wand, &set, &[6], Method::Dp)?))?;
    let sample = if quick { 40 } else { 400 };
    let step = (n / sample).max(1);
    let ids: Vec<u32> = (0..n as u32).step_by(step).take(sample).collect();
    let actions = wand.actions(&w);
    let t0 = Instant::now();
    let mut agree = 0;
    for &i in &ids {
        let c = enumerate::reachable_count(&w, e.space.state(i), &actions, &set, 6);
        agree += (c as u32 == counts[0][i as usize]) as usize;
    }
    let enum_per_state_ms = t0.elapsed().as_secs_f64() * 1e3 / ids.len() as f64;
    ensure!(
        agree == ids.len(),
        "set propagation and enumeration disagree on {} of {} states",
        ids.len() - agree,
        ids.len()
    );
    figs.push(Figure {
        zero_ok: false,
        name: "exp2 E^6 all states, set propagation".into(),
        value: dp_ms,
        unit: "ms",
        note: format!("(wand -> boulder+door, {n} states)"),
    });
    figs.push(Figure {
        zero_ok: false,
        name: "exp2 E^6 per state, enumeration".into(),
        value: enum_per_state_ms,
        unit: "ms",
        note: format!(
            "(6^6 sequences, 1 thread, {} sampled states, {agree} agree with set propagation)",
            ids.len()
        ),
    });
    figs.push(Figure {
        zero_ok: false,
        name: "exp2 speed-up of set propagation at h = 6".into(),
        value: enum_per_state_ms * n as f64 / dp_ms,
        unit: "x",
        note: "(enumeration extrapolated to all states / set propagation; goal >= 1000x)".into(),
    });
    empowerment_stochastic(quick, figs)
}

/// exp1-tree-slip: per-value time of distribution propagation against the brute force
/// (every sequence, every outcome, Blahut-Arimoto) on the same states at h = 4, and the
/// service's whole LOOKUP table (axe -> tree, h = 8 unequipped / 3 equipped).
fn empowerment_stochastic(quick: bool, figs: &mut Vec<Figure>) -> Result<()> {
    let w = load_world("exp1-tree-slip")?;
    let limits = Limits::default();
    let e = Engine::new(&w, limits)?;
    let n = e.space.len();
    let axe = ToolSel::Tool(w.tool_index("axe").context("exp1-tree-slip has an axe")?);
    let tree = objects(&w, &["tree"]);
    let sample = if quick { 30 } else { 300 };
    let ids: Vec<u32> = (0..n as u32)
        .step_by((n / sample).max(1))
        .take(sample)
        .collect();
    let t0 = Instant::now();
    let fast = e.values_at(axe, &tree, 4, &ids, Method::Dp)?;
    let fast_ms = t0.elapsed().as_secs_f64() * 1e3 / ids.len() as f64;
    let t0 = Instant::now();
    let slow = e.values_at(axe, &tree, 4, &ids, Method::Enumerate)?;
    let slow_ms = t0.elapsed().as_secs_f64() * 1e3 / ids.len() as f64;
    let agree = fast
        .iter()
        .zip(&slow)
        .filter(|(a, b)| (a.bits - b.bits).abs() < 2e-9)
        .count();
    ensure!(
        agree == ids.len(),
        "distribution propagation and brute force disagree on {} of {} states",
        ids.len() - agree,
        ids.len()
    );
    figs.push(Figure {
        zero_ok: false,
        name: "exp1-tree-slip E^4 per value, distribution propagation".into(),
        value: fast_ms,
        unit: "ms",
        note: format!("(axe -> tree, {} sampled states)", ids.len()),
    });
    figs.push(Figure {
        zero_ok: false,
        name: "exp1-tree-slip E^4 per value, brute force".into(),
        value: slow_ms,
        unit: "ms",
        note: format!("(6^4 sequences, every outcome, Blahut-Arimoto; {agree} agree to 2e-9 bits)"),
    });
    // Every state at once, as the service's table is made (the support prefilter and
    // the sinks computed once for all states), against the brute force extrapolated
    // from the sample to all states: the method of the set-propagation speed-up above.
    let (all_ms, all) = median_ms(if quick { 3 } else { 11 }, || {
        Ok(e.values(axe, &tree, 4, Method::Dp)?)
    })?;
    for (&i, f) in ids.iter().zip(&fast) {
        ensure!(
            (all[i as usize] - f.bits).abs() < 2e-9,
            "E^4 of every state disagrees with the per-state value at state {i}"
        );
    }
    figs.push(Figure {
        zero_ok: false,
        name: "exp1-tree-slip E^4 all states, distribution propagation".into(),
        value: all_ms,
        unit: "ms",
        note: format!(
            "(axe -> tree, {n} states, {:.2} us a value)",
            all_ms * 1e3 / n as f64
        ),
    });
    figs.push(Figure {
        zero_ok: false,
        name: "exp1-tree-slip speed-up at h = 4".into(),
        value: slow_ms * n as f64 / all_ms,
        unit: "x",
        note: "(brute force extrapolated to all states / all states at once; goal >= 1000x)".into(),
    });
    let t0 = Instant::now();
    let e = Engine::new(&w, limits)?;
    let table = e.lookup_values(axe, &tree, 8, 3, false)?;
    let table_ms = t0.elapsed().as_secs_f64() * 1e3;
    ensure!(
        table.iter().all(|v| v.is_finite()),
        "the table is not finite"
    );
    figs.push(Figure {
        zero_ok: false,
        name: "exp1-tree-slip service table incl. enumeration".into(),
        value: table_ms,
        unit: "ms",
        note: format!("(axe -> tree, h = 8 unequipped / 3 equipped, {n} states; goal <= 60 s)"),
    });
    // exp2-slip as a run's service builds it: the world's objects, tool selection by the
    // matrix (equation 6), the world's horizons.
    let w = load_world("exp2-slip")?;
    let t0 = Instant::now();
    let e = Engine::new(&w, limits)?;
    let set = fulcrum_empowerment::request::objects_or_default(&w, None)?;
    let tool = fulcrum_empowerment::request::tool_sel(&w, &e, Some("auto"), &set)?;
    let (hu, he) = (
        w.empowerment.horizon_unequipped,
        w.empowerment.horizon_equipped,
    );
    let table = e.lookup_values(tool, &set, hu, he, false)?;
    let table_ms = t0.elapsed().as_secs_f64() * 1e3;
    ensure!(
        table.iter().all(|v| v.is_finite()),
        "the exp2-slip table is not finite"
    );
    figs.push(Figure {
        zero_ok: false,
        name: "exp2-slip service table incl. enumeration and tool selection".into(),
        value: table_ms,
        unit: "ms",
        note: format!(
            "({} -> {}, h = {hu} unequipped / {he} equipped, {} states; goal <= 5 min)",
            tool.name(&w),
            fulcrum_empowerment::set_name(&w, &set),
            e.space.len()
        ),
    });
    Ok(())
}

/// A generated world of >= 10^6 states: enumeration, one matrix column at h = 8, peak
/// memory.
pub(super) fn empowerment_big(quick: bool, figs: &mut Vec<Figure>) -> Result<()> {
    let p = big_world_params(quick);
    let text = generate(&p)?;
    let w = parse_world(&text, "generated")?;
    let limits = Limits::default();
    let t0 = Instant::now();
    let e = Engine::new(&w, limits)?;
    let enum_ms = t0.elapsed().as_secs_f64() * 1e3;
    let n = e.space.len();
    let label = format!("gen {}x{} t{} o{}", p.width, p.height, p.tools, p.objects);
    figs.push(Figure { zero_ok: false, name: format!("{label} state enumeration"), value: enum_ms, unit: "ms", note: format!("({n} states, `fulcrum world generate --width {} --height {} --tools {} --objects {} --seed {}`)", p.width, p.height, p.tools, p.objects, p.seed) });
    let column = ObjectSet::Objects(vec![0]);
    let proj = propagate::Projection::new(&e.space, &column);
    let t0 = Instant::now();
    let m = e.matrix(std::slice::from_ref(&column), 8, 8, Method::Dp)?;
    let col_ms = t0.elapsed().as_secs_f64() * 1e3;
    ensure!(
        m.values.iter().all(|r| r[0].is_finite()),
        "matrix column is not finite"
    );
    figs.push(Figure {
        zero_ok: false,
        name: format!("{label} matrix column at h = 8"),
        value: col_ms,
        unit: "ms",
        note: format!(
            "({} tools -> {}, {} projected states; goal <= 2 s at 10^6 states)",
            m.tools.len(),
            m.columns[0],
            proj.size
        ),
    });
    figs.push(Figure {
        zero_ok: false,
        name: format!("{label} column cost per state per tool per step"),
        value: col_ms * 1e6 / (n * m.tools.len() * 8) as f64,
        unit: "ns",
        note: "(6 actions, one 64-bit word per set)".into(),
    });
    figs.push(Figure {
        zero_ok: false,
        name: "peak memory (VmHWM) after the big world".into(),
        value: peak_mib(),
        unit: "MiB",
        note: format!(
            "({} MiB estimated for the state space)",
            e.space.bytes() >> 20
        ),
    });
    Ok(())
}

/// Layouts never seen: for each of the first 1,000 layouts of `toolbox` (quick: 100),
/// the time from the layout seed to the whole table the empowerment service would answer
/// from for train's default form (the layout drawn and parsed, its states enumerated, the
/// matrix's tool selection for the task object, the potential Phi = sum over h <= 8 of
/// E^h in every state, a boulder counted by its condition as train's default counts it): median, 99th percentile and mean (what a run meeting a layout
/// an episode pays on average), and the table's size. What a service computing E for
/// a layout on first sight would pay per layout.
pub(super) fn family_layouts(quick: bool, figs: &mut Vec<Figure>) -> Result<()> {
    use fulcrum_world::family::load_family;
    let f = load_family("toolbox")?;
    let n = if quick { 100 } else { 1000 };
    let (mut ms, mut states) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for seed in 0..n as u64 {
        let t0 = Instant::now();
        let w = f.layout(seed)?;
        let engine = Engine::new(&w, Limits::default())?;
        // The objects train's default form counts (a destroy task's boulder by its
        // condition).
        let set = fulcrum_empowerment::request::potential_objects(&w, None, true)?;
        let e = &w.empowerment;
        let (_, table) = fulcrum_empowerment::request::lookup_table(
            &w,
            &engine,
            None,
            &set,
            e.horizon_unequipped,
            e.horizon_equipped,
            true,
        )?;
        ms.push(t0.elapsed().as_secs_f64() * 1e3);
        ensure!(table.len() == engine.space.len(), "one value per state");
        states.push(table.len() as f64);
    }
    let mean = ms.iter().sum::<f64>() / n as f64;
    ms.sort_by(f64::total_cmp);
    states.sort_by(f64::total_cmp);
    figs.push(Figure {
        zero_ok: false,
        name: "toolbox layout never seen: whole Phi table".into(),
        value: super::percentile(&ms, 0.5),
        unit: "ms",
        note: format!(
            "(median of {n} layouts, p99 {:.2} ms, mean {mean:.2} ms; {:.0}-{:.0} states, table {:.0} KiB at most; goal <= 5 ms)",
            super::percentile(&ms, 0.99),
            states[0],
            states[n - 1],
            states[n - 1] * 4.0 / 1024.0
        ),
    });
    Ok(())
}
