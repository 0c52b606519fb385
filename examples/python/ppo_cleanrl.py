"""PPO in PyTorch on fulcrum's vector environments, in the shape of CleanRL's ppo.py.

    pip install ./python torch
    python examples/python/ppo_cleanrl.py --world exp1-tree --seed 1

The settings are `fulcrum train`'s defaults, so that the two can be compared run for
run: 8 worlds x 128 steps per update (1024 env steps), Adam at 2.5e-4 annealed to 0,
4 epochs x 4 minibatches, clip 0.2, entropy 0.01, value 0.5, gradient norm 0.5,
gamma 0.99, GAE 0.95, advantages normalised per minibatch with the floor 0.1 under the
standard deviation, actions sampled from the per-mode mask, and the reward R + beta * E
of the world file (EmpowermentReward, additive). The network is fulcrum's: the one-hot
glyph grid and the flags, two ReLU layers of 64, a policy head and a value head.

It prints a line every 10 updates and, at the end, the env steps at which the success
rate (the share of finished episodes that did the task, pooled over the last 10
updates, as `fulcrum experiment` pools it) first reached 0.9, the env steps per
second of the whole loop (stepping, inference and updates), and the samples x epochs
per second of the PPO updates alone (fulcrum's "learner samples x epochs/s").

It should end like this (seed 1, on the 2-core machine of BENCHMARKS.md, 2026-11-30,
PyTorch 2.15 on the CPU):

    update 480/488  steps 491520  success 0.999  7159 steps/s
    update 488/488  steps 499712  success 0.999  7171 steps/s
    done: 499712 env steps in 69.7 s (7171 steps/s); success 0.9 first at 107520 env steps; PPO updates 48815 samples x epochs/s

Seeds 1 to 3 reached 0.9 at 107,520, 119,808 and 102,400 env steps, where `fulcrum
train` with the same settings did at 82,944, 113,664 and 96,256, 12 to 16 times faster
(BENCHMARKS.md, "Python"). It is not run in CI (PyTorch is a large download).
"""

import argparse
import time
from collections import deque

import numpy as np
import torch
import torch.nn as nn
from torch.distributions.categorical import Categorical

import fulcrum
from fulcrum.wrappers import EmpowermentReward


def parse():
    p = argparse.ArgumentParser()
    p.add_argument("--world", default="exp1-tree")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--total-steps", type=int, default=499_712)
    p.add_argument("--num-envs", type=int, default=8)
    p.add_argument("--num-steps", type=int, default=128)
    p.add_argument("--lr", type=float, default=2.5e-4)
    p.add_argument("--gamma", type=float, default=0.99)
    p.add_argument("--gae-lambda", type=float, default=0.95)
    p.add_argument("--epochs", type=int, default=4)
    p.add_argument("--minibatches", type=int, default=4)
    p.add_argument("--clip", type=float, default=0.2)
    p.add_argument("--ent-coef", type=float, default=0.01)
    p.add_argument("--vf-coef", type=float, default=0.5)
    p.add_argument("--max-grad-norm", type=float, default=0.5)
    p.add_argument("--adv-floor", type=float, default=0.1)
    p.add_argument("--hidden", type=int, default=64)
    p.add_argument("--no-empowerment", action="store_true")
    p.add_argument("--stop-at-solve", action="store_true", help="stop once 0.9 is reached")
    return p.parse_args()


class Agent(nn.Module):
    def __init__(self, cells, glyphs, flags, actions, hidden):
        super().__init__()
        self.glyphs = glyphs
        self.l1 = nn.Linear(cells * glyphs + flags, hidden)
        self.l2 = nn.Linear(hidden, hidden)
        self.pi = nn.Linear(hidden, actions)
        self.v = nn.Linear(hidden, 1)
        for layer, std in ((self.l1, 2**0.5), (self.l2, 2**0.5), (self.pi, 0.01), (self.v, 1.0)):
            nn.init.orthogonal_(layer.weight, std)
            nn.init.zeros_(layer.bias)

    def trunk(self, glyphs, flags):
        one_hot = nn.functional.one_hot(glyphs.long().flatten(1), self.glyphs).flatten(1)
        x = torch.cat([one_hot.float(), flags.float()], dim=1)
        return torch.relu(self.l2(torch.relu(self.l1(x))))

    def value(self, glyphs, flags):
        return self.v(self.trunk(glyphs, flags)).squeeze(-1)

    def act(self, glyphs, flags, mask, action=None):
        h = self.trunk(glyphs, flags)
        logits = self.pi(h).masked_fill(mask == 0, -1e8)
        dist = Categorical(logits=logits)
        if action is None:
            action = dist.sample()
        return action, dist.log_prob(action), dist.entropy(), self.v(h).squeeze(-1)


def main():
    a = parse()
    torch.manual_seed(a.seed)
    np.random.seed(a.seed)
    torch.set_num_threads(1)
    env = fulcrum.make_vec(a.world, num_envs=a.num_envs, seed=a.seed)
    if not a.no_empowerment:
        env = EmpowermentReward(env, form="additive", gamma=a.gamma)
    w = env.unwrapped.world
    n, T = a.num_envs, a.num_steps
    cells, glyphs = w.width * w.height, 9 + len(w.tools)
    nflags, nact = 2 * len(w.tools) + 2, len(w.actions)
    agent = Agent(cells, glyphs, nflags, nact, a.hidden)
    opt = torch.optim.Adam(agent.parameters(), lr=a.lr, eps=1e-5)

    obs_g = torch.zeros((T, n, w.height, w.width), dtype=torch.uint8)
    obs_f = torch.zeros((T, n, nflags), dtype=torch.uint8)
    masks = torch.zeros((T, n, nact), dtype=torch.int8)
    actions = torch.zeros((T, n), dtype=torch.long)
    logps = torch.zeros((T, n))
    rewards = torch.zeros((T, n))
    dones = torch.zeros((T, n))
    values = torch.zeros((T, n))
    valid = np.zeros((T, n), dtype=bool)

    obs, info = env.reset(seed=a.seed)
    next_g = torch.from_numpy(obs["glyphs"].copy())
    next_f = torch.from_numpy(obs["flags"].copy())
    next_m = torch.from_numpy(info["action_mask"].copy())
    next_done = torch.zeros(n)
    # Next-step autoreset: a step whose previous step ended an episode is a reset step
    # (its action is ignored, no transition): it is left out of the loss (`valid`), and
    # `dones` keeps the returns from crossing episodes.
    prev_ended = np.zeros(n, dtype=bool)
    updates = a.total_steps // (n * T)
    window = deque(maxlen=10)  # (episodes, successes) of the last 10 updates
    solved_at, steps, t0 = None, 0, time.perf_counter()
    learn_s = 0.0  # time in PPO updates
    samples = 0  # samples x epochs they processed
    for update in range(1, updates + 1):
        for g in opt.param_groups:
            g["lr"] = a.lr * (1.0 - (update - 1.0) / updates)
        episodes = successes = 0
        for t in range(T):
            obs_g[t], obs_f[t], masks[t], dones[t] = next_g, next_f, next_m, next_done
            with torch.no_grad():
                act, logp, _, v = agent.act(next_g, next_f, next_m)
            actions[t], logps[t], values[t] = act, logp, v
            obs, reward, term, trunc, info = env.step(act.numpy())
            steps += n
            valid[t] = ~prev_ended
            rewards[t] = torch.from_numpy(np.where(prev_ended, 0.0, reward))
            ended = term | trunc
            episodes += int(ended.sum())
            successes += int(term.sum())
            next_g = torch.from_numpy(obs["glyphs"].copy())
            next_f = torch.from_numpy(obs["flags"].copy())
            next_m = torch.from_numpy(info["action_mask"].copy())
            # A truncated episode bootstraps from its last state's value (CleanRL
            # ignores truncation; fulcrum's learner does not).
            if trunc.any():
                with torch.no_grad():
                    vt = agent.value(next_g, next_f)
                rewards[t] += a.gamma * vt * torch.from_numpy(trunc.astype(np.float32))
            next_done = torch.from_numpy(ended.astype(np.float32))
            prev_ended = ended.copy()
        window.append((episodes, successes))
        with torch.no_grad():
            next_v = agent.value(next_g, next_f)
            adv = torch.zeros((T, n))
            last = torch.zeros(n)
            for t in reversed(range(T)):
                nonterminal = 1.0 - (next_done if t == T - 1 else dones[t + 1])
                nv = next_v if t == T - 1 else values[t + 1]
                delta = rewards[t] + a.gamma * nv * nonterminal - values[t]
                last = delta + a.gamma * a.gae_lambda * nonterminal * last
                adv[t] = last
            returns = adv + values
        b = lambda x: x.reshape((T * n,) + x.shape[2:])
        bg, bf, bm = b(obs_g), b(obs_f), b(masks)
        ba, blp, badv, bret, bv = b(actions), b(logps), b(adv), b(returns), b(values)
        t_learn = time.perf_counter()
        keep = np.flatnonzero(valid.reshape(-1))
        mb = len(keep) // a.minibatches
        for _ in range(a.epochs):
            idx = np.random.permutation(keep)
            for s in range(0, mb * a.minibatches, mb):
                i = idx[s : s + mb]
                _, lp, ent, v = agent.act(bg[i], bf[i], bm[i], ba[i])
                ratio = (lp - blp[i]).exp()
                ad = badv[i]
                ad = (ad - ad.mean()) / (torch.clamp(ad.std(), min=a.adv_floor) + 1e-8)
                pg = torch.max(-ad * ratio, -ad * ratio.clamp(1 - a.clip, 1 + a.clip)).mean()
                v_clipped = bv[i] + (v - bv[i]).clamp(-a.clip, a.clip)
                vl = 0.5 * torch.max((v - bret[i]) ** 2, (v_clipped - bret[i]) ** 2).mean()
                loss = pg - a.ent_coef * ent.mean() + a.vf_coef * vl
                opt.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(agent.parameters(), a.max_grad_norm)
                opt.step()
        learn_s += time.perf_counter() - t_learn
        samples += mb * a.minibatches * a.epochs
        eps = sum(e for e, _ in window)
        rate = sum(s for _, s in window) / eps if eps else float("nan")
        if solved_at is None and eps and rate >= 0.9:
            solved_at = steps
        if update % 10 == 0 or update == updates:
            sps = steps / (time.perf_counter() - t0)
            print(f"update {update}/{updates}  steps {steps}  success {rate:.3f}  {sps:.0f} steps/s")
        if solved_at is not None and a.stop_at_solve:
            break
    elapsed = time.perf_counter() - t0
    print(
        f"done: {steps} env steps in {elapsed:.1f} s ({steps / elapsed:.0f} steps/s); "
        f"success 0.9 first at {solved_at if solved_at is not None else 'never'} env steps; "
        f"PPO updates {samples / learn_s:.0f} samples x epochs/s"
    )


if __name__ == "__main__":
    main()
