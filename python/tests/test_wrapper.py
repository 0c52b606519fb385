"""EmpowermentReward: R + beta * b on the hand-checked path to the tree of exp1-tree."""

from pathlib import Path

import numpy as np
import pytest
import gymnasium as gym

import fulcrum
from fulcrum.empowerment import value
from fulcrum.wrappers import EmpowermentReward
from test_env import TO_THE_TREE, W

# E(s_{t+1}) along TO_THE_TREE, counted by hand (test_empowerment's trace, without
# t = 0): axe -> tree, h_u 8 / h_e 3.
E_NEXT = [0, 0, 0, 1, 0, 0, 0, 0, 1, 1, 1, 0]
R = [0] * 11 + [1]
BETA = 0.0009  # exp1-tree's [empowerment] beta


def walk(env, actions, other=W):
    out = []
    for a in actions:
        _, r, term, trunc, info = env.step(np.array([a, other]))
        out.append(
            (
                float(r[0]),
                float(info["intrinsic_reward"][0]),
                float(info["empowerment"][0]),
                bool(term[0]),
            )
        )
    return out


def test_the_default_form_is_horizon_potential():
    # The documented default: potential-based shaping with Phi = sum of E^h, beta 0.05
    # (it cannot trap); the paper's additive bonus is form="additive".
    env = EmpowermentReward(fulcrum.make_vec("exp1-tree", num_envs=2))
    assert env.settings.startswith("horizon-potential: beta 0.05, axe -> tree, h 8 unequipped / 3")
    explicit = EmpowermentReward(
        fulcrum.make_vec("exp1-tree", num_envs=2), form="horizon-potential"
    )
    env.reset()
    explicit.reset()
    assert walk(env, TO_THE_TREE) == walk(explicit, TO_THE_TREE)


def test_additive_is_r_plus_beta_e():
    env = EmpowermentReward(fulcrum.make_vec("exp1-tree", num_envs=2), form="additive")
    env.reset()
    got = walk(env, TO_THE_TREE)
    assert [g[2] for g in got] == E_NEXT
    assert [g[1] for g in got] == pytest.approx([BETA * e for e in E_NEXT])
    assert [g[0] for g in got] == pytest.approx([r + BETA * e for r, e in zip(R, E_NEXT)])
    assert env.settings.startswith("additive: beta 0.0009, axe -> tree, h 8 unequipped / 3")
    # The autoreset step pays nothing.
    _, r, _, _, info = env.step(np.array([W, W]))
    assert float(r[0]) == 0.0 and float(info["intrinsic_reward"][0]) == 0.0


def test_potential_shaping_telescopes_by_hand():
    g = 0.9
    env = EmpowermentReward(
        fulcrum.make_vec("exp1-tree", num_envs=2), form="potential", beta=1.0, gamma=g
    )
    env.reset()
    got = walk(env, TO_THE_TREE)
    phi = [0] + E_NEXT  # E(s_0) = 0
    want = [g * phi[t + 1] - phi[t] for t in range(11)] + [-phi[11]]  # terminal: 0
    assert [x[1] for x in got] == pytest.approx(want)


@pytest.mark.parametrize("form", ["potential", "horizon-potential"])
def test_the_potential_forms_through_many_episodes_match_numpy(form):
    # b_t = gamma Phi(s_{t+1}) - Phi(s_t), 0 potential when terminal, nothing paid on the
    # autoreset step, Phi(s_0) after every reset, recomputed here from the values the
    # wrapper reports. Over the agent's cell, whose E is positive everywhere (terminal
    # states too), at h = 3: Phi(s_0) from the brute force over all action sequences
    # (E^1 = 2 bits by hand: stay, north, south, east). World 0 plays TO_THE_TREE and its
    # autoreset step again and again (terminations); the others act at random and reach
    # the 100-step limit (truncations).
    n, g, beta = 8, 0.9, 2.0
    world = fulcrum.World("exp1-tree")
    e = [
        value(world, world.initial_state, tool="axe", objects="agent", horizon=h, method="enumerate")
        for h in (1, 2, 3)
    ]
    assert e[0] == 2.0
    phi0 = e[2] if form == "potential" else sum(e)
    env = EmpowermentReward(
        fulcrum.make_vec("exp1-tree", num_envs=n),
        form=form,
        beta=beta,
        gamma=g,
        tool="axe",
        objects="agent",
        horizons=3,
    )
    env.reset()
    rng = np.random.default_rng(0)
    script = TO_THE_TREE + [W]
    phi = np.full(n, phi0)
    starts = np.zeros(n, dtype=bool)  # this step is an autoreset step
    terms = truncs = 0
    for t in range(1300):
        a = rng.integers(0, env.single_action_space.n, size=n)
        a[0] = script[t % len(script)]
        _, r, term, trunc, info = env.step(a)
        v = info["empowerment"].astype(np.float64)
        want = np.where(starts, 0.0, beta * (g * np.where(term, 0.0, v) - phi))
        assert np.allclose(info["intrinsic_reward"], want, atol=1e-5), t
        assert np.allclose(r, env.unwrapped._core.reward + want, atol=1e-5), t
        assert not v[starts].any() and v[~starts].all(), t
        phi = np.where(starts | term | trunc, phi0, v)
        starts = term | trunc
        terms += int(term.sum())
        truncs += int(trunc.sum())
    assert terms >= 100 and truncs >= (n - 1) * 12


def test_first_visit_pays_once_per_inventory():
    env = EmpowermentReward(fulcrum.make_vec("exp1-tree", num_envs=2), form="first-visit")
    env.reset()
    got = walk(env, TO_THE_TREE)
    # Without the axe, E > 0 first at t = 4; with it, at t = 9; nothing after.
    want = [0, 0, 0, 0.1, 0, 0, 0, 0, 0.1, 0, 0, 0]
    assert [x[1] for x in got] == pytest.approx(want)


def test_count_pays_one_over_root_visits():
    env = EmpowermentReward(fulcrum.make_vec("exp1-tree", num_envs=1), form="count", beta=1.0)
    env.reset()
    seq = [0, 2, 0, 2]  # N, S, N, S: (1,3), (1,4), (1,3), (1,4)
    got = []
    for a in seq:
        _, _, _, _, info = env.step(np.array([a]))
        got.append(float(info["intrinsic_reward"][0]))
    assert got == pytest.approx([1.0, 1.0, 2**-0.5, 2**-0.5])


def test_explicit_tool_objects_and_horizons():
    # The wall with the pickaxe, one horizon everywhere: standing next to the wall
    # holding the pickaxe, it can be dug within 3 steps.
    env = EmpowermentReward(
        fulcrum.make_vec("exp1-tree", num_envs=1),
        form="additive",
        tool="pickaxe",
        objects=["wall"],
        horizons=3,
        beta=1.0,
    )
    assert "pickaxe -> wall, h 3 unequipped / 3 equipped" in env.settings
    env.reset()
    # (1,4) -> (4,6) picks up the pickaxe, then east to (8,6), next to the wall at (9,6).
    path = [2, 2, 1, 1, 1, 1, 1, 1, 1]
    for a in path:
        _, r, _, _, info = env.step(np.array([a]))
    assert env.unwrapped.describe(0).startswith("agent=8,6 holding=pickaxe")
    assert float(info["empowerment"][0]) == 1.0 and float(r[0]) == 1.0


def test_over_other_wrappers_the_reward_they_return_gets_the_bonus():
    base = fulcrum.make_vec("exp1-tree", num_envs=2)
    inner = gym.wrappers.vector.TransformReward(base, lambda r: 10 * r)
    env = EmpowermentReward(inner, form="additive")
    env.reset()
    got = walk(env, TO_THE_TREE)
    assert got[-1][0] == pytest.approx(10.0 + 0.0)
    assert got[8][0] == pytest.approx(BETA)


def test_bad_settings_raise_value_error_with_the_cli_sentence():
    env = fulcrum.make_vec("exp1-tree", num_envs=1)
    with pytest.raises(ValueError, match="unknown intrinsic reward form 'additve'"):
        EmpowermentReward(env, form="additve")
    with pytest.raises(ValueError, match="unknown tool 'saw' in world 'exp1-tree'"):
        EmpowermentReward(env, tool="saw")
    with pytest.raises(ValueError, match="unknown object 'rock' in world 'exp1-tree'"):
        EmpowermentReward(env, objects="rock")
    with pytest.raises(ValueError, match="horizon 99 is too large"):
        EmpowermentReward(env, horizons=(99, 3))
    with pytest.raises(ValueError, match="wraps a fulcrum vector environment"):
        EmpowermentReward(gym.make_vec("CartPole-v1", num_envs=1))


def test_empowerment_reward_on_a_stochastic_world_pays_the_noisy_channels_e():
    # exp1-tree-slip: along sampled episodes the bonus's E(s') is the capacity of the
    # noisy channel at the state the draw reached (fulcrum.empowerment.value, checked
    # against the NumPy brute force in test_empowerment), h 8 without the axe and 3
    # with it; the state reached is the draw's, not the intended move's.
    venv = fulcrum.make_vec("exp1-tree-slip", num_envs=2, seed=3)
    env = EmpowermentReward(venv, form="additive")
    assert venv.world.stochastic
    rng = np.random.default_rng(0)
    by_h = {3: ([], []), 8: ([], [])}
    ended = [False, False]
    for _ in range(300):
        obs, _, term, trunc, info = env.step(rng.integers(0, 9, size=2))
        for e in range(2):
            # The step after an episode's end is its reset (next-step autoreset).
            if ended[e]:
                ended[e] = False
                continue
            ended[e] = bool(term[e] or trunc[e])
            states, got = by_h[3 if obs["flags"][e][0] == 1 else 8]
            states.append(venv.states[e].tobytes())
            got.append(float(info["empowerment"][e]))
    for h, (states, got) in by_h.items():
        if states:
            want = fulcrum.empowerment.value(
                venv.world, states, tool="axe", objects="tree", horizon=h
            )
            assert got == pytest.approx(list(want), abs=1e-6), h
    assert len({round(v, 6) for v in by_h[8][1]}) >= 2


# A room whose task is to destroy a boulder the agent can also push about.
BOULDER_ROOM = Path(__file__).resolve().parents[2] / "tests" / "worlds" / "boulder-room.toml"


def test_the_potential_counts_a_destroy_tasks_boulder_by_its_condition():
    # As in training: the boulder intact or destroyed, not its cell. Phi = H + 1 - d(s)
    # where the pickaxe destroys it in d <= H = 6 steps, so max Phi = 6 (d = 1 facing
    # it, the pickaxe chosen) and beta = 0.4 / 6.
    path = BOULDER_ROOM
    env = EmpowermentReward(fulcrum.make_vec(str(path), num_envs=1))
    assert env.settings.startswith(
        f"horizon-potential: beta {0.4 / 6!r}, pickaxe -> conditions:boulder, h 6"
    ), env.settings
    env.reset()
    seen = []
    for a in [1, 1, 2, 0, 3, 3, 2, 1, 1, 1, 0, 0]:
        _, _, _, _, info = env.step(np.array([a]))
        seen.append(float(info["empowerment"][0]))
    assert max(seen) <= 6.0 and all(v == int(v) for v in seen), seen
    full = EmpowermentReward(
        fulcrum.make_vec(str(path), num_envs=1), potential_objects="full"
    )
    assert "pickaxe -> boulder, h 6" in full.settings, full.settings
    additive = EmpowermentReward(fulcrum.make_vec(str(path), num_envs=1), form="additive")
    assert "pickaxe -> boulder, h 6" in additive.settings, additive.settings
    with pytest.raises(ValueError, match="unknown potential objects 'cells'"):
        EmpowermentReward(fulcrum.make_vec(str(path), num_envs=1), potential_objects="cells")
