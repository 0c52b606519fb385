//! Timing harness for `local::update` (the `fulcrum bench` figure "learner samples x
//! epochs/s"): one PPO update with CleanRL defaults on exp1-tree observations.
//!
//! `cargo run --release -p fulcrum-learner --example update_speed -- [N] [REPS]`
//! (N samples per update, default 512; REPS timed updates, default 11; median printed).
//! Wall-clock times on a shared 2-core VM drift by up to 2x over minutes: compare
//! variants by interleaved runs.
//!
//! - `OLD=1`: time the candle-autograd update the fused one replaced (kept here as
//!   `update_candle`, with candle-op Adam), single-threaded with `RAYON_NUM_THREADS=1
//!   CANDLE_NUM_THREADS=1`.
//! - `PHASES=1`: split the time of an update into its phases (for the fused one: data
//!   preparation, loading, gradient, clipping + Adam, storing; for `OLD=1`: forward +
//!   loss, backward + clipping, Adam).
//! - `TREND=1`: print every update's time and stats, then the number of subnormal
//!   weights and moments and a hash of the weights.

#[global_allocator]
static ALLOC: mimalloc::MiMalloc = mimalloc::MiMalloc;

use std::time::Instant;

use candle_core::{Device, Result, Tensor};
use fulcrum_learner::adam::Adam;
use fulcrum_learner::diagnostics::Stats;
use fulcrum_learner::local::{update, UpdateData};
use fulcrum_learner::net::Net;
use fulcrum_learner::ppo::{clipped_grads, loss, Minibatch};
use fulcrum_shared::layout::shape_for;
use fulcrum_shared::load_world;
use fulcrum_shared::ppo_config::PpoConfig;
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
    let shape = shape_for(&w, 64);
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
    let old = std::env::var("OLD").is_ok_and(|v| v == "1");
    if !old && std::env::var("PHASES").is_ok_and(|v| v == "1") {
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
    let update = if old { update_candle } else { update };
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
        "{} n {n}: update median {med:.3} ms (min {:.3}, max {:.3}) -> {:.0} samples x epochs/s; {:?}",
        if old { "candle" } else { "fused" },
        ms[0],
        ms[ms.len() - 1],
        (n * cfg.epochs) as f64 / (med / 1e3),
        last.unwrap()
    );
}

/// Adam as candle ops (the implementation before the fused one).
fn adam_candle(adam: &mut Adam, net: &Net, grads: &[Tensor], lr: f64) -> Result<()> {
    const B1: f64 = 0.9;
    const B2: f64 = 0.999;
    const EPS: f64 = 1e-5;
    adam.step += 1;
    let t = adam.step as i32;
    let (c1, c2) = (1.0 - B1.powi(t), 1.0 - B2.powi(t));
    for (i, ((_, var), g)) in net.params.iter().zip(grads).enumerate() {
        adam.m[i] = ((&adam.m[i] * B1)? + (g * (1.0 - B1))?)?;
        adam.v[i] = ((&adam.v[i] * B2)? + (g.sqr()? * (1.0 - B2))?)?;
        let mhat = (&adam.m[i] / c1)?;
        let denom = ((&adam.v[i] / c2)?.sqrt()? + EPS)?;
        let upd = ((mhat / denom)? * lr)?;
        var.set(&(var.as_tensor() - upd)?)?;
    }
    Ok(())
}

/// The candle-autograd update (before the fused one).
fn update_candle(
    net: &Net,
    adam: &mut Adam,
    cfg: &PpoConfig,
    lr: f64,
    rng: &mut ChaCha8Rng,
    d: &UpdateData,
) -> Result<Stats> {
    let n = d.actions.len();
    let (c, f) = (net.shape.cells, net.shape.flags);
    let mb = n / cfg.minibatches.max(1);
    let mut idx: Vec<usize> = (0..n).collect();
    let mut sum = Stats::default();
    let mut count = 0;
    let dev = net.device().clone();
    let t_start = Instant::now();
    let mut times = [0.0f64; 3];
    for _ in 0..cfg.epochs {
        idx.shuffle(rng);
        for chunk in idx.chunks(mb.max(1)) {
            let g: Vec<u8> = chunk
                .iter()
                .flat_map(|&i| d.glyphs[i * c..(i + 1) * c].iter().copied())
                .collect();
            let fl: Vec<u8> = chunk
                .iter()
                .flat_map(|&i| d.flags[i * f..(i + 1) * f].iter().copied())
                .collect();
            let pick_f = |v: &[f32]| {
                Tensor::from_vec(
                    chunk.iter().map(|&i| v[i]).collect::<Vec<f32>>(),
                    chunk.len(),
                    &dev,
                )
            };
            let obs = net.batch(&g, &fl)?;
            let actions = Tensor::from_vec(
                chunk.iter().map(|&i| d.actions[i]).collect::<Vec<u32>>(),
                chunk.len(),
                &dev,
            )?;
            let (old_lp, adv, ret, old_v) = (
                pick_f(d.logprobs)?,
                pick_f(d.advantages)?,
                pick_f(d.returns)?,
                pick_f(d.values)?,
            );
            let batch = Minibatch {
                obs: &obs,
                actions: &actions,
                old_logprob: &old_lp,
                advantages: &adv,
                returns: &ret,
                old_values: &old_v,
                logit_bias: None,
                int: None,
            };
            let t0 = Instant::now();
            let (l, s) = loss(net, &batch, cfg)?;
            let t1 = Instant::now();
            let (grads, _) = clipped_grads(net, &l, cfg.max_grad_norm)?;
            let t2 = Instant::now();
            adam_candle(adam, net, &grads, lr)?;
            let t3 = Instant::now();
            times[0] += (t1 - t0).as_secs_f64() * 1e3;
            times[1] += (t2 - t1).as_secs_f64() * 1e3;
            times[2] += (t3 - t2).as_secs_f64() * 1e3;
            sum.policy_loss += s.policy_loss;
            sum.value_loss += s.value_loss;
            sum.entropy += s.entropy;
            sum.approx_kl += s.approx_kl;
            sum.clip_frac += s.clip_frac;
            count += 1;
        }
    }
    if std::env::var("PHASES").is_ok_and(|v| v == "1") {
        println!(
            "candle update {:.3} ms: forward+loss {:.3} ms, backward+clip {:.3} ms, adam {:.3} ms",
            t_start.elapsed().as_secs_f64() * 1e3,
            times[0],
            times[1],
            times[2]
        );
    }
    let k = count.max(1) as f32;
    Ok(Stats {
        policy_loss: sum.policy_loss / k,
        value_loss: sum.value_loss / k,
        entropy: sum.entropy / k,
        approx_kl: sum.approx_kl / k,
        clip_frac: sum.clip_frac / k,
    })
}
