"""``gracenav run --log FILE.mcap``: the file read back, every channel checked, and the
sampled values compared with trajectory.csv and events.csv."""

from __future__ import annotations

import base64
import csv
import json
import math
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mcap")

from mcap.reader import make_reader

from gracenav.cli import main
from gracenav.scenarios.mcap_log import (
    LOG_CHANNELS,
    RUN_GAP,
    lean_from_quaternion,
    lean_quaternion,
)
from gracenav.world import load_map

FIG5_MAP = {
    "bounds": [[-1.0, -1.0], [3.5, 3.0]],
    "resolution": 0.05,
    "obstacles": [
        {"rectangle": {"min": [0.75, 1.0], "max": [1.25, 1.5]}},
        {"rectangle": {"min": [1.75, 0.25], "max": [2.25, 0.75]}},
    ],
}
PUSH_T, PUSH = 3.0, (0.0, 9.0)
STRIDE = 8


def _scenario(tmp: Path) -> Path:
    import yaml

    spec = {
        "name": "fig5 with a push",
        "map": FIG5_MAP,
        "robot": {"footprint_radius": 0.2},
        "planner": {"cost": "time", "max_halvings": 1},
        "task": {
            "kind": "point_to_point",
            "goal": [2.0, 2.0, 0.0, 0.0],
            "starts": [[0.0, 0.0, 0.0, 0.0], [0.0, 2.0, 0.0, 0.0]],
        },
        "disturbances": [{"kind": "push", "time": PUSH_T, "impulse": list(PUSH)}],
        "simulation": {"plant": "model3d", "seed": 0, "max_time": 40},
    }
    path = tmp / "pushed.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


@pytest.fixture(scope="module")
def logged(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    tmp = tmp_path_factory.mktemp("mcap")
    out, log = tmp / "out", tmp / "run.mcap"
    status = main(
        ["run", str(_scenario(tmp)), "--out", str(out), "--log", str(log), "--no-animation"]
    )
    assert status == 0
    return out, log


def _read(log: Path) -> dict[str, list[tuple[int, dict]]]:  # type: ignore[type-arg]
    topics: dict[str, list[tuple[int, dict]]] = defaultdict(list)  # type: ignore[type-arg]
    with log.open("rb") as fh:
        reader = make_reader(fh)
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            assert schema is not None
            assert schema.encoding == "jsonschema" and channel.message_encoding == "json"
            assert schema.name == LOG_CHANNELS[channel.topic]
            json.loads(schema.data)  # a valid JSON schema document
            topics[channel.topic].append((message.log_time, json.loads(message.data)))
    return topics


def _trajectory(out: Path) -> np.ndarray:
    return np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1)


def test_every_channel_is_there(logged: tuple[Path, Path]) -> None:
    _out, log = logged
    topics = _read(log)
    assert set(topics) == set(LOG_CHANNELS)
    assert len(topics["/map"]) == len(topics["/gracenav/robot"]) == 2  # one per run
    for _, m in topics["/gracenav/robot"]:
        ids = {e["id"] for e in m["entities"]}
        assert {"robot", "goal 0"} <= ids
        robot = next(e for e in m["entities"] if e["id"] == "robot")
        assert robot["frame_id"] == "base_link" and robot["spheres"] and robot["cylinders"]
    assert len(topics["/gracenav/path"]) == 2 + 2  # a trail per run and a push arrow per run


def test_samples_match_trajectory_csv(logged: tuple[Path, Path]) -> None:
    out, log = logged
    topics = _read(log)
    traj = _trajectory(out)
    states = [m for _, m in topics["/gracenav/state"]]
    tfs = [m for _, m in topics["/tf"]]
    assert len(states) == len(tfs)
    for run in (0, 1):
        rows = traj[traj[:, 0] == run]
        want = list(range(0, rows.shape[0], STRIDE))
        if want[-1] != rows.shape[0] - 1:
            want.append(rows.shape[0] - 1)
        got = [m for m in states if m["run"] == run]
        assert len(got) == len(want)
        sampled = rows[want]
        cols = ("t", "x", "y", "xdot", "ydot", "lean_x", "lean_y", "tau_x", "tau_y")
        values = np.array([[m[c] for c in cols] for m in got])
        # trajectory.csv keeps 6 decimals (t, x, y, velocities, reference), 7 significant
        # digits of the lean and 5 decimals of the torque
        np.testing.assert_allclose(values[:, :5], sampled[:, 1:6], rtol=0, atol=1.5e-6)
        np.testing.assert_allclose(values[:, 5:7], sampled[:, 6:8], rtol=1e-6, atol=1e-12)
        np.testing.assert_allclose(values[:, 7:9], sampled[:, 8:10], rtol=0, atol=1.5e-5)
        ref = np.array([[m["ref_x"], m["ref_y"]] for m in got])
        np.testing.assert_allclose(ref, sampled[:, 10:12], rtol=0, atol=1.5e-6)
        np.testing.assert_array_equal([m["policy"] for m in got], sampled[:, 12].astype(int))
    # The transform puts base_link at the ball's centre, tilted by the lean.
    for s, f in zip(states[::50], tfs[::50], strict=True):
        assert f["parent_frame_id"] == "map" and f["child_frame_id"] == "base_link"
        assert f["timestamp"] == s["timestamp"]
        assert f["translation"]["x"] == pytest.approx(s["x"], abs=1e-12)
        assert f["translation"]["y"] == pytest.approx(s["y"], abs=1e-12)
        q = f["rotation"]
        lean = lean_from_quaternion((q["x"], q["y"], q["z"], q["w"]))
        np.testing.assert_allclose(lean, [s["lean_x"], s["lean_y"]], rtol=0, atol=1e-12)
    # Log times: run 1 follows run 0 after the gap; within a run, log time = t + offset.
    first = {m["run"]: (t, m["t"]) for t, m in reversed(topics["/gracenav/state"])}
    last = {m["run"]: (t, m["t"]) for t, m in topics["/gracenav/state"]}
    assert first[0] == (0, 0.0) and first[1][1] == 0.0
    assert last[0][1] == pytest.approx(traj[traj[:, 0] == 0][-1, 1], abs=1e-6)
    assert first[1][0] - last[0][0] == pytest.approx(RUN_GAP * 1e9, abs=2)


def test_pushes_domains_and_events(logged: tuple[Path, Path]) -> None:
    out, log = logged
    topics = _read(log)
    traj = _trajectory(out)
    pushes = [m for _, m in topics["/gracenav/pushes"]]
    assert [p["run"] for p in pushes] == [0, 1]
    for p in pushes:
        assert p["t"] == pytest.approx(PUSH_T, abs=1e-12)
        assert (p["impulse"]["x"], p["impulse"]["y"]) == pytest.approx(PUSH, abs=1e-12)
        rows = traj[(traj[:, 0] == p["run"]) & (np.abs(traj[:, 1] - PUSH_T) < 0.6e-3)]
        assert (p["position"]["x"], p["position"]["y"]) == pytest.approx(
            tuple(rows[0, 2:4]), abs=2e-3
        )
    with (out / "events.csv").open() as fh:
        switches = [r for r in csv.DictReader(fh) if not r["reason"].startswith("replan")]
    domains = [m for _, m in topics["/gracenav/domains"]]
    assert len(domains) == len(switches)
    for row, m in zip(switches, domains, strict=True):
        label = next(e for e in m["entities"] if e["id"] == "policy label")
        meta = {d["key"]: d["value"] for d in label["metadata"]}
        assert int(meta["row"]) == int(row["to"])
        if int(row["to"]) >= 0:
            assert meta["policy"] == row["to_name"]
            drawn = next(e for e in m["entities"] if e["id"] == "policy")
            # D'(t) samples, S, G and the reference: closed ellipses around the centre
            assert len(drawn["lines"]) >= 4
            s_line = np.array([[p["x"], p["y"]] for p in drawn["lines"][-3]["points"]])
            np.testing.assert_allclose(s_line[0], s_line[-1], atol=1e-9)
    messages = [m["message"] for _, m in topics["/gracenav/events"]]
    assert sum("push of (0, 9) N s" in s for s in messages) == 2
    assert sum("ended (goal_reached)" in s for s in messages) == 2
    assert sum("switch" in s for s in messages) == len(switches)


def test_map_grid_is_the_map(logged: tuple[Path, Path]) -> None:
    _, log = logged
    grid = _read(log)["/map"][0][1]
    wm = load_map(FIG5_MAP)
    ny, nx = wm.occupied.shape
    assert grid["column_count"] == nx and grid["frame_id"] == "map"
    assert grid["cell_size"] == {"x": 0.05, "y": 0.05}
    assert grid["fields"] == [{"name": "occupied", "offset": 0, "type": 1}]
    data = np.frombuffer(base64.b64decode(grid["data"]), dtype=np.uint8).reshape(ny, nx)
    np.testing.assert_array_equal(data == 100, wm.occupied)
    assert set(np.unique(data)) <= {0, 100}
    assert grid["pose"]["position"]["x"] == pytest.approx(-1.0)


@pytest.mark.parametrize(
    "lean", [(0.0, 0.0), (0.07, 0.0), (0.0, -0.05), (0.1, 0.2), (-0.3, 0.25), (1.2, -0.9)]
)
def test_lean_quaternion_round_trip_and_axes(lean: tuple[float, float]) -> None:
    q = lean_quaternion(lean)
    assert math.isclose(sum(v * v for v in q), 1.0, rel_tol=1e-12)
    np.testing.assert_allclose(lean_from_quaternion(q), lean, rtol=0, atol=1e-12)
    # Body axis: leaning toward +x tips the z axis toward +x (REP-103), +y toward +y.
    x, y, z, w = q
    bx, by = 2 * (x * z + w * y), 2 * (y * z - w * x)
    assert np.sign(bx) == np.sign(lean[0]) and np.sign(by) == np.sign(lean[1])


@pytest.mark.parametrize(
    ("name", "needle"),
    [("run.txt", "must end in .mcap"), ("run.rrd", "Rerun files are not written")],
)
def test_bad_log_names_are_refused_up_front(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, needle: str
) -> None:
    status = main(
        [
            "run",
            str(_scenario(tmp_path)),
            "--out",
            str(tmp_path / "o"),
            "--log",
            str(tmp_path / name),
        ]
    )
    assert status == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("gracenav: error: --log") and needle in err[0]
    assert not (tmp_path / "o").exists() and not (tmp_path / name).exists()
