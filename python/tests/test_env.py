"""The gymnasium environments: spaces, dynamics against hand counts, autoreset, masks."""

import numpy as np
import pytest
import gymnasium as gym
from gymnasium.utils.env_checker import check_env

import fulcrum
from conftest import world_map

WORLDS = ["exp1-tree", "exp1-wall", "exp2", "exp3", "room"]

# Actions of exp1-tree: N E S W apply axe pickaxe tin_opener key.
N, E, S, W, APPLY, AXE = 0, 1, 2, 3, 4, 5
# From the start (1,4): up to the axe's row, east over the axe at (4,2) (picked up on
# arrival) to (8,2), next to the tree at (9,2); apply, choose the axe, strike east.
TO_THE_TREE = [N, N, E, E, E, E, E, E, E, APPLY, AXE, E]


def glyph_ids(rows: list[str], tools: str) -> np.ndarray:
    """A map's glyph ids, by the table of the observation (hand-written here)."""
    table = {"#": 0, ".": 1, ">": 2, "@": 3, "T": 4, "=": 5, "+": 6, "'": 7, "0": 8}
    for k, letter in enumerate(tools):
        table[letter] = 9 + k
    return np.array([[table[c] for c in row] for row in rows], dtype=np.uint8)


@pytest.mark.parametrize("name", WORLDS)
def test_registered_env_passes_gymnasiums_checker(name):
    env = gym.make(f"fulcrum/{name}-v0")
    check_env(env.unwrapped, skip_render_check=False)
    env.close()


def test_reset_and_step_shapes_and_dtypes():
    env = fulcrum.make_vec("exp1-tree", num_envs=5, seed=0)
    obs, info = env.reset(seed=0)
    assert obs["glyphs"].shape == (5, 8, 12) and obs["glyphs"].dtype == np.uint8
    assert obs["flags"].shape == (5, 10) and obs["flags"].dtype == np.uint8
    assert info["action_mask"].shape == (5, 9) and info["action_mask"].dtype == np.int8
    assert env.single_action_space == gym.spaces.Discrete(9)
    assert env.action_space.shape == (5,)
    assert obs in env.observation_space
    obs, r, term, trunc, info = env.step(np.full(5, E))
    assert r.shape == (5,) and r.dtype == np.float32
    assert term.dtype == np.bool_ and trunc.dtype == np.bool_
    assert obs in env.observation_space
    assert env.states.shape == (5, fulcrum.STATE_BYTES)


def test_initial_observation_is_the_map_of_the_world_file(repo):
    env = fulcrum.make_vec("exp1-tree", num_envs=2)
    obs, _ = env.reset()
    expected = glyph_ids(world_map(repo, "exp1-tree"), "apok")
    assert (obs["glyphs"][0] == expected).all()
    assert (obs["glyphs"][1] == expected).all()
    # Nothing held; mode normal (flag 4 + 0).
    assert obs["flags"][0].tolist() == [0, 0, 0, 0, 1, 0, 0, 0, 0, 0]


def test_a_move_redraws_the_agent_and_the_floor_it_left():
    env = fulcrum.make_vec("exp1-tree", num_envs=1)
    env.reset()
    obs, *_ = env.step(np.array([E]))
    assert obs["glyphs"][0, 4, 2] == 3 and obs["glyphs"][0, 4, 1] == 1
    assert env.describe(0) == "agent=2,4 mode=normal tree=intact wall=intact"


def test_the_hand_path_destroys_the_tree_then_next_step_autoresets(repo):
    env = fulcrum.make_vec("exp1-tree", num_envs=2)
    env.reset()
    # Env 1 stays put against the west wall (W from (1,4) does nothing).
    rewards, ends = [], []
    for a in TO_THE_TREE:
        obs, r, term, trunc, info = env.step(np.array([a, W]))
        rewards.append(float(r[0]))
        ends.append((bool(term[0]), bool(trunc[0])))
    assert rewards == [0.0] * 11 + [1.0]
    assert ends == [(False, False)] * 11 + [(True, False)]
    # Holding the axe (flag 0), back in normal mode; the tree's cell shows floor.
    assert obs["flags"][0, 0] == 1 and obs["flags"][0, 4] == 1
    assert obs["glyphs"][0, 2, 9] == 1
    # The next step resets env 0 (its action is ignored): reward 0, not ended, the
    # initial map; env 1 steps as usual.
    obs, r, term, trunc, _ = env.step(np.array([N, W]))
    assert float(r[0]) == 0.0 and not term[0] and not trunc[0]
    assert (obs["glyphs"][0] == glyph_ids(world_map(repo, "exp1-tree"), "apok")).all()
    assert env.describe(0) == "agent=1,4 mode=normal tree=intact wall=intact"
    assert env._core.episode_steps.tolist() == [0, 13]


def test_truncation_at_max_steps_then_autoreset():
    env = fulcrum.make_vec("exp1-tree", num_envs=1)
    env.reset()
    for t in range(1, 101):
        _, r, term, trunc, _ = env.step(np.array([W]))
        assert bool(trunc[0]) == (t == 100) and not term[0] and float(r[0]) == 0.0
    env.step(np.array([E]))
    assert env.describe(0) == "agent=1,4 mode=normal tree=intact wall=intact"


def test_reset_mask_resets_only_the_masked_envs():
    env = fulcrum.make_vec("exp1-tree", num_envs=3)
    env.step(np.array([E, E, E]))
    env.reset(options={"reset_mask": np.array([True, False, True])})
    assert [env.describe(e).split()[0] for e in range(3)] == [
        "agent=1,4",
        "agent=2,4",
        "agent=1,4",
    ]


def run_random(seed: int, steps: int = 300):
    env = fulcrum.make_vec("exp2", num_envs=8)
    env.reset(seed=seed)
    out = []
    for _ in range(steps):
        a = env.action_space.sample()
        obs, r, term, trunc, _ = env.step(a)
        out.append((a.copy(), obs["glyphs"].copy(), r.copy(), term.copy()))
    return out


def test_same_seed_same_trajectory_other_seed_other_actions():
    a, b, c = run_random(3), run_random(3), run_random(4)
    for x, y in zip(a, b):
        for u, v in zip(x, y):
            assert np.array_equal(u, v)
    assert any(not np.array_equal(x[0], z[0]) for x, z in zip(a, c))


def reference_mask(flags: np.ndarray, n: int) -> np.ndarray:
    """The per-mode mask from the flags, as the documentation's table states it."""
    held = flags[:n].astype(bool)
    mode = flags[n:]
    m = np.zeros(5 + n, dtype=np.int8)
    if mode[0]:  # normal: moves; apply when a tool is held
        m[:4] = 1
        m[4] = 1 if held.any() else 0
    elif mode[1]:  # choosing a tool: the held tools
        m[5:] = held
    else:  # choosing a direction: moves
        m[:4] = 1
    return m


@pytest.mark.parametrize("name", ["exp1-tree", "exp2", "exp3"])
def test_the_mask_allows_only_actions_that_do_something(name):
    env = fulcrum.make_vec(name, num_envs=16, seed=1)
    world = env.world
    n = len(world.tools)
    rng = np.random.default_rng(1)
    seen_modes = set()
    _, info = env.reset()
    for _ in range(400):
        mask = info["action_mask"]
        # Sample from the mask, as training does, so that prompts are reached often.
        acts = np.array([rng.choice(np.flatnonzero(m)) for m in mask])
        for e in range(env.num_envs):
            flags = env._core.flags[e]
            assert np.array_equal(mask[e], reference_mask(flags, n)), env.describe(e)
            state = env.states[e].tobytes()
            seen_modes.add(world.describe(state).split("mode=")[1].split()[0])
            # Every masked action is a no-op, or a prompt cancelled back to normal.
            for a in np.flatnonzero(mask[e] == 0):
                after = world.describe(world.step(state, int(a)))
                before = world.describe(state)
                cancelled = before.replace(
                    before.split("mode=")[1].split()[0], "normal", 1
                )
                assert after in (before, cancelled), (before, a, after)
        _, _, _, _, info = env.step(acts)
    assert {"normal", "choosing-tool"} <= seen_modes
    assert any(m.startswith("choosing-direction") for m in seen_modes)


def test_render_draws_the_agent_mark_in_its_cell():
    env = gym.make("fulcrum/exp1-tree-v0", render_mode="rgb_array")
    env.reset()
    img = env.render()
    assert img.shape == (8 * 16, 12 * 16, 3) and img.dtype == np.uint8
    # The agent at (1,4): the middle of its tile is the agent's red mark; a floor
    # tile's middle is floor.
    assert img[4 * 16 + 8, 1 * 16 + 8].tolist() == [200, 40, 40]
    assert img[1 * 16 + 8, 1 * 16 + 8].tolist() == [222, 222, 214]
    vec = fulcrum.make_vec("exp1-tree", num_envs=2, render_mode="rgb_array")
    frames = vec.render()
    assert len(frames) == 2 and np.array_equal(frames[0], img)


def test_single_env_refuses_to_step_an_ended_episode():
    env = fulcrum.FulcrumEnv("exp1-tree")
    env.reset()
    for a in TO_THE_TREE:
        _, r, term, _, _ = env.step(a)
    assert term and r == 1.0
    with pytest.raises(RuntimeError, match="call reset"):
        env.step(N)


def test_vector_env_through_gymnasium_make_vec():
    env = gym.make_vec("fulcrum/room-v0", num_envs=4, vectorization_mode="vector_entry_point")
    obs, _ = env.reset(seed=0)
    assert obs["glyphs"].shape[0] == 4
    env.step(env.action_space.sample())


def crop_reference(glyphs: np.ndarray, x: int, y: int, r: int) -> np.ndarray:
    """The (2r+1)^2 window of a full glyph grid around (x, y), rock (0) beyond it: the
    full map padded with r cells of rock on every side, then sliced."""
    padded = np.pad(glyphs, r, constant_values=0)
    return padded[y : y + 2 * r + 1, x : x + 2 * r + 1]


@pytest.mark.parametrize("name,r", [("exp1-tree", 4), ("exp2", 4), ("room", 2), ("exp3", 7)])
def test_a_crop_is_the_full_maps_window_at_random_states(name, r):
    n = 16
    full = fulcrum.make_vec(name, num_envs=n, seed=0)
    crop = fulcrum.make_vec(name, num_envs=n, seed=0, view=f"crop:{r}")
    assert crop.view == f"crop:{r}" and full.view == "full"
    side = 2 * r + 1
    assert crop.single_observation_space["glyphs"].shape == (side, side)
    assert crop.observation_space["glyphs"].shape == (n, side, side)
    rng = np.random.default_rng(5)
    beyond = 0
    for step in range(400):
        acts = rng.integers(0, len(full.world.actions), n)
        fo = full.step(acts)[0]
        co = crop.step(acts)[0]
        assert np.array_equal(fo["flags"], co["flags"]), step
        for e in range(n):
            (y, x) = np.argwhere(fo["glyphs"][e] == 3)[0]
            want = crop_reference(fo["glyphs"][e], x, y, r)
            assert np.array_equal(co["glyphs"][e], want), (step, e)
            beyond += int(x < r or y < r or x + r >= full.world.width or y + r >= full.world.height)
    # The walks do reach the map's edge, where the window holds rock beyond it.
    assert beyond > 100


def test_a_bad_view_is_one_clear_sentence():
    with pytest.raises(ValueError, match=r"unknown view 'crop:0' \(views: full, or crop:R"):
        fulcrum.make_vec("room", num_envs=1, view="crop:0")


# exp1-tree-slip: moves slip with probability 0.1, each of the three other directions
# then taken with 0.1 / 3 (docs/world.md, "Stochastic worlds"). From the start (1,4)
# east: (2,4) with 0.9, north (1,3) and south (1,5) with 1/30 each, west into the wall
# (stays at (1,4)) with 1/30. Hand-derived from the rules, not from the code.
SLIP_EAST = {(2, 4): 0.9, (1, 3): 0.1 / 3, (1, 5): 0.1 / 3, (1, 4): 0.1 / 3}


def agent_cells(glyphs: np.ndarray) -> list[tuple[int, int]]:
    """The agent's (x, y) in each environment's full-view glyphs."""
    return [(int(c[1]), int(c[0])) for c in (np.argwhere(g == 3)[0] for g in glyphs)]


def test_a_stochastic_world_samples_its_outcomes_at_their_probabilities():
    w = fulcrum.World("exp1-tree-slip")
    assert w.stochastic and not fulcrum.World("exp1-tree").stochastic
    start = w.pack("agent=1,4 mode=normal tree=intact")
    got = {}
    for packed, p in w.outcomes(start, "E"):
        d = w.describe(packed)
        xy = tuple(int(v) for v in d.split("agent=")[1].split()[0].split(","))
        got[xy] = p
    assert got == pytest.approx(SLIP_EAST)
    # 20 x 2000 sampled first steps east: Pearson's chi-square against the hand
    # probabilities, 3 degrees of freedom; 16.27 is its 0.999 quantile.
    env = fulcrum.make_vec("exp1-tree-slip", num_envs=2000, seed=11)
    counts = dict.fromkeys(SLIP_EAST, 0)
    for _ in range(20):
        env.reset()
        obs, *_ = env.step(np.full(2000, E))
        for xy in agent_cells(obs["glyphs"]):
            counts[xy] += 1
    n = sum(counts.values())
    assert n == 40_000
    chi2 = sum((counts[k] - n * p) ** 2 / (n * p) for k, p in SLIP_EAST.items())
    assert chi2 < 16.27, (counts, chi2)


def run_actions(env, actions):
    """The packed states after each of ``actions`` (rows: steps)."""
    out = []
    for a in actions:
        env.step(a)
        out.append(env.states.copy())
    return np.stack(out)


def test_the_seed_fixes_a_stochastic_worlds_episodes():
    rng = np.random.default_rng(1)
    acts = rng.integers(0, 4, size=(150, 3))
    a = run_actions(fulcrum.make_vec("exp1-tree-slip", num_envs=3, seed=5), acts)
    b = run_actions(fulcrum.make_vec("exp1-tree-slip", num_envs=3, seed=5), acts)
    c = run_actions(fulcrum.make_vec("exp1-tree-slip", num_envs=3, seed=6), acts)
    assert (a == b).all()
    assert (a != c).any()
    # A reset with a seed starts the same streams again.
    env = fulcrum.make_vec("exp1-tree-slip", num_envs=3, seed=9)
    env.step(acts[0])
    env.reset(seed=5)
    assert (run_actions(env, acts) == a).all()
    # Environment e of a vector seeded s is one environment seeded s + e.
    for e in range(3):
        single = fulcrum.FulcrumEnv("exp1-tree-slip")
        single.reset(seed=5 + e)
        states = []
        for t in range(150):
            _, _, term, trunc, _ = single.step(int(acts[t, e]))
            states.append(np.frombuffer(single.state, dtype=np.uint8))
            if term or trunc:
                break
        assert (np.stack(states) == a[: len(states), e]).all()


def test_action_masks_are_the_info_mask_as_booleans():
    """sb3-contrib's protocol: ``action_masks()`` on the single and the vector env gives
    the bits of ``info["action_mask"]`` as booleans, step after step (the mask changes with
    the mode: at the tool prompt only the held tools' selects are allowed)."""
    import gymnasium as gym

    fulcrum.register_envs()
    one = gym.make("fulcrum/exp1-tree-v0")
    # Through gymnasium's wrappers, as sb3-contrib finds it.
    masks = one.get_wrapper_attr("action_masks")
    vec = fulcrum.make_vec("exp1-tree", 3, seed=2)
    _, info1 = one.reset(seed=2)
    _, infov = vec.reset(seed=2)
    rng = np.random.default_rng(2)
    seen = set()
    for _ in range(300):
        m1 = masks()
        assert m1.dtype == np.bool_ and m1.shape == (9,)
        assert np.array_equal(m1, info1["action_mask"] != 0)
        mv = vec.action_masks()
        assert mv.dtype == np.bool_ and mv.shape == (3, 9)
        assert np.array_equal(mv, infov["action_mask"] != 0)
        seen.add(tuple(m1.tolist()))
        a = int(rng.choice(np.flatnonzero(m1)))
        _, _, term, trunc, info1 = one.step(a)
        if term or trunc:
            _, info1 = one.reset()
        acts = np.array([rng.choice(np.flatnonzero(r)) for r in mv], dtype=np.int64)
        _, _, _, _, infov = vec.step(acts)
    # Normal mode without a tool: the four moves only; with the axe, apply too.
    assert (True, True, True, True, False, False, False, False, False) in seen
    assert len(seen) >= 3


def test_onehot_observations_are_the_glyphs_and_flags_spelled_out():
    """``obs="onehot"``: each cell's glyph id one-hot, then the flags, float32; the same
    episodes as the Dict form (argmax of each cell's block is its glyph id), step after
    step, in the vector and the single environment, on a full and a cropped view."""
    import gymnasium as gym

    for view, shape in [("full", (8, 12)), ("crop:2", (5, 5))]:
        a = fulcrum.make_vec("exp1-tree", 4, seed=3, view=view)
        b = fulcrum.make_vec("exp1-tree", 4, seed=3, view=view, obs="onehot")
        cells, ids = shape[0] * shape[1], fulcrum.envs.GLYPH_TOOL0 + 4
        assert b.single_observation_space.shape == (cells * ids + 10,)
        assert b.single_observation_space.dtype == np.float32
        oa, _ = a.reset(seed=3)
        ob, _ = b.reset(seed=3)
        rng = np.random.default_rng(3)
        for _ in range(150):
            grid = ob[:, : cells * ids].reshape(4, cells, ids)
            assert np.array_equal(grid.sum(axis=2), np.ones((4, cells), np.float32))
            assert np.array_equal(grid.argmax(axis=2), oa["glyphs"].reshape(4, cells))
            assert np.array_equal(ob[:, cells * ids :], oa["flags"].astype(np.float32))
            assert b.observation_space.contains(ob)
            acts = rng.integers(0, 9, size=4)
            oa, *_ = a.step(acts)
            ob, *_ = b.step(acts)

    fulcrum.register_envs()
    one = gym.make("fulcrum/exp1-tree-v0", obs="onehot")
    from gymnasium.utils.env_checker import check_env

    check_env(one.unwrapped)
    o, _ = one.reset(seed=0)
    assert o.shape == one.observation_space.shape and o.dtype == np.float32
    # The agent's glyph (3) at its start cell (1, 4) of exp1-tree.
    assert o[(4 * 12 + 1) * (fulcrum.envs.GLYPH_TOOL0 + 4) + 3] == 1.0
    with pytest.raises(ValueError, match="obs 'pixels' is not offered: dict or onehot"):
        fulcrum.make_vec("exp1-tree", 2, obs="pixels")


def test_the_reward_wrapper_passes_onehot_observations_fresh():
    """EmpowermentReward over ``obs="onehot"`` returns the observation of the step just
    taken (the one-hot form is encoded by the env's step, which the wrapper must not skip),
    and the same rewards as over the Dict form."""
    from fulcrum.wrappers import EmpowermentReward

    a = EmpowermentReward(fulcrum.make_vec("exp1-tree", 2, seed=1))
    b = EmpowermentReward(fulcrum.make_vec("exp1-tree", 2, seed=1, obs="onehot"))
    a.reset(seed=1)
    b.reset(seed=1)
    ids = fulcrum.envs.GLYPH_TOOL0 + 4
    rng = np.random.default_rng(1)
    for _ in range(60):
        acts = rng.integers(0, 9, size=2)
        oa, ra, *_ = a.step(acts)
        ob, rb, *_ = b.step(acts)
        grid = ob[:, : 96 * ids].reshape(2, 96, ids).argmax(axis=2)
        assert np.array_equal(grid, oa["glyphs"].reshape(2, 96))
        assert np.array_equal(ra, rb)
