"""``render_mode="rgb_array"`` of the bundled envs: Gymnasium's render API, and frames that
show the state (shape, dtype, determinism, content)."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import geoq  # noqa: F401  (registers the envs)
from geoq.envs import PendulumSwingUpEnv, TwoRoomsEnv
from geoq.envs._render import FRAME_SIZE, TwoRoomsPainter, two_rooms_frame

ENV_IDS = ["geoq/PendulumSwingUp-v0", "geoq/TwoRooms-v0"]
ROD = np.array([204, 77, 77])
BLUE = np.array([45, 85, 200])


def _frames(env_id: str, seed: int, n: int) -> list[np.ndarray]:
    env = gymnasium.make(env_id, render_mode="rgb_array")
    env.reset(seed=seed)
    env.action_space.seed(seed)
    frames = [env.render()]
    for _ in range(n):
        env.step(env.action_space.sample())
        frames.append(env.render())
    env.close()
    return frames


@pytest.mark.filterwarnings("ignore:.*symmetric and normalized space")
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_rgb_array_follows_gymnasium_render_api(env_id: str) -> None:
    env = gymnasium.make(env_id, render_mode="rgb_array")
    assert "rgb_array" in env.metadata["render_modes"]
    assert env.metadata["render_fps"] == 20
    assert env.render_mode == "rgb_array"
    env.reset(seed=0)
    frame = env.render()
    assert isinstance(frame, np.ndarray)
    assert frame.shape == (FRAME_SIZE, FRAME_SIZE, 3)
    assert frame.dtype == np.uint8
    check_env(env.unwrapped, skip_render_check=False)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_frames_are_deterministic_and_follow_the_state(env_id: str) -> None:
    a, b = _frames(env_id, 3, 12), _frames(env_id, 3, 12)
    for fa, fb in zip(a, b, strict=True):
        np.testing.assert_array_equal(fa, fb)
    assert not np.array_equal(a[0], a[-1]), "the frame did not change with the state"
    c = _frames(env_id, 4, 12)
    assert not np.array_equal(a[-1], c[-1])


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_without_a_render_mode_render_warns_and_returns_none(env_id: str) -> None:
    env = gymnasium.make(env_id).unwrapped
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode"):
        assert env.render() is None


@pytest.mark.parametrize("cls", [PendulumSwingUpEnv, TwoRoomsEnv])
def test_render_before_reset_and_unknown_modes_are_refused(cls: type) -> None:
    with pytest.raises(RuntimeError, match="reset"):
        cls(render_mode="rgb_array").render()
    with pytest.raises(ValueError, match="'rgb_array'"):
        cls(render_mode="ansi")


def _matches(frame: np.ndarray, color: np.ndarray) -> np.ndarray:
    return np.all(np.abs(frame.astype(int) - color) <= 2, axis=-1)


@pytest.mark.parametrize(("theta", "above"), [(0.0, True), (np.pi, False), (0.2, True)])
def test_the_rod_points_where_theta_says(theta: float, above: bool) -> None:
    env = PendulumSwingUpEnv(render_mode="rgb_array")
    env.reset(options={"state": [theta, 0.0]})
    rod = _matches(env.render(), ROD)
    rows, cols = np.nonzero(rod)
    assert rod.sum() > 500
    centre = FRAME_SIZE / 2
    assert (np.mean(rows) < centre) == above  # image rows grow downwards
    if theta == 0.2:  # positive theta leans right on screen
        assert np.mean(cols) > centre


def test_the_torque_bar_shows_the_last_torque() -> None:
    env = PendulumSwingUpEnv(render_mode="rgb_array")
    env.reset(options={"state": [np.pi, 0.0]})
    still = env.render()
    env.step(np.array([5.0]))
    pushed = env.render()
    bar = slice(int(0.88 * FRAME_SIZE), FRAME_SIZE)
    assert not _matches(still[bar], BLUE).any()
    cols = np.nonzero(_matches(pushed[bar], BLUE))[1]
    assert cols.size and cols.min() >= FRAME_SIZE // 2 - 1  # right of the centre


def test_the_point_is_drawn_at_its_position() -> None:
    env = TwoRoomsEnv(render_mode="rgb_array")
    for x, y in [(0.2, 0.8), (0.75, 0.2), (0.9, 0.9)]:
        env.reset(options={"state": [x, y]})
        rows, cols = np.nonzero(_matches(env.render(), BLUE))
        margin, side = 0.05 * FRAME_SIZE, 0.9 * FRAME_SIZE
        assert abs(np.mean(cols) - (margin + side * x)) < 2
        assert abs(np.mean(rows) - (margin + side * (1 - y))) < 2


def test_the_painter_gives_the_bits_of_a_fresh_drawing_whatever_came_before() -> None:
    path = np.random.default_rng(0).uniform(0, 1, size=(30, 2))
    painter = TwoRoomsPainter()
    for k in (1, 5, 6, 30, 12):  # growing, then an unrelated (shorter) path: redrawn
        np.testing.assert_array_equal(painter.frame(path[:k]), two_rooms_frame(path[:k]))
