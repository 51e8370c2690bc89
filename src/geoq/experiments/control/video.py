"""Pictures of an agent at work: one greedy episode as frames, and an animated GIF.

* :func:`check_renderable`: whether an env id can draw ``rgb_array`` frames (a
  ``ValueError`` saying what to do if not), cheap enough to call before any work.
* :func:`record_episode`: one deterministic (greedy) episode of an agent, with a frame
  of the env's ``render()`` before the first step and after every step.
* :func:`gif_bytes` / :func:`write_gif`: frames -> animated GIF (Pillow, which
  matplotlib already needs), written atomically like every other output.

``geoq evaluate AGENT --video FILE.gif`` is these three in a row.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from pathlib import Path

import gymnasium
import numpy as np

from geoq._io import atomic_write_bytes
from geoq.experiments.control.evaluation import Actor

__all__ = ["RecordedEpisode", "check_renderable", "gif_bytes", "record_episode", "write_gif"]


@dataclass(frozen=True)
class RecordedEpisode:
    """One greedy episode with its frames.

    Attributes
    ----------
    frames : ``[T + 1]`` images ``[H, W, 3]`` uint8: the start state, then one per step.
    ret : undiscounted return.
    success : ``info["is_success"]`` at the end (1/0), NaN where unreported.
    fps : the env's ``metadata["render_fps"]`` (frames per second of real time).
    """

    frames: list[np.ndarray]
    ret: float
    success: float
    fps: float


def _episode_seed(seed: int) -> int:
    """The reset seed of episode 0 of ``evaluate_agent(..., seed=seed)``: the video shows
    the first of the evaluation episodes of the same seed."""
    return int(np.random.SeedSequence(seed).spawn(1)[0].generate_state(1)[0])


def check_renderable(env_id: str) -> None:
    """A ``ValueError`` saying why unless ``env_id`` draws ``rgb_array`` frames: it lists
    the mode and a first frame after a reset is an ``[H, W, 3]`` uint8 array (so a missing
    drawing library, e.g. pygame for Gymnasium's classic-control envs, is found here)."""
    advice = "videos need render_mode='rgb_array', e.g. geoq/PendulumSwingUp-v0 or geoq/TwoRooms-v0"
    probe = gymnasium.make(env_id)
    spec_modes = list(probe.metadata.get("render_modes", []))
    probe.close()
    if "rgb_array" not in spec_modes:
        raise ValueError(f"{env_id} cannot draw frames (render modes {spec_modes}); {advice}")
    try:
        env = gymnasium.make(env_id, render_mode="rgb_array")
        try:
            env.reset(seed=0)
            frame = env.render()
        finally:
            env.close()
    except (ImportError, gymnasium.error.Error) as exc:  # DependencyNotInstalled is both
        raise ValueError(f"{env_id} cannot draw frames here: {exc}") from exc
    if not (
        isinstance(frame, np.ndarray)
        and frame.dtype == np.uint8
        and frame.ndim == 3
        and frame.shape[2] == 3
    ):
        raise ValueError(f"{env_id}'s render() gave no [H, W, 3] uint8 frame; {advice}")


def record_episode(agent: Actor, env_id: str | None = None, seed: int = 0) -> RecordedEpisode:
    """One deterministic (greedy) episode of ``agent`` with a frame per state.

    The episode starts from the reset of episode 0 of
    :func:`~geoq.experiments.control.evaluation.evaluate_agent` with the same ``seed``, so its
    return is that episode's.
    """
    env_id = env_id or agent.env_id
    if not env_id:
        raise ValueError("the agent has no registered env id; pass env_id=")
    check_renderable(env_id)
    env = gymnasium.make(env_id, render_mode="rgb_array")
    try:
        obs, _ = env.reset(seed=_episode_seed(seed))
        frames = [np.asarray(env.render())]
        ret, success = 0.0, math.nan
        while True:
            action, _ = agent.predict(np.asarray(obs, dtype=np.float64)[None], deterministic=True)
            obs, r, terminated, truncated, info = env.step(
                np.asarray(action)[0].astype(env.action_space.dtype)
            )
            ret += float(r)
            frames.append(np.asarray(env.render()))
            if terminated or truncated:
                if "is_success" in info:
                    success = float(bool(info["is_success"]))
                break
        fps = float(env.metadata.get("render_fps") or 20)
    finally:
        env.close()
    return RecordedEpisode(frames=frames, ret=ret, success=success, fps=fps)


def gif_bytes(frames: list[np.ndarray], fps: float) -> bytes:
    """An animated, looping GIF of ``frames`` (each ``[H, W, 3]`` uint8) at ``fps``.

    GIF delays are whole centiseconds: 20 fps is exact (5 cs), others are rounded.
    """
    from PIL import Image

    if not frames:
        raise ValueError("no frames to write")
    if not math.isfinite(fps) or fps <= 0:
        raise ValueError(f"fps must be finite and > 0, got {fps!r}")
    images = [Image.fromarray(np.ascontiguousarray(f, dtype=np.uint8)) for f in frames]
    buffer = io.BytesIO()
    images[0].save(
        buffer,
        format="GIF",
        save_all=True,
        append_images=images[1:],
        duration=max(10 * round(100.0 / fps), 10),  # ms, whole centiseconds
        loop=0,
    )
    return buffer.getvalue()


def write_gif(path: str | Path, frames: list[np.ndarray], fps: float) -> Path:
    """Write :func:`gif_bytes` of ``frames`` to ``path`` atomically; return the path."""
    return atomic_write_bytes(path, gif_bytes(frames, fps))
