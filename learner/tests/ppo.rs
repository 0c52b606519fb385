//! The learner's pieces against reference numbers computed outside candle.

use candle_core::{Device, Tensor};
use fulcrum_contracts::layout::NetShape;
use fulcrum_contracts::ppo_config::PpoConfig;
use fulcrum_learner::adam::Adam;
use fulcrum_learner::net::{logprob_entropy, Net};
use fulcrum_learner::ppo::{clipped_grads, loss, Minibatch};

fn shape() -> NetShape {
    NetShape {
        cells: 6,
        glyphs: 4,
        flags: 3,
        hidden: 5,
        actions: 4,
        int_value: false,
    }
}

/// Reference (plain Python, kept here):
/// ```python
/// for l, a in zip([[1.0, 2.0, 0.5], [0.0, 0.0, 0.0]], [1, 2]):
///     m = max(l); z = sum(exp(x - m) for x in l); lp = [x - m - log(z) for x in l]
///     print(lp[a], -sum(exp(p) * p for p in lp))
/// ```
#[test]
fn categorical_logprob_and_entropy() {
    let dev = Device::Cpu;
    let logits = Tensor::new(&[[1.0f32, 2.0, 0.5], [0.0, 0.0, 0.0]], &dev).unwrap();
    let actions = Tensor::new(&[1u32, 2], &dev).unwrap();
    let (lp, ent) = logprob_entropy(&logits, &actions).unwrap();
    let (lp, ent): (Vec<f32>, Vec<f32>) = (lp.to_vec1().unwrap(), ent.to_vec1().unwrap());
    let want_lp = [-0.4643687841079449, -1.0986122886681098];
    let want_ent = [0.9059592564792267, 1.0986122886681096];
    for k in 0..2 {
        assert!((lp[k] as f64 - want_lp[k]).abs() < 1e-6, "{lp:?}");
        assert!((ent[k] as f64 - want_ent[k]).abs() < 1e-6, "{ent:?}");
    }
}

fn params(net: &Net) -> Vec<Vec<f32>> {
    net.params
        .iter()
        .map(|(_, v)| v.as_tensor().flatten_all().unwrap().to_vec1().unwrap())
        .collect()
}

/// Forward pass written with plain loops over the one-hot grid: the embedding-sum
/// layer must equal a linear layer on one-hot inputs.
fn reference_forward(net: &Net, glyphs: &[u8], flags: &[u8]) -> (Vec<Vec<f32>>, Vec<f32>) {
    let s = net.shape;
    let p = params(net);
    let (emb, wf, b1, w2, b2, wp, bp, wv, bv) = (
        &p[0], &p[1], &p[2], &p[3], &p[4], &p[5], &p[6], &p[7], &p[8],
    );
    let n = glyphs.len() / s.cells;
    let mut logits = vec![];
    let mut values = vec![];
    for b in 0..n {
        // One-hot x of length C*G, then x @ E.
        let mut x = vec![0.0f32; s.cells * s.glyphs];
        for c in 0..s.cells {
            x[c * s.glyphs + glyphs[b * s.cells + c] as usize] = 1.0;
        }
        let mut h1 = vec![0.0f32; s.hidden];
        for (j, h) in h1.iter_mut().enumerate() {
            let mut acc = b1[j];
            for (i, xi) in x.iter().enumerate() {
                acc += xi * emb[i * s.hidden + j];
            }
            for k in 0..s.flags {
                acc += flags[b * s.flags + k] as f32 * wf[k * s.hidden + j];
            }
            *h = acc.max(0.0);
        }
        let h2: Vec<f32> = (0..s.hidden)
            .map(|j| {
                (b2[j]
                    + (0..s.hidden)
                        .map(|i| h1[i] * w2[i * s.hidden + j])
                        .sum::<f32>())
                .max(0.0)
            })
            .collect();
        logits.push(
            (0..s.actions)
                .map(|a| {
                    bp[a]
                        + (0..s.hidden)
                            .map(|i| h2[i] * wp[i * s.actions + a])
                            .sum::<f32>()
                })
                .collect(),
        );
        values.push(bv[0] + (0..s.hidden).map(|i| h2[i] * wv[i]).sum::<f32>());
    }
    (logits, values)
}

fn sample_obs() -> (Vec<u8>, Vec<u8>) {
    let glyphs = vec![0, 1, 2, 3, 1, 1, 3, 3, 0, 2, 1, 0, 2, 2, 2, 1, 0, 3];
    let flags = vec![1, 0, 1, 0, 1, 0, 0, 0, 1];
    (glyphs, flags)
}

#[test]
fn embedding_sum_equals_the_one_hot_linear_layer() {
    let net = Net::new(shape(), 11, &Device::Cpu).unwrap();
    let (g, f) = sample_obs();
    let (logits, values) = net.forward(&net.batch(&g, &f).unwrap()).unwrap();
    let (rl, rv) = reference_forward(&net, &g, &f);
    let l: Vec<Vec<f32>> = logits.to_vec2().unwrap();
    let v: Vec<f32> = values.to_vec1().unwrap();
    for b in 0..3 {
        assert!(
            (v[b] - rv[b]).abs() < 1e-5,
            "value {b}: {} vs {}",
            v[b],
            rv[b]
        );
        for a in 0..4 {
            assert!((l[b][a] - rl[b][a]).abs() < 1e-5);
        }
    }
    // Same seed, same weights; another seed, others.
    assert_eq!(
        params(&net),
        params(&Net::new(shape(), 11, &Device::Cpu).unwrap())
    );
    assert_ne!(
        params(&net),
        params(&Net::new(shape(), 12, &Device::Cpu).unwrap())
    );
}

#[test]
fn clipped_surrogate_and_value_loss() {
    let dev = Device::Cpu;
    let net = Net::new(shape(), 5, &dev).unwrap();
    let (g, f) = sample_obs();
    let obs = net.batch(&g, &f).unwrap();
    let actions = [0u32, 3, 1];
    // Old log-probs chosen so that the three ratios are inside, above and below the
    // clip range.
    let (rl, rv) = reference_forward(&net, &g, &f);
    let lp_new: Vec<f32> = (0..3)
        .map(|b| {
            let m = rl[b].iter().cloned().fold(f32::MIN, f32::max);
            let z: f32 = rl[b].iter().map(|x| (x - m).exp()).sum();
            rl[b][actions[b] as usize] - m - z.ln()
        })
        .collect();
    let old_lp = [lp_new[0] - 0.1, lp_new[1] - 0.5, lp_new[2] + 0.5];
    let adv = [1.0f32, -2.0, 0.5];
    let ret = [0.3f32, -0.2, 1.0];
    let old_v = [rv[0] + 0.5, rv[1] - 0.05, rv[2]];
    let cfg = PpoConfig::default();
    let t = |v: &[f32]| Tensor::from_slice(v, v.len(), &dev).unwrap();
    let (at, olt, advt, rett, ovt) = (
        Tensor::from_slice(&actions, 3, &dev).unwrap(),
        t(&old_lp),
        t(&adv),
        t(&ret),
        t(&old_v),
    );
    let mb = Minibatch {
        obs: &obs,
        actions: &at,
        old_logprob: &olt,
        advantages: &advt,
        returns: &rett,
        old_values: &ovt,
        logit_bias: None,
        int: None,
    };
    let (total, stats) = loss(&net, &mb, &cfg).unwrap();
    // Reference, scalar by scalar (CleanRL's formulas).
    let mean = adv.iter().sum::<f32>() / 3.0;
    let std = (adv.iter().map(|a| (a - mean).powi(2)).sum::<f32>() / 2.0).sqrt();
    let mut pg = 0.0;
    let mut vl = 0.0;
    for b in 0..3 {
        let a = (adv[b] - mean) / (std + 1e-8);
        let r = (lp_new[b] - old_lp[b]).exp();
        pg += (-a * r).max(-a * r.clamp(0.8, 1.2)) / 3.0;
        let vc = old_v[b] + (rv[b] - old_v[b]).clamp(-0.2, 0.2);
        vl += 0.5 * (rv[b] - ret[b]).powi(2).max((vc - ret[b]).powi(2)) / 3.0;
    }
    assert!(
        (stats.policy_loss - pg).abs() < 1e-5,
        "{} vs {pg}",
        stats.policy_loss
    );
    assert!(
        (stats.value_loss - vl).abs() < 1e-5,
        "{} vs {vl}",
        stats.value_loss
    );
    // Two of the three ratios (e^0.5 and e^-0.5) are outside [0.8, 1.2].
    assert!((stats.clip_frac - 2.0 / 3.0).abs() < 1e-6);
    let t: f32 = total.to_scalar().unwrap();
    assert!((t - (pg - 0.01 * stats.entropy + 0.5 * vl)).abs() < 1e-5);
}

#[test]
fn adam_first_step_and_gradient_clipping() {
    let dev = Device::Cpu;
    let net = Net::new(shape(), 9, &dev).unwrap();
    let (g, f) = sample_obs();
    let (_, values) = net.forward(&net.batch(&g, &f).unwrap()).unwrap();
    let l = values.sqr().unwrap().sum_all().unwrap();
    let (grads, norm) = clipped_grads(&net, &l, 1e-3).unwrap();
    // Clipped to the limit: the global norm of the returned gradients is 1e-3.
    let after: f32 = grads
        .iter()
        .map(|g| {
            g.sqr()
                .unwrap()
                .sum_all()
                .unwrap()
                .to_scalar::<f32>()
                .unwrap()
        })
        .sum::<f32>()
        .sqrt();
    assert!(norm > 1e-3);
    assert!((after - 1e-3).abs() < 1e-6, "{after}");
    // Adam's first step moves each weight by lr * g / (|g| + eps): m_hat = g, v_hat = g^2.
    let before = params(&net);
    let gv: Vec<Vec<f32>> = grads
        .iter()
        .map(|g| g.flatten_all().unwrap().to_vec1().unwrap())
        .collect();
    let mut adam = Adam::new(&net).unwrap();
    adam.apply(&net, &grads, 0.1).unwrap();
    let now = params(&net);
    for (k, p) in now.iter().enumerate() {
        for (i, x) in p.iter().enumerate() {
            let g = gv[k][i];
            let want = before[k][i] - 0.1 * g / (g.abs() + 1e-5);
            assert!((x - want).abs() < 1e-5, "param {k}[{i}]: {x} vs {want}");
        }
    }
    assert_eq!(adam.step, 1);
}
