"""Issue 12, class 4: a tampered archive raises ArchiveError (never MemoryError, never a
silently wrong posterior)."""

from __future__ import annotations

import io
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest

from geoq._io import ArchiveError, load_archive, save_archive
from geoq.gp import NumericalWarning, SparseOnlineGP
from geoq.gp._persist import FORMAT_KIND, FORMAT_VERSION
from geoq.kernels import GeodesicKernel, ResistanceKernel, SquaredExponential

RNG = np.random.default_rng(3)
X = RNG.uniform(-1, 1, (60, 2))
Y = np.sin(3 * X[:, 0])


def _saved(tmp_path: Path, kernel=None) -> Path:  # type: ignore[no-untyped-def]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        gp = SparseOnlineGP(kernel or SquaredExponential(0.4), noise=0.01, max_bv=15).fit(X, Y)
    path = tmp_path / "gp.npz"
    gp.save(path)
    return path


def _rewrite_header(path: Path, entry: str, shape: tuple[int, ...]) -> None:
    """Replace the .npy header of ``entry`` so that it declares ``shape`` (data unchanged)."""
    with zipfile.ZipFile(path) as zf:
        members = {i.filename: zf.read(i) for i in zf.infolist()}
    raw = io.BytesIO(members[entry])
    np.lib.format.read_magic(raw)
    _, fortran, dtype = np.lib.format.read_array_header_1_0(raw)
    data = raw.read()
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        header, {"descr": np.lib.format.dtype_to_descr(dtype), "fortran_order": fortran,
                 "shape": shape}
    )  # fmt: skip
    members[entry] = header.getvalue() + data
    with zipfile.ZipFile(path, "w") as zf:
        for name, blob in members.items():
            zf.writestr(name, blob)


@pytest.mark.parametrize("shape", [(10**12,), (10**6, 10**6), (2**62,)])
def test_a_huge_declared_size_is_an_archive_error_not_a_memory_error(
    tmp_path: Path, shape: tuple[int, ...]
) -> None:
    path = _saved(tmp_path)
    _rewrite_header(path, "S.npy", shape)
    with pytest.raises(ArchiveError, match=r"'S.npy' declares shape .* but holds"):
        SparseOnlineGP.load(path)


def _tampered(tmp_path: Path, kernel, **scale: float) -> Path:  # type: ignore[no-untyped-def]
    path = _saved(tmp_path, kernel)
    _, arrays = load_archive(path, FORMAT_KIND, FORMAT_VERSION)
    for name, factor in scale.items():
        arrays[name] = arrays[name] * factor
    save_archive(path, FORMAT_KIND, FORMAT_VERSION, arrays)
    return path


@pytest.mark.parametrize(
    "make", [lambda: SquaredExponential(0.4), lambda: ResistanceKernel(eps=0.3)]
)
def test_a_scaled_cholesky_factor_is_refused(tmp_path: Path, make) -> None:  # type: ignore[no-untyped-def]
    path = _tampered(tmp_path, make(), cholesky_factor=2.0)
    with pytest.raises(ArchiveError, match="cholesky_factor does not reproduce"):
        SparseOnlineGP.load(path)


@pytest.mark.parametrize(
    "make",
    [
        lambda: SquaredExponential(0.4),
        lambda: GeodesicKernel(eps=0.9, method="interpolated", normalize=True, attach=True),
    ],
)
def test_a_scaled_whitened_posterior_is_refused(tmp_path: Path, make) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ArchiveError, match="eigenvalues in"):
        SparseOnlineGP.load(_tampered(tmp_path, make(), S=50.0))
    with pytest.raises(ArchiveError, match="mu and the deletion scores' alpha disagree"):
        SparseOnlineGP.load(_tampered(tmp_path, make(), mu=3.0))


@pytest.mark.parametrize(
    "make",
    [
        lambda: SquaredExponential(0.4),
        lambda: ResistanceKernel(eps=0.3),
        lambda: GeodesicKernel(eps=0.3, method="nearest"),
        lambda: GeodesicKernel(eps=0.9, method="interpolated", normalize=True, attach=True),
    ],
)
def test_untampered_models_still_load_with_the_same_predictions(tmp_path: Path, make) -> None:  # type: ignore[no-untyped-def]
    path = _saved(tmp_path, make())
    gp = SparseOnlineGP.load(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        again = SparseOnlineGP(make(), noise=0.01, max_bv=15).fit(X, Y)
    np.testing.assert_array_equal(gp.predict(X), again.predict(X))
