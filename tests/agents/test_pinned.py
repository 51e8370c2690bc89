"""The agent's actions and targets on short fixed-seed runs, pinned bit for bit.

A refactor must leave every pinned number as it is; a change of the algorithm
re-records them (``python -m tests.agents._pinned record``) and says why in its commit.
The runs are computed in a subprocess under the portable kernel setting
(:func:`tests._kernels.portable`), where the bits are those of any x86-64 machine:
the test runs on every one, whatever kernels its own process uses.
"""

from __future__ import annotations

import numpy as np
import pytest
from tests._kernels import supports_portable
from tests.agents._pinned import FIXTURE, RUNS, RecordActions, run_portably

from geoq.agents import GPQAgent

PINNED = dict(np.load(FIXTURE, allow_pickle=False))

pytestmark = [
    pytest.mark.numbers,
    pytest.mark.skipif(
        not supports_portable(),
        reason="the pinned bits are those of the x86-64 baseline; this CPU is not x86-64",
    ),
]


def _assert_pinned(name: str, got: dict[str, np.ndarray], pinned: dict[str, np.ndarray]) -> None:
    keys = sorted(k for k in pinned if k.startswith(f"{name}/"))
    assert keys == sorted(k for k in got if k.startswith(f"{name}/"))
    for key in keys:
        np.testing.assert_array_equal(
            got[key],
            pinned[key],
            err_msg=f"{key}: recorded on {pinned['platform']}, computed on {got['platform']}",
        )


@pytest.mark.parametrize("name", [*sorted(RUNS), "saved"])
def test_run_is_pinned_bit_for_bit(name: str) -> None:
    """``saved``: an agent saved by the recording code loads and continues as pinned."""
    _assert_pinned(name, run_portably([name]), PINNED)


def test_the_pins_can_fail() -> None:
    """The comparison is not vacuous: one recorded target moved by one ulp fails it, and
    so does another seed's run."""
    got = run_portably(["point_nearest"])
    _assert_pinned("point_nearest", got, PINNED)
    one_ulp = dict(PINNED)
    targets = one_ulp["point_nearest/targets"].copy()
    targets[-1] = np.nextafter(targets[-1], np.inf)
    one_ulp["point_nearest/targets"] = targets
    with pytest.raises(AssertionError, match="point_nearest/targets"):
        _assert_pinned("point_nearest", got, one_ulp)
    pinned = PINNED["point_nearest/actions"]
    assert pinned.shape == (200, 1) and np.ptp(pinned) > 0
    make_env, kwargs, steps = RUNS["point_nearest"]
    env = RecordActions(make_env())
    GPQAgent(env, **{**kwargs, "seed": 1}).learn(steps)
    assert not np.array_equal(np.array(env.actions), pinned)
