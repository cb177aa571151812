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
from gracenav.graph import build_graph
from gracenav.library import build_library
from gracenav.palette import load_palette
from gracenav.simulate import Push, state_from_position
from gracenav.world import load_map

GOAL = [2.0, 2.0, 0.0, 0.0]
SCENARIOS = Path(str(resources.files("gracenav") / "data" / "scenarios"))


@pytest.fixture(scope="module")
def library():  # type: ignore[no-untyped-def]
    pal = load_palette()
    data = yaml.safe_load((SCENARIOS / "fig5_point_to_point.yaml").read_text())
    lib = build_library(pal, load_map(data["map"]), max_halvings=1)
    return lib, build_graph(lib)


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
    robot = HybridController(lib, graph, params=plant)
    x0 = state_from_position([0.0, 2.0, 0.0, 0.0], nominal.ball_radius)
    options = ExecutionOptions(max_time=40.0)
    t0 = time.perf_counter()
    ep = robot.run(x0, [GOAL], disturbances=[Push(time=2.0, impulse=(0.0, -8.0))], options=options)
    assert time.perf_counter() - t0 < 60.0
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
    import gracenav.execution as execution
    from gracenav.simulate import SimulationResult, StopReason

    calls = []

    def stuck(x, ref, gains, **kwargs):  # type: ignore[no-untyped-def]
        calls.append(1)
        return SimulationResult(
            time=np.zeros(1),
            states=np.asarray(x, dtype=float)[None, :],
            inputs=np.zeros((1, 2)),
            radius=gains.params.ball_radius,
            max_lean=0.0,
            max_torque=0.0,
            saturated_ticks=0,
            max_domain_value=2.0,
            stop_reason=StopReason.DOMAIN_EXIT,
        )

    monkeypatch.setattr(execution, "simulate", stuck)
    lib, graph = library
    robot = HybridController(lib, graph)
    x0 = state_from_position([0.0, 2.0, 0.0, 0.0], lib.palette.params.ball_radius)
    ep = robot.run(x0, [GOAL])
    assert ep.status is TaskStatus.NO_PROGRESS
    assert len(calls) == execution._MAX_STALLED_SEGMENTS + 1
    assert ep.time.shape == (1,) and ep.time[0] == 0.0
