"""The hybrid controller (paper Sec. IV-C, V-B): execute and switch motion policies.

A timer is reset when a policy starts; a policy starts only if the position
state is in its start domain S; it runs until the timer reaches t_f and the
state is in its goal domain G, then the tree's next policy takes over (G ⊂ S
of the next by construction: a graceful switch). Every control tick the state
is checked against the outer domain D'(t); on exit (a large disturbance) the
current policy stops and the policy with the lowest cost-to-go whose S
contains the state starts, without replanning. If there is none, the robot
switches to balancing (station-keeping) mode and the task stops: the only
non-graceful switches are these recoveries.
"""

from __future__ import annotations

import enum
import math
import time as _time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.capture import CapturePlan, PlacedPolicy, capture_for
from gracenav.domains import EllipsoidalDomain
from gracenav.errors import ConfigError, PlanningError
from gracenav.graph import PreparesGraph
from gracenav.library import PolicyLibrary, quarter_turn
from gracenav.params import BallbotParams
from gracenav.planning import CostCriterion, LazyPolicyTree, PolicyTree, plan_tree
from gracenav.policies import PrimitiveKind, flat_position_state, instantiated_reference
from gracenav.replanning import HOLD_MARGIN, ObstacleSensing, ObstacleTracker, ReplanEvent
from gracenav.simulate import (
    BodyForce,
    Disturbance,
    Drag,
    Push,
    Reference,
    SimulationOptions,
    SimulationResult,
    StateJump,
    StopReason,
    position_state,
    simulate,
)
from gracenav.world.moving import MovingObstacle

__all__ = [
    "CAPTURE",
    "TERMINAL",
    "Episode",
    "EventReason",
    "ExecutionOptions",
    "HybridController",
    "SwitchEvent",
    "TaskStatus",
    "TerminalPolicy",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


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
    shift) bring it onto a rest trim (:mod:`gracenav.capture`)."""

    @property
    def graceful(self) -> bool:
        """Whether a switch for this reason keeps the motion graceful."""
        return self in (EventReason.GRACEFUL, EventReason.NEW_GOAL, EventReason.HOLD_GOAL)


class TaskStatus(enum.Enum):
    """How a task ended."""

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
        Simulated plant.
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
        catch at it (:mod:`gracenav.capture`) before falling back to balancing mode,
        and start with one when none contains the start state.
    sensing : ObstacleSensing
        Range, period and margin of the moving-obstacle sensing (used only when a run
        has moving obstacles; :mod:`gracenav.replanning`).
    simulation : SimulationOptions
        Integration substeps, sensor noise and the fall limit (a fall ends the task
        with :attr:`TaskStatus.FELL`).
    """

    plant: Literal["model3d", "mujoco"] = "model3d"
    max_time: float = 120.0
    goal_tolerance: float = 0.05
    balance_time: float = 5.0
    balance_chunk: float = 0.125
    resume_from_balancing: bool = True
    capture: bool = True
    simulation: SimulationOptions = field(default_factory=SimulationOptions)
    sensing: ObstacleSensing = field(default_factory=ObstacleSensing)

    def __post_init__(self) -> None:
        if self.plant not in ("model3d", "mujoco"):
            raise ConfigError(f"plant must be 'model3d' or 'mujoco', got {self.plant!r}")
        if not self.max_time > 0:
            raise ConfigError(f"max_time must be positive, got {self.max_time!r}")
        if not self.goal_tolerance > 0:
            raise ConfigError(f"goal_tolerance must be positive, got {self.goal_tolerance!r}")


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
        (``params``: the plant's; default CMU ballbot), shape (N − 1,)."""
        from gracenav.model.ballbot3d import Ballbot3D

        model = Ballbot3D(params)
        acc = model.accelerations(self.states[:, :4], self.states[:, 4:], self.inputs)
        ball = self.radius * (acc[:, :2] + acc[:, 2:])
        dt = np.diff(self.time)
        return np.asarray(np.linalg.norm(np.diff(ball, axis=0), axis=1) / dt)


#: Policies in a row that may end at their first tick (an instantaneous disturbance at
#: a switch can do that once) before the task stops with TaskStatus.NO_PROGRESS.
_MAX_STALLED_SEGMENTS = 8

#: Clearance (m) beyond the footprint that balancing mode keeps on its way to the
#: point it holds (see HybridController._recovery_point).
_BALANCING_MARGIN = 0.05
#: Nearest rest-trim starts balancing mode considers as the point to hold.
_BALANCING_SEARCH = 64
#: Most policies a lazy tree closes to find where balancing mode holds the robot.
_LAZY_RECOVERY_BUDGET = 200_000

#: Distance (m, m/s) within which a goal counts as the end state of a lattice trim.
_ON_LATTICE = 1e-9

#: Policy index of the terminal regulator in :attr:`Episode.policy` and
#: :class:`SwitchEvent` (it is not a library row; −1 is balancing mode).
TERMINAL = -2
#: Policy index of a placed catch or shift (:mod:`gracenav.capture`).
CAPTURE = -4


@dataclass(frozen=True)
class TerminalPolicy(PlacedPolicy):
    """A capture regulator of the palette placed at a goal off the lattice: a
    :class:`~gracenav.capture.PlacedPolicy` at heading 0 whose reference starts (and
    holds) at the goal.

    Attributes
    ----------
    approach : int
        The library rest trim the task reaches first; its G lies in this S.
    """

    approach: int

    @property
    def goal_xy(self) -> NDArray[np.float64]:
        """Where it holds the robot (m)."""
        return self.start_xy

    def outer_domain(self, t: float) -> EllipsoidalDomain:
        """D'(t) in the world frame."""
        return self._world(self.policy.outer_domain(t))

    @property
    def name(self) -> str:
        """E.g. ``regulate[ep=0.55m]@(1.23, 2.5)``."""
        x, y = self.goal_xy
        return f"{self.policy.name}@({x:g}, {y:g})"


def _segment_disturbances(
    disturbances: Sequence[Disturbance], t0: float, dt: float, nt: int, applied: set[int]
) -> tuple[list[Disturbance], list[int]]:
    """The disturbances of the window [t0, t0 + nt·dt] in local time; instantaneous ones
    already applied (``applied``: indices) are skipped. Returns them and the indices of
    the instantaneous ones included."""
    out: list[Disturbance] = []
    inst: list[int] = []
    t1 = t0 + nt * dt
    for i, d in enumerate(disturbances):
        if isinstance(d, (Push, StateJump)):
            if i in applied or not (t0 - 0.5 * dt <= d.time <= t1 + 0.5 * dt):
                continue
            out.append(replace(d, time=max(0.0, d.time - t0)))
            inst.append(i)
        elif isinstance(d, (BodyForce, Drag)):
            a, b = max(d.start_time, t0), min(d.end_time, t1)
            if b - a > 0.5 * dt:
                out.append(replace(d, start_time=a - t0, end_time=b - t0))
    return out, inst


class _Recorder:
    """Concatenates the samples of consecutive segments (policies or balancing chunks).

    A segment's last sample is the next segment's first (same time and state), so only
    samples [0, last) of each are kept; :meth:`arrays` appends the final state.
    """

    def __init__(self) -> None:
        self.t: list[FloatArray] = []
        self.x: list[FloatArray] = []
        self.u: list[FloatArray] = []
        self.pol: list[IntArray] = []
        self.ref: list[FloatArray] = []

    def add(self, t0: float, res: SimulationResult, policy: int, ref: FloatArray) -> None:
        n = res.states.shape[0] - 1
        self.t.append(t0 + res.time[:n])
        self.x.append(res.states[:n])
        self.u.append(res.inputs[:n])
        self.pol.append(np.full(n, policy, dtype=np.int64))
        self.ref.append(ref[:n])

    def arrays(
        self, t: float, x: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, IntArray, FloatArray]:
        """time, states, inputs, policy, reference with the final state appended (its
        input, policy and reference repeat the last sample's)."""
        last = next((i for i in range(len(self.u) - 1, -1, -1) if self.u[i].size), None)
        u_end = self.u[last][-1:] if last is not None else np.zeros((1, 2))
        pol_end = self.pol[last][-1:] if last is not None else np.array([-1], dtype=np.int64)
        ref_end = self.ref[last][-1:] if last is not None else np.zeros((1, 6))
        return (
            np.concatenate([*self.t, [t]]),
            np.concatenate([*self.x, x[None, :]]),
            np.concatenate([*self.u, u_end]),
            np.concatenate([*self.pol, pol_end]),
            np.concatenate([*self.ref, ref_end]),
        )


def _disturbed(disturbances: Sequence[Disturbance], t: float) -> bool:
    """Whether a force or drag acts at time ``t`` (the robot is still held)."""
    return any(
        isinstance(d, (BodyForce, Drag)) and d.start_time <= t < d.end_time for d in disturbances
    )


class HybridController:
    """Executes navigation tasks with a policy library, its graph and single-goal trees.

    Parameters
    ----------
    library : PolicyLibrary
    graph : PreparesGraph
    criterion : {"time", "distance"}
        Optimality criterion of the trees.
    params : BallbotParams, optional
        Parameters of the simulated plant (default: the palette's). They may differ
        from the controller's nominal parameters (model mismatch): every decision of
        the hybrid controller (domain membership, references, the goal test) uses the
        position state the controller *measures*, from the encoder angles and its
        nominal ball radius, exactly as the compiled closed loop monitors D'(t).
    """

    def __init__(
        self,
        library: PolicyLibrary,
        graph: PreparesGraph,
        *,
        criterion: CostCriterion | str = CostCriterion.TIME,
        params: BallbotParams | None = None,
    ) -> None:
        self.library = library
        self.graph = graph
        self.criterion = CostCriterion(criterion) if isinstance(criterion, str) else criterion
        self.palette = library.palette
        self.gains = self.palette.gains
        self.params = params if params is not None else self.palette.params
        self._adjacency = graph.search_form(self.criterion.value)
        self._trees: dict[int, PolicyTree | LazyPolicyTree] = {}
        self._last_goal = -1  # the goal policy of the last tree asked for
        # Terminal regulators depend on the library and the goal only: shared by every
        # controller on the same library (a scenario's runs, a campaign's trials).
        self._terminals: dict[tuple[float, ...], tuple[TerminalPolicy, ...]] = (
            library._cache.setdefault("terminal_policies", {})
        )
        self.tree_seconds: list[float] = []

    # -- planning ------------------------------------------------------------------
    def goal_policy(self, goal: ArrayLike) -> int:
        """The closest trim policy (Euclidean, to its G's centre; the shortest of equally
        close ones) whose G contains ``goal``; for a goal at rest that no trim's G
        contains, the rest trim the task ends on before the terminal regulator at the
        goal takes over (:meth:`terminal_policies`).

        Raises
        ------
        PlanningError
            If the goal is outside the map, in an obstacle (grown by the footprint), or
            no trim policy's goal domain contains it and no terminal regulator fits
            there (outside coverage).
        """
        g = np.asarray(goal, dtype=float)
        if g.shape != (4,) or not np.all(np.isfinite(g)):
            raise ConfigError(f"a goal is a position state (x, y, xdot, ydot), got {goal!r}")
        wm = self.library.world_map
        (x0, y0), (x1, y1) = wm.bounds
        if not (x0 <= g[0] <= x1 and y0 <= g[1] <= y1):
            raise PlanningError(
                f"goal ({g[0]:g}, {g[1]:g}) is outside the map [{x0:g}, {x1:g}] × [{y0:g}, {y1:g}]"
            )
        if float(wm.clearance(g[None, :2])[0]) < self.library.footprint_radius:
            raise PlanningError(
                f"goal ({g[0]:g}, {g[1]:g}) is inside an obstacle or closer to one than the "
                f"robot's footprint radius {self.library.footprint_radius:g} m"
            )
        trims = self.library.trim_indices()
        ends = self.library.end_state[trims]
        candidates = []
        # Nearest first; among equally near trims (a rest trim and the longer capture
        # trim end at the same state) the shortest, so a task does not end on a hold
        # longer than it needs.
        order = np.lexsort((self.library.durations[trims], np.linalg.norm(ends - g, axis=1)))
        near = trims[order][:64]
        inside = np.flatnonzero(self._goal_domains_contain(near, g))
        if inside.size:
            candidates.append(int(near[inside[0]]))
        at_rest = bool(np.all(g[2:] == 0.0))
        exact = bool(candidates) and bool(
            np.linalg.norm(self.library.end_state[candidates[0]] - g) <= _ON_LATTICE
        )
        if candidates and (exact or not at_rest):
            return candidates[0]
        # A goal at rest off the lattice: a terminal regulator brings the robot onto it;
        # without one, the trim whose G contains it (within G's extent of the goal).
        terminals = self.terminal_policies(g) if at_rest else ()
        if terminals:
            return terminals[0].approach
        if candidates:
            return candidates[0]
        where = ", ".join(f"{v:g}" for v in g)
        if np.all(g[2:] == 0.0):
            raise PlanningError(
                f"goal ({where}) is outside coverage: no trim policy of the library has it in "
                "its goal domain and no capture regulator fits there (it needs a clearance of "
                "the footprint plus its outer domain radius, and a rest trim of the library "
                "within its start domain); move the goal away from obstacles or use more "
                "lattice halvings"
            )
        raise PlanningError(
            f"goal ({where}) is outside coverage: a moving goal must be a cruise trim of the "
            "library (on the instantiation lattice, at a trim velocity, away from obstacles)"
        )

    def _goal_domains_contain(self, rows: IntArray, g: FloatArray) -> BoolArray:
        """Whether G of each library row in ``rows`` contains the position state ``g``:
        ``g`` taken into each policy's own frame and tested against its G there (the
        same ellipsoid as the world-frame G, rotated by a quarter turn), vectorised."""
        lib = self.library
        out = np.zeros(rows.shape, dtype=bool)
        for p in np.unique(lib.palette_index[rows]):
            sel = np.flatnonzero(lib.palette_index[rows] == p)
            pol = self.palette.policies[int(p)]
            local = pol.domain(pol.duration)
            r = rows[sel]
            q = np.empty((r.size, 4))
            for k in range(4):  # world -> policy frame: rotate by -k quarter turns
                m = lib.orientation[r] == k
                if np.any(m):
                    rt = quarter_turn(k).T
                    q[m, :2] = (g[:2] - lib.start_xy[r[m]]) @ rt.T
                    q[m, 2:] = g[2:] @ rt.T
            out[sel] = local.contains(q)
        return out

    def _terminal(self, goal: ArrayLike, goal_id: int) -> TerminalPolicy | None:
        """The terminal regulator a task toward ``goal`` ends with, if ``goal_id`` is the
        approach trim :meth:`goal_policy` chose for it."""
        terms = self._terminals.get(tuple(float(v) for v in np.asarray(goal, dtype=float)))
        for term in terms or ():
            if term.approach == goal_id:
                return term
        return None

    def terminal_policies(self, goal: ArrayLike) -> tuple[TerminalPolicy, ...]:
        """Terminal regulators for a goal at rest off the lattice, best first.

        For each capture regulator of the palette, largest first, whose outer domain
        (a disc of radius ``outer_factors[0]`` × e_p(S) around the goal, not shrinking)
        grown by the footprint is clear of obstacles: every rest trim of the library
        whose G lies in the regulator's S at the goal (exact ellipsoid containment),
        nearest first. Empty when the palette has no regulators or none fits.
        """
        g = np.asarray(goal, dtype=float)
        key = tuple(float(v) for v in g)
        got = self._terminals.get(key)
        if got is not None:
            return got
        lib = self.library
        clearance = float(lib.world_map.clearance(g[None, :2])[0]) - lib.footprint_radius
        rest = lib.trim_indices(PrimitiveKind.REST)
        out: list[TerminalPolicy] = []
        regs = sorted(
            (p for p in self.palette.policies if p.capture),
            key=lambda p: -p.start_radii.position,
        )
        for reg in regs:
            reach = reg.outer_factors[0] * reg.start_radii.position
            if clearance < reach:
                continue
            ends = lib.end_state[rest]
            dist = np.linalg.norm(ends[:, :2] - g[:2], axis=1)
            near = np.flatnonzero(dist <= reg.start_radii.position)
            near = near[np.lexsort((lib.durations[rest[near]], dist[near]))]
            for i in rest[near]:
                term = TerminalPolicy(reg, 0.0, g[:2].copy(), int(i))
                if term.start_domain.contains_domain(lib.policy(int(i)).goal_domain):
                    out.append(term)
            if out:
                break
        result = tuple(out)
        self._terminals[key] = result
        return result

    def tree(self, goal_policy: int) -> PolicyTree | LazyPolicyTree:
        """The single-goal optimal tree toward library row ``goal_policy`` (cached).

        The whole tree (:func:`plan_tree`) when the graph keeps its reversed graph
        (:meth:`PreparesGraph.search_form`, up to :data:`gracenav.graph.STORED_EDGES`
        edges); above that, a :class:`LazyPolicyTree` that :meth:`best_policy` and
        :meth:`_recovery_point` settle where they read it (a whole tree there takes
        tens of seconds); its entry in :attr:`tree_seconds` is its allocation, the
        search runs as it is read. A lazy tree is settled at the goal policy of the tree
        asked for before (if it is another): a surveillance task reads the next goal's
        tree at the previous goal policy.
        """
        tree = self._trees.get(goal_policy)
        if tree is None:
            t0 = _time.perf_counter()
            if self._adjacency is self.graph:
                tree = LazyPolicyTree(self.graph, goal_policy, criterion=self.criterion)
            else:
                tree = plan_tree(self._adjacency, goal_policy, criterion=self.criterion)
            self.tree_seconds.append(_time.perf_counter() - t0)
            self._trees[goal_policy] = tree
        if isinstance(tree, LazyPolicyTree) and self._last_goal not in (-1, goal_policy):
            tree.settle([self._last_goal])
        self._last_goal = goal_policy
        return tree

    def _recovery_point(
        self,
        p: FloatArray,
        tree: PolicyTree | LazyPolicyTree,
        dyn: ObstacleTracker | None = None,
    ) -> FloatArray:
        """Where balancing mode holds the robot: the start of the nearest rest trim of
        the library that reaches the goal and that the robot can be driven to without
        driving toward an obstacle: along the straight segment from the robot to it
        (sampled every map cell) the clearance stays at least the footprint plus
        :data:`_BALANCING_MARGIN`, or the robot's own clearance if that is smaller. The
        current position if none of the :data:`_BALANCING_SEARCH` nearest qualifies.
        With moving obstacles (``dyn``), a point or a segment a known obstacle may reach
        within :data:`gracenav.replanning.HOLD_HORIZON` is not a candidate either, and
        when they block the way every unblocked rest trim is a candidate.

        On a lazy tree, "reaches the goal" is what the search knows: it is settled (at
        most :data:`_LAZY_RECOVERY_BUDGET` more policies closed) until the cheapest of
        the :data:`_BALANCING_SEARCH` nearest rest trims is closed, and every rest trim
        with a path to the goal found so far (closed or open) is a candidate; one the
        search has not met yet is not."""
        here = np.asarray(p[:2], dtype=float)
        all_rest = self.library.trim_indices(PrimitiveKind.REST)
        if isinstance(tree, LazyPolicyTree):
            near = np.argsort(np.linalg.norm(self.library.start_xy[all_rest] - here, axis=1))
            tree.settle(all_rest[near[:_BALANCING_SEARCH]], best=True, budget=_LAZY_RECOVERY_BUDGET)
            reaches = tree.reached(all_rest)
        else:
            reaches = np.isfinite(tree.cost_to_go[all_rest])
        passes = [all_rest[reaches | (all_rest == tree.goal)]]
        if dyn is not None and np.any(dyn.blocked):
            # The way is blocked: any free rest trim will do to wait for it to clear.
            passes.append(all_rest[~dyn.blocked[all_rest]])
        wm = self.library.world_map
        # A robot already nearer than that to an obstacle may not get any nearer.
        need = min(
            self.library.footprint_radius + _BALANCING_MARGIN,
            float(wm.clearance(here[None, :])[0]),
        )
        step = float(wm.resolution)
        for rest in passes:
            xy = self.library.start_xy[rest]
            if dyn is not None:  # only points clear of the obstacles' predicted motion
                xy = xy[dyn.points_clear(xy, _BALANCING_MARGIN + HOLD_MARGIN)]
            order = np.argsort(np.linalg.norm(xy - here, axis=1), kind="stable")
            for q in xy[order[:_BALANCING_SEARCH]]:
                n = max(2, int(np.ceil(np.linalg.norm(q - here) / step)) + 1)
                seg = here + np.linspace(0.0, 1.0, n)[:, None] * (q - here)
                if np.all(wm.clearance(seg[1:]) >= need) and (
                    dyn is None or dyn.path_clear(here, seg[1:], _BALANCING_MARGIN + HOLD_MARGIN)
                ):
                    return np.asarray(q, dtype=float)
        return here

    def capture_plan(self, x: ArrayLike, tree: PolicyTree | LazyPolicyTree) -> CapturePlan | None:
        """The cheapest verified capture (catch, shift, rest trim toward the tree's goal)
        of the model state ``x`` (8,), or None (see :class:`gracenav.capture.Capture`).
        Settled and still catches are considered when the lean and lean rate (norms
        over both axes) are within their band of upright; the pushed ones test the
        flat output's position state (catches start upright)."""
        capture = capture_for(self.library)
        xs = np.asarray(x, dtype=float)
        p = position_state(xs, self.params.ball_radius)
        flat = flat_position_state(p, xs[2:4], xs[6:8], self.params)
        deviation = (float(np.hypot(*xs[2:4])), float(np.hypot(*xs[6:8])))
        settle = None
        if isinstance(tree, LazyPolicyTree):  # close the cheapest of the rows asked for
            lazy = tree

            def settle(rows: IntArray) -> None:
                lazy.settle(rows, best=True, budget=_LAZY_RECOVERY_BUDGET)

        return capture.plan(
            p,
            lean_deviation=deviation,
            cost_to_go=tree.cost_to_go,
            settle=settle,
            flat_state=flat,
        )

    def best_policy(self, p: ArrayLike, tree: PolicyTree | LazyPolicyTree) -> int:
        """The policy with the lowest cost-to-go whose S contains ``p`` (−1 if none).

        Capture regulators are candidates only when no other policy that reaches the
        goal contains ``p``: they catch a robot the navigation policies cannot. A lazy
        tree is settled until the cheapest of the other policies (of the regulators if
        only they contain ``p``) is closed, with its ties: the same choice as the whole
        tree's (a whole search if none of them reaches the goal)."""
        hits = self.library.start_domain_contains(np.asarray(p, dtype=float)[None, :])
        idx = hits.indices[hits.indptr[0] : hits.indptr[1]]
        if idx.size == 0:
            return -1
        capture = self.library.types.is_capture[self.library.type_index[idx]]
        if isinstance(tree, LazyPolicyTree):
            tree.settle(idx[~capture] if np.any(~capture) else idx, best=True)
        cost = tree.cost_to_go[idx]
        ok = np.isfinite(cost)
        if not np.any(ok):
            return -1
        if np.any(ok & ~capture):
            cost = np.where(capture, np.inf, cost)
        return int(idx[int(np.argmin(cost))])

    # -- execution -----------------------------------------------------------------
    def run(
        self,
        x0: ArrayLike,
        goals: Sequence[ArrayLike],
        *,
        loops: int = 1,
        disturbances: Sequence[Disturbance] = (),
        options: ExecutionOptions | None = None,
        moving_obstacles: Sequence[MovingObstacle] = (),
    ) -> Episode:
        """Execute a task: reach ``goals`` in order, ``loops`` times (surveillance), or
        one goal once (point-to-point).

        Parameters
        ----------
        x0 : array_like, shape (8,)
            Initial plant state.
        goals : sequence of array_like, shape (4,)
            Goal position states (x, y, ẋ, ẏ): rest goals for point-to-point, moving
            goals (cruise velocities) for surveillance.
        loops : int
            How many times to go through ``goals``.
        disturbances : sequence of Push, BodyForce, StateJump, Drag
            In episode time.
        options : ExecutionOptions, optional
        moving_obstacles : sequence of MovingObstacle
            Obstacles not in the map, which the controller learns of within its sensing
            range (``options.sensing``): it then blocks the policies they may meet,
            repairs the tree every sensing period, switches away from a policy that
            becomes blocked while it runs, and holds an unblocked rest trim while no
            way to the goal is free (:mod:`gracenav.replanning`).

        Raises
        ------
        PlanningError
            A goal is impossible, or the first goal is unreachable from the start.
        """
        options = options if options is not None else ExecutionOptions()
        if loops < 1:
            raise ConfigError(f"loops must be >= 1, got {loops!r}")
        if len(goals) == 0:
            raise ConfigError("a task needs at least one goal")
        goal_ids = [self.goal_policy(g) for g in goals]
        terminals: list[TerminalPolicy | None] = [
            self._terminal(g, i) for g, i in zip(goals, goal_ids, strict=True)
        ]
        dt = 1.0 / 1024.0
        r = self.gains.params.ball_radius  # the controller's (measured) position states
        x = np.asarray(x0, dtype=float).copy()
        p = position_state(x, r)
        tree = self.tree(goal_ids[0])
        current = self.best_policy(p, tree)
        if current < 0 and len(goals) == 1:
            # The goal's trim may lie on a sub-lattice the start cannot reach (maneuvers
            # move by whole multiples of d): approach it through another rest trim whose
            # G lies in a terminal regulator at the goal.
            for cand in self.terminal_policies(goals[0]):
                tree = self.tree(cand.approach)
                current = self.best_policy(p, tree)
                if current >= 0:
                    goal_ids, terminals = [cand.approach], [cand]
                    break
            else:
                tree = self.tree(goal_ids[0])
        dyn = (
            ObstacleTracker(self.library, self.graph, moving_obstacles, options.sensing)
            if moving_obstacles
            else None
        )
        holding = False
        blocked_time = 0.0
        if dyn is not None and current >= 0:
            tree = dyn.update(0.0, p[:2], tree)
            current = self.best_policy(p, tree)
            if current < 0:
                current = dyn.hold_policy(p)
                holding = current >= 0
        sequence = goal_ids * loops
        terminal_seq = terminals * loops
        goal_states = [np.asarray(g, dtype=float) for g in goals] * loops
        k_goal = 0
        captured: list[PlacedPolicy] = []  # placed catch and shifts still to run
        capture_plans: list[tuple[float, CapturePlan]] = []
        capture_row = -1  # the rest trim a capture ends on
        if current < 0 and options.capture and dyn is None:
            # A start inside no library S may lie in a catch's (coverage counts it).
            plan = self.capture_plan(x, tree)
            if plan is not None:
                capture_plans.append((0.0, plan))
                captured, capture_row = list(plan.policies), plan.rest_row
                current = CAPTURE
        if current < 0 and not captured:
            hits = self.library.start_domain_contains(p[None, :])
            why = (
                "no library policy's start domain contains the start state, and no catch "
                "placed there clears the obstacles (outside coverage)"
                if hits.nnz == 0
                else "the goal cannot be reached from any policy whose start domain contains it"
            )
            where = ", ".join(f"{v:.3g}" for v in p)
            raise PlanningError(f"start ({where}): {why}")
        record = _Recorder()
        events = [SwitchEvent(0.0, -1, current, EventReason.START, 0)]
        goals_reached: list[tuple[float, int]] = []
        applied: set[int] = set()
        t = 0.0
        ticks = 0
        max_ticks = max(1, math.ceil(options.max_time / dt - 1e-9))
        stalled = 0  # consecutive policies that ended at their first tick
        status = TaskStatus.TIMEOUT
        offset = 0  # ticks of the current policy already run (moving obstacles)
        while ticks < max_ticks:
            term = terminal_seq[k_goal]
            if current == CAPTURE or (current == TERMINAL and term is not None):
                placed = captured[0] if current == CAPTURE else term
                assert placed is not None
                prim = placed.primitive
                ref, ref_pos = placed.reference(r)
                _, shapes = placed.outer_monitor()
                is_goal = False
            else:
                inst = self.library.policy(current)
                prim = inst.policy.primitive
                ref, ref_pos = instantiated_reference(prim, inst.orientation, inst.start_xy, r)
                # Domain shapes are invariant under rotations of the plane: only the
                # centres move with the instantiation.
                _, shapes = inst.policy.outer_monitor()
                is_goal = current == sequence[k_goal]
            if is_goal and k_goal + 1 < len(sequence):
                # Regenerate the tree for the next goal while the last policy to the
                # current goal runs (paper Sec. V-C).
                self.tree(sequence[k_goal + 1])
            remaining = prim.num_ticks - offset
            n_seg = min(remaining, max_ticks - ticks)
            truncated = n_seg < remaining
            split = False  # the segment ends at the next look at the moving obstacles
            if dyn is not None and dyn.ticks_to_next(t, dt) < n_seg:
                n_seg, split, truncated = dyn.ticks_to_next(t, dt), True, False
            if offset or n_seg < prim.num_ticks:  # run ticks offset .. offset + n_seg only
                part = slice(offset, offset + n_seg + 1)
                ref = Reference(ref.states[part], ref.inputs[part], ref.dt)
                ref_pos, shapes = ref_pos[part], shapes[part]
            local, inst_idx = _segment_disturbances(disturbances, t, dt, n_seg, applied)
            res = simulate(
                x,
                ref,
                self.gains,
                params=self.params,
                plant=options.plant,
                disturbances=local,
                options=options.simulation,
                monitor=(np.ascontiguousarray(ref_pos[:, :4]), shapes),
                stop_on_exit=True,
            )
            last = res.states.shape[0] - 1
            for i in inst_idx:
                if round((disturbances[i].time - t) / dt) <= last:  # type: ignore[union-attr]
                    applied.add(i)
            record.add(t, res, current, ref_pos)
            t += last * dt
            ticks += last
            if holding:
                blocked_time += last * dt
            x = res.states[-1].copy()
            p = position_state(x, r)
            if res.stop_reason is StopReason.FELL:
                status = TaskStatus.FELL
                break
            if truncated and res.stop_reason is StopReason.COMPLETED:
                status = TaskStatus.BLOCKED if holding else TaskStatus.TIMEOUT
                break
            stalled = stalled + 1 if last == 0 else 0
            if stalled > _MAX_STALLED_SEGMENTS:
                status = TaskStatus.NO_PROGRESS
                break
            if dyn is not None:
                if dyn.due(t):
                    tree = dyn.update(t, p[:2], tree)
                if holding:
                    free_row = self.best_policy(p, tree)
                    if free_row >= 0:  # the way is free again
                        events.append(SwitchEvent(t, current, free_row, EventReason.RESUMED, ticks))
                        current, offset, holding = free_row, 0, False
                        continue
                if split and res.stop_reason is StopReason.COMPLETED:
                    offset += last
                    blocked_now = (
                        bool(dyn.known)
                        if current == CAPTURE
                        else dyn.disc_blocked(
                            term.goal_xy,
                            float(term.policy.outer_extents(0.0)[0]),
                            term.policy.duration,
                        )
                        if current == TERMINAL and term is not None
                        else dyn.is_blocked(current)
                        or (holding and not dyn.hold_row_clear(current))
                    )
                    if not blocked_now:
                        continue  # the same policy goes on
                    offset = 0
                    nxt = self.best_policy(p, tree)
                    if nxt >= 0:
                        events.append(SwitchEvent(t, current, nxt, EventReason.OBSTACLE, ticks))
                        current, holding = nxt, False
                        continue
                    wait_row = dyn.hold_policy(p)
                    if wait_row >= 0:
                        events.append(SwitchEvent(t, current, wait_row, EventReason.BLOCKED, ticks))
                        current, holding = wait_row, True
                        continue
                    # Nothing unblocked contains the state: balancing mode below.
                offset = 0
                if holding and res.stop_reason is StopReason.COMPLETED:
                    wait_row = dyn.hold_policy(p)
                    if wait_row >= 0:  # still blocked: hold on (no new event)
                        current = wait_row
                        continue
            g = goal_states[k_goal]
            near_goal = bool(
                np.linalg.norm(p[:2] - g[:2]) <= options.goal_tolerance
                and np.linalg.norm(p[2:] - g[2:]) <= options.goal_tolerance
            )
            if res.stop_reason is StopReason.DOMAIN_EXIT:
                reason = EventReason.DOMAIN_EXIT
                nxt = self.best_policy(p, tree)
            elif current == CAPTURE:
                if captured[0].goal_domain.contains(p):
                    captured.pop(0)
                    reason = EventReason.GRACEFUL
                    if captured:
                        nxt = CAPTURE
                    else:
                        nxt = capture_row
                        if not self.library.policy(nxt).start_domain.contains(p):
                            nxt, reason = self.best_policy(p, tree), EventReason.NOT_IN_GOAL
                else:
                    reason, nxt = EventReason.NOT_IN_GOAL, self.best_policy(p, tree)
            elif current == TERMINAL and term is not None:
                if near_goal:
                    goals_reached.append((t, k_goal))
                    status = TaskStatus.GOAL_REACHED
                    break
                if term.start_domain.contains(p):
                    reason, nxt = EventReason.HOLD_GOAL, TERMINAL
                else:
                    reason, nxt = EventReason.NOT_IN_GOAL, self.best_policy(p, tree)
            elif not inst.goal_domain.contains(p):
                reason = EventReason.NOT_IN_GOAL
                nxt = self.best_policy(p, tree)
            elif is_goal and term is not None:
                # Off-lattice goal: the terminal regulator takes over from the rest trim.
                if term.start_domain.contains(p):
                    reason, nxt = EventReason.TERMINAL, TERMINAL
                else:
                    reason, nxt = EventReason.HOLD_GOAL, current
            elif is_goal:
                goals_reached.append((t, k_goal))
                if k_goal + 1 < len(sequence):
                    k_goal += 1
                    tree = self.tree(sequence[k_goal])
                    if dyn is not None:
                        tree = dyn.retarget(tree)
                    reason = EventReason.NEW_GOAL
                    nxt = int(tree.next_policy[current])
                    if nxt < 0 or not self.library.policy(nxt).start_domain.contains(p):
                        nxt = self.best_policy(p, tree)
                        reason = EventReason.NOT_IN_GOAL
                elif loops > 1 or inst.kind is PrimitiveKind.CRUISE:
                    status = TaskStatus.LOOPS_COMPLETED
                    break
                else:
                    if near_goal:
                        status = TaskStatus.GOAL_REACHED
                        break
                    reason, nxt = EventReason.HOLD_GOAL, current
            else:
                reason = EventReason.GRACEFUL
                nxt = int(tree.next_policy[current])
                if nxt < 0 or not self.library.policy(nxt).start_domain.contains(p):
                    nxt = self.best_policy(p, tree)
                    reason = EventReason.NOT_IN_GOAL
            if ticks >= max_ticks:
                status = TaskStatus.BLOCKED if holding else TaskStatus.TIMEOUT
                break
            if nxt == -1 and dyn is not None and np.any(dyn.blocked):
                wait_row = dyn.hold_policy(p)
                if wait_row >= 0:  # obstacles block the way: wait on a free rest trim
                    events.append(SwitchEvent(t, current, wait_row, EventReason.BLOCKED, ticks))
                    current, holding = wait_row, True
                    continue
            if nxt == -1 and options.capture and (dyn is None or not dyn.known):
                plan = self.capture_plan(x, tree)
                if plan is not None:
                    events.append(SwitchEvent(t, current, CAPTURE, EventReason.CAPTURE, ticks))
                    capture_plans.append((t, plan))
                    captured, capture_row = list(plan.policies), plan.rest_row
                    current, offset = CAPTURE, 0
                    continue
            if nxt == -1:
                # Balancing mode: station keeping at the nearest rest-trim start of the
                # library from which the goal is reachable, checking every chunk whether
                # some policy's S now contains the state; the task stops if none does
                # within ``balance_time``.
                events.append(SwitchEvent(t, current, -1, EventReason.BALANCING, ticks))
                hold_xy = self._recovery_point(p, tree, dyn)
                waited = 0.0
                nxt = -1
                fell = False
                limit = options.balance_time
                while waited < limit - 1e-9 and ticks < max_ticks:
                    chunk = min(options.balance_chunk, limit - waited, (max_ticks - ticks) * dt)
                    hold = Reference.hold(hold_xy, chunk, params=self.gains.params)
                    local, inst_idx = _segment_disturbances(
                        disturbances, t, dt, hold.num_ticks, applied
                    )
                    bal = simulate(
                        x,
                        hold,
                        self.gains,
                        params=self.params,
                        plant=options.plant,
                        disturbances=local,
                        options=options.simulation,
                    )
                    n = bal.states.shape[0] - 1
                    applied.update(inst_idx)
                    hold_ref = np.zeros((n + 1, 6))
                    hold_ref[:, :2] = hold_xy
                    record.add(t, bal, -1, hold_ref)
                    t += n * dt
                    ticks += n
                    waited += n * dt
                    if dyn is not None and np.any(dyn.blocked):
                        blocked_time += n * dt  # waiting for the way to clear
                        if options.resume_from_balancing:  # as long as it takes
                            limit = max(limit, waited + options.balance_chunk)
                    x = bal.states[-1].copy()
                    p = position_state(x, r)
                    if bal.stop_reason is StopReason.FELL:
                        fell = True
                        break
                    if dyn is not None and dyn.due(t):
                        tree = dyn.update(t, p[:2], tree)
                        if not dyn.hold_clear(hold_xy, _BALANCING_MARGIN + HOLD_MARGIN):
                            hold_xy = self._recovery_point(p, tree, dyn)
                    if options.resume_from_balancing and not _disturbed(disturbances, t):
                        nxt = self.best_policy(p, tree)
                        if nxt >= 0:
                            break
                if fell:
                    status = TaskStatus.FELL
                    break
                if nxt < 0:
                    if dyn is not None and np.any(dyn.blocked):
                        status = TaskStatus.BLOCKED
                    else:
                        status = (
                            TaskStatus.TIMEOUT if waited < limit - 1e-9 else TaskStatus.NO_POLICY
                        )
                    break
                events.append(SwitchEvent(t, -1, nxt, EventReason.RECOVERED, ticks))
                current = nxt
                continue
            events.append(SwitchEvent(t, current, nxt, reason, ticks))
            current = nxt
        time, states, inputs, policy, reference = record.arrays(t, x)
        return Episode(
            time=time,
            states=states,
            inputs=inputs,
            policy=policy,
            reference=reference,
            events=tuple(events),
            status=status,
            goals_reached=tuple(goals_reached),
            tree_seconds=tuple(self.tree_seconds),
            radius=self.params.ball_radius,
            replans=tuple(dyn.replans) if dyn is not None else (),
            blocked_time=blocked_time,
            moving_obstacles=tuple(moving_obstacles),
            captures=tuple(capture_plans),
        )
