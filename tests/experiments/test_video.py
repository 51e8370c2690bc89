"""``geoq evaluate AGENT --video FILE.gif``: one greedy episode as an animated GIF."""

from __future__ import annotations

from pathlib import Path

import gymnasium
import numpy as np
import pytest
from PIL import Image, ImageSequence
from typer.testing import CliRunner

from geoq.agents import GPQAgent
from geoq.cli import app
from geoq.experiments.control.evaluation import evaluate_agent
from geoq.experiments.control.video import check_renderable, gif_bytes, record_episode

RUNNER = CliRunner()


@pytest.fixture(scope="module")
def tiny_agent(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A saved two-rooms agent after a few steps (the episode it is filmed in is 200 steps
    at most; the frames, not the learning, are under test)."""
    agent = GPQAgent("geoq/TwoRooms-v0", max_bv=20, seed=0, n_candidates=5)
    agent.learn(40)
    path = tmp_path_factory.mktemp("agent") / "agent.npz"
    agent.save(path)
    return path


def test_evaluate_writes_a_valid_multi_frame_gif(tiny_agent: Path, tmp_path: Path) -> None:
    video = tmp_path / "episode.gif"
    result = RUNNER.invoke(
        app, ["evaluate", str(tiny_agent), "--episodes", "1", "--video", str(video)]
    )
    assert result.exit_code == 0, result.output
    assert f"video: {video}" in result.output
    agent = GPQAgent.load(tiny_agent)
    episode = record_episode(agent, seed=0)
    with Image.open(video) as gif:
        assert gif.format == "GIF"
        assert gif.size == (400, 400)
        assert gif.info["loop"] == 0
        frames, durations = [], []
        for f in ImageSequence.Iterator(gif):
            frames.append(np.asarray(f.convert("RGB")))
            durations.append(f.info["duration"])
    # Pillow merges repeated frames (the point pressed against the wall) into one with the
    # summed delay: the film still lasts one 50 ms frame (20 fps) per state.
    assert len(frames) >= 2
    assert sum(durations) == 50 * len(episode.frames)
    assert not np.array_equal(frames[0], frames[-1]), "the point never moved"
    starts = np.cumsum([0, *durations[:-1]]) // 50  # the state each GIF frame shows first
    for k in (0, len(frames) // 2, len(frames) - 1):  # GIF quantises colours: compare loosely
        assert np.mean(np.abs(frames[k].astype(int) - episode.frames[starts[k]])) < 3.0
    assert [p.name for p in tmp_path.iterdir()] == ["episode.gif"], "a temporary file was left"


def test_the_video_is_the_first_evaluation_episode_of_the_seed(tiny_agent: Path) -> None:
    agent = GPQAgent.load(tiny_agent)
    for seed in (0, 7):
        episode = record_episode(agent, seed=seed)
        first = evaluate_agent(agent, n_episodes=1, seed=seed)
        assert episode.ret == first.returns[0]
        assert len(episode.frames) == 1 - int(episode.ret)  # -1 per step, a frame per state


@pytest.mark.parametrize(
    ("name", "match"),
    [("episode.png", "does not end in .gif"), ("missing/episode.gif", "does not exist")],
)
def test_bad_video_paths_are_usage_errors_before_any_work(
    tiny_agent: Path, tmp_path: Path, name: str, match: str
) -> None:
    result = RUNNER.invoke(app, ["evaluate", str(tiny_agent), "--video", str(tmp_path / name)])
    assert result.exit_code == 2
    assert match in " ".join(result.output.split())
    assert not list(tmp_path.iterdir())


def test_a_directory_is_not_a_video_path(tiny_agent: Path, tmp_path: Path) -> None:
    (tmp_path / "d.gif").mkdir()
    result = RUNNER.invoke(app, ["evaluate", str(tiny_agent), "--video", str(tmp_path / "d.gif")])
    assert result.exit_code == 2


class _Blind(gymnasium.Env[np.ndarray, np.ndarray]):
    metadata = {"render_modes": []}  # noqa: RUF012

    def __init__(self, render_mode: str | None = None) -> None:
        self.observation_space = gymnasium.spaces.Box(-1.0, 1.0, (1,))
        self.action_space = gymnasium.spaces.Box(-1.0, 1.0, (1,))


def test_an_env_that_cannot_draw_is_refused_with_the_reason() -> None:
    gymnasium.register("geoq_test/Blind-v0", entry_point=_Blind)
    try:
        with pytest.raises(ValueError, match=r"cannot draw frames \(render modes \[\]\)"):
            check_renderable("geoq_test/Blind-v0")
    finally:
        del gymnasium.registry["geoq_test/Blind-v0"]
    check_renderable("geoq/PendulumSwingUp-v0")


def test_gif_bytes_refuses_nothing_to_show() -> None:
    with pytest.raises(ValueError, match="no frames"):
        gif_bytes([], 20.0)
    with pytest.raises(ValueError, match="fps"):
        gif_bytes([np.zeros((4, 4, 3), np.uint8)], 0.0)
