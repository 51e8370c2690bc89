"""README.md: a short page for users whose every Python block runs as written.

The documentation site's pages are checked by ``tests/test_docs.py``.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCKS = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.DOTALL)


def test_readme_has_python_examples() -> None:
    assert len(BLOCKS) >= 2


def test_readme_examples_run_in_order(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)  # the examples save files
    namespace: dict[str, object] = {}
    for block in BLOCKS:
        exec(compile(block, str(README), "exec"), namespace)


def test_readme_names_the_locked_versions() -> None:
    """The install section's "tested with" versions are the lock's pins."""
    root = README.parent
    text = README.read_text()
    lock_name = re.search(r"the\s+lock\s+`(requirements/py[\d.]+\.txt)`", text)
    assert lock_name, "README names no lock file"
    pins = dict(re.findall(r"^([a-z0-9_-]+)==([^\s;]+)", (root / lock_name[1]).read_text(), re.M))
    named = re.findall(r"\b(numpy|scipy|numba|gymnasium|matplotlib) (\d[\w.]*\d)", text)
    assert {name for name, _ in named} == {"numpy", "scipy", "numba", "gymnasium", "matplotlib"}
    for name, version in named:
        assert pins[name] == version, f"README says {name} {version}; the lock pins {pins[name]}"


def test_readme_is_a_short_page_for_users() -> None:
    """A user's page: <= 200 lines, the two commands, nothing dated, no commit hashes
    (the history lives in docs/results.md and CHANGELOG.md)."""
    text = README.read_text()
    assert len(text.splitlines()) <= 200
    assert "make demo" in text and "make test" in text
    assert not re.findall(r"\b20\d\d-\d\d-\d\d\b", text), "a date: move it to docs/results.md"
    assert not re.findall(r"`[0-9a-f]{7,40}`", text), "a commit hash: move it to docs/results.md"


def test_readme_links_resolve() -> None:
    root = README.parent
    for target in re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", README.read_text()):
        if "://" not in target:
            assert (root / target).exists(), f"README links to a missing {target}"
