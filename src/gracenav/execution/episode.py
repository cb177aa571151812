"""Episodes: a per-tick controller driving a plant, tick by tick, and the record.

:func:`drive` is the one loop of gracenav's simulations: at every control tick it
applies the disturbances due (state jumps, then pushes, as instantaneous changes of
the plant's state), hands the controller the measured state, records the true state
and the command, and advances the plant by one period with the command held and the
forces acting over it. It calls the controller's ``step`` only: the same controller
drives a robot from another loop.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import NDArray

from gracenav.errors import ConfigError
from gracenav.execution.capture import CapturePlan
from gracenav.execution.smoothness import JerkProfile, jerk_profile
from gracenav.execution.types import Command, EventReason, SwitchEvent, TaskStatus
from gracenav.params import BallbotParams
from gracenav.planning.repair import ReplanEvent
from gracenav.sim import BodyForce, Disturbance, Drag, Push, StateJump, position_state
from gracenav.sim.plant import DisturbablePlant, Plant
from gracenav.world.moving import MovingObstacle

if TYPE_CHECKING:
    from gracenav.execution.arrival import ArrivalPlan

__all__ = ["Episode", "ExecutionLog", "TickController", "Trace", "drive", "held_at"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class TickController(Protocol):
    """A controller :func:`drive` can run: one command per control tick."""

    def step(self, t: float, x: FloatArray, *, held: bool = False) -> Command:
        """The command for tick time ``t`` (s) and measured state ``x`` (8,)."""
        ...


@dataclass(frozen=True)
class ExecutionLog:
    """What a controller kept of one task, besides the samples."""

    events: tuple[SwitchEvent, ...]
    status: TaskStatus
    goals_reached: tuple[tuple[float, int], ...]
    tree_seconds: tuple[float, ...]
    replans: tuple[ReplanEvent, ...] = ()
    blocked_time: float = 0.0
    captures: tuple[tuple[float, CapturePlan], ...] = ()
    arrival: ArrivalPlan | None = None


@dataclass(frozen=True)
class Episode:
    """One simulated task execution.

    Attributes
    ----------
    time : ndarray, shape (N,)
        Control tick times (s).
    states : ndarray, shape (N, 8)
        Plant states.
    inputs : ndarray, shape (N, 2)
        Commanded (saturated) torques (N m).
    policy : ndarray of int, shape (N,)
        Library row executing at each tick (−1 in balancing mode).
    reference : ndarray, shape (N, 6)
        Reference x, y, ẋ, ẏ, ẍ, ÿ of the executing policy (world frame).
    events : tuple of SwitchEvent
    status : TaskStatus
    goals_reached : tuple of (float, int)
        Time and goal index of every goal reached (surveillance: several).
    tree_seconds : tuple of float
        Wall time of every single-goal tree computation (s).
    radius : float
        The plant's ball radius (m): :attr:`position_state` is where the robot truly
        is, which differs from what the controller believes (its nominal radius) when
        the plant's radius is not the nominal one.
    replans : tuple of ReplanEvent
        Every repair of the tree for moving obstacles, with its reason and latency.
    blocked_time : float
        Time (s) spent waiting (on a rest trim, or in balancing mode) while moving
        obstacles blocked every way to the goal.
    moving_obstacles : tuple of MovingObstacle
        The run's moving obstacles (their true motion), for checks and drawings.
    captures : tuple of (float, CapturePlan)
        Time and plan (placed catch and shift, rest trim) of every capture started
        (:data:`CAPTURE` in :attr:`policy`), for checks and drawings.
    arrival : ArrivalPlan or None
        The end maneuver designed when the task started
        (:mod:`gracenav.execution.arrival`), if any; while it runs, :attr:`policy` is
        :data:`CAPTURE` too.
    """

    time: FloatArray
    states: FloatArray
    inputs: FloatArray
    policy: IntArray
    reference: FloatArray
    events: tuple[SwitchEvent, ...]
    status: TaskStatus
    goals_reached: tuple[tuple[float, int], ...]
    tree_seconds: tuple[float, ...]
    radius: float
    replans: tuple[ReplanEvent, ...] = ()
    blocked_time: float = 0.0
    moving_obstacles: tuple[MovingObstacle, ...] = ()
    captures: tuple[tuple[float, CapturePlan], ...] = ()
    arrival: ArrivalPlan | None = None

    @classmethod
    def from_trace(
        cls, trace: Trace, log: ExecutionLog, moving_obstacles: Sequence[MovingObstacle] = ()
    ) -> Episode:
        """The episode of a :func:`drive` run: its samples and the controller's log."""
        return cls(
            time=trace.time,
            states=trace.states,
            inputs=trace.inputs,
            policy=trace.policy,
            reference=trace.reference,
            events=log.events,
            status=log.status,
            goals_reached=log.goals_reached,
            tree_seconds=log.tree_seconds,
            radius=trace.radius,
            replans=log.replans,
            blocked_time=log.blocked_time,
            moving_obstacles=tuple(moving_obstacles),
            captures=log.captures,
            arrival=log.arrival,
        )

    @property
    def position_state(self) -> FloatArray:
        """Ball [x, y, ẋ, ẏ] at each tick (m, m/s), shape (N, 4)."""
        return position_state(self.states, self.radius)

    @property
    def lean(self) -> FloatArray:
        """Body lean [φ_x, φ_y] (rad), shape (N, 2)."""
        return self.states[:, 2:4]

    @property
    def reached_goal(self) -> bool:
        """Whether the task ended at its goal (or completed its loops)."""
        return self.status in (TaskStatus.GOAL_REACHED, TaskStatus.LOOPS_COMPLETED)

    @property
    def path_length(self) -> float:
        """XY length of the ball's path (m)."""
        p = self.position_state[:, :2]
        return float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1)))

    @property
    def switches(self) -> int:
        """Number of policy switches (the first start excluded)."""
        return sum(1 for e in self.events if e.reason is not EventReason.START)

    @property
    def non_graceful_switches(self) -> int:
        """Switches forced by a disturbance (domain exit, not in G, balancing mode,
        recovery from it)."""
        return sum(
            1 for e in self.events if e.reason is not EventReason.START and not e.reason.graceful
        )

    @property
    def verified_recoveries(self) -> int:
        """Switches after a domain exit (or an end outside G) straight into a policy
        whose start domain contains the state: recoveries the method guarantees."""
        forced = (EventReason.DOMAIN_EXIT, EventReason.NOT_IN_GOAL)
        return sum(
            1
            for e in self.events
            if (e.reason in forced and e.to_policy >= 0) or e.reason is EventReason.CAPTURE
        )

    @property
    def balancing_time(self) -> float:
        """Time (s) spent in balancing mode, the unverified last resort."""
        if self.time.size < 2:
            return 0.0
        dt = np.diff(self.time)
        return float(np.sum(dt[self.policy[:-1] == -1]))

    def graceful_torque_jumps(self) -> FloatArray:
        """|Δτ| (N m) between the last tick of a policy and the first of its graceful
        successor, one per graceful switch."""
        ticks = [e.tick for e in self.events if e.reason.graceful and e.tick > 0]
        if not ticks:
            return np.zeros(0)
        t = np.asarray(ticks)
        return np.asarray(np.max(np.abs(self.inputs[t] - self.inputs[t - 1]), axis=1))

    def ball_jerk(self, params: BallbotParams | None = None) -> FloatArray:
        """Ball jerk magnitude (m/s³) between ticks, from the 3D model's accelerations
        (``params``: the plant's; default CMU ballbot), shape (N − 1,).

        A difference of accelerations over one control period: it reads every step of
        the held torque as Δa × the control rate, so it includes the chatter that
        measurement noise causes. The run summaries use :meth:`jerk_profile`."""
        from gracenav.model.ballbot3d import Ballbot3D

        model = Ballbot3D(params)
        acc = model.accelerations(self.states[:, :4], self.states[:, 4:], self.inputs)
        ball = self.radius * (acc[:, :2] + acc[:, 2:])
        dt = np.diff(self.time)
        return np.asarray(np.linalg.norm(np.diff(ball, axis=0), axis=1) / dt)

    def jerk_profile(self, breaks: Sequence[float] = ()) -> JerkProfile:
        """The ball's jerk from the true state: :mod:`gracenav.execution.smoothness`'s
        estimate from the plant's ball velocity, leaving out the ticks around each time
        in ``breaks`` (s; the pushes)."""
        return jerk_profile(self.time, self.position_state[:, 2:], breaks=breaks)


def held_at(disturbances: Sequence[Disturbance], t: float) -> bool:
    """Whether a force or drag acts at time ``t`` (s): the robot is held."""
    return any(
        isinstance(d, (BodyForce, Drag)) and d.start_time <= t < d.end_time for d in disturbances
    )


class _Schedule:
    """The disturbances by control tick: instantaneous ones at round(time / dt), forces
    and drags over the periods [round(start / dt), round(end / dt))."""

    def __init__(self, disturbances: Sequence[Disturbance], dt: float) -> None:
        self.disturbances = tuple(disturbances)
        self.jumps: dict[int, FloatArray] = {}
        self.kicks: dict[int, FloatArray] = {}
        self.changes: set[int] = set()
        self.forces: list[tuple[int, int, FloatArray]] = []
        self.drags: list[tuple[int, int, FloatArray, float]] = []
        self.dt = dt
        damping: float | None = None
        for d in self.disturbances:
            if isinstance(d, StateJump):
                delta = np.asarray(d.delta, dtype=float)
                if delta.shape != (8,):
                    raise ConfigError(f"StateJump.delta must have 8 entries, got {delta.shape}")
                n = self._tick(d.time, "state jump")
                self.jumps[n] = self.jumps.get(n, np.zeros(8)) + delta
            elif isinstance(d, Push):
                n = self._tick(d.time, "push")
                self.kicks[n] = self.kicks.get(n, np.zeros(2)) + np.asarray(d.impulse, dtype=float)
            elif isinstance(d, BodyForce):
                a, b = self._tick(d.start_time, "force start"), self._tick(d.end_time, "force end")
                self.forces.append((a, b, np.asarray(d.force, dtype=float)))
                self.changes.update((a, b))
            elif isinstance(d, Drag):
                if damping is not None and damping != d.damping:
                    raise ConfigError("all drags of one run must share the same damping")
                damping = d.damping
                a, b = self._tick(d.start_time, "drag start"), self._tick(d.end_time, "drag end")
                self.drags.append((a, b, np.asarray(d.velocity, dtype=float), d.damping))
                self.changes.update((a, b))
            else:  # pragma: no cover - typing guards this
                raise ConfigError(f"unknown disturbance {d!r}")

    def _tick(self, t: float, what: str) -> int:
        if not (np.isfinite(t) and t >= 0.0):
            raise ConfigError(f"{what} time must be finite and >= 0 s, got {t!r}")
        return round(t / self.dt)

    def forces_at(self, n: int) -> tuple[FloatArray, FloatArray, float]:
        """Force (2,), drag [active, vx, vy] and damping over the period from tick n."""
        f = np.zeros(2)
        drag = np.zeros(3)
        damping = 0.0
        for a, b, force in self.forces:
            if a <= n < b:
                f += force
        for a, b, vel, gain in self.drags:
            if a <= n < b:
                drag[0], drag[1:3], damping = 1.0, vel, gain
        return f, drag, damping


class _Buffer:
    """Growable per-tick arrays."""

    def __init__(self) -> None:
        self.n = 0
        self.t = np.zeros(4096)
        self.x = np.zeros((4096, 8))
        self.u = np.zeros((4096, 2))
        self.pol = np.zeros(4096, dtype=np.int64)
        self.ref = np.zeros((4096, 6))

    def add(self, t: float, x: FloatArray, cmd: Command) -> None:
        if self.n == self.t.shape[0]:
            for name in ("t", "x", "u", "pol", "ref"):
                a = getattr(self, name)
                setattr(self, name, np.concatenate([a, np.zeros_like(a)]))
        i = self.n
        self.t[i] = t
        self.x[i] = x
        self.u[i] = cmd.torque
        self.pol[i] = cmd.policy
        self.ref[i] = cmd.reference
        self.n += 1


@dataclass(frozen=True)
class Trace:
    """The samples :func:`drive` recorded: one a tick, and the final state (its input,
    policy and reference repeat the last tick's)."""

    time: FloatArray
    states: FloatArray
    inputs: FloatArray
    policy: IntArray
    reference: FloatArray
    radius: float


def drive(
    controller: TickController,
    plant: Plant,
    *,
    dt: float,
    max_ticks: int,
    disturbances: Sequence[Disturbance] = (),
) -> Trace:
    """Run ``controller`` on ``plant`` (already reset to the start state) from time 0
    until a command says ``done``.

    Parameters
    ----------
    controller : TickController
        Already reset for its task.
    plant : Plant
        A :class:`DisturbablePlant` when there are disturbances.
    dt : float
        Control period (s).
    max_ticks : int
        Guard: the controller's own time limit should end the run before; past this
        many ticks the run stops (RuntimeError, a controller that never ends).
    disturbances : sequence of Push, BodyForce, StateJump, Drag
        In run time.

    Returns
    -------
    Trace
    """
    sched = _Schedule(disturbances, dt)
    if sched.disturbances and not isinstance(plant, DisturbablePlant):
        raise ConfigError(
            f"{type(plant).__name__} takes no disturbances (it has no push, jump and "
            "set_force methods): run without them"
        )
    buf = _Buffer()
    last: Command | None = None
    for n in range(max_ticks + 1):
        if n in sched.jumps:
            plant.jump(sched.jumps[n])  # type: ignore[attr-defined]
        if n in sched.kicks:
            plant.push(sched.kicks[n])  # type: ignore[attr-defined]
        t = n * dt
        held = bool(sched.disturbances) and held_at(sched.disturbances, t)
        cmd = controller.step(t, plant.measure(), held=held)
        x = plant.state()
        if cmd.done:
            end = (
                last
                if last is not None
                else Command(np.zeros(2), True, cmd.status, -1, np.zeros(6))
            )
            buf.add(t, x, end)
            return Trace(
                buf.t[: buf.n].copy(),
                buf.x[: buf.n].copy(),
                buf.u[: buf.n].copy(),
                buf.pol[: buf.n].copy(),
                buf.ref[: buf.n].copy(),
                float(plant.ball_radius),
            )
        buf.add(t, x, cmd)
        last = cmd
        if sched.disturbances and (n in sched.changes or n == 0):
            f, drag, damping = sched.forces_at(n)
            plant.set_force(f, drag, damping)  # type: ignore[attr-defined]
        plant.advance(cmd.torque, dt)
    raise RuntimeError(f"the controller did not end its task within {max_ticks} ticks")
