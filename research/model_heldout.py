"""How the agent's dynamics model predicts transitions it has not seen (issue 46).

On an agent saved by ``research/checkpoint_actors.py --save DIR`` (or any saved
``GPQAgent``), the model the agent's ``policy-net`` planner fits (its settings,
``geoq.agents.policy_planning.NET_MODEL``) is fitted to the first ``--train``
transitions stored and asked for the next ones (at most 1,000): the transitions a model
fitted at that point would be asked about next. Printed per row: the state changes'
RMSE over their std in the training data (mean, median and largest over the state's
inputs; a constant input left out), the reward's the same way, the terminations the
model says (probability above 1/2) at terminations and elsewhere, and the fit's time.
Rows: no change at all, the least-squares linear step, and the model with and without
``residual_noise`` (docs/design-notes.md, part thirty-three); ``--mlp K`` adds an
ensemble of ``K`` MBPO-sized networks (4 layers of 200 SiLU units, bootstrapped, Adam,
200 epochs; the mean of the members), which needs ``torch``::

    python research/model_heldout.py runs/w6/agent_3000.npz --train 2500 [--mlp 3]
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from typing import Any

import numpy as np

HELD_OUT = 1000


def relative_errors(pred: np.ndarray, change: np.ndarray, rewards: np.ndarray,
                    train_change: np.ndarray, train_rewards: np.ndarray) -> str:  # fmt: skip
    """The state changes' and the reward's RMSE over their training std."""
    std = train_change.std(axis=0)
    live = std > 1e-9
    rel = np.sqrt(np.mean((pred[:, : change.shape[1]] - change) ** 2, axis=0))[live] / std[live]
    reward = np.sqrt(np.mean((pred[:, change.shape[1]] - rewards) ** 2)) / train_rewards.std()
    return (f"state changes {rel.mean():.3f} (median {np.median(rel):.3f}, largest "
            f"{rel.max():.3f}); reward {reward:.3f}")  # fmt: skip


def mlp_ensemble(X: np.ndarray, Y: np.ndarray, Xq: np.ndarray, members: int) -> np.ndarray:
    """The mean prediction ``[Q, J]`` of ``members`` bootstrapped networks (module docstring)."""
    import torch

    torch.set_num_threads(1)
    torch.manual_seed(0)
    xm, xs = X.mean(axis=0), X.std(axis=0) + 1e-8
    ym, ys = Y.mean(axis=0), Y.std(axis=0) + 1e-8
    Xt, Yt = torch.tensor((X - xm) / xs), torch.tensor((Y - ym) / ys)
    Xqt, out = torch.tensor((Xq - xm) / xs), []
    for k in range(members):
        width, layers = 200, []
        for n_in in (X.shape[1], width, width):
            layers += [torch.nn.Linear(n_in, width), torch.nn.SiLU()]
        net = torch.nn.Sequential(*layers, torch.nn.Linear(width, Y.shape[1])).double()
        opt = torch.optim.Adam(net.parameters(), lr=1e-3, weight_decay=1e-5)
        rng = np.random.default_rng(k)
        boot = rng.choice(len(X), size=len(X))
        for _ in range(200):
            order = rng.permutation(boot)
            for b in range(0, len(order), 256):
                rows = order[b : b + 256]
                loss = ((net(Xt[rows]) - Yt[rows]) ** 2).mean()
                opt.zero_grad()
                loss.backward()
                opt.step()
        with torch.no_grad():
            out.append(net(Xqt).numpy() * ys + ym)
    return np.mean(out, axis=0)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("agent", help="a saved GPQAgent (.npz)")
    parser.add_argument("--train", type=int, required=True, help="transitions fitted")
    parser.add_argument("--mlp", type=int, default=0, help="members of the networks' ensemble")
    parser.add_argument("--rng", type=int, default=0, help="the fits' generator seed")
    args = parser.parse_args(argv)

    from geoq.agents import GPQAgent
    from geoq.agents.policy_planning import NET_MODEL
    from geoq.models import GPDynamicsModel

    agent: Any = GPQAgent.load(args.agent)
    data, d = agent.buffer.transitions(), agent.obs_dim
    if not 2 <= args.train < len(data):
        parser.error(f"--train must be in [2, {len(data)}), the transitions stored")
    fit, ask = slice(0, args.train), slice(args.train, args.train + HELD_OUT)
    S, A, R, S2, T = (data.states, data.actions, data.rewards, data.next_states,
                      data.terminated)  # fmt: skip
    change, train_change = S2[ask] - S[ask], S2[fit] - S[fit]
    print(f"{args.agent}: {args.train} transitions fitted, {len(R[ask])} asked "
          f"({int(T[ask].sum())} terminations among them)")  # fmt: skip

    def row(name: str, pred: np.ndarray, ends: Any = None, spent: float = 0.0) -> None:
        said = "" if ends is None else (
            f"; terminations said {int(np.sum(ends & T[ask]))}/{int(T[ask].sum())}, "
            f"elsewhere {int(np.sum(ends & ~T[ask]))}")  # fmt: skip
        print(f"{name:>22}: {relative_errors(pred, change, R[ask], train_change, R[fit])}{said}"
              + (f"; {spent:.1f} s" if spent else ""))  # fmt: skip

    row("no change", np.column_stack([np.zeros_like(change), np.full(len(change), R[fit].mean())]))
    X = np.column_stack([S[fit], A[fit], np.ones(args.train)])
    W, *_ = np.linalg.lstsq(X, np.column_stack([train_change, R[fit]]), rcond=None)
    row("linear least squares", np.column_stack([S[ask], A[ask], np.ones(len(R[ask]))]) @ W)
    for flag in (False, True):
        model = GPDynamicsModel(d, agent.action_dim, replace(NET_MODEL, residual_noise=flag))
        start = time.perf_counter()
        model.fit(S[fit], A[fit], R[fit], S2[fit], T[fit], np.random.default_rng(args.rng))
        spent = time.perf_counter() - start
        mean = model.predict_mean(S[ask], A[ask])
        row(f"model, residual {'on' if flag else 'off'}", mean, mean[:, d + 1] > 0.5, spent)
    if args.mlp:
        start = time.perf_counter()
        Y = np.column_stack([train_change, R[fit]])
        pred = mlp_ensemble(np.hstack([S[fit], A[fit]]), Y, np.hstack([S[ask], A[ask]]), args.mlp)
        row(f"{args.mlp} networks", pred, None, time.perf_counter() - start)


if __name__ == "__main__":
    main()
