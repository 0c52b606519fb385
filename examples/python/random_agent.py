"""A random agent on exp1-tree with the empowerment reward: E along one episode.

    python examples/python/random_agent.py [WORLD]

Actions are drawn from the per-mode mask (as training samples them), in 16 worlds at
once; the episode of world 0 is printed step by step with its task reward R, the
empowerment E(s_{t+1}) of the world's tool over its objects, and the reward the agent
gets, R + beta * E (the paper's equation (1)). Steps with E > 0 and the first five are
printed; a run on exp1-tree ends:

    t= 39 E          R=0 E=1.000 bits R+beta*E=0.0009  agent=3,2 mode=normal tree=intact wall=intact
    episode over after 100 steps (out of time); E summed 1.000 bits

(one step from the axe at (4,2), the tree can be felled within the 8 steps of the
unequipped horizon: E = 1 bit.)
"""

import sys

import numpy as np

import fulcrum
from fulcrum.wrappers import EmpowermentReward

world = sys.argv[1] if len(sys.argv) > 1 else "exp1-tree"
env = EmpowermentReward(fulcrum.make_vec(world, num_envs=16, seed=0), form="additive")
print(env.settings)
rng = np.random.default_rng(0)
obs, info = env.reset(seed=0)
names = env.unwrapped.world.actions
total_e = 0.0
for t in range(1, 10_000):
    mask = info["action_mask"]
    actions = np.array([rng.choice(np.flatnonzero(m)) for m in mask])
    obs, reward, terminated, truncated, info = env.step(actions)
    e = float(info["empowerment"][0])
    total_e += e
    if e > 0 or terminated[0] or t <= 5:
        r = float(reward[0] - info["intrinsic_reward"][0])
        print(
            f"t={t:3d} {names[actions[0]]:<10} R={r:.0f} E={e:.3f} bits "
            f"R+beta*E={float(reward[0]):.4f}  {env.unwrapped.describe(0)}"
        )
    if terminated[0] or truncated[0]:
        how = "the task done" if terminated[0] else "out of time"
        print(f"episode over after {t} steps ({how}); E summed {total_e:.3f} bits")
        break
