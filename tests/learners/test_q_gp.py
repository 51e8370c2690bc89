"""The GP Q-function learner: scaling, standardisation, refit, and an exact-GP oracle."""

from __future__ import annotations

import numpy as np
import pytest

from geoq.gp import ExactGP
from geoq.kernels import SquaredExponential
from geoq.learners import PENDULUM_SCALING, GPQFunction, InputScaling, QGPConfig
from geoq.policies import default_policy
from geoq.rollouts import collect_rollouts


@pytest.fixture(scope="module")
def rollouts():
    return collect_rollouts(2, 40, default_policy(), np.random.default_rng(3), gamma=0.95)


def test_scaling_round_trip_and_periods():
    Z = np.array([[np.pi, -8.0, 5.0], [0.1, 2.0, -1.0]])
    X = PENDULUM_SCALING.transform(Z)
    np.testing.assert_allclose(X * np.asarray(PENDULUM_SCALING.scale), Z)
    np.testing.assert_allclose(PENDULUM_SCALING.inverse(X), Z)
    assert PENDULUM_SCALING.scaled_periods()[0] == pytest.approx(
        2 * np.pi / PENDULUM_SCALING.scale[0]
    )
    assert PENDULUM_SCALING.scaled_periods()[1:].tolist() == [0.0, 0.0]


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(scale=(1.0, 0.0), periods=(0, 0), names=("a", "b")),
        dict(scale=(1.0,), periods=(0, 0), names=("a",)),
        dict(scale=(1.0,), periods=(-1.0,), names=("a",)),
    ],
)
def test_scaling_rejects_bad_values(kwargs):
    with pytest.raises(ValueError):
        InputScaling(**kwargs)


def test_euclidean_learner_equals_exact_gp_on_scaled_standardised_data(rollouts):
    cfg = QGPConfig(
        kernel="euclidean", max_bv=1000, tol=0.0, noise=0.05, lengthscale=(0.8, 1.5, 2.0)
    )
    q = GPQFunction(cfg).fit(rollouts)
    Z = np.vstack([np.column_stack([r.states, r.actions]) for r in rollouts])
    y = np.concatenate([r.returns for r in rollouts])
    X = Z / np.asarray(cfg.scaling.scale)
    m, s = y.mean(), y.std()
    exact = ExactGP(SquaredExponential(lengthscale=np.array([0.8, 1.5, 2.0])), noise=0.05).fit(
        X, (y - m) / s
    )
    S = np.array([[0.3, -1.0], [-2.5, 4.0]])
    A = np.array([1.0, -3.0])
    em, es = exact.predict(np.column_stack([S, A]) / np.asarray(cfg.scaling.scale), return_std=True)
    qm, qs = q.predict(S, A, return_std=True)
    np.testing.assert_allclose(qm, m + s * em, rtol=1e-7, atol=1e-7)
    np.testing.assert_allclose(qs, s * es, rtol=1e-7, atol=1e-7)
    np.testing.assert_allclose(q.prior_variance(S, A), s**2 * np.ones(2))


def test_refit_end_equals_gp_refit_on_all_data(rollouts):
    cfg = QGPConfig(kernel="nearest", max_bv=15, eps=0.3, sigma_sp=8.0)
    online = GPQFunction(cfg).fit(rollouts)
    refitted = GPQFunction(cfg.replace(refit="end")).fit(rollouts)
    S, A = rollouts[0].states[:5], rollouts[0].actions[:5]
    manual = online.refit().predict(S, A)
    np.testing.assert_allclose(refitted.predict(S, A), manual, rtol=1e-10, atol=1e-10)


def test_geodesic_learner_graph_follows_basis(rollouts):
    q = GPQFunction(QGPConfig(kernel="interpolated", max_bv=20, sigma_se=0.1)).fit(rollouts)
    gp = q.gp_
    assert gp is not None and gp.n_bv <= 20
    np.testing.assert_array_equal(gp.kernel.graph.nodes, gp.basis_vectors)
    mean, std = q.predict(rollouts[1].states, rollouts[1].actions, return_std=True)
    assert np.all(np.isfinite(mean)) and np.all(std >= 0)


def test_config_round_trip_and_validation():
    cfg = QGPConfig(kernel="interpolated", lengthscale=(1.0, 2.0, 3.0), refit="episode")
    assert QGPConfig.from_dict(cfg.as_dict()) == cfg
    with pytest.raises(ValueError, match="kernel"):
        QGPConfig(kernel="cosine")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="refit"):
        QGPConfig(refit="sometimes")  # type: ignore[arg-type]


def test_unfitted_and_bad_inputs(rollouts):
    q = GPQFunction()
    with pytest.raises(RuntimeError, match="fit"):
        q.predict(np.zeros((1, 2)), np.zeros(1))
    with pytest.raises(ValueError, match="no roll-outs"):
        q.fit([])
    q.fit(rollouts[:1])
    with pytest.raises(ValueError, match="rows"):
        q.predict(np.zeros((2, 2)), np.zeros(3))
    with pytest.raises(ValueError, match="non-finite"):
        q.predict(np.array([[np.nan, 0.0]]), np.zeros(1))


def test_same_seed_same_numbers():
    def run():
        ro = collect_rollouts(2, 30, default_policy(), np.random.default_rng(11))
        return (
            GPQFunction(QGPConfig(kernel="nearest", max_bv=10))
            .fit(ro)
            .predict(ro[0].states, ro[0].actions)
        )

    np.testing.assert_array_equal(run(), run())


# -- issue 12, class 8: a QGPConfig is checked when it is made, not when it first fits -------
@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"max_bv": 0}, "max_bv"),
        ({"max_bv": 2.5}, "max_bv"),
        ({"max_bv": True}, "max_bv"),
        ({"max_bv": 10**30}, "max_bv"),
        ({"tol": 1.5}, "tol"),
        ({"noise": 0.0}, "noise"),
        ({"noise": "0.1"}, "noise"),
        ({"noise": float("nan")}, "noise"),
        ({"amplitude": -1.0}, "amplitude"),
        ({"eps": 1.0}, "eps"),
        ({"sigma_sp": float("inf")}, "sigma_sp"),
        ({"sigma_se": 0}, "sigma_se"),
        ({"resistance_lengthscale": -2}, "resistance_lengthscale"),
        ({"lengthscale": (1.0, 2.0)}, "lengthscale"),
        ({"lengthscale": 1e-320}, "lengthscale"),
        ({"lengthscale": "1"}, "lengthscale"),
        ({"standardize": "yes"}, "standardize"),
        ({"scaling": None}, "scaling"),
        ({"kernel": "rbf"}, "kernel"),
    ],
)
def test_qgp_config_validates_at_construction(changes: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        QGPConfig(**changes)
    with pytest.raises(ValueError, match=field):
        QGPConfig().replace(**changes)


def test_qgp_config_round_trips_and_refuses_unknown_fields() -> None:
    cfg = QGPConfig(lengthscale=(0.5, 1.0, 2.0), noise=0.1)
    assert QGPConfig.from_dict(cfg.as_dict()) == cfg
    with pytest.raises(ValueError, match="unknown learner field"):
        QGPConfig.from_dict({**cfg.as_dict(), "noize": 1.0})


# -- issue 13: fit_twin shares the first roll-out's stream; same bits as two fits ----------
@pytest.mark.parametrize(
    "cfg",
    [
        QGPConfig(kernel="euclidean", max_bv=15),
        QGPConfig(kernel="nearest", max_bv=15, sigma_sp=8.0),
        QGPConfig(kernel="interpolated", max_bv=15, sigma_se=0.1),
        QGPConfig(kernel="resistance", max_bv=15),
        QGPConfig(kernel="nearest", max_bv=15, pd_novelty=True),
    ],
    ids=["euclidean", "nearest", "interpolated", "resistance", "pd_novelty"],
)
def test_fit_twin_equals_two_separate_fits_bit_for_bit(rollouts, cfg: QGPConfig) -> None:
    S, A = rollouts[1].states, rollouts[1].actions
    online = GPQFunction(cfg)
    twin = online.fit_twin(rollouts, "episode")
    alone = GPQFunction(cfg).fit(rollouts)
    twin_alone = GPQFunction(cfg.replace(refit="episode")).fit(rollouts)
    assert twin.config == twin_alone.config
    for got, want in ((online, alone), (twin, twin_alone)):
        assert got.gp_ is not None and want.gp_ is not None
        assert got.gp_.kernel is not want.gp_.kernel
        assert got.gp_.diagnostics == want.gp_.diagnostics
        for a, b in zip(
            got.predict(S, A, return_std=True), want.predict(S, A, return_std=True), strict=True
        ):
            np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(got.gp_.basis_vectors, want.gp_.basis_vectors)
    # the learners are independent: refitting one leaves the other as it was
    before = twin.predict(S, A)
    online.refit()
    np.testing.assert_array_equal(twin.predict(S, A), before)
