#!/usr/bin/env python3
"""Reference values for learner/tests/ppo_reference.rs: one PPO update (CleanRL's
ppo.py loss, torch's clip_grad_norm_ and Adam) on a tiny actor-critic, in JAX.

    pip install "jax[cpu]"
    python3 scripts/reference/ppo_update.py

float32 throughout (JAX's default); gradients by jax.grad. The model, the data and the
update are defined here from their description (not from fulcrum's Rust code):

- Inputs (the same formulas in the Rust test, each computed in f64 and cast to f32):
  weights w[i] = 0.3 * sin(0.9 * i + 0.5); N = 12 samples; glyph of sample s at cell c
  (3s + 5c + sc) % 4; flags row s % 5 of FLAG_ROWS; action the k-th allowed one, k = s %
  (number allowed); old log-prob = log-prob under w + 0.3 sin(s); old value = value
  under w + 0.25 sin(2.3 s + 1); return cos(0.9 s); advantage 1.5 sin(0.7 s + 0.2).
- Network (C cells, G glyphs, F flags, H hidden, A actions), parameters in this flat
  order, each row-major: embed (C*G, H), flags.w (F, H), l1.b (H), l2.w (H, H), l2.b (H),
  pi.w (H, A), pi.b (A), v.w (H, 1), v.b (1).
  z1 = l1.b + sum_c embed[c*G + g_c] + f @ flags.w; h1 = relu(z1);
  h2 = relu(h1 @ l2.w + l2.b); logits = h2 @ pi.w + pi.b; value = h2 @ v.w + v.b.
- Action mask (two tools; flags [held0, held1, normal, choosing-tool, dir0, dir1];
  actions N, E, S, W, apply, select0, select1): normal: the moves, and apply if a tool
  is held; choosing-tool: select_k per held tool k; choosing-direction: the moves.
  Masked logits are -inf.
- Loss (CleanRL ppo.py, norm_adv and clip_vloss on), with fulcrum's advantage-std floor
  0.1: A = (adv - mean) / (max(std_unbiased, 0.1) + 1e-8).
- Then global-norm clipping to 0.5 (torch.nn.utils.clip_grad_norm_) and one torch Adam
  step (betas 0.9/0.999, eps 1e-5, zero moments) at lr 1e-2. The gradient's norm is
  about 0.3, under 0.5, so the same is done at max_grad_norm 0.2 (`*_TIGHT`), where
  clipping scales it.

The last part of the output is Rust source (constants) pasted into the test.
"""

import math

import jax
import jax.numpy as jnp
import numpy as np

C, G, F, H, A = 6, 4, 6, 5, 7
N = 12
CLIP, ENT_COEF, VF_COEF, MAX_GRAD_NORM, ADV_STD_FLOOR = 0.2, 0.01, 0.5, 0.5, 0.1
TIGHT_GRAD_NORM = 0.2  # a second max_grad_norm, one that clips this batch's gradient
LR, BETA1, BETA2, ADAM_EPS = 1e-2, 0.9, 0.999, 1e-5
LOGP_SHIFT = 0.3
# Weights w[i] = 0.3 * sin(WEIGHT_FREQ * i + 0.5). At a frequency of 1.7, three of the five
# second-layer units are dead (z2 < 0) in every sample and 139 of the 233 gradient
# entries are 0; at 0.9 every unit of both layers is active in some sample.
WEIGHT_FREQ = 0.9

SHAPES = [
    ("embed", (C * G, H)),
    ("flags_w", (F, H)),
    ("l1_b", (H,)),
    ("l2_w", (H, H)),
    ("l2_b", (H,)),
    ("pi_w", (H, A)),
    ("pi_b", (A,)),
    ("v_w", (H, 1)),
    ("v_b", (1,)),
]
NPARAMS = sum(int(np.prod(s)) for _, s in SHAPES)

FLAG_ROWS = [
    [0, 0, 1, 0, 0, 0],
    [1, 0, 1, 0, 0, 0],
    [1, 1, 0, 1, 0, 0],
    [0, 1, 0, 1, 0, 0],
    [1, 0, 0, 0, 1, 0],
]


def f32(x):
    """A number computed in f64, cast to f32."""
    return np.float32(x)


def unflatten(flat):
    params, off = {}, 0
    for name, shape in SHAPES:
        n = int(np.prod(shape))
        params[name] = flat[off : off + n].reshape(shape)
        off += n
    return params


def flatten(params):
    return jnp.concatenate([params[name].reshape(-1) for name, _ in SHAPES])


def allowed_actions(flags):
    """Bool (A,) of the actions a flag row allows."""
    held0, held1, normal, choosing, dir0, dir1 = flags
    ok = [False] * A
    if normal:
        ok[0:4] = [True] * 4
        ok[4] = bool(held0 or held1)
    elif choosing:
        ok[5], ok[6] = bool(held0), bool(held1)
    elif dir0 or dir1:
        ok[0:4] = [True] * 4
    if not any(ok):
        ok = [True] * A
    return ok


def forward(params, glyphs, flags):
    """glyphs (N, C) int, flags (N, F) f32 -> logits (N, A), values (N,)."""
    rows = jnp.arange(C)[None, :] * G + glyphs  # (N, C)
    z1 = params["l1_b"] + params["embed"][rows].sum(axis=1) + flags @ params["flags_w"]
    h1 = jax.nn.relu(z1)
    z2 = h1 @ params["l2_w"] + params["l2_b"]
    h2 = jax.nn.relu(z2)
    logits = h2 @ params["pi_w"] + params["pi_b"]
    value = (h2 @ params["v_w"] + params["v_b"])[:, 0]
    return logits, value, z1, z2


def logprob_entropy(logits, mask, actions):
    """CleanRL's Categorical(logits=...).log_prob / .entropy, with invalid actions at
    -inf (jnp.where keeps their 0 * -inf terms out of the entropy and its gradient)."""
    masked = jnp.where(mask, logits, -jnp.inf)
    logp_all = jax.nn.log_softmax(masked, axis=-1)
    safe = jnp.where(mask, logp_all, 0.0)
    p = jnp.where(mask, jnp.exp(safe), 0.0)
    entropy = -jnp.sum(jnp.where(mask, p * safe, 0.0), axis=-1)
    logp = jnp.take_along_axis(logp_all, actions[:, None], axis=1)[:, 0]
    return logp, entropy


def ppo_loss(flat, batch):
    """CleanRL ppo.py's loss of one minibatch; returns (loss, aux)."""
    params = unflatten(flat)
    logits, newvalue, _, _ = forward(params, batch["glyphs"], batch["flags"])
    newlogprob, entropy = logprob_entropy(logits, batch["mask"], batch["actions"])
    logratio = newlogprob - batch["logprobs"]
    ratio = jnp.exp(logratio)
    approx_kl = jax.lax.stop_gradient(((ratio - 1) - logratio).mean())
    clipfrac = jax.lax.stop_gradient((jnp.abs(ratio - 1.0) > CLIP).astype(jnp.float32).mean())
    mb_advantages = batch["advantages"]
    std = jnp.maximum(jnp.std(mb_advantages, ddof=1), ADV_STD_FLOOR)
    mb_advantages = (mb_advantages - mb_advantages.mean()) / (std + 1e-8)
    pg_loss1 = -mb_advantages * ratio
    pg_loss2 = -mb_advantages * jnp.clip(ratio, 1 - CLIP, 1 + CLIP)
    pg_loss = jnp.maximum(pg_loss1, pg_loss2).mean()
    v_loss_unclipped = (newvalue - batch["returns"]) ** 2
    v_clipped = batch["values"] + jnp.clip(newvalue - batch["values"], -CLIP, CLIP)
    v_loss_clipped = (v_clipped - batch["returns"]) ** 2
    v_loss_max = jnp.maximum(v_loss_unclipped, v_loss_clipped)
    v_loss = 0.5 * v_loss_max.mean()
    entropy_loss = entropy.mean()
    loss = pg_loss - ENT_COEF * entropy_loss + v_loss * VF_COEF
    aux = dict(
        policy_loss=pg_loss,
        value_loss=v_loss,
        entropy=entropy_loss,
        approx_kl=approx_kl,
        clip_frac=clipfrac,
        ratio=ratio,
        v_diff=newvalue - batch["values"],
        v_unclipped=v_loss_unclipped,
        v_clipped=v_loss_clipped,
    )
    return loss, aux


def clip_grad_norm(g, max_norm):
    """torch.nn.utils.clip_grad_norm_ on one flat gradient."""
    total_norm = jnp.sqrt(jnp.sum(g * g))
    clip_coef = max_norm / (total_norm + 1e-6)
    clip_coef_clamped = jnp.minimum(clip_coef, 1.0)
    return g * clip_coef_clamped, total_norm


def adam_step(w, g, lr, step=1):
    """torch.optim.Adam (single-tensor), from zero moments."""
    exp_avg = jnp.zeros_like(w)
    exp_avg_sq = jnp.zeros_like(w)
    exp_avg = exp_avg + (g - exp_avg) * (1 - BETA1)  # lerp_
    exp_avg_sq = exp_avg_sq * BETA2 + (1 - BETA2) * g * g
    bias_correction1 = 1 - BETA1**step
    bias_correction2 = 1 - BETA2**step
    step_size = lr / bias_correction1
    denom = jnp.sqrt(exp_avg_sq) / math.sqrt(bias_correction2) + ADAM_EPS
    return w - step_size * exp_avg / denom


def inputs(masked):
    w = np.array([f32(0.3 * math.sin(WEIGHT_FREQ * i + 0.5)) for i in range(NPARAMS)], np.float32)
    glyphs = np.array([[(3 * s + 5 * c + s * c) % 4 for c in range(C)] for s in range(N)], np.int32)
    flag_bytes = np.array([FLAG_ROWS[s % 5] for s in range(N)], np.int32)
    if masked:
        mask = np.array([allowed_actions(r) for r in flag_bytes], bool)
    else:
        mask = np.ones((N, A), bool)
    actions = []
    for s in range(N):
        ok = [a for a in range(A) if mask[s, a]]
        actions.append(ok[s % len(ok)])
    actions = np.array(actions, np.int32)
    flags = flag_bytes.astype(np.float32)
    logits0, value0, z1, z2 = forward(unflatten(jnp.asarray(w)), jnp.asarray(glyphs), jnp.asarray(flags))
    logp0, _ = logprob_entropy(logits0, jnp.asarray(mask), jnp.asarray(actions))
    logp0, value0 = np.asarray(logp0), np.asarray(value0)
    logprobs = np.array(
        [f32(float(logp0[s]) + LOGP_SHIFT * math.sin(s)) for s in range(N)], np.float32
    )
    values = np.array([f32(float(value0[s]) + 0.25 * math.sin(2.3 * s + 1)) for s in range(N)], np.float32)
    returns = np.array([f32(math.cos(0.9 * s)) for s in range(N)], np.float32)
    advantages = np.array([f32(1.5 * math.sin(0.7 * s + 0.2)) for s in range(N)], np.float32)
    batch = dict(
        glyphs=jnp.asarray(glyphs),
        flags=jnp.asarray(flags),
        mask=jnp.asarray(mask),
        actions=jnp.asarray(actions),
        logprobs=jnp.asarray(logprobs),
        values=jnp.asarray(values),
        returns=jnp.asarray(returns),
        advantages=jnp.asarray(advantages),
    )
    pre = dict(logp0=logp0, value0=value0, z1=np.asarray(z1), z2=np.asarray(z2), actions=actions)
    return jnp.asarray(w), batch, pre


def rs(x):
    """An f32 as the shortest decimal that reads back as the same f32."""
    x = np.float32(x)
    assert np.isfinite(x)
    s = str(x)
    return s if ("." in s or "e" in s) else s + ".0"


def rust_array(name, xs, ty="f32", fmt=rs):
    """A Rust constant, its elements wrapped to lines of at most 100 characters."""
    xs = np.asarray(xs).reshape(-1)
    lines, line = [], "   "
    for x in xs:
        item = f" {fmt(x)},"
        if len(line) + len(item) > 100:
            lines.append(line)
            line = "   "
        line += item
    lines.append(line)
    body = "\n".join(lines)
    return f"pub const {name}: [{ty}; {len(xs)}] = [\n{body}\n];"


def case(masked):
    tag = "MASKED" if masked else "UNMASKED"
    w, batch, pre = inputs(masked)
    (loss, aux), g = jax.value_and_grad(ppo_loss, has_aux=True)(w, batch)
    assert not np.any(np.isnan(np.asarray(g))), "NaN in the gradient"
    # At max_grad_norm 0.5 (CleanRL's and fulcrum's default) this batch's gradient is
    # not clipped (its norm is about 0.3); at 0.2 it is.
    g_clipped, norm = clip_grad_norm(g, MAX_GRAD_NORM)
    w_new = adam_step(w, g_clipped, LR)
    g_clipped2, _ = clip_grad_norm(g, TIGHT_GRAD_NORM)
    w_new2 = adam_step(w, g_clipped2, LR)
    ratio = np.asarray(aux["ratio"])
    n_clipped = int(np.sum(np.abs(ratio - 1.0) > CLIP))
    print(f"# {tag.lower()} case")
    print(f"actions = {pre['actions'].tolist()}")
    print(f"loss = {float(loss)!r}")
    for k in ["policy_loss", "value_loss", "entropy", "approx_kl", "clip_frac"]:
        print(f"{k} = {float(aux[k])!r}")
    print(f"grad norm before clipping = {float(norm)!r}")
    assert float(norm) < MAX_GRAD_NORM and float(norm) > TIGHT_GRAD_NORM
    print(f"ratios outside the clip range: {n_clipped} of {N}")
    assert 0 < n_clipped < N
    # Margins of the non-smooth decisions (none must sit at rounding distance).
    print(f"min | |ratio - 1| - clip | = {np.min(np.abs(np.abs(ratio - 1.0) - CLIP)):.3g}")
    vd = np.asarray(aux["v_diff"])
    print(f"value clipped in {int(np.sum(np.abs(vd) > CLIP))} of {N}; min | |v - v_old| - clip | = {np.min(np.abs(np.abs(vd) - CLIP)):.3g}")
    vu, vc = np.asarray(aux["v_unclipped"]), np.asarray(aux["v_clipped"])
    outside = np.abs(vd) > CLIP
    if outside.any():
        print(f"min |v_loss_unclipped - v_loss_clipped| where clipped = {np.min(np.abs(vu - vc)[outside]):.3g}")
    print(f"min |z1|, |z2| (ReLU kinks) = {np.min(np.abs(pre['z1'])):.3g}, {np.min(np.abs(pre['z2'])):.3g}")
    alive1, alive2 = (pre["z1"] > 0).any(axis=0), (pre["z2"] > 0).any(axis=0)
    print(f"units active in some sample: layer 1 {int(alive1.sum())} of {H}, layer 2 {int(alive2.sum())} of {H}")
    assert alive1.all() and alive2.all()
    print(f"gradient entries exactly 0: {int(np.sum(np.asarray(g) == 0))} of {NPARAMS}")
    consts = [
        rust_array(f"{tag}_ACTIONS", pre["actions"], "u32", lambda a: str(int(a))),
        rust_array(f"{tag}_LOGP0", pre["logp0"]),
        rust_array(f"{tag}_VALUE0", pre["value0"]),
        rust_array(
            f"{tag}_STATS",
            [aux[k] for k in ["policy_loss", "value_loss", "entropy", "approx_kl", "clip_frac"]],
        ),
        f"pub const {tag}_LOSS: f32 = {rs(loss)};",
        f"pub const {tag}_NORM: f32 = {rs(norm)};",
        rust_array(f"{tag}_GRAD", g_clipped),
        rust_array(f"{tag}_WEIGHTS_AFTER", w_new),
        rust_array(f"{tag}_GRAD_TIGHT", g_clipped2),
        rust_array(f"{tag}_WEIGHTS_AFTER_TIGHT", w_new2),
    ]
    return consts


def main():
    print(f"jax {jax.__version__}, numpy {np.__version__}, backend {jax.default_backend()}")
    print(f"{NPARAMS} parameters")
    consts = case(True) + case(False)
    print("# Rust constants")
    for c in consts:
        print(c)


if __name__ == "__main__":
    main()
