"""Fitted Q-iteration on a fixed basis: value iteration oracle and the GP's own refit."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from hypothesis import given, settings
from hypothesis import strategies as st

from geoq.agents.fitted_q import (
    DenseCandidates,
    SeparableCandidates,
    _best_candidates,
    _bootstrap,
    fitted_q_sweeps,
)
from geoq.gp import CONFIG, SparseOnlineGP
from geoq.gp._resync import ProjectedSystem, projected_system
from geoq.kernels import SquaredExponential

N_STATES, GAMMA = 11, 0.9
ACTIONS = np.array([-1.0, 1.0])


def _chain() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every (state, action) of a deterministic chain: -1 per step, terminal at the right end."""
    s = np.repeat(np.arange(N_STATES), 2)
    a = np.tile(ACTIONS, N_STATES)
    s2 = np.clip(s + a.astype(int), 0, N_STATES - 1)
    X = np.column_stack([s / (N_STATES - 1), a])
    Xn = np.column_stack([np.repeat(s2 / (N_STATES - 1), 2), np.tile(ACTIONS, len(s2))])
    rewards = -np.ones(len(s))
    continues = (s2 != N_STATES - 1).astype(float)
    return X, Xn, rewards, continues, s2


def _value_iteration() -> np.ndarray:
    """Q*(s, a) by brute-force value iteration, in the order of :func:`_chain`."""
    _, _, rewards, continues, s2 = _chain()
    q = np.zeros(len(rewards))
    for _ in range(500):
        v = q.reshape(N_STATES, 2).max(axis=1)
        q = rewards + GAMMA * continues * v[s2]
    return q


def _features(
    kernel: SquaredExponential, X: np.ndarray, Xn: np.ndarray, bv: np.ndarray, noise: float
) -> tuple[ProjectedSystem, np.ndarray]:
    """The projected system of ``X`` on ``bv`` (factor of ``K_BV`` by plain Cholesky) and the
    next-state covariances."""
    R = scipy.linalg.cholesky(kernel(bv), lower=False)
    return projected_system(kernel, X, bv, R, noise, CONFIG), kernel(Xn, bv)


def test_interpolating_basis_gives_the_optimal_q_of_a_deterministic_chain() -> None:
    X, Xn, rewards, continues, _ = _chain()
    kernel = SquaredExponential(lengthscale=np.array([0.03, 0.5]))
    system, Kn = _features(kernel, X, Xn, X, 1e-10)
    res = fitted_q_sweeps(
        system, Kn, rewards, continues, GAMMA, np.zeros(len(rewards)),
        y_mean=-5.0, y_scale=3.0, max_sweeps=500, tol=1e-10,
    )  # fmt: skip
    np.testing.assert_allclose(res.targets, _value_iteration(), atol=1e-6)
    assert res.sweeps < 500 and res.max_change <= 1e-10


def test_one_sweep_equals_bootstrapping_from_the_gp_refit() -> None:
    """The whitened sweep is the DTC posterior of SparseOnlineGP.refit on the same basis."""
    X, Xn, rewards, continues, _ = _chain()
    kernel = SquaredExponential(lengthscale=np.array([0.2, 0.8]))
    rng = np.random.default_rng(0)
    gp = SparseOnlineGP(kernel, noise=0.05, max_bv=8).fit(X, rng.normal(size=len(X)))
    bv = gp.basis_vectors
    y0 = rng.normal(size=len(X)) * 2 - 3
    y_mean, y_scale = -3.0, 2.0
    gp.refit(X, (y0 - y_mean) / y_scale)
    q_next = y_mean + y_scale * gp.predict(Xn).reshape(len(X), 2).max(axis=1)
    expected = rewards + GAMMA * continues * q_next
    system, Kn = _features(kernel, X, Xn, bv, 0.05)
    res = fitted_q_sweeps(
        system, Kn, rewards, continues, GAMMA, y0,
        y_mean=y_mean, y_scale=y_scale, max_sweeps=1, tol=0.0,
    )  # fmt: skip
    assert res.sweeps == 1
    np.testing.assert_allclose(res.targets, expected, rtol=1e-9, atol=1e-9)


def test_bounds_clip_every_target() -> None:
    X, Xn, rewards, continues, _ = _chain()
    kernel = SquaredExponential(lengthscale=np.array([0.03, 0.5]))
    system, Kn = _features(kernel, X, Xn, X, 1e-10)
    res = fitted_q_sweeps(
        system, Kn, rewards, continues, GAMMA, np.zeros(len(rewards)),
        y_mean=0.0, y_scale=1.0, max_sweeps=500, tol=1e-10, bounds=(-3.0, -1.0),
    )  # fmt: skip
    assert res.targets.min() >= -3.0 and res.targets.max() <= -1.0
    assert res.targets.min() == pytest.approx(-3.0)  # far states are clipped


def test_active_candidate_sweeps_reach_the_fixed_point_of_full_sweeps() -> None:
    """Pruned sweeps (best 1 of 2 candidates between full sweeps) end where full sweeps end."""
    X, Xn, rewards, continues, _ = _chain()
    kernel = SquaredExponential(lengthscale=np.array([0.15, 0.8]))
    rng = np.random.default_rng(1)
    gp = SparseOnlineGP(kernel, noise=0.01, max_bv=12).fit(X, rng.normal(size=len(X)))
    system, Kn = _features(kernel, X, Xn, gp.basis_vectors, 0.01)
    common = dict(y_mean=-4.0, y_scale=2.0, max_sweeps=2_000, tol=1e-11)
    args = (system, Kn, rewards, continues, GAMMA, np.zeros(len(rewards)))
    full = fitted_q_sweeps(*args, **common, n_active=2, refresh_every=1)  # type: ignore[arg-type]
    pruned = fitted_q_sweeps(*args, **common, n_active=1, refresh_every=7)  # type: ignore[arg-type]
    assert full.sweeps < 2_000 and pruned.sweeps < 2_000
    np.testing.assert_allclose(pruned.targets, full.targets, atol=1e-9)


def test_slot_columns_give_the_plain_layouts_targets() -> None:
    """Basis columns permuted into slots among columns of junk (zero weight) change nothing
    but rounding."""
    X, Xn, rewards, continues, _ = _chain()
    kernel = SquaredExponential(lengthscale=np.array([0.15, 0.8]))
    gp = SparseOnlineGP(kernel, noise=0.01, max_bv=12).fit(X, -np.arange(len(X), dtype=float))
    system, Kn = _features(kernel, X, Xn, gp.basis_vectors, 0.01)
    m = Kn.shape[1]
    rng = np.random.default_rng(3)
    slots = rng.permutation(m + 5)[:m]
    wide = rng.uniform(-1e3, 1e3, size=(Kn.shape[0], m + 5))  # finite junk where no BV sits
    wide[:, slots] = Kn
    common = dict(y_mean=-4.0, y_scale=2.0, max_sweeps=300, tol=1e-11)
    args = (rewards, continues, GAMMA, np.zeros(len(rewards)))
    plain = fitted_q_sweeps(system, Kn, *args, **common)  # type: ignore[arg-type]
    slotted = fitted_q_sweeps(system, wide, *args, **common, slots=slots)  # type: ignore[arg-type]
    assert slotted.sweeps == plain.sweeps
    np.testing.assert_allclose(slotted.targets, plain.targets, rtol=0, atol=1e-10)


def _separable(kernel: SquaredExponential, Xn: np.ndarray, bv: np.ndarray) -> SeparableCandidates:
    """The chain's next-state covariances as a state factor [N, m] and an action factor [2, m]."""
    state, action = kernel.restricted(slice(0, 1), kernel.variance), kernel.restricted(slice(1, 2))
    next_states = Xn[:: len(ACTIONS), :1]
    return SeparableCandidates(state(next_states, bv[:, :1]), action(ACTIONS[:, None], bv[:, 1:]))


def test_separable_covariances_are_the_dense_ones() -> None:
    """Oracle: the product of the factors is the kernel on the joint inputs, and one matrix
    product gives every ``Q(s'_i, a_k)`` of the dense mat-vec."""
    X, Xn, *_ = _chain()
    kernel = SquaredExponential(lengthscale=np.array([0.15, 0.8]), variance=2.5)
    bv = X[::3]
    sep, dense = _separable(kernel, Xn, bv), DenseCandidates(kernel(Xn, bv), len(ACTIONS))
    assert (sep.n_candidates, sep.n_columns) == (dense.n_candidates, dense.n_columns)
    rng = np.random.default_rng(4)
    w = rng.normal(size=len(bv))
    np.testing.assert_allclose(sep.q(w), dense.q(w), rtol=1e-13, atol=1e-13)
    top = rng.integers(0, len(ACTIONS), size=(len(Xn) // len(ACTIONS), 3))  # repeats allowed
    np.testing.assert_allclose(
        sep.restrict(top).q(w), dense.restrict(top).q(w), rtol=1e-13, atol=1e-13
    )


@pytest.mark.parametrize("n_active", [1, None])
def test_separable_sweeps_are_the_dense_sweeps(n_active: int | None) -> None:
    """Same sweeps, pruned (the best candidate between full sweeps) or not, as with the
    dense matrix: the separable form changes how ``Q(s', a_k)`` is computed, not what."""
    X, Xn, rewards, continues, _ = _chain()
    kernel = SquaredExponential(lengthscale=np.array([0.15, 0.8]))
    gp = SparseOnlineGP(kernel, noise=0.01, max_bv=12).fit(X, -np.arange(len(X), dtype=float))
    bv = gp.basis_vectors
    system, Kn = _features(kernel, X, Xn, bv, 0.01)
    common = dict(y_mean=-4.0, y_scale=2.0, max_sweeps=300, tol=1e-11, n_active=n_active)
    args = (rewards, continues, GAMMA, np.zeros(len(rewards)))
    dense = fitted_q_sweeps(system, Kn, *args, **common, refresh_every=7)  # type: ignore[arg-type]
    sep = fitted_q_sweeps(system, _separable(kernel, Xn, bv), *args, **common, refresh_every=7)  # type: ignore[arg-type]
    assert sep.sweeps == dense.sweeps < 300
    np.testing.assert_allclose(sep.targets, dense.targets, rtol=0, atol=1e-10)


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), K=st.integers(1, 25), n=st.integers(1, 5))
def test_best_candidates_are_the_n_largest_of_each_row(seed: int, K: int, n: int) -> None:
    """Oracle: a full sort. With ties (rounded values) the set may differ, its values not."""
    n = min(n, K)
    rng = np.random.default_rng(seed)
    q = np.round(rng.normal(size=(30, K)), 1)
    top = _best_candidates(q, n)
    assert top.shape == (30, n)
    for row, cols in zip(q, top, strict=True):
        assert len(set(cols.tolist())) == n
        np.testing.assert_array_equal(np.sort(row[cols]), np.sort(row)[K - n :])


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), K=st.integers(1, 6))
def test_bootstrap_is_the_numpy_expression_bit_for_bit(seed: int, K: int) -> None:
    rng = np.random.default_rng(seed)
    N = 40
    q, y = rng.normal(size=(N, K)), rng.normal(size=N) * 5
    rewards, continues = rng.normal(size=N), (rng.random(N) < 0.8).astype(float)
    y_mean, y_scale, gamma, lo, hi = -1.3, 2.7, 0.95, -6.0, 4.0
    expected = np.clip(rewards + gamma * continues * (y_mean + y_scale * q.max(axis=1)), lo, hi)
    y_new = np.empty(N)
    change = _bootstrap(q, rewards, gamma * continues, y_mean, y_scale, lo, hi, y, y_new)
    assert y_new.tobytes() == expected.tobytes()
    assert change == np.max(np.abs(expected - y))
