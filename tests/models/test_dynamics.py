"""The dynamics model against the exact GP, and its batched prediction against each GP's own."""

from __future__ import annotations

import numpy as np
import pytest

from geoq._io import ArchiveError
from geoq.gp import ExactGP, SparseOnlineGP
from geoq.kernels.stationary import SquaredExponential
from geoq.models import GPDynamicsModel, ModelSettings


def _transitions(n: int, rng: np.random.Generator, d_s: int = 2, d_a: int = 1):
    """Non-linear steps with a reward and terminations: ``(S, A, R, S2, T)``."""
    S = rng.uniform(-1.0, 1.0, size=(n, d_s))
    A = rng.uniform(-1.0, 1.0, size=(n, d_a))
    change = np.column_stack(
        [np.sin(4.0 * S[:, 0]) * A[:, 0], np.cos(3.0 * S[:, -1]) + S[:, 0] * A[:, -1]]
        + [0.1 * S[:, j] for j in range(2, d_s)]
    )
    R = -np.sum(S**2, axis=1) - 0.1 * np.sum(A**2, axis=1)
    T = (S[:, 0] > 0.8).astype(float)
    return S, A, R, S + 0.1 * change, T


def _outputs(S, A, R, S2, T):
    return np.column_stack([S2 - S, R, T])


@pytest.mark.parametrize("linear_mean", [False, True])
def test_every_output_is_the_exact_gp_when_every_transition_is_a_basis_vector(
    linear_mean: bool,
) -> None:
    """Each output is the exact GP of its deviations from its prior mean: the data's mean,
    or (``linear_mean``) the least-squares linear function of the standardised inputs."""
    rng = np.random.default_rng(0)
    data = _transitions(25, rng)
    settings = ModelSettings(max_bv=100, tol=0.0, linear_mean=linear_mean)
    model = GPDynamicsModel(2, 1, settings).fit(*data, rng)
    Sq, Aq = rng.uniform(-1.2, 1.2, size=(9, 2)), rng.uniform(-1.0, 1.0, size=(9, 1))
    mean, std = model.predict(Sq, Aq)
    Y = _outputs(*data)
    X = (np.hstack(data[:2]) - model.x_mean) / model.x_scale
    Xq = (np.hstack([Sq, Aq]) - model.x_mean) / model.x_scale
    if linear_mean:
        weights = np.linalg.lstsq(X, Y - Y.mean(axis=0), rcond=None)[0]
        np.testing.assert_allclose(model.linear, weights, rtol=1e-9, atol=1e-12)
    else:
        assert not model.linear.any()
    prior, prior_q = Y.mean(axis=0) + X @ model.linear, Y.mean(axis=0) + Xq @ model.linear
    exact_outputs = 0
    for j, gp in enumerate(model.gps):
        assert gp is not None  # every output varies in these data
        if gp.n_bv < len(Y):  # a near-duplicate input (novelty floor): not the exact GP
            continue
        exact_outputs += 1
        kernel = SquaredExponential(gp.kernel.lengthscale, variance=gp.kernel.variance)
        z = (Y[:, j] - prior[:, j]) / model.y_scale[j]
        mu, sd = ExactGP(kernel, gp.noise).fit(X, z).predict(Xq, return_std=True)
        np.testing.assert_allclose(mean[:, j], prior_q[:, j] + model.y_scale[j] * mu,
                                   rtol=1e-7, atol=1e-9)  # fmt: skip
        # The variance is the prior's less a near-equal term: accurate to the prior's 1e-9.
        np.testing.assert_allclose(std[:, j] ** 2, (model.y_scale[j] * sd) ** 2,
                                   rtol=0, atol=1e-9 * model.prior_std[j] ** 2)  # fmt: skip
    assert exact_outputs >= 3


def test_batched_prediction_is_each_gps_own_prediction() -> None:
    rng = np.random.default_rng(1)
    data = _transitions(400, rng, d_s=3, d_a=2)
    model = GPDynamicsModel(3, 2, ModelSettings(max_bv=40)).fit(*data, rng)
    for i in range(5):  # online steps after the fit
        model.observe(*(np.asarray(x)[i] for x in _transitions(5, rng, 3, 2)))
    Sq, Aq = rng.uniform(-2, 2, size=(33, 3)), rng.uniform(-1, 1, size=(33, 2))
    mean, std = model.predict(Sq, Aq)
    Xq = (np.hstack([Sq, Aq]) - model.x_mean) / model.x_scale
    for j, gp in enumerate(model.gps):
        assert gp is not None
        mu, sd = gp.predict(Xq, return_std=True)
        expected = model.y_mean[j] + model.y_scale[j] * mu
        if j == 3:  # the reward: within the rewards seen
            expected = np.clip(expected, *model.reward_range)
        np.testing.assert_allclose(mean[:, j], expected, rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(std[:, j] ** 2, (model.y_scale[j] * sd) ** 2,
                                   rtol=0, atol=1e-9 * model.prior_std[j] ** 2)  # fmt: skip
    assert np.all(std >= 0)


def test_far_from_the_data_the_std_is_the_prior_std() -> None:
    rng = np.random.default_rng(2)
    model = GPDynamicsModel(2, 1).fit(*_transitions(200, rng), rng)
    _, std = model.predict(np.full((1, 2), 1e3), np.zeros((1, 1)))
    np.testing.assert_allclose(std[0], model.prior_std, rtol=1e-9)


def test_the_predicted_reward_stays_within_the_rewards_seen() -> None:
    rng = np.random.default_rng(8)
    S, A, _, S2, T = _transitions(200, rng)
    R = np.where(S[:, 0] > 0.5, 0.0, 1.0)  # a jump: the GP overshoots beside it
    model = GPDynamicsModel(2, 1).fit(S, A, R, S2, T, rng)
    Sq = np.column_stack([np.linspace(-1.5, 1.5, 301), np.zeros(301)])
    mean, _ = model.predict(Sq, np.zeros((301, 1)))
    assert mean[:, 2].min() >= 0.0 and mean[:, 2].max() <= 1.0
    model.observe(S[0], A[0], 3.0, S2[0], False)
    assert np.array_equal(model.reward_range, [0.0, 3.0])


def test_a_constant_output_is_its_constant_without_uncertainty() -> None:
    rng = np.random.default_rng(3)
    S, A, R, S2, _ = _transitions(100, rng)
    model = GPDynamicsModel(2, 1).fit(S, A, R, S2, np.zeros(100), rng)
    assert model.gps[3] is None and model.prior_std[3] == 0.0
    mean, std = model.predict(S[:4], A[:4])
    assert np.all(mean[:, 3] == 0.0) and np.all(std[:, 3] == 0.0)


def test_a_linear_step_is_learned_exactly_and_extrapolated_with_a_linear_mean() -> None:
    """``s' = s + 0.1 (M s + B a)``, reward linear, no termination: the prior means are the
    step itself, nothing is left for the GPs, and the model is exact far from the data."""
    rng = np.random.default_rng(11)
    M, B = np.array([[0.0, 1.0], [-2.0, -0.3]]), np.array([[0.0], [1.5]])
    S, A = rng.uniform(-1, 1, size=(200, 2)), rng.uniform(-1, 1, size=(200, 1))
    step = lambda S, A: S + 0.1 * (S @ M.T + A @ B.T)  # noqa: E731
    reward = lambda S, A: 1.0 - S[:, 0] + 0.5 * A[:, 0]  # noqa: E731
    data = (S, A, reward(S, A), step(S, A), np.zeros(200))
    model = GPDynamicsModel(2, 1, ModelSettings(linear_mean=True)).fit(*data, rng)
    assert all(gp is None for gp in model.gps)
    Sq, Aq = rng.uniform(-5, 5, size=(7, 2)), rng.uniform(-1, 1, size=(7, 1))
    model.reward_range = np.array([-np.inf, np.inf])  # the rewards far away are not clipped
    mean, std = model.predict(Sq, Aq)
    np.testing.assert_allclose(mean[:, :2], step(Sq, Aq) - Sq, rtol=0, atol=1e-9)
    np.testing.assert_allclose(mean[:, 2], reward(Sq, Aq), rtol=0, atol=1e-9)
    assert np.all(std == 0.0)


def _walled(n: int, rng: np.random.Generator):
    """A smooth step, but a state past the wall at ``s_0 = 0.95`` is thrown back to ``s_0 = 0``
    (a contact: one jump the smooth step does not explain)."""
    S, A = rng.uniform(-1, 1, size=(n, 2)), rng.uniform(-1, 1, size=(n, 1))
    S2 = S + 0.05 * np.column_stack([S[:, 1] + A[:, 0], np.sin(3 * S[:, 0]) - S[:, 1]])
    hit = S[:, 0] > 0.95
    S2[hit, 0] = 0.0
    return (S, A, -np.abs(S[:, 0]), S2, np.zeros(n)), hit


def _brute_force_outliers(model: GPDynamicsModel, S, A, S2, mads: float) -> np.ndarray:
    """The outlier test by hand, with numpy alone (the model uses scipy's MAD): least
    squares, the median, and the MAD scaled by ``1 / Phi^-1(3/4)``."""
    X = (np.hstack([S, A]) - model.x_mean) / model.x_scale
    Y = S2 - S - (S2 - S).mean(axis=0)
    res = Y - X @ np.linalg.lstsq(X, Y, rcond=None)[0]
    med = np.median(res, axis=0)
    mad = 1.482602218505602 * np.median(np.abs(res - med), axis=0)
    return np.any(np.abs(res - med) > mads * mad, axis=1)


def test_transitions_the_smooth_step_does_not_explain_are_left_out_of_the_state_changes() -> None:
    """Every jump at the wall is an outlier and nothing else is (against a hand-made test);
    left out, the state changes' GPs learn the smooth step far better away from the wall,
    while the reward's GP still takes every transition."""
    rng = np.random.default_rng(12)
    data, hit = _walled(800, rng)
    trimmed = GPDynamicsModel(2, 1, ModelSettings(outlier_mads=6.0)).fit(
        *data, np.random.default_rng(0)
    )
    plain = GPDynamicsModel(2, 1).fit(*data, np.random.default_rng(0))
    flagged = _brute_force_outliers(trimmed, data[0], data[1], data[3], 6.0)
    assert np.array_equal(flagged, hit) and trimmed.n_outliers == hit.sum() > 10
    assert plain.n_outliers == 0
    (Sq, Aq, _, S2q, _), hit_q = _walled(300, rng)
    inside = ~hit_q & (Sq[:, 0] < 0.6)
    error = {name: np.abs(m.predict_mean(Sq, Aq)[:, :2] - (S2q - Sq))[inside].mean()
             for name, m in (("trimmed", trimmed), ("plain", plain))}  # fmt: skip
    assert error["trimmed"] < 0.2 * error["plain"], error
    reward_gp = trimmed.gps[2]
    assert reward_gp is not None and reward_gp.n_bv > 0


def test_an_outlier_streamed_in_leaves_the_state_changes_as_they_were() -> None:
    rng = np.random.default_rng(13)
    data, _ = _walled(300, rng)
    model = GPDynamicsModel(2, 1, ModelSettings(outlier_mads=6.0)).fit(*data, rng)
    q = (rng.uniform(-0.5, 0.5, size=(5, 2)), rng.uniform(-1, 1, size=(5, 1)))
    before, seen = model.predict_mean(*q), model.n_outliers
    model.observe([0.97, 0.1], [0.5], -0.97, [0.0, 0.1], False)  # thrown back by the wall
    after = model.predict_mean(*q)
    assert model.n_outliers == seen + 1 and np.array_equal(after[:, :2], before[:, :2])
    model.observe([0.1, 0.1], [0.5], -0.1, [0.13, 0.1 + 0.05 * (np.sin(0.3) - 0.1)], False)
    assert model.n_outliers == seen + 1 and not np.array_equal(
        model.predict_mean(*q)[:, :2], after[:, :2]
    )


def test_the_same_seed_gives_the_same_model() -> None:
    data = _transitions(300, np.random.default_rng(4))
    a = GPDynamicsModel(2, 1).fit(*data, np.random.default_rng(5))
    b = GPDynamicsModel(2, 1).fit(*data, np.random.default_rng(5))
    q = (data[0][:20], data[1][:20])
    assert all(np.array_equal(x, y) for x, y in zip(a.predict(*q), b.predict(*q), strict=True))


@pytest.mark.parametrize(
    "settings",
    [
        ModelSettings(max_bv=50),
        ModelSettings(max_bv=50, linear_mean=True),
        ModelSettings(max_bv=50, outlier_mads=3.0),
        ModelSettings(max_bv=50, standardised_support=True),
        ModelSettings(max_bv=50, residual_noise=False),
    ],
)
def test_arrays_round_trip_and_the_model_continues_identically(settings: ModelSettings) -> None:
    rng = np.random.default_rng(6)
    data = _transitions(200, rng)
    model = GPDynamicsModel(2, 1, settings).fit(*data, rng)
    copy = GPDynamicsModel.from_arrays(model.to_arrays())
    more = _transitions(10, rng)
    for m in (model, copy):
        for i in range(10):
            m.observe(*(np.asarray(x)[i] for x in more))
    q = (more[0], more[1])
    for x, y in zip(model.predict(*q), copy.predict(*q), strict=True):
        assert np.array_equal(x, y)
    assert GPDynamicsModel.from_arrays(GPDynamicsModel(2, 1).to_arrays()).fitted is False
    assert copy.settings == model.settings


def test_a_model_saved_before_linear_means_loads_with_the_datas_mean() -> None:
    """Archives of the first version: four settings and no ``linear`` weights."""
    rng = np.random.default_rng(8)
    model = GPDynamicsModel(2, 1).fit(*_transitions(60, rng), rng)
    arrays = model.to_arrays()
    old = {k: v for k, v in arrays.items() if k != "linear"} | {"settings": arrays["settings"][:4]}
    copy = GPDynamicsModel.from_arrays(old)
    assert copy.settings.linear_mean is False and not copy.linear.any()
    q = _transitions(5, rng)[:2]
    assert np.array_equal(copy.predict_mean(*q), model.predict_mean(*q))


def test_a_model_saved_before_the_residual_noise_loads_without_it() -> None:
    """Archives of 8 settings were fitted with the evidence's noise however the budget fit."""
    rng = np.random.default_rng(8)
    settings = ModelSettings(residual_noise=False)
    model = GPDynamicsModel(2, 1, settings).fit(*_transitions(60, rng), rng)
    arrays = model.to_arrays()
    assert arrays["settings"].shape == (9,)
    copy = GPDynamicsModel.from_arrays({**arrays, "settings": arrays["settings"][:8]})
    assert copy.settings == model.settings


def _budget_bound(seed: int, residual_noise: bool) -> tuple[GPDynamicsModel, tuple]:
    """A model of 15 basis vectors per output on 400 transitions of a sharp simulator, and
    the transitions."""
    rng = np.random.default_rng(seed)
    data = _transitions(400, rng, d_s=3, d_a=2)
    settings = ModelSettings(max_bv=15, fit_points=60, residual_noise=residual_noise)
    return GPDynamicsModel(3, 2, settings).fit(*data, np.random.default_rng(seed + 1)), data


def test_a_budget_that_misses_its_transitions_takes_the_residual_as_noise() -> None:
    """Oracle: the evidence's GP streamed by hand, its mean squared residual at the
    transitions, and a GP streamed again with that residual as its noise variance."""
    evidence, data = _budget_bound(3, residual_noise=False)
    model, _ = _budget_bound(3, residual_noise=True)
    X = (np.hstack(data[:2]) - model.x_mean) / model.x_scale
    Y = _outputs(*data)
    raised = 0
    for j, (first, gp) in enumerate(zip(evidence.gps, model.gps, strict=True)):
        assert first is not None and gp is not None
        z = (Y[:, j] - model.y_mean[j]) / model.y_scale[j]
        residual = float(np.mean((first.predict(X) - z) ** 2))
        assert np.array_equal(gp.kernel.lengthscale, first.kernel.lengthscale)
        if residual <= first.noise:
            assert gp.noise == first.noise
            assert np.array_equal(gp.predict(X), first.predict(X))
            continue
        raised += 1
        assert gp.noise == residual
        again = SparseOnlineGP(first.kernel, noise=residual, max_bv=15, tol=first.tol).fit(X, z)
        assert np.array_equal(gp.predict(X), again.predict(X))
    assert raised >= 1  # the data are made so that some output's budget misses them


def test_a_budget_that_holds_every_transition_keeps_the_evidences_noise() -> None:
    """The exact GP's residuals at its data are below its noise (their expectation is
    ``sigma^2 tr(sigma^2 (K + sigma^2 I)^-1) / N``): the same model either way."""
    data = _transitions(25, np.random.default_rng(0))
    a, b = (GPDynamicsModel(2, 1, ModelSettings(max_bv=100, tol=0.0, residual_noise=flag))
            .fit(*data, np.random.default_rng(1)) for flag in (True, False))  # fmt: skip
    q = _transitions(9, np.random.default_rng(2))[:2]
    assert all(np.array_equal(x, y) for x, y in zip(a.predict(*q), b.predict(*q), strict=True))


def test_on_fresh_transitions_the_residual_noise_predicts_better() -> None:
    """The pathology the setting is for: with the evidence's noise the termination's
    15 basis vectors predict fresh transitions worse than their mean does (a mean squared
    error 23 times their variance); with the residual as noise, within a third of it."""
    evidence, _ = _budget_bound(5, residual_noise=False)
    model, _ = _budget_bound(5, residual_noise=True)
    q = _transitions(500, np.random.default_rng(105), d_s=3, d_a=2)
    Y = _outputs(*q)
    before, after = (np.mean((m.predict_mean(*q[:2]) - Y) ** 2, axis=0) / Y.var(axis=0)
                     for m in (evidence, model))  # fmt: skip
    assert before[-1] > 10.0 and after[-1] < 0.35
    assert np.all(after <= before + 0.01)


def test_the_residual_noise_is_refused_unless_it_is_0_or_1() -> None:
    rng = np.random.default_rng(7)
    arrays = GPDynamicsModel(2, 1).fit(*_transitions(50, rng), rng).to_arrays()
    bad = arrays["settings"].copy()
    bad[8] = 0.5
    with pytest.raises(ArchiveError, match="residual_noise"):
        GPDynamicsModel.from_arrays({**arrays, "settings": bad})


def test_the_standardised_support_counts_an_input_no_output_depends_on() -> None:
    """A state input the step ignores: the default support does not see a state far along
    it, the standardised one does; brute force: the nearest seen state in data units."""
    rng = np.random.default_rng(9)
    S = rng.uniform(-1.0, 1.0, size=(150, 2))
    A = rng.uniform(-1.0, 1.0, size=(150, 1))
    S2 = S + np.column_stack([np.zeros(150), 0.1 * A[:, 0] + 0.3 * np.sin(3 * S[:, 1])])  # not 0
    data = (S, A, np.ones(150), S2, np.zeros(150))
    relevance = GPDynamicsModel(2, 1).fit(*data, np.random.default_rng(10))
    standard = GPDynamicsModel(2, 1, ModelSettings(standardised_support=True)).fit(
        *data, np.random.default_rng(10)
    )
    far = np.array([[6.0, 0.0]])  # far along the ignored input
    assert 10 * relevance.support.distance(far)[0] < standard.support.distance(far)[0]
    seen = np.vstack([S, S2]) / standard.x_scale[:2]
    nearest = np.min(np.linalg.norm(seen - far / standard.x_scale[:2], axis=1))
    assert standard.support.distance(far)[0] == pytest.approx(nearest / standard.support.spacing)


def test_a_damaged_model_is_an_archive_error() -> None:
    rng = np.random.default_rng(7)
    arrays = GPDynamicsModel(2, 1).fit(*_transitions(50, rng), rng).to_arrays()
    for key, bad in (("x_scale", np.array([1.0, -1.0, 1.0])), ("y_mean", np.ones(2)),
                     ("dims", np.array([2])), ("linear", np.ones((3, 4))),
                     ("linear", np.ones((2, 4))), ("settings", np.array([50, 300, 1, 0, 0.5])),
                     ("settings", np.ones(8)), ("outlier_mad", np.zeros(2)),
                     ("outlier_line", np.ones((3, 3))), ("n_outliers", np.array(-1))):  # fmt: skip
        with pytest.raises(ArchiveError, match="dynamics model"):
            GPDynamicsModel.from_arrays({**arrays, key: bad})


def _zeros(n: int = 3, d_a: int = 1, n_next: int = 3, reward: object = None) -> tuple:
    rewards = np.zeros(n) if reward is None else reward
    return np.zeros((n, 2)), np.zeros((n, d_a)), rewards, np.zeros((n_next, 2)), np.zeros(n)


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (_zeros(n_next=2), "rows"),
        (_zeros(d_a=2), "actions"),
        (_zeros(reward=[0.0, np.nan, 0.0]), "rewards"),
        (_zeros(n=1, n_next=1), "at least 2"),
    ],
)
def test_bad_transitions_are_refused(args, match) -> None:
    with pytest.raises(ValueError, match=match):
        GPDynamicsModel(2, 1).fit(*args, np.random.default_rng(0))


def test_predict_and_observe_need_a_fit() -> None:
    with pytest.raises(RuntimeError, match="fit"):
        GPDynamicsModel(2, 1).predict(np.zeros((1, 2)), np.zeros((1, 1)))
    with pytest.raises(RuntimeError, match="fit"):
        GPDynamicsModel(2, 1).observe(np.zeros(2), np.zeros(1), 0.0, np.zeros(2), False)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("max_bv", 0),
        ("fit_points", 1),
        ("restarts", -1),
        ("tol", 2.0),
        ("outlier_mads", -1.0),
        ("outlier_mads", float("nan")),
    ],
)
def test_bad_settings_are_refused(field: str, value: float) -> None:
    with pytest.raises(ValueError, match=field):
        ModelSettings(**{field: value})


def test_a_drawn_step_is_the_mean_plus_the_std_times_the_generators_normals() -> None:
    """``draw`` asks only the state changes for their std: the same numbers as ``predict``'s,
    with the generator's normals in the same order."""
    rng = np.random.default_rng(14)
    data = _transitions(150, rng, d_s=3, d_a=2)
    model = GPDynamicsModel(3, 2, ModelSettings(max_bv=40)).fit(*data, rng)
    S, A = data[0][:9], data[1][:9]
    mean, S2 = model.draw(S, A, np.random.default_rng(15))
    expected_mean, std = model.predict(S, A)
    z = np.random.default_rng(15).standard_normal((9, 3))
    assert np.array_equal(mean, expected_mean)
    assert np.array_equal(S2, S + expected_mean[:, :3] + std[:, :3] * z)
    assert np.all(std[:, :3] > 0)
