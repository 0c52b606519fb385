//! Timing harness for `local::update` (the `fulcrum bench` figure "learner samples x
//! epochs/s"): one PPO update with CleanRL defaults on exp1-tree observations.
//!
//! `cargo run --release -p fulcrum-learner --example update_speed -- [N] [REPS]`
//! (N samples per update, default 512; REPS timed updates, default 11; median printed).
//! Wall-clock times on a shared 2-core VM drift by up to 2x over minutes: compare
//! variants by interleaved runs.
//!
//! - `PHASES=1`: split the time of an update into its phases (data preparation,
//!   loading, gradient, clipping + Adam, storing).
//! - `TREND=1`: print every update's time and stats, then the number of subnormal
//!   weights and moments and a hash of the weights.

#[global_allocator]
static ALLOC: mimalloc::MiMalloc = mimalloc::MiMalloc;

use std::time::Instant;

use candle_core::Device;
use fulcrum_contracts::layout::shape_for;
use fulcrum_contracts::ppo_config::PpoConfig;
use fulcrum_learner::adam::Adam;
use fulcrum_learner::local::{update, UpdateData};
use fulcrum_learner::net::Net;
use fulcrum_world::load_world;
use fulcrum_world::View;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(512);
    let reps: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(11);
    let w = load_world("exp1-tree").unwrap();
    let spec = w.obs_spec();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let actions: Vec<u8> = (0..n)
        .map(|_| rng.random_range(0..w.num_actions() as u8))
        .collect();
    let shape = shape_for(&w, View::Full, 64);
    let net = Net::new(shape, 1, &Device::Cpu).unwrap();
    let mut adam = Adam::new(&net).unwrap();
    let mut glyphs = vec![0u8; n * spec.cells()];
    let mut flags = vec![0u8; n * spec.flags];
    let mut ep = w.reset();
    for i in 0..n {
        let out = w.env_step(&mut ep, actions[i]);
        if out.terminated || out.truncated {
            ep = w.reset();
        }
        w.observe(
            &ep.state,
            &mut glyphs[i * spec.cells()..(i + 1) * spec.cells()],
            &mut flags[i * spec.flags..(i + 1) * spec.flags],
        );
    }
    let acts: Vec<u32> = actions.iter().map(|&a| a as u32).collect();
    let lp = vec![-(w.num_actions() as f32).ln(); n];
    let vals = vec![0.0f32; n];
    let adv: Vec<f32> = (0..n)
        .map(|i| ((i * 37) % 11) as f32 / 10.0 - 0.5)
        .collect();
    let ret = adv.clone();
    let cfg = PpoConfig::default();
    let data = UpdateData {
        glyphs: &glyphs,
        flags: &flags,
        actions: &acts,
        logprobs: &lp,
        values: &vals,
        advantages: &adv,
        returns: &ret,
        action_mask: false,
        int: None,
    };
    let prep =
        fulcrum_learner::fused::Data::new(shape, &glyphs, &flags, &acts, &lp, &vals, &adv, &ret)
            .unwrap();
    eprintln!(
        "{} samples: {} dense, {:.2} differing cells per sparse sample",
        n,
        prep.dense_samples(),
        prep.differing_cells() as f64 / (n - prep.dense_samples()).max(1) as f64
    );
    if std::env::var("PHASES").is_ok_and(|v| v == "1") {
        // Time the fused update's phases: as `update`, with clocks between them.
        let mb = n / cfg.minibatches;
        let mut idx: Vec<usize> = (0..n).collect();
        let (mut tg, mut ta) = (Vec::new(), Vec::new());
        let (mut t_data, mut t_load, mut t_store, mut t_all) = (0.0, 0.0, 0.0, 0.0);
        for _ in 0..reps {
            let t00 = Instant::now();
            let prep = fulcrum_learner::fused::Data::new(
                shape, &glyphs, &flags, &acts, &lp, &vals, &adv, &ret,
            )
            .unwrap();
            let t01 = Instant::now();
            let mut fl = fulcrum_learner::fused::Learner::load(&net, &adam).unwrap();
            let t02 = Instant::now();
            for _ in 0..cfg.epochs {
                idx.shuffle(&mut rng);
                for chunk in idx.chunks(mb) {
                    let t0 = Instant::now();
                    std::hint::black_box(fl.gradient(&prep, chunk, &cfg));
                    let t1 = Instant::now();
                    fl.clip_and_step(cfg.max_grad_norm, 2.5e-4);
                    tg.push((t1 - t0).as_secs_f64() * 1e6);
                    ta.push(t1.elapsed().as_secs_f64() * 1e6);
                }
            }
            let t03 = Instant::now();
            fl.store(&net, &mut adam).unwrap();
            let t04 = Instant::now();
            t_data += (t01 - t00).as_secs_f64() * 1e6 / reps as f64;
            t_load += (t02 - t01).as_secs_f64() * 1e6 / reps as f64;
            t_store += (t04 - t03).as_secs_f64() * 1e6 / reps as f64;
            t_all += (t04 - t00).as_secs_f64() * 1e3 / reps as f64;
        }
        let (sg, sa): (f64, f64) = (tg.iter().sum(), ta.iter().sum());
        println!(
            "update mean {t_all:.3} ms: data {t_data:.0} us, load {t_load:.0} us, store {t_store:.0} us, gradient {:.0} us, clip+adam {:.0} us (means per update)",
            sg / reps as f64,
            sa / reps as f64
        );
        tg.sort_by(|a, b| a.partial_cmp(b).unwrap());
        ta.sort_by(|a, b| a.partial_cmp(b).unwrap());
        println!(
            "per minibatch of {mb}: gradient {:.1} us, clip+adam {:.1} us (medians of {})",
            tg[tg.len() / 2],
            ta[ta.len() / 2],
            tg.len()
        );
        return;
    }
    // One warm-up update.
    update(&net, &mut adam, &cfg, 2.5e-4, &mut rng, &data).unwrap();
    let mut ms = Vec::with_capacity(reps);
    let mut last = None;
    for _ in 0..reps {
        let t0 = Instant::now();
        let s = update(&net, &mut adam, &cfg, 2.5e-4, &mut rng, &data).unwrap();
        ms.push(t0.elapsed().as_secs_f64() * 1e3);
        if std::env::var("TREND").is_ok_and(|v| v == "1") {
            eprintln!("{:.3} ms {:?}", ms[ms.len() - 1], s);
        }
        last = Some(s);
    }
    if std::env::var("TREND").is_ok_and(|v| v == "1") {
        let fl = fulcrum_learner::fused::Learner::load(&net, &adam).unwrap();
        let sub = |x: &[f32]| x.iter().filter(|v| v.is_subnormal()).count();
        let zero = |x: &[f32]| x.iter().filter(|v| **v == 0.0).count();
        eprintln!(
            "subnormal: w {} m {} v {}; zero m {} of {}; weights hash {:x}",
            sub(&fl.w),
            sub(&fl.m),
            sub(&fl.v),
            zero(&fl.m),
            fl.m.len(),
            fl.w.iter()
                .fold(0u64, |h, x| h.rotate_left(5) ^ x.to_bits() as u64)
        );
    }
    ms.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let med = ms[ms.len() / 2];
    println!(
        "fused n {n}: update median {med:.3} ms (min {:.3}, max {:.3}) -> {:.0} samples x epochs/s; {:?}",
        ms[0],
        ms[ms.len() - 1],
        (n * cfg.epochs) as f64 / (med / 1e3),
        last.unwrap()
    );
}
