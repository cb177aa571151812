"""The navigation GIF: frame count, size and timing, and frames that change where, and
only where, the robot moves."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from gracenav.plotting.navigation import animate_episode
from gracenav.scenarios import parse_scenario, run_scenario

FIG5 = Path(str(resources.files("gracenav") / "data" / "scenarios" / "fig5_point_to_point.yaml"))
TAB_BLUE = np.array([31, 119, 180])  # the ball
REACH_PX = 70  # the ball, the lean line (<= 0.6 m) and D' (< 0.3 m) lie within this of the ball


@pytest.fixture(scope="module")
def fig5_one_run():  # type: ignore[no-untyped-def]
    data = yaml.safe_load(FIG5.read_text())
    data["task"]["starts"] = data["task"]["starts"][:1]  # from (0, 0): north, then east
    return run_scenario(parse_scenario(data, source=str(FIG5)))


def frames_of(path: Path) -> list[np.ndarray]:
    with Image.open(path) as gif:
        out = []
        for k in range(gif.n_frames):
            gif.seek(k)
            out.append(np.asarray(gif.convert("RGB")).astype(np.int16))
            assert gif.info["duration"] == 100
        assert gif.info["loop"] == 0
    return out


def data_to_pixels(frame: np.ndarray, bounds: tuple) -> tuple[np.ndarray, np.ndarray]:
    """Affine map from map coordinates (m) to pixel (column, row): scale and origin, from
    the map's border line, the only dark lines that run along most of the axes."""
    dark = frame.sum(axis=2) < 150
    cols = np.flatnonzero(dark.mean(axis=0) > 0.5)
    rows = np.flatnonzero(dark.mean(axis=1) > 0.5)
    (x0, y0), (x1, y1) = bounds
    scale = np.array([(cols.max() - cols.min()) / (x1 - x0), (rows.min() - rows.max()) / (y1 - y0)])
    origin = np.array([cols.min(), rows.max()]) - scale * np.array([x0, y0])
    return scale, origin


def test_gif_frames_size_and_motion(fig5_one_run, tmp_path) -> None:  # type: ignore[no-untyped-def]
    result = fig5_one_run
    ep = result.episodes[0]
    assert ep.reached_goal
    out = animate_episode(result, 0, tmp_path / "animation.gif")
    assert out == tmp_path / "animation.gif"
    frames = frames_of(out)
    ticks = np.arange(0, ep.time.size, round(0.1 / (ep.time[1] - ep.time[0])))
    # one frame per 0.1 s of the episode (102 ticks of 1/1024 s), the first at t = 0
    assert len(frames) == ticks.size == -(-ep.time.size // 102)
    assert all(f.shape == (500, 500, 3) for f in frames)
    scale, origin = data_to_pixels(frames[0], result.world_map.bounds)
    np.testing.assert_allclose(abs(scale[0]), abs(scale[1]), rtol=0.02)  # equal aspect
    ball = origin + scale * ep.position_state[ticks, :2]  # pixel (column, row) per frame
    path = np.rint(origin + scale * ep.position_state[:, :2]).astype(int)
    top = int(np.rint(origin[1] + scale[1] * result.world_map.bounds[1][1]))
    # The tick at which the path first comes within 3 px of each pixel: the trail so far
    # is redrawn whole every frame.
    reached = np.full((500, 500), ep.time.size)
    tick = np.arange(path.shape[0])
    for dr in range(-3, 4):
        for dc in range(-3, 4):
            np.minimum.at(reached, (path[:, 1] + dr, path[:, 0] + dc), tick)
    for k in range(1, len(frames)):
        changed = np.abs(frames[k] - frames[k - 1]).sum(axis=2) > 30
        changed[:top] = False  # the title (the clock) changes every frame
        near = reached <= ticks[k]
        for c, r in np.rint(ball[k - 1 : k + 1]).astype(int):
            near[max(r - REACH_PX, 0) : r + REACH_PX, max(c - REACH_PX, 0) : c + REACH_PX] = True
        # Nothing changes away from the robot and its trail.
        assert not np.any(changed & ~near), k
    moved = 0
    for k in range(3, len(frames)):
        step = ball[k] - ball[k - 3]
        if np.hypot(*step) < 12:  # the ball's marker is 11 px across
            continue
        moved += 1
        # The ball is drawn at its new place, which it had not reached ...
        c, r = np.rint(ball[k]).astype(int)
        assert np.abs(frames[k][r, c] - TAB_BLUE).max() < 30, k
        assert np.abs(frames[k - 3][r, c] - TAB_BLUE).max() > 60, k
        # ... and is gone from its old place (beside the trail through its centre).
        side = np.array([-step[1], step[0]]) / np.hypot(*step)
        c, r = np.rint(ball[k - 3] + 4 * side).astype(int)
        assert np.abs(frames[k - 3][r, c] - TAB_BLUE).max() < 30, k
        assert np.abs(frames[k][r, c] - TAB_BLUE).max() > 60, k
    assert moved > 20
    # The title changes every frame (the clock); the first and last frames differ.
    assert all(np.any(frames[k][:top] != frames[k - 1][:top]) for k in range(1, len(frames)))
    assert np.abs(frames[-1] - frames[0]).sum(axis=2).astype(bool).sum() > 1000


def test_gif_frame_rate(fig5_one_run, tmp_path) -> None:  # type: ignore[no-untyped-def]
    ep = fig5_one_run.episodes[0]
    out = animate_episode(fig5_one_run, 0, tmp_path / "slow.gif", fps=5)
    with Image.open(out) as gif:
        assert gif.n_frames == np.arange(0, ep.time.size, 205).size == -(-ep.time.size // 205)
        assert gif.size == (500, 500) and gif.info["duration"] == 200
