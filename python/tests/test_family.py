"""World families from Python: ``World.layout(family, seed)`` is the layout the command
line shows for the same family and seed, and a bad family is the command line's sentence."""

import json
import subprocess

import numpy as np
import pytest

import fulcrum
from fulcrum import empowerment
from fulcrum.wrappers import EmpowermentReward


def cli_json(fulcrum_bin, *args):
    out = subprocess.run([fulcrum_bin, *args], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def test_a_layout_is_the_command_lines(fulcrum_bin):
    assert fulcrum.builtin_families() == ["toolbox", "two-rooms"]
    for family in fulcrum.builtin_families():
        for seed in [0, 3, 41]:
            w = fulcrum.World.layout(family, seed)
            v = cli_json(fulcrum_bin, "world", "show", family, "--layout", str(seed), "--json")
            assert w.name == v["world"] == f"{family}-{seed}"
            assert "".join(row + "\n" for row in w.map) == v["map"]
            assert w.actions == v["actions"]
    # Every layout of a family has the family's size and actions.
    shapes = {(fulcrum.World.layout("toolbox", s).width, fulcrum.World.layout("toolbox", s).height,
               tuple(fulcrum.World.layout("toolbox", s).actions)) for s in range(50)}
    assert shapes == {(10, 8, ("N", "E", "S", "W", "apply", "axe", "pickaxe", "wand"))}


def test_a_family_is_not_one_world_and_bad_families_are_the_cli_sentence(tmp_path, fulcrum_bin):
    with pytest.raises(ValueError, match="world family"):
        fulcrum.World("toolbox")
    bad = tmp_path / "fam.toml"
    bad.write_text('name = "f"\n\n[family]\nwidth = 10\nheight = 8\ntools = ["key"]\nobjects = ["tree"]\n')
    out = subprocess.run([fulcrum_bin, "world", "show", str(bad), "--layout", "0"],
                         capture_output=True, text=True)
    assert out.returncode == 2
    want = out.stderr.strip().removeprefix("fulcrum: ")
    with pytest.raises(ValueError) as e:
        fulcrum.World.layout(str(bad), 0)
    assert str(e.value) == want and ":7:12:" in want


HELD_OUT = 2**40


def initial_glyphs(family, seed):
    """Layout ``seed``'s first observation, from the layout made as one world."""
    env = fulcrum.make_vec(fulcrum.World.layout(family, seed), 1)
    return env.reset()[0]["glyphs"][0].copy()


def test_a_vector_on_a_family_plays_a_layout_per_episode():
    env = fulcrum.make_vec("toolbox", 4, seed=5, layouts=16)
    obs, info = env.reset(seed=5)
    layouts = info["layout"].copy()
    assert env.layouts == "16"
    assert layouts.dtype == np.uint64 and all(0 <= s < 16 for s in layouts)
    # Each environment sees its layout as the layout made on its own would show it.
    for e, s in enumerate(layouts):
        assert np.array_equal(obs["glyphs"][e], initial_glyphs("toolbox", int(s)))
    # The same seed draws the same layouts; another seed others.
    assert np.array_equal(env.reset(seed=5)[1]["layout"], layouts)
    draws = {tuple(env.reset(seed=k)[1]["layout"].tolist()) for k in range(6)}
    assert len(draws) > 1


def test_an_autoreset_draws_a_fresh_layout_and_shows_all_of_it():
    env = fulcrum.make_vec("toolbox", 2, seed=1, layouts="all")
    obs, info = env.reset(seed=1)
    first = info["layout"].copy()
    # Moving north forever never ends the task: the episodes end at max_steps (100).
    for _ in range(100):
        obs, _, term, trunc, info = env.step(np.zeros(2, dtype=np.int64))
    assert trunc.all() and not term.any()
    obs, _, _, _, info = env.step(np.zeros(2, dtype=np.int64))
    second = info["layout"].copy()
    assert all(a != b for a, b in zip(first, second))
    assert all(s < HELD_OUT for s in second)
    for e, s in enumerate(second):
        assert np.array_equal(obs["glyphs"][e], initial_glyphs("toolbox", int(s)))


def test_held_out_layouts_and_the_single_environment():
    env = fulcrum.make_vec("toolbox", 8, seed=0, layouts="test:5")
    seeds = env.reset(seed=0)[1]["layout"]
    assert all(HELD_OUT <= s < HELD_OUT + 5 for s in seeds)
    env = fulcrum.make_vec("two-rooms", 3, seed=0, layouts="train:2")
    assert set(env.reset(seed=0)[1]["layout"].tolist()) <= {0, 1}

    import gymnasium as gym
    fulcrum.register_envs()
    one = gym.make("fulcrum/toolbox-v0", layouts=4, render_mode="ansi")
    _, info = one.reset(seed=3)
    s = info["layout"]
    assert isinstance(s, int) and 0 <= s < 4
    assert one.reset(seed=3)[1]["layout"] == s
    # The text picture is the layout's own map.
    w = fulcrum.World.layout("toolbox", s)
    assert one.render().splitlines() == w.render_text(w.initial_state)


def test_bad_layouts_are_one_sentence():
    with pytest.raises(ValueError, match="a run trains on 1 to 1099511627776 layouts"):
        fulcrum.make_vec("toolbox", 2, layouts=0)
    with pytest.raises(ValueError, match="'0' is not a number of layouts"):
        fulcrum.make_vec("toolbox", 2, layouts="test:0")
    with pytest.raises(ValueError, match="needs a world family, and 'exp1-tree' is one world"):
        fulcrum.make_vec("exp1-tree", 2, layouts=16)
    env = fulcrum.make_vec("toolbox", 2, layouts=16)
    with pytest.raises(ValueError, match="the count form counts the visits of one world"):
        EmpowermentReward(env, form="count")
    with pytest.raises(ValueError, match="objects does not fit a world family"):
        EmpowermentReward(env, objects="tree")


def _phi(world, state):
    """Phi = sum over h = 1..H of E^h, H the larger of the layout's horizons."""
    d = world.empowerment_defaults
    top = max(d["horizon_unequipped"], d["horizon_equipped"])
    return sum(empowerment.value(world, state, horizon=h) for h in range(1, top + 1))


@pytest.mark.parametrize("form", ["additive", "horizon-potential"])
def test_the_reward_wrapper_reads_each_layouts_own_table(form):
    """Each step's value is E (or Phi) of the state on the episode's own layout, made as
    one world; a potential episode starts from its new layout's start potential."""
    beta, gamma = 0.5, 0.9
    env = EmpowermentReward(fulcrum.make_vec("toolbox", 4, layouts=6), form=form, beta=beta, gamma=gamma)
    rng = np.random.default_rng(1)
    _, info = env.reset(seed=3)
    layouts = {}
    prev = [None] * 4  # (layout, packed state) before the step; None after an end
    ended = [False] * 4
    checked_starts = nonzero_starts = 0
    for _ in range(400):
        masks = info["action_mask"]
        actions = np.array([rng.choice(np.flatnonzero(m)) for m in masks])
        before = [(int(info["layout"][e]), bytes(env.unwrapped.states[e])) for e in range(4)]
        _, reward, term, trunc, info = env.step(actions)
        for e in range(4):
            seed = int(info["layout"][e])
            w = layouts.setdefault(seed, fulcrum.World.layout("toolbox", seed))
            s = bytes(env.unwrapped.states[e])
            if ended[e]:
                # The reset step pays nothing.
                assert info["intrinsic_reward"][e] == 0.0
            elif form == "additive":
                want = empowerment.value(w, s)
                assert info["empowerment"][e] == pytest.approx(want, rel=1e-5, abs=1e-6)
                assert info["intrinsic_reward"][e] == pytest.approx(beta * want, rel=1e-5, abs=1e-6)
            else:
                pw = layouts[before[e][0]]
                phi_next = 0.0 if term[e] else _phi(w, s)
                want = beta * (gamma * phi_next - _phi(pw, before[e][1]))
                assert info["intrinsic_reward"][e] == pytest.approx(want, rel=1e-4, abs=1e-5)
                if prev[e] is None:
                    checked_starts += 1
                    nonzero_starts += _phi(pw, before[e][1]) > 0
            prev[e] = None if ended[e] else before[e]
            ended[e] = bool(term[e] or trunc[e])
    if form == "horizon-potential":
        # Episodes began on several layouts, each paid from its own start potential.
        assert checked_starts >= 8 and nonzero_starts >= 2, (checked_starts, nonzero_starts)
    assert len(layouts) >= 3
