"""Issue 12, class 1: valid-looking but extreme input is rejected up front or gives finite,
right results (never a silent NaN). update, fit, partial_fit, refit and predict agree."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from geoq._validation import MAX_MAGNITUDE
from geoq.gp import NumericalWarning, SparseOnlineGP
from geoq.kernels import GeodesicKernel, ResistanceKernel, SquaredExponential

RNG = np.random.default_rng(0)
X = RNG.uniform(-1, 1, (30, 2))
Y = np.sin(X[:, 0])


def _finite(*arrays: np.ndarray) -> bool:
    return all(np.all(np.isfinite(a)) for a in arrays)


@pytest.mark.parametrize("value", [1e151, 1e300, 1.7e308])
def test_huge_targets_are_refused_by_every_entry_point(value: float) -> None:
    gp = SparseOnlineGP(SquaredExponential(0.5), noise=0.01, max_bv=3).fit(X, Y)
    before = gp.predict(X, return_std=True)
    y_bad = Y.copy()
    y_bad[7] = -value
    for call in (
        lambda: gp.update(X[0], value),
        lambda: gp.partial_fit(X, y_bad),
        lambda: gp.fit(X, y_bad),
        lambda: gp.refit(X, y_bad),
    ):
        with pytest.raises(ValueError, match=r"y must be below 1e\+150.*standardise"):
            call()
    np.testing.assert_array_equal(gp.predict(X, return_std=True)[0], before[0])


@pytest.mark.parametrize("value", [1e151, 1e300])
def test_huge_inputs_are_refused_by_every_entry_point_and_the_kernels(value: float) -> None:
    gp = SparseOnlineGP(SquaredExponential(0.5), noise=0.01, max_bv=3).fit(X, Y)
    X_bad = X.copy()
    X_bad[3, 1] = value
    for call in (
        lambda: gp.update(X_bad[3], 0.0),
        lambda: gp.partial_fit(X_bad, Y),
        lambda: gp.fit(X_bad, Y),
        lambda: gp.refit(X_bad, Y),
        lambda: gp.predict(X_bad),
        lambda: SquaredExponential(0.5)(X_bad),
        lambda: SquaredExponential(0.5).diag(X_bad),
    ):
        with pytest.raises(ValueError, match=r"must be below 1e\+150.*rescale"):
            call()


def test_targets_at_the_bound_stay_finite_when_the_deletion_scores_overflow() -> None:
    y = np.resize([MAX_MAGNITUDE, -MAX_MAGNITUDE], 30)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)  # the tiny noise is floored
        gp = SparseOnlineGP(SquaredExponential(0.5), noise=1e-300, max_bv=3).fit(X, y)
    mean, std = gp.predict(X, return_std=True)
    assert _finite(mean, std) and np.all(std >= 0)
    # alpha^2 overflows: no score ranks the BVs, the newest point goes, and that is counted.
    assert gp.diagnostics.score_clipped > 0


@pytest.mark.parametrize("lengthscale", [1e-300, 1e-160, 1e160, 1e300])
def test_extreme_but_representable_lengthscales_give_right_finite_results(
    lengthscale: float,
) -> None:
    gp = SparseOnlineGP(SquaredExponential(lengthscale), noise=0.01, max_bv=40).fit(X, Y)
    far = X + 0.5
    mean, std = gp.predict(np.vstack([X, far]), return_std=True)
    assert _finite(mean, std) and np.all(std >= 0)
    if lengthscale < 1:  # every distinct pair uncorrelated: each point sees itself only
        np.testing.assert_allclose(mean[:30], Y / 1.01, rtol=1e-12)
        np.testing.assert_array_equal(mean[30:], 0.0)
    else:  # one constant function: the mean of the targets, shrunk by the noise
        assert gp.n_bv == 1
        np.testing.assert_allclose(mean, Y.sum() / (30 + 0.01), rtol=1e-9)


@pytest.mark.parametrize("lengthscale", [1e-310, 5e-324, [1.0, 1e-315]])
def test_lengthscales_whose_reciprocal_overflows_are_refused(lengthscale: object) -> None:
    with pytest.raises(ValueError, match="overflows float64"):
        SquaredExponential(np.asarray(lengthscale))


def test_tiny_lengthscale_with_large_inputs_gives_no_nan() -> None:
    k = SquaredExponential(1e-300)
    Z = np.array([[1e10, 0.0], [1e10, 0.0], [-1e10, 0.0]])
    K = k(Z)
    assert _finite(K)
    np.testing.assert_array_equal(K, [[1, 1, 0], [1, 1, 0], [0, 0, 1]])


@pytest.mark.parametrize("normalize", [True, False])
@pytest.mark.parametrize("attach", [True, False])
@pytest.mark.parametrize("sigma_se", [0.01, 1e-300])
def test_eq5_kernel_far_from_every_node_is_finite(
    normalize: bool, attach: bool, sigma_se: float
) -> None:
    def make() -> GeodesicKernel:
        return GeodesicKernel(
            eps=0.3, method="interpolated", normalize=normalize, attach=attach, sigma_se=sigma_se
        )

    far = np.array([[1e3, -1e3], [1e100, 1e100], [MAX_MAGNITUDE, -MAX_MAGNITUDE], [0.1, 0.1]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        gp = SparseOnlineGP(make(), noise=0.01, max_bv=20).fit(X, Y)
        mean, std = gp.predict(far, return_std=True)
        assert _finite(mean, std) and np.all(std >= 0)
        if attach and normalize:  # a huge attaching cost: the prior far away (unnormalised,
            # every weight underflows to 0 and JC12 eq. 5's sum is 0, as the formula says)
            np.testing.assert_array_equal(mean[:3], 0.0)
            np.testing.assert_allclose(std[:3], 1.0)
        gp.update(far[1], 0.5)  # an update far away keeps the state finite
        mean, std = gp.predict(X, return_std=True)
        assert _finite(mean, std) and np.all(std >= 0)


def test_resistance_kernel_far_from_every_node_is_finite() -> None:
    gp = SparseOnlineGP(ResistanceKernel(eps=0.3), noise=0.01, max_bv=20).fit(X, Y)
    mean, std = gp.predict(np.array([[1e100, -1e100], [0.0, 0.0]]), return_std=True)
    assert _finite(mean, std) and np.all(std >= 0)


@pytest.mark.parametrize("variance", [1e-320, 1e-151, 1e151, 1.7e308])
def test_kernel_variances_whose_products_leave_float64_are_refused(variance: float) -> None:
    with pytest.raises(ValueError, match=r"variance \(amplitude\) must be in"):
        SquaredExponential(1.0, variance=variance)
    with pytest.raises(ValueError, match=r"variance \(amplitude\) must be in"):
        GeodesicKernel(eps=0.3, amplitude=variance)
    with pytest.raises(ValueError, match=r"variance \(amplitude\) must be in"):
        ResistanceKernel(eps=0.3, amplitude=variance)
