"""What geoq's Gymnasium shells share: the ``reset(options=...)`` contract."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

__all__ = ["start_option"]


def start_option(options: Mapping[str, Any] | None) -> Any:
    """``options["state"]`` (None when absent); any other option is a ``ValueError``."""
    rest = {} if options is None else dict(options)
    start = rest.pop("state", None)
    if rest:
        raise ValueError(f"unknown reset option(s) {sorted(rest)}; the only option is 'state'")
    return start
