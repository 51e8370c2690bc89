"""The ``GPQAgent`` file format: a versioned, pickle-free ``.npz`` (see ``geoq._io``).

Arrays: ``gp/*`` (the sparse GP), ``buffer/*`` (the transitions and their
targets), ``episodes``, ``candidates``, ``action_box``, ``obs_dim``,
``covariances/*`` (the fitted-Q phases' column order, optional), ``explorer/*``
(the exploration map, :mod:`geoq.agents.map_explorer`; optional); ``meta``
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
from geoq.agents.buffer import TransitionBuffer
from geoq.agents.config import GPQConfig, check_seed
from geoq.agents.state import LearningState, TrainingLog
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
        **agent.state.as_dict(),
        **agent.log.as_dict(),
    }
    arrays["meta"] = np.asarray(json.dumps(meta, allow_nan=True))
    arrays["episodes"] = agent.log.episodes_array()
    arrays["candidates"] = agent.candidates
    arrays["action_box"] = np.vstack([agent.action_low, agent.action_high])
    arrays["obs_dim"] = np.int64(agent.obs_dim)
    slots = agent.phase.covariances.slot_arrays()
    arrays.update({f"covariances/{k}": v for k, v in slots.items()})
    arrays.update({f"explorer/{k}": v for k, v in agent.explorer.to_arrays().items()})
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
        state = LearningState.from_dict(meta).check(config.gamma)
        log = TrainingLog.from_dict(meta, episodes)
        rng = np.random.default_rng()
        rng.bit_generator.state = meta["rng_state"]
        seed, env_id = check_seed(meta["seed"]), meta["env_id"]
        if not isinstance(env_id, str):
            raise ValueError(f"env_id {env_id!r} is not a string")
    except ArchiveError:
        raise
    except (KeyError, ValueError, TypeError, AttributeError, IndexError, OverflowError) as exc:
        raise ArchiveError(f"{path}: not a valid GPQAgent archive ({exc}); save it again") from exc
    d_a = box.shape[1] if box.ndim == 2 else -1
    if (
        box.shape != (2, d_a) or candidates.ndim != 2 or candidates.shape[1] != d_a
        or scaling.dim != obs_dim + d_a or buffer.obs_dim != obs_dim
        or buffer.action_dim != d_a or episodes.ndim != 2 or episodes.shape[1] != 4
        or not (np.all(np.isfinite(box)) and np.all(np.isfinite(candidates)))
        or np.any(candidates < box[0]) or np.any(candidates > box[1])
        or state.num_timesteps < len(buffer) or not np.all(np.isfinite(episodes[:, :3]))
    ):  # fmt: skip
        raise ArchiveError(f"{path}: inconsistent GPQAgent archive; save it again")
    try:
        config.for_dims(obs_dim, d_a)  # the length-scales' count
        fitted = state.fitted_lengthscale
        if fitted is not None and len(fitted) != obs_dim + d_a:
            raise ValueError(f"{len(fitted)} fitted length-scales for {obs_dim + d_a} inputs")
    except ValueError as exc:
        raise ArchiveError(f"{path}: inconsistent GPQAgent archive ({exc}); save it again") from exc
    agent = cls.__new__(cls)
    agent._assemble(
        config=config, scaling=scaling, action_box=box, obs_dim=obs_dim, env_id=env_id,
        seed=seed, rng=rng, candidates=candidates, buffer=buffer, state=state, log=log,
    )  # fmt: skip
    agent.gp = gp
    if "covariances/slots" in a:  # files from before the slots: a fresh column order
        try:
            agent.phase.covariances.restore_slots(
                np.asarray(a["covariances/basis"]), np.asarray(a["covariances/slots"])
            )
        except (KeyError, ValueError) as exc:
            raise ArchiveError(
                f"{path}: inconsistent GPQAgent archive ({exc}); save it again"
            ) from exc
    try:  # files from before the map: none, as they explored
        agent.explorer.restore({k[9:]: v for k, v in a.items() if k.startswith("explorer/")})
    except (KeyError, ValueError, TypeError) as exc:
        raise ArchiveError(f"{path}: inconsistent GPQAgent archive ({exc}); save it again") from exc
    agent.env = None
    if env is None and agent.env_id and agent.env_id in gymnasium.registry:
        env = agent.env_id
    if env is not None:
        agent.set_env(env)
    return agent
