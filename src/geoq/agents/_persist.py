"""The ``GPQAgent`` file format: a versioned, pickle-free ``.npz`` (see ``geoq._io``).

Arrays: ``gp/*`` (the sparse GP), ``buffer/*`` (the transitions and their
targets), ``episodes``, ``candidates``, ``action_box``, ``obs_dim``,
``covariances/*`` (the fitted-Q phases' column order, optional); ``meta``
is JSON (config, scaling, env id, seed, generator state, standardisation,
counters). Optional meta keys added after version 1 default to a fresh agent's
values, so older files load.
"""

from __future__ import annotations

import json
from os import PathLike
from typing import TYPE_CHECKING, Any

import gymnasium
import numpy as np

from geoq._io import ArchiveError, load_archive, save_archive
from geoq.agents._covariance_cache import NextStateCovariances
from geoq.agents.buffer import EpisodeRecord, TransitionBuffer
from geoq.agents.config import GPQConfig
from geoq.gp import SparseOnlineGP
from geoq.learners.scaling import InputScaling

if TYPE_CHECKING:
    from geoq.agents.gpq import GPQAgent

__all__ = ["load_agent", "save_agent"]

_ARCHIVE_KIND = "GPQAgent"
_ARCHIVE_VERSION = 1


def save_agent(agent: GPQAgent, path: str | PathLike[str]) -> None:
    """Write ``agent`` to ``path`` (see :meth:`GPQAgent.save`)."""
    arrays: dict[str, Any] = {f"gp/{k}": v for k, v in agent.gp.to_arrays().items()}
    arrays.update({f"buffer/{k}": v for k, v in agent.buffer.to_arrays().items()})
    meta = {
        "config": agent.config.as_dict(),
        "scaling": agent.scaling.as_dict(),
        "env_id": agent.env_id,
        "seed": agent.seed,
        "rng_state": agent.rng.bit_generator.state,
        "y_mean": agent.y_mean,
        "y_scale": agent.y_scale,
        "reward_range": list(agent.reward_range),
        "terminal_reward_range": list(agent.terminal_reward_range),
        "num_timesteps": agent.num_timesteps,
        "last_train_timestep": agent.last_train_timestep,
        "fitted_q_sweeps": agent.fitted_q_sweeps,
        "fitted_q_residuals": agent.fitted_q_residuals,
        "imagined_counts": agent.imagined_counts,
        "train_seconds": agent.train_seconds,
        "scaling_pending": agent.scaling_pending,
        "data_scaled": agent.data_scaled,
        "rescales": agent.rescales,
        "fitted_lengthscale": agent.fitted_lengthscale,
        "evidence_fits": agent.evidence_fits,
        "evidence_due": agent.evidence_due,
    }
    arrays["meta"] = np.asarray(json.dumps(meta, allow_nan=True))
    arrays["episodes"] = np.array(
        [[e.timesteps, e.episode, e.ret, e.success] for e in agent.episodes], dtype=np.float64
    ).reshape(-1, 4)
    arrays["candidates"] = agent.candidates
    arrays["action_box"] = np.vstack([agent.action_low, agent.action_high])
    arrays["obs_dim"] = np.int64(agent.obs_dim)
    arrays.update({f"covariances/{k}": v for k, v in agent._next_covariances.slot_arrays().items()})
    save_archive(path, _ARCHIVE_KIND, _ARCHIVE_VERSION, arrays)


def load_agent(
    cls: type[GPQAgent], path: str | PathLike[str], env: gymnasium.Env | str | None
) -> GPQAgent:
    """Read an agent written by :func:`save_agent` (see :meth:`GPQAgent.load`)."""
    _, a = load_archive(path, _ARCHIVE_KIND, _ARCHIVE_VERSION)
    try:
        meta = json.loads(str(a["meta"]))
        # A file from before train_fraction ran its phases every train_every steps.
        config = GPQConfig.from_dict({"train_fraction": 0.0, **meta["config"]})
        sc = meta["scaling"]
        scaling = InputScaling(tuple(sc["scale"]), tuple(sc["periods"]), tuple(sc["names"]))
        box = np.asarray(a["action_box"], dtype=np.float64)
        candidates = np.asarray(a["candidates"], dtype=np.float64)
        obs_dim = int(a["obs_dim"])
        gp = SparseOnlineGP.from_arrays(
            {k[3:]: v for k, v in a.items() if k.startswith("gp/")}, source=path
        )
        buffer = TransitionBuffer.from_arrays(
            {k[7:]: v for k, v in a.items() if k.startswith("buffer/")}
        )
        episodes = np.asarray(a["episodes"], dtype=np.float64)
    except ArchiveError:
        raise
    except (KeyError, ValueError, TypeError) as exc:
        raise ArchiveError(f"{path}: not a valid GPQAgent archive ({exc}); save it again") from exc
    d_a = box.shape[1] if box.ndim == 2 else -1
    if (
        box.shape != (2, d_a) or candidates.ndim != 2 or candidates.shape[1] != d_a
        or scaling.dim != obs_dim + d_a or buffer.obs_dim != obs_dim
        or buffer.action_dim != d_a or episodes.ndim != 2 or episodes.shape[1] != 4
        or not (np.all(np.isfinite(box)) and np.all(np.isfinite(candidates)))
        or np.any(candidates < box[0]) or np.any(candidates > box[1])
        or not np.isfinite(meta["y_mean"]) or not (meta["y_scale"] > 0)
    ):  # fmt: skip
        raise ArchiveError(f"{path}: inconsistent GPQAgent archive; save it again")
    agent = cls.__new__(cls)
    agent.config, agent.scaling = config, scaling
    agent.obs_dim, agent.action_dim = obs_dim, d_a
    agent.action_low, agent.action_high = box[0].copy(), box[1].copy()
    agent.env_id = str(meta["env_id"])
    agent.seed = meta["seed"]
    agent.rng = np.random.default_rng()
    agent.rng.bit_generator.state = meta["rng_state"]
    agent.candidates = candidates
    agent.gp, agent.buffer = gp, buffer
    agent.y_mean, agent.y_scale = float(meta["y_mean"]), float(meta["y_scale"])
    lo, hi = meta["reward_range"]
    agent.reward_range = (float(lo), float(hi))
    # Files before the split counted terminal rewards in reward_range: still valid bounds.
    t_lo, t_hi = meta.get("terminal_reward_range", (np.inf, -np.inf))
    agent.terminal_reward_range = (float(t_lo), float(t_hi))
    agent.num_timesteps = int(meta["num_timesteps"])
    agent.last_train_timestep = int(meta.get("last_train_timestep", agent.num_timesteps))
    agent.fitted_q_sweeps = [int(v) for v in meta["fitted_q_sweeps"]]
    # Files before the field did not record the residuals: NaN, one per phase.
    residuals = meta.get("fitted_q_residuals", [np.nan] * len(agent.fitted_q_sweeps))
    agent.fitted_q_residuals = [float(v) for v in residuals]
    agent.imagined_counts = [int(v) for v in meta.get("imagined_counts", [])]
    agent.train_seconds = float(meta.get("train_seconds", 0.0))
    agent.scaling_pending = bool(meta.get("scaling_pending", False))
    agent.data_scaled = bool(meta.get("data_scaled", False))
    agent.rescales = int(meta.get("rescales", 0))
    fitted = meta.get("fitted_lengthscale")
    agent.fitted_lengthscale = None if fitted is None else tuple(float(v) for v in fitted)
    agent.evidence_fits = list(meta.get("evidence_fits", []))
    agent.evidence_due = int(meta.get("evidence_due", 0))
    agent._next_covariances = NextStateCovariances(agent.max_bv)
    if "covariances/slots" in a:  # files from before the slots: a fresh column order
        try:
            agent._next_covariances.restore_slots(
                np.asarray(a["covariances/basis"]), np.asarray(a["covariances/slots"])
            )
        except (KeyError, ValueError) as exc:
            raise ArchiveError(
                f"{path}: inconsistent GPQAgent archive ({exc}); save it again"
            ) from exc
    agent.episodes = [EpisodeRecord(int(t), int(e), float(r), float(s)) for t, e, r, s in episodes]
    agent.env = None
    if env is None and agent.env_id and agent.env_id in gymnasium.registry:
        env = agent.env_id
    if env is not None:
        agent.set_env(env)
    return agent
