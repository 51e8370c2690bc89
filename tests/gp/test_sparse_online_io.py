"""Input validation and persistence of the sparse online GP."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import geoq._io
from geoq._io import FORMAT_KEY, ArchiveError
from geoq.gp import SparseOnlineGP
from geoq.kernels import SquaredExponential


def _fitted(lengthscale: object = 0.5, n: int = 120) -> tuple[SparseOnlineGP, np.ndarray]:
    rng = np.random.default_rng(0)
    X = rng.uniform(-2, 2, (n, 2))
    y = np.sin(X[:, 0]) + 0.1 * rng.normal(size=n)
    gp = SparseOnlineGP(SquaredExponential(lengthscale), noise=0.01, max_bv=15, tol=1e-4)
    return gp.fit(X, y), X


def _state(gp: SparseOnlineGP) -> dict[str, object]:
    return {
        "m": gp.n_bv,
        "bv": gp._bv.copy(),
        "R": gp._R.copy(),
        "mu": gp._mu.copy(),
        "S": gp._S.copy(),
        "alpha": gp._alpha.copy(),
        "mdiag": gp._mdiag.copy(),
        "counters": gp._counts.step.copy(),
        "changes": gp._changes,
        "dim": gp._dim,
    }


def _assert_same_state(a: dict[str, object], b: dict[str, object]) -> None:
    assert a.keys() == b.keys()
    for k in a:
        np.testing.assert_array_equal(np.asarray(a[k]), np.asarray(b[k]), err_msg=k)


# -------------------------------------------------------------------- validation
@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"noise": 0.0}, "noise must be a finite number > 0"),
        ({"noise": -1.0}, "noise must be a finite number > 0"),
        ({"noise": float("nan")}, "noise must be a finite number > 0"),
        ({"max_bv": 0}, "max_bv must be an integer in \\[1, 5000\\]"),
        ({"max_bv": 2.5}, "max_bv must be an integer in \\[1, 5000\\]"),
        ({"max_bv": True}, "max_bv must be an integer in \\[1, 5000\\]"),
        ({"tol": -1e-3}, "tol must be a finite number >= 0"),
        ({"tol": float("inf")}, "tol must be a finite number >= 0"),
        ({"tol": "big"}, "tol must be a finite number >= 0"),
    ],
)
def test_bad_constructor_arguments(kwargs: dict[str, object], match: str) -> None:
    args: dict[str, object] = {"noise": 0.01, "max_bv": 10, "tol": 1e-3} | kwargs
    with pytest.raises(ValueError, match=match):
        SparseOnlineGP(SquaredExponential(0.5), **args)  # type: ignore[arg-type]


def test_kernel_must_be_a_geoq_kernel() -> None:
    with pytest.raises(ValueError, match="kernel must be a geoq Kernel"):
        SparseOnlineGP(lambda a, b: a @ b.T, noise=0.1, max_bv=5)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("X", "y", "match"),
    [
        (np.zeros(5), np.zeros(5), r"X has shape \(5,\); expected a 2-D array"),
        (np.zeros((5, 2, 1)), np.zeros(5), "expected a 2-D array"),
        (np.zeros((5, 2)), np.zeros(4), "y has 4 entries; expected 5"),
        (np.zeros((5, 2)), np.zeros((5, 1)), r"y has shape \(5, 1\); expected a 1-D array"),
        (np.array([[0.0, np.nan], [0.0, 1.0]]), np.zeros(2), "X contains 1 non-finite value"),
        (np.array([[0.0, np.inf]] * 3), np.zeros(3), "X contains 3 non-finite value"),
        (np.zeros((3, 2)), np.array([0.0, np.nan, 1.0]), "y contains 1 non-finite"),
        (np.zeros((3, 2)), np.array([0.0, -np.inf, 1.0]), "y contains 1 non-finite"),
        ([["a", "b"]], [0.0], "X must be numeric"),
    ],
)
def test_bad_fit_input(X: object, y: object, match: str) -> None:
    gp = SparseOnlineGP(SquaredExponential(0.5), noise=0.01, max_bv=5)
    with pytest.raises(ValueError, match=match):
        gp.fit(X, y)  # type: ignore[arg-type]


def test_ard_kernel_fixes_the_dimension() -> None:
    gp = SparseOnlineGP(SquaredExponential(np.array([0.5, 1.0])), noise=0.01, max_bv=5)
    with pytest.raises(ValueError, match=r"expected \(n, 2\)"):
        gp.fit(np.zeros((4, 3)), np.zeros(4))


@pytest.mark.parametrize(
    ("x", "y", "match"),
    [
        (np.zeros(3), 0.0, r"x has shape \(3,\); expected \(2,\)"),
        (np.zeros((1, 2)), 0.0, "expected one point of shape"),
        (np.array([np.nan, 0.0]), 0.0, "x contains 1 non-finite"),
        (np.array([np.inf, 0.0]), 0.0, "x contains 1 non-finite"),
        (np.zeros(2), float("nan"), "y must be one finite number"),
        (np.zeros(2), float("-inf"), "y must be one finite number"),
        (np.zeros(2), np.zeros(2), "y must be one finite number"),
        (np.zeros(2), "z", "y must be a finite number"),
    ],
)
def test_rejected_update_leaves_the_model_unchanged(x: object, y: object, match: str) -> None:
    gp, X = _fitted()
    before = _state(gp)
    mean_before = gp.predict(X[:10])
    with pytest.raises(ValueError, match=match):
        gp.update(x, y)  # type: ignore[arg-type]
    _assert_same_state(before, _state(gp))
    np.testing.assert_array_equal(gp.predict(X[:10]), mean_before)
    gp.update(np.zeros(2), 0.0)  # and it still works
    assert gp.diagnostics.n_seen == 121


def test_wrong_dimension_after_first_fit() -> None:
    gp, _ = _fitted()
    before = _state(gp)
    with pytest.raises(ValueError, match=r"expected \(2,\)"):
        gp.update(np.zeros(3), 1.0)
    with pytest.raises(ValueError, match=r"expected \(n, 2\)"):
        gp.partial_fit(np.zeros((4, 3)), np.zeros(4))
    with pytest.raises(ValueError, match=r"expected \(n, 2\)"):
        gp.predict(np.zeros((4, 1)))
    with pytest.raises(ValueError, match=r"expected \(n, 2\)"):
        gp.refit(np.zeros((4, 3)), np.zeros(4))
    with pytest.raises(ValueError, match="non-finite"):
        gp.partial_fit(np.array([[0.0, 1.0], [np.nan, 0.0]]), np.zeros(2))
    _assert_same_state(before, _state(gp))


def test_empty_model_predicts_the_prior() -> None:
    gp = SparseOnlineGP(SquaredExponential(0.5, variance=2.0), noise=0.01, max_bv=5)
    mean, std = gp.predict(np.zeros((3, 2)), return_std=True)
    np.testing.assert_array_equal(mean, 0.0)
    np.testing.assert_allclose(std, np.sqrt(2.0))


# -------------------------------------------------------------------- save / load
@pytest.mark.parametrize("lengthscale", [0.5, np.array([0.4, 0.9])])
def test_save_load_round_trip(tmp_path: Path, lengthscale: object) -> None:
    gp, _ = _fitted(lengthscale)
    path = tmp_path / "model.npz"
    gp.save(path)
    loaded = SparseOnlineGP.load(path)
    assert loaded.get_params()["noise"] == gp.noise and loaded.max_bv == gp.max_bv
    assert loaded.tol == gp.tol and loaded.resync_every == gp.resync_every
    Xs = np.random.default_rng(1).uniform(-2, 2, (50, 2))
    for a, b in zip(
        gp.predict(Xs, return_std=True), loaded.predict(Xs, return_std=True), strict=True
    ):
        np.testing.assert_array_equal(a, b)
    assert loaded.diagnostics == gp.diagnostics
    # Continued updates (crossing a resync) are identical too.
    rng = np.random.default_rng(2)
    Xn = rng.uniform(-2, 2, (150, 2))
    yn = np.cos(Xn[:, 1])
    gp.partial_fit(Xn, yn)
    loaded.partial_fit(Xn, yn)
    _assert_same_state(_state(gp), _state(loaded))
    for a, b in zip(
        gp.predict(Xs, return_std=True), loaded.predict(Xs, return_std=True), strict=True
    ):
        np.testing.assert_array_equal(a, b)


def test_save_load_empty_model(tmp_path: Path) -> None:
    gp = SparseOnlineGP(SquaredExponential(0.5), noise=0.01, max_bv=5)
    gp.save(tmp_path / "empty.npz")
    loaded = SparseOnlineGP.load(tmp_path / "empty.npz")
    assert loaded.n_bv == 0
    loaded.fit(np.zeros((2, 3)), np.ones(2))
    assert loaded.n_bv == 1


def _rewrite(src: Path, dst: Path, edit: object) -> None:
    with np.load(src, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    edit(arrays)  # type: ignore[operator]
    with open(dst, "wb") as fh:
        np.savez(fh, **arrays)


def test_truncated_file_is_rejected(tmp_path: Path) -> None:
    gp, _ = _fitted()
    path = tmp_path / "model.npz"
    gp.save(path)
    data = path.read_bytes()
    for cut in (0, 10, len(data) // 2, len(data) - 5):
        bad = tmp_path / f"cut{cut}.npz"
        bad.write_bytes(data[:cut])
        with pytest.raises(ArchiveError, match="truncated or corrupt"):
            SparseOnlineGP.load(bad)
    with pytest.raises(ArchiveError, match="no such file"):
        SparseOnlineGP.load(tmp_path / "missing.npz")


def _set(key: str, value: object):  # type: ignore[no-untyped-def]
    def edit(a: dict[str, object]) -> None:
        a[key] = value

    return edit


def _drop(key: str):  # type: ignore[no-untyped-def]
    def edit(a: dict[str, object]) -> None:
        del a[key]

    return edit


def _header(version: int, kind: str = "SparseOnlineGP"):  # type: ignore[no-untyped-def]
    return _set(FORMAT_KEY, np.asarray(json.dumps({"kind": kind, "version": version})))


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (_drop("S"), "entry 'S' is missing"),
        (_drop("noise"), "entry 'noise' is missing"),
        (_set("S", np.zeros((3, 3))), "entry 'S' has shape"),
        (_set("mu", np.zeros(2)), "entry 'mu' has shape"),
        (_set("basis_vectors", np.zeros((40, 2))), "basis_vectors has shape"),
        (_set("basis_vectors", np.float64(1.0)), "basis_vectors has shape"),
        (_set("basis_vectors", np.zeros((15, 3))), "basis_vectors has shape"),
        (_set("counters", np.zeros(3, dtype=np.int64)), "entry 'counters' has shape"),
        (_set("noise", np.float64(-1.0)), "invalid model parameters"),
        (_set("max_bv", np.int64(0)), "invalid model parameters"),
        (_set("mu", np.full(15, np.nan)), "contains NaN or inf"),
        (_set("S", np.asarray([["x"] * 15] * 15)), "has dtype"),
        (_set("cholesky_factor", np.zeros((15, 15))), "cholesky_factor is not upper triangular"),
        (_set("S", np.triu(np.ones((15, 15)))), "S is not symmetric"),
        (_set("kernel.class", np.asarray("NoSuchKernel")), "cannot rebuild the kernel"),
        (_drop(FORMAT_KEY), "not a geoq archive"),
        (_set(FORMAT_KEY, np.asarray("{not json")), "corrupt geoq archive header"),
        (_header(99), "format version 99 is newer than this geoq supports"),
        (_header(2, kind="ExactGP"), "holds a 'ExactGP', expected a 'SparseOnlineGP'"),
    ],
)
def test_tampered_file_is_rejected(tmp_path: Path, edit: object, match: str) -> None:
    gp, _ = _fitted()
    path = tmp_path / "model.npz"
    gp.save(path)
    assert gp.n_bv == 15
    bad = tmp_path / "bad.npz"
    _rewrite(path, bad, edit)
    with pytest.raises(ArchiveError, match=match):
        SparseOnlineGP.load(bad)


@pytest.mark.parametrize("version", [1, 2])
def test_older_format_versions_still_load(tmp_path: Path, version: int) -> None:
    """Format 1 had 8 counters (no ``noise_floored``), formats 1-2 no
    ``covariance_projections`` nor the predict-time repair state: they load with
    those at 0 and predict exactly as saved."""
    gp, X = _fitted()
    path = tmp_path / "model.npz"
    gp.save(path)
    old = tmp_path / f"v{version}.npz"

    def downgrade(a: dict[str, object]) -> None:
        _header(version)(a)
        if version == 1:
            a["counters"] = np.asarray(a["counters"])[:8]
        for name in (
            "extra.covariance_projections",
            "predict_rescaled",
            "novelty_clipped_at_refit",
        ):
            del a[name]

    _rewrite(path, old, downgrade)
    loaded = SparseOnlineGP.load(old)
    assert loaded.diagnostics.noise_floored == 0
    assert loaded.diagnostics.covariance_projections == 0
    np.testing.assert_array_equal(loaded.predict(X), gp.predict(X))


def test_save_is_atomic(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    gp, X = _fitted()
    path = tmp_path / "model.npz"
    gp.save(path)
    original = path.read_bytes()
    gp.partial_fit(X[:20] + 0.01, np.zeros(20))  # a different model

    def boom(fd: int) -> None:
        raise OSError("disk full (simulated, after a partial write)")

    monkeypatch.setattr(geoq._io.os, "fsync", boom)
    with pytest.raises(OSError, match="disk full"):
        gp.save(path)
    monkeypatch.undo()
    assert path.read_bytes() == original  # the old model is intact
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.npz"]  # no temp file left
    SparseOnlineGP.load(path)
    with pytest.raises(OSError, match="disk full"):
        monkeypatch.setattr(geoq._io.os, "fsync", boom)
        gp.save(tmp_path / "new.npz")
    assert not (tmp_path / "new.npz").exists()
