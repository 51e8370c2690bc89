"""What geoq's Gymnasium shells share: the ``reset(options=...)`` contract, the horizon."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium
import numpy as np

from geoq._typing import FloatArray

__all__ = ["episode_horizon", "numeric_start_state", "start_option"]


def start_option(options: Mapping[str, Any] | None) -> Any:
    """``options["state"]`` (None when absent); any other option is a ``ValueError``."""
    rest = {} if options is None else dict(options)
    start = rest.pop("state", None)
    if rest:
        raise ValueError(f"unknown reset option(s) {sorted(rest)}; the only option is 'state'")
    return start


def numeric_start_state(state: Any, names: tuple[str, ...]) -> FloatArray:
    """``options["state"]`` as a finite float64 vector, one entry per name, or a ``ValueError``."""
    what = f"[{', '.join(names)}]"
    try:
        s = np.asarray(state, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"options['state'] must be numeric {what}: {exc}") from exc
    if s.shape != (len(names),):
        raise ValueError(f"options['state'] has shape {s.shape}; expected ({len(names)},) {what}")
    if not np.isfinite(s).all():
        raise ValueError(f"options['state'] = {s.tolist()} is not finite")
    return s


def episode_horizon(spec: gymnasium.envs.registration.EnvSpec | None, default: int) -> int:
    """The registered ``max_episode_steps``, or ``default`` for an env made directly."""
    limit = spec.max_episode_steps if spec is not None else None
    return int(limit) if limit is not None else default
