"""The hybrid controller's per-tick state machine for one task.

A task runs in *segments*: a policy (or the part of it up to the next look at the
moving obstacles, or up to the time limit), or a chunk of balancing mode. Every
tick :meth:`Supervisor.tick` checks the fall limit and the running policy's outer
domain D'(t) on the measured state and computes the Fig. 2 control law; when a
segment ends (its last tick, or a domain exit) the switching rules decide what
runs next at the same tick: the next policy of the tree, a recovery, a capture, a
hold while moving obstacles block the way, balancing mode, or the end of the task.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray

from gracenav.control.law import TrackingLaw
from gracenav.execution.capture import CapturePlan, PlacedPolicy, ShiftTerminal, TerminalPolicy
from gracenav.execution.episode import ExecutionLog
from gracenav.execution.goals import ON_LATTICE
from gracenav.execution.jobs import Job
from gracenav.execution.obstacles import ObstacleTracker
from gracenav.execution.types import (
    CAPTURE,
    TERMINAL,
    Command,
    EventReason,
    ExecutionOptions,
    SwitchEvent,
    TaskStatus,
)
from gracenav.planning import PolicyTree as WholeTree
from gracenav.planning.repair import HOLD_MARGIN, ReplanEvent, repair_tree
from gracenav.policies import PrimitiveKind, instantiated_reference
from gracenav.sim import position_state, state_from_position

if TYPE_CHECKING:
    from concurrent.futures import ThreadPoolExecutor

    from gracenav.control import ControllerGains as _Gains
    from gracenav.execution.arrival import ArrivalPlan
    from gracenav.execution.capture import Terminal
    from gracenav.execution.goals import Goals
    from gracenav.library import PolicyLibrary
    from gracenav.params import BallbotParams
    from gracenav.planning import LazyPolicyTree, PolicyTree
    from gracenav.planning.graph import PreparesGraph
    from gracenav.policies.domains import EllipsoidalDomain

__all__ = ["Planner", "Segment", "Supervisor", "fallen"]

FloatArray = NDArray[np.float64]

#: Policies in a row that may end at their first tick (an instantaneous disturbance at
#: a switch can do that once) before the task stops with TaskStatus.NO_PROGRESS.
MAX_STALLED_SEGMENTS = 8
#: Clearance (m) beyond the footprint that balancing mode keeps on its way to the
#: point it holds (see HybridController.recovery_point).
BALANCING_MARGIN = 0.05

#: A capture that lands with a start domain that no longer holds the state is asked
#: again from the state then, at most this many times, before balancing mode.
CAPTURE_TRIES = 3
#: Longest wait (s) for a capture computed in the background before balancing mode.
CAPTURE_WAIT = 1.0
#: A capture computed in the background is planned from the state predicted this far
#: ahead (s) and starts then (later if it lands later): longer than a capture plan
#: takes on this machine (2-28 ms measured).
CAPTURE_LEAD = 0.05
#: When moving obstacles block a goal's own end (its trim or terminal), other ends of
#: the way to it (:meth:`Goals.alternatives`) are tried with the trees toward at most
#: this many approach trims.
RETARGET_TREES = 16
#: Ticks (0.125 s) over which the ball's measured position state is averaged before the
#: goal's terminal regulator or rest trim ends the task (ExecutionOptions.
#: settle_tolerance): the decoupled baseline tests its goal at this period.
SETTLE_WINDOW = 128

_NO_CENTER = np.zeros((0,))
_NO_SHAPE = np.zeros((0, 0))


class Planner(Protocol):
    """What a :class:`Supervisor` asks of its hybrid controller: the library, the
    controller's model, and the planning queries (:class:`HybridController`)."""

    library: PolicyLibrary
    graph: PreparesGraph
    goals: Goals
    gains: _Gains
    params: BallbotParams
    dt: float
    radius: float
    law: TrackingLaw

    @property
    def whole_trees(self) -> bool: ...

    def planning_executor(self) -> ThreadPoolExecutor | Executor: ...

    def tree(self, goal_policy: int) -> PolicyTree | LazyPolicyTree: ...

    def best_policy(self, p: Any, tree: PolicyTree | LazyPolicyTree) -> int: ...

    def capture_plan(self, x: Any, tree: PolicyTree | LazyPolicyTree) -> CapturePlan | None: ...

    def recovery_point(
        self, p: FloatArray, tree: PolicyTree | LazyPolicyTree, dyn: ObstacleTracker | None = None
    ) -> FloatArray: ...


@dataclass
class Segment:
    """What runs until the next decision: reference rows 0..n (n + 1 ticks)."""

    policy: int
    ref_states: FloatArray
    ref_inputs: FloatArray
    ref_pos: FloatArray
    centers: FloatArray | None
    shapes: FloatArray | None
    n: int
    truncated: bool = False
    split: bool = False
    is_goal: bool = False
    balance: bool = False
    waiting: bool = False
    k: int = 0
    #: A hold that may be left before its end: (row, its S, lean band); see
    #: :meth:`Supervisor._leaving`.
    leave: tuple[int, EllipsoidalDomain, tuple[float, float]] | None = None
    #: The tick from which a shift terminal's hold may take over from its last shift;
    #: see :meth:`Supervisor._hold_from`.
    hold_from: int | None = None

    def command(self, law: TrackingLaw, x: FloatArray) -> tuple[FloatArray, float]:
        """The law's torque at tick ``k`` for the measured state ``x``, and the value of
        the monitored outer domain (0 without one; > 1: outside)."""
        k = self.k
        ref, after = self.ref_states[k], self.ref_states[min(k + 1, self.n)]
        if self.centers is not None and self.shapes is not None:
            return law(x, ref, self.ref_inputs[k], self.centers[k], self.shapes[k], after)
        return law(x, ref, self.ref_inputs[k], _NO_CENTER, _NO_SHAPE, after)


#: How near (m, m/s, m/s²) a reference is to the goal at rest where a task may settle.
_AT_REST = 1e-6


def fallen(x: FloatArray, fall_lean: float) -> bool:
    """Whether the lean in either plane is beyond ``fall_lean`` (rad) or not finite."""
    return not (abs(x[2]) <= fall_lean and abs(x[3]) <= fall_lean)


class Supervisor:
    """One task of a :class:`~gracenav.execution.HybridController`, tick by tick.

    Built by :meth:`HybridController.reset`, which has checked the goals and chosen
    the first policy (``current``; :data:`CAPTURE` with ``capture_plan``).
    """

    def __init__(
        self,
        hc: Planner,
        options: ExecutionOptions,
        *,
        sequence: list[int],
        terminals: list[Terminal | None],
        goal_states: list[FloatArray],
        tree: PolicyTree | LazyPolicyTree,
        current: int,
        dyn: ObstacleTracker | None,
        holding: bool,
        capture_plan: CapturePlan | None,
        loops: int,
        arrival: ArrivalPlan | None = None,
    ) -> None:
        self.hc = hc
        self.options = options
        self.dt = hc.dt
        self.r = hc.radius
        self.law = hc.law
        self.sequence = sequence
        self.terminals = terminals
        self.goal_states = goal_states
        self.tree = tree
        self.current = current
        self.dyn = dyn
        self.holding = holding
        self.loops = loops
        self.k_goal = 0
        #: The stage of a shift terminal running (:attr:`ShiftTerminal.stages`).
        self.term_stage = 0
        #: Replans logged when the free other ends of the way were last listed, those
        #: ends, and the trees toward their approach trims (see _retarget).
        self.retarget_seen = -1
        self.retarget_free: list[Terminal] = []
        self.retarget_trees: dict[int, Any] = {}
        self.captured: list[PlacedPolicy] = []
        #: The end maneuver designed when the task started (taken after its policy).
        self.arrival = arrival
        self.capture_plans: list[tuple[float, CapturePlan]] = []
        self.capture_row = -1
        #: The last position states while a policy that settles runs (see _settled).
        self.settle_buf = np.zeros((SETTLE_WINDOW, 4))
        self.settle_n = 0
        self.settling = False
        #: Tick of the running segment from which its reference rests at the goal.
        self.settle_from = 0
        #: Domain exits per library row, the rows set aside after repeated exits on
        #: the tree they were set aside from, and the repairs (see _set_aside).
        self.exits: dict[int, int] = {}
        self.set_aside: NDArray[np.bool_] | None = None
        self.aside_tree: PolicyTree | None = None
        self.own_replans: list[ReplanEvent] = []
        if capture_plan is not None:
            self.capture_plans.append((0.0, capture_plan))
            self.captured, self.capture_row = list(capture_plan.policies), capture_plan.rest_row
        self.events = [SwitchEvent(0.0, -1, current, EventReason.START, 0)]
        self.goals_reached: list[tuple[float, int]] = []
        self.blocked_time = 0.0
        self.ticks = 0
        self.max_ticks = max(1, math.ceil(options.max_time / self.dt - 1e-9))
        self.stalled = 0
        self.offset = 0
        self.status = TaskStatus.RUNNING
        self.segment: Segment | None = None
        self.balancing = False
        self.hold_xy = np.zeros(2)
        self.waited = 0.0
        self.limit = 0.0
        self.recovered = -1
        self.fall_lean = float(options.simulation.fall_lean)
        self.x = np.zeros(8)
        self.held = False
        self.last_t: float | None = None
        self.final: Command | None = None
        self.hold_final: FloatArray | None = None
        self.background = options.planning != "instant"
        self.executor = hc.planning_executor() if options.planning == "threaded" else None
        self.look_job: Job | None = None
        self.capture_job: Job | None = None
        self.capture_tries = 0
        self.capture_at = 0
        self.tree_job: Job | None = None
        #: The running policy's reference and domains: (row, placed policy or None,
        #: states, inputs, ball reference, D' shapes).
        self.arrays: (
            tuple[int, PlacedPolicy | None, FloatArray, FloatArray, FloatArray, FloatArray] | None
        ) = None
        if self.background and options.capture:
            # Load the compiled prediction once here, not in the tick that first needs it.
            from gracenav.sim import Reference, simulate

            seg = self._coast(state_from_position(np.zeros(4), self.r), 2)
            ref = Reference(seg.ref_states, seg.ref_inputs, self.dt)
            simulate(seg.ref_states[0], ref, hc.gains, params=hc.params)

    def _job(self, fn: Callable[[], Any]) -> Job:
        return Job(
            fn,
            executor=self.executor,
            tick=self.ticks,
            dt=self.dt,
            latency=self.options.planning_latency,
        )

    # -- the tick ------------------------------------------------------------------
    def tick(self, t: float, x: FloatArray, held: bool) -> Command:
        """The command for tick time ``t`` and measured state ``x``."""
        if self.final is not None:
            return self._after_end(x)
        if self.last_t is not None:
            missed = round((t - self.last_t) / self.dt) - 1
            if missed > 0:  # ticks the caller skipped: the reference moves on as well
                self._skip(missed)
        self.last_t = t
        self.x = x
        self.held = held
        while self.status is TaskStatus.RUNNING:
            seg = self.segment
            if seg is None:
                self._begin()
                continue
            k = seg.k
            if self.background and self._land(seg, k):
                continue
            if fallen(x, self.fall_lean):
                self.segment = None
                self._finish(TaskStatus.FELL)
                break
            tau, val = seg.command(self.law, x)
            exited = val > 1.0
            if not self.settling or k < self.settle_from:
                self.settle_n = 0
            elif not exited and self._settled(x):
                self.segment = None
                self.goals_reached.append((self.t, self.k_goal))
                self._finish(TaskStatus.GOAL_REACHED, hold_xy=self.goal_states[self.k_goal][:2])
                break
            if (
                not exited
                and seg.hold_from is not None
                and k >= seg.hold_from
                and self._may_hold(x)
            ):
                # The last shift's rest tail is left for the regulator at the goal.
                self.segment = None
                self.term_stage += 1
                self._event(TERMINAL, EventReason.HOLD_GOAL)
                self.offset = 0
                continue
            if not exited and seg.leave is not None and self._may_leave(seg.leave, x):
                # The hold is left before its end (see _leaving).
                self.segment = None
                to = seg.leave[0]
                self.captured = []
                self._event(to, EventReason.GRACEFUL)
                self.current, self.offset = to, 0
                continue
            if exited or k == seg.n:
                self.segment = None
                if seg.balance:
                    self._end_chunk(seg, k)
                elif seg.waiting:
                    self._wait_more(seg)
                else:
                    self._end_segment(seg, k, exited)
                continue
            seg.k += 1
            self.ticks += 1
            return Command(tau, False, TaskStatus.RUNNING, seg.policy, seg.ref_pos[k])
        return self._after_end(x)

    def _skip(self, missed: int) -> None:
        seg = self.segment
        if seg is None:
            return
        m = min(missed, seg.n - seg.k)
        seg.k += m
        self.ticks += m

    @property
    def t(self) -> float:
        """Task time (s) of the current tick: k/1024 exactly."""
        return self.ticks * self.dt

    def _finish(self, status: TaskStatus, hold_xy: FloatArray | None = None) -> None:
        """End the task; afterwards the robot balances at ``hold_xy`` (default: where
        it is)."""
        self.status = status
        xy = position_state(self.x, self.r)[:2] if hold_xy is None else hold_xy
        hold = state_from_position(np.r_[xy, 0.0, 0.0], self.r)
        self.hold_final = hold if status is not TaskStatus.FELL else None

    def _leaving(self, current: int) -> tuple[int, EllipsoidalDomain, tuple[float, float]] | None:
        """The policy a hold starting now may hand over to before its own end, with its
        S and the lean band it was verified from, or None.

        A hold is the last stage of a capture (a shift or catch, which ends resting at
        a point while the robot settles there) or a capture regulator. The policy after
        it (past the rest trim it ends on, as :meth:`_past_hold` skips it) starts at
        rest; when it was verified from the still band too
        (:attr:`~gracenav.policies.MotionPolicy.starts_from_still_band`), it starts at
        the first tick at which its S holds the state and the lean and lean rate are
        within that band (:meth:`_may_leave`): the rule of every switch, a verified
        policy whose S contains the state, with a lean it was verified from. Only with
        ``skip_holds``, not while moving obstacles are tracked or the robot holds for a
        blocked way, and not onto the goal's rest trim. (An earlier stage of a capture is
        held to its end: handing a moving robot to the next shift, which starts at rest,
        made the starts of the random pairs slower and jerkier.)"""
        if not self.options.skip_holds or self.dyn is not None or self.holding:
            return None
        lib = self.hc.library
        catch = lib.palette.options.catch
        if catch is None:
            return None
        if current == CAPTURE:
            if len(self.captured) != 1:
                return None
            after = self.capture_row
        elif 0 <= current < len(lib) and lib.policy(current).policy.capture:
            after = int(self.tree.next_policy[current])
        else:
            return None
        if after < 0 or after == self.sequence[self.k_goal]:
            return None
        if lib.policy(after).policy.primitive.kind is PrimitiveKind.REST:
            rest, after = after, int(self.tree.next_policy[after])
            if after < 0 or after == rest:
                return None
        nxt = lib.policy(after)
        if not nxt.policy.starts_from_still_band:
            return None
        band = (float(catch.still_lean[0]), float(catch.still_lean[1]))
        return after, nxt.start_domain, band

    def _may_leave(
        self, leave: tuple[int, EllipsoidalDomain, tuple[float, float]], x: FloatArray
    ) -> bool:
        """Whether the hold may be left at this tick (:meth:`_leaving`): the lean and
        lean rate (norms over both axes; the plan lean where the next policy starts is
        upright) within the still band and its S holding the state."""
        _, domain, band = leave
        if math.hypot(x[2], x[3]) > band[0] or math.hypot(x[6], x[7]) > band[1]:
            return False
        return bool(domain.contains(position_state(x, self.r)))

    def _settles(self, current: int, is_goal: bool) -> bool:
        """Whether the policy starting may end the task before its own end
        (:meth:`_settled`): the last goal's terminal regulator, the last shift or the
        hold of its shift terminal, or the rest trim that ends at the last goal; each
        settles only from the tick its reference rests at the goal
        (:meth:`_settle_tick`), which is then the hold after the end too."""
        if self.k_goal + 1 < len(self.sequence) or self.loops > 1:
            return False
        term = self.terminals[self.k_goal]
        if current == TERMINAL:
            # A regulator's reference is the goal; a shift terminal's last shift or hold
            # settles from where its reference rests at the goal (_settle_tick).
            return term is not None and (
                isinstance(term, TerminalPolicy) or self.term_stage >= len(term.shifts) - 1
            )
        if not is_goal or term is not None or current < 0:
            return False
        lib = self.hc.library
        g = self.goal_states[self.k_goal]
        return bool(
            lib.policy(current).policy.primitive.kind is PrimitiveKind.REST
            and np.all(g[2:] == 0.0)
            and np.linalg.norm(lib.end_state[current] - g) <= ON_LATTICE
        )

    def _settle_tick(self, ref_pos: FloatArray) -> int:
        """The tick of the current segment from which the policy's reference (ball
        position, velocity and acceleration, ``ref_pos``) rests at the goal for the rest
        of the policy: 0 for a rest trim at the goal or a terminal regulator, the start
        of a shift's rest tail; past the segment's end when it never does (a shift of a
        terminal that ends next to the goal)."""
        g = self.goal_states[self.k_goal]
        if not np.all(g[2:] == 0.0):
            return len(ref_pos)
        return self._rest_tick(ref_pos, g[:2])

    def _rest_tick(self, ref_pos: FloatArray, xy: FloatArray) -> int:
        """The tick of the current segment from which the reference ``ref_pos`` rests at
        ``xy`` for the rest of the policy (past the segment's end if it does not end
        there at rest)."""
        end = ref_pos[-1]
        if not (np.linalg.norm(end[:2] - xy) <= _AT_REST and np.all(np.abs(end[2:]) <= _AT_REST)):
            return len(ref_pos)
        moving = np.flatnonzero(np.any(np.abs(ref_pos - end) > _AT_REST, axis=1))
        first = int(moving[-1]) + 1 if moving.size else 0
        return max(0, first - self.offset)

    def _hold_from(self, current: int, ref_pos: FloatArray) -> int | None:
        """For the last shift of a shift terminal whose hold is a capture regulator at
        the goal (the shift ends at the grid point next to it): the tick of the current
        segment from which the hold may take over, the start of the shift's rest tail
        (its reference rests there), once the regulator's S holds the state within the
        lean band (:meth:`_may_hold`); None otherwise. With ``skip_holds`` only, as the
        other holds left early (:meth:`_leaving`)."""
        term = self.terminals[self.k_goal]
        if (
            current != TERMINAL
            or not isinstance(term, ShiftTerminal)
            or not self.options.skip_holds
            or self.term_stage != len(term.shifts) - 1
            or not term.hold.policy.capture
        ):
            return None
        end = ref_pos[-1, :2]
        if np.linalg.norm(end - term.goal_xy) <= _AT_REST:
            return None
        tick = self._rest_tick(ref_pos, end)
        return tick if tick < len(ref_pos) else None

    def _may_hold(self, x: FloatArray) -> bool:
        """Whether the shift terminal's hold may start at this tick: its S holds the
        state and the lean is within the band its stages were verified from."""
        term = self.terminals[self.k_goal]
        assert isinstance(term, ShiftTerminal)
        return bool(
            term.hold.start_domain.contains(position_state(x, self.r))
            and term.accepts_lean(float(np.hypot(*x[2:4])), float(np.hypot(*x[6:8])))
        )

    def _settled(self, x: FloatArray) -> bool:
        """Whether a policy that settles (:meth:`_settles`) may end the task at this
        tick: the ball, averaged over the last :data:`SETTLE_WINDOW` ticks (the
        measurement's noise averages out), within ``settle_tolerance`` of the goal and
        slower than ``goal_tolerance``.
        """
        self.settle_buf[self.settle_n % SETTLE_WINDOW] = position_state(x, self.r)
        self.settle_n += 1
        if self.settle_n < SETTLE_WINDOW:
            return False
        g = self.goal_states[self.k_goal]
        p = self.settle_buf.mean(axis=0)
        opts = self.options
        return bool(
            np.hypot(*(p[:2] - g[:2])) <= min(opts.settle_tolerance, opts.goal_tolerance)
            and np.hypot(*(p[2:] - g[2:])) <= opts.goal_tolerance
        )

    def _after_end(self, x: FloatArray) -> Command:
        """After the task: balance where it ended (nothing after a fall)."""
        ref = np.zeros(6)
        hold = self.hold_final
        if hold is None or not np.all(np.isfinite(x)):
            tau = np.zeros(2)
        else:
            ref[:2] = position_state(hold, self.r)[:2]
            tau, _ = self.law(x, hold, np.zeros(2), _NO_CENTER, _NO_SHAPE)
        self.final = Command(tau, True, self.status, -1, ref)
        return self.final

    def log(self, tree_seconds: tuple[float, ...]) -> ExecutionLog:
        """What the task kept besides the samples."""
        return ExecutionLog(
            events=tuple(self.events),
            status=self.status,
            goals_reached=tuple(self.goals_reached),
            tree_seconds=tree_seconds,
            replans=(tuple(self.dyn.replans) if self.dyn is not None else ())
            + tuple(self.own_replans),
            blocked_time=self.blocked_time,
            captures=tuple(self.capture_plans),
            arrival=self.arrival,
        )

    # -- segments ------------------------------------------------------------------
    def _begin(self) -> None:
        """Start what runs next at this tick (a policy segment or a balancing chunk)."""
        if self.balancing:
            self._begin_chunk()
            return
        if self.ticks >= self.max_ticks:
            self._finish(TaskStatus.BLOCKED if self.holding else TaskStatus.TIMEOUT)
            return
        hc, dt = self.hc, self.dt
        current = self.current
        term = self.terminals[self.k_goal]
        placed: PlacedPolicy | None = None
        if current == CAPTURE or (current == TERMINAL and term is not None):
            if current == CAPTURE:
                placed = self.captured[0]
            elif isinstance(term, ShiftTerminal):
                placed = term.stages[self.term_stage]
            else:
                placed = term
            assert placed is not None
            prim = placed.primitive
            is_goal = False
        else:
            inst = hc.library.policy(current)
            prim = inst.policy.primitive
            is_goal = current == self.sequence[self.k_goal]
        self.settling = self._settles(current, is_goal)
        cached = self.arrays
        if cached is None or cached[0] != current or cached[1] is not placed:
            # A policy's reference and domains are built once while it runs (a look at
            # the moving obstacles splits it into several segments).
            if placed is not None:
                ref, ref_pos = placed.reference(self.r)
                _, shapes = placed.outer_monitor()
            else:
                ref, ref_pos = instantiated_reference(prim, inst.orientation, inst.start_xy, self.r)
                # Domain shapes are invariant under rotations of the plane: only the
                # centres move with the instantiation.
                _, shapes = inst.policy.outer_monitor()
            cached = (current, placed, ref.states, ref.inputs, ref_pos, shapes)
            self.arrays = cached
        _, _, ref_states, ref_inputs, ref_pos, shapes = cached
        if self.settling:
            self.settle_from = self._settle_tick(ref_pos)
            self.settling = self.settle_from < len(ref_pos)
        if is_goal and self.k_goal + 1 < len(self.sequence):
            # Regenerate the tree for the next goal while the last policy to the
            # current goal runs (paper Sec. V-C).
            nxt_goal = self.sequence[self.k_goal + 1]
            if self.background and hc.whole_trees and self.tree_job is None:
                self.tree_job = self._job(lambda: hc.tree(nxt_goal))
            elif not self.background or not hc.whole_trees:
                hc.tree(nxt_goal)
        remaining = prim.num_ticks - self.offset
        n_seg = min(remaining, self.max_ticks - self.ticks)
        truncated = n_seg < remaining
        split = False  # the segment ends at the next look at the moving obstacles
        dyn = self.dyn
        if dyn is not None and dyn.ticks_to_next(self.t, dt) < n_seg:
            n_seg, split, truncated = dyn.ticks_to_next(self.t, dt), True, False
        part = slice(self.offset, self.offset + n_seg + 1)
        self.segment = Segment(
            policy=current,
            ref_states=ref_states[part],
            ref_inputs=ref_inputs[part],
            ref_pos=ref_pos[part],
            centers=np.ascontiguousarray(ref_pos[part, :4]),
            shapes=np.ascontiguousarray(shapes[part]),
            n=n_seg,
            truncated=truncated,
            split=split,
            is_goal=is_goal,
            leave=self._leaving(current),
            hold_from=self._hold_from(current, ref_pos),
        )

    def _event(self, to: int, reason: EventReason, frm: int | None = None) -> None:
        f = self.current if frm is None else frm
        self.events.append(SwitchEvent(self.t, f, to, reason, self.ticks))

    def _end_segment(self, seg: Segment, last: int, exited: bool, looked: bool = False) -> None:
        """The switching rules at the end of a policy segment of ``last`` ticks
        (``looked``: it ended because a look at the moving obstacles landed)."""
        hc, options, dyn = self.hc, self.options, self.dyn
        t, x = self.t, self.x
        p = position_state(x, self.r)
        completed = not exited
        if self.holding:
            self.blocked_time += last * self.dt
        if seg.truncated and completed:
            self._finish(TaskStatus.BLOCKED if self.holding else TaskStatus.TIMEOUT)
            return
        self.stalled = self.stalled + 1 if last == 0 else 0
        if self.stalled > MAX_STALLED_SEGMENTS:
            self._finish(TaskStatus.NO_PROGRESS)
            return
        current = self.current
        term = self.terminals[self.k_goal]
        if dyn is not None:
            if dyn.due(t) and not looked:
                self._look(t, p)
            if self.holding:
                free_row = hc.best_policy(p, self.tree)
                if self._end_blocked():  # the way may be free, but not its end
                    free_row = self._retarget(p)
                if free_row >= 0:  # the way is free again
                    self._event(free_row, EventReason.RESUMED)
                    self.current, self.offset, self.holding = free_row, 0, False
                    return
            if seg.split and completed:
                self.offset += last
                blocked_now = (
                    bool(dyn.known)
                    if current == CAPTURE
                    else self._terminal_blocked(term)
                    if current == TERMINAL and term is not None
                    else dyn.is_blocked(current)
                    or (self.holding and not dyn.hold_row_clear(current))
                )
                if not blocked_now:
                    return  # the same policy goes on
                self.offset = 0
                nxt = hc.best_policy(p, self.tree)
                if nxt < 0 and self._end_blocked():
                    nxt = self._retarget(p)
                if nxt >= 0:
                    self._event(nxt, EventReason.OBSTACLE)
                    self.current, self.holding = nxt, False
                    return
                wait_row = dyn.hold_policy(p)
                if wait_row >= 0:
                    self._event(wait_row, EventReason.BLOCKED)
                    self.current, self.holding = wait_row, True
                    return
                # Nothing unblocked contains the state: balancing mode below.
            self.offset = 0
            if self.holding and completed:
                wait_row = dyn.hold_policy(p)
                if wait_row >= 0:  # still blocked: hold on (no new event)
                    self.current = wait_row
                    return
        decided = self._next_policy(seg, p, exited)
        if decided is None:  # the task ended
            return
        reason, row = decided
        if self.ticks >= self.max_ticks:
            self._finish(TaskStatus.BLOCKED if self.holding else TaskStatus.TIMEOUT)
            return
        if row == -1 and dyn is not None and (np.any(dyn.blocked) or self._end_blocked()):
            if self._end_blocked():
                row = self._retarget(p)
                if row >= 0:  # another end of the way to the goal is free
                    self._event(row, EventReason.OBSTACLE)
                    self.current = row
                    return
            wait_row = dyn.hold_policy(p)
            if wait_row >= 0:  # obstacles block the way: wait on a free rest trim
                self._event(wait_row, EventReason.BLOCKED)
                self.current, self.holding = wait_row, True
                return
        if row == -1 and options.capture and (dyn is None or not dyn.known) and self.background:
            self.capture_tries = 0
            self._ask_capture(x)
            return
        if row == -1 and options.capture and (dyn is None or not dyn.known):
            plan = hc.capture_plan(x, self.tree)
            if plan is not None:
                self._event(CAPTURE, EventReason.CAPTURE)
                self.capture_plans.append((t, plan))
                self.captured, self.capture_row = list(plan.policies), plan.rest_row
                self.current, self.offset = CAPTURE, 0
                return
        if row == -1:
            self._balance(p)
            return
        self._event(row, reason)
        self.current = row

    def _balance(self, p: FloatArray) -> None:
        """Balancing mode: station keeping at the nearest rest-trim start of the
        library from which the goal is reachable, checking every chunk whether some
        policy's S now contains the state; the task stops if none does within
        ``balance_time``."""
        self._event(-1, EventReason.BALANCING)
        self.hold_xy = self.hc.recovery_point(p, self.tree, self.dyn)
        self.waited = 0.0
        self.recovered = -1
        self.limit = self.options.balance_time
        self.balancing = True

    # -- computations in the background ---------------------------------------------
    def _look(self, t: float, p: FloatArray) -> None:
        """Look at the moving obstacles now (instant) or ask for a look."""
        dyn = self.dyn
        assert dyn is not None
        if not self.background:
            self.tree = dyn.update(t, p[:2], self.tree)
            return
        dyn.next_time = t + dyn.sensing.period
        if self.look_job is None:
            xy, tree = p[:2].copy(), self.tree
            self.look_job = self._job(lambda: dyn.look(t, xy, tree))

    def _coast(self, x: FloatArray, n: int) -> Segment:
        """A waiting segment of ``n`` ticks: upright at the measured velocity from the
        measured position (the reference the robot follows while a capture is
        computed), with the friction the plan expects at that ball rate."""
        from gracenav import _kernels

        p = position_state(x, self.r)
        tau = np.arange(n + 1)[:, None] * self.dt
        pos = np.zeros((n + 1, 6))
        pos[:, :2] = p[:2] + tau * p[2:]
        pos[:, 2:4] = p[2:]
        states = state_from_position(pos[:, :4], self.r)
        fr = self.law.friction
        ff = np.array([_kernels.friction(fr, float(w)) for w in states[0, 4:6]])
        return Segment(
            policy=self.current,
            ref_states=states,
            ref_inputs=np.tile(ff, (n + 1, 1)),
            ref_pos=pos,
            centers=None,
            shapes=None,
            n=n,
            waiting=True,
        )

    def _ask_capture(self, x: FloatArray) -> None:
        """Ask for a capture of the state predicted :data:`CAPTURE_LEAD` ahead while the
        robot coasts (:meth:`_coast`), predicted on the controller's own model."""
        from gracenav.sim import Reference, simulate

        lead = max(1, round(CAPTURE_LEAD / self.dt))
        wait = self._coast(x, lead + round(CAPTURE_WAIT / self.dt))
        ref = Reference(wait.ref_states[: lead + 1], wait.ref_inputs[: lead + 1], self.dt)
        gains = self.hc.gains
        x_at = simulate(x, ref, gains, params=self.hc.params).states[-1]
        tree, hc = self.tree, self.hc
        self.capture_tries += 1
        self.capture_at = self.ticks + lead
        self.capture_job = self._job(lambda: hc.capture_plan(x_at, tree))
        self.segment = wait

    def _wait_more(self, seg: Segment) -> None:
        """The wait ran out before the capture landed: balancing mode."""
        self.capture_job = None
        self._balance(position_state(self.x, self.r))

    def _land(self, seg: Segment, k: int) -> bool:
        """Adopt what the background finished by this tick; True when that ended the
        running segment (something else starts at this tick)."""
        dyn = self.dyn
        if self.look_job is not None and self.look_job.ready(self.ticks):
            assert dyn is not None
            look, self.look_job = self.look_job.result(), None
            goal = self.tree.goal
            self.tree = dyn.apply(look)
            if self.tree.goal != goal:  # the task's end moved while the look was computed
                self.tree = dyn.retarget(self.hc.tree(goal))
            if not (seg.balance or seg.waiting):
                # The policy is judged against what the look saw, here.
                self.segment = None
                seg.split, seg.truncated = True, False
                self._end_segment(seg, k, exited=False, looked=True)
                return True
        if (
            self.capture_job is not None
            and self.ticks >= self.capture_at
            and self.capture_job.ready(self.ticks)
        ):
            plan, self.capture_job = self.capture_job.result(), None
            self.segment = None
            p = position_state(self.x, self.r)
            t = self.t
            if plan is not None and plan.policies[0].start_domain.contains(p):
                self._event(CAPTURE, EventReason.CAPTURE)
                self.capture_plans.append((t, plan))
                self.captured, self.capture_row = list(plan.policies), plan.rest_row
                self.current, self.offset = CAPTURE, 0
                return True
            nxt = self.hc.best_policy(p, self.tree)
            if nxt >= 0:
                self._event(nxt, EventReason.NOT_IN_GOAL)
                self.current, self.offset = nxt, 0
            elif self.capture_tries < CAPTURE_TRIES:
                self._ask_capture(self.x)
            else:
                self._balance(p)
            return True
        return False

    def _next_policy(
        self, seg: Segment, p: FloatArray, exited: bool
    ) -> tuple[EventReason, int] | None:
        """(reason, next row or −1) after a segment, or None when the task ended."""
        hc, options = self.hc, self.options
        current = self.current
        term = self.terminals[self.k_goal]
        g = self.goal_states[self.k_goal]
        near_goal = bool(
            np.linalg.norm(p[:2] - g[:2]) <= options.goal_tolerance
            and np.linalg.norm(p[2:] - g[2:]) <= options.goal_tolerance
        )
        if exited:
            if 0 <= current < len(hc.library):
                self._set_aside(current)
            return EventReason.DOMAIN_EXIT, hc.best_policy(p, self.tree)
        if current == CAPTURE:
            if self.captured[0].goal_domain.contains(p):
                self.captured.pop(0)
                if self.captured:
                    return EventReason.GRACEFUL, CAPTURE
                nxt = self.capture_row
                if nxt == TERMINAL:
                    # An end maneuver to a goal off the lattice: the capture regulator
                    # there, the terminal or the hold after a terminal's shifts.
                    if isinstance(term, ShiftTerminal):
                        if self._may_hold(self.x):
                            self.term_stage = len(term.shifts)
                            return EventReason.HOLD_GOAL, TERMINAL
                    elif term is not None and self._terminal_starts(term, p):
                        self.term_stage = 0
                        return EventReason.TERMINAL, TERMINAL
                    return EventReason.NOT_IN_GOAL, hc.best_policy(p, self.tree)
                if not hc.library.policy(nxt).start_domain.contains(p):
                    return EventReason.NOT_IN_GOAL, hc.best_policy(p, self.tree)
                return self._past_hold(nxt, p)
            return EventReason.NOT_IN_GOAL, hc.best_policy(p, self.tree)
        if current == TERMINAL and isinstance(term, ShiftTerminal):
            return self._next_stage(term, p, near_goal)
        if current == TERMINAL and term is not None:
            if near_goal:
                self.goals_reached.append((self.t, self.k_goal))
                self._finish(TaskStatus.GOAL_REACHED)
                return None
            if term.start_domain.contains(p):
                return EventReason.HOLD_GOAL, TERMINAL
            return EventReason.NOT_IN_GOAL, hc.best_policy(p, self.tree)
        inst = hc.library.policy(current)
        if not inst.goal_domain.contains(p):
            return EventReason.NOT_IN_GOAL, hc.best_policy(p, self.tree)
        arrival = self.arrival
        if (
            arrival is not None
            and current == arrival.after
            and not seg.is_goal
            and arrival.plan.catch.start_domain.contains(p)
        ):
            # The end maneuver designed at the start, straight to rest at the goal.
            self.captured = list(arrival.plan.policies)
            self.capture_row = arrival.plan.rest_row
            self.offset = 0
            return EventReason.GRACEFUL, CAPTURE
        if seg.is_goal and term is not None:
            # Off-lattice goal: the terminal takes over from the rest trim.
            if self.dyn is not None and self._end_blocked():
                # Known obstacles block the terminal: another end of the way, or wait.
                row = self._retarget(p)
                term = self.terminals[self.k_goal]
                if row < 0 or term is None:
                    return EventReason.OBSTACLE, -1
                if term.approach != current:
                    return EventReason.OBSTACLE, row
            if self._terminal_starts(term, p):
                self.term_stage = 0
                return EventReason.TERMINAL, TERMINAL
            return EventReason.HOLD_GOAL, current
        if seg.is_goal:
            self.goals_reached.append((self.t, self.k_goal))
            if self.k_goal + 1 < len(self.sequence):
                self.k_goal += 1
                if self.tree_job is not None:  # started a whole policy ago
                    self.tree_job.result()
                    self.tree_job = None
                self.tree = hc.tree(self.sequence[self.k_goal])
                if self.dyn is not None:
                    self.tree = self.dyn.retarget(self.tree)
                nxt = int(self.tree.next_policy[current])
                if nxt < 0 or not hc.library.policy(nxt).start_domain.contains(p):
                    return EventReason.NOT_IN_GOAL, hc.best_policy(p, self.tree)
                return EventReason.NEW_GOAL, nxt
            if self.loops > 1 or inst.kind is PrimitiveKind.CRUISE:
                self._finish(TaskStatus.LOOPS_COMPLETED)
                return None
            if near_goal:
                self._finish(TaskStatus.GOAL_REACHED)
                return None
            return EventReason.HOLD_GOAL, current
        nxt = int(self.tree.next_policy[current])
        if nxt < 0 or not hc.library.policy(nxt).start_domain.contains(p):
            return EventReason.NOT_IN_GOAL, hc.best_policy(p, self.tree)
        return self._past_hold(nxt, p)

    def _set_aside(self, row: int) -> None:
        """Count a domain exit from library row ``row`` when the row had been entered
        by a graceful switch (its S held the state where a verified policy handed over;
        a row entered after another exit, as in the moments after a push, is not
        counted); at the ``ExecutionOptions.set_aside_exits``-th, plan the rest of the
        way to the current goal without it (:func:`gracenav.planning.repair.repair_tree`,
        the repair moving obstacles use): a policy the robot keeps leaving although it
        was started as planned (its domains too small for the sensor's noise, or for
        the plant) is not started again, and the capture that follows the exit takes
        the robot onto another way. What is set aside holds on the tree it was set
        aside from: a new goal's tree starts with none. Whole trees only, and not while
        moving obstacles are tracked (their repair owns the tree then)."""
        started = self.events[-1] if self.events else None
        if started is None or started.to_policy != row or not started.reason.graceful:
            return  # entered after an exit or a push: the exit says nothing of the policy
        n = self.exits.get(row, 0) + 1
        self.exits[row] = n
        limit = self.options.set_aside_exits
        if limit <= 0 or n < limit or self.dyn is not None:
            return
        if not isinstance(self.tree, WholeTree):
            return
        if self.set_aside is None or self.tree is not self.aside_tree:
            # The first set aside on this tree (a new goal's tree holds none yet).
            self.set_aside = np.zeros(len(self.hc.library), dtype=bool)
        was = self.set_aside.copy()
        self.set_aside[row] = True
        t0 = time.perf_counter()
        self.tree, changed = repair_tree(self.tree, self.hc.graph, was, self.set_aside)
        self.aside_tree = self.tree
        self.own_replans.append(
            ReplanEvent(
                self.t, "policy_left", time.perf_counter() - t0, int(self.set_aside.sum()), changed
            )
        )

    def _past_hold(self, row: int, p: FloatArray) -> tuple[EventReason, int]:
        """The switch into rest trim ``row`` (its S holds ``p``), or past it.

        A rest trim on the way holds the robot where the policy after it starts at
        rest; when that policy's S (the terminal's, at a goal off the lattice) already
        holds the state, the hold is skipped and it starts now: the same rule as every
        switch (a verified policy whose S contains the state), one rest trim's
        duration sooner. Not while moving obstacles are tracked or the robot holds for
        a blocked way (there the hold is where the robot waits), nor for other rows.
        """
        hc = self.hc
        if (
            not self.options.skip_holds
            or self.dyn is not None
            or self.holding
            or not 0 <= row < len(hc.library)
        ):
            return EventReason.GRACEFUL, row
        pol = hc.library.policy(row).policy
        if pol.primitive.kind is not PrimitiveKind.REST or pol.capture:
            return EventReason.GRACEFUL, row
        if row == self.sequence[self.k_goal]:
            term = self.terminals[self.k_goal]
            if (
                term is not None
                and self.loops <= 1
                and term.approach == row
                and self._terminal_starts(term, p)
            ):
                self.term_stage = 0
                return EventReason.TERMINAL, TERMINAL
            return EventReason.GRACEFUL, row
        nxt = int(self.tree.next_policy[row])
        if nxt >= 0 and nxt != row and hc.library.policy(nxt).start_domain.contains(p):
            return EventReason.GRACEFUL, nxt
        return EventReason.GRACEFUL, row

    # -- the end at a goal off the lattice ------------------------------------------
    def _terminal_starts(self, term: Terminal, p: FloatArray) -> bool:
        """Whether the terminal may start now: its S holds ``p`` (and, for shifts, the
        lean is within the band they were verified from)."""
        if not term.start_domain.contains(p):
            return False
        if isinstance(term, ShiftTerminal):
            x = self.x
            return term.accepts_lean(float(np.hypot(*x[2:4])), float(np.hypot(*x[6:8])))
        return True

    def _next_stage(
        self, term: ShiftTerminal, p: FloatArray, near_goal: bool
    ) -> tuple[EventReason, int] | None:
        """After a stage of a shift terminal: the next shift when its S holds the state
        (the last one's G does, where the task ended), the goal when the robot is there,
        the hold while it is not (its S holds the state), else back to the library."""
        stage = term.stages[self.term_stage]
        if not stage.goal_domain.contains(p):
            return EventReason.NOT_IN_GOAL, self.hc.best_policy(p, self.tree)
        if self.term_stage + 1 < len(term.shifts):
            self.term_stage += 1
            return EventReason.GRACEFUL, TERMINAL
        g = self.goal_states[self.k_goal]
        if (
            near_goal
            and self.term_stage < len(term.shifts)
            and not self.settling
            and np.hypot(*(term.goal_xy - g[:2])) <= _AT_REST
        ):
            # The last shift ends at a grid point next to the goal: the hold at the
            # goal settles the robot there unless it is there already.
            near_goal = bool(
                np.hypot(*(p[:2] - g[:2]))
                <= min(self.options.settle_tolerance, self.options.goal_tolerance)
            )
        if near_goal:
            self.goals_reached.append((self.t, self.k_goal))
            self._finish(TaskStatus.GOAL_REACHED)
            return None
        x = self.x
        if term.hold.start_domain.contains(p) and term.accepts_lean(
            float(np.hypot(*x[2:4])), float(np.hypot(*x[6:8]))
        ):
            self.term_stage = len(term.shifts)
            return EventReason.HOLD_GOAL, TERMINAL
        return EventReason.NOT_IN_GOAL, self.hc.best_policy(p, self.tree)

    def _terminal_blocked(self, term: Terminal) -> bool:
        """Whether a known moving obstacle's predicted motion meets the terminal's swept
        D' grown by the footprint and margin (over the terminal's duration)."""
        dyn = self.dyn
        assert dyn is not None
        if isinstance(term, ShiftTerminal):
            return dyn.sweep_blocked(term.sweep_points, term.sweep_reach, term.duration)
        return dyn.disc_blocked(
            term.goal_xy,
            float(term.policy.outer_extents(0.0)[0]),
            term.policy.duration,
        )

    def _end_blocked(self) -> bool:
        """Whether known obstacles block the current goal's own end: its trim policy,
        or the approach trim or the terminal of a goal off the lattice."""
        dyn = self.dyn
        if dyn is None:
            return False
        term = self.terminals[self.k_goal]
        if term is None:
            return dyn.is_blocked(self.sequence[self.k_goal])
        return dyn.is_blocked(term.approach) or self._terminal_blocked(term)

    def _retarget(self, p: FloatArray) -> int:
        """Another end of the way to the goal while known obstacles block its own (a
        parked cart next to the goal): of the goal's terminals
        (:meth:`Goals.alternatives`) whose approach trim and swept D' are clear, the one
        with the least cost-to-go from a policy whose S holds ``p`` plus its duration,
        on the trees toward at most :data:`RETARGET_TREES` approach trims without the
        blocked policies (kept until what blocks changes). On success the task ends
        there instead (the tree, the goal trim and the terminal change) and the row to
        run is returned; −1 if none is free. Only for the last goal of a point-to-point
        task, at rest."""
        dyn, hc = self.dyn, self.hc
        if dyn is None or self.loops > 1 or self.k_goal + 1 != len(self.sequence):
            return -1
        g = self.goal_states[self.k_goal]
        if np.any(g[2:] != 0.0):
            return -1
        if self.retarget_seen != len(dyn.replans):
            self.retarget_seen = len(dyn.replans)
            lib = hc.library
            free = [
                t
                for t in hc.goals.alternatives(g)
                if not dyn.is_blocked(t.approach) and not self._terminal_blocked(t)
            ]
            free.sort(key=lambda t: (t.duration, float(lib.durations[t.approach]), t.approach))
            self.retarget_free = free
            self.retarget_trees = {}
        trees = self.retarget_trees
        rows: dict[int, int] = {}  # the policy to run toward each approach trim
        best: tuple[float, Terminal, Any, int] | None = None
        for term in self.retarget_free:
            a = term.approach
            if a not in trees:
                if len(trees) >= RETARGET_TREES:
                    continue
                trees[a] = dyn.retarget(hc.tree(a))
            tree = trees[a]
            if a not in rows:
                rows[a] = hc.best_policy(p, tree)
            row = rows[a]
            if row < 0:
                continue
            cost = float(tree.cost_to_go[row]) + term.duration
            if best is None or cost < best[0]:
                best = (cost, term, tree, row)
        if best is None:
            return -1
        _, term, tree, row = best
        self.sequence[self.k_goal] = term.approach
        self.terminals[self.k_goal] = term
        self.tree = tree
        return row

    # -- balancing mode ------------------------------------------------------------
    def _begin_chunk(self) -> None:
        options = self.options
        if not (self.waited < self.limit - 1e-9 and self.ticks < self.max_ticks):
            self._end_balancing()
            return
        chunk = min(
            options.balance_chunk, self.limit - self.waited, (self.max_ticks - self.ticks) * self.dt
        )
        n = max(1, round(chunk / self.dt))
        x_ref = state_from_position(np.r_[self.hold_xy, 0.0, 0.0], self.r)
        ref_pos = np.zeros((n + 1, 6))
        ref_pos[:, :2] = self.hold_xy
        self.segment = Segment(
            policy=-1,
            ref_states=np.tile(x_ref, (n + 1, 1)),
            ref_inputs=np.zeros((n + 1, 2)),
            ref_pos=ref_pos,
            centers=None,
            shapes=None,
            n=n,
            balance=True,
        )

    def _end_chunk(self, seg: Segment, n: int) -> None:
        dyn, options = self.dyn, self.options
        self.waited += n * self.dt
        if dyn is not None and (np.any(dyn.blocked) or self._end_blocked()):
            self.blocked_time += n * self.dt  # waiting for the way to clear
            if options.resume_from_balancing:  # as long as it takes
                self.limit = max(self.limit, self.waited + options.balance_chunk)
        p = position_state(self.x, self.r)
        t = self.t
        if dyn is not None and dyn.due(t):
            self._look(t, p)
            if not dyn.hold_clear(self.hold_xy, BALANCING_MARGIN + HOLD_MARGIN):
                self.hold_xy = self.hc.recovery_point(p, self.tree, dyn)
        if options.resume_from_balancing and not self.held:
            nxt = self.hc.best_policy(p, self.tree)
            if dyn is not None and self._end_blocked():  # the way is free, not its end
                nxt = self._retarget(p)
            if nxt >= 0:
                self.recovered = nxt
                self._end_balancing()

    def _end_balancing(self) -> None:
        self.balancing = False
        dyn = self.dyn
        if self.recovered < 0:
            if dyn is not None and (np.any(dyn.blocked) or self._end_blocked()):
                self._finish(TaskStatus.BLOCKED)
            elif self.waited < self.limit - 1e-9:
                self._finish(TaskStatus.TIMEOUT)
            else:
                self._finish(TaskStatus.NO_POLICY)
            return
        self._event(self.recovered, EventReason.RECOVERED, frm=-1)
        self.current = self.recovered
        self.recovered = -1
