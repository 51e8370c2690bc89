"""Stable-Baselines3's SAC as a control baseline (benchmark only; optional dependency).

``pip install 'geoq[baselines]'`` installs stable-baselines3, which pulls torch
(several GB): neither ``make install``, ``make test`` nor ``make demo`` needs it.
SAC runs with its default settings (learning rate 3e-4 in SB3 >= 2, buffer
1e6, batch 256, ``learning_starts = 100``, one gradient step per env step) on
one torch thread, is evaluated exactly as the GP agent is
(:func:`geoq.experiments.control.evaluation.evaluate_agent`), at the same checkpoints.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np

from geoq.experiments.control.evaluation import ControlCell, learn_with_checkpoints

__all__ = ["BASELINES", "sac_cell"]

#: Names of the baselines a benchmark cell can run instead of a GP agent.
BASELINES: tuple[str, ...] = ("sac",)


class _Evaluated:
    """SB3 model -> the ``predict``/``env_id`` interface of :func:`evaluate_agent`."""

    def __init__(self, model: Any, env_id: str) -> None:
        self.model, self.env_id = model, env_id

    def predict(self, observation: Any, deterministic: bool = True) -> tuple[np.ndarray, None]:
        actions, _ = self.model.predict(observation, deterministic=deterministic)
        return np.asarray(actions, dtype=np.float64).reshape(len(observation), -1), None


def sac_cell(cell: ControlCell) -> dict[str, Any]:
    """Train SAC for ``cell.timesteps`` steps, evaluating every ``cell.eval_every``."""
    try:
        import torch
        from stable_baselines3 import SAC
    except ImportError as exc:  # pragma: no cover - depends on the optional extra
        raise ImportError(
            "the SAC baseline needs stable-baselines3: pip install 'geoq[baselines]' "
            "(it pulls torch, several GB)"
        ) from exc
    torch.set_num_threads(1)
    env = gymnasium.make(cell.env_id)
    model = SAC("MlpPolicy", env, seed=cell.seed, verbose=0, device="cpu", **dict(cell.config))
    row = learn_with_checkpoints(
        cell,
        lambda n: model.learn(total_timesteps=n, reset_num_timesteps=False),
        _Evaluated(model, cell.env_id),
    )
    return row | {"train_timesteps": [], "train_return": [], "n_bv": 0}
