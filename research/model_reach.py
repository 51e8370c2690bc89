"""How far the agent's model carries a policy, against the task.

Learns ``GPQAgent(env, seed=seed)`` for ``--steps`` (``--chunk`` at a time, as the
benchmark's evaluations cut it), then rolls its ``policy-net`` model's means out from
the newest 64 episodes' first states under two policies: the action box's centre
(``centre``: the first weights of every search, whose output weights are zero) and the
weights the last search left (``weights``). Per policy: the model's steps until each
roll-out ends (termination output above 1/2), leaves the data (one spacing, where its
halt starts) and halts for sure (two), as medians over the particles (the horizon where
it does neither), the reward it sums until it ends or halts for sure, and beside them the
task's own episodes under the same policy (10, greedy: length and return). Whether the
model's level says anything of a policy's worth on a task (issue 46, part eighteen)::

    python research/model_reach.py Walker2d-v5 --seed 4 --steps 1500 --chunk 500
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

from geoq.agents import GPQAgent


def model_reach(model, starts, act, horizon):  # type: ignore[no-untyped-def]
    """Per particle: the first step each ends, leaves the data and halts (``horizon``: never),
    and the model's reward summed until it ends or halts."""
    P, d = starts.shape
    S, running = starts.copy(), np.ones(P, dtype=bool)
    marks = {name: np.full(P, horizon) for name in ("ends", "leaves", "halts")}
    total = np.zeros(P)
    for t in range(horizon):
        if not running.any():
            break
        rows = np.flatnonzero(running)
        mean = model.predict_mean(S[rows], act(S[rows]))
        S[rows] = S[rows] + mean[:, :d]
        total[rows] += mean[:, d]
        dist = model.support.distance(S[rows])
        for name, hit in (("ends", mean[:, d + 1] > 0.5), ("leaves", dist > 1.0),
                          ("halts", dist >= 2.0)):  # fmt: skip
            first = rows[hit & (marks[name][rows] == horizon)]
            marks[name][first] = t
        running[rows[(mean[:, d + 1] > 0.5) | (dist >= 2.0)]] = False
    return marks, total


def task_episodes(env_id, act, episodes, seed):  # type: ignore[no-untyped-def]
    """Lengths and returns of ``episodes`` greedy episodes of ``act`` on the task."""
    env, lengths, returns = gym.make(env_id), [], []
    for k in range(episodes):
        s, _ = env.reset(seed=seed + k)
        total, steps, done = 0.0, 0, False
        while not done:
            s, r, terminated, truncated, _ = env.step(act(s[None])[0])
            total, steps, done = total + float(r), steps + 1, terminated or truncated
        lengths.append(steps)
        returns.append(total)
    return np.array(lengths), np.array(returns)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env", help="Gymnasium id (or module:id)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=1500)
    parser.add_argument("--chunk", type=int, default=500)
    a = parser.parse_args()
    agent = GPQAgent(a.env, seed=a.seed)
    for done in range(0, a.steps, a.chunk):
        agent.learn(min(a.chunk, a.steps - done))
    planning, feedback = agent.planning, agent.planning.feedback
    model, starts = planning.model, feedback.starts[-64:]
    mid = (agent.action_low + agent.action_high) / 2.0
    policies = {"centre": lambda S: np.broadcast_to(mid, (S.shape[0], mid.shape[0])).copy()}
    if feedback.policy is not None:
        policy, gains = feedback.policy, feedback.gains.copy()
        policies["weights"] = lambda S: policy.act(gains, S)
    print(f"{a.env} seed {a.seed} after {a.steps} steps: "
          f"horizon {feedback.horizon}, data's rewards {model.reward_range}, policy acts "
          f"{feedback.acting}, model's score for the weights {feedback.value:.1f}")  # fmt: skip
    for name, act in policies.items():
        marks, total = model_reach(model, starts, act, feedback.horizon)
        lengths, returns = task_episodes(a.env, act, 10, 10_000)
        medians = ", ".join(f"{k} {np.median(v):.0f}" for k, v in marks.items())
        print(f"{name:>8}: model (median step) {medians}; reward until then "
              f"{np.median(total):.1f}; task: length {np.median(lengths):.0f}, return "
              f"{np.median(returns):.1f} (medians of 10)")  # fmt: skip


if __name__ == "__main__":
    main()
