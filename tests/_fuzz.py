"""The fuzz tests' hypothesis settings, shared by tests/test_fuzz*.py."""

from __future__ import annotations

import os

from hypothesis import HealthCheck, settings


def fuzz_settings(default_examples: int) -> settings:
    """Derandomised settings with ``HYPOTHESIS_FUZZ_EXAMPLES`` (else ``default_examples``)
    examples, no deadline, and the slow-data health checks off."""
    return settings(
        max_examples=int(os.environ.get("HYPOTHESIS_FUZZ_EXAMPLES", str(default_examples))),
        deadline=None,
        derandomize=True,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
    )
