"""The package's layering (STYLE.md: data flows one way) holds: import-linter's contracts
in ``pyproject.toml`` are kept (``make lint`` runs the same check)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_import_layers_are_kept() -> None:
    exe = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    if exe is None:
        pytest.skip("import-linter is not installed (the dev extra: make install)")
    done = subprocess.run([exe], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    assert "1 kept, 0 broken" in done.stdout


def test_no_module_is_over_500_lines() -> None:
    """A module past ~500 lines usually holds two jobs (STYLE.md)."""
    long = {
        str(p.relative_to(ROOT)): n
        for p in (ROOT / "src" / "geoq").rglob("*.py")
        if (n := len(p.read_text().splitlines())) > 500
    }
    assert not long, long


def test_learn_fits_on_a_screen() -> None:
    """``GPQAgent.learn`` reads like SB3's: collect, train when due, log."""
    import inspect

    from geoq.agents import GPQAgent

    lines = inspect.getsource(GPQAgent.learn).splitlines()
    assert len(lines) <= 45, len(lines)
