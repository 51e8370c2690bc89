"""The ``GPQAgent`` file format: a versioned, pickle-free ``.npz`` (see ``geoq._io``).

Arrays: ``gp/*`` (the sparse GP), ``buffer/*`` (the transitions and their
targets), ``episodes``, ``candidates``, ``action_box``, ``obs_dim``,
``covariances/*`` (the fitted-Q phases' column order, optional), ``explorer/*``
(the exploration map, :mod:`geoq.agents.map_explorer`; optional), ``model/*`` (the
dynamics model and plans, :mod:`geoq.agents.model_planning`; with a planner), ``actor/*``
(the policy trained on ``Q``, :mod:`geoq.agents.q_actor`; once it has weights), ``kept_q/*``
(the copy of ``Q`` greedy actions follow, :mod:`geoq.agents.kept_q`; with ``keep_q``); ``meta``
is JSON (config, scaling, env id, seed, generator state, standardisation,
counters). Optional meta keys added after version 1 default to a fresh agent's
values, so older files load.

The stored config is resolved on loading exactly as a new agent's is
(:meth:`GPQConfig.for_dims`: a hand-edited ``"auto"`` or ``max_bv: null`` becomes
what an agent of those settings holds) and checked against the rest of the file:
the GP's budget, noise and novelty threshold, its kernel (kind and hyper-parameters:
those the config makes with the length-scales in use and the stored scaling's
periods) and the fitted length-scales; a mismatch is an :class:`ArchiveError` that
names the field.
"""

from __future__ import annotations

import json
from os import PathLike
from typing import TYPE_CHECKING, Any

import gymnasium
import numpy as np

from geoq._io import ArchiveError, load_archive, save_archive
from geoq._typing import FloatArray
from geoq.agents.buffer import TransitionBuffer
from geoq.agents.config import GPQConfig, check_seed
from geoq.agents.map_explorer import MapExplorer
from geoq.agents.state import LearningState, TrainingLog
from geoq.gp import SparseOnlineGP
from geoq.kernels.base import kernel_to_arrays
from geoq.learners.scaling import InputScaling

if TYPE_CHECKING:
    from geoq.agents.gpq import GPQAgent

__all__ = ["load_agent", "save_agent"]

_ARCHIVE_KIND = "GPQAgent"
_ARCHIVE_VERSION = 1

#: Config fields a file written before them lacks, and the value its code behaved as:
#: phases every ``train_every`` steps, length-scales by the rule, the candidates' greedy,
#: no actor, evidence fits on 300 points, no kept ``Q``.
_LEGACY_CONFIG: dict[str, Any] = {
    "train_fraction": 0.0,
    "hyperparameters": "rule",
    "greedy_actions": "candidates",
    "actor": "off",
    "evidence_points": 300,
    "evidence_points_blind": 300,
    "keep_q": "off",
}

#: The config field (or file entry) behind each of a kernel's saved hyper-parameters
#: (:func:`geoq.kernels.base.kernel_to_arrays` keys without ``kernel.``); the others
#: are the state a kernel follows its basis with (graph nodes, paths, ...), unchecked.
_KERNEL_FIELDS = {
    "class": "kernel", "distance": "kernel", "distance.method": "kernel",
    "distance.normalize": "kernel", "distance.attach": "kernel",
    "distance.graph.edge_weight": "kernel", "distance.graph.temporal_edges": "kernel",
    "variance": "amplitude", "distance.sigma_sp": "sigma_sp", "distance.sigma_se": "sigma_se",
    "distance.graph.eps": "eps", "distance.lengthscale": "resistance_lengthscale",
    "lengthscale": "lengthscale (or state_lengthscale / action_lengthscale, fitted_lengthscale)",
    "period": "scaling periods", "distance.graph.period": "scaling periods",
}  # fmt: skip


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
    arrays.update({f"model/{k}": v for k, v in agent.planning.to_arrays().items()})
    arrays.update({f"actor/{k}": v for k, v in agent.actor.to_arrays().items()})
    arrays.update({f"kept_q/{k}": v for k, v in agent.kept_q.to_arrays().items()})
    save_archive(path, _ARCHIVE_KIND, _ARCHIVE_VERSION, arrays)


def load_agent(
    cls: type[GPQAgent], path: str | PathLike[str], env: gymnasium.Env | str | None
) -> GPQAgent:
    """Read an agent written by :func:`save_agent` (see :meth:`GPQAgent.load`)."""
    _, a = load_archive(path, _ARCHIVE_KIND, _ARCHIVE_VERSION)
    try:
        meta = json.loads(str(a["meta"]))
        config = GPQConfig.from_dict({**_LEGACY_CONFIG, **meta["config"]})
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
        config = config.for_dims(obs_dim, d_a)  # as a new agent's: "auto" and None resolved
        _check_config(config, gp, state, scaling, obs_dim, candidates)
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
        _check_explorer(config, agent.explorer)
        agent.planning.restore({k[6:]: v for k, v in a.items() if k.startswith("model/")},
                               str(path))  # fmt: skip
        agent.actor.restore({k[6:]: v for k, v in a.items() if k.startswith("actor/")}, obs_dim)
        kept = {k[7:]: v for k, v in a.items() if k.startswith("kept_q/")}
        agent.kept_q.restore(kept, agent, str(path))
    except (KeyError, ValueError, TypeError) as exc:
        raise ArchiveError(f"{path}: inconsistent GPQAgent archive ({exc}); save it again") from exc
    agent.env = None
    if env is None and agent.env_id and agent.env_id in gymnasium.registry:
        env = agent.env_id
    if env is not None:
        agent.set_env(env)
    return agent


def _check_config(
    config: GPQConfig, gp: SparseOnlineGP, state: LearningState, scaling: InputScaling,
    obs_dim: int, candidates: FloatArray,
) -> None:  # fmt: skip
    """A ``ValueError`` naming the field unless the resolved ``config`` is what made ``gp``,
    ``state`` and ``candidates`` ``[K, d_a]`` (an agent of ``obs_dim`` + ``d_a`` inputs
    scaled by ``scaling``): the candidates' count, the GP's budget, noise, novelty
    threshold and input width, its kernel's kind and hyper-parameters, and the fitted
    length-scales' count and origin."""
    n, action_dim = candidates.shape
    k = config.n_candidates if action_dim == 1 else 2 ** int(np.ceil(np.log2(config.n_candidates)))
    if n != k:
        raise ValueError(f"config n_candidates is {config.n_candidates} but the file holds {n} "
                         f"candidate actions, not {k}")  # fmt: skip
    d = obs_dim + action_dim
    for name, value in (("max_bv", gp.max_bv), ("noise", gp.noise), ("tol", gp.tol)):
        if getattr(config, name) != value:
            raise ValueError(
                f"config {name} is {getattr(config, name)!r} but the stored GP's is {value!r}"
            )
    if gp.n_bv and gp.basis_vectors.shape[1] != d:
        raise ValueError(f"the stored GP's inputs have {gp.basis_vectors.shape[1]} dimensions, "
                         f"not {d}")  # fmt: skip
    fitted = state.fitted_lengthscale
    if fitted is not None and len(fitted) != d:
        raise ValueError(f"fitted_lengthscale has {len(fitted)} entries for {d} inputs")
    if fitted is not None and config.hyperparameters != "evidence":
        raise ValueError(
            f"fitted_lengthscale is set but config hyperparameters is {config.hyperparameters!r} "
            "(length-scales are fitted only with 'evidence')"
        )
    lengthscale = config.lengthscale_in_use(obs_dim, action_dim, state)
    made = config.agent_kernel(lengthscale, scaling)  # as GPQAgent._new_gp makes it
    expected, stored = kernel_to_arrays(made, ""), kernel_to_arrays(gp.kernel, "")
    for key, field in _KERNEL_FIELDS.items():
        want, got = expected.get(key), stored.get(key)
        if want is None or got is None:
            same = want is None and got is None
        else:
            same = np.shape(want) == np.shape(got) and bool(np.array_equal(want, got))
        if not same:
            raise ValueError(
                f"the stored GP's kernel has {key} {_show(got)} where the config makes "
                f"{_show(want)} (config field: {field})"
            )


def _check_explorer(config: GPQConfig, explorer: MapExplorer) -> None:
    """A ``ValueError`` naming ``explore_map`` if the restored map contradicts it: ``off``
    has none (and has decided so), ``on`` has one once decided."""
    mode, has_map = config.explore_map, explorer.map is not None
    if (mode == "off" and (has_map or not explorer.decided)) or (
        mode == "on" and explorer.decided and not has_map
    ):
        state = "a map" if has_map else ("no map" if explorer.decided else "no map yet")
        raise ValueError(f"config explore_map is {mode!r} but the file holds {state}")


def _show(value: Any) -> str:
    return "none" if value is None else repr(np.asarray(value).tolist())
