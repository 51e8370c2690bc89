"""What ``Q``'s evidence fit says about the actions, by how many points it sees (issue 46,
part twenty-seven).

``hyperparameters="evidence"`` fits the squared exponential's ARD length-scales to at most
``GPQConfig.evidence_points`` (300 by default) of the stored inputs and their standardised
targets. On each saved agent given (``research/checkpoint_actors.py --save DIR`` keeps
them, or any ``GPQAgent.save`` file), this fits the same evidence
(``fit_squared_exponential``, no restart, started from the median heuristic) to
``--points`` random subsets of the agent's window, one per size, and prints per fit: the
log evidence per point, the noise, each action length-scale over the action box's side
(scaled; at most 1 opens the actor's gate,
:func:`geoq.agents.q_actor.curves_inside`), the median state length-scale, and the fit's
seconds::

    python research/checkpoint_actors.py Walker2d-v5 --seed 3 --save runs/w3
    python research/evidence_points.py runs/w3/agent_2500.npz --points 300 1000 2500

With ``--bias``, each subset is also fitted with ``k_s(s, s') (w + (1 - w) k_a(a, a'))``,
a value of the state plus an advantage (a dueling split: the action factor's constant
``w`` lets the state's part ignore the actions while the advantage's part resolves them),
from several starts of ``w`` and of the action length-scales; it prints the best fit's
``w`` beside the same columns. Nothing in the agents is changed.
"""

from __future__ import annotations

import argparse
import itertools
import time
import warnings
from pathlib import Path

import numpy as np
import scipy.linalg
import scipy.optimize

from geoq.agents import GPQAgent
from geoq.gp.evidence import LOG_BOUNDS, fit_squared_exponential
from geoq.gp.numerics import NumericalWarning


def window_data(agent: GPQAgent) -> tuple[np.ndarray, np.ndarray]:
    """The inputs ``[n, d]`` and standardised targets ``[n]`` a refit of ``agent`` reads."""
    c, st, buffer = agent.config, agent.state, agent.buffer
    stored = buffer.transitions(last=c.window)
    z = (buffer.targets(last=c.window) - st.y_mean) / st.y_scale
    return agent.inputs(stored.states, stored.actions), z


class BiasEvidence:
    """``-log p(z | X)`` and its gradient for ``var k_s (w + (1 - w) k_a) + noise I``;
    ``theta = (log l_1..d, log var, log noise, logit w)``, the last ``d_a`` inputs the
    actions."""

    def __init__(self, X: np.ndarray, z: np.ndarray, d_a: int) -> None:
        self.z, self.d_a, self.d = z, d_a, X.shape[1]
        self.D2 = np.ascontiguousarray(np.moveaxis((X[:, None, :] - X[None, :, :]) ** 2, 2, 0))

    def __call__(self, theta: np.ndarray) -> tuple[float, np.ndarray]:
        d, s = self.d, self.d - self.d_a
        inv_l2 = np.exp(-2.0 * theta[:d])
        var, noise = np.exp(theta[d]), np.exp(theta[d + 1])
        w = 1.0 / (1.0 + np.exp(-theta[d + 2]))
        Ks = np.exp(-0.5 * np.tensordot(inv_l2[:s], self.D2[:s], axes=1))
        Ka = np.exp(-0.5 * np.tensordot(inv_l2[s:], self.D2[s:], axes=1))
        VK = var * Ks * (w + (1.0 - w) * Ka)
        n = len(self.z)
        L = np.linalg.cholesky(VK + (noise + 1e-10) * np.eye(n))
        alpha = scipy.linalg.cho_solve((L, True), self.z)
        log_ev = -0.5 * self.z @ alpha - np.log(np.diag(L)).sum() - 0.5 * n * np.log(2 * np.pi)
        W = np.outer(alpha, alpha) - scipy.linalg.cho_solve((L, True), np.eye(n))
        grad = np.empty_like(theta)
        grad[:s] = 0.5 * np.tensordot(self.D2[:s], W * VK, axes=2) * inv_l2[:s]
        Wa = W * (var * Ks * (1.0 - w) * Ka)
        grad[s:d] = 0.5 * np.tensordot(self.D2[s:], Wa, axes=2) * inv_l2[s:]
        grad[d] = 0.5 * np.sum(W * VK)
        grad[d + 1] = 0.5 * np.trace(W) * noise
        grad[d + 2] = 0.5 * np.sum(W * var * Ks * (1.0 - Ka)) * w * (1.0 - w)
        return -log_ev, -grad


def fit_bias(X: np.ndarray, z: np.ndarray, d_a: int, start: np.ndarray) -> tuple[np.ndarray, float]:
    """The best of :class:`BiasEvidence`'s L-BFGS-B runs from ``w`` in 0.5 / 0.9 / 0.99 and
    the action length-scales at ``start``'s or 0.5 / 1 / 2: ``(theta, log evidence)``."""
    objective, d = BiasEvidence(X, z, d_a), X.shape[1]
    bounds = [LOG_BOUNDS["lengthscale"]] * d + [LOG_BOUNDS["variance"], LOG_BOUNDS["noise"],
                                                (-12.0, 12.0)]  # fmt: skip
    best: scipy.optimize.OptimizeResult | None = None
    for w0, la in itertools.product((0.5, 0.9, 0.99), (None, 0.5, 1.0, 2.0)):
        ls0 = np.array(start, dtype=float)
        if la is not None:
            ls0[d - d_a :] = la
        var = np.var(z)
        theta0 = np.r_[np.log(ls0), np.log(var), np.log(var / 10), np.log(w0 / (1 - w0))]
        run = scipy.optimize.minimize(objective, theta0, jac=True, method="L-BFGS-B", bounds=bounds)
        if best is None or run.fun < best.fun:
            best = run
    assert best is not None
    return best.x, -float(best.fun)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("agents", type=Path, nargs="+", help="saved GPQAgent files")
    parser.add_argument("--points", type=int, nargs="+", default=[300, 1000])
    parser.add_argument("--bias", action="store_true", help="also fit the value + advantage split")
    parser.add_argument("--seed", type=int, default=0, help="of the subsets drawn")
    args = parser.parse_args()
    for path in args.agents:
        agent = GPQAgent.load(path)
        X, z = window_data(agent)
        d_a = agent.action_high.shape[0]
        box = (agent.action_high - agent.action_low) / np.asarray(agent.scaling.scale)[-d_a:]
        print(f"{path}: {len(z)} stored transitions, {X.shape[1]} inputs, box side (scaled) "
              f"{np.round(box, 3)}")  # fmt: skip
        for n in args.points:
            rng = np.random.default_rng(args.seed)
            idx = rng.choice(len(z), size=min(n, len(z)), replace=False)
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", NumericalWarning)
                fit = fit_squared_exponential(
                    X[idx], z[idx], ard=True, max_points=len(idx), n_restarts=0,
                    rng=np.random.default_rng(1),
                )  # fmt: skip
            ls = np.broadcast_to(np.asarray(fit.kernel.lengthscale), (X.shape[1],))
            print(f"  SE   n {len(idx):5d}  log evidence / n {fit.log_evidence / len(idx):7.3f}  "
                  f"noise {fit.noise:.2g}  action ls / side {np.round(ls[-d_a:] / box, 2)}  "
                  f"state ls median {np.median(ls[:-d_a]):.2f}  "
                  f"{time.perf_counter() - t0:.0f} s", flush=True)  # fmt: skip
            if args.bias:
                theta, log_ev = fit_bias(X[idx], z[idx], d_a, ls)
                d = X.shape[1]
                lsb, w = np.exp(theta[:d]), 1.0 / (1.0 + np.exp(-theta[d + 2]))
                print(f"  bias n {len(idx):5d}  log evidence / n {log_ev / len(idx):7.3f}  "
                      f"noise {np.exp(theta[d + 1]):.2g}  action ls / side "
                      f"{np.round(lsb[-d_a:] / box, 2)}  state ls median "
                      f"{np.median(lsb[:-d_a]):.2f}  w {w:.3f}", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
