"""The agent's actions and targets on short fixed-seed runs, pinned bit for bit.

A refactor must leave every pinned number as it is; a change of the algorithm
re-records them (``python -m tests.agents._pinned``) and says why in its commit.
The bits are those of the machine that recorded them (``platform`` in the fixture:
the CPU's SIMD kernels that NumPy dispatches to change the last bits of ``exp``);
elsewhere the comparison is skipped, with the reason.
"""

from __future__ import annotations

import numpy as np
import pytest
from tests.agents._pinned import (
    FIXTURE,
    RUNS,
    RecordActions,
    continue_saved,
    platform_tag,
    run,
)

from geoq.agents import GPQAgent

PINNED = dict(np.load(FIXTURE, allow_pickle=False))
SAME_PLATFORM = pytest.mark.skipif(
    str(PINNED["platform"]) != platform_tag(),
    reason=f"pinned on {PINNED['platform']}; this machine is {platform_tag()}",
)


def _assert_pinned(name: str, got: dict[str, np.ndarray]) -> None:
    for key, value in got.items():
        np.testing.assert_array_equal(value, PINNED[f"{name}/{key}"], err_msg=f"{name}: {key}")


@SAME_PLATFORM
@pytest.mark.parametrize("name", sorted(RUNS))
def test_run_is_pinned_bit_for_bit(name: str) -> None:
    _assert_pinned(name, run(name))


@SAME_PLATFORM
def test_an_agent_saved_by_the_recording_code_loads_and_continues_as_pinned() -> None:
    _assert_pinned("saved", continue_saved())


def test_the_pins_can_fail() -> None:
    """Another seed gives other actions: the comparison above is not vacuous."""
    pinned = PINNED["point_nearest/actions"]
    assert pinned.shape == (200, 1) and np.ptp(pinned) > 0
    make_env, kwargs, steps = RUNS["point_nearest"]
    env = RecordActions(make_env())
    GPQAgent(env, **{**kwargs, "seed": 1}).learn(steps)
    assert not np.array_equal(np.array(env.actions), pinned)
