"""Intrinsic rewards for fulcrum's vector environments.

:class:`EmpowermentReward` adds ``beta * b_t`` to the task reward ``r_t`` of each
transition ``s_t -> s_{t+1}``, with ``b_t`` by form, the same code as ``fulcrum train
--intrinsic``:

============================  ===================================================
form                          b_t
============================  ===================================================
``additive`` (equation (1))   E(s_{t+1})
``potential``                 gamma E(s_{t+1}) - E(s_t)  (0 potential when terminal)
``horizon-potential``         the same with Phi = sum over h = 1..H of E^h
``first-visit``               E(s_{t+1}), once per inventory and episode
``count``                     1 / sqrt(N(s_{t+1})), N the visits of this wrapper
``none``                      0
============================  ===================================================

E is exact: ``E^h_{j,D}(s) = log2 |R_h(s)|`` bits for tool j's actions over the objects
D, with ``h = h_e`` where j is held and ``h_u`` elsewhere (the world's
``[empowerment]`` values unless given). The table is computed once, when the wrapper is
made; a step then costs one array read per environment, in Rust, in the same call as
the step. On a world family (``make_vec("toolbox", n, layouts=...)``) each layout has its
own table, made the first time an episode plays it (the layout's own task object, the
family's tool and horizons unless given); the count form is for one world.
"""

from __future__ import annotations

from typing import Sequence

import gymnasium as gym

from fulcrum.envs import FulcrumVectorEnv


def _objects_arg(objects: str | Sequence[str] | None) -> str | None:
    if objects is None or isinstance(objects, str):
        return objects
    return "+".join(objects)


def _horizons_arg(horizons) -> tuple[int | None, int | None]:
    if horizons is None:
        return None, None
    if isinstance(horizons, int):
        return horizons, horizons
    try:
        hu, he = horizons
    except (TypeError, ValueError):
        raise ValueError(
            f"horizons is {horizons!r}: give one horizon, or (unequipped, equipped)"
        ) from None
    return hu, he


class EmpowermentReward(gym.vector.VectorWrapper):
    """Reward ``r + beta * b`` (module docs), intrinsic part in ``info``.

    ``info["intrinsic_reward"]`` is ``beta * b`` per environment and
    ``info["empowerment"]`` the value looked up for s_{t+1} (E, Phi, or the visit
    count), so both can be logged apart. Arrays are the wrapper's own, rewritten every
    step.

    Parameters: ``form`` (above; the default is ``horizon-potential``, as ``fulcrum
    train``'s: potential-based shaping keeps the task's optimal policies, so it cannot
    make standing where E is high pay more than the task, as the additive bonus can),
    ``beta`` (default: the world's for additive and
    potential, 0.4 / max Phi for horizon-potential as in training, 0.1 for first-visit),
    ``tool`` (a tool
    name, ``"all"`` or ``"auto"``: the matrix's selection), ``objects`` (``"tree"``,
    ``"boulder+door"``, a list of names, or ``"agent"``), ``horizons`` (``h`` or
    ``(h_u, h_e)``), ``gamma`` (the potential forms' discount; use your PPO's),
    ``potential_objects`` (``"task"``, the default as in training: the potential forms
    count a destroy task's objects by their conditions only, a boulder intact or
    destroyed and not its cell, unless ``objects`` names them; ``"full"``: their full
    state, as E).
    """

    def __init__(
        self,
        env: gym.vector.VectorEnv,
        form: str = "horizon-potential",
        beta: float | None = None,
        tool: str | None = None,
        objects: str | Sequence[str] | None = None,
        horizons: int | tuple[int, int] | None = None,
        gamma: float = 0.99,
        potential_objects: str = "task",
    ):
        super().__init__(env)
        base = env.unwrapped
        if not isinstance(base, FulcrumVectorEnv):
            raise ValueError(
                "EmpowermentReward wraps a fulcrum vector environment "
                f"(fulcrum.make_vec), not {type(base).__name__}"
            )
        hu, he = _horizons_arg(horizons)
        # Straight over a fulcrum env whose observation the core writes itself (not the
        # one-hot form, which its step encodes after the core's).
        self._direct = env is base and getattr(base, "_onehot", None) is None
        self._base = base
        self._base_info = None
        self._wrapped_info = {}
        self._total, self._intrinsic, self._value = base._core.attach_intrinsic(
            form,
            beta,
            tool,
            _objects_arg(objects),
            hu,
            he,
            float(gamma),
            potential_objects,
        )
        self.settings = base._core.intrinsic_settings[-1]
        """The form, beta, tool, objects and horizons in force, in words."""
        self._step_core = base._core.step
        self._result = (
            base._obs,
            self._total,
            base._terminated,
            base._truncated,
            self._info(base._info),
        )

    def _info(self, info):
        # The fulcrum env returns the same info dict (of the same arrays) every step:
        # build ours once per such dict, not once per step.
        if info is not self._base_info:
            self._base_info = info
            self._wrapped_info = {
                **info,
                "intrinsic_reward": self._intrinsic,
                "empowerment": self._value,
            }
        return self._wrapped_info

    def reset(self, *, seed=None, options=None):
        obs, info = self.env.reset(seed=seed, options=options)
        return obs, self._info(info)

    def step(self, actions):
        if self._direct:
            # Straight over the fulcrum env: its step is one call into Rust, which also
            # computes the intrinsic reward; make the same call and return the same
            # (persistent) arrays, without a second Python frame.
            self._step_core(actions)
            return self._result
        obs, reward, terminated, truncated, info = self.env.step(actions)
        # Over other wrappers: add to the reward they return.
        total = reward + self._intrinsic
        return obs, total, terminated, truncated, self._info(info)
