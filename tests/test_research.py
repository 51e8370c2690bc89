"""The research scripts (``research/``) still load, and the layouts the exploration
figures are measured on keep their walls and doors.

The scripts' figures are records of what a version measured (docs/design-notes.md,
docs/exploration.md, docs/results.md) and are not re-run here; a script that no longer
loads (an import path or a helper's signature changed under it) is caught.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

RESEARCH = Path(__file__).resolve().parents[1] / "research"
SCRIPTS = sorted(RESEARCH.rglob("*.py")) if RESEARCH.is_dir() else []


@pytest.mark.skipif(not RESEARCH.is_dir(), reason="research/ not shipped here")
def test_there_are_research_scripts() -> None:
    assert {p.name for p in SCRIPTS} >= {"probe_planner.py", "layouts.py"}


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: str(p.relative_to(RESEARCH)))
def test_every_research_script_loads_and_answers_help(script: Path) -> None:
    """Importing every module the script names, then its ``--help`` (a script without
    options, a layout or a prototype, just loads)."""
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, str(script), "--help"], env=env,
                          capture_output=True, text=True, timeout=120)  # fmt: skip
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-3000:]


def _make_layout(name: str) -> Any:
    """``research/explore/layouts.make_env(name)`` (the scripts are not a package)."""
    path = str(RESEARCH / "explore")
    if path not in sys.path:
        sys.path.insert(0, path)
    from layouts import make_env

    return make_env(name)


@pytest.mark.skipif(not RESEARCH.is_dir(), reason="research/ not shipped here")
@pytest.mark.parametrize(
    ("name", "moves", "expected"),
    [
        # a horizontal wall at y = 0.5 stops a point going straight up from the right ...
        ("floor-door-left", [(0.0, 1.0)] * 20, (None, 0.5)),
        # ... and its door on the left lets it through
        ("floor-door-left", [(-1.0, 0.0)] * 20 + [(0.0, 1.0)] * 20, (0.0, 1.0)),
        # the vertical wall's door is at the bottom, the horizontal wall's on the right
        ("four-rooms", [(1.0, -1.0)] * 10 + [(1.0, 0.0)] * 10 + [(0.0, 1.0)] * 20, (1.0, 1.0)),
        ("four-rooms", [(0.0, 1.0)] * 20, (None, 0.5)),
    ],
)
def test_a_layouts_walls_stop_a_point_and_its_doors_let_it_through(
    name: str, moves: list[tuple[float, float]], expected: tuple[float | None, float]
) -> None:
    """The crossing rules of ``research/explore/layouts.py`` (what the exploration
    figures are measured on), checked with scripted walks: blocked just below a wall,
    through at a door (the goal is never on these paths)."""
    env = _make_layout(name)
    s, _ = env.reset(seed=0)
    for a in moves:
        s, *_ = env.step(np.array(a))
    x, y = expected
    if x is not None:
        assert s[0] == x
    if y == 0.5:
        assert 0.45 < s[1] < 0.5  # pressed against the wall, not through it
    else:
        assert s[1] == y


@pytest.mark.skipif(not RESEARCH.is_dir(), reason="research/ not shipped here")
def test_a_layout_in_another_box_observes_the_unit_square_rescaled() -> None:
    unit, big = _make_layout("narrow-door"), _make_layout("big-box")
    assert np.array_equal(big.observation_space.low, [-5.0, -5.0])
    su, _ = unit.reset(seed=1)
    sb, _ = big.reset(seed=1)
    np.testing.assert_allclose(sb, -5.0 + 10.0 * su, rtol=0, atol=1e-12)


def _cartpole() -> Any:
    """``research/heldout/cartpole_swingup`` (the scripts are not a package)."""
    path = str(RESEARCH / "heldout")
    if path not in sys.path:
        sys.path.insert(0, path)
    import cartpole_swingup

    return cartpole_swingup


@pytest.mark.skipif(not RESEARCH.is_dir(), reason="research/ not shipped here")
def test_the_held_out_cartpole_steps_as_scipys_integrator_does() -> None:
    """The held-out swing-up's RK4 step against ``scipy.integrate.solve_ivp`` on the same
    equations (an independent integrator), from hanging, sideways and upright states."""
    from scipy.integrate import solve_ivp

    cp = _cartpole()
    for z0, force in [((0.1, -0.3, 3.0, 1.0), 4.0), ((0.0, 0.5, 1.5, -2.0), -10.0),
                      ((-1.0, 0.0, 0.2, 0.0), 0.0)]:  # fmt: skip
        z0 = np.array(z0)
        exact = solve_ivp(lambda t, z, f=force: cp._derivative(z, f), (0.0, cp.DT), z0,
                          rtol=1e-12, atol=1e-12).y[:, -1]  # fmt: skip
        # RK4's own error over one 0.05 s step is about 1e-4; a wrong term moves omega by 0.1+
        np.testing.assert_allclose(cp.cartpole_step(z0, force), exact, rtol=0, atol=1e-3)


@pytest.mark.skipif(not RESEARCH.is_dir(), reason="research/ not shipped here")
def test_the_held_out_cartpole_hangs_still_falls_from_upright_and_pays_the_pole_up() -> None:
    """Hanging is stable and upright is not (PILCO's angle convention, flipped); the reward
    is about 0 hanging and 1 upright at the centre; the rail ends an episode."""
    cp = _cartpole()
    hang, up = np.array([0.0, 0.0, np.pi + 0.1, 0.0]), np.array([0.0, 0.0, 0.1, 0.0])
    for _ in range(10):
        hang, up = cp.cartpole_step(hang, 0.0), cp.cartpole_step(up, 0.0)
    assert abs(hang[2] - np.pi) < 0.1 and abs(up[2]) > 0.2
    env = cp.CartPoleSwingUpEnv()
    env.reset(seed=0)
    env._z = np.array([0.0, 0.0, 0.0, 0.0])
    _, r_up, *_ = env.step(np.zeros(1))
    env._z = np.array([0.0, 0.0, np.pi, 0.0])
    _, r_hang, *_ = env.step(np.zeros(1))
    env._z = np.array([cp.RAIL, 1.0, np.pi, 0.0])
    *_, terminated, _, _ = env.step(np.zeros(1))
    assert r_up > 0.99 and r_hang < 1e-3 and terminated
