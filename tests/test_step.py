"""The per-tick contract of the hybrid controller: ``reset`` once, ``step(t, x)`` every
tick from a loop of the caller's, on plants gracenav's driver has never seen."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from gracenav.errors import ConfigError
from gracenav.execution import Command, ExecutionOptions, HybridController, TaskStatus
from gracenav.library import build_library
from gracenav.model.ballbot3d import Ballbot3D
from gracenav.palette import load_palette
from gracenav.params import BallbotParams
from gracenav.planning.graph import build_graph
from gracenav.sim import Model3DPlant, MujocoPlant, Plant, Push, position_state, state_from_position
from gracenav.world import load_map

SCENARIOS = Path(__file__).resolve().parent.parent / "src" / "gracenav" / "data" / "scenarios"
START = np.array([0.0, 0.0, 0.0, 0.0])
GOAL = np.array([2.0, 2.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def fig5():  # type: ignore[no-untyped-def]
    palette = load_palette()
    spec = yaml.safe_load((SCENARIOS / "fig5_point_to_point.yaml").read_text())
    lib = build_library(palette, load_map(spec["map"]), footprint_radius=0.2, max_halvings=1)
    return lib, build_graph(lib)


class NumpyBallbot:
    """A plant written here: the 3D model's equations (numpy, not the compiled kernel)
    integrated by a classical RK4 of its own, with a torque limit of its own."""

    def __init__(self, params: BallbotParams, substeps: int = 2) -> None:
        self.model = Ballbot3D(params)
        self.ball_radius = params.ball_radius
        self.limit = params.torque_limit
        self.substeps = substeps
        self.x = np.zeros(8)

    def reset(self, x0):  # type: ignore[no-untyped-def]
        self.x = np.array(x0, dtype=float)

    def state(self):  # type: ignore[no-untyped-def]
        return self.x.copy()

    def measure(self):  # type: ignore[no-untyped-def]
        return self.x.copy()

    def _f(self, x, tau):  # type: ignore[no-untyped-def]
        return np.concatenate([x[4:], self.model.accelerations(x[:4], x[4:], tau)])

    def advance(self, torque, dt):  # type: ignore[no-untyped-def]
        tau = np.clip(torque, -self.limit, self.limit)
        h = dt / self.substeps
        for _ in range(self.substeps):
            x = self.x
            k1 = self._f(x, tau)
            k2 = self._f(x + 0.5 * h * k1, tau)
            k3 = self._f(x + 0.5 * h * k2, tau)
            k4 = self._f(x + h * k3, tau)
            self.x = x + h * (k1 + 2 * k2 + 2 * k3 + k4) / 6.0


def _drive_by_hand(hc: HybridController, plant, goal, kicks=None, limit=200_000):  # type: ignore[no-untyped-def]
    """The caller's own loop: measure, step, hold the torque for one period."""
    dt = 1.0 / hc.control_rate
    plant.reset(state_from_position(START, hc.radius))
    hc.reset(plant.measure(), [goal], options=ExecutionOptions(max_time=40.0))
    commands: list[Command] = []
    for n in range(limit):
        if kicks and n in kicks:
            plant.push(kicks[n])
        cmd = hc.step(n * dt, plant.measure())
        commands.append(cmd)
        if cmd.done:
            return commands
        plant.advance(cmd.torque, dt)
    raise AssertionError("the task never ended")


@pytest.mark.slow
def test_a_plant_written_here_reaches_the_goal(fig5) -> None:  # type: ignore[no-untyped-def]
    lib, graph = fig5
    hc = HybridController(lib, graph)
    plant = NumpyBallbot(lib.palette.params)
    assert isinstance(plant, Plant)
    cmds = _drive_by_hand(hc, plant, GOAL)
    last = cmds[-1]
    assert last.done and last.status is TaskStatus.GOAL_REACHED
    assert all(c.status is TaskStatus.RUNNING and not c.done for c in cmds[:-1])
    torques = np.array([c.torque for c in cmds[:-1]])
    assert torques.shape == (len(cmds) - 1, 2)
    assert np.all(np.abs(torques) <= lib.palette.params.torque_limit)
    p = position_state(plant.state(), plant.ball_radius)
    assert np.linalg.norm(p[:2] - GOAL[:2]) <= 0.05 and np.linalg.norm(p[2:]) <= 0.05
    # Every policy the commands name was a library row or a placed policy, and the
    # references start where the task started and end at the goal.
    refs = np.array([c.reference for c in cmds[:-1]])
    assert refs.shape[1] == 6
    np.testing.assert_allclose(refs[-1, :2], GOAL[:2], atol=0.05)
    # After the end the controller keeps balancing the robot where it stopped.
    more = hc.step((len(cmds)) / hc.control_rate, plant.measure())
    assert more.done and more.status is TaskStatus.GOAL_REACHED
    assert np.all(np.isfinite(more.torque))


def test_driving_by_hand_equals_run(fig5) -> None:  # type: ignore[no-untyped-def]
    """run() is the same loop: the same commands on the same plant, bit for bit."""
    lib, graph = fig5
    hc = HybridController(lib, graph)
    dt = 1.0 / hc.control_rate
    push = Push(3.0, (0.0, 9.0))
    cmds = _drive_by_hand(hc, Model3DPlant(), GOAL, kicks={round(push.time / dt): push.impulse})
    ep = HybridController(lib, graph).run(
        state_from_position(START, lib.palette.params.ball_radius),
        [GOAL],
        disturbances=[push],
        options=ExecutionOptions(max_time=40.0),
    )
    assert ep.status is cmds[-1].status is TaskStatus.GOAL_REACHED
    assert ep.inputs.shape[0] == len(cmds)
    np.testing.assert_array_equal(ep.inputs[:-1], np.array([c.torque for c in cmds[:-1]]))
    np.testing.assert_array_equal(ep.policy[:-1], [c.policy for c in cmds[:-1]])


@pytest.mark.slow
def test_mujoco_plant_by_hand(fig5) -> None:  # type: ignore[no-untyped-def]
    pytest.importorskip("mujoco")
    lib, graph = fig5
    hc = HybridController(lib, graph)
    plant = MujocoPlant(lib.palette.params)
    cmds = _drive_by_hand(hc, plant, GOAL)
    assert cmds[-1].status is TaskStatus.GOAL_REACHED


def test_contract_errors_and_constants(fig5) -> None:  # type: ignore[no-untyped-def]
    lib, graph = fig5
    hc = HybridController(lib, graph)
    assert hc.control_rate == 1024.0
    with pytest.raises(ConfigError, match="before reset"):
        hc.step(0.0, np.zeros(8))
    with pytest.raises(ConfigError, match="shape"):
        hc.reset(np.zeros(7), [GOAL])
    with pytest.raises(ConfigError, match="at least one goal"):
        hc.reset(np.zeros(8), [])


def test_a_missed_tick_moves_the_reference_on(fig5) -> None:  # type: ignore[no-untyped-def]
    """A caller that skips a tick (t two periods on) gets the reference of that tick."""
    lib, graph = fig5
    dt = 1.0 / 1024.0
    x0 = state_from_position(START, lib.palette.params.ball_radius)
    a, b = HybridController(lib, graph), HybridController(lib, graph)
    a.reset(x0, [GOAL])
    b.reset(x0, [GOAL])
    ra = [a.step(n * dt, x0).reference for n in range(6)]
    rb = [b.step(n * dt, x0).reference for n in (0, 1, 3, 4, 5)]
    np.testing.assert_array_equal(ra[3], rb[2])
    np.testing.assert_array_equal(ra[5], rb[4])


def test_a_fall_ends_the_task_with_zero_torque(fig5) -> None:  # type: ignore[no-untyped-def]
    lib, graph = fig5
    hc = HybridController(lib, graph)
    x0 = state_from_position(START, lib.palette.params.ball_radius)
    hc.reset(x0, [GOAL])
    fallen = x0.copy()
    fallen[2] = np.radians(30.0)
    cmd = hc.step(0.0, fallen)
    assert cmd.done and cmd.status is TaskStatus.FELL
    np.testing.assert_array_equal(cmd.torque, 0.0)


# -- computations longer than a tick ------------------------------------------------

ROOM = Path(__file__).resolve().parent.parent / "examples" / "maps" / "room_5m_box.yaml"


@pytest.fixture(scope="module")
def room():  # type: ignore[no-untyped-def]
    lib = build_library(load_palette(), load_map(ROOM), footprint_radius=0.2, max_halvings=1)
    return lib, build_graph(lib)


def test_modelled_latency_captures_land_later_and_still_catch(room) -> None:  # type: ignore[no-untyped-def]
    """With planning="modelled" and a latency of 20 ms, a push only a catch recovers
    from (22 N s at 2 s: at 3 s a library policy holds the pushed robot) is caught by
    a catch planned for the state 50 ms ahead, which starts when its start domain holds
    the state then; the task reaches the goal without balancing mode, as with the
    capture computed at once."""
    from gracenav.execution import EventReason

    lib, graph = room
    x0 = state_from_position([1.0, 1.0, 0.0, 0.0], lib.palette.params.ball_radius)
    push = [Push(2.0, (22.0, 5.0))]
    runs = {}
    for mode in ("instant", "modelled"):
        opts = ExecutionOptions(max_time=60.0, planning=mode, planning_latency=0.02)
        ep = HybridController(lib, graph).run(
            x0, [(4.0, 4.0, 0.0, 0.0)], disturbances=push, options=opts
        )
        assert ep.status is TaskStatus.GOAL_REACHED, mode
        reasons = [e.reason for e in ep.events]
        assert EventReason.CAPTURE in reasons and EventReason.BALANCING not in reasons, mode
        runs[mode] = ep
    inst = next(e for e in runs["instant"].events if e.reason is EventReason.CAPTURE)
    late = next(e for e in runs["modelled"].events if e.reason is EventReason.CAPTURE)
    # The catch starts the lead (51 ticks) after the domain exit the instant one starts at.
    assert late.tick - inst.tick == 51


def test_threaded_planning_never_waits_in_step(room, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """A capture computed on the worker thread while step keeps returning commands:
    the worker is held until 200 ticks after the push (released by the loop itself), so
    a step that waited for it would stall for the worker's 30 s timeout. The worker
    splits no verification over the cores, which the loop needs."""
    import threading
    import time

    from gracenav.execution import EventReason
    from gracenav.sim import closed_loop

    lib, graph = room
    hc = HybridController(lib, graph)
    release = threading.Event()
    plan = hc.capture_plan
    batch_threads: list[int] = []

    def held_plan(x, tree):  # type: ignore[no-untyped-def]
        batch_threads.append(closed_loop._kernel_threads(1 << 20))
        assert release.wait(30.0)
        return plan(x, tree)

    monkeypatch.setattr(hc, "capture_plan", held_plan)
    plant = Model3DPlant()
    dt = 1.0 / hc.control_rate
    plant.reset(state_from_position([1.0, 1.0, 0.0, 0.0], hc.radius))
    hc.reset(plant.measure(), [(4.0, 4.0, 0.0, 0.0)], options=ExecutionOptions(planning="threaded"))
    push_tick = 2 * 1024  # the push of the test above, which only a catch recovers from
    slowest = 0.0
    try:
        for n in range(120 * 1024):
            if n == push_tick:
                plant.push(np.array([22.0, 5.0]))
            if n == push_tick + 200:
                release.set()
            t0 = time.perf_counter()
            cmd = hc.step(n * dt, plant.measure())
            if push_tick <= n < push_tick + 200:
                slowest = max(slowest, time.perf_counter() - t0)
            if cmd.done:
                break
            plant.advance(cmd.torque, dt)
    finally:
        release.set()
        hc.close()
    # The worker was held until 200 ticks after the push: a step that waited for it would
    # have waited the worker's whole 30 s (it is released only by later steps). A hang
    # guard, not a timing: how fast a step is belongs in bench/bench_step.py.
    assert slowest < 10.0
    assert batch_threads and set(batch_threads) == {1}
    assert closed_loop._kernel_threads(1 << 20) == closed_loop._cores()  # this thread
    assert cmd.done and cmd.status is TaskStatus.GOAL_REACHED
    log = hc.log()
    assert any(e.reason is EventReason.CAPTURE for e in log.events) or any(
        e.reason is EventReason.BALANCING for e in log.events
    )
