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
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from gracenav.capture import CapturePlan, PlacedPolicy
from gracenav.control import ControllerGains
from gracenav.execution.episode import ExecutionLog
from gracenav.execution.types import (
    CAPTURE,
    TERMINAL,
    Command,
    EventReason,
    ExecutionOptions,
    SwitchEvent,
    TaskStatus,
)
from gracenav.policies import PrimitiveKind, instantiated_reference
from gracenav.replanning import HOLD_MARGIN, ObstacleTracker
from gracenav.simulate import position_state, state_from_position

if TYPE_CHECKING:
    from gracenav.execution.controller import HybridController, TerminalPolicy
    from gracenav.planning import LazyPolicyTree, PolicyTree

__all__ = ["Supervisor", "TrackingLaw"]

FloatArray = NDArray[np.float64]

#: Policies in a row that may end at their first tick (an instantaneous disturbance at
#: a switch can do that once) before the task stops with TaskStatus.NO_PROGRESS.
MAX_STALLED_SEGMENTS = 8
#: Clearance (m) beyond the footprint that balancing mode keeps on its way to the
#: point it holds (see HybridController.recovery_point).
BALANCING_MARGIN = 0.05

_NO_CENTER = np.zeros((0,))
_NO_SHAPE = np.zeros((0, 0))


class TrackingLaw:
    """The Fig. 2 cascade of the palette's gains, one tick at a time (compiled)."""

    def __init__(self, gains: ControllerGains) -> None:
        from gracenav.model.ballbot3d import Ballbot3D
        from gracenav.model.friction import friction_constants

        p = gains.params
        self.radius = float(Ballbot3D(p).constants()[0])
        self.friction = friction_constants(p)
        self.k = gains.kernel_arrays()
        self.max_comp = float(gains.max_lean_compensation)
        self.friction_comp = bool(gains.friction_compensation)
        self.torque_limit = float(p.torque_limit)

    def __call__(
        self, x: FloatArray, x_ref: FloatArray, tau_ff: FloatArray, c: FloatArray, shape: FloatArray
    ) -> tuple[FloatArray, float]:
        """Saturated torque (2,) and the D'(t) value of ``x`` (0 without a domain)."""
        from gracenav import _kernels

        out = np.empty(2)
        val = _kernels.tracking_tick(
            self.radius,
            self.friction,
            self.k,
            self.max_comp,
            self.friction_comp,
            self.torque_limit,
            x,
            x_ref,
            tau_ff,
            c,
            shape,
            out,
        )
        return out, float(val)


@dataclass
class _Segment:
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
    k: int = 0


class Supervisor:
    """One task of a :class:`~gracenav.execution.HybridController`, tick by tick.

    Built by :meth:`HybridController.reset`, which has checked the goals and chosen
    the first policy (``current``; :data:`CAPTURE` with ``capture_plan``).
    """

    def __init__(
        self,
        hc: HybridController,
        options: ExecutionOptions,
        *,
        sequence: list[int],
        terminals: list[TerminalPolicy | None],
        goal_states: list[FloatArray],
        tree: PolicyTree | LazyPolicyTree,
        current: int,
        dyn: ObstacleTracker | None,
        holding: bool,
        capture_plan: CapturePlan | None,
        loops: int,
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
        self.captured: list[PlacedPolicy] = []
        self.capture_plans: list[tuple[float, CapturePlan]] = []
        self.capture_row = -1
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
        self.segment: _Segment | None = None
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
            lean_ok = abs(x[2]) <= self.fall_lean and abs(x[3]) <= self.fall_lean
            if not lean_ok:  # also a state that is no longer finite
                self.segment = None
                self._finish(TaskStatus.FELL)
                break
            if seg.centers is not None:
                assert seg.shapes is not None
                tau, val = self.law(
                    x, seg.ref_states[k], seg.ref_inputs[k], seg.centers[k], seg.shapes[k]
                )
            else:
                tau, val = self.law(x, seg.ref_states[k], seg.ref_inputs[k], _NO_CENTER, _NO_SHAPE)
            exited = val > 1.0
            if exited or k == seg.n:
                self.segment = None
                if seg.balance:
                    self._end_chunk(seg, k)
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

    def _finish(self, status: TaskStatus) -> None:
        self.status = status
        hold = state_from_position(np.r_[position_state(self.x, self.r)[:2], 0.0, 0.0], self.r)
        self.hold_final = hold if status is not TaskStatus.FELL else None

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
            replans=tuple(self.dyn.replans) if self.dyn is not None else (),
            blocked_time=self.blocked_time,
            captures=tuple(self.capture_plans),
        )

    # -- segments ------------------------------------------------------------------
    def _begin(self) -> None:
        """Start what runs next at this tick (a policy segment or a balancing chunk)."""
        if self.balancing:
            self._begin_chunk()
            return
        if self.ticks >= self.max_ticks:
            self._finish(TaskStatus.TIMEOUT)
            return
        hc, dt = self.hc, self.dt
        current = self.current
        term = self.terminals[self.k_goal]
        if current == CAPTURE or (current == TERMINAL and term is not None):
            placed = self.captured[0] if current == CAPTURE else term
            assert placed is not None
            prim = placed.primitive
            ref, ref_pos = placed.reference(self.r)
            _, shapes = placed.outer_monitor()
            is_goal = False
        else:
            inst = hc.library.policy(current)
            prim = inst.policy.primitive
            ref, ref_pos = instantiated_reference(prim, inst.orientation, inst.start_xy, self.r)
            # Domain shapes are invariant under rotations of the plane: only the
            # centres move with the instantiation.
            _, shapes = inst.policy.outer_monitor()
            is_goal = current == self.sequence[self.k_goal]
        if is_goal and self.k_goal + 1 < len(self.sequence):
            # Regenerate the tree for the next goal while the last policy to the
            # current goal runs (paper Sec. V-C).
            hc.tree(self.sequence[self.k_goal + 1])
        remaining = prim.num_ticks - self.offset
        n_seg = min(remaining, self.max_ticks - self.ticks)
        truncated = n_seg < remaining
        split = False  # the segment ends at the next look at the moving obstacles
        dyn = self.dyn
        if dyn is not None and dyn.ticks_to_next(self.t, dt) < n_seg:
            n_seg, split, truncated = dyn.ticks_to_next(self.t, dt), True, False
        part = slice(self.offset, self.offset + n_seg + 1)
        self.segment = _Segment(
            policy=current,
            ref_states=ref.states[part],
            ref_inputs=ref.inputs[part],
            ref_pos=ref_pos[part],
            centers=np.ascontiguousarray(ref_pos[part, :4]),
            shapes=np.ascontiguousarray(shapes[part]),
            n=n_seg,
            truncated=truncated,
            split=split,
            is_goal=is_goal,
        )

    def _event(self, to: int, reason: EventReason, frm: int | None = None) -> None:
        f = self.current if frm is None else frm
        self.events.append(SwitchEvent(self.t, f, to, reason, self.ticks))

    def _end_segment(self, seg: _Segment, last: int, exited: bool) -> None:
        """The switching rules at the end of a policy segment of ``last`` ticks."""
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
            if dyn.due(t):
                self.tree = dyn.update(t, p[:2], self.tree)
            if self.holding:
                free_row = hc.best_policy(p, self.tree)
                if free_row >= 0:  # the way is free again
                    self._event(free_row, EventReason.RESUMED)
                    self.current, self.offset, self.holding = free_row, 0, False
                    return
            if seg.split and completed:
                self.offset += last
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
                    or (self.holding and not dyn.hold_row_clear(current))
                )
                if not blocked_now:
                    return  # the same policy goes on
                self.offset = 0
                nxt = hc.best_policy(p, self.tree)
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
        if row == -1 and dyn is not None and np.any(dyn.blocked):
            wait_row = dyn.hold_policy(p)
            if wait_row >= 0:  # obstacles block the way: wait on a free rest trim
                self._event(wait_row, EventReason.BLOCKED)
                self.current, self.holding = wait_row, True
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
            # Balancing mode: station keeping at the nearest rest-trim start of the
            # library from which the goal is reachable, checking every chunk whether
            # some policy's S now contains the state; the task stops if none does
            # within ``balance_time``.
            self._event(-1, EventReason.BALANCING)
            self.hold_xy = hc.recovery_point(p, self.tree, dyn)
            self.waited = 0.0
            self.recovered = -1
            self.limit = options.balance_time
            self.balancing = True
            return
        self._event(row, reason)
        self.current = row

    def _next_policy(
        self, seg: _Segment, p: FloatArray, exited: bool
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
            return EventReason.DOMAIN_EXIT, hc.best_policy(p, self.tree)
        if current == CAPTURE:
            if self.captured[0].goal_domain.contains(p):
                self.captured.pop(0)
                if self.captured:
                    return EventReason.GRACEFUL, CAPTURE
                nxt = self.capture_row
                if not hc.library.policy(nxt).start_domain.contains(p):
                    return EventReason.NOT_IN_GOAL, hc.best_policy(p, self.tree)
                return EventReason.GRACEFUL, nxt
            return EventReason.NOT_IN_GOAL, hc.best_policy(p, self.tree)
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
        if seg.is_goal and term is not None:
            # Off-lattice goal: the terminal regulator takes over from the rest trim.
            if term.start_domain.contains(p):
                return EventReason.TERMINAL, TERMINAL
            return EventReason.HOLD_GOAL, current
        if seg.is_goal:
            self.goals_reached.append((self.t, self.k_goal))
            if self.k_goal + 1 < len(self.sequence):
                self.k_goal += 1
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
        return EventReason.GRACEFUL, nxt

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
        self.segment = _Segment(
            policy=-1,
            ref_states=np.tile(x_ref, (n + 1, 1)),
            ref_inputs=np.zeros((n + 1, 2)),
            ref_pos=ref_pos,
            centers=None,
            shapes=None,
            n=n,
            balance=True,
        )

    def _end_chunk(self, seg: _Segment, n: int) -> None:
        dyn, options = self.dyn, self.options
        self.waited += n * self.dt
        if dyn is not None and np.any(dyn.blocked):
            self.blocked_time += n * self.dt  # waiting for the way to clear
            if options.resume_from_balancing:  # as long as it takes
                self.limit = max(self.limit, self.waited + options.balance_chunk)
        p = position_state(self.x, self.r)
        t = self.t
        if dyn is not None and dyn.due(t):
            self.tree = dyn.update(t, p[:2], self.tree)
            if not dyn.hold_clear(self.hold_xy, BALANCING_MARGIN + HOLD_MARGIN):
                self.hold_xy = self.hc.recovery_point(p, self.tree, dyn)
        if options.resume_from_balancing and not self.held:
            nxt = self.hc.best_policy(p, self.tree)
            if nxt >= 0:
                self.recovered = nxt
                self._end_balancing()

    def _end_balancing(self) -> None:
        self.balancing = False
        dyn = self.dyn
        if self.recovered < 0:
            if dyn is not None and np.any(dyn.blocked):
                self._finish(TaskStatus.BLOCKED)
            elif self.waited < self.limit - 1e-9:
                self._finish(TaskStatus.TIMEOUT)
            else:
                self._finish(TaskStatus.NO_POLICY)
            return
        self._event(self.recovered, EventReason.RECOVERED, frm=-1)
        self.current = self.recovered
        self.recovered = -1
