"""Gymnasium environments over fulcrum's tool worlds.

Observation (a ``Dict``), for a ``W x H`` world with ``n`` tools:

- ``glyphs``: uint8 ``(H, W)``, a glyph id per cell: 0 rock, 1 floor, 2 goal, 3 agent,
  4 tree, 5 wall, 6 closed door, 7 open door, 8 boulder, 9 + k tool k on the floor;
  with ``view="crop:R"``, uint8 ``(2R + 1, 2R + 1)``: the window centred on the agent
  (as MiniHack's ``glyphs_crop``), cells beyond the map read as rock;
- ``flags``: uint8 ``(2n + 2,)``: held tool k at k, then the mode one-hot (normal,
  choosing-tool, choosing-direction(k)).

In a stochastic world (``[dynamics] slip``, a rule's ``p``; ``docs/world.md``) every
step draws its outcome from the environment's own generator, which ``reset(seed=...)``
seeds; the same seed replays the same episodes.

Actions: ``Discrete(5 + n)``: N, E, S, W, apply, then select tool k. Every action is
legal in every state (the world turns a useless one into "nothing happens");
``info["action_mask"]`` (int8, 1 = can do something) is the per-mode mask that
``fulcrum train`` samples with.

On a world family (``"toolbox"``, ``"two-rooms"`` or a file with a ``[family]`` table;
``docs/world.md``, "World families") each episode plays one layout, drawn when it starts
from the environment's own generator (seeded by ``reset(seed=...)``): ``layouts=N`` (the
layout seeds ``0..N``, as ``fulcrum train --layouts N``), ``"all"`` (the default: a fresh
layout every episode), ``"test:K"`` or ``"test:A..B"`` (held-out layouts, seeds from 2^40
on, which no training run meets) or ``"train:K"``. The shapes are the family's, the same
for every layout; ``info["layout"]`` holds each episode's layout seed.

The vector environment writes its observations, rewards and flags into numpy arrays it
owns, in place: the arrays a step returns are the same objects every step, valid until
the next step (copy what you keep). Autoreset is gymnasium's next-step mode.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from fulcrum import _native

# Glyph ids (``fulcrum_world::env``); tool k on the floor is ``GLYPH_TOOL0 + k``.
GLYPH_NAMES = (
    "rock",
    "floor",
    "goal",
    "agent",
    "tree",
    "wall",
    "door-closed",
    "door-open",
    "boulder",
)
GLYPH_TOOL0 = 9


def _spaces(core: _native.VecCore) -> tuple[spaces.Dict, spaces.Discrete]:
    world = core.world
    n = len(world.tools)
    obs = spaces.Dict(
        {
            "glyphs": spaces.Box(
                0, GLYPH_TOOL0 + n - 1, tuple(core.glyphs.shape[1:]), np.uint8
            ),
            "flags": spaces.Box(0, 1, (2 * n + 2,), np.uint8),
        }
    )
    return obs, spaces.Discrete(len(world.actions))


class _OneHot:
    """The flat observation of ``obs="onehot"``, for policies that read a vector of
    numbers (Stable-Baselines3's ``MlpPolicy``): for each cell of the glyph grid, row by
    row, a one-hot vector over the ``GLYPH_TOOL0 + n`` glyph ids, then the ``2n + 2``
    flags as 0 or 1; float32, written in place from the core's arrays after each step."""

    def __init__(self, core: _native.VecCore):
        g = core.glyphs
        n_envs, self.cells = g.shape[0], g.shape[1] * g.shape[2]
        self.ids = GLYPH_TOOL0 + len(core.world.tools)
        split = self.cells * self.ids
        self.out = np.zeros((n_envs, split + core.flags.shape[1]), np.float32)
        # Views: the one-hot block as (env, cell, id), the glyphs as (env, cell).
        self._grid = self.out[:, :split].reshape(n_envs, self.cells, self.ids)
        self._flags_out = self.out[:, split:]
        self._glyphs = g.reshape(n_envs, self.cells)
        self._flags = core.flags
        self._eye = np.eye(self.ids, dtype=np.float32)

    def space(self) -> spaces.Box:
        return spaces.Box(0.0, 1.0, (self.out.shape[1],), np.float32)

    def encode(self) -> np.ndarray:
        np.take(self._eye, self._glyphs, axis=0, out=self._grid, mode="clip")
        self._flags_out[...] = self._flags
        return self.out


def _check_obs(obs: str) -> None:
    if obs not in ("dict", "onehot"):
        raise ValueError(f"obs '{obs}' is not offered: dict or onehot")


def _first_seed(seed: int | list[int] | None) -> int | None:
    if isinstance(seed, (list, tuple)):
        return None if len(seed) == 0 or seed[0] is None else int(seed[0])
    return seed


_SEED_BOUND = 2**63


def _world_seeds(
    seed: int | list[int] | None, n: int, rng: np.random.Generator
) -> list[int]:
    """One seed per environment for a stochastic world's outcomes: ``seed + e`` for an
    integer (gymnasium's convention for vector environments), the list as given, or
    drawn from ``rng`` (``np_random``) where no seed is given."""
    if isinstance(seed, (list, tuple)):
        if len(seed) != n:
            raise ValueError(f"{len(seed)} seeds for {n} environments: give one per environment")
        return [
            int(rng.integers(_SEED_BOUND)) if s is None else int(s) % 2**64 for s in seed
        ]
    if seed is None:
        return [int(v) for v in rng.integers(_SEED_BOUND, size=n)]
    return [(int(seed) + e) % 2**64 for e in range(n)]


class FulcrumVectorEnv(gym.vector.VectorEnv):
    """``num_envs`` episodes of one world, stepped together in Rust.

    ``world`` is a :class:`fulcrum.World`, a built-in name or a world file's path, or a
    world family's name or path with ``layouts`` (see the module docs); ``view`` is
    ``"full"`` (the whole map) or ``"crop:R"`` (the ``(2R+1) x (2R+1)`` window around the
    agent), as ``fulcrum train --view``; ``obs`` is ``"dict"`` (glyph ids and flags, the
    default) or ``"onehot"`` (one flat float32 vector: each cell's glyph one-hot, then
    the flags; for policies that read numbers, such as Stable-Baselines3's).
    """

    metadata = {
        "render_modes": ["rgb_array"],
        "render_fps": 4,
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        world: str | _native.World = "exp1-tree",
        num_envs: int = 1,
        render_mode: str | None = None,
        tile: int = 16,
        view: str = "full",
        layouts: int | str | None = None,
        obs: str = "dict",
    ):
        if render_mode not in (None, "rgb_array"):
            raise ValueError(
                f"render_mode '{render_mode}' is not offered: rgb_array or None"
            )
        _check_obs(obs)
        self._core = _native.VecCore(world, int(num_envs), view, layouts)
        self.layouts = self._core.layouts
        self.world = self._core.world
        self.view = self._core.view
        self.num_envs = int(num_envs)
        self._seeded = False
        self.render_mode = render_mode
        self.tile = tile
        self.single_observation_space, self.single_action_space = _spaces(self._core)
        core = self._core
        self._onehot = _OneHot(core) if obs == "onehot" else None
        if self._onehot is not None:
            self.single_observation_space = self._onehot.space()
        self.observation_space = batch_space(
            self.single_observation_space, self.num_envs
        )
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._obs = (
            {"glyphs": core.glyphs, "flags": core.flags}
            if self._onehot is None
            else self._onehot.out
        )
        self._reward = core.reward
        self._terminated = core.terminated
        self._truncated = core.truncated
        self._info = {"action_mask": core.action_mask}
        if self.layouts is not None:
            self._info["layout"] = core.layout
        # Every step returns these same objects (rewritten in place by the core): one
        # tuple made once, so that a step makes no Python object at all.
        self._step_core = core.step
        self._result = (
            self._obs,
            self._reward,
            self._terminated,
            self._truncated,
            self._info,
        )

    @property
    def states(self) -> np.ndarray:
        """uint8 ``(num_envs, 38)``: the packed states (for :class:`ServiceClient`)."""
        return self._core.states

    def reset(
        self,
        *,
        seed: int | list[int] | None = None,
        options: dict[str, Any] | None = None,
    ):
        """Every episode (or those of ``options["reset_mask"]``) back to the start.

        ``seed`` seeds ``action_space``, ``np_random`` and, in a stochastic world, the
        outcomes: environment e draws from its own generator, seeded ``seed + e`` (or
        ``seed[e]`` for a list); the first reset without a seed seeds them from
        ``np_random``. A deterministic world draws nothing.
        """
        first = _first_seed(seed)
        super().reset(seed=first)
        if first is not None:
            self.action_space.seed(first)
        if seed is not None or not self._seeded:
            self._core.seed(_world_seeds(seed, self.num_envs, self.np_random))
            self._seeded = True
        mask = None
        if options and options.get("reset_mask") is not None:
            mask = np.ascontiguousarray(options["reset_mask"], dtype=np.bool_)
        self._core.reset(mask)
        if self._onehot is not None:
            self._onehot.encode()
        return self._obs, self._info

    def step(self, actions):
        self._step_core(actions)
        if self._onehot is not None:
            self._onehot.encode()
        return self._result

    def render(self):
        """A tuple of RGB arrays, one per environment (``render_mode="rgb_array"``)."""
        if self.render_mode != "rgb_array":
            return None
        return tuple(self._core.render(e, self.tile) for e in range(self.num_envs))

    def describe(self, e: int) -> str:
        """The text description of environment ``e``'s state."""
        return self._core.describe(e)

    def action_masks(self) -> np.ndarray:
        """bool ``(num_envs, |A|)``: the actions that can do something now, the bits of
        ``info["action_mask"]`` (sb3-contrib's ``action_masks()`` protocol)."""
        return self._core.action_mask != 0


class FulcrumEnv(gym.Env):
    """One episode of a world (``gymnasium.make("fulcrum/exp1-tree-v0")``), or of a
    layout of a world family (``gymnasium.make("fulcrum/toolbox-v0", layouts=16)``).

    Observations are copies; ``info["action_mask"]`` is the per-mode mask (and, on a
    family, ``info["layout"]`` the episode's layout seed); ``view`` and ``layouts`` as
    :class:`FulcrumVectorEnv`'s.
    """

    metadata = {"render_modes": ["rgb_array", "ansi"], "render_fps": 4}

    def __init__(
        self,
        world: str | _native.World = "exp1-tree",
        render_mode: str | None = None,
        tile: int = 16,
        view: str = "full",
        layouts: int | str | None = None,
        obs: str = "dict",
    ):
        if render_mode not in (None, "rgb_array", "ansi"):
            raise ValueError(
                f"render_mode '{render_mode}' is not offered: rgb_array, ansi or None"
            )
        _check_obs(obs)
        self._core = _native.VecCore(world, 1, view, layouts)
        self.layouts = self._core.layouts
        self.world = self._core.world
        self.view = self._core.view
        self.render_mode = render_mode
        self.tile = tile
        self.observation_space, self.action_space = _spaces(self._core)
        self._onehot = _OneHot(self._core) if obs == "onehot" else None
        if self._onehot is not None:
            self.observation_space = self._onehot.space()
        self._ended = False
        self._seeded = False

    def _observe(self):
        c = self._core
        if self._onehot is not None:
            obs = self._onehot.encode()[0].copy()
        else:
            obs = {"glyphs": c.glyphs[0].copy(), "flags": c.flags[0].copy()}
        info = {"action_mask": c.action_mask[0].copy()}
        if self.layouts is not None:
            info["layout"] = int(c.layout[0])
        return obs, info

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """The episode back to the start (on a family, on a layout drawn anew). ``seed``
        seeds ``np_random``, the layouts and, in a stochastic world, the outcomes (as
        environment 0 of a vector seeded alike)."""
        super().reset(seed=seed)
        if seed is not None or not self._seeded:
            self._core.seed(_world_seeds(seed, 1, self.np_random))
            self._seeded = True
        self._core.reset(None)
        self._ended = False
        return self._observe()

    def step(self, action):
        if self._ended:
            raise RuntimeError(
                "the episode has ended: call reset() before stepping again"
            )
        self._core.step(np.array([action], dtype=np.int64))
        c = self._core
        terminated = bool(c.terminated[0])
        truncated = bool(c.truncated[0])
        self._ended = terminated or truncated
        obs, info = self._observe()
        return obs, float(c.reward[0]), terminated, truncated, info

    def render(self):
        if self.render_mode == "rgb_array":
            return self._core.render(0, self.tile)
        if self.render_mode == "ansi":
            return "\n".join(self._core.render_text(0)) + "\n"
        return None

    def action_masks(self) -> np.ndarray:
        """bool ``(|A|,)``: the actions that can do something now, the bits of
        ``info["action_mask"]`` (sb3-contrib's ``MaskablePPO`` asks for this)."""
        return self._core.action_mask[0] != 0

    @property
    def state(self) -> bytes:
        """The packed state (38 bytes)."""
        return self._core.states[0].tobytes()

    def describe(self) -> str:
        """The text description of the state."""
        return self._core.describe(0)


def make_vec(
    world: str | _native.World = "exp1-tree",
    num_envs: int = 1,
    seed: int | None = None,
    render_mode: str | None = None,
    view: str = "full",
    layouts: int | str | None = None,
    obs: str = "dict",
) -> FulcrumVectorEnv:
    """A :class:`FulcrumVectorEnv`, reset (with ``seed`` if given); on a world family,
    ``layouts`` as the module docs say (``make_vec("toolbox", 8, layouts=16)``)."""
    env = FulcrumVectorEnv(
        world,
        num_envs=num_envs,
        render_mode=render_mode,
        view=view,
        layouts=layouts,
        obs=obs,
    )
    env.reset(seed=seed)
    return env


def register_envs() -> None:
    """Register ``fulcrum/<world>-v0`` for each built-in world and world family (single
    and vector; a family's take ``layouts``, by default ``"all"``)."""
    for name in [*_native.builtin_worlds(), *_native.builtin_families()]:
        env_id = f"fulcrum/{name}-v0"
        if env_id in gym.registry:
            continue
        gym.register(
            id=env_id,
            entry_point="fulcrum.envs:FulcrumEnv",
            vector_entry_point="fulcrum.envs:FulcrumVectorEnv",
            kwargs={"world": name},
        )
