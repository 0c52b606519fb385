"""Two learned estimators of empowerment, trained on a dataset of exact E and scored
against it: how far are the standard bounds from the truth?

    pip install ./python torch
    fulcrum empowerment dataset exp2 --objects agent --horizon 3 --states sample:2000 \\
        --sequences 64 --out exp2-agent-h3.npz
    python examples/python/learned_empowerment.py exp2-agent-h3.npz --estimator variational \\
        --out estimates.csv
    fulcrum empowerment score exp2-agent-h3.npz --estimates estimates.csv

Both read only the dataset: each row's observation (glyphs and flags) and its sampled
action sequences a^h with the projection p = proj_D(s_h) each ends in. Both estimate
I(A^h; P | s), the information the action sequence carries about the objects' outcome,
which is at most E(s) = the channel's capacity (log2 of the number of outcomes in a
deterministic world), with equality only under the best source.

- ``variational`` (Barber and Agakov's bound, as Mohamed and Rezende 2015 use it): a
  source omega(a^h | s) and an inverse model q(a^h | s, p), each a product over the h
  steps of a softmax over the tool's six actions;

      I >= E_{a ~ omega, p ~ T} [ log q(a | s, p) - log omega(a | s) ].

  The dataset holds K uniform sequences a row, so omega and q are renormalised over
  them and the expectation is a sum over the K: the bound of the channel restricted to
  the sampled sequences, which is below E and below log K (an importance-weighted
  expectation over the whole (A_j)^h instead lets omega put its mass off the sample and
  the bound run away). q and omega climb the bound together.
- ``infonce`` (the contrastive bound, van den Oord et al. 2018, as contrastive
  empowerment estimators use it): a critic f(s, a, p) = g(s, a) . e(p) scores each of a
  row's K sequences against the K outcomes of that row;

      I >= (1/K) sum_i [ f(s, a_i, p_i) - log (1/K) sum_j exp f(s, a_i, p_j) ],

  under the uniform source; it cannot exceed log K (log2 K bits).

The estimate of a row is its bound over its own K sequences, in bits; it is written as
a CSV (``row,state,horizon,estimate``) that ``fulcrum empowerment score`` and
``fulcrum.empowerment.score`` read, and that ``fulcrum train --empowerment-from`` trains
on when the dataset holds every state (``--states all``) at the horizons the run uses. The script prints the bound's mean over the rows every
``--log-every`` steps and, at the end, the score.
"""

import argparse
import csv
import math

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

NO_ACTION = 255
LN2 = math.log(2.0)


def load(path):
    """The dataset as tensors: state features (n, d), per-row sequences (n, K, h, 6)
    one-hot actions with a step mask, and (n, K) projection ids."""
    z = np.load(path)
    n = len(z["E"])
    glyphs = torch.as_tensor(z["glyphs"].reshape(n, -1).astype(np.int64))
    n_glyphs = int(glyphs.max()) + 1
    x = torch.cat(
        [F.one_hot(glyphs, n_glyphs).flatten(1).float(), torch.as_tensor(z["flags"]).float()], 1
    )
    rows = z["seq_row"]
    k = len(rows) // n
    if len(rows) != n * k or not (rows.reshape(n, k) == np.arange(n)[:, None]).all():
        raise SystemExit(f"{path}: every row needs the same number of sequences, in row order")
    if k < 2:
        raise SystemExit(f"{path}: {k} sequence a row; make the dataset with --sequences 2 or more")
    tool = z["tool_actions"].tolist()
    acts = z["seq_actions"].reshape(n, k, -1)
    step = torch.as_tensor(acts != NO_ACTION)  # (n, K, h)
    index = np.vectorize(lambda a: tool.index(a) if a != NO_ACTION else 0)(acts)
    a = F.one_hot(torch.as_tensor(index.astype(np.int64)), len(tool)).float()
    a = a * step[..., None]
    proj = torch.as_tensor(z["seq_proj"].reshape(n, k).astype(np.int64))
    return {
        "x": x,
        "a": a,
        "step": step.float(),
        "proj": proj,
        "projections": len(z["proj_key"]),
        "E": z["E"],
        "horizon": z["horizon"],
        "state": z["state"],
    }


def mlp(i, o, hidden):
    return nn.Sequential(nn.Linear(i, hidden), nn.ReLU(), nn.Linear(hidden, hidden), nn.ReLU(), nn.Linear(hidden, o))


class Variational(nn.Module):
    """Source omega(a | s) and inverse model q(a | s, p), per-step softmaxes, each
    renormalised over the row's K sampled sequences."""

    def __init__(self, d, h, n_act, projections, hidden=128):
        super().__init__()
        self.h, self.n_act = h, n_act
        self.source = mlp(d, h * n_act, hidden)
        self.proj = nn.Embedding(projections, hidden)
        self.inverse = mlp(d + hidden, h * n_act, hidden)

    def bound(self, x, a, step, proj):
        """Per-row bound in nats (B,), and the loss, from B rows of K sequences."""
        b, k = proj.shape
        # log omega(a_k | s), renormalised over the row's K sequences.
        log_w = F.log_softmax(self.source(x).view(b, self.h, self.n_act), -1)
        log_omega = torch.einsum("bhc,bkhc->bk", log_w, a)
        log_omega = torch.log_softmax(log_omega, 1)
        # log q(a_j | s, p_k) for every pair, renormalised over j.
        inp = torch.cat([x[:, None].expand(b, k, -1), self.proj(proj)], -1)
        log_q = F.log_softmax(self.inverse(inp).view(b, k, self.h, self.n_act), -1)
        log_q = torch.log_softmax(torch.einsum("bkhc,bjhc->bkj", log_q, a), 2)
        log_q = log_q.diagonal(dim1=1, dim2=2)  # log q(a_k | s, p_k)
        bound = (log_omega.exp() * (log_q - log_omega)).sum(1)
        return bound, -bound.mean()


class InfoNCE(nn.Module):
    """Critic f(s, a, p) = g(s, a) . e(p), scored against a row's K outcomes."""

    def __init__(self, d, h, n_act, projections, hidden=128):
        super().__init__()
        self.g = mlp(d + h * n_act, hidden, hidden)
        self.e = nn.Embedding(projections, hidden)

    def bound(self, x, a, step, proj):
        b, k = proj.shape
        g = self.g(torch.cat([x[:, None].expand(b, k, -1), a.flatten(2)], -1))  # (B, K, H)
        f = torch.einsum("bih,bjh->bij", g, self.e(proj))  # (B, K, K): a_i against p_j
        bound = (f.diagonal(dim1=1, dim2=2) - torch.logsumexp(f, 2) + math.log(k)).mean(1)
        return bound, -bound.mean()


def estimate(model, data, batch=256):
    """Every row's bound in bits."""
    out = []
    with torch.no_grad():
        for i in range(0, len(data["x"]), batch):
            s = slice(i, i + batch)
            out.append(model.bound(data["x"][s], data["a"][s], data["step"][s], data["proj"][s])[0])
    return (torch.cat(out) / LN2).numpy()


def train(data, estimator, steps, batch=64, lr=1e-3, seed=0, log_every=0):
    """Train an estimator on the dataset; returns the model and the mean bound (bits)
    at each logged step."""
    torch.manual_seed(seed)
    n, d = data["x"].shape
    h, n_act = data["a"].shape[2], data["a"].shape[3]
    kind = {"variational": Variational, "infonce": InfoNCE}[estimator]
    model = kind(d, h, n_act, data["projections"])
    opt = torch.optim.Adam(model.parameters(), lr=lr)
    gen = torch.Generator().manual_seed(seed)
    curve = []
    for t in range(1, steps + 1):
        i = torch.randint(0, n, (batch,), generator=gen)
        _, loss = model.bound(data["x"][i], data["a"][i], data["step"][i], data["proj"][i])
        opt.zero_grad()
        loss.backward()
        opt.step()
        if log_every and (t % log_every == 0 or t == steps):
            mean = float(estimate(model, data).mean())
            curve.append((t, mean))
            print(f"step {t:6d}  mean bound {mean:.4f} bits  (mean true E {data['E'].mean():.4f})")
    return model, curve


def write_estimates(path, data, est):
    """The estimates as `row,state,horizon,estimate`: `fulcrum empowerment score` reads
    the rows, `fulcrum train --empowerment-from` the states (hex of the packed bytes)."""
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["row", "state", "horizon", "estimate"])
        for i, v in enumerate(est):
            w.writerow([i, bytes(data["state"][i]).hex(), int(data["horizon"][i]), f"{v:.6f}"])


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("dataset", help="an .npz of `fulcrum empowerment dataset`")
    p.add_argument("--estimator", choices=["variational", "infonce"], default="variational")
    p.add_argument("--steps", type=int, default=3000)
    p.add_argument("--batch", type=int, default=64, help="rows per step (each with its K sequences)")
    p.add_argument("--lr", type=float, default=1e-3)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--log-every", type=int, default=500)
    p.add_argument("--out", default="estimates.csv", help="the estimates, row,state,horizon,estimate (bits)")
    args = p.parse_args()
    torch.set_num_threads(max(1, torch.get_num_threads()))
    data = load(args.dataset)
    model, _ = train(data, args.estimator, args.steps, args.batch, args.lr, args.seed, args.log_every)
    est = estimate(model, data)
    write_estimates(args.out, data, est)
    try:
        from fulcrum import empowerment

        s = empowerment.score(est, args.dataset)
        rho = "-" if s["spearman"] is None else f"{s['spearman']:.3f}"
        print(f"wrote {args.out}: MAE {s['mae']:.4f} bits, bias {s['bias']:+.4f}, Spearman {rho}")
    except ImportError:
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
