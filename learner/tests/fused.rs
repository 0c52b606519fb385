//! The fused update ([`fulcrum_learner::fused`]) against candle's autograd: the same
//! losses, diagnostics and gradients to rounding, the same update as the candle loss,
//! gradient clipping and Adam, and the same bits from every compiled variant.

use candle_core::{Device, Tensor};
use fulcrum_contracts::layout::NetShape;
use fulcrum_contracts::layout::Offsets;
use fulcrum_contracts::ppo_config::PpoConfig;
use fulcrum_learner::adam::Adam;
use fulcrum_learner::fused::{Data, Learner};
use fulcrum_learner::net::{logprob_entropy, mask_bias, Net};
use fulcrum_learner::ppo::{clipped_grads, loss, Minibatch};
use fulcrum_learner::preset::Preset;
use fulcrum_learner::simd::Simd;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
struct Rollout {
    glyphs: Vec<u8>,
    flags: Vec<u8>,
    actions: Vec<u32>,
    logprobs: Vec<f32>,
    values: Vec<f32>,
    advantages: Vec<f32>,
    returns: Vec<f32>,
}

/// Observations: grids that differ from one random grid in a few cells (as a world's
/// observations do), every fourth one random throughout (summed directly); old
/// log-probs and values near the network's own so that ratios fall inside and outside
/// the clip range, and values on both sides of the value clip.
fn rollout(net: &Net, n: usize, seed: u64) -> Rollout {
    let s = net.shape;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let grid: Vec<u8> = (0..s.cells)
        .map(|_| rng.random_range(0..s.glyphs as u8))
        .collect();
    let mut glyphs = Vec::with_capacity(n * s.cells);
    for i in 0..n {
        let mut g = grid.clone();
        if i % 4 == 3 {
            g.iter_mut()
                .for_each(|x| *x = rng.random_range(0..s.glyphs as u8));
        } else {
            for _ in 0..3 {
                g[rng.random_range(0..s.cells)] = rng.random_range(0..s.glyphs as u8);
            }
        }
        glyphs.extend(g);
    }
    let flags: Vec<u8> = (0..n * s.flags).map(|_| rng.random_range(0..2u8)).collect();
    let actions: Vec<u32> = (0..n)
        .map(|_| rng.random_range(0..s.actions as u32))
        .collect();
    let obs = net.batch(&glyphs, &flags).unwrap();
    let (logits, value) = net.forward(&obs).unwrap();
    let at = Tensor::from_slice(&actions, n, &Device::Cpu).unwrap();
    let (lp, _) = logprob_entropy(&logits, &at).unwrap();
    let lp: Vec<f32> = lp.to_vec1().unwrap();
    let value: Vec<f32> = value.to_vec1().unwrap();
    Rollout {
        logprobs: lp
            .iter()
            .map(|x| x + rng.random_range(-0.4f32..0.4))
            .collect(),
        values: value
            .iter()
            .map(|x| x + rng.random_range(-0.5f32..0.5))
            .collect(),
        advantages: (0..n).map(|_| rng.random_range(-2.0f32..2.0)).collect(),
        returns: (0..n).map(|_| rng.random_range(-1.0f32..1.0)).collect(),
        glyphs,
        flags,
        actions,
    }
}

fn shapes() -> Vec<NetShape> {
    vec![
        NetShape {
            cells: 6,
            glyphs: 4,
            flags: 3,
            hidden: 5,
            actions: 4,
            int_value: false,
        },
        NetShape {
            cells: 20,
            glyphs: 7,
            flags: 4,
            hidden: 40,
            actions: 6,
            int_value: false,
        },
        NetShape {
            cells: 30,
            glyphs: 9,
            flags: 6,
            hidden: 64,
            actions: 7,
            int_value: false,
        },
    ]
}

fn close(a: f32, b: f32, tol: f32) -> bool {
    (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
}

#[test]
fn gradient_and_stats_match_candle_autograd() {
    check_gradient(false, PpoConfig::default());
    // CleanRL's exact setting: no advantage floor.
    check_gradient(false, Preset::CleanRl.ppo());
}

/// The RLlib preset's loss: advantages as given (normalised over the batch before),
/// RLlib's value loss `min((v - R)^2, 10)`, the KL penalty; with and without the mask.
#[test]
fn rllib_gradient_and_stats_match_candle_autograd() {
    let cfg = PpoConfig {
        // Small enough that some squared errors exceed it (both sides of the min).
        vf_loss_clip: 0.3,
        ..Preset::Rllib.ppo()
    };
    check_gradient(false, cfg);
    check_gradient(true, cfg);
}

/// With the action mask: the candle path adds `MASKED_LOGIT` to the removed actions'
/// logits (probability exactly 0), the fused path skips them; entropy, log-probs and
/// every gradient agree, and the removed actions' logits get no gradient.
#[test]
fn masked_gradient_and_stats_match_candle_autograd() {
    check_gradient(true, PpoConfig::default());
}

/// Redraw a rollout's actions among those its flags allow (with the masked
/// distribution's log-probs, perturbed as `rollout` does).
fn mask_rollout(net: &Net, r: &mut Rollout, seed: u64) {
    let s = net.shape;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for (i, a) in r.actions.iter_mut().enumerate() {
        let m = fulcrum_world::mask::action_mask(&r.flags[i * s.flags..(i + 1) * s.flags]);
        let ok: Vec<u32> = (0..s.actions as u32).filter(|&k| m >> k & 1 == 1).collect();
        *a = ok[rng.random_range(0..ok.len())];
    }
    let n = r.actions.len();
    let dev = Device::Cpu;
    let obs = net.batch(&r.glyphs, &r.flags).unwrap();
    let bias = mask_bias(&r.flags, s.flags, s.actions, &dev).unwrap();
    let logits = (net.forward(&obs).unwrap().0 + bias).unwrap();
    let at = Tensor::from_slice(&r.actions, n, &dev).unwrap();
    let lp: Vec<f32> = logprob_entropy(&logits, &at).unwrap().0.to_vec1().unwrap();
    r.logprobs = lp
        .iter()
        .map(|x| x + rng.random_range(-0.4f32..0.4))
        .collect();
}

/// Two value heads: the intrinsic head's clipped value loss against its own returns
/// adds to the extrinsic one's; every gradient (the new head's included) agrees.
#[test]
fn intrinsic_value_head_gradient_matches_candle_autograd() {
    check_gradient_heads(false, PpoConfig::default(), true);
    check_gradient_heads(true, Preset::Rllib.ppo(), true);
}

fn check_gradient(masked: bool, cfg: PpoConfig) {
    check_gradient_heads(masked, cfg, false);
}

fn check_gradient_heads(masked: bool, cfg: PpoConfig, int_value: bool) {
    let dev = Device::Cpu;
    for (k, shape) in shapes().into_iter().enumerate() {
        let shape = NetShape { int_value, ..shape };
        // The first shape is no world's (flags != 2n + 2): its mask allows all.
        if masked && k == 0 {
            continue;
        }
        let net = Net::new(shape, 7 + k as u64, &dev).unwrap();
        let n = 37;
        let mut r = rollout(&net, n, 100 + k as u64);
        if masked {
            mask_rollout(&net, &mut r, 300 + k as u64);
        }
        let bias = mask_bias(&r.flags, shape.flags, shape.actions, &dev).unwrap();
        // The intrinsic head's old values and returns, on both sides of the clip.
        let mut irng = ChaCha8Rng::seed_from_u64(500 + k as u64);
        let (vals_int, rets_int): (Vec<f32>, Vec<f32>) = if int_value {
            let obs = net.batch(&r.glyphs, &r.flags).unwrap();
            let vi: Vec<f32> = net.forward_all(&obs).unwrap().2.unwrap().to_vec1().unwrap();
            (
                vi.iter()
                    .map(|x| x + irng.random_range(-0.5f32..0.5))
                    .collect(),
                (0..n).map(|_| irng.random_range(-1.0f32..1.0)).collect(),
            )
        } else {
            (Vec::new(), Vec::new())
        };
        let (ovi, rti) = (
            Tensor::from_slice(&vals_int, vals_int.len(), &dev).unwrap(),
            Tensor::from_slice(&rets_int, rets_int.len(), &dev).unwrap(),
        );
        // Candle: loss and unclipped gradient.
        let t = |v: &[f32]| Tensor::from_slice(v, v.len(), &dev).unwrap();
        let obs = net.batch(&r.glyphs, &r.flags).unwrap();
        let at = Tensor::from_slice(&r.actions, n, &dev).unwrap();
        let (olp, adv, ret, ov) = (
            t(&r.logprobs),
            t(&r.advantages),
            t(&r.returns),
            t(&r.values),
        );
        let mb = Minibatch {
            obs: &obs,
            actions: &at,
            old_logprob: &olp,
            advantages: &adv,
            returns: &ret,
            old_values: &ov,
            logit_bias: masked.then_some(&bias),
            int: int_value.then_some((&rti, &ovi)),
        };
        let (l, want) = loss(&net, &mb, &cfg).unwrap();
        let (grads, want_norm) = clipped_grads(&net, &l, f32::MAX).unwrap();
        let want_g: Vec<f32> = grads
            .iter()
            .flat_map(|g| g.flatten_all().unwrap().to_vec1::<f32>().unwrap())
            .collect();
        assert!(want.clip_frac > 0.0 && want.clip_frac < 1.0, "{want:?}");
        // Fused.
        let data = Data::new(
            shape,
            &r.glyphs,
            &r.flags,
            &r.actions,
            &r.logprobs,
            &r.values,
            &r.advantages,
            &r.returns,
        )
        .unwrap()
        .with_action_mask(masked)
        .unwrap();
        let data = if int_value {
            data.with_intrinsic(&vals_int, &rets_int).unwrap()
        } else {
            data
        };
        assert!(data.differing_cells() > 0);
        assert!(data.dense_samples() > 0 && data.dense_samples() < n);
        let mut fl = Learner::load(&net, &Adam::new(&net).unwrap()).unwrap();
        let idx: Vec<usize> = (0..n).collect();
        let got = fl.gradient(&data, &idx, &cfg);
        for (a, b) in [
            (got.policy_loss, want.policy_loss),
            (got.value_loss, want.value_loss),
            (got.entropy, want.entropy),
            (got.approx_kl, want.approx_kl),
            (got.clip_frac, want.clip_frac),
        ] {
            assert!(close(a, b, 1e-5), "{got:?} vs {want:?}");
        }
        assert_eq!(fl.g.len(), want_g.len());
        let scale = want_g.iter().fold(0.0f32, |m, x| m.max(x.abs()));
        for (i, (a, b)) in fl.g.iter().zip(&want_g).enumerate() {
            assert!(
                (a - b).abs() <= 1e-5 * scale,
                "shape {k}, grad {i}: {a} vs {b} (max |g| {scale})"
            );
        }
        if masked {
            // An action removed in every sample gets no gradient at its bias.
            let o = Offsets::new(shape);
            let removed = (0..n).fold(u32::MAX, |m, i| {
                m & !fulcrum_world::mask::action_mask(
                    &r.flags[i * shape.flags..(i + 1) * shape.flags],
                )
            });
            for a in (0..shape.actions).filter(|&a| removed >> a & 1 == 1) {
                assert_eq!(fl.g[o.bp + a], 0.0, "shape {k}, action {a}");
            }
        }
        let norm = fl.clip_and_step(f32::MAX, 0.0);
        assert!(close(norm, want_norm, 1e-5), "{norm} vs {want_norm}");
    }
}

#[test]
fn update_matches_candle_loss_clipping_and_adam() {
    let dev = Device::Cpu;
    for (k, shape) in shapes().into_iter().enumerate() {
        let a = Net::new(shape, 21 + k as u64, &dev).unwrap();
        let b = Net::new(shape, 21 + k as u64, &dev).unwrap();
        let (mut adam_a, mut adam_b) = (Adam::new(&a).unwrap(), Adam::new(&b).unwrap());
        let n = 64;
        let cfg = PpoConfig::default();
        let mut rng_a = ChaCha8Rng::seed_from_u64(5);
        let mut rng_b = ChaCha8Rng::seed_from_u64(5);
        // Two rollouts: the second uses rows the first did not and leaves rows that
        // only have moments from the first.
        for u in 0..2 {
            let r = rollout(&a, n, 200 + 10 * u + k as u64);
            let d = fulcrum_learner::local::UpdateData {
                glyphs: &r.glyphs,
                flags: &r.flags,
                actions: &r.actions,
                logprobs: &r.logprobs,
                values: &r.values,
                advantages: &r.advantages,
                returns: &r.returns,
                action_mask: false,
                int: None,
            };
            fulcrum_learner::local::update(&a, &mut adam_a, &cfg, 1e-3, &mut rng_a, &d).unwrap();
            reference_update(&b, &mut adam_b, &cfg, 1e-3, &mut rng_b, &d);
        }
        assert_eq!(adam_a.step, adam_b.step);
        let (fa, fb) = (a.flat().unwrap(), b.flat().unwrap());
        for (i, (x, y)) in fa.iter().zip(&fb).enumerate() {
            assert!((x - y).abs() < 2e-5, "shape {k}, weight {i}: {x} vs {y}");
        }
        for (ma, mb) in adam_a.m.iter().zip(&adam_b.m) {
            assert_eq!(ma.dims(), mb.dims());
        }
        // The generator advanced alike (same shuffles).
        assert_eq!(rng_a.random::<u64>(), rng_b.random::<u64>());
    }
}

/// The update as candle autograd: `loss`, `clipped_grads`, `Adam::apply`.
fn reference_update(
    net: &Net,
    adam: &mut Adam,
    cfg: &PpoConfig,
    lr: f64,
    rng: &mut ChaCha8Rng,
    d: &fulcrum_learner::local::UpdateData,
) {
    use rand::seq::SliceRandom;
    let n = d.actions.len();
    let (c, f) = (net.shape.cells, net.shape.flags);
    let mb = n / cfg.minibatches.max(1);
    let mut idx: Vec<usize> = (0..n).collect();
    let dev = Device::Cpu;
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
            let pick = |v: &[f32]| {
                let x: Vec<f32> = chunk.iter().map(|&i| v[i]).collect();
                Tensor::from_vec(x, chunk.len(), &dev).unwrap()
            };
            let acts: Vec<u32> = chunk.iter().map(|&i| d.actions[i]).collect();
            let obs = net.batch(&g, &fl).unwrap();
            let at = Tensor::from_vec(acts, chunk.len(), &dev).unwrap();
            let (olp, adv, ret, ov) = (
                pick(d.logprobs),
                pick(d.advantages),
                pick(d.returns),
                pick(d.values),
            );
            let batch = Minibatch {
                obs: &obs,
                actions: &at,
                old_logprob: &olp,
                advantages: &adv,
                returns: &ret,
                old_values: &ov,
                logit_bias: None,
                int: None,
            };
            let (l, _) = loss(net, &batch, cfg).unwrap();
            let (grads, _) = clipped_grads(net, &l, cfg.max_grad_norm).unwrap();
            adam.apply(net, &grads, lr).unwrap();
        }
    }
}

#[test]
fn compiled_variants_give_the_same_bits() {
    let dev = Device::Cpu;
    let shape = shapes()[2];
    let net = Net::new(shape, 3, &dev).unwrap();
    let r = rollout(&net, 48, 9);
    let data = Data::new(
        shape,
        &r.glyphs,
        &r.flags,
        &r.actions,
        &r.logprobs,
        &r.values,
        &r.advantages,
        &r.returns,
    )
    .unwrap();
    let adam = Adam::new(&net).unwrap();
    let idx: Vec<usize> = (0..48).collect();
    let cfg = PpoConfig::default();
    let mut runs = Vec::new();
    for v in [Simd::None, Simd::Avx2, Simd::Avx512] {
        let mut fl = Learner::load(&net, &adam).unwrap();
        if !fl.set_simd(v) {
            continue;
        }
        let mut stats = Vec::new();
        for _ in 0..3 {
            stats.push(fl.gradient(&data, &idx, &cfg));
            fl.clip_and_step(cfg.max_grad_norm, 1e-3);
        }
        runs.push((v, stats, fl.w.clone(), fl.m.clone(), fl.v.clone()));
    }
    // A CPU without AVX2 runs only the baseline: nothing to compare, which must not pass
    // as a comparison.
    assert!(
        runs.len() >= 2,
        "this CPU runs only the baseline variant (no AVX2): the same-bits test compares nothing here; run it on an x86-64 CPU with AVX2"
    );
    for r in &runs[1..] {
        assert_eq!(r.1, runs[0].1, "{:?}", r.0);
        assert!(
            r.2 == runs[0].2 && r.3 == runs[0].3 && r.4 == runs[0].4,
            "{:?}",
            r.0
        );
    }
}
