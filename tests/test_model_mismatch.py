"""The hybrid controller on a plant whose parameters differ from the controller's."""

from __future__ import annotations

import dataclasses
import time
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
import yaml

from gracenav.execution import ExecutionOptions, HybridController, TaskStatus
from gracenav.sim import Model3DPlant, Push, state_from_position

GOAL = [2.0, 2.0, 0.0, 0.0]
SCENARIOS = Path(str(resources.files("gracenav") / "data" / "scenarios"))
#: Wall-clock hang guard (s) of one run: a run takes well under a second, so this fails
#: only on a run that never ends, not on a slow machine.
HANG_GUARD_S = 60.0


@pytest.fixture(scope="module")
def library(fig5_library, fig5_graph):  # type: ignore[no-untyped-def]
    """The Fig. 5 map's library (one halving; conftest) and its graph."""
    return fig5_library, fig5_graph


@pytest.mark.parametrize(
    "scale",
    [
        {"ball_radius": 1.02},
        {"ball_radius": 0.98},
        {"body_mass": 1.2, "body_inertia_x": 1.2, "body_inertia_y": 1.2},
        {"body_mass": 0.8, "ball_mass": 0.8, "ball_inertia": 0.8},
    ],
)
def test_every_mismatched_run_ends_in_bounded_time(library, scale) -> None:  # type: ignore[no-untyped-def]
    lib, graph = library
    nominal = lib.palette.params
    plant = dataclasses.replace(nominal, **{k: getattr(nominal, k) * v for k, v in scale.items()})
    robot = HybridController(lib, graph)
    x0 = state_from_position([0.0, 2.0, 0.0, 0.0], nominal.ball_radius)
    options = ExecutionOptions(max_time=40.0)
    t0 = time.perf_counter()
    push = [Push(time=2.0, impulse=(0.0, -8.0))]
    ep = robot.run(x0, [GOAL], disturbances=push, options=options, plant=Model3DPlant(plant))
    assert time.perf_counter() - t0 < HANG_GUARD_S
    assert ep.status in tuple(TaskStatus)
    # time advanced, and never far past max_time
    assert 0.0 < ep.time[-1] <= options.max_time + 5.0
    assert np.all(np.diff(ep.time) > 0)
    # where the robot truly is: the encoders measure θ + φ, the controller multiplies by
    # its nominal radius, the floor by the plant's; so p_true = (r_plant / r_nominal) p
    ratio = plant.ball_radius / nominal.ball_radius
    q = ep.states[:, :2] + ep.states[:, 2:4]
    np.testing.assert_allclose(
        ep.position_state[:, :2], ratio * nominal.ball_radius * q, rtol=1e-12
    )
    if ep.reached_goal:
        p_ctrl = nominal.ball_radius * q[-1]
        assert np.linalg.norm(p_ctrl - GOAL[:2]) <= options.goal_tolerance + 1e-9


def test_policies_that_never_advance_stop_the_task(library, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """A plant on which every policy leaves D' at its first tick must not loop forever."""
    from gracenav.execution.supervisor import MAX_STALLED_SEGMENTS

    calls = []

    def stuck(x, x_ref, tau_ff, c, shape, x_next=None):  # type: ignore[no-untyped-def]
        calls.append(1)
        return np.zeros(2), 2.0  # every tick outside D'(t)

    lib, graph = library
    robot = HybridController(lib, graph)
    monkeypatch.setattr(robot, "law", stuck)
    x0 = state_from_position([0.0, 2.0, 0.0, 0.0], lib.palette.params.ball_radius)
    ep = robot.run(x0, [GOAL])
    assert ep.status is TaskStatus.NO_PROGRESS
    # One tick of each stalled policy, then the hold command after the task ended.
    assert len(calls) == MAX_STALLED_SEGMENTS + 1 + 1
    assert ep.time.shape == (1,) and ep.time[0] == 0.0


# -- scenario level: simulation.plant_params ---------------------------------------------

FACTORS = {
    "ball_radius": 1.02,
    "ball_mass": 0.8,
    "body_mass": 0.8,
    "ball_inertia": 1.2,
    "body_inertia_x": 1.2,
    "body_inertia_y": 1.2,
    "body_inertia_z": 1.2,
}


def _mismatch_scenario(max_time: float = 40.0):  # type: ignore[no-untyped-def]
    from gracenav.scenarios import parse_scenario

    data = yaml.safe_load((SCENARIOS / "fig5_point_to_point.yaml").read_text())
    data["task"]["starts"] = [[0.0, 2.0, 0.0, 0.0]]
    push = min(1.0, max_time / 2)
    data["disturbances"] = [{"kind": "push", "time": push, "impulse": [0.0, -8.0]}]
    data["simulation"]["max_time"] = max_time
    data["simulation"]["plant_params"] = dict(FACTORS)
    return parse_scenario(data, source="mismatch.yaml")


def test_scenario_plant_factors_run_to_an_end_in_bounded_time(palette) -> None:
    from gracenav.scenarios import run_scenario, summary_dict

    sc = _mismatch_scenario()
    assert dict(sc.plant_factors) == FACTORS
    t0 = time.perf_counter()
    res = run_scenario(sc)
    assert time.perf_counter() - t0 < HANG_GUARD_S
    nominal = palette.params
    plant = res.plant_params
    assert plant is not None
    for name in dataclasses.asdict(nominal):
        factor = FACTORS.get(name, 1.0)
        assert getattr(plant, name) == pytest.approx(factor * getattr(nominal, name), rel=1e-15)
    ep, run = res.episodes[0], res.runs[0]
    # The episode ran on the scaled plant: its true positions use the plant's radius.
    assert ep.radius == pytest.approx(1.02 * nominal.ball_radius, rel=1e-15)
    assert run.stop_reason in {s.value for s in TaskStatus}
    assert 0.0 < run.time_s <= sc.max_time + 1.0 / 1024.0 + 1e-12
    assert not run.contact and run.outcome == run.stop_reason
    summary = summary_dict(res)
    assert summary["plant_param_factors"] == FACTORS
    assert summary["plant_params"]["body_mass"] == pytest.approx(0.8 * nominal.body_mass)
    assert summary["plant_params"]["gravity"] == nominal.gravity


def test_scenario_plant_factors_apply_on_top_of_explicit_params() -> None:
    from gracenav.params import BallbotParams
    from gracenav.scenarios import apply_plant_factors, run_scenario

    sc = _mismatch_scenario(max_time=0.25)
    base = BallbotParams(body_mass=60.0, torque_limit=50.0)
    plant = apply_plant_factors(sc, base)
    assert plant.body_mass == pytest.approx(48.0, rel=1e-15)
    assert plant.torque_limit == 50.0  # not scaled: kept from the explicit parameters
    assert plant.ball_radius == pytest.approx(1.02 * base.ball_radius, rel=1e-15)
    res = run_scenario(sc, params=base)
    assert res.plant_params == plant
    assert res.episodes[0].radius == plant.ball_radius
    no_factors = dataclasses.replace(sc, plant_factors=())
    assert apply_plant_factors(no_factors, base) is base


BAD_FACTORS = [
    (
        {"body_inertia": 1.2},
        "mismatch.yaml: unknown key(s) 'simulation.plant_params.body_inertia'; allowed: "
        "ball_inertia, ball_mass, ball_radius, body_com_height, body_inertia_x, "
        "body_inertia_y, body_inertia_z, body_mass, coulomb_friction, torque_limit, "
        "viscous_friction",
    ),
    (
        {"gravity": 1.1},
        "mismatch.yaml: unknown key(s) 'simulation.plant_params.gravity'; allowed: "
        "ball_inertia, ball_mass, ball_radius, body_com_height, body_inertia_x, "
        "body_inertia_y, body_inertia_z, body_mass, coulomb_friction, torque_limit, "
        "viscous_friction",
    ),
    (
        {"body_mass": -0.8},
        "mismatch.yaml: 'simulation.plant_params.body_mass' must be a number in [0.5, 2], got -0.8",
    ),
    (
        {"ball_radius": 0},
        "mismatch.yaml: 'simulation.plant_params.ball_radius' must be a number in [0.5, 2], got 0",
    ),
    (
        {"body_inertia_x": 2.5},
        "mismatch.yaml: 'simulation.plant_params.body_inertia_x' must be a number in "
        "[0.5, 2], got 2.5",
    ),
    (
        {"ball_mass": "0.9"},
        "mismatch.yaml: 'simulation.plant_params.ball_mass' must be a finite number, got "
        "'0.9' (a string: write numbers without quotes)",
    ),
    (
        {"ball_mass": float("nan")},
        "mismatch.yaml: 'simulation.plant_params.ball_mass' must be a finite number, got nan",
    ),
    (
        [1.02],
        "mismatch.yaml: 'simulation.plant_params' must be a mapping, got a list",
    ),
]


@pytest.mark.parametrize(("factors", "message"), BAD_FACTORS)
def test_bad_plant_factors_are_refused_in_one_line(factors, message) -> None:  # type: ignore[no-untyped-def]
    from gracenav.errors import ConfigError
    from gracenav.scenarios import parse_scenario

    data = yaml.safe_load((SCENARIOS / "fig5_point_to_point.yaml").read_text())
    data["simulation"]["plant_params"] = factors
    with pytest.raises(ConfigError) as info:
        parse_scenario(data, source="mismatch.yaml")
    assert str(info.value) == message


def test_bad_plant_factors_on_the_command_line(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    from gracenav.cli import main

    text = (SCENARIOS / "fig5_point_to_point.yaml").read_text()
    text = text.replace("max_time: 60}", "max_time: 60, plant_params: {body_mass: 3}}")
    path = tmp_path / "mismatch.yaml"
    path.write_text(text)
    assert main(["run", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err == (
        f"gracenav: error: {path}: 'simulation.plant_params.body_mass' must be a number in "
        "[0.5, 2], got 3\n"
    )
    assert not (tmp_path / "o").exists()
