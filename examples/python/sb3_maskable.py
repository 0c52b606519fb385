"""sb3-contrib's MaskablePPO on a fulcrum world, with no wrapper of your own.

    pip install ./python sb3-contrib
    python examples/python/sb3_maskable.py --world exp1-tree --seed 1

``gymnasium.make("fulcrum/<world>-v0", obs="onehot")`` gives one flat float32 vector
(each cell's glyph one-hot, then the flags), which Stable-Baselines3's ``MlpPolicy``
reads as numbers, and ``action_masks()``, which MaskablePPO asks every environment for
before it samples: at the "which tool?" prompt only the held tools, and so on (the
per-mode mask of ``fulcrum train``). The settings are ``fulcrum train``'s where SB3 has
them: 8 environments x 128 steps per update, 4 epochs of 4 minibatches (batch 256),
Adam at 2.5e-4, clip 0.2, entropy 0.01, value 0.5, gradient norm 0.5, gamma 0.99,
GAE 0.95, two tanh layers of 64. The reward is the task's alone (fulcrum's R; for
R + beta E wrap each environment in ``fulcrum.wrappers.EmpowermentReward``).

It prints the success rate every 10 updates, counted as ``fulcrum train`` counts it (the
episodes that did the task over those that ended in the last 10 updates), and at the
end the env steps and seconds at which it first reached 0.9 (``--until-solved`` stops
there) and the env steps per second of the whole loop.
"""

import argparse
import time
from collections import deque

import gymnasium as gym
from sb3_contrib import MaskablePPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.env_util import make_vec_env

import fulcrum  # noqa: F401  (registers fulcrum/<world>-v0)


class Success(BaseCallback):
    """The success rate as ``fulcrum train`` and ``fulcrum experiment`` count it: the
    episodes that did the task (return >= 1, the task's reward) over the episodes that
    ended in the last 10 updates, pooled; and the env steps and seconds at the end of
    the first update at which it reached 0.9. With ``stop``, training ends there."""

    def __init__(self, every: int, stop: bool):
        super().__init__()
        self.updates_window = deque(maxlen=10)
        self.episodes = 0
        self.successes = 0
        self.first = None
        self.every = every
        self.stop = stop
        self.updates = 0
        self.t0 = time.perf_counter()

    def _on_step(self) -> bool:
        for info in self.locals["infos"]:
            if "episode" in info:
                self.episodes += 1
                self.successes += int(info["episode"]["r"] >= 1.0)
        return not (self.stop and self.first is not None)

    def rate(self) -> float:
        episodes = sum(e for e, _ in self.updates_window)
        return sum(s for _, s in self.updates_window) / episodes if episodes else 0.0

    def _on_rollout_end(self) -> None:
        self.updates += 1
        self.updates_window.append((self.episodes, self.successes))
        self.episodes = self.successes = 0
        rate = self.rate()
        if self.first is None and rate >= 0.9:
            self.first = (self.num_timesteps, time.perf_counter() - self.t0)
        if self.every and self.updates % self.every == 0:
            print(f"update {self.updates}  steps {self.num_timesteps}  success {rate:.3f}", flush=True)


def make(world: str, n_envs: int, seed: int):
    return make_vec_env(lambda: gym.make(f"fulcrum/{world}-v0", obs="onehot"), n_envs=n_envs, seed=seed)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--world", default="exp1-tree")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--steps", type=int, default=499712)
    p.add_argument("--log-every", type=int, default=10, help="updates between lines")
    p.add_argument("--until-solved", action="store_true", help="stop at a success rate of 0.9")
    args = p.parse_args()
    t0 = time.perf_counter()
    env = make(args.world, 8, args.seed)
    model = MaskablePPO(
        "MlpPolicy",
        env,
        n_steps=128,
        batch_size=256,
        n_epochs=4,
        learning_rate=2.5e-4,
        gamma=0.99,
        gae_lambda=0.95,
        clip_range=0.2,
        ent_coef=0.01,
        vf_coef=0.5,
        max_grad_norm=0.5,
        policy_kwargs={"net_arch": [64, 64]},
        seed=args.seed,
        device="cpu",
    )
    cb = Success(args.log_every, args.until_solved)
    cb.t0 = t0
    model.learn(total_timesteps=args.steps, callback=cb)
    dt = time.perf_counter() - t0
    steps = cb.first[0] if cb.first else model.num_timesteps
    first = "never" if cb.first is None else f"at {cb.first[0]} env steps, {cb.first[1]:.1f} s"
    print(f"done: {steps} env steps in {dt:.1f} s ({steps / dt:.0f} steps/s); success 0.9 first {first}")


if __name__ == "__main__":
    main()
