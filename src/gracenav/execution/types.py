"""What the hybrid controller says and is told: task statuses, switch events, its
options and the command it returns every tick."""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from gracenav.errors import ConfigError
from gracenav.planning.repair import ObstacleSensing
from gracenav.sim import SimulationOptions
from gracenav.sim.plant import PLANT_KINDS, PlantKind

__all__ = [
    "CAPTURE",
    "TERMINAL",
    "Command",
    "EventReason",
    "ExecutionOptions",
    "PlanningMode",
    "SwitchEvent",
    "TaskStatus",
]

FloatArray = NDArray[np.float64]

#: How computations longer than a tick relate to the ticks (:class:`ExecutionOptions`).
PlanningMode = Literal["instant", "threaded", "modelled"]

#: Policy index of the terminal regulator in :attr:`Episode.policy` and
#: :class:`SwitchEvent` (it is not a library row; −1 is balancing mode).
TERMINAL = -2
#: Policy index of a placed catch or shift (:mod:`gracenav.execution.capture`).
CAPTURE = -4


class EventReason(enum.Enum):
    """Why the hybrid controller started a policy."""

    START = "start"
    GRACEFUL = "graceful"
    NEW_GOAL = "new_goal"
    HOLD_GOAL = "hold_goal"
    DOMAIN_EXIT = "domain_exit"
    NOT_IN_GOAL = "not_in_goal"
    BALANCING = "balancing"
    RECOVERED = "recovered"
    TERMINAL = "terminal"
    """The goal is off the lattice: a capture regulator at the goal takes over from a
    rest trim whose G lies in its S (the reference steps to the goal)."""
    OBSTACLE = "obstacle"
    """A known moving obstacle blocked the running policy: switched away mid-policy."""
    BLOCKED = "blocked"
    """No unblocked way to the goal: an unblocked rest trim holds the robot."""
    RESUMED = "resumed"
    """The way cleared while holding: the task goes on."""
    CAPTURE = "capture"
    """No library policy's S contains the state: a catch placed at the state (and a
    shift) bring it onto a rest trim (:mod:`gracenav.execution.capture`)."""

    @property
    def graceful(self) -> bool:
        """Whether a switch for this reason keeps the motion graceful."""
        return self in (EventReason.GRACEFUL, EventReason.NEW_GOAL, EventReason.HOLD_GOAL)


class TaskStatus(enum.Enum):
    """How a task ended (:attr:`RUNNING` while it runs)."""

    RUNNING = "running"
    """The task has not ended (:attr:`Command.status` before ``done``)."""
    GOAL_REACHED = "goal_reached"
    LOOPS_COMPLETED = "loops_completed"
    NO_POLICY = "no_policy"
    TIMEOUT = "timeout"
    FELL = "fell"
    """The lean exceeded the fall limit (``SimulationOptions.fall_lean``)."""
    #: Consecutive policies ended without advancing time (e.g. every policy whose S
    #: contains the state leaves its D' at once): the task stops instead of looping.
    NO_PROGRESS = "no_progress"
    BLOCKED = "blocked"
    """Time ran out while moving obstacles blocked every way to the goal."""


@dataclass(frozen=True)
class SwitchEvent:
    """One entry of the hybrid controller's event log.

    Attributes
    ----------
    time : float
        Time of the switch (s).
    from_policy, to_policy : int
        Library rows (−1: none, i.e. the task start or balancing mode).
    reason : EventReason
    tick : int
        Sample index in the episode's arrays.
    """

    time: float
    from_policy: int
    to_policy: int
    reason: EventReason
    tick: int


@dataclass(frozen=True)
class ExecutionOptions:
    """Options of :class:`HybridController` runs.

    Parameters
    ----------
    plant : {"model3d", "mujoco"}
        Simulated plant of :meth:`HybridController.run` when it is given none.
    max_time : float
        Give up after this simulated time (s), even in the middle of a policy: a task
        never runs past it by more than one control tick.
    goal_tolerance : float
        A point-to-point task ends when, after the goal policy, the ball is within
        this distance (m) of the goal and slower than this speed (m/s); until then the
        goal rest trim is held (trims may last any time).
    balance_time : float
        Longest time (s) spent in balancing mode waiting for the state to enter some
        policy's start domain before the task stops.
    balance_chunk : float
        How often (s) balancing mode checks the start domains.
    resume_from_balancing : bool
        Resume the task from balancing mode once a start domain contains the state (a
        gracenav extension: the paper assumes 100 % coverage and stops the task).
    capture : bool
        When no library policy's start domain contains the state, place a verified
        catch at it (:mod:`gracenav.execution.capture`) before falling back to balancing mode,
        and start with one when none contains the start state.
    sensing : ObstacleSensing
        Range, period and margin of the moving-obstacle sensing (used only when a run
        has moving obstacles; :mod:`gracenav.planning.repair`).
    simulation : SimulationOptions
        Integration substeps and sensor noise of the simulated plant, and the fall
        limit (a lean beyond it ends the task with :attr:`TaskStatus.FELL`).
    planning : {"instant", "threaded", "modelled"}
        How computations longer than a tick (captures, repairs for moving obstacles,
        the next goal's tree) relate to the ticks. ``"instant"``: inside the
        :meth:`HybridController.step` that needs them, as if they took no time (the
        default: simulated episodes are deterministic). ``"threaded"``: on a worker
        thread while ``step`` goes on returning commands (for a robot: ``step`` never
        waits for a plan): the running policy goes on until a repair lands, and the
        robot follows the exited policy's reference (or holds its last point) until a
        capture lands, which is then used only if its start domain contains the state
        at that tick. ``"modelled"``: as ``"threaded"``, but each computation runs at
        once and lands ``planning_latency`` later in simulated time (the waiting of a
        robot, reproduced in simulation).
    planning_latency : float or None
        With ``"modelled"``: the latency (s) of every computation, or None for its own
        wall time on this machine (runs are then not reproducible).
    settle_tolerance : float
        While the last goal's terminal regulator (at a goal off the lattice) or the rest
        trim that ends at the goal holds the robot, the task ends at the first tick the
        ball, averaged over the last 0.125 s, is within this distance (m) of the goal
        (and within ``goal_tolerance``, whichever is smaller) and slower than
        ``goal_tolerance``, instead of at the end of that policy's run. Its reference is
        the goal at rest, and the robot balances about the goal with the same law after
        the end: the motion is the same, the task ends when the robot is there.
    skip_holds : bool
        Start the policy after a rest trim on the way (or the terminal after the goal's
        rest trim) as soon as its start domain holds the state, instead of holding the
        rest trim for its whole duration first; and leave a hold (the last stage of a
        capture, a capture regulator) for the policy after it once that policy's S
        holds the state with the lean within the still band it was verified from
        (:attr:`gracenav.policies.MotionPolicy.starts_from_still_band`), instead of at
        the hold's end (gracenav extensions; False runs every rest trim and hold to its
        end, as the paper does).
    set_aside_exits : int
        Plan the rest of the way to the current goal without a library policy once the
        robot has left its domain this many times in the task (a repair of the tree,
        logged as a replan ``policy_left``); 0 never does (a gracenav extension: a
        policy whose domains the sensor noise or the plant keeps leaving is otherwise
        started again after every capture).
    online_starts : bool
        At a start at rest that a capture or a capture regulator would take onto the
        lattice, design and verify one maneuver from the start onto a library policy
        ahead that starts at a cruise state and take it where it is priced lower (by
        what each way runs, less what ``online_ends`` saves on it)
        (:mod:`gracenav.execution.launch`; a gracenav extension: such a start plans and
        verifies up to four maneuvers on the 3D model in each of two searches (onto
        cruise trims, and onto any policy from a cruise state), each search a median
        2.7 s and up to about 10 s of wall time, then the chosen one from the still
        band, about 1.2 s, measured on the random pairs by ``bench/bench_starts.py``).
    online_ends : bool
        For a single goal at rest on the lattice, design and verify one maneuver from
        the end of a moving policy on the tree's way straight to rest at the goal, and
        take it when that policy ends where it is priced lower than the rest of the
        way (:mod:`gracenav.execution.arrival`; a gracenav extension: up to four
        maneuvers planned and verified on the 3D model for each way to start when the
        task starts, median 0.26 s and at most 1.6 s each on the random pairs,
        ``bench/bench_starts.py``).
    position_filter : bool
        Act on the ball position a steady-state Kalman filter estimates from the
        measured position and ball rates, tuned to the sensor noise ``simulation``
        states (:class:`gracenav.control.PositionEstimator`; with no position noise
        the measurement passes through unchanged). False acts on the raw measurement.
    """

    plant: PlantKind = "model3d"
    max_time: float = 120.0
    goal_tolerance: float = 0.05
    balance_time: float = 5.0
    balance_chunk: float = 0.125
    resume_from_balancing: bool = True
    capture: bool = True
    simulation: SimulationOptions = field(default_factory=SimulationOptions)
    sensing: ObstacleSensing = field(default_factory=ObstacleSensing)
    planning: PlanningMode = "instant"
    planning_latency: float | None = None
    settle_tolerance: float = 0.01
    skip_holds: bool = True
    set_aside_exits: int = 2
    online_starts: bool = True
    online_ends: bool = True
    position_filter: bool = True

    def __post_init__(self) -> None:
        if self.plant not in PLANT_KINDS:
            raise ConfigError(
                f"plant must be {' or '.join(map(repr, PLANT_KINDS))}, got {self.plant!r}"
            )
        if not self.max_time > 0:
            raise ConfigError(f"max_time must be positive, got {self.max_time!r}")
        if not self.goal_tolerance > 0:
            raise ConfigError(f"goal_tolerance must be positive, got {self.goal_tolerance!r}")
        if not self.settle_tolerance > 0:
            raise ConfigError(
                f"settle_tolerance must be positive (m), got {self.settle_tolerance!r}"
            )
        if self.planning not in ("instant", "threaded", "modelled"):
            raise ConfigError(
                f"planning must be 'instant', 'threaded' or 'modelled', got {self.planning!r}"
            )
        if self.planning_latency is not None and not (
            math.isfinite(self.planning_latency) and self.planning_latency >= 0.0
        ):
            raise ConfigError(
                f"planning_latency must be >= 0 (s) or None, got {self.planning_latency!r}"
            )
        if isinstance(self.set_aside_exits, bool) or not isinstance(self.set_aside_exits, int):
            raise ConfigError(f"set_aside_exits must be an int >= 0, got {self.set_aside_exits!r}")
        if self.set_aside_exits < 0:
            raise ConfigError(
                f"set_aside_exits must be >= 0 (0: never), got {self.set_aside_exits}"
            )


@dataclass(frozen=True, slots=True)
class Command:
    """What :meth:`HybridController.step` returns for one control tick.

    Attributes
    ----------
    torque : ndarray, shape (2,)
        Generalised torques (N m) on θ_x and θ_y, as :class:`gracenav.model.Ballbot3D`
        takes them, saturated at the controller's torque limit; hold them until the
        next tick.
    done : bool
        The task has ended (:attr:`status`); later commands keep the robot balancing
        where it ended (zero torque after a fall).
    status : TaskStatus
        :attr:`TaskStatus.RUNNING` until ``done``.
    policy : int
        Library row running (:data:`TERMINAL`, :data:`CAPTURE`, −1 balancing mode or a
        hold).
    reference : ndarray, shape (6,)
        Reference x, y, ẋ, ẏ, ẍ, ÿ (m, m/s, m/s²) of this tick, world frame.
    """

    torque: FloatArray
    done: bool
    status: TaskStatus
    policy: int
    reference: FloatArray
