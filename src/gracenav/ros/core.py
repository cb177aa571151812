"""What the navigator node does, without ROS: the library built and the tasks planned on
a worker thread, a command every control tick, and the safe behaviours.

The control path (:meth:`NavigatorCore.control`) never waits for a plan: until the
library is built and a goal's first tree is planned (on a worker thread), the robot
balances where it is (the Fig. 2 law toward the ball's position at rest); the new task
takes over at the first tick after its plan lands, with its time starting there.
Bad state readings are dropped with a log line (:meth:`NavigatorCore.reject`); when no
valid reading has come for ``state_timeout`` the node holds its last command, and
after ``stop_timeout`` it stops (zero torque, the task dropped), until readings come
back (then it balances where the robot is and waits for a goal).
"""

from __future__ import annotations

import enum
import json
import math
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.errors import ConfigError, GracenavError
from gracenav.sim.state import position_state, state_from_position

__all__ = ["NavigatorCore", "NavigatorOptions", "Phase", "TickResult"]

FloatArray = NDArray[np.float64]
Logger = Callable[[str, str], None]
"""``log(level, message)`` with level ``"info"``, ``"warn"`` or ``"error"``."""

_NO_CENTER = np.zeros((0,))
_NO_SHAPE = np.zeros((0, 0))

#: Relative change of a stated noise (:meth:`NavigatorCore.set_noise`) below which the
#: position filter is kept as it is (a covariance that moves a little every reading
#: does not rebuild it every tick).
NOISE_CHANGE = 0.1


class Phase(enum.Enum):
    """What the navigator is doing (the ``state`` of its status)."""

    WAITING_FOR_MAP = "waiting_for_map"
    BUILDING = "building_library"
    READY = "ready"
    PLANNING = "planning"
    RUNNING = "running"
    DONE = "done"
    STOPPED = "stopped"


@dataclass(frozen=True)
class NavigatorOptions:
    """Options of the navigator (ROS parameters of the same names).

    Parameters
    ----------
    footprint_radius : float
        Robot footprint radius (m) the library keeps clear of obstacles.
    max_halvings : int
        Lattice halvings of the library (:func:`gracenav.library.build_library`).
    cost : {"time", "distance"}
        Optimality criterion of the trees.
    max_time : float
        Longest task (s) before it stops as timed out.
    goal_tolerance : float
        Distance (m) and speed (m/s) within which a goal at rest is reached.
    state_timeout : float
        Wall time (s) without a valid state reading after which the last command is
        held (and a line logged).
    stop_timeout : float
        Wall time (s) without a valid state reading after which the node stops: zero
        torque, task dropped.
    log_stride : int
        Control ticks per sample of the MCAP recording.
    position_noise_std : float
        Standard deviation (m) of the white noise on the odometry's ball position:
        every tick (balancing in place and in a task) acts on the position a
        steady-state Kalman filter estimates from it and the odometry's velocity
        (:class:`gracenav.control.PositionEstimator`, started again after a gap in the
        readings); 0 (the default) acts on the position as received.
    """

    footprint_radius: float = 0.2
    max_halvings: int = 1
    cost: str = "time"
    max_time: float = 120.0
    goal_tolerance: float = 0.05
    state_timeout: float = 0.1
    stop_timeout: float = 0.5
    log_stride: int = 8
    position_noise_std: float = 0.0

    def __post_init__(self) -> None:
        v = self.position_noise_std
        if not (isinstance(v, int | float) and np.isfinite(v) and 0 <= v <= 1):
            raise ConfigError(
                f"position_noise_std must be a standard deviation within [0, 1] m, got {v!r}"
            )
        for name in ("footprint_radius", "max_time", "goal_tolerance"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and np.isfinite(v) and v > 0):
                raise ConfigError(f"{name} must be a positive number, got {v!r}")
        if not (0 < self.state_timeout < self.stop_timeout):
            raise ConfigError(
                "state_timeout and stop_timeout must satisfy 0 < state_timeout < stop_timeout "
                f"(s), got {self.state_timeout!r} and {self.stop_timeout!r}"
            )
        if self.cost not in ("time", "distance"):
            raise ConfigError(f"cost must be 'time' or 'distance', got {self.cost!r}")
        if not (isinstance(self.max_halvings, int) and 0 <= self.max_halvings <= 6):
            raise ConfigError(
                f"max_halvings must be an integer in [0, 6], got {self.max_halvings!r}"
            )
        if not (isinstance(self.log_stride, int) and self.log_stride >= 1):
            raise ConfigError(f"log_stride must be a positive integer, got {self.log_stride!r}")


@dataclass(frozen=True, slots=True)
class TickResult:
    """The command of one tick and what changed.

    Attributes
    ----------
    torque : ndarray, shape (2,)
        Generalised torques (N m) on θ_x and θ_y.
    policy : int
        Library row running (< 0: balancing, terminal regulator, catch, none).
    reference : ndarray, shape (6,)
        Reference x, y, ẋ, ẏ, ẍ, ÿ (m, m/s, m/s²), ``map`` frame.
    switched : bool
        The policy changed at this tick (or a new task started).
    finished : str or None
        The task ended at this tick: its status (``goal_reached``, ...).
    """

    torque: FloatArray
    policy: int
    reference: FloatArray
    switched: bool
    finished: str | None


class NavigatorCore:
    """The navigator's logic: map → library (background), goals → task (background),
    state → command (every tick, never waiting).

    Parameters
    ----------
    palette : Palette
        The motion policy palette (its gains balance the robot before a task).
    options : NavigatorOptions
    log : callable(level, message)
        Where log lines go.
    recorder : McapRunLog, optional
        Records the map, samples, switches and events.
    """

    def __init__(
        self,
        palette: Any,
        options: NavigatorOptions,
        *,
        log: Logger,
        recorder: Any = None,
    ) -> None:
        from gracenav.control import CONTROL_RATE, PositionEstimator, TrackingLaw

        self.palette = palette
        self.options = options
        self.log = log
        self.recorder = recorder
        self.radius = float(palette.params.ball_radius)
        self.dt = 1.0 / CONTROL_RATE
        self.law = TrackingLaw(palette.gains)
        # Every tick's state, balancing in place and in a task alike, is filtered here
        # once (the controller of a task is given it as it is: its own filter is off).
        self._estimator = PositionEstimator(
            self.radius, self.dt, position_std=options.position_noise_std
        )
        self._noise = (float(options.position_noise_std), 0.0)
        self._estimated = False
        self._lock = threading.Lock()
        self.phase = Phase.WAITING_FOR_MAP
        self.world_map: Any = None
        self.library: Any = None
        self.graph: Any = None
        self._hc: Any = None
        self._pending: Any = None
        self._wanted: tuple[list[FloatArray], int] | None = None
        self._planning = False
        self._t0: float | None = None
        self._hold: FloatArray | None = None
        self.goals: list[FloatArray] = []
        self.x_last: FloatArray | None = None
        self.last_torque = np.zeros(2)
        self.policy = -1
        self.ticks = 0
        self.task_ticks = 0
        self.first_tick_wall: float | None = None
        self.last_valid_wall: float | None = None
        self.staleness = "ok"
        self.message = "waiting for a map"
        self._rejections: dict[str, float] = {}
        self._log_origin: float | None = None
        self._tick_sum = 0.0
        self._tick_max = 0.0

    # -- map and library ---------------------------------------------------------------
    def set_map(self, world_map: Any, *, prepared: Any = None, background: bool = True) -> None:
        """Build the library on ``world_map`` (on a worker thread unless ``background``
        is False); ``prepared``: a library built already
        (:class:`gracenav.scenarios.PreparedLibrary`)."""
        with self._lock:
            if self.phase is Phase.BUILDING:
                self.log("warn", "a map arrived while the library is being built: ignored")
                return
            self.phase = Phase.BUILDING
            self.message = "building the library"
        self.world_map = world_map
        if background:
            threading.Thread(
                target=self._build, args=(world_map, prepared), name="gracenav-library", daemon=True
            ).start()
        else:
            self._build(world_map, prepared)

    def _build(self, world_map: Any, prepared: Any) -> None:
        from gracenav.execution.capture import capture_for
        from gracenav.library import build_library
        from gracenav.planning.graph import build_graph

        t0 = time.perf_counter()
        try:
            if prepared is not None:
                library, graph = prepared.library, prepared.graph
            else:
                library = build_library(
                    self.palette,
                    world_map,
                    footprint_radius=self.options.footprint_radius,
                    max_halvings=self.options.max_halvings,
                )
                graph = build_graph(library)
            capture_for(library)  # built once here rather than in the first plan
        except GracenavError as exc:
            self.log("error", f"cannot build the library on the map: {exc}")
            with self._lock:
                self.phase = Phase.WAITING_FOR_MAP
                self.message = f"library failed: {exc}"
            return
        self.log(
            "info",
            f"library: {len(library)} policies, {graph.num_edges} edges, coverage "
            f"{100 * float(library.coverage):.1f} %, built in {time.perf_counter() - t0:.1f} s",
        )
        if self.recorder is not None:
            self.recorder.library = library
            self.recorder.world_map(self._log_time(), world_map)
            self.recorder.robot(self._log_time(), self.radius, self.options.footprint_radius)
        with self._lock:
            self.library, self.graph = library, graph
            self.phase = Phase.READY
            self.message = "ready: send a goal"
            wanted, self._wanted = self._wanted, None
        if wanted is not None:
            self.request_goals(*wanted)

    # -- goals -------------------------------------------------------------------------
    def request_goals(self, goals: Sequence[ArrayLike], loops: int = 1) -> None:
        """Start a task toward ``goals`` (position states (4,), m and m/s), ``loops``
        times: planned on a worker thread from the latest state; the running task goes
        on (or the robot balances) until the plan lands. A request while the library is
        built or another plan runs waits for it (the latest request wins)."""
        gs = [np.asarray(g, dtype=float).reshape(4) for g in goals]
        if not gs or not all(np.all(np.isfinite(g)) for g in gs):
            self.log("error", "a goal must be a finite position; goal ignored")
            return
        with self._lock:
            if self.library is None or self._planning or self.x_last is None:
                self._wanted = (gs, loops)
                why = (
                    "the library is not built yet"
                    if self.library is None
                    else "another plan is running"
                    if self._planning
                    else "no state reading yet"
                )
                self.log("info", f"goal queued: {why}")
                return
            self._planning = True
            x0 = self.x_last.copy()
            if self.phase is not Phase.RUNNING:
                self.phase = Phase.PLANNING
            self.message = "planning"
        threading.Thread(
            target=self._plan, args=(gs, loops, x0), name="gracenav-plan", daemon=True
        ).start()

    def _plan(self, goals: list[FloatArray], loops: int, x0: FloatArray) -> None:
        from gracenav.execution import ExecutionOptions, HybridController
        from gracenav.sim import limit_batch_threads

        limit_batch_threads(1)  # it plans beside the control callback: one core
        t0 = time.perf_counter()
        hc = HybridController(self.library, self.graph, criterion=self.options.cost)
        opts = ExecutionOptions(
            max_time=self.options.max_time,
            goal_tolerance=self.options.goal_tolerance,
            planning="threaded",
            position_filter=False,  # control() filters every tick's state
        )
        try:
            hc.reset(x0, goals, loops=loops, options=opts)
        except GracenavError as exc:
            hc.close()
            self.log("error", f"goal rejected: {exc}")
            with self._lock:
                self._planning = False
                if self.phase is Phase.PLANNING:
                    self.phase = Phase.READY
                self.message = f"goal rejected: {exc}"
                wanted, self._wanted = self._wanted, None
            if wanted is not None:
                self.request_goals(*wanted)
            return
        where = "; ".join(f"({g[0]:.3g}, {g[1]:.3g})" for g in goals)
        self.log("info", f"planned the task to {where} in {time.perf_counter() - t0:.2f} s")
        with self._lock:
            self._pending = (hc, goals)
            self._planning = False
            wanted, self._wanted = self._wanted, None
        if wanted is not None:
            self.request_goals(*wanted)

    # -- control -----------------------------------------------------------------------
    def _balance(self, x: FloatArray) -> FloatArray:
        if self._hold is None:
            self._hold = state_from_position(
                np.r_[position_state(x, self.radius)[:2], 0.0, 0.0], self.radius
            )
        tau, _ = self.law(x, self._hold, np.zeros(2), _NO_CENTER, _NO_SHAPE)
        return np.asarray(tau, dtype=float)

    def set_noise(self, position_std: float, velocity_std: float) -> bool:
        """Tune the position filter to the noise (m, m/s) a reading states (e.g. its
        covariance): each clipped to [0, 1]. The filter is built again only when either
        differs from the one it is tuned to by more than :data:`NOISE_CHANGE` (relative;
        from or to zero, any change), and then goes on from its last estimate. Returns
        whether it was built again.

        Raises
        ------
        ConfigError
            A standard deviation that is negative or not finite.
        """
        for name, v in (("position_std", position_std), ("velocity_std", velocity_std)):
            if not (math.isfinite(v) and v >= 0.0):
                raise ConfigError(f"{name} must be a non-negative standard deviation, got {v!r}")
        new = (min(float(position_std), 1.0), min(float(velocity_std), 1.0))
        if all(
            abs(a - b) <= NOISE_CHANGE * max(a, b) for a, b in zip(new, self._noise, strict=True)
        ):
            return False  # within 10 % of each (so zero stays zero, and any change from it counts)
        from gracenav.control import PositionEstimator

        estimator = PositionEstimator(self.radius, self.dt, *new)
        if self._estimated and self.x_last is not None:
            estimator.reset(self.x_last)  # the last estimate, not a new measurement
        self._estimator, self._noise = estimator, new
        self.log(
            "info",
            f"position filter tuned to {new[0] * 1e3:.3g} mm and {new[1] * 1e3:.3g} mm/s of noise",
        )
        return True

    def control(self, t: float, x: ArrayLike, wall: float | None = None) -> TickResult:
        """The command for the state ``x`` (8,) measured at time ``t`` (s, the reading's
        stamp). Never waits: a plan that has landed is adopted here, one still running
        is not waited for."""
        wall = time.monotonic() if wall is None else wall
        xs = np.asarray(x, dtype=float)
        if self.staleness != "ok":
            self.log("info", "state readings are back: balancing in place")
            self.staleness = "ok"
            self._estimated = False  # after a gap the estimate starts again
        if self._estimated:
            xs = self._estimator.update(xs)
        else:
            xs = self._estimator.reset(xs)
            self._estimated = True
        self.x_last = xs.copy()
        self.last_valid_wall = wall
        if self.first_tick_wall is None:
            self.first_tick_wall = wall
        switched = False
        finished = None
        pending = None
        with self._lock:
            if self._pending is not None:
                pending, self._pending = self._pending, None
            wanted = self._wanted if (not self._planning and self.library is not None) else None
            if wanted is not None:
                self._wanted = None
        if wanted is not None:
            self.request_goals(*wanted)
        if pending is not None:
            old, (self._hc, self.goals) = self._hc, pending
            if old is not None:
                threading.Thread(target=old.close, daemon=True).start()
            self._t0 = t
            self.task_ticks = 0
            self.phase = Phase.RUNNING
            self.message = "running"
            switched = True
            self._event(
                t,
                "task started toward " + ", ".join(f"({g[0]:.3g}, {g[1]:.3g})" for g in self.goals),
            )
        if self._hc is not None and self._t0 is not None:
            cmd = self._hc.step(t - self._t0, xs)
            torque, policy, reference = cmd.torque, int(cmd.policy), cmd.reference
            self.task_ticks += 1
            if cmd.done and self.phase is Phase.RUNNING:
                self.phase = Phase.DONE
                finished = cmd.status.value
                self.message = finished
                self._event(t, f"task ended: {finished} after {t - self._t0:.2f} s")
        else:
            torque = self._balance(xs)
            p = position_state(self._hold, self.radius) if self._hold is not None else np.zeros(4)
            policy, reference = -1, np.r_[p[:2], 0.0, 0.0, 0.0, 0.0]
        if policy != self.policy:
            switched = True
            self.policy = policy
            if self.recorder is not None:
                name = self.library.policy(policy).name if (policy >= 0 and self.library) else None
                self.recorder.policy(self._log_time(t), policy, name=name)
        self.last_torque = np.asarray(torque, dtype=float)
        if self.recorder is not None and self.ticks % self.options.log_stride == 0:
            p = position_state(xs, self.radius)
            self.recorder.sample(
                self._log_time(t),
                run=0,
                run_time=t - (self._t0 if self._t0 is not None else t),
                position_state=p,
                lean=xs[2:4],
                lean_rate=xs[6:8],
                torque=self.last_torque,
                reference=reference,
                policy=policy,
                radius=self.radius,
            )
        self.ticks += 1
        return TickResult(self.last_torque, policy, np.asarray(reference), switched, finished)

    def _log_time(self, t: float | None = None) -> float:
        if self._log_origin is None:
            self._log_origin = 0.0 if t is None else t
        return self._log_origin if t is None else t

    def _event(self, t: float, message: str, level: str = "info") -> None:
        self.log(level, message)
        if self.recorder is not None:
            self.recorder.event(self._log_time(t), message, level=2 if level == "info" else 3)

    # -- bad input and silence ---------------------------------------------------------
    def reject(self, what: str, why: str, wall: float | None = None) -> None:
        """A reading or request dropped: one log line per reason every 2 s (wall)."""
        wall = time.monotonic() if wall is None else wall
        key = f"{what}: {why}"
        if wall - self._rejections.get(key, -np.inf) >= 2.0:
            self._rejections[key] = wall
            self.log("warn", f"{key}; dropped (holding the last command)")

    def watchdog(self, wall: float | None = None) -> str:
        """``"ok"``, ``"hold"`` (no valid state for ``state_timeout``: the last command
        is held) or ``"stop"`` (for ``stop_timeout``: zero torque, the task dropped);
        logs each change once."""
        wall = time.monotonic() if wall is None else wall
        if self.last_valid_wall is None:
            return "ok"
        quiet = wall - self.last_valid_wall
        if quiet >= self.options.stop_timeout and self.staleness != "stop":
            self.staleness = "stop"
            self.log(
                "error",
                f"no valid state reading for {quiet:.2f} s (stop_timeout "
                f"{self.options.stop_timeout:g} s): stopping, zero torque, task dropped",
            )
            hc, self._hc = self._hc, None
            if hc is not None:
                threading.Thread(target=hc.close, daemon=True).start()
            self._t0 = None
            self._hold = None
            self.last_torque = np.zeros(2)
            self.phase = Phase.STOPPED
            self.message = "stopped: no valid state"
        elif quiet >= self.options.state_timeout and self.staleness == "ok":
            self.staleness = "hold"
            self.log(
                "warn",
                f"no valid state reading for {quiet:.2f} s (state_timeout "
                f"{self.options.state_timeout:g} s): holding the last command",
            )
        return self.staleness

    def note_tick_time(self, seconds: float) -> None:
        """Record the wall time (s) a tick took from reading to command."""
        self._tick_sum += seconds
        self._tick_max = max(self._tick_max, seconds)

    def status(self, wall: float | None = None) -> dict[str, Any]:
        """The status the node publishes (JSON-ready)."""
        wall = time.monotonic() if wall is None else wall
        rate = 0.0
        if self.first_tick_wall is not None and wall > self.first_tick_wall:
            rate = self.ticks / (wall - self.first_tick_wall)
        return {
            "state": self.phase.value,
            "message": self.message,
            "policy": self.policy,
            "goals": [[float(g[0]), float(g[1])] for g in self.goals],
            "ticks": self.ticks,
            "task_ticks": self.task_ticks,
            "control_rate_hz": round(rate, 1),
            "tick_ms_mean": round(1000.0 * self._tick_sum / max(1, self.ticks), 3),
            "tick_ms_max": round(1000.0 * self._tick_max, 3),
            "staleness": self.staleness,
        }

    def status_json(self) -> str:
        """:meth:`status` as one line of JSON."""
        return json.dumps(self.status())

    def plan_rows(self) -> list[int]:
        """The library rows the running task plans to go through from the current
        policy to its goal (empty when unknown: no task, or a lazy tree)."""
        from gracenav.planning import PolicyTree

        hc = self._hc
        if hc is None or self.policy < 0 or not self.goals:
            return [self.policy] if self.policy >= 0 else []
        trees = [tr for tr in hc._trees.values() if isinstance(tr, PolicyTree)]
        for tree in trees:
            if tree.reachable(self.policy):
                return list(tree.path_from(self.policy))
        return [self.policy]

    def close(self) -> None:
        """Stop the running task's planning thread and finish the recording."""
        if self._hc is not None:
            self._hc.close()
        if self.recorder is not None:
            self.recorder.close()
