"""NextStateCovariances: the kept covariances equal a fresh computation to the bit."""

from __future__ import annotations

import numpy as np
import pytest
from tests.agents._tasks import PointToGoal

from geoq.agents import GPQAgent
from geoq.agents._covariance_cache import GROWTH, NextStateCovariances, separable_factors
from geoq.kernels import SquaredExponential


def _candidate_inputs(candidates: np.ndarray):  # type: ignore[no-untyped-def]
    def inputs(states: np.ndarray) -> np.ndarray:
        K = len(candidates)
        return np.hstack([np.repeat(states, K, axis=0), np.tile(candidates, (len(states), 1))])

    return inputs


@pytest.mark.parametrize("period", [None, (2.0, 0.0, 0.0)])
def test_reused_covariances_equal_a_fresh_computation_bit_for_bit(period) -> None:  # type: ignore[no-untyped-def]
    """Oracle: ``kernel.to_basis`` on the whole matrix, over phases where the window
    grows then slides and basis vectors are added, deleted and reordered."""
    rng = np.random.default_rng(0)
    kernel = SquaredExponential(lengthscale=(0.3, 0.5, 0.8), period=period)
    candidates = np.linspace(-1, 1, 5)[:, None]
    inputs = _candidate_inputs(candidates)
    states = rng.uniform(-1, 1, size=(400, 2))
    basis = rng.uniform(-1, 1, size=(30, 3))
    cache = NextStateCovariances(min_slots=20)
    window = 150
    for i, total in enumerate((40, 90, 160, 160, 230, 300, 320, 340, 360, 380, 400)):
        first = max(0, total - window)
        keep = rng.permutation(len(basis))[: len(basis) - 4]  # delete 4, reorder the rest
        basis = np.vstack([basis[keep], rng.uniform(-1, 1, size=(6, 3))])  # add 6
        # every other phase, scratch rows (imagined next states) after the held ones:
        # computed afresh, and the next phase's new transitions overwrite them
        scratch = rng.uniform(-1, 1, size=(i % 2 * (7 + 20 * i), 2))
        got, slots = cache.get(
            kernel, inputs, states[first:total], first, basis, len(candidates),
            scratch_states=scratch if len(scratch) else None,
        )  # fmt: skip
        assert got.shape[0] == (total - first + len(scratch)) * len(candidates)
        assert len(set(slots.tolist())) == len(basis) and np.all(np.isfinite(got))
        np.testing.assert_array_equal(
            got[:, slots], kernel.to_basis(inputs(np.vstack([states[first:total], scratch])), basis)
        )
    cache.clear()
    got, slots = cache.get(kernel, inputs, states[:10], 0, basis, len(candidates))
    np.testing.assert_array_equal(got[:, slots], kernel.to_basis(inputs(states[:10]), basis))
    # a jump backwards starts afresh
    got, slots = cache.get(kernel, inputs, states[:5], 0, basis, len(candidates))
    np.testing.assert_array_equal(got[:, slots], kernel.to_basis(inputs(states[:5]), basis))


def test_a_kept_basis_vector_keeps_its_slot_and_freed_slots_are_reused() -> None:
    kernel = SquaredExponential(lengthscale=0.5)
    inputs = _candidate_inputs(np.zeros((1, 1)))
    states = np.linspace(0, 1, 8)[:, None]
    basis = np.arange(10.0).reshape(5, 2)
    cache = NextStateCovariances()
    _, slots = cache.get(kernel, inputs, states, 0, basis, 1)
    assert slots.tolist() == [0, 1, 2, 3, 4]
    # delete rows 1 and 3, reorder, add two new ones: they take the freed slots 1 and 3
    basis2 = np.vstack([basis[[4, 0, 2]], [[50.0, 51.0], [60.0, 61.0]]])
    _, slots2 = cache.get(kernel, inputs, states, 0, basis2, 1)
    assert slots2.tolist() == [4, 0, 2, 1, 3]


def test_agents_learn_the_same_with_and_without_reuse(monkeypatch: pytest.MonkeyPatch) -> None:
    """A sliding window (60 transitions), uniform and graph replay: same curves, same bits,
    when every phase's matrix is computed afresh (in the same slot columns, zeros in
    the free ones: the zero-weight columns' stale values do not count)."""
    kept_get = NextStateCovariances.get

    def fresh(self, kernel, inputs, next_states, first, basis, n_candidates, scratch_states=None):  # type: ignore[no-untyped-def]
        kept, slots = kept_get(
            self, kernel, inputs, next_states, first, basis, n_candidates, scratch_states
        )
        if scratch_states is not None:
            next_states = np.vstack([next_states, scratch_states])
        out = np.zeros_like(kept)
        out[:, slots] = kernel.to_basis(inputs(next_states), basis)
        return out, slots

    def run(replay: str) -> GPQAgent:
        agent = GPQAgent(PointToGoal(), seed=1, gamma=0.9, max_bv=40, window=60, replay=replay)
        return agent.learn(300)

    reused = {r: run(r) for r in ("uniform", "graph")}
    monkeypatch.setattr(NextStateCovariances, "get", fresh)
    for replay, agent in reused.items():
        again = run(replay)
        assert again.episodes == agent.episodes
        np.testing.assert_array_equal(again.buffer.targets(), agent.buffer.targets())
        obs = np.linspace(-1, 1, 9)[:, None]
        np.testing.assert_array_equal(again.predict(obs)[0], agent.predict(obs)[0])


def test_a_kernel_that_follows_its_basis_is_refused() -> None:
    agent = GPQAgent(PointToGoal(), kernel="resistance", max_bv=10)
    with pytest.raises(ValueError, match="follows its basis"):
        NextStateCovariances().get(
            agent.gp.kernel, lambda s: s, np.zeros((1, 1)), 0, np.zeros((1, 2)), 1
        )


def test_the_buffer_stays_within_growth_of_a_sliding_window() -> None:
    """Memory: the rows held never exceed GROWTH x the window's, however long the run."""
    kernel = SquaredExponential(lengthscale=0.5)
    inputs = _candidate_inputs(np.zeros((1, 1)))
    states = np.linspace(0, 1, 2_000)[:, None]
    basis = np.zeros((3, 2))
    cache = NextStateCovariances()
    window = 100
    for total in range(25, 2_000, 25):
        first = max(0, total - window)
        got, slots = cache.get(kernel, inputs, states[first:total], first, basis, 1)
        assert got.shape == (total - first, 3)
        assert cache._K.shape[0] <= GROWTH * window + 1
    np.testing.assert_array_equal(
        got[:, slots], kernel.to_basis(inputs(states[first:total]), basis)
    )


@pytest.mark.parametrize("lengthscale", [0.4, (0.3, 0.5, 0.7, 0.9)])
def test_separable_factors_multiply_to_the_kernel(lengthscale) -> None:  # type: ignore[no-untyped-def]
    """Oracle: ``k_s(s, s_j) k_a(a, a_j)`` is the squared exponential on ``[s, a]``, wrapped
    angle included; the state factor is evaluated against the full basis vectors."""
    rng = np.random.default_rng(5)
    kernel = SquaredExponential(lengthscale=lengthscale, variance=1.7, period=(2.0, 0.0, 0.0, 0.0))
    factors = separable_factors(kernel, 2)
    assert factors is not None
    state, action = factors
    assert not state.tracks_basis
    S, A = rng.uniform(-2, 2, (30, 2)), rng.uniform(-1, 1, (7, 2))
    basis = rng.uniform(-2, 2, (9, 4))
    product = state.to_basis(S, basis)[:, None, :] * action.to_basis(A, basis[:, 2:])[None]
    joint = np.hstack([np.repeat(S, len(A), axis=0), np.tile(A, (len(S), 1))])
    np.testing.assert_allclose(product.reshape(-1, 9), kernel.to_basis(joint, basis), rtol=1e-13)


def test_only_an_unchanged_squared_exponential_is_separable() -> None:
    class Shifted(SquaredExponential):
        def to_basis(self, X: np.ndarray, basis: np.ndarray) -> np.ndarray:
            return super().to_basis(X, basis) + 1.0

    assert separable_factors(Shifted(lengthscale=0.5), 1) is None
    agent = GPQAgent(PointToGoal(), kernel="resistance", max_bv=10)
    assert separable_factors(agent.gp.kernel, 1) is None
