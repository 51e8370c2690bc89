"""The package's layering (STYLE.md: data flows one way) holds: import-linter's contracts
in ``pyproject.toml`` are kept (``make lint`` runs the same check), no module imports
itself through others, and modules stay small."""

from __future__ import annotations

import ast
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.sparse import coo_array
from scipy.sparse.csgraph import connected_components

ROOT = Path(__file__).resolve().parents[1]


def test_import_layers_are_kept() -> None:
    exe = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    if exe is None:
        pytest.skip("import-linter is not installed (the dev extra: make install)")
    done = subprocess.run([exe], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    kept = re.search(r"Contracts: (\d+) kept, 0 broken", done.stdout)
    assert kept is not None and int(kept.group(1)) >= 3, done.stdout[-3000:]


def _modules(src: Path) -> dict[str, Path]:
    """Every module of the package by dotted name (a package by its ``__init__``)."""
    names = {}
    for path in (src / "geoq").rglob("*.py"):
        parts = list(path.relative_to(src).with_suffix("").parts)
        names[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return names


def import_edges(src: Path) -> set[tuple[str, str, bool]]:
    """``(importer, imported, under TYPE_CHECKING)`` for every import of a package module
    by another, wherever it stands (top level, in a function, under ``TYPE_CHECKING``)."""
    modules, edges = _modules(src), set()
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        tree = ast.parse(path.read_text())
        typing_only = {
            id(inner)
            for node in ast.walk(tree)
            if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)
            for inner in ast.walk(node)
        }
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join(up + ([base] if base else []))
                targets = [
                    f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base
                    for a in node.names
                ]
            else:
                continue
            edges |= {(name, t, id(node) in typing_only) for t in targets
                      if t in modules and t != name}  # fmt: skip
    return edges


def import_cycles(edges: set[tuple[str, str, bool]]) -> list[list[str]]:
    """The strongly connected sets of more than one module (scipy's components)."""
    names = sorted({n for a, b, _ in edges for n in (a, b)})
    index = {n: i for i, n in enumerate(names)}
    rows, cols = zip(*[(index[a], index[b]) for a, b, _ in edges], strict=True)
    graph = coo_array((np.ones(len(rows)), (rows, cols)), shape=(len(names),) * 2)
    _, label = connected_components(graph, directed=True, connection="strong")
    groups = [[names[i] for i in np.flatnonzero(label == c)] for c in np.unique(label)]
    return [g for g in groups if len(g) > 1]


def test_no_import_cycle_but_a_persistence_modules_typing_import() -> None:
    """A module reaches itself through no chain of imports, type-only ones included; the one
    exception is a persistence module (``*_persist``) naming the class it saves under
    ``TYPE_CHECKING``."""
    edges = {
        (a, b, typing_only)
        for a, b, typing_only in import_edges(ROOT / "src")
        if not (typing_only and a.rpartition(".")[2].endswith("_persist"))
    }
    assert import_cycles(edges) == []


def test_the_cycle_finder_finds_cycles() -> None:
    """The check above can fail: a type-only cycle and a longer one are found, a chain is not."""
    edges = {("a", "b", False), ("b", "a", True), ("c", "d", False), ("d", "e", False),
             ("e", "c", False), ("e", "f", False)}  # fmt: skip
    assert sorted(import_cycles(edges)) == [["a", "b"], ["c", "d", "e"]]


def test_the_import_graph_sees_every_kind_of_import() -> None:
    """Known edges of each kind are read: a type-only import, one inside a function (the
    CLI's lazy imports), a top-level one."""
    edges = import_edges(ROOT / "src")
    assert ("geoq.agents._persist", "geoq.agents.gpq", True) in edges
    assert ("geoq.cli._paper", "geoq.experiments.paper.reproduce", False) in edges
    assert ("geoq.agents.gpq", "geoq.agents.model_planning", False) in edges


def test_no_reference_to_documents_outside_the_repo() -> None:
    """The code and docs cite the paper and each other, not the project's private notes."""
    cited = [
        str(p.relative_to(ROOT))
        for folder in ("src", "docs", "tests", "benchmarks", "research")
        for p in (ROOT / folder).rglob("*")
        if p.suffix in {".py", ".md"} and re.search(r"\bSPEC(\.md| §| section)", p.read_text())
    ]
    assert not cited, cited


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
