"""Bad and edge inputs, as a demanding user gives them: every case runs the command line and
must end with the documented exit status and exactly one line on standard error (an
error, or the status line of a fall), never a traceback.

Runs use a 3 m × 3 m map with one pass of instantiation (a library of ~1800 policies,
built in ~0.3 s), no animation and short ``max_time``.
"""

from __future__ import annotations

import copy
import json
import math
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from gracenav._util.io import parse_yaml
from gracenav.cli import main
from gracenav.errors import GracenavError
from gracenav.scenarios import RunSummary, load_scenario, parse_scenario

SRC = Path(__file__).resolve().parents[1] / "src"

BASE: dict[str, Any] = {
    "name": "tiny move",
    "map": {"bounds": [[0.0, 0.0], [3.0, 3.0]], "resolution": 0.05},
    "robot": {"footprint_radius": 0.2},
    "planner": {"cost": "time", "max_halvings": 0},
    "task": {
        "kind": "point_to_point",
        "goal": [2.0, 1.5, 0.0, 0.0],
        "starts": [[1.0, 1.5, 0.0, 0.0]],
    },
    "simulation": {"plant": "model3d", "seed": 0, "max_time": 8},
}


def scenario(**patch: Any) -> dict[str, Any]:
    """BASE with ``patch`` applied: ``{"task.goal": value}``; a value of ``...`` deletes."""
    data = copy.deepcopy(BASE)
    for dotted, value in patch.items():
        keys = dotted.split(".")
        node = data
        for k in keys[:-1]:
            node = node.setdefault(k, {})
        if value is ...:
            node.pop(keys[-1], None)
        else:
            node[keys[-1]] = value
    return data


def cli(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    try:
        status = main(argv)
    except SystemExit as exc:  # argparse exits by itself
        status = int(exc.code or 0)
    out, err = capsys.readouterr()
    return status, out, err


def one_line(err: str, prefix: str = "gracenav: error:") -> str:
    assert "Traceback" not in err, err
    assert err.count("\n") == 1 and err.endswith("\n"), err
    assert err.startswith(prefix), err
    return err


def write(tmp_path: Path, data: Any, name: str = "s.yaml") -> Path:
    path = tmp_path / name
    if isinstance(data, bytes):
        path.write_bytes(data)
    elif isinstance(data, str):
        path.write_text(data)
    else:
        path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def run_bad(tmp_path: Path, capsys: Any, data: Any, message: str, *extra: str) -> str:
    """Run ``gracenav run`` on ``data``: status 2, one error line holding ``message``, and
    no output directory created."""
    path = write(tmp_path, data)
    out = tmp_path / "out"
    status, _, err = cli(["run", str(path), "--out", str(out), "--no-animation", *extra], capsys)
    one_line(err)
    assert message in err, err
    assert status == 2
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
    return err


# -- the file itself ---------------------------------------------------------------------

FILES = [
    pytest.param(b"name: caf\xe9\n", "not UTF-8", id="latin1"),
    pytest.param(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", "not UTF-8", id="png"),
    pytest.param(b"name: x\x00\n", "binary", id="nul-bytes"),
    pytest.param("", "expected a mapping of scenario keys", id="empty"),
    pytest.param("# only a comment\n", "got nothing", id="comment-only"),
    pytest.param("- 1\n- 2\n", "got a list", id="top-level-list"),
    pytest.param("just text\n", "got a string", id="top-level-string"),
    pytest.param("name: a\nname: b\n", "duplicate key 'name'", id="duplicate-key"),
    pytest.param(
        "name: a\ntask: {kind: point_to_point, goal: [1, 1, 0, 0], goal: [2, 2, 0, 0]}\n",
        "duplicate key 'goal'",
        id="duplicate-nested-key",
    ),
    pytest.param("name: x\ntask: [1, 2\n", "not valid YAML", id="syntax"),
    pytest.param(
        "[" * 5000 + "]" * 5000, "not valid YAML", id="deep-nesting", marks=pytest.mark.slow
    ),
    pytest.param("!!python/object:os.system {}\n", "not valid YAML", id="python-tag"),
    pytest.param("a: &x [1]\nb: *y\n", "not valid YAML", id="unknown-alias"),
    pytest.param("x" * (1 << 20) + "\n", "larger than", id="huge-file"),
    pytest.param("name: x\nmax_time: " + "9" * 5000 + "\n", "not valid YAML", id="5000-digits"),
    pytest.param("{1: 2, [3]: 4}\n", "not valid YAML", id="unhashable-key"),
    pytest.param("{" + "9" * 400 + ": 1}\n", "unknown key(s) '~1e400'", id="huge-int-key"),
]


@pytest.mark.parametrize(("content", "message"), FILES)
def test_bad_scenario_files(tmp_path, capsys, content, message) -> None:
    run_bad(tmp_path, capsys, content, message)


def test_directory_instead_of_file(tmp_path, capsys) -> None:
    status, _, err = cli(["run", str(tmp_path), "--out", str(tmp_path / "o")], capsys)
    assert status == 2 and "is a directory" in one_line(err)


def test_fifo_instead_of_file_does_not_hang(tmp_path, capsys) -> None:
    os.mkfifo(tmp_path / "pipe.yaml")
    status, _, err = cli(["run", str(tmp_path / "pipe.yaml"), "--out", str(tmp_path / "o")], capsys)
    assert status == 2 and "not a regular file" in one_line(err)


def test_missing_file(tmp_path, capsys) -> None:
    status, _, err = cli(["run", str(tmp_path / "nope.yaml"), "--out", str(tmp_path / "o")], capsys)
    assert status == 2 and "No such file" in one_line(err)


# -- every key: wrong types, NaN/inf, negative, huge -------------------------------------

KEYS = [
    ({"bogus": 1}, "unknown key(s) 'bogus'"),
    ({"name": 3}, "'name' must be a non-empty one-line string"),
    ({"name": "a\nb"}, "'name'"),
    ({"name": "\x1b[2Jwiped"}, "without control characters"),
    ({"name": ...}, "missing key 'name'"),
    ({"map": [1, 2]}, "'map' must be a mapping, got a list"),
    ({"map": ...}, "missing key 'map'"),
    ({"map": {"ros_map": 5}}, "'map.ros_map'"),
    ({"map": {"ros_map": "x.yaml", "bounds": [[0, 0], [1, 1]]}}, "unknown key(s) 'map.bounds'"),
    ({"map.bounds": [[0, 0], [1e5, 1e5]]}, "cells"),
    (
        {"robot.footprint_radius": -0.1},
        "'robot.footprint_radius' must be a number in [0, 5] m, got -0.1",
    ),
    (
        {"robot.footprint_radius": 1e9},
        "'robot.footprint_radius' must be a number in [0, 5] m, got 1000000000.0",
    ),
    ({"robot.footprint_radius": "wide"}, "'robot.footprint_radius' must be a finite number"),
    ({"planner.cost": "money"}, "'planner.cost' must be one of time, distance"),
    ({"planner.max_halvings": -1}, "'planner.max_halvings' must be an integer in [0, 20]"),
    ({"planner.max_halvings": 1.5}, "'planner.max_halvings' must be an integer"),
    ({"planner.max_halvings": True}, "'planner.max_halvings' must be an integer"),
    ({"task": "go"}, "'task' must be a mapping, got a string"),
    ({"task.kind": "teleport"}, "'task.kind' must be one of"),
    ({"task.goal": [1, 2, 3]}, "'task.goal' must be a list of 4 numbers"),
    ({"task.goal": [float("nan"), 0, 0, 0]}, "'task.goal' must be a list of 4 numbers"),
    ({"task.goal": [float("inf"), 0, 0, 0]}, "(finite)"),
    ({"task.goal": [1e300, 0, 0, 0]}, "'task.goal' entries must be within"),
    ({"task.goal": [True, 0, 0, 0]}, "'task.goal'"),
    ({"task.starts": []}, "'task.starts' must be a non-empty list"),
    ({"task.starts": "here"}, "'task.starts' must be a non-empty list"),
    ({"task.starts": [[0, 0, 0, 0]] * 101}, "at most 100 are allowed"),
    ({"task.starts": [[1, "a", 0, 0]]}, "'task.starts[0]'"),
    ({"task.starts": [None]}, "'task.starts[0]' must be a list of 4 numbers [x, y, xdot, ydot]"),
    ({"simulation": 5}, "'simulation' must be a mapping"),
    ({"simulation.plant": "gazebo"}, "'simulation.plant' must be one of model3d, mujoco"),
    ({"simulation.seed": -1}, "'simulation.seed' must be an integer in [0, 4294967295]"),
    ({"simulation.seed": 2**70}, "'simulation.seed'"),
    ({"simulation.seed": 1.5}, "'simulation.seed'"),
    (
        {"simulation.position_noise_std": -0.01},
        "'simulation.position_noise_std' must be a number in [0, 1] m, got -0.01",
    ),
    (
        {"simulation.velocity_noise_std": 2},
        "'simulation.velocity_noise_std' must be a number in [0, 1] m/s, got 2",
    ),
    ({"simulation.max_time": 0}, "'simulation.max_time' must be a positive number (s), got 0"),
    ({"simulation.max_time": -5}, "'simulation.max_time' must be a positive number (s), got -5"),
    (
        {"simulation.max_time": "10s"},
        "'simulation.max_time' must be a finite number (s), got '10s'",
    ),
    ({"simulation.max_time": float("inf")}, "'simulation.max_time' must be a finite number"),
    ({"simulation.max_time": 10**400}, "'simulation.max_time' must be a finite number"),
    ({"simulation.max_time": 1e9}, "more than the budget of 1800 s"),
    ({"disturbances": {"kind": "push"}}, "'disturbances' must be a list"),
    ({"disturbances": [7]}, "'disturbances[0]' must be a mapping, got a number"),
    ({"disturbances": [{"kind": "wind"}]}, "'disturbances[0].kind' must be one of push, drag"),
    ({"disturbances": [{"kind": "push", "time": 1.0}]}, "missing key 'disturbances[0].impulse'"),
    (
        {"disturbances": [{"kind": "push", "time": -1, "impulse": [10, 0]}]},
        "'disturbances[0].time' must be a number >= 0 s, got -1",
    ),
    (
        {"disturbances": [{"kind": "push", "time": 50, "impulse": [10, 0]}]},
        "the push would never apply",
    ),
    (
        {"disturbances": [{"kind": "push", "time": 1, "impulse": [1e6, 0]}]},
        "'disturbances[0].impulse' entries must be within ±1000",
    ),
    (
        {"disturbances": [{"kind": "push", "time": 1, "impulse": [1, 2, 3]}]},
        "'disturbances[0].impulse' must be a list of 2 numbers",
    ),
    (
        {"disturbances": [{"kind": "drag", "start_time": 3, "end_time": 2, "velocity": [0, 1]}]},
        "start_time < end_time",
    ),
    (
        {"disturbances": [{"kind": "drag", "start_time": 1, "end_time": 2, "velocity": [99, 0]}]},
        "'disturbances[0].velocity' entries must be within ±10",
    ),
    (
        {"disturbances": [{"kind": "drag", "start_time": 9, "end_time": 10, "velocity": [1, 0]}]},
        "the drag would never apply",
    ),
]


@pytest.mark.parametrize(
    ("patch", "message"), KEYS, ids=[f"{i}-{next(iter(p))}" for i, (p, _) in enumerate(KEYS)]
)
def test_bad_scenario_values_name_the_key(tmp_path, capsys, patch, message) -> None:
    err = run_bad(tmp_path, capsys, scenario(**patch), message)  # NaN, inf: .nan, .inf
    assert str(tmp_path / "s.yaml") in err  # the file is named


def test_surveillance_loops(tmp_path, capsys) -> None:
    task = {"kind": "surveillance", "start": [1, 1.5, 0, 0], "goals": [[2, 1.5, 0.5, 0]]}
    run_bad(tmp_path, capsys, scenario(task={**task, "loops": 10**9}), "in [1, 10000]")
    run_bad(tmp_path, capsys, scenario(task={**task, "loops": 0}), "'task.loops'")
    # Loops that cannot fit in max_time: the estimate and the largest that fits.
    err = run_bad(tmp_path, capsys, scenario(task={**task, "loops": 100}), "need at least 100 s")
    assert "loops <= 8" in err


def test_halvings_over_budget_give_the_estimate(tmp_path, capsys) -> None:
    data = scenario(**{"planner.max_halvings": 8})
    err = run_bad(tmp_path, capsys, data, "more than the memory budget of 2 GiB")
    assert "planner.memory_limit_gib" in err and re.search(r"max_halvings <= [1-7]\b", err)


def test_the_memory_budget_is_not_the_decoupled_baselines() -> None:
    """The decoupled baseline builds no library: a library over gracenav's memory
    budget is refused for gracenav only."""
    from gracenav.errors import ConfigError
    from gracenav.palette import load_palette
    from gracenav.scenarios import check_scenario, load_scenario_map, parse_scenario

    data = scenario(**{"planner.max_halvings": 8})
    sc = parse_scenario(data, source="big.yaml")
    world = load_scenario_map(sc)
    with pytest.raises(ConfigError, match="more than the memory budget"):
        check_scenario(sc, world, load_palette())
    dec = parse_scenario({**data, "planner": {"kind": "decoupled", "max_halvings": 8}}, source="d")
    check_scenario(dec, world, load_palette())  # no error


@pytest.mark.parametrize(
    ("patch", "message"),
    [
        ({"task.starts": [[9.0, 9.0, 0, 0]]}, "'task.starts[0]' (9, 9) is outside the map"),
        ({"task.goal": [0.1, 0.1, 0, 0]}, "'task.goal' (0.1, 0.1) is inside an obstacle"),
        ({"task.goal": [2.1, 1.47, 0.3, 0]}, "'task.goal': goal (2.1, 1.47, 0.3, 0) is outside"),
        (
            # 1.5 m/s: faster than any start domain reaches (the capture trim: 0.64 m/s)
            {"task.starts": [[1.0, 1.5, 0, 0], [1.1, 1.43, 1.5, 0]]},
            "'task.starts[1]': start (1.1, 1.43, 1.5, 0): no library policy",
        ),
        ({"map.ros_map": "nowhere.yaml", "map.bounds": ...}, "nowhere.yaml"),
        ({"map.bounds": [[0, 0], [1]]}, "bounds"),
    ],
)
def test_impossible_tasks_and_maps(tmp_path, capsys, patch, message) -> None:
    data = scenario(**patch)
    if "map.ros_map" in patch:
        data["map"] = {"ros_map": patch["map.ros_map"]}
    path = write(tmp_path, data)
    status, _, err = cli(["run", str(path), "--out", str(tmp_path / "o"), "--no-animation"], capsys)
    assert status == 2 and message in one_line(err), err
    assert "np.float64" not in err


def test_mujoco_plant_without_mujoco(tmp_path, capsys, monkeypatch) -> None:
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "mujoco" else real(name, *a)
    )
    path = write(tmp_path, scenario(**{"simulation.plant": "mujoco"}))
    status, _, err = cli(["run", str(path), "--out", str(tmp_path / "o")], capsys)
    assert status == 2 and "simulation.plant mujoco needs the optional" in one_line(err)
    argv = ["simulate", "balance", "--plant", "mujoco", "--out", str(tmp_path / "o")]
    status, _, err = cli(argv, capsys)
    assert status == 2 and "--plant mujoco needs the optional" in one_line(err)
    assert not (tmp_path / "o").exists()


def test_yaml_12_numbers_are_numbers(tmp_path) -> None:
    text = yaml.safe_dump(BASE, sort_keys=False).replace("max_time: 8", "max_time: 8e0")
    assert load_scenario(write(tmp_path, text)).max_time == 8.0


# -- physics: falls and max_time -----------------------------------------------------------


def _run(tmp_path: Path, capsys: Any, data: dict[str, Any]) -> tuple[int, str, dict[str, Any]]:
    path = write(tmp_path, data)
    out = tmp_path / "out"
    status, _, err = cli(["run", str(path), "--out", str(out), "--no-animation"], capsys)
    text = (out / "summary.json").read_text()
    summary = json.loads(text, parse_constant=lambda c: pytest.fail(f"non-JSON {c}"))
    return status, err, summary


@pytest.mark.parametrize(
    "disturbance",
    [
        {"kind": "drag", "start_time": 0.5, "end_time": 2.0, "velocity": [10.0, 0.0]},
        {"kind": "push", "time": 0.5, "impulse": [500.0, 0.0]},
    ],
    ids=["drag-10mps", "push-500Ns"],
)
def test_a_fall_is_reported(tmp_path, capsys, disturbance) -> None:
    status, err, summary = _run(tmp_path, capsys, scenario(disturbances=[disturbance]))
    assert status == 1
    assert "fell" in one_line(err, "gracenav: fell:")
    run = summary["runs"][0]
    assert run["stop_reason"] == "fell" and not run["reached_goal"]
    assert 20.0 < run["max_lean_deg"] < 25.0  # stopped at the tick it fell
    assert run["time_s"] < 2.0


def test_max_time_is_enforced_within_one_tick(tmp_path, capsys) -> None:
    status, err, summary = _run(tmp_path, capsys, scenario(**{"simulation.max_time": 0.01}))
    assert status == 1 and err == ""
    run = summary["runs"][0]
    assert run["stop_reason"] == "timeout"
    assert 0.01 <= run["time_s"] <= 0.01 + 1 / 1024 + 1e-12


def test_summary_is_strict_json_with_units() -> None:
    run = RunSummary(
        start=(0.0, 0.0, 0.0, 0.0),
        reached_goal=True,
        stop_reason="loops_completed",
        time_s=1.0,
        path_length_m=1.0,
        final_error_m=None,
        final_speed_mps=float("nan"),
        max_lean_deg=1.0,
        max_torque_nm=1.0,
        max_jerk_mps3=1.0,
        p95_jerk_mps3=0.5,
        switches=0,
        non_graceful_switches=0,
        max_graceful_torque_jump_nm=0.0,
        min_clearance_m=float("inf"),
        goals_reached=1,
        tree_ms=0.1,
    )
    d = run.to_dict()
    json.dumps(d, allow_nan=False)
    assert d["final_error_m"] is None and d["final_speed_mps"] is None
    for key in ("max_torque_nm", "max_jerk_mps3", "p95_jerk_mps3", "max_graceful_torque_jump_nm"):
        assert key in d


BALANCE = [
    (["--lean-deg", "25"], "--lean-deg must be within ±20 degrees"),
    (["--lean-deg", "-20"], "--lean-deg must be within ±20 degrees"),
    (["--lean-deg", "inf"], "expected a finite number"),
    (["--lean-deg", "abc"], "expected a number"),
    (["--push", "1e6", "0"], "pushes up to 80 N s"),
    (["--push", "60", "60"], "pushes up to 80 N s"),
    (["--push", "nan", "0"], "expected a finite number"),
    (["--push", "10", "0", "--duration", "0.5"], "longer than 1 s"),
    (["--duration", "1e9"], "--duration: expected a number in (0, 600] s, got '1e9' (see"),
    (["--duration", "-1"], "--duration: expected a number in (0, 600] s, got '-1' (see"),
    (["--duration", "0"], "--duration: expected a number in (0, 600] s, got '0' (see"),
    (["--plant", "gazebo"], "invalid choice"),
]


@pytest.mark.parametrize(("args", "message"), BALANCE)
def test_simulate_balance_refuses(tmp_path, capsys, args, message) -> None:
    out = tmp_path / "o"
    status, _, err = cli(["simulate", "balance", *args, "--out", str(out)], capsys)
    assert status == 2 and message in one_line(err), err
    assert not out.exists()


def test_simulate_balance_reports_a_fall(tmp_path, capsys) -> None:
    out = tmp_path / "o"
    argv = ["simulate", "balance", "--lean-deg", "19.9", "--push", "70", "0", "--out", str(out)]
    status, _, err = cli(argv, capsys)
    assert status == 1
    assert "fell over at t = " in one_line(err, "gracenav: fell:")
    assert (out / "trajectory.csv").exists()


def test_simulate_balance_reports_a_diverged_plant(tmp_path, capsys) -> None:
    params = write(tmp_path, "ball_radius: 1.0e9\n", "p.yaml")
    argv = ["simulate", "balance", "--params", str(params), "--out", str(tmp_path / "o")]
    status, stdout, err = cli(argv, capsys)
    assert status == 1 and "diverged" in one_line(err, "gracenav: fell:")
    assert "nan" not in stdout


# -- --params ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("wheel_count: 3\n", "unknown key(s) 'wheel_count'; allowed: ball_inertia"),
        ("body_mass: -1\n", "p.yaml: 'body_mass' must be a positive number (kg), got -1\n"),
        ("body_mass: heavy\n", "'body_mass' must be a finite number (kg), got 'heavy'\n"),
        ("body_mass: .nan\n", "'body_mass' must be a finite number (kg), got nan\n"),
        ("body_mass: '60'\n", "got '60' (a string: write numbers without quotes)\n"),
        ("coulomb_friction: -1\n", "'coulomb_friction' must be a number >= 0 N m, got -1\n"),
        ("body_mass: 50\nbody_mass: 60\n", "duplicate key 'body_mass'"),
        ("- 1\n", "expected a mapping of parameter keys"),
        (b"body_mass: \xff\n", "not UTF-8"),
        (None, "No such file"),
    ],
)
def test_bad_params_files(tmp_path, capsys, content, message) -> None:
    params = tmp_path / "p.yaml"
    if content is not None:
        write(tmp_path, content, "p.yaml")
    out = tmp_path / "o"
    argv = ["simulate", "balance", "--params", str(params), "--duration", "0.5", "--out", str(out)]
    status, _, err = cli(argv, capsys)
    assert status == 2 and message in one_line(err), err
    assert not out.exists()


def test_params_json_duplicate_key(tmp_path, capsys) -> None:
    params = write(tmp_path, '{"body_mass": 50, "body_mass": 60}', "p.json")
    argv = ["simulate", "balance", "--params", str(params), "--out", str(tmp_path / "o")]
    status, _, err = cli(argv, capsys)
    assert status == 2 and "duplicate key 'body_mass'" in one_line(err)


def test_params_with_an_absurd_ball_radius_end_quickly(tmp_path, capsys) -> None:
    # A 10^9 m ball under the nominal controller used to loop at constant time until
    # memory ran out; the run now ends (fell or no_progress) at once: in simulated time
    # (time_s below); the wall-clock bound is only a hang guard (the command takes
    # well under a second).
    params = write(tmp_path, "ball_radius: 1.0e9\n", "p.yaml")
    path = write(tmp_path, BASE)
    out = str(tmp_path / "o")
    argv = ["run", str(path), "--params", str(params), "--out", out, "--no-animation"]
    t0 = time.perf_counter()
    status, _, err = cli(argv, capsys)
    assert status == 1 and "Traceback" not in err
    assert time.perf_counter() - t0 < 60.0
    run = json.loads((tmp_path / "o" / "summary.json").read_text())["runs"][0]
    assert run["stop_reason"] in ("fell", "no_progress") and run["time_s"] < 1.0


def test_non_physical_params_end_without_hanging(tmp_path, capsys) -> None:
    # A body of 1 mg under the nominal controller: the task ends (here in balancing
    # mode) within max_time; it used to be able to loop without advancing time.
    params = write(tmp_path, "body_mass: 1.0e-6\n", "p.yaml")
    path = write(tmp_path, scenario(**{"simulation.max_time": 6}))
    argv = [
        "run",
        str(path),
        "--params",
        str(params),
        "--out",
        str(tmp_path / "o"),
        "--no-animation",
    ]
    status, _, err = cli(argv, capsys)
    assert status == 1 and "Traceback" not in err
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["runs"][0]["time_s"] <= 6.0 + 1 / 1024


def test_partial_params_file_is_valid(tmp_path, capsys) -> None:
    params = write(tmp_path, "body_mass: 60.0\n", "p.yaml")
    out = tmp_path / "o"
    argv = ["simulate", "balance", "--params", str(params), "--duration", "2", "--out", str(out)]
    status, stdout, err = cli(argv, capsys)
    assert status == 0 and err == "" and "max lean 5.00°" in stdout


# -- outputs -------------------------------------------------------------------------------


def test_out_is_checked_before_any_simulation(tmp_path, capsys, monkeypatch) -> None:
    import gracenav.scenarios

    runs = []
    run_scenario = gracenav.scenarios.run_scenario

    def counted(*args, **kwargs):  # type: ignore[no-untyped-def]
        runs.append(1)
        return run_scenario(*args, **kwargs)

    monkeypatch.setattr(gracenav.scenarios, "run_scenario", counted)
    path = write(tmp_path, BASE)
    (tmp_path / "cwd").mkdir()
    monkeypatch.chdir(tmp_path / "cwd")  # empty: only the rule protects it
    afile = tmp_path / "afile"
    afile.write_text("keep")
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    cases = [
        (afile, "exists and is not a directory"),
        (afile / "sub", "is a file, not a directory"),
        (foreign, "holds files gracenav did not write (notes.txt)"),
        (Path("/sys/gracenav-out"), "cannot write in /sys"),
        (Path("."), "is the current directory or holds it"),
        (Path(".."), "is the current directory or holds it"),
    ]
    for out, message in cases:
        status, _, err = cli(["run", str(path), "--out", str(out)], capsys)
        assert status == 2 and message in one_line(err), err
        assert not runs  # refused before the library and the runs
    assert afile.read_text() == "keep" and (foreign / "notes.txt").read_text() == "mine"


def test_previous_results_are_replaced_as_a_whole(tmp_path, capsys) -> None:
    out = tmp_path / "o"
    out.mkdir()
    (out / "balance.png").write_text("old")
    (out / "trajectory.csv").write_text("old")
    argv = ["simulate", "balance", "--duration", "1", "--out", str(out)]
    assert cli(argv, capsys)[0] == 0
    assert (out / "trajectory.csv").read_text().startswith("t,x,y")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o"]  # no staging, lock or old dir


def test_leftovers_of_a_killed_run_are_recovered(tmp_path, capsys) -> None:
    # A run killed outright between the two renames of its publication: the previous
    # results are in .o.old-*/previous, its new ones in .o.tmp-*, and there is no o.
    old = tmp_path / ".o.old-x1" / "previous"
    old.mkdir(parents=True)
    (old / "trajectory.csv").write_text("previous")
    (tmp_path / ".o.tmp-x2").mkdir()
    (tmp_path / ".o.lock").write_text("")
    # The next run into o restores them first (here it then fails on its scenario).
    path = write(tmp_path, scenario(**{"planner.max_halvings": 8}))
    status, _, err = cli(["run", str(path), "--out", str(tmp_path / "o")], capsys)
    assert status == 2 and "memory budget" in one_line(err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o", "s.yaml"]
    assert (tmp_path / "o" / "trajectory.csv").read_text() == "previous"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["plot", "library", "MAP", "--out", "l.txt"], "'.txt' is not a figure format"),
        (["plot", "primitives", "--out", "p"], "no suffix is not a figure format"),
        (["plot", "domain", "rest_to_cruise_x_2_0", "--out", "TMP"], "is a directory"),
        (["plot", "library", "MAP", "--out", "l.png", "--max-halvings", "8"], "budget"),
        (
            ["plot", "library", "MAP", "--out", "l.png", "--footprint", "-1"],
            "--footprint: expected a number in [0, 5] m, got '-1'",
        ),
        (["plot", "library", "MAP", "--out", "l.png", "--max-halvings", "1.5"], "integer"),
        (
            ["plot", "primitives", "--d", "0", "--out", "p.png"],
            "--d: expected a number in [0.1, 2] m, got '0'",
        ),
    ],
)
def test_plot_outputs_checked_up_front(tmp_path, capsys, argv, message) -> None:
    mp = write(tmp_path, BASE["map"], "map.yaml")
    names = {"MAP": str(mp), "TMP": str(tmp_path)}
    names.update({n: str(tmp_path / n) for n in ("l.txt", "l.png", "p", "p.png")})
    argv = [names.get(a, a) for a in argv]
    status, _, err = cli(argv, capsys)
    assert status == 2 and message in one_line(err), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map.yaml"]


# -- signals and concurrent runs (subprocesses) --------------------------------------------


def _spawn(args: list[str], cwd: Path) -> subprocess.Popen[str]:
    env = {**os.environ, "PYTHONPATH": str(SRC), "MPLBACKEND": "Agg"}
    return subprocess.Popen(
        [sys.executable, "-m", "gracenav.cli", *args],
        cwd=cwd,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _wait_for(predicate: Any, proc: subprocess.Popen[str], timeout: float = 60.0) -> None:
    t0 = time.monotonic()
    while not predicate():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() - t0 < timeout
        time.sleep(0.01)


@pytest.mark.parametrize(("sig", "code"), [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_interrupted_run_leaves_previous_results(tmp_path, sig, code) -> None:
    path = write(tmp_path, scenario(**{"simulation.max_time": 30}))
    out = tmp_path / "o"
    out.mkdir()
    old = {n: f"previous {n}" for n in ("summary.json", "trajectory.csv", "paths.png")}
    for n, text in old.items():
        (out / n).write_text(text)
    proc = _spawn(["run", str(path), "--out", "o"], tmp_path)
    _wait_for(lambda: any(p.name.startswith(".o.tmp-") for p in tmp_path.iterdir()), proc)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    assert "Traceback" not in err and err.count("\n") == 1 and "discarded" in err
    assert {p.name: p.read_text() for p in out.iterdir()} == old
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o", "s.yaml"]


def test_concurrent_run_into_the_same_out_is_refused(tmp_path, capsys) -> None:
    path = write(tmp_path, scenario(**{"simulation.max_time": 30}))
    proc = _spawn(["run", str(path), "--out", "o"], tmp_path)
    try:
        _wait_for(lambda: (tmp_path / ".o.lock").exists(), proc)
        status, _, err = cli(["run", str(path), "--out", str(tmp_path / "o")], capsys)
        assert status == 2 and "in use by another gracenav run" in one_line(err)
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.communicate(timeout=60)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


# -- fuzzing the scenario loader -----------------------------------------------------------


def _load_text(text: str) -> None:
    try:
        parse_scenario(parse_yaml(text, "fuzz.yaml"), source="fuzz.yaml")
    except GracenavError:
        pass


yaml_chars = st.sampled_from([*"abkn:-[]{},.#&*!|>'\"\n 0123456789e+_~@%", "\t"])


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.text(yaml_chars, max_size=80))
def test_fuzz_yamlish_text_loads_or_raises_a_package_error(text: str) -> None:
    _load_text(text)


@settings(max_examples=60, deadline=None)
@given(st.binary(max_size=64))
def test_fuzz_bytes_through_the_file_reader(data: bytes) -> None:
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "s.yaml"
        path.write_bytes(data)
        try:
            load_scenario(path)
        except GracenavError:
            pass


values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(min_value=-(2**80), max_value=2**80)
    | st.sampled_from([10**400, -(10**400), 2**63, 0.0, -0.0, 1e-300, 1e308])
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=6), inner),
    max_leaves=10,
)


def _paths(node: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    out = [prefix] if prefix else []
    if isinstance(node, dict):
        for k, v in node.items():
            out += _paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += _paths(v, (*prefix, i))
    return out


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_fuzz_mutations_of_a_valid_scenario(data: st.DataObject) -> None:
    doc = copy.deepcopy(BASE)
    doc["disturbances"] = [
        {"kind": "push", "time": 1.0, "impulse": [10.0, 0.0]},
        {"kind": "drag", "start_time": 1.0, "end_time": 2.0, "velocity": [0.2, 0.0]},
    ]
    for _ in range(data.draw(st.integers(1, 3))):
        path = data.draw(st.sampled_from(_paths(doc)))
        parent = doc
        for k in path[:-1]:
            parent = parent[k]
        action = data.draw(st.sampled_from(["replace", "delete", "add"]))
        if action == "replace":
            parent[path[-1]] = data.draw(values)
        elif action == "delete":
            del parent[path[-1]]
        elif isinstance(parent, dict):
            key = data.draw(st.text(max_size=6) | st.integers() | st.sampled_from([10**400]))
            parent[key] = data.draw(values)
        else:
            parent.append(data.draw(values))
    try:
        sc = parse_scenario(doc, source="fuzz.yaml")
    except GracenavError:
        return
    assert math.isfinite(sc.max_time) and sc.max_time * len(sc.starts) <= 1800
    assert all(math.isfinite(v) for s in (*sc.starts, *sc.goals) for v in s)


# -- the schema layer: gracenav._util.validate.Fields -------------------------------------------
# Scenario, parameter and map documents are all read through these readers; each test
# asserts the exact message shape: "SOURCE: 'KEY.PATH' must be ..., got VALUE", one line.


@pytest.mark.parametrize(
    ("limits", "text"),
    [
        ({}, "a finite number"),
        ({"unit": "m"}, "a finite number (m)"),
        ({"positive": True, "unit": "m"}, "a positive number (m)"),
        ({"minimum": 0.0, "unit": "s"}, "a number >= 0 s"),
        ({"maximum": 600.0, "unit": "s"}, "a number <= 600 s"),
        ({"minimum": 0.0, "maximum": 5.0, "unit": "m"}, "a number in [0, 5] m"),
        ({"positive": True, "maximum": 600.0, "unit": "s"}, "a number in (0, 600] s"),
        ({"positive": True, "minimum": 2.0}, "a number >= 2"),
        ({"integer": True, "minimum": 0, "maximum": 2**32 - 1}, "an integer in [0, 4294967295]"),
        ({"integer": True, "minimum": 1}, "an integer >= 1"),
    ],
)
def test_number_range_words_every_kind_of_limit(limits: dict[str, Any], text: str) -> None:
    from gracenav._util.validate import number_range

    assert number_range(**limits) == text


def _refusal(read: Any) -> str:
    from gracenav.errors import ConfigError, MapError

    with pytest.raises((ConfigError, MapError)) as info:
        read()
    msg = str(info.value)
    assert "\n" not in msg and "np." not in msg
    return msg


def test_fields_number_messages() -> None:
    import numpy as np

    from gracenav._util.validate import Fields
    from gracenav.errors import MapError

    doc = {"radius": -1, "quoted": "0.5", "huge": 10**400, "np": np.float64(-1.5), "t": True}
    f = Fields(doc, "obstacles[2].circle", "map.yaml", error=MapError)
    assert _refusal(lambda: f.number("radius", positive=True, unit="m")) == (
        "map.yaml: 'obstacles[2].circle.radius' must be a positive number (m), got -1"
    )
    assert _refusal(lambda: f.number("quoted", unit="m")) == (
        "map.yaml: 'obstacles[2].circle.quoted' must be a finite number (m), got '0.5' "
        "(a string: write numbers without quotes)"
    )
    assert _refusal(lambda: f.number("huge")) == (
        "map.yaml: 'obstacles[2].circle.huge' must be a finite number, got ~1e400"
    )
    assert _refusal(lambda: f.number("np", minimum=0.0, maximum=1.0)) == (
        "map.yaml: 'obstacles[2].circle.np' must be a number in [0, 1], got -1.5"
    )
    assert _refusal(lambda: f.number("t")) == (
        "map.yaml: 'obstacles[2].circle.t' must be a finite number, got true"
    )
    assert _refusal(lambda: f.number("absent")) == (
        "map.yaml: missing key 'obstacles[2].circle.absent'"
    )
    assert f.number("absent", 0.25) == 0.25
    with pytest.raises(MapError):  # the error type given, not ConfigError
        f.number("radius", positive=True)


def test_check_number_for_function_arguments() -> None:
    import numpy as np

    from gracenav._util.validate import check_number
    from gracenav.errors import ConfigError

    assert check_number(np.float32(0.5), "resolution", "WorldMap") == 0.5
    assert _refusal(lambda: check_number(np.int64(10), "size", "office_map", minimum=14.0)) == (
        "office_map: 'size' must be a number >= 14, got 10"
    )
    with pytest.raises(ConfigError):
        check_number(np.bool_(True), "size", "office_map")


def test_fields_points_messages() -> None:
    from gracenav._util.validate import Fields

    f = Fields(
        {"bounds": [[0, 0]], "poly": [[0, 0], [1, "x"]], "ok": [[0, 1], [2.5, 3]]}, "", "m.yaml"
    )
    assert f.points("ok", what="points [x, y]") == ((0.0, 1.0), (2.5, 3.0))
    xy = "[x, y] (m)"
    assert (
        _refusal(
            lambda: f.points("bounds", min_len=2, max_len=2, what="corners [x, y] (m)", item=xy)
        )
        == "m.yaml: 'bounds' must be a list of 2 corners [x, y] (m), got [[0, 0]]"
    )
    assert _refusal(lambda: f.points("poly", what="vertices", item=xy)) == (
        "m.yaml: 'poly[1]' must be a list of 2 numbers [x, y] (m) (finite), got [1, 'x']"
    )
    assert _refusal(lambda: f.points("bounds", min_len=3, what="vertices")) == (
        "m.yaml: 'bounds' must be a list of at least 3 vertices, got [[0, 0]]"
    )
    assert _refusal(lambda: f.points("ok", max_len=1, what="points", advice="merge them")) == (
        "m.yaml: 'ok' has 2 entries; at most 1 are allowed; merge them"
    )
    assert _refusal(lambda: f.points("ok", bound=2.0, what="points")) == (
        "m.yaml: 'ok[1]' entries must be within ±2, got [2.5, 3]"
    )


def test_fields_variant_messages() -> None:
    from gracenav._util.validate import Fields

    options = ("rectangle", "circle")
    kind, body = Fields({"circle": {"radius": 1}}, "obstacles[0]", "s").variant(options)
    assert kind == "circle" and body.where == "obstacles[0].circle" and body.data["radius"] == 1
    for doc, got in (({}, "none"), ({"circle": {}, "rectangle": {}}, "'circle', 'rectangle'")):
        assert _refusal(lambda doc=doc: Fields(doc, "obstacles[0]", "s").variant(options)) == (
            f"s: 'obstacles[0]' must hold exactly one of the keys rectangle, circle, got {got}"
        )
    assert _refusal(lambda: Fields({"circle": 3}, "o", "s").variant(options)) == (
        "s: 'o.circle' must be a mapping, got a number"
    )
    assert _refusal(lambda: Fields([1], "o", "s", expect="a mapping {circle: ...}")) == (
        "s: 'o' must be a mapping {circle: ...}, got a list"
    )


def test_fields_file_messages(tmp_path: Path) -> None:
    from gracenav._util.validate import Fields

    (tmp_path / "img.pgm").write_bytes(b"")
    (tmp_path / "sub").mkdir()
    doc = {"here": "img.pgm", "absolute": str(tmp_path / "img.pgm"), "gone": "x/none.pgm"}
    f = Fields({**doc, "folder": "sub", "empty": ""}, "", str(tmp_path / "map.yaml"))
    assert f.file("here", tmp_path) == tmp_path / "img.pgm"
    assert f.file("absolute", Path("/nowhere")) == tmp_path / "img.pgm"
    assert f.file("gone", tmp_path, must_exist=False) == tmp_path / "x" / "none.pgm"
    assert _refusal(lambda: f.file("gone", tmp_path)) == (
        f"{tmp_path / 'map.yaml'}: 'gone': file {tmp_path / 'x' / 'none.pgm'} not found; a "
        "relative path is taken from the folder of map.yaml"
    )
    assert _refusal(lambda: f.file("folder", tmp_path)).startswith(
        f"{tmp_path / 'map.yaml'}: 'folder': file {tmp_path / 'sub'} is a folder, not a file; "
    )
    assert _refusal(lambda: f.file("empty", tmp_path)) == (
        f"{tmp_path / 'map.yaml'}: 'empty' must be a non-empty one-line string of at most 4096 "
        "characters without control characters, got ''"
    )


_field_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers()
    | st.sampled_from([10**400, 2**63, -0.0, 1e308])
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=4), inner),
    max_leaves=8,
)


@settings(max_examples=200, deadline=None)
@given(_field_values)
@example({"'": None})  # a key with a quote is still named in single quotes
def test_fuzz_every_reader_returns_or_refuses_in_one_line(value: Any) -> None:
    from gracenav._util.validate import Fields
    from gracenav.errors import MapError

    readers = [
        lambda f: f.number("v", positive=True, maximum=10.0, unit="m"),
        lambda f: f.integer("v", minimum=1, maximum=5),
        lambda f: f.choice("v", ("a", "b")),
        lambda f: f.string("v"),
        lambda f: f.vector("v", 2, bound=5.0),
        lambda f: f.items("v", min_len=1, max_len=3, what="things"),
        lambda f: f.points("v", min_len=2, max_len=3, what="points"),
        lambda f: f.sub("v").variant(("a", "b")),
        lambda f: f.file("v", Path("/nonexistent-folder")),
        lambda f: Fields(value, "v", "f.yaml", error=MapError).check_keys(("a",)),
    ]
    for read in readers:
        try:
            read(Fields({"v": value}, "top", "f.yaml", error=MapError))
        except MapError as exc:
            msg = str(exc)
            assert re.match(r"f\.yaml: .*'(top\.)?v['.\[]", msg), msg  # names the key path
            assert "\n" not in msg and "np." not in msg
