"""What the model's score of a saved agent's searched policy is made of (issue 46).

On an agent saved by ``research/checkpoint_actors.py --save DIR`` whose ``policy-net``
planner has searched a policy, two things are printed.

- The task's returns of the policy's weights (the acting ones) from ``--episodes``
  fresh starts (reset seeds ``20_000 + e``), with the training actions' Gaussian noise
  at several levels (in half-ranges of the action box; 0 is what greedy actions do,
  ``geoq.agents.policy_planning.EXPLORATION`` what its training episodes do), and the
  episodes' mean length.
- The model's mean return for the weights over several horizons, from the newest 64
  episodes' first states (the starts a search judges from), the steps its halts were paid
  the least reward seen for, and the return with the halts paid nothing: how much of
  the score is the halts' price (docs/design-notes.md, part thirty-four)::

    python research/policy_score.py runs/w3/agent_2000.npz --env Walker2d-v5
"""

from __future__ import annotations

import argparse

import numpy as np

STARTS = 64


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("agent", help="a saved GPQAgent (.npz)")
    parser.add_argument("--env", required=True, help="Gymnasium id (or module:id)")
    parser.add_argument("--episodes", type=int, default=8)
    parser.add_argument("--noise", default="0,0.05,0.1", help="comma-separated levels")
    parser.add_argument("--horizons", default="50,100,200,1000", help="comma-separated")
    args = parser.parse_args()

    import gymnasium as gym

    from geoq.agents import GPQAgent
    from geoq.models import rollout_outcomes

    agent = GPQAgent.load(args.agent, args.env)
    feedback, model = agent.planning.feedback, agent.planning.model
    policy, weights = feedback.policy, feedback.gains
    if policy is None:
        raise SystemExit(f"{args.agent}: no policy searched yet")
    print(f"policy acting: {feedback.acting}; the model's score on record {feedback.value:.1f}; "
          f"its returns on record {np.round(feedback.returns, 1).tolist()}")  # fmt: skip

    env = gym.make(args.env)
    for level in (float(x) for x in args.noise.split(",")):
        rng = np.random.default_rng(0)
        returns, lengths = [], []
        for e in range(args.episodes):
            s, _ = env.reset(seed=20_000 + e)
            total, steps, done = 0.0, 0, False
            while not done:
                a = policy.act(weights, np.asarray(s, dtype=np.float64)[None, :])
                a = a + level * policy.half * rng.standard_normal(a.shape)
                a = np.clip(a, feedback.low, feedback.high)
                s, r, terminated, truncated, _ = env.step(a[0])
                total, steps, done = total + float(r), steps + 1, terminated or truncated
            returns.append(total)
            lengths.append(steps)
        print(f"task, noise {level:g}: return {np.mean(returns):.1f} (least {min(returns):.1f}), "
              f"{np.mean(lengths):.0f} steps")  # fmt: skip

    least = float(model.reward_range[0])
    for horizon in (int(x) for x in args.horizons.split(",")):
        score, halted = rollout_outcomes(model, feedback.starts[-STARTS:],
                                         lambda t, S, rows: policy.act(weights, S), horizon,
                                         gamma=1.0, noise=None)  # fmt: skip
        print(
            f"model, horizon {horizon}: return {score.mean():.1f}, halted steps "
            f"{halted.mean():.1f}, halts paid nothing {np.mean(score - halted * least):.1f}"
        )


if __name__ == "__main__":
    main()
