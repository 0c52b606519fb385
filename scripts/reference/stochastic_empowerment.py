"""Reference values of stochastic object empowerment, by brute force, for the two tiny
worlds of empowerment/tests/reference/ (tiny-axe.toml, tiny-corridor.toml).

Independent of the Rust code: the dynamics of these two maps are written out below
(docs/world.md: moves that slip, tool prompts, a rule that acts with probability p),
every action sequence of length h is followed through every outcome, and the channel
from sequences to proj_D(S_h) goes to Blahut-Arimoto (base 2) until its upper bound
max_x D(W_x || q) and lower bound log2 sum_x p_x 2^D_x are within 1e-12 bits.

Writes empowerment/tests/reference/stochastic_reference.txt: one line per (world, D,
h, state): `world D h x y inventory mode tree bits`.
    python3 scripts/reference/stochastic_empowerment.py
"""
import itertools
import numpy as np

DIRS = [(0, -1), (1, 0), (0, 1), (-1, 0)]
WORLDS = {
    # name: (floor cells, agent start, axe cell or None, tree cell or None, slip, p)
    "tiny-axe": ({(1, 1), (2, 1), (1, 2), (2, 2), (3, 2)}, (1, 1), (2, 1), (3, 1), 0.2, 0.7),
    "tiny-corridor": ({(1, 1), (2, 1), (3, 1), (4, 1)}, (1, 1), None, None, 0.3, 1.0),
}


def walk(w, s, d):
    floor, _, axe, tree, _, _ = w
    x, y, inv, mode, tr = s
    t = (x + DIRS[d][0], y + DIRS[d][1])
    if t == tree and tr == 0:
        return s
    if t not in floor and t != tree:
        return s
    return (t[0], t[1], 1 if t == axe else inv, mode, tr)


def outcomes(w, s, a):
    """[(state, probability)] of action a (0-3 moves, 4 apply, 5 select the axe)."""
    _, _, _, tree, q, p = w
    x, y, inv, mode, tr = s
    if mode == 0:
        if a < 4:
            return [(walk(w, s, d), 1 - q if d == a else q / 3) for d in range(4)]
        return [((x, y, inv, 1, tr) if a == 4 and inv else s, 1.0)]
    if mode == 1:
        return [((x, y, inv, 2 if a == 5 and inv else 0, tr), 1.0)]
    n = (x, y, inv, 0, tr)
    if a < 4 and (x + DIRS[a][0], y + DIRS[a][1]) == tree and tr == 0:
        return [((x, y, inv, 0, 2), p), (n, 1 - p)]
    return [(n, 1.0)]


def capacity(rows):
    w = np.array(rows)
    w = w[:, w.sum(axis=0) > 0]
    px = np.full(len(w), 1.0 / len(w))
    for _ in range(200000):
        q = px @ w
        with np.errstate(divide="ignore", invalid="ignore"):
            d = np.where(w > 0, w * np.log2(w / q), 0.0).sum(axis=1)
        z = px @ np.exp2(d)
        if d.max() - np.log2(z) < 1e-12:
            break
        px = px * np.exp2(d) / z
    return max(np.log2(z), 0.0)


def value(w, s, actions, proj, h):
    rows = []
    for seq in itertools.product(actions, repeat=h):
        dist = {s: 1.0}
        for a in seq:
            nxt = {}
            for t, pt in dist.items():
                for u, pu in outcomes(w, t, a):
                    nxt[u] = nxt.get(u, 0.0) + pt * pu
            dist = nxt
        row = {}
        for t, pt in dist.items():
            row[proj(t)] = row.get(proj(t), 0.0) + pt
        rows.append(row)
    keys = sorted({k for r in rows for k in r})
    return capacity([[r.get(k, 0.0) for k in keys] for r in rows])


def space(w, actions):
    start = (w[1][0], w[1][1], 0, 0, 0)
    seen, todo = {start}, [start]
    while todo:
        s = todo.pop()
        for a in actions:
            for t, pt in outcomes(w, s, a):
                if pt > 0 and t not in seen:
                    seen.add(t)
                    todo.append(t)
    return sorted(seen)


def main():
    lines = []
    cases = [
        ("tiny-axe", "tree", [0, 1, 2, 3, 4, 5], lambda t: t[4]),
        ("tiny-axe", "agent", [0, 1, 2, 3, 4, 5], lambda t: (t[0], t[1])),
        ("tiny-corridor", "agent", [0, 1, 2, 3, 4], lambda t: (t[0], t[1])),
    ]
    for name, dname, actions, proj in cases:
        w = WORLDS[name]
        for h in range(1, 5):
            for s in space(w, actions if name == "tiny-corridor" else [0, 1, 2, 3, 4, 5]):
                v = value(w, s, actions, proj, h)
                lines.append(f"{name} {dname} {h} {s[0]} {s[1]} {s[2]} {s[3]} {s[4]} {v:.12f}")
    with open("empowerment/tests/reference/stochastic_reference.txt", "w") as f:
        f.write("# world D h x y inventory mode tree bits (scripts/reference/stochastic_empowerment.py)\n")
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
