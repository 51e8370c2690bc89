"""Property-based fuzzing of the public entry points (issue 12).

The rule checked everywhere: a call either raises a clear ``ValueError`` (``ArchiveError``
for files) and leaves the model as it was, or returns finite, right results. Examples are
drawn from extreme but representable floats (tiny, huge, subnormal, NaN/inf, wrong
shapes); the profile is deterministic (``derandomize=True``) and small (~30 s in total).
A longer run: ``HYPOTHESIS_FUZZ_EXAMPLES=500 pytest tests/test_fuzz.py``.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from tests._fuzz import fuzz_settings

from geoq._io import ArchiveError
from geoq._validation import MAX_MAGNITUDE
from geoq.experiments.paper.config import config_for_scale, config_with_overrides
from geoq.gp import NumericalWarning, SparseOnlineGP
from geoq.kernels import GeodesicKernel, ResistanceKernel, SquaredExponential

FUZZ = fuzz_settings(100)

#: Floats a hostile but realistic user passes: ordinary, extreme, subnormal, non-finite.
EXTREME = st.one_of(
    st.floats(-3, 3),
    st.sampled_from([0.0, -0.0, 1e-300, 5e-324, 1e-160, 1e149, -1e149, 1e150, 1e151, 1e300,
                     -1e300, 1.7e308, np.inf, -np.inf, np.nan]),
)  # fmt: skip
POSITIVE = st.one_of(
    st.floats(1e-3, 1e3),
    st.sampled_from([1e-320, 5e-324, 1e-300, 1e-160, 1e-10, 1e10, 1e160, 1e300, 1.7e308]),
)

RNG = np.random.default_rng(7)
X0 = RNG.uniform(-1, 1, (25, 2))
Y0 = np.sin(3 * X0[:, 0])
XT = RNG.uniform(-1.5, 1.5, (6, 2))

KERNELS = {
    "se": lambda: SquaredExponential(0.5),
    "nearest": lambda: GeodesicKernel(eps=0.3, method="nearest"),
    "interpolated": lambda: GeodesicKernel(
        eps=0.9, method="interpolated", normalize=True, attach=True
    ),
    "resistance": lambda: ResistanceKernel(eps=0.3),
}


def _gp(name: str) -> SparseOnlineGP:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        return SparseOnlineGP(KERNELS[name](), noise=0.01, max_bv=12).fit(X0, Y0)


def _state(gp: SparseOnlineGP) -> tuple[Any, ...]:
    mu, S = gp.whitened_posterior
    return gp.n_bv, gp.basis_vectors, mu, S, gp.cholesky_factor, gp.diagnostics


def _same(a: tuple[Any, ...], b: tuple[Any, ...]) -> bool:
    return all(
        np.array_equal(u, v) if isinstance(u, np.ndarray) else u == v
        for u, v in zip(a, b, strict=True)
    )


def _valid_prediction(gp: SparseOnlineGP, X: np.ndarray) -> None:
    mean, std = gp.predict(X, return_std=True)
    assert mean.shape == std.shape == (X.shape[0],)
    assert np.all(np.isfinite(mean)) and np.all(np.isfinite(std)) and np.all(std >= 0)


def _acceptable(X: np.ndarray | None, y: np.ndarray | None) -> bool:
    """What every entry point accepts: finite numbers of magnitude <= MAX_MAGNITUDE."""
    return all(
        a is None or (np.all(np.isfinite(a)) and np.all(np.abs(a) <= MAX_MAGNITUDE)) for a in (X, y)
    )


def _apply(gp: SparseOnlineGP, call: Any, accept: bool) -> None:
    """The rule: accepted -> finite predictions; refused -> ValueError, state unchanged."""
    before = _state(gp)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        try:
            call()
        except ValueError as exc:
            assert str(exc), "an error must say what went wrong"
            assert not accept, f"refused acceptable input: {exc}"
            assert _same(_state(gp), before), "a refused call changed the model"
            return
        assert accept, "accepted input it documents as refused"
        _valid_prediction(gp, XT)


@pytest.fixture(scope="module")
def gps() -> dict[str, SparseOnlineGP]:
    return {name: _gp(name) for name in KERNELS}


@FUZZ
@given(name=st.sampled_from(sorted(KERNELS)), x=st.lists(EXTREME, min_size=2, max_size=2),
       y=EXTREME)  # fmt: skip
def test_update(gps: dict[str, SparseOnlineGP], name: str, x: list[float], y: float) -> None:
    gp = gps[name]
    xa, ya = np.array(x), np.array([y])
    _apply(gp, lambda: gp.update(xa, y), _acceptable(xa, ya))


@FUZZ
@given(
    name=st.sampled_from(sorted(KERNELS)),
    row=st.integers(0, 9),
    col=st.integers(0, 2),
    value=EXTREME,
    method=st.sampled_from(["partial_fit", "fit", "refit"]),
)
def test_batches(
    gps: dict[str, SparseOnlineGP], name: str, row: int, col: int, value: float, method: str
) -> None:
    gp = gps[name] if method != "fit" else _gp(name)
    X = RNG.uniform(-1, 1, (10, 2))
    y = np.cos(X[:, 1])
    if col < 2:
        X[row, col] = value
    else:
        y[row] = value
    _apply(gp, lambda: getattr(gp, method)(X, y), _acceptable(X, y))


@FUZZ
@given(name=st.sampled_from(sorted(KERNELS)), value=EXTREME, n=st.integers(0, 5))
def test_predict(gps: dict[str, SparseOnlineGP], name: str, value: float, n: int) -> None:
    gp = gps[name]
    X = np.vstack([XT[:n], [[value, -value]]])
    before = _state(gp)
    if not _acceptable(X, None):
        with pytest.raises(ValueError):
            gp.predict(X, return_std=True)
    else:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NumericalWarning)
            _valid_prediction(gp, X)
    assert _same(_state(gp)[:5], before[:5])  # predict changes nothing but repair counts


@FUZZ
@given(shape=st.sampled_from([(3,), (3, 3), (3, 1), (0, 2), (2, 2, 2)]))
def test_shapes_are_checked(gps: dict[str, SparseOnlineGP], shape: tuple[int, ...]) -> None:
    gp = gps["se"]
    X = np.zeros(shape)
    ok = len(shape) == 2 and shape[1] == 2
    _apply(gp, lambda: gp.partial_fit(X, np.zeros(shape[0])), ok)


@FUZZ
@given(lengthscale=POSITIVE, variance=POSITIVE, noise=POSITIVE)
def test_gp_hyperparameters(lengthscale: float, variance: float, noise: float) -> None:
    try:
        kernel = SquaredExponential(lengthscale, variance=variance)
        gp = SparseOnlineGP(kernel, noise=noise, max_bv=10)
    except ValueError as exc:
        assert str(exc)
        return
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        gp.fit(X0, Y0)
        _valid_prediction(gp, np.vstack([X0[:3], XT]))
        gp.refit(X0, Y0)
        _valid_prediction(gp, XT)


@FUZZ
@given(
    name=st.sampled_from(["se", "interpolated", "nearest"]),
    a=st.lists(EXTREME, min_size=2, max_size=2),
    b=st.lists(EXTREME, min_size=2, max_size=2),
)
def test_kernels(gps: dict[str, SparseOnlineGP], name: str, a: list[float], b: list[float]) -> None:
    kernel = gps[name].kernel
    Z = np.array([a, b])
    if not _acceptable(Z, None):
        with pytest.raises(ValueError):
            kernel(Z)
        return
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        K = kernel(Z)
        d = kernel.diag(Z)
    assert K.shape == (2, 2) and np.all(np.isfinite(K)) and np.all(np.isfinite(d))
    np.testing.assert_allclose(K, K.T, rtol=1e-12, atol=0)


ENTRIES = ["mu", "S", "cholesky_factor", "score_alpha", "basis_vectors"]


@settings(
    max_examples=max(4, FUZZ.max_examples // 8),
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    name=st.sampled_from(sorted(KERNELS)),
    entry=st.sampled_from(ENTRIES),
    factor=st.sampled_from([1.0, -1.0, 3.0, np.nan, 1e300]),
)
def test_save_load_round_trip(
    tmp_path: Path, gps: dict[str, SparseOnlineGP], name: str, entry: str, factor: float
) -> None:
    from geoq._io import load_archive, save_archive
    from geoq.gp._persist import FORMAT_KIND, FORMAT_VERSION

    gp = gps[name]
    path = tmp_path / f"{name}.npz"
    gp.save(path)
    if factor == 1.0:
        loaded = SparseOnlineGP.load(path)
        np.testing.assert_array_equal(loaded.predict(XT), gp.predict(XT))
        return
    _, arrays = load_archive(path, FORMAT_KIND, FORMAT_VERSION)
    with np.errstate(over="ignore", invalid="ignore"):
        arrays[entry] = arrays[entry] * factor
    save_archive(path, FORMAT_KIND, FORMAT_VERSION, arrays)
    try:
        loaded = SparseOnlineGP.load(path)
    except ArchiveError as exc:
        assert str(path) in str(exc)
        return
    # Accepted: then it must predict finite numbers (a sign flip of mu is a valid posterior).
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        _valid_prediction(loaded, XT)


JSON_VALUES = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(-(10**30), 10**30), EXTREME,
              st.text(max_size=5)),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner,
                                                                max_size=3),
    max_leaves=6,
)  # fmt: skip
FIELDS = ["seeds", "budgets", "gamma", "learner", "kernels", "variants", "graph_eps",
          "root_seed", "eval_pairs", "scale", "train_steps", "bogus"]  # fmt: skip
LEARNER_FIELDS = ["noise", "tol", "max_bv", "eps", "lengthscale", "kernel", "standardize",
                  "scaling", "bogus"]  # fmt: skip


@FUZZ
@given(
    top=st.dictionaries(st.sampled_from(FIELDS), JSON_VALUES, max_size=3),
    learner=st.dictionaries(st.sampled_from(LEARNER_FIELDS), JSON_VALUES, max_size=2),
)
def test_reproduce_config_loader(top: dict[str, Any], learner: dict[str, Any]) -> None:
    overrides = dict(top)
    if learner:
        overrides["learner"] = learner
    text = json.dumps(overrides)  # what --config reads
    try:
        cfg = config_with_overrides(config_for_scale("quick"), json.loads(text))
    except ValueError as exc:
        assert str(exc) and "\n" not in str(exc)
        return
    # accepted: a full, valid configuration that round-trips through config.json
    assert cfg.scale == "quick"
    again = config_with_overrides(config_for_scale("quick"), json.loads(json.dumps(cfg.as_dict())))
    assert again == cfg
