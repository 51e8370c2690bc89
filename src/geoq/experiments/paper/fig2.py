"""Fig. 2: value maps ``V(s) = Q(s, f(s))`` over a (theta, omega) grid.

``f`` is the policy's deterministic controller (the mean action of the fixed
Gaussian policy), so each map is one slice of ``Q`` through the action the
policy intends; we do *not* maximise over actions (the paper's maps are of
``Q^pi`` of a fixed policy, whose greedy maximum is a different object). The
ground truth is Monte-Carlo ``Q^pi`` at the same state-action pairs.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from geoq._typing import FloatArray
from geoq.evaluation.metrics import mse
from geoq.evaluation.monte_carlo import mc_q_values
from geoq.learners import GPQFunction, QGPConfig
from geoq.policies import GaussianPolicy
from geoq.rollouts import Rollout

__all__ = ["ValueMaps", "state_grid", "value_maps"]


@dataclass(frozen=True)
class ValueMaps:
    """Value maps on a grid.

    Attributes
    ----------
    theta : ``[G]`` grid angles, omega : ``[G]`` grid speeds.
    maps : name -> ``[G, G]`` values, indexed ``[theta, omega]``; ``"monte_carlo"`` is the truth.
    stds : name -> ``[G, G]`` posterior std (GP maps) or standard error (Monte Carlo).
    basis : kernel name -> ``[n_bv, 3]`` basis vectors in raw units.
    mse : kernel name -> MSE of the map against the Monte-Carlo map.
    """

    theta: FloatArray
    omega: FloatArray
    maps: dict[str, FloatArray]
    stds: dict[str, FloatArray]
    basis: dict[str, FloatArray] = field(default_factory=dict)
    mse: dict[str, float] = field(default_factory=dict)

    def rows(self) -> list[dict[str, float | str]]:
        """Tidy rows: one per (map, theta, omega)."""
        out: list[dict[str, float | str]] = []
        for name, values in self.maps.items():
            for i, th in enumerate(self.theta):
                for j, om in enumerate(self.omega):
                    out.append(
                        {
                            "map": name,
                            "theta": float(th),
                            "omega": float(om),
                            "value": float(values[i, j]),
                            "std": float(self.stds[name][i, j]),
                        }
                    )
        return out


def state_grid(n: int, omega_max: float = 8.0) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Grid ``theta [n]`` over [-pi, pi), ``omega [n]`` over +-omega_max, states ``[n*n, 2]``."""
    theta = -np.pi + (np.arange(n, dtype=np.float64) + 0.5) * (2 * np.pi / n)
    omega = np.linspace(-omega_max, omega_max, n, dtype=np.float64)
    T, W = np.meshgrid(theta, omega, indexing="ij")
    states: FloatArray = np.column_stack([T.ravel(), W.ravel()])
    return theta, omega, states


def value_maps(
    rollouts: Sequence[Rollout],
    learners: Mapping[str, QGPConfig],
    policy: GaussianPolicy,
    rng: np.random.Generator,
    grid: int,
    mc_rollouts: int,
    gamma: float,
) -> ValueMaps:
    """Fit one learner per entry of ``learners`` to ``rollouts`` and map ``Q(s, f(s))``."""
    theta, omega, states = state_grid(grid)
    actions = policy.mean_action(states)
    truth = mc_q_values(states, actions, policy, rng, n_rollouts=mc_rollouts, gamma=gamma)
    shape = (grid, grid)
    maps = {"monte_carlo": truth.mean.reshape(shape)}
    stds = {"monte_carlo": truth.stderr.reshape(shape)}
    basis: dict[str, FloatArray] = {}
    errors: dict[str, float] = {}
    for name, cfg in learners.items():
        q = GPQFunction(cfg).fit(rollouts)
        mean, std = q.predict(states, actions, return_std=True)
        maps[name] = mean.reshape(shape)
        stds[name] = std.reshape(shape)
        assert q.gp_ is not None
        basis[name] = cfg.scaling.inverse(q.gp_.basis_vectors)
        errors[name] = mse(mean, truth.mean)
    return ValueMaps(theta, omega, maps, stds, basis, errors)
