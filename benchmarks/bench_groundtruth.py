"""Ground-truth speed: Monte-Carlo Q^pi (500 pairs x 100 roll-outs) and the TD baseline.

Goals (issue 4): each under 10 s on 2 cores. Baselines measured in the same
process: MC one pair at a time (the pairs x roll-outs batch split up), and the
TD updates as a pure-Python loop, each on a slice and scaled up.
"""

from __future__ import annotations

import time

import numpy as np

from geoq.baselines import StateActionGrid, sarsa_evaluate, td_baseline
from geoq.evaluation import mc_q_values, mse, sample_evaluation_pairs
from geoq.policies import default_policy
from geoq.rollouts import collect_rollouts

N_PAIRS = 500
N_ROLLOUTS = 100
GOAL_S = 10.0


def _timed(fn, *args, **kwargs):  # type: ignore[no-untyped-def]
    start = time.perf_counter()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - start


def _python_sarsa(cells, acts, rewards, gamma, step_size, n_cells, n_actions):  # type: ignore[no-untyped-def]
    table = [[0.0] * n_actions for _ in range(n_cells)]
    visits = [[0] * n_actions for _ in range(n_cells)]
    for e in range(len(rewards)):
        c, a, r = cells[e], acts[e], rewards[e]
        for t in range(len(r)):
            i, j = c[t], a[t]
            visits[i][j] += 1
            alpha = max(1.0 / visits[i][j], step_size)
            table[i][j] += alpha * (r[t] + gamma * table[c[t + 1]][a[t + 1]] - table[i][j])
    return table


def main(quick: bool = False) -> None:
    """``quick``: tiny sizes, figures of no meaning (``benchmarks/run.py --quick``)."""
    n_pairs, n_rollouts, n_episodes = (20, 5, 20) if quick else (N_PAIRS, N_ROLLOUTS, 800)
    policy = default_policy()
    states, actions = sample_evaluation_pairs(n_pairs, policy, np.random.default_rng(1))

    est, t_mc = _timed(mc_q_values, states, actions, policy, np.random.default_rng(2), n_rollouts)
    n_slow = 2 if quick else 10
    _, t_slow = _timed(
        lambda: [
            mc_q_values(states[i : i + 1], actions[i : i + 1], policy, rng, n_rollouts)
            for i, rng in enumerate(np.random.default_rng(3).spawn(n_slow))
        ]
    )
    t_slow_full = t_slow * n_pairs / n_slow
    print(f"MC ground truth, {n_pairs} pairs x {n_rollouts} roll-outs x horizon {est.horizon}")
    print(f"  vectorised over pairs and roll-outs  {t_mc:7.2f} s   (goal < {GOAL_S:.0f} s)")
    print(
        f"  one pair at a time (from {n_slow} pairs)   {t_slow_full:7.2f} s   "
        f"({t_slow_full / t_mc:.0f}x slower)"
    )
    print(
        f"  standard error: mean {est.stderr.mean():.4f}  median {np.median(est.stderr):.4f}  "
        f"max {est.stderr.max():.4f}   (Q range {est.mean.min():.2f} .. {est.mean.max():.2f})"
    )

    # Warm the compiled kernels (numba caches them on disk after the first run).
    _, t_compile = _timed(td_baseline, policy, np.random.default_rng(0), n_episodes=2, steps=2)
    _, t_compile2 = _timed(
        td_baseline, policy, np.random.default_rng(0), n_episodes=2, steps=2, method="sarsa"
    )
    print(
        f"\nTD baseline, {n_episodes} episodes x 150 steps = {150 * n_episodes:,} updates "
        f"(first call incl. compile/cache load: {t_compile + t_compile2:.2f} s)"
    )
    for method in ("td0", "sarsa"):
        td, t_td = _timed(
            td_baseline, policy, np.random.default_rng(4), n_episodes=n_episodes, method=method
        )
        err = mse(td.q(states, actions), est.mean)
        print(
            f"  {method:5s} simulate + update  {t_td:7.3f} s   (goal < {GOAL_S:.0f} s)   "
            f"MSE vs MC {err:7.3f}   (var of MC truth {np.var(est.mean):.2f}; "
            f"{(td.state_visits > 0).sum()} of 3600 cells visited)"
        )

    grid = StateActionGrid.pendulum()
    rollouts = collect_rollouts(n_episodes, 151, policy, np.random.default_rng(4))
    S = np.stack([ro.states for ro in rollouts])
    A = np.stack([ro.actions for ro in rollouts])
    R = np.stack([ro.rewards[:150] for ro in rollouts])
    _, t_upd = _timed(sarsa_evaluate, S, A, R, grid, 0.95, "sarsa")
    n_py = min(80, n_episodes)
    cells, acts = grid.state_index(S[:n_py]).tolist(), grid.action_index(A[:n_py]).tolist()
    _, t_py = _timed(
        _python_sarsa, cells, acts, R[:n_py].tolist(), 0.95, 0.8, grid.n_cells, grid.n_actions
    )
    t_py_full = t_py * n_episodes / n_py
    print(
        f"  SARSA updates only: compiled {t_upd:.4f} s, pure Python loop "
        f"(from {n_py} episodes) {t_py_full:.3f} s"
    )


if __name__ == "__main__":
    main()
