"""sb3-contrib's MaskablePPO against the real package, as examples/python/sb3_maskable.py
runs it: it finds the masks itself and samples only actions they allow."""

import warnings

import gymnasium as gym
import numpy as np
from sb3_contrib import MaskablePPO
from stable_baselines3.common.env_checker import check_env
from stable_baselines3.common.env_util import make_vec_env

import fulcrum  # noqa: F401


class Audit(gym.Wrapper):
    """Records, for each step, whether the action taken was allowed by the mask the
    environment showed before it (test code, not something a user writes)."""

    log: list = []

    def step(self, action):
        mask = self.env.unwrapped.action_masks()
        Audit.log.append((bool(mask[int(action)]), bool(mask.all())))
        return self.env.step(action)


def test_maskable_ppo_samples_only_allowed_actions():
    Audit.log = []
    env = make_vec_env(
        lambda: gym.make("fulcrum/exp1-tree-v0", obs="onehot"), n_envs=8, seed=3, wrapper_class=Audit
    )
    model = MaskablePPO(
        "MlpPolicy", env, n_steps=128, batch_size=256, n_epochs=2, seed=3, device="cpu", policy_kwargs={"net_arch": [64, 64]}
    )
    model.learn(total_timesteps=4096)
    assert model.num_timesteps == 4096
    allowed = [a for a, _ in Audit.log]
    assert len(allowed) == 4096
    assert all(allowed), f"{allowed.count(False)} actions outside the mask"
    # The check compared something: most steps had actions masked out (the moves and
    # apply are allowed in the normal mode, the tool keys only at the prompt).
    assert sum(1 for _, full in Audit.log if not full) > 2000


def test_stable_baselines_checks_the_onehot_environment_without_a_warning():
    env = gym.make("fulcrum/exp1-tree-v0", obs="onehot")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env)
    assert [str(w.message) for w in caught] == []
    obs, _ = env.reset(seed=0)
    assert obs.dtype == np.float32 and obs.ndim == 1
