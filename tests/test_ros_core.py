"""The ROS nodes' conventions and logic without ROS: conversions, the DDS environment,
and the navigator core's balancing, queueing and safe behaviours."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from gracenav._util.io import note_signal
from gracenav.ros import convert
from gracenav.ros.core import NavigatorCore, NavigatorOptions, Phase
from gracenav.ros.env import LOCAL_DDS, local_dds_environment
from gracenav.ros.node import signals_ask_to_stop, stop_requested


def test_import_gracenav_and_its_ros_package_do_not_import_rclpy() -> None:
    code = (
        "import sys, gracenav, gracenav.ros, gracenav.ros.core, gracenav.ros.convert, "
        "gracenav.cli; assert 'rclpy' not in sys.modules, 'rclpy imported'"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)


def _deliver(sig: int) -> None:
    os.kill(os.getpid(), sig)
    end = time.monotonic() + 5.0
    while time.monotonic() < end:  # the handler runs between two bytecodes
        time.sleep(0.001)
        if stop_requested():
            return


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_first_signal_asks_the_spin_loops_to_stop_and_a_second_interrupts(sig: int) -> None:
    before = signal.getsignal(sig)
    note_signal(None)
    try:
        with signals_ask_to_stop():
            assert not stop_requested()
            _deliver(sig)  # recorded, no exception: the loops return by themselves
            assert stop_requested()
            with pytest.raises(KeyboardInterrupt):
                os.kill(os.getpid(), sig)
                time.sleep(5.0)
        assert signal.getsignal(sig) is before
    finally:
        note_signal(None)


def test_local_dds_environment_keeps_the_users_values() -> None:
    env: dict[str, str] = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}
    got = local_dds_environment(env)
    assert got["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SUBNET"
    assert got["ROS_LOCALHOST_ONLY"] == "1" and env["RMW_IMPLEMENTATION"] == "rmw_fastrtps_cpp"
    fresh: dict[str, str] = {}
    assert local_dds_environment(fresh) == LOCAL_DDS == fresh
    assert "ROS_DOMAIN_ID" not in fresh and os.environ is not fresh


@pytest.mark.parametrize("seed", range(5))
def test_readings_round_trip_to_the_model_state(seed: int) -> None:
    rng = np.random.default_rng(seed)
    r = 0.1058
    x = rng.normal(size=8) * np.array([5, 5, 0.1, 0.1, 3, 3, 0.5, 0.5])
    p = convert.odometry_from_state(x, r)
    q, w = convert.imu_from_state(x)
    back = convert.state_from_readings(p, q, w, r)
    np.testing.assert_allclose(back, x, rtol=0, atol=1e-12)


def test_torque_vector_convention() -> None:
    # Rolling toward +x turns the ball about +y; toward +y, about -x.
    np.testing.assert_array_equal(convert.vector_from_torque([2.0, 0.0]), [0.0, 2.0, 0.0])
    np.testing.assert_array_equal(convert.vector_from_torque([0.0, 3.0]), [-3.0, 0.0, 0.0])
    t = np.array([0.7, -1.3])
    np.testing.assert_array_equal(convert.torque_from_vector(convert.vector_from_torque(t)), t)
    # A lean rate toward +x is a rotation rate about +y.
    _, w = convert.imu_from_state([0, 0, 0, 0, 0, 0, 0.4, 0.0])
    np.testing.assert_array_equal(w, [0.0, 0.4, 0.0])


def _core(lines: list[tuple[str, str]]) -> NavigatorCore:
    from gracenav.palette import load_palette

    opts = NavigatorOptions(state_timeout=0.1, stop_timeout=0.3)
    return NavigatorCore(load_palette(), opts, log=lambda lvl, msg: lines.append((lvl, msg)))


def test_without_a_map_the_robot_balances_in_place_and_a_goal_waits() -> None:
    from gracenav.sim import Model3DPlant, state_from_position

    lines: list[tuple[str, str]] = []
    core = _core(lines)
    plant = Model3DPlant(core.palette.params)
    plant.reset(state_from_position([0.5, -0.2, 0.0, 0.0], core.radius, lean=(0.03, -0.02)))
    core.request_goals([[2.0, 2.0, 0.0, 0.0]])
    assert ("info", "goal queued: the library is not built yet") in lines
    for k in range(2048):  # 2 s
        tick = core.control(k * core.dt, plant.measure(), wall=0.0)
        plant.advance(tick.torque, core.dt)
    assert tick.policy == -1 and core.phase is Phase.WAITING_FOR_MAP
    x = plant.state()
    p = convert.odometry_from_state(x, core.radius)
    np.testing.assert_allclose(p[:2], [0.5, -0.2], atol=0.05)
    assert np.hypot(*x[2:4]) < 0.01 and np.hypot(*p[2:]) < 0.05


def _balance_noisy(
    core: NavigatorCore, retune: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """1 s of balancing in place at (0.5, -0.2) on 5 mm of odometry noise (seed 7): the
    torques and the ball's true position at the end; with ``retune`` the core is told,
    half-way, that the noise is that (m)."""
    from gracenav.sim import Model3DPlant, state_from_position

    plant = Model3DPlant(core.palette.params, position_noise_std=0.005, seed=7)
    plant.reset(state_from_position([0.5, -0.2, 0.0, 0.0], core.radius))
    torques = []
    for k in range(1024):
        if retune is not None and k == 512:
            core.set_noise(retune, 0.0)
        tick = core.control(k * core.dt, plant.measure(), wall=0.0)
        plant.advance(tick.torque, core.dt)
        torques.append(tick.torque)
    return np.array(torques), convert.odometry_from_state(plant.state(), core.radius)[:2]


def test_a_noisy_odometry_is_filtered_before_the_balancing_law() -> None:
    """5 mm of noise on the odometry's position: told so (``position_noise_std``), the
    node balances in place on the filtered position, with a fraction of the torque's
    chatter; the position it keeps is the same to within the noise."""
    from gracenav.palette import load_palette

    palette = load_palette()
    chatter, held = {}, {}
    for told in (0.0, 0.005):
        opts = NavigatorOptions(state_timeout=0.1, stop_timeout=0.3, position_noise_std=told)
        core = NavigatorCore(palette, opts, log=lambda lvl, msg: None)
        torques, held[told] = _balance_noisy(core)
        chatter[told] = float(np.mean(np.abs(np.diff(torques, axis=0))))
    assert chatter[0.005] < 0.2 * chatter[0.0]
    np.testing.assert_allclose(held[0.005], [0.5, -0.2], atol=0.02)
    np.testing.assert_allclose(held[0.0], [0.5, -0.2], atol=0.02)


def test_a_noise_stated_by_the_readings_tunes_the_filter_as_the_option_does() -> None:
    """``set_noise`` (what the node calls with the odometry's covariance when
    ``noise_from_covariance`` is on) before the first reading gives, torque for torque,
    the run of the ``position_noise_std`` option; a change within 10 % keeps the filter
    (same torques), a larger one builds it again and goes on from the last estimate
    (no step: the torque's change at the switch is below five times the run's median);
    refused and clipped values."""
    from gracenav.palette import load_palette

    palette = load_palette()
    quiet = lambda lvl, msg: None  # noqa: E731
    told = NavigatorOptions(state_timeout=0.1, stop_timeout=0.3, position_noise_std=0.005)
    by_option, _ = _balance_noisy(NavigatorCore(palette, told, log=quiet))
    opts = NavigatorOptions(state_timeout=0.1, stop_timeout=0.3)
    lines: list[tuple[str, str]] = []
    core = NavigatorCore(palette, opts, log=lambda lvl, msg: lines.append((lvl, msg)))
    assert core.set_noise(0.005, 0.0)
    assert any("position filter tuned to 5 mm" in m for _, m in lines)
    np.testing.assert_array_equal(_balance_noisy(core)[0], by_option)
    core = NavigatorCore(palette, opts, log=quiet)
    core.set_noise(0.005, 0.0)
    np.testing.assert_array_equal(_balance_noisy(core, retune=0.0052)[0], by_option)
    core = NavigatorCore(palette, opts, log=quiet)
    core.set_noise(0.005, 0.0)
    retuned, _ = _balance_noisy(core, retune=0.01)
    np.testing.assert_array_equal(retuned[:512], by_option[:512])
    assert not np.array_equal(retuned[512:], by_option[512:])
    steps = np.abs(np.diff(retuned, axis=0)).max(axis=1)
    assert steps[511] < 5 * np.median(steps)  # the tick after the retune
    assert core.set_noise(0.0, 0.0) and not core.set_noise(0.0, 0.0)
    lines.clear()
    core = NavigatorCore(palette, opts, log=lambda lvl, msg: lines.append((lvl, msg)))
    assert core.set_noise(3.0, 2.0) and not core.set_noise(1.0, 1.0)  # clipped to 1 and 1
    assert [m for _, m in lines] == ["position filter tuned to 1e+03 mm and 1e+03 mm/s of noise"]
    from gracenav.errors import ConfigError

    for bad in (-0.001, float("nan")):
        with pytest.raises(ConfigError, match="non-negative standard deviation"):
            core.set_noise(bad, 0.0)


def test_odometry_covariances_state_the_noise() -> None:
    pose, twist = np.zeros(36), np.zeros(36)
    pose[0], pose[7], twist[0], twist[7] = 0.005**2, 0.004**2, 0.01**2, 0.02**2
    got = convert.noise_from_covariance(pose, twist)
    assert got is not None
    np.testing.assert_allclose(got, (0.005, 0.02), rtol=1e-12)
    assert convert.noise_from_covariance(np.zeros(36), np.zeros(36)) == (0.0, 0.0)
    for k, v in ((0, -1.0), (7, float("nan")), (0, float("inf"))):
        bad = pose.copy()
        bad[k] = v
        assert convert.noise_from_covariance(bad, twist) is None
    assert convert.noise_from_covariance(np.zeros(9), twist) is None


def test_silence_holds_then_stops_and_readings_bring_balancing_back() -> None:
    lines: list[tuple[str, str]] = []
    core = _core(lines)
    x = np.zeros(8)
    x[2] = 0.02  # leaning: the balancing torque is not zero
    tick = core.control(0.0, x, wall=10.0)
    assert np.any(tick.torque != 0.0)
    assert core.watchdog(10.05) == "ok"
    assert core.watchdog(10.15) == "hold"
    np.testing.assert_array_equal(core.last_torque, tick.torque)  # held
    assert core.watchdog(10.35) == "stop" and core.phase is Phase.STOPPED
    np.testing.assert_array_equal(core.last_torque, [0.0, 0.0])
    assert core.watchdog(11.0) == "stop"
    levels = [lvl for lvl, msg in lines if "no valid state reading" in msg]
    assert levels == ["warn", "error"]  # each change logged once
    core.control(1.0, x, wall=11.1)
    assert core.staleness == "ok"
    assert any("readings are back" in msg for _, msg in lines)


def test_rejections_are_logged_once_per_reason_every_two_seconds() -> None:
    lines: list[tuple[str, str]] = []
    core = _core(lines)
    for k in range(100):
        core.reject("/odom", "frame_id 'x' is not 'odom' or 'map'", wall=0.01 * k)
    core.reject("/imu", "orientation or angular velocity is not finite", wall=0.5)
    core.reject("/odom", "frame_id 'x' is not 'odom' or 'map'", wall=2.5)
    assert [m for _, m in lines] == [
        "/odom: frame_id 'x' is not 'odom' or 'map'; dropped (holding the last command)",
        "/imu: orientation or angular velocity is not finite; dropped (holding the last command)",
        "/odom: frame_id 'x' is not 'odom' or 'map'; dropped (holding the last command)",
    ]


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"state_timeout": 0.5, "stop_timeout": 0.2}, "state_timeout < stop_timeout"),
        ({"cost": "energy"}, "cost must be"),
        ({"footprint_radius": -1.0}, "footprint_radius must be a positive number"),
        ({"position_noise_std": -0.001}, "position_noise_std must be a standard deviation"),
        ({"position_noise_std": float("nan")}, "position_noise_std must be a standard deviation"),
    ],
)
def test_bad_navigator_options(kwargs: dict[str, object], needle: str) -> None:
    from gracenav.errors import ConfigError

    with pytest.raises(ConfigError, match=needle):
        NavigatorOptions(**kwargs)  # type: ignore[arg-type]


def test_a_route_is_driven_through_its_goals_in_order() -> None:
    # A surveillance route as /gracenav/route gives it: the navigator core plans it on
    # a worker thread and drives the robot through every goal, then ends at the last.
    from gracenav.sim import Model3DPlant, state_from_position
    from gracenav.world import Rectangle, WorldMap

    lines: list[tuple[str, str]] = []
    core = _core(lines)
    world = WorldMap.from_shapes(
        [[0.0, 0.0], [4.0, 3.0]], [Rectangle((1.8, 2.2), (2.2, 3.0))], resolution=0.05
    )
    core.set_map(world, background=False)
    plant = Model3DPlant(core.palette.params)
    plant.reset(state_from_position([1.0, 1.0, 0.0, 0.0], core.radius))
    core.control(0.0, plant.measure(), wall=0.0)
    route = [[3.0, 1.0, 0.0, 0.0], [3.0, 2.0, 0.0, 0.0], [1.0, 2.0, 0.0, 0.0]]
    core.request_goals(route)
    visits: list[int] = []
    finished = None
    for k in range(1, 60 * 1024):
        if core.phase is Phase.PLANNING and k % 64 == 0:
            import time

            time.sleep(0.001)  # let the planning thread run
        tick = core.control(k * core.dt, plant.measure(), wall=k * core.dt)
        plant.advance(tick.torque, core.dt)
        if k % 256 == 0:
            p = convert.odometry_from_state(plant.state(), core.radius)
            near = [j for j, g in enumerate(route) if np.hypot(p[0] - g[0], p[1] - g[1]) < 0.05]
            if near and (not visits or visits[-1] != near[0]):
                visits.append(near[0])
        if tick.finished is not None:
            finished = tick.finished
            break
    assert finished == "goal_reached", lines
    assert visits == [0, 1, 2]
    p = convert.odometry_from_state(plant.state(), core.radius)
    np.testing.assert_allclose(p[:2], route[-1][:2], atol=0.01)
    core.close()
