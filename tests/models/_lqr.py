"""A double integrator with quadratic cost and its LQR solution (scipy's Riccati
equation): the oracle the planner's and the policy search's tests share."""

from __future__ import annotations

import numpy as np
import scipy.linalg

from geoq.models import GPDynamicsModel, ModelSettings

DT = 0.1
A_SYS = np.array([[1.0, DT], [0.0, 1.0]])  # a double integrator: position, velocity
B_SYS = np.array([[0.0], [DT]])
Q_COST, R_COST = np.diag([1.0, 0.1]), np.array([[0.01]])


def lqr() -> tuple[np.ndarray, np.ndarray]:
    """``P`` (cost-to-go ``s^T P s``) and the gain ``K`` (``a = -K s``), undiscounted."""
    P = scipy.linalg.solve_discrete_are(A_SYS, B_SYS, Q_COST, R_COST)
    K = np.linalg.solve(R_COST + B_SYS.T @ P @ B_SYS, B_SYS.T @ P @ A_SYS)
    return P, K


def reward(S: np.ndarray, A: np.ndarray) -> np.ndarray:
    """``-s^T Q s - a^T R a`` of states ``[P, 2]`` and actions ``[P, 1]``."""
    return -np.einsum("pi,ij,pj->p", S, Q_COST, S) - np.einsum("pi,ij,pj->p", A, R_COST, A)


def true_return(act, starts: np.ndarray, T: int) -> float:  # type: ignore[no-untyped-def]
    """The mean return over ``T`` steps of the true system from ``starts`` [P, 2] under
    ``act(states [P, 2]) -> actions [P, 1]``, by a plain loop."""
    S, total = starts.copy(), 0.0
    for _ in range(T):
        A = act(S)
        total += reward(S, A).sum()
        S = S @ A_SYS.T + A @ B_SYS.T
    return total / len(starts)


def learned_model(rng: np.random.Generator, action_bound: float) -> GPDynamicsModel:
    """A GP model (150 basis vectors) fitted to 400 transitions of states uniform on
    ``[-2, 2]^2`` and actions uniform on ``[-action_bound, action_bound]``."""
    S = rng.uniform(-2.0, 2.0, size=(400, 2))
    A = rng.uniform(-action_bound, action_bound, size=(400, 1))
    S2 = S @ A_SYS.T + A @ B_SYS.T
    return GPDynamicsModel(2, 1, ModelSettings(max_bv=150)).fit(
        S, A, reward(S, A), S2, np.zeros(400), rng
    )


class Everywhere:
    """A support that has seen every state."""

    def distance(self, S: np.ndarray) -> np.ndarray:
        return np.zeros(len(S))
