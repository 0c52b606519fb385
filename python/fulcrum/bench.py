"""Throughput of the Python package: ``python -m fulcrum.bench [--quick] [--json]``.

Figures, from alternating repetitions in this one process, one core:

- ``make_vec``: env steps per second of a 64-world vector environment stepped from
  Python with random actions (drawn beforehand with numpy, outside the timing), the
  loop a researcher's rollout would run;
- the same through ``EmpowermentReward`` with the paper's additive bonus
  (``form="additive"``), and with the wrapper's default form (``horizon-potential``),
  and what each adds to a step, in percent;
- the wrapper's default form on a world family (``toolbox``, 16 training layouts, a
  table per layout), against the same vector environment unwrapped;
- MiniGrid's DoorKey-5x5 (a small room with a key and a door, the closest MiniGrid
  task), 64 worlds in gymnasium's synchronous vector environment, stepped the same way,
  and fulcrum's ratio to it, when ``minigrid`` is installed.

``fulcrum bench`` runs this module when the package is importable and adds its figures.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np

import fulcrum
from fulcrum.wrappers import EmpowermentReward

NUM_ENVS = 64
# The training layouts of the family row (`make_vec("toolbox", layouts=...)`).
FAMILY_LAYOUTS = 16


def _rate(env, actions: np.ndarray) -> float:
    """Env steps per second of stepping ``env`` through ``actions`` (T, N)."""
    step = env.step
    t0 = time.perf_counter()
    for a in actions:
        step(a)
    return actions.size / (time.perf_counter() - t0)


def _minigrid():
    try:
        import gymnasium as gym
        import minigrid  # noqa: F401  (registers the MiniGrid environments)
    except ImportError:
        return None
    env = gym.make_vec("MiniGrid-DoorKey-5x5-v0", num_envs=NUM_ENVS, vectorization_mode="sync")
    env.reset(seed=0)
    return env


def run(quick: bool = False) -> dict:
    """The figures. The machine's speed drifts over seconds, so plain and wrapped
    stepping alternate in short blocks: each steps/s figure is the median over its
    blocks, and each overhead is the median of the ratios of adjacent blocks."""
    blocks = 40 if quick else 200
    steps = 500
    rng = np.random.default_rng(0)
    plain = fulcrum.make_vec("exp1-tree", num_envs=NUM_ENVS, seed=0)
    wrapped = EmpowermentReward(
        fulcrum.make_vec("exp1-tree", num_envs=NUM_ENVS, seed=0), form="additive"
    )
    default = EmpowermentReward(fulcrum.make_vec("exp1-tree", num_envs=NUM_ENVS, seed=0))
    n_actions = plain.single_action_space.n
    actions = rng.integers(0, n_actions, size=(steps, NUM_ENVS), dtype=np.int64)
    fam_plain = fulcrum.make_vec("toolbox", num_envs=NUM_ENVS, seed=0, layouts=FAMILY_LAYOUTS)
    fam_default = EmpowermentReward(
        fulcrum.make_vec("toolbox", num_envs=NUM_ENVS, seed=0, layouts=FAMILY_LAYOUTS)
    )
    fam_actions = rng.integers(
        0, fam_plain.single_action_space.n, size=(steps, NUM_ENVS), dtype=np.int64
    )
    _rate(plain, actions), _rate(wrapped, actions), _rate(default, actions)  # warm-up
    _rate(fam_plain, fam_actions), _rate(fam_default, fam_actions)
    p_rates, w_rates, d_rates, w_ratios, d_ratios = [], [], [], [], []
    fp_rates, fd_rates, f_ratios = [], [], []
    for _ in range(blocks):
        p, w, d = _rate(plain, actions), _rate(wrapped, actions), _rate(default, actions)
        p_rates.append(p)
        w_rates.append(w)
        d_rates.append(d)
        w_ratios.append(p / w)
        d_ratios.append(p / d)
        fp, fd = _rate(fam_plain, fam_actions), _rate(fam_default, fam_actions)
        fp_rates.append(fp)
        fd_rates.append(fd)
        f_ratios.append(fp / fd)
    out = {
        "num_envs": NUM_ENVS,
        "world": "exp1-tree",
        "make_vec_steps_per_s": statistics.median(p_rates),
        # The additive bonus: time per wrapped step over time per plain step, minus one.
        "wrapped_steps_per_s": statistics.median(w_rates),
        "wrapper_overhead_percent": (statistics.median(w_ratios) - 1.0) * 100.0,
        # The same for the wrapper's default form.
        "default_form": default.settings.split(":")[0],
        "default_steps_per_s": statistics.median(d_rates),
        "default_overhead_percent": (statistics.median(d_ratios) - 1.0) * 100.0,
        # The default form on a family's layouts, against the family unwrapped.
        "family": f"toolbox, {FAMILY_LAYOUTS} layouts",
        "family_layouts": FAMILY_LAYOUTS,
        "family_steps_per_s": statistics.median(fp_rates),
        "family_default_steps_per_s": statistics.median(fd_rates),
        "family_overhead_percent": (statistics.median(f_ratios) - 1.0) * 100.0,
        "blocks": blocks,
        "steps_per_block": steps * NUM_ENVS,
    }
    mg = _minigrid()
    if mg is not None:
        mg_actions = rng.integers(0, 7, size=(100, NUM_ENVS), dtype=np.int64)
        _rate(mg, mg_actions)
        mg_rates, fulcrum_rates = [], []
        for _ in range(3 if quick else 7):
            mg_rates.append(_rate(mg, mg_actions))
            fulcrum_rates.append(_rate(plain, actions))
        out["minigrid_steps_per_s"] = statistics.median(mg_rates)
        out["ratio_to_minigrid"] = statistics.median(fulcrum_rates) / out["minigrid_steps_per_s"]
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="fewer, shorter repetitions")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    a = p.parse_args()
    r = run(a.quick)
    if a.json:
        print(json.dumps(r))
        return
    print(f"make_vec exp1-tree x {NUM_ENVS}, random actions: {r['make_vec_steps_per_s']:,.0f} env steps/s")
    print(
        f"  with EmpowermentReward, additive: {r['wrapped_steps_per_s']:,.0f} env steps/s "
        f"(+{r['wrapper_overhead_percent']:.1f}% per step)"
    )
    print(
        f"  with EmpowermentReward, {r['default_form']} (its default): "
        f"{r['default_steps_per_s']:,.0f} env steps/s (+{r['default_overhead_percent']:.1f}% per step)"
    )
    print(
        f"make_vec {r['family']} x {NUM_ENVS}: {r['family_steps_per_s']:,.0f} env steps/s; "
        f"with EmpowermentReward, {r['default_form']}: {r['family_default_steps_per_s']:,.0f} "
        f"(+{r['family_overhead_percent']:.1f}% per step)"
    )
    if "minigrid_steps_per_s" in r:
        print(
            f"MiniGrid DoorKey-5x5 x {NUM_ENVS} (sync vector env): "
            f"{r['minigrid_steps_per_s']:,.0f} env steps/s; fulcrum x{r['ratio_to_minigrid']:.0f}"
        )


if __name__ == "__main__":
    main()
