"""The hybrid controller (paper Sec. IV-C, V-B): execute and switch motion policies,
one control tick at a time.

A timer is reset when a policy starts; a policy starts only if the position
state is in its start domain S; it runs until the timer reaches t_f and the
state is in its goal domain G, then the tree's next policy takes over (G ⊂ S
of the next by construction: a graceful switch). Every control tick the state
is checked against the outer domain D'(t); on exit (a large disturbance) the
current policy stops and the policy with the lowest cost-to-go whose S
contains the state starts, without replanning. If there is none, a verified
catch is placed at the state (:mod:`gracenav.execution.capture`), else the robot
switches to balancing (station-keeping) mode: the only non-graceful switches
are these recoveries.

:meth:`HybridController.step` runs that supervisor per tick on the measured state;
the policies run between switches in *segments* (a policy, or the part of it up to
the next look at the moving obstacles, or a chunk of balancing mode), and at the
end of a segment the same decisions are taken as when whole segments were
simulated at once.
"""

from __future__ import annotations

import math
import time as _time
import weakref
from collections.abc import Sequence
from concurrent.futures import Executor, ThreadPoolExecutor

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.control import CONTROL_RATE, PositionEstimator, TrackingLaw
from gracenav.errors import ConfigError, PlanningError
from gracenav.execution.arrival import ArrivalPlan, arrival_plan, run_to_go, way_time
from gracenav.execution.capture import (
    CapturePlan,
    PlacedPolicy,
    Terminal,
    TerminalPolicy,
    capture_for,
)
from gracenav.execution.episode import Episode, ExecutionLog, drive
from gracenav.execution.goals import ON_LATTICE, Goals
from gracenav.execution.launch import LaunchOptions, confirm_launch, launch_candidates
from gracenav.execution.obstacles import ObstacleTracker
from gracenav.execution.supervisor import BALANCING_MARGIN, Supervisor
from gracenav.execution.types import (
    CAPTURE,
    Command,
    ExecutionOptions,
    TaskStatus,
)
from gracenav.library import PolicyLibrary
from gracenav.params import BallbotParams
from gracenav.planning import CostCriterion, LazyPolicyTree, PolicyTree, plan_tree
from gracenav.planning.graph import PreparesGraph
from gracenav.planning.repair import HOLD_MARGIN
from gracenav.policies import PrimitiveKind, flat_position_state
from gracenav.sim import Disturbance, limit_batch_threads, position_state
from gracenav.sim.plant import Plant
from gracenav.world.moving import MovingObstacle

__all__ = ["HybridController"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

#: Nearest rest-trim starts balancing mode considers as the point to hold.
_BALANCING_SEARCH = 64
#: Most policies a lazy tree closes to find where balancing mode holds the robot.
_LAZY_RECOVERY_BUDGET = 200_000
#: Trees toward at most this many approach trims are searched for a start that reaches
#: neither the goal's trim nor its terminals (:meth:`HybridController._other_end`).
_START_TREES = 8


class HybridController:
    """Executes navigation tasks with a policy library, its graph and single-goal trees.

    Parameters
    ----------
    library : PolicyLibrary
    graph : PreparesGraph
    criterion : {"time", "distance"}
        Optimality criterion of the trees.
    params : BallbotParams, optional
        The robot as the controller knows it (default: the palette's, which its gains
        were designed for): its ball radius turns measured angles into position states
        for every decision (domain membership, the goal test, captures). The plant's
        true parameters are the plant's own (:meth:`run`'s ``plant``) and may differ
        (model mismatch).

    Notes
    -----
    Per tick: :meth:`reset` starts a task, then :meth:`step` is called once every
    control tick (:attr:`control_rate`) with the measured state and returns the
    torque to hold until the next tick. :meth:`run` is such a loop over a simulated
    (or a user's) :class:`~gracenav.sim.Plant`.
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
        # Terminal regulators are shared by every controller on the same library.
        self.goals = Goals(library)
        self.tree_seconds: list[float] = []
        self.dt = 1.0 / CONTROL_RATE
        self.radius = float(self.gains.params.ball_radius)
        self.law = TrackingLaw(self.gains)
        self._task: Supervisor | None = None
        self._estimator: PositionEstimator | None = None
        self._executor: ThreadPoolExecutor | None = None

    @property
    def whole_trees(self) -> bool:
        """Whether trees are whole (:func:`plan_tree`) rather than lazy: the graph keeps
        its reversed graph (:meth:`PreparesGraph.search_form`)."""
        return self._adjacency is not self.graph

    def planning_executor(self) -> Executor:
        """The worker thread of ``planning="threaded"`` (:class:`ExecutionOptions`),
        started on first use and stopped by :meth:`close` (or when the controller is
        collected)."""
        if self._executor is None:
            # It plans beside the control loop: its verifications keep to one core.
            self._executor = ThreadPoolExecutor(
                max_workers=1,
                thread_name_prefix="gracenav-plan",
                initializer=limit_batch_threads,
                initargs=(1,),
            )
            weakref.finalize(self, self._executor.shutdown, wait=False)
        return self._executor

    def close(self) -> None:
        """Stop the planning thread, if one was started (waits for a running plan)."""
        if self._executor is not None:
            self._executor.shutdown(wait=True)
            self._executor = None

    @property
    def control_rate(self) -> float:
        """The rate (Hz) :meth:`step` must be called at: the palette's verification rate."""
        return CONTROL_RATE

    # -- planning ------------------------------------------------------------------
    def goal_policy(self, goal: ArrayLike) -> int:
        """The library row a task toward ``goal`` ends on (:meth:`Goals.goal_policy`).

        Raises
        ------
        PlanningError
            The goal is outside the map, in an obstacle or outside coverage.
        """
        return self.goals.goal_policy(goal)

    def terminal_policies(self, goal: ArrayLike) -> tuple[Terminal, ...]:
        """Terminals (capture regulators, else shifts) for a goal at rest off the
        lattice, best first (:meth:`Goals.terminal_policies`)."""
        return self.goals.terminal_policies(goal)

    def _terminal(self, goal: ArrayLike, goal_id: int) -> Terminal | None:
        return self.goals.terminal(goal, goal_id)

    def tree(self, goal_policy: int) -> PolicyTree | LazyPolicyTree:
        """The single-goal optimal tree toward library row ``goal_policy`` (cached).

        The whole tree (:func:`plan_tree`) when the graph keeps its reversed graph
        (:meth:`PreparesGraph.search_form`, up to :data:`gracenav.planning.graph.STORED_EDGES`
        edges); above that, a :class:`LazyPolicyTree` that :meth:`best_policy` and
        :meth:`recovery_point` settle where they read it (a whole tree there takes
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

    def recovery_point(
        self,
        p: FloatArray,
        tree: PolicyTree | LazyPolicyTree,
        dyn: ObstacleTracker | None = None,
    ) -> FloatArray:
        """Where balancing mode holds the robot: the start of the nearest rest trim of
        the library that reaches the goal and that the robot can be driven to without
        driving toward an obstacle: along the straight segment from the robot to it
        (sampled every map cell) the clearance stays at least the footprint plus
        :data:`BALANCING_MARGIN`, or the robot's own clearance if that is smaller. The
        current position if none of the :data:`_BALANCING_SEARCH` nearest qualifies.
        With moving obstacles (``dyn``), a point or a segment a known obstacle may reach
        within :data:`gracenav.planning.repair.HOLD_HORIZON` is not a candidate either, and
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
        # The fine copies' rest trims (near obstacles, narrow D') only when no other
        # will do: balancing mode is not verified, and waits longer than a rest trim.
        fine = self.library.is_fine
        passes = [r[~fine(r)] for r in passes] + [r[fine(r)] for r in passes]
        wm = self.library.world_map
        # A robot already nearer than that to an obstacle may not get any nearer.
        need = min(
            self.library.footprint_radius + BALANCING_MARGIN,
            float(wm.clearance(here[None, :])[0]),
        )
        step = float(wm.resolution)
        for rest in passes:
            xy = self.library.start_xy[rest]
            if dyn is not None:  # only points clear of the obstacles' predicted motion
                xy = xy[dyn.points_clear(xy, BALANCING_MARGIN + HOLD_MARGIN)]
            order = np.argsort(np.linalg.norm(xy - here, axis=1), kind="stable")
            for q in xy[order[:_BALANCING_SEARCH]]:
                n = max(2, int(np.ceil(np.linalg.norm(q - here) / step)) + 1)
                seg = here + np.linspace(0.0, 1.0, n)[:, None] * (q - here)
                if np.all(wm.clearance(seg[1:]) >= need) and (
                    dyn is None or dyn.path_clear(here, seg[1:], BALANCING_MARGIN + HOLD_MARGIN)
                ):
                    return np.asarray(q, dtype=float)
        return here

    def capture_plan(
        self, x: ArrayLike, tree: PolicyTree | LazyPolicyTree | None
    ) -> CapturePlan | None:
        """The cheapest verified capture (catch, shift, rest trim toward the tree's goal)
        of the model state ``x`` (8,), or None (see :class:`gracenav.execution.capture.Capture`).
        Settled and still catches are considered when the lean and lean rate (norms
        over both axes) are within their band of upright; the pushed ones test the
        flat output's position state (catches start upright). ``tree`` None: any
        verified capture, whether or not its rest trim has a way to a goal."""
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
            cost_to_go=None if tree is None else tree.cost_to_go,
            settle=settle,
            flat_state=flat,
        )

    def _other_end(
        self, x: FloatArray, goal: ArrayLike, *, capture: bool
    ) -> tuple[Terminal, PolicyTree | LazyPolicyTree, int, CapturePlan | None] | None:
        """For a start that reaches neither the goal's trim nor its terminals: the
        cheapest of the goal's other terminals (:meth:`Goals.alternatives`, a goal at
        rest only) that a policy whose S holds the start reaches, or else that a
        capture of the start reaches, with trees toward at most :data:`_START_TREES`
        approach trims: (terminal, tree, row or :data:`CAPTURE`, capture plan)."""
        g = np.asarray(goal, dtype=float)
        if np.any(g[2:] != 0.0):
            return None
        p = position_state(x, self.radius)
        trees: dict[int, PolicyTree | LazyPolicyTree] = {}
        best: tuple[float, Terminal, int] | None = None
        for cand in self.goals.alternatives(g):
            a = cand.approach
            if a not in trees:
                if len(trees) >= _START_TREES:
                    continue
                trees[a] = self.tree(a)
            row = self.best_policy(p, trees[a])
            if row >= 0:
                cost = float(trees[a].cost_to_go[row]) + cand.duration
                if best is None or cost < best[0]:
                    best = (cost, cand, row)
        if best is not None:
            return best[1], trees[best[1].approach], best[2], None
        if not capture:
            return None
        caught: tuple[float, Terminal, CapturePlan] | None = None
        plans: dict[int, CapturePlan | None] = {}
        for cand in self.goals.alternatives(g):
            tree = trees.get(cand.approach)
            if tree is None:
                continue
            if cand.approach not in plans:
                plans[cand.approach] = self.capture_plan(x, tree)
            plan = plans[cand.approach]
            if plan is not None and (caught is None or plan.cost + cand.duration < caught[0]):
                caught = (plan.cost + cand.duration, cand, plan)
        if caught is None:
            return None
        return caught[1], trees[caught[1].approach], CAPTURE, caught[2]

    def _start_price(
        self,
        tree: PolicyTree | LazyPolicyTree,
        current: int,
        plan: CapturePlan | None,
        *,
        skip_holds: bool,
    ) -> float | None:
        """What the start costs where a maneuver designed at the start
        (:func:`gracenav.execution.launch.launch_candidates`) may replace it: a capture or a
        capture regulator, priced as it runs, or nothing (inf); None where it may not.

        The capture is priced as it runs: its plan's cost less, with ``skip_holds``, the
        rest trim it ends on when that is skipped (the policy after it starts at once)
        and the last stage's rest tail when the policy after the rest trim is verified
        from the still band (it is left as soon as the lean is in the band, within the
        tail). The regulator is priced at its cost-to-go less the rest trim after it
        when that is skipped. (The trees price every hold in full; compared in full,
        the capture of ``random_pairs.yaml`` trial 1, which runs 0.4 s faster than the
        maneuver, was priced 1.6 s higher.)"""
        lib = self.library
        if current == CAPTURE and plan is not None:
            budget = plan.cost
            row = plan.rest_row
        elif current >= 0 and lib.policy(current).policy.capture:
            budget = float(tree.cost_to_go[current])
            row = int(tree.next_policy[current])
        elif current < 0 and plan is None:
            return math.inf
        else:
            return None
        if skip_holds and row >= 0 and lib.policy(row).policy.primitive.kind is PrimitiveKind.REST:
            after = int(tree.next_policy[row])
            if after >= 0 and after != row:
                budget -= lib.policy(row).duration
                catch = lib.palette.options.catch
                if (
                    current == CAPTURE
                    and catch is not None
                    and lib.policy(after).policy.starts_from_still_band
                ):
                    budget -= catch.tail
        return budget

    def _launches(
        self,
        x: FloatArray,
        tree: PolicyTree | LazyPolicyTree,
        budget: float,
        *,
        maneuvers: bool,
        run: FloatArray,
    ) -> tuple[CapturePlan, ...]:
        """The maneuvers from the start (:func:`gracenav.execution.launch.launch_candidates`)
        onto cruise trims, or with ``maneuvers`` onto any policy that starts at a cruise
        state, priced below ``budget``, sized in the order of what their ways ``run``
        (:func:`gracenav.execution.arrival.run_to_go`), cheapest first; not yet verified
        from the still band (:func:`~gracenav.execution.launch.confirm_launch`)."""
        lean = (float(np.hypot(*x[2:4])), float(np.hypot(*x[6:8])))
        p = position_state(x, self.radius)
        opts = LaunchOptions(maneuvers=maneuvers)
        return launch_candidates(
            self.library, p, lean, tree.cost_to_go, budget, opts, run_to_go=run
        )

    def _arrival(
        self,
        goal: ArrayLike,
        terminal: Terminal | None,
        way: list[int],
        *,
        skip_holds: bool,
    ) -> ArrivalPlan | None:
        """The end maneuver (:func:`gracenav.execution.arrival.arrival_plan`) on ``way``
        (the tree's way from the first library policy the task runs) to a goal at rest:
        the goal policy's point, or off the lattice the capture regulator the
        ``terminal`` places there; None where there is none or it does not pay."""
        g = np.asarray(goal, dtype=float)
        if np.any(g[2:] != 0.0):
            return None
        if terminal is None:
            if np.linalg.norm(self.library.start_xy[way[-1]] - g[:2]) > ON_LATTICE:
                return None
            return arrival_plan(self.library, way, skip_holds=skip_holds)
        if terminal.approach != way[-1]:
            return None
        # The capture regulator at the goal: the terminal, or the hold after its shifts
        # (which the maneuver saves: all but the last one's rest tail, which the hold
        # takes over with skip_holds).
        lead = 0.0
        hold: PlacedPolicy
        if isinstance(terminal, TerminalPolicy):
            hold = terminal
        else:
            hold = terminal.hold
            lead = sum(s.duration for s in terminal.shifts)
            catch = self.library.palette.options.catch
            if skip_holds and catch is not None:
                lead -= catch.tail
        if not hold.policy.capture or np.linalg.norm(hold.start_xy - g[:2]) > ON_LATTICE:
            return None
        return arrival_plan(self.library, way, hold=hold, lead=lead, skip_holds=skip_holds)

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
    def reset(
        self,
        x0: ArrayLike,
        goals: Sequence[ArrayLike],
        *,
        loops: int = 1,
        options: ExecutionOptions | None = None,
        moving_obstacles: Sequence[MovingObstacle] = (),
    ) -> None:
        """Start a task from the measured state ``x0``: reach ``goals`` in order,
        ``loops`` times (surveillance), or one goal once (point-to-point). Plans the
        first tree (and, when no library policy's start domain holds ``x0``, a catch)
        before it returns; call it before the control loop starts.

        Parameters
        ----------
        x0 : array_like, shape (8,)
            Measured state (:class:`gracenav.model.Ballbot3D` convention).
        goals : sequence of array_like, shape (4,)
            Goal position states (x, y, ẋ, ẏ) (m, m/s): rest goals for point-to-point,
            moving goals (cruise velocities) for surveillance.
        loops : int
            How many times to go through ``goals``.
        options : ExecutionOptions, optional
        moving_obstacles : sequence of MovingObstacle
            Obstacles not in the map, which the controller learns of within its sensing
            range (``options.sensing``): it then blocks the policies they may meet,
            repairs the tree every sensing period, switches away from a policy that
            becomes blocked while it runs, and holds an unblocked rest trim while no
            way to the goal is free (:mod:`gracenav.planning.repair`).

        Raises
        ------
        ConfigError
            Malformed arguments.
        PlanningError
            A goal is impossible, or the first goal is unreachable from the start.
        """
        options = options if options is not None else ExecutionOptions()
        if loops < 1:
            raise ConfigError(f"loops must be >= 1, got {loops!r}")
        if len(goals) == 0:
            raise ConfigError("a task needs at least one goal")
        x = np.array(x0, dtype=float)
        if x.shape != (8,) or not np.all(np.isfinite(x)):
            raise ConfigError(f"a start state is a finite array of shape (8,), got {x0!r}")
        self._task = None
        self._estimator = None
        if options.position_filter:
            sensor = options.simulation
            self._estimator = PositionEstimator(
                self.radius,
                self.dt,
                sensor.position_noise_std,
                sensor.velocity_noise_std,
            )
            x = self._estimator.reset(x)
        goal_ids = [self.goal_policy(g) for g in goals]
        terminals: list[Terminal | None] = [
            self._terminal(g, i) for g, i in zip(goals, goal_ids, strict=True)
        ]
        p = position_state(x, self.radius)
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
        if dyn is not None and current >= 0:
            tree = dyn.update(0.0, p[:2], tree)
            current = self.best_policy(p, tree)
            if current < 0:
                current = dyn.hold_policy(p)
                holding = current >= 0
        if options.capture:
            capture_for(self.library)  # built once per library, here rather than mid-task
        plan = None
        if current < 0 and options.capture and dyn is None:
            # A start inside no library S may lie in a catch's (coverage counts it).
            plan = self.capture_plan(x, tree)
            if plan is not None:
                current = CAPTURE
        if current < 0 and plan is None and dyn is None and len(goals) == 1:
            # Nor through the goal's own terminals: through any other end of the way.
            other = self._other_end(x, goals[0], capture=options.capture)
            if other is not None:
                cand, tree, current, plan = other
                goal_ids, terminals = [cand.approach], [cand]
        # The ways to start: as found, or through any of the maneuvers designed at the
        # start onto cruise trims or onto policies from a cruise state (the few whose
        # ways run soonest, each a candidate). Each is priced as it runs
        # (its way from the first library policy, a lazy tree read along it, by the
        # durations that run, not as the tree prices it: fine copies at twice their
        # duration, holds in full), less what an end designed online saves on it; the
        # cheapest is taken.
        price = None
        if options.online_starts and dyn is None and len(goals) == 1:
            # Priced against whatever the start takes otherwise, that other end included
            # (unpriced only where nothing else serves the start).
            price = self._start_price(tree, current, plan, skip_holds=options.skip_holds)
        starts: list[tuple[float, CapturePlan | None, int]] = [
            (price if price is not None else 0.0, plan, current)
        ]
        launched: dict[int, int] = {}  # starts designed online: row launched onto -> index
        if price is not None:
            ways_run = run_to_go(
                self.library, tree.next_policy, tree.cost_to_go, skip_holds=options.skip_holds
            )
            for maneuvers in (True, False):
                for online in self._launches(x, tree, price, maneuvers=maneuvers, run=ways_run):
                    if online.rest_row not in launched:
                        launched[online.rest_row] = len(starts)
                        starts.append((online.cost, online, CAPTURE))
        ends = options.online_ends and dyn is None and len(goals) == 1 and loops == 1
        arrival = None
        if ends or len(starts) > 1:
            # Each way priced as it runs, less what its end saves; the cheapest taken,
            # a start designed online once it is verified from the still band too.
            priced: list[tuple[float, int, ArrivalPlan | None]] = []
            for k, (cost, way_plan, way_current) in enumerate(starts):
                first = way_plan.rest_row if way_current == CAPTURE and way_plan else way_current
                end = None
                if first >= 0 and tree.reachable(first):
                    way = tree.path_from(first)
                    run = way_time(self.library, way, skip_holds=options.skip_holds)
                    cost += run - float(tree.cost_to_go[first])
                    if ends:
                        skip = options.skip_holds
                        end = self._arrival(goals[0], terminals[0], way, skip_holds=skip)
                priced.append((cost - (end.saving if end is not None else 0.0), k, end))
            for _, k, end in sorted(priced, key=lambda c: (c[0], c[1])):
                chosen, chosen_current = starts[k][1], starts[k][2]
                if k in launched.values() and chosen is not None:
                    chosen = confirm_launch(self.library, chosen)
                    if chosen is None:
                        continue
                plan, current, arrival = chosen, chosen_current, end
                break
        else:
            _, plan, current = min(starts, key=lambda s: s[0])
        if current < 0 and plan is None:
            hits = self.library.start_domain_contains(p[None, :])
            caught = options.capture and dyn is None  # a catch at the start was tried
            if hits.nnz == 0 and caught and self.capture_plan(x, None) is not None:
                why = (
                    "no library policy's start domain contains the start state, and the rest "
                    "trims that a catch and at most two shifts with their swept outer domains "
                    "clear reach from it have no way to the goal (near walls a rest trim may "
                    "have no way out that fits); move the start or use more lattice halvings"
                )
            elif hits.nnz == 0:
                why = (
                    "no library policy's start domain contains the start state, and no catch "
                    "placed there clears the obstacles (outside coverage)"
                )
            else:
                why = "the goal cannot be reached from any policy whose start domain contains it"
                if caught:
                    why += (
                        ", nor from a rest trim of the library that a catch and at most two "
                        "shifts reach from the start with their swept outer domains clear (near "
                        "walls a rest trim may have no way out that fits); move the start or "
                        "use more lattice halvings"
                    )
            where = ", ".join(f"{v:.3g}" for v in p)
            raise PlanningError(f"start ({where}): {why}")
        self._task = Supervisor(
            self,
            options,
            sequence=goal_ids * loops,
            terminals=terminals * loops,
            goal_states=[np.asarray(g, dtype=float) for g in goals] * loops,
            tree=tree,
            current=current,
            dyn=dyn,
            holding=holding,
            capture_plan=plan,
            arrival=arrival,
            loops=loops,
        )

    def step(self, t: float, x: ArrayLike, *, held: bool = False) -> Command:
        """The command for one control tick.

        Parameters
        ----------
        t : float
            Time (s) of this tick since the task started (:meth:`reset` is tick 0).
            Call once a tick, at :attr:`control_rate`; a tick the caller missed (``t``
            ahead by more than half a period) moves the reference on as well.
        x : array_like, shape (8,)
            Measured state (its ball position filtered first when
            ``ExecutionOptions.position_filter``: :class:`~gracenav.control.PositionEstimator`).
        held : bool
            An external force known to act on the robot (a hand holding it): balancing
            mode does not hand back to a policy while it acts.

        Returns
        -------
        Command
            Torque to hold until the next tick, and whether the task has ended.

        Raises
        ------
        ConfigError
            Before :meth:`reset`.
        """
        if self._task is None:
            raise ConfigError("HybridController.step before reset(): start a task first")
        y = np.asarray(x, dtype=float)
        if self._estimator is not None:
            y = self._estimator.update(y)
        return self._task.tick(float(t), y, held)

    def log(self) -> ExecutionLog:
        """What the task has kept so far besides the samples: switch events, goals
        reached, tree times, repairs, captures, its status."""
        if self._task is None:
            raise ConfigError("no task: call reset() first")
        return self._task.log(tuple(self.tree_seconds))

    @property
    def status(self) -> TaskStatus:
        """The task's status (:attr:`TaskStatus.RUNNING` until it ends)."""
        if self._task is None:
            raise ConfigError("no task: call reset() first")
        return self._task.status

    def run(
        self,
        x0: ArrayLike,
        goals: Sequence[ArrayLike],
        *,
        loops: int = 1,
        disturbances: Sequence[Disturbance] = (),
        options: ExecutionOptions | None = None,
        moving_obstacles: Sequence[MovingObstacle] = (),
        plant: Plant | None = None,
    ) -> Episode:
        """Execute a task in simulation: :meth:`reset`, then :meth:`step` every tick on
        ``plant`` (:func:`gracenav.execution.drive`) until the task ends.

        Parameters
        ----------
        x0 : array_like, shape (8,)
            Initial plant state (the controller is given the plant's measurement of it).
        goals, loops, options, moving_obstacles
            As :meth:`reset`.
        disturbances : sequence of Push, BodyForce, StateJump, Drag
            In episode time (the plant must take them: :class:`gracenav.sim.DisturbablePlant`).
        plant : Plant, optional
            Default: ``options.plant`` with the palette's parameters and
            ``options.simulation``'s substeps and noise.

        Raises
        ------
        PlanningError
            A goal is impossible, or the first goal is unreachable from the start.
        """
        options = options if options is not None else ExecutionOptions()
        if plant is None:
            sim = options.simulation
            plant = sim.plant(options.plant, self.palette.params)
        plant.reset(np.asarray(x0, dtype=float))
        self.reset(
            plant.measure(),
            goals,
            loops=loops,
            options=options,
            moving_obstacles=moving_obstacles,
        )
        assert self._task is not None
        trace = drive(
            self,
            plant,
            dt=self.dt,
            max_ticks=self._task.max_ticks + 1,
            disturbances=disturbances,
        )
        return Episode.from_trace(trace, self.log(), moving_obstacles)
