"""End-to-end navigation: every shipped scenario, the hybrid controller's behaviour, and
the documented error of each kind of bad scenario."""

from __future__ import annotations

import copy
import json
import typing
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
import yaml

from gracenav import ConfigError, PlanningError, planning
from gracenav.cli import main
from gracenav.execution import EventReason, ExecutionOptions, HybridController, TaskStatus
from gracenav.planning.graph import CostCriterion, CostName
from gracenav.scenarios import load_scenario, parse_scenario, run_scenario, write_outputs
from gracenav.sim import state_from_position
from gracenav.sim.plant import PLANT_KINDS, PlantKind

SCENARIOS = Path(str(resources.files("gracenav") / "data" / "scenarios"))
DEG5 = 5.0


@pytest.fixture(scope="module")
def fig5():
    return run_scenario(load_scenario(SCENARIOS / "fig5_point_to_point.yaml"))


def test_fig5_every_start_reaches_the_goal_gracefully(fig5, tmp_path) -> None:
    assert len(fig5.runs) == 4
    for run, ep in zip(fig5.runs, fig5.episodes, strict=True):
        assert run.reached_goal, run
        assert run.final_error_m < 0.05 and run.final_speed_mps < 0.05
        assert run.max_lean_deg < DEG5
        assert run.min_clearance_m > 0.0  # the footprint never touches an obstacle
        assert run.non_graceful_switches == 0
        # The reference is continuous through acceleration across every switch ...
        # (the step across a switch is no larger than the ordinary steps around it).
        steps = np.abs(np.diff(ep.reference, axis=0))
        for e in ep.events[1:]:
            around = np.r_[steps[e.tick - 6 : e.tick - 1], steps[e.tick : e.tick + 5]]
            assert np.all(steps[e.tick - 1] <= 1.5 * around.max(axis=0) + 1e-9), e
        # ... and the commanded torque does not jump at graceful switches (the palette's
        # measured bound over all 1025 connecting pairs is 0.03 N m).
        assert np.max(ep.graceful_torque_jumps()) <= 0.031
        assert run.tree_ms < 50.0
    write_outputs(fig5, tmp_path, animation=False)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert [r["reached_goal"] for r in summary["runs"]] == [True] * 4
    assert summary["speed_clearance_s"] == fig5.scenario.speed_clearance
    header = (tmp_path / "trajectory.csv").read_text().splitlines()[0].split(",")
    for col in ("run", "t", "x", "y", "xdot", "ydot", "lean_x", "lean_y", "tau_x", "tau_y"):
        assert col in header
    assert (tmp_path / "events.csv").read_text().startswith("run,time,from,to")
    # Both files are valid CSV: policy names hold commas ("...@0°(0, 0)") and are quoted.
    import csv

    with open(tmp_path / "events.csv", newline="") as f:
        events = list(csv.reader(f))
    assert len(events) == 1 + sum(len(ep.events) for ep in fig5.episodes)
    assert all(len(row) == 8 for row in events)
    assert any("," in row[5] for row in events[1:])
    table = np.loadtxt(tmp_path / "trajectory.csv", delimiter=",", skiprows=1)
    assert table.shape == (sum(ep.time.size for ep in fig5.episodes), len(header))
    np.testing.assert_allclose(
        table[: fig5.episodes[0].time.size, 1], fig5.episodes[0].time, atol=5e-7
    )
    assert (tmp_path / "paths.png").stat().st_size > 10_000


def test_fig7_drag_exits_recovers_without_replanning_and_reaches_goal() -> None:
    res = run_scenario(load_scenario(SCENARIOS / "fig7_drag.yaml"))
    run, ep = res.runs[0], res.episodes[0]
    assert run.reached_goal and run.final_error_m < 0.05
    assert run.non_graceful_switches >= 1
    reasons = [e.reason for e in ep.events]
    assert EventReason.BALANCING in reasons or EventReason.DOMAIN_EXIT in reasons
    # One tree, computed once: no replanning after the disturbance.
    assert len(ep.tree_seconds) == 1


def test_fig8_surveillance_completes_five_loops() -> None:
    res = run_scenario(load_scenario(SCENARIOS / "fig8_surveillance.yaml"))
    run, ep = res.runs[0], res.episodes[0]
    assert ep.status is TaskStatus.LOOPS_COMPLETED
    assert run.goals_reached == 4 * 5
    assert run.max_lean_deg < DEG5
    assert run.non_graceful_switches == 0
    # The paper: five loops in about 90 s, about 0.55 m/s on average.
    assert 60.0 < run.time_s < 100.0
    assert 0.45 < run.path_length_m / run.time_s < 0.65


def test_fig5_on_the_mujoco_plant() -> None:
    pytest.importorskip("mujoco")
    sc = load_scenario(SCENARIOS / "fig5_point_to_point.yaml")
    import dataclasses

    sc = dataclasses.replace(sc, plant="mujoco", starts=sc.starts[1:2])
    res = run_scenario(sc)
    assert res.runs[0].reached_goal and res.runs[0].final_error_m < 0.05
    assert res.runs[0].max_lean_deg < DEG5


def test_push_is_absorbed_or_recovered() -> None:
    data = yaml.safe_load((SCENARIOS / "fig5_point_to_point.yaml").read_text())
    data["task"]["starts"] = [[0.0, 2.0, 0.0, 0.0]]
    data["disturbances"] = [{"kind": "push", "time": 2.0, "impulse": [0.0, -15.0]}]
    res = run_scenario(parse_scenario(data))
    assert res.runs[0].reached_goal


@pytest.fixture(scope="module")
def controller(fig5_library, fig5_graph) -> HybridController:
    """On the Fig. 5 map's library (one halving; conftest)."""
    return HybridController(fig5_library, fig5_graph)


def test_goal_errors_say_which(controller: HybridController) -> None:
    with pytest.raises(PlanningError, match="outside the map"):
        controller.goal_policy([9.0, 9.0, 0.0, 0.0])
    with pytest.raises(PlanningError, match="inside an obstacle"):
        controller.goal_policy([1.0, 1.25, 0.0, 0.0])
    with pytest.raises(PlanningError, match="outside coverage"):
        controller.goal_policy([2.1, 2.07, 0.3, 0.0])
    r = controller.params.ball_radius
    with pytest.raises(PlanningError, match="start"):
        controller.run(state_from_position([3.4, 2.9, 0.0, 0.0], r), [[2.0, 2.0, 0.0, 0.0]])


def test_hybrid_controller_event_log(controller: HybridController) -> None:
    r = controller.params.ball_radius
    ep = controller.run(
        state_from_position([0.0, 0.0, 0.0, 0.0], r),
        [[2.0, 2.0, 0.0, 0.0]],
        options=ExecutionOptions(max_time=60.0),
    )
    assert ep.events[0].reason is EventReason.START
    for a, b in zip(ep.events[:-1], ep.events[1:], strict=True):
        assert b.from_policy == a.to_policy and b.time > a.time
        # Each policy ran its full duration before a graceful switch.
        if b.reason is EventReason.GRACEFUL:
            dur = controller.library.durations[a.to_policy]
            assert b.time - a.time == pytest.approx(dur, abs=1e-9)
    # Every tick's policy matches the log.
    for e in ep.events:
        assert ep.policy[e.tick] == e.to_policy


BAD = [
    ({"bogus": 1}, "unknown key"),
    ({"task": {"kind": "teleport"}}, "task.kind"),
    ({"task": {"goal": [1, 2, 3]}}, "task.goal"),
    ({"task": {"starts": "here"}}, "task.starts"),
    ({"robot": {"footprint_radius": "wide"}}, "robot.footprint_radius"),
    ({"planner": {"cost": "money"}}, "planner.cost"),
    ({"planner": {"kind": "rrt"}}, "'planner.kind' must be one of gracenav, decoupled"),
    ({"planner": {"resume_from_balancing": 0}}, "'planner.resume_from_balancing' must be true"),
    ({"planner": {"seed": -1}}, "planner.seed"),
    ({"planner": {"speed_clearance": -0.2}}, "'planner.speed_clearance' must be a number in"),
    ({"simulation": {"plant": "gazebo"}}, "simulation.plant"),
    ({"simulation": {"seed": 1.5}}, "simulation.seed"),
    ({"disturbances": [{"kind": "push", "time": 1.0}]}, "disturbances[0].impulse"),
    (
        {"disturbances": [{"kind": "drag", "start_time": 3, "end_time": 2, "velocity": [0, 1]}]},
        "start_time < end_time",
    ),
    ({"name": ""}, "'name'"),
]


@pytest.mark.parametrize(("patch", "message"), BAD)
def test_bad_scenarios_name_the_key(patch: dict, message: str) -> None:
    data = yaml.safe_load((SCENARIOS / "fig5_point_to_point.yaml").read_text())
    data = copy.deepcopy(data)
    for k, v in patch.items():
        if isinstance(v, dict) and isinstance(data.get(k), dict):
            data[k].update(v)
        else:
            data[k] = v
    with pytest.raises(ConfigError, match=message.replace("[", r"\[").replace("]", r"\]")):
        parse_scenario(data, source="bad.yaml")


def test_plant_kinds_and_cost_criteria_have_one_home() -> None:
    """The scenario's simulation.plant and planner.cost take the values of
    gracenav.sim.plant.PLANT_KINDS and gracenav.planning.graph.CostCriterion, whose string
    types list the same values; planning's CostCriterion is the graph's."""
    assert typing.get_args(PlantKind) == PLANT_KINDS
    assert typing.get_args(CostName) == tuple(c.value for c in CostCriterion)
    assert planning.CostCriterion is CostCriterion
    data = yaml.safe_load((SCENARIOS / "fig5_point_to_point.yaml").read_text())
    for kind in PLANT_KINDS:
        data["simulation"] = {"plant": kind}
        assert parse_scenario(copy.deepcopy(data)).plant == kind
    for c in CostCriterion:
        data["planner"]["cost"] = c.value
        assert parse_scenario(copy.deepcopy(data)).cost == c.value


def test_bad_scenario_files(tmp_path, capsys) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\ntask: [1, 2\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_scenario(bad)
    assert main(["run", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("gracenav: error:") and err.count("\n") == 1
    missing_map = tmp_path / "ros.yaml"
    missing_map.write_text(
        "name: x\nmap: {ros_map: nowhere.yaml}\ntask: {kind: point_to_point, goal: [0, 0, 0, 0], "
        "starts: [[0, 0, 0, 0]]}\n"
    )
    assert main(["run", str(missing_map), "--out", str(tmp_path / "o")]) == 2
    assert "nowhere.yaml" in capsys.readouterr().err


def test_goal_policy_is_the_shortest_of_equally_near_trims(controller: HybridController) -> None:
    """The rest trim (1 s) and the capture trim (3 s) end at the same goal state: a task
    ends on the rest trim, not on a 2 s longer hold."""
    goal = controller.library.policy(controller.goal_policy([2.0, 2.0, 0.0, 0.0]))
    assert goal.policy.primitive.name == "rest" and goal.duration == pytest.approx(1.0)


# -- contact: the simulated robot passes through walls; the summary must say so ----------


def test_a_drag_into_a_wall_is_contact_not_a_reached_goal(tmp_path, capsys) -> None:
    """Dragged 1 m through the wall at x = -1 m, the robot comes back and its controller
    reaches the goal; the run must still not count as reaching it."""
    data = yaml.safe_load((SCENARIOS / "fig5_point_to_point.yaml").read_text())
    data["task"]["starts"] = [[0.0, 0.0, 0.0, 0.0]]
    data["disturbances"] = [
        {"kind": "drag", "start_time": 0.5, "end_time": 1.5, "velocity": [-1.0, 0.0]}
    ]
    path = tmp_path / "wall.yaml"
    path.write_text(yaml.safe_dump(data))
    out = tmp_path / "out"
    status = main(["run", str(path), "--out", str(out), "--no-animation"])
    captured = capsys.readouterr()
    assert status == 1
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("gracenav: contact: ")
    assert "run 1 at t = " in lines[0]
    run = json.loads((out / "summary.json").read_text())["runs"][0]
    assert run["stop_reason"] == "goal_reached"  # what the controller reported
    assert run["contact"] is True and run["outcome"] == "contact"
    assert run["reached_goal"] is False
    assert run["min_clearance_m"] < 0.0
    # The footprint (0.2 m) reaches the wall at x = -1 m when the ball passes x = -0.8 m:
    # the drag starts at 0.5 s and moves the body at up to 1 m/s.
    trajectory = np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1, usecols=(1, 2))
    t_contact = run["contact_time_s"]
    first = int(np.flatnonzero(trajectory[:, 1] < -0.8)[0])
    assert 0.5 < t_contact < 1.5
    assert t_contact == pytest.approx(trajectory[first, 0], abs=2.0 / 1024.0)
    assert "touched an obstacle at t = " in captured.out


def test_run_summary_contact_and_outcome() -> None:
    from gracenav.scenarios import RunSummary

    fields = {
        "start": (0.0, 0.0, 0.0, 0.0),
        "stop_reason": "goal_reached",
        "time_s": 1.0,
        "path_length_m": 1.0,
        "final_error_m": 0.0,
        "final_speed_mps": 0.0,
        "max_lean_deg": 1.0,
        "max_torque_nm": 1.0,
        "max_jerk_mps3": 1.0,
        "p95_jerk_mps3": 0.5,
        "switches": 0,
        "non_graceful_switches": 0,
        "max_graceful_torque_jump_nm": 0.0,
        "goals_reached": 1,
        "tree_ms": 0.1,
    }
    clear = RunSummary(reached_goal=True, min_clearance_m=0.1, **fields)
    assert clear.outcome == "goal_reached" and not clear.contact
    d = clear.to_dict()
    assert list(d)[:6] == [
        "start",
        "reached_goal",
        "outcome",
        "stop_reason",
        "contact",
        "contact_time_s",
    ]
    assert d["contact_time_s"] is None
    touched = RunSummary(
        reached_goal=False, min_clearance_m=-0.01, contact=True, contact_time_s=0.5, **fields
    )
    assert touched.outcome == "contact" and touched.to_dict()["outcome"] == "contact"
    with pytest.raises(ValueError, match="contact cannot have reached"):
        RunSummary(reached_goal=True, min_clearance_m=-0.01, contact=True, **fields)


def test_planner_keys_and_a_shared_library() -> None:
    """planner.resume_from_balancing and planner.seed reach the run; a library prepared
    once serves other runs on the same map (even with another simulation seed) and is
    refused for another footprint."""
    import dataclasses

    from gracenav.scenarios import prepare_library, run_scenario

    data = yaml.safe_load((SCENARIOS / "fig5_point_to_point.yaml").read_text())
    data["planner"] = {
        **data.get("planner", {}),
        "resume_from_balancing": False,
        "seed": 7,
        "speed_clearance": 0.05,
    }
    data["task"]["starts"] = data["task"]["starts"][:1]
    sc = parse_scenario(data, source="s.yaml")
    assert sc.resume_from_balancing is False and sc.library_seed == 7
    assert sc.speed_clearance == 0.05  # not the default, so the key is read
    assert sc.planner == "gracenav"
    prepared = prepare_library(sc)
    assert prepared.library.speed_clearance == 0.05
    first = run_scenario(sc, prepared=prepared)
    other = dataclasses.replace(sc, seed=123)
    again = run_scenario(other, prepared=prepared)
    assert again.library is first.library
    assert again.runs[0].reached_goal and first.runs[0].reached_goal
    with pytest.raises(ValueError, match="another map, footprint"):
        run_scenario(dataclasses.replace(sc, footprint_radius=0.25), prepared=prepared)
    with pytest.raises(ValueError, match="another map, footprint"):
        run_scenario(dataclasses.replace(sc, speed_clearance=0.2), prepared=prepared)
