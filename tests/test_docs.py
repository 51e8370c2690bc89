"""Every Python block of the documentation site runs as written, page by page, in order.

Each page under ``docs/`` gets a fresh namespace and a temporary working directory (the
examples save files); a page's blocks share the namespace, as a reader would run them.
The API pages are generated from the docstrings and hold no blocks of their own.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
BLOCK = re.compile(r"^```python\n(.*?)^```", flags=re.DOTALL | re.MULTILINE)
PAGES = sorted(p for p in DOCS.rglob("*.md") if "_ext" not in p.parts)


def _blocks(page: Path) -> list[str]:
    return BLOCK.findall(page.read_text())


def test_the_guides_have_examples() -> None:
    with_code = {p.relative_to(DOCS).as_posix() for p in PAGES if _blocks(p)}
    for page in ("getting-started.md", "guide/gp-and-kernels.md", "guide/graph.md",
                 "guide/agent.md", "guide/tasks.md", "guide/reproduction.md"):  # fmt: skip
        assert page in with_code, f"{page} lost its examples"


@pytest.mark.parametrize(
    "page", [p for p in PAGES if _blocks(p)], ids=lambda p: p.relative_to(DOCS).as_posix()
)
def test_page_examples_run_in_order(
    page: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    namespace: dict[str, object] = {"__name__": f"docs_{page.stem}"}
    for block in _blocks(page):
        exec(compile(block, str(page), "exec"), namespace)


def test_every_page_is_in_the_navigation() -> None:
    nav = (ROOT / "mkdocs.yml").read_text()
    for page in PAGES:
        assert page.relative_to(DOCS).as_posix() in nav, f"{page} is not in mkdocs.yml's nav"


def test_the_site_builds_without_a_warning(tmp_path: Path) -> None:
    """``mkdocs build --strict`` (what ``make docs`` runs), where the docs extra is installed."""
    pytest.importorskip("mkdocs")
    pytest.importorskip("mkdocstrings_handlers.python")
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path)],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
        env={"NO_MKDOCS_2_WARNING": "1", "PATH": f"{Path(sys.executable).parent}:/usr/bin:/bin"},
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert (tmp_path / "api" / "agents" / "index.html").is_file()
