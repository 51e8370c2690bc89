"""Short learning runs whose every action and target is pinned (``data/pinned_runs.npz``).

A refactor of the agent must leave them identical, bit for bit; a change of the
algorithm re-records them (``python -m tests.agents._pinned record``, then say why in
the commit). Each run covers one path of the agent: the default squared exponential
with uniform replay on three tasks, graph replay, no replay, a graph kernel, the
resistance kernel, length-scales by evidence, and inputs scaled from warm-up data.

The runs are recorded and checked in a subprocess under the portable kernel setting
(:func:`tests._kernels.portable`: the SIMD, BLAS, numba and libm kernels of the x86-64
baseline), so the pinned bits are those of any x86-64 machine, not of the one that
recorded them. ``python -m tests.agents._pinned run OUT NAME ...`` writes the named
runs' arrays to ``OUT`` (``saved`` names the continuation of :data:`SAVED_AGENT`).
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
from tests._kernels import PORTABLE_FLAG, ROOT, in_effect, portable
from tests.agents._tasks import PointToGoal

import geoq  # noqa: F401  (registers the envs)
from geoq.agents import GPQAgent

FIXTURE = Path(__file__).parent / "data" / "pinned_runs.npz"
#: An agent saved by the code that recorded the fixture, and how it continues.
SAVED_AGENT = Path(__file__).parent / "data" / "saved_agent.npz"


class UnboundedPoint(PointToGoal):
    """:class:`PointToGoal` whose observation space declares no bounds (data scaling)."""

    def __init__(self) -> None:
        super().__init__()
        self.observation_space = gymnasium.spaces.Box(-np.inf, np.inf, shape=(1,))


class RecordActions(gymnasium.Wrapper):  # type: ignore[type-arg]
    """Keeps every action the agent sends to the env."""

    def __init__(self, env: gymnasium.Env) -> None:  # type: ignore[type-arg]
        super().__init__(env)
        self.actions: list[np.ndarray] = []

    def step(self, action: Any) -> Any:
        self.actions.append(np.array(action, dtype=np.float64))
        return self.env.step(action)


#: name -> (env factory, GPQAgent arguments, steps)
RUNS: dict[str, tuple[Any, dict[str, Any], int]] = {
    "swingup": (lambda: gymnasium.make("geoq/PendulumSwingUp-v0"), {"seed": 0}, 300),
    "swingup_graph": (
        lambda: gymnasium.make("geoq/PendulumSwingUp-v0"),
        {"seed": 1, "replay": "graph", "max_bv": 100},
        300,
    ),
    "mountaincar": (lambda: gymnasium.make("MountainCarContinuous-v0"), {"seed": 0}, 300),
    "tworooms": (lambda: gymnasium.make("geoq/TwoRooms-v0"), {"seed": 0, "max_bv": 150}, 300),
    "tworooms_none": (
        lambda: gymnasium.make("geoq/TwoRooms-v0"),
        {"seed": 2, "replay": "none", "max_bv": 100},
        200,
    ),
    "point_nearest": (PointToGoal, {"seed": 0, "kernel": "nearest", "max_bv": 60}, 200),
    "point_resistance": (PointToGoal, {"seed": 0, "kernel": "resistance", "max_bv": 40}, 150),
    "pendulum_evidence": (
        lambda: gymnasium.make("Pendulum-v1"),
        {"seed": 0, "hyperparameters": "evidence", "max_bv": 100},
        300,
    ),
    "unbounded_point": (
        UnboundedPoint,
        {"seed": 0, "gamma": 0.9, "max_bv": 120, "warmup_steps": 60},
        400,
    ),
}


def run(name: str) -> dict[str, np.ndarray]:
    """The run's actions ``[T, d_a]``, final targets, posterior weights and episode records."""
    make_env, kwargs, steps = RUNS[name]
    env = RecordActions(make_env())
    agent = GPQAgent(env, **kwargs).learn(steps)
    return outcome(agent, env.actions)


def outcome(agent: GPQAgent, actions: list[np.ndarray]) -> dict[str, np.ndarray]:
    episodes = [[e.timesteps, e.episode, e.ret, e.success] for e in agent.episodes]
    return {
        "actions": np.array(actions),
        "targets": agent.buffer.targets(),
        "alpha": np.asarray(agent.gp.alpha, dtype=np.float64),
        "standardisation": np.array([agent.state.y_mean, agent.state.y_scale]),
        "episodes": np.array(episodes, dtype=np.float64).reshape(-1, 4),
    }


def continue_saved(steps: int = 60) -> dict[str, np.ndarray]:
    """:data:`SAVED_AGENT` loaded and run ``steps`` more steps."""
    env = RecordActions(PointToGoal())
    agent = GPQAgent.load(SAVED_AGENT, env=env).learn(steps)
    return outcome(agent, env.actions)


def platform_tag() -> str:
    """Where the fixture's bits were computed: the architecture, the kernels in effect
    (:func:`tests._kernels.in_effect`) and the versions of what computes them."""
    import scipy

    libc = "-".join(platform.libc_ver())
    kernels = " ".join(f"{k} {v}" for k, v in in_effect().items())
    return (
        f"{platform.machine()} ({kernels}); numpy {np.__version__}, scipy {scipy.__version__}, "
        f"{libc}"
    )


def compute(names: list[str]) -> dict[str, np.ndarray]:
    """The arrays of the runs ``names`` (``saved``: :func:`continue_saved`), keyed
    ``NAME/ARRAY`` as in the fixture, and ``platform``."""
    arrays: dict[str, np.ndarray] = {"platform": np.asarray(platform_tag())}
    for name in names:
        got = continue_saved() if name == "saved" else run(name)
        arrays.update({f"{name}/{k}": v for k, v in got.items()})
    return arrays


def run_portably(names: list[str]) -> dict[str, np.ndarray]:
    """:func:`compute` in a subprocess under the portable kernel setting."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "runs.npz"
        done = subprocess.run(
            [sys.executable, "-m", "tests.agents._pinned", "run", str(out), *names],
            cwd=ROOT,
            env=portable(),
            capture_output=True,
            text=True,
        )
        if done.returncode != 0:
            raise RuntimeError(f"the pinned runs {names} failed:\n{done.stderr[-4000:]}")
        with np.load(out, allow_pickle=False) as data:
            got = dict(data)
    expected = "(numpy baseline openblas Nehalem numba nehalem)"
    if expected not in str(got["platform"]):
        raise RuntimeError(f"the portable kernel setting did not take: {got['platform']}")
    return got


def record() -> None:
    """Re-records the fixture and the saved agent (under the portable setting)."""
    arrays = {f"{name}/{k}": v for name in RUNS for k, v in run(name).items()}
    agent = GPQAgent(PointToGoal(), seed=5, max_bv=30, window=50, gamma=0.9).learn(100)
    agent.save(SAVED_AGENT)
    arrays.update({f"saved/{k}": v for k, v in continue_saved().items()})
    arrays["platform"] = np.asarray(platform_tag())
    np.savez_compressed(FIXTURE, **arrays)


def _main(argv: list[str]) -> int:
    if argv[:1] == ["run"] and len(argv) >= 3:
        np.savez(argv[1], **compute(argv[2:]))
        return 0
    if argv != ["record"]:
        print(__doc__, file=sys.stderr)
        return 2
    if os.environ.get(PORTABLE_FLAG) != "1":  # record where the test checks
        return subprocess.call([sys.executable, "-m", "tests.agents._pinned", "record"],
                               cwd=ROOT, env=portable())  # fmt: skip
    record()
    print(f"wrote {FIXTURE} and {SAVED_AGENT} ({platform_tag()})", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))
