"""Starts at rest through one maneuver designed and verified at the start (a gracenav
extension, off by default: :attr:`~gracenav.execution.ExecutionOptions.online_starts`).

A task that starts at rest off the lattice reaches it through a capture (a shift onto a
rest trim, then a maneuver from rest) or a capture regulator. One maneuver from the start
itself onto the state of a library cruise trim ahead does both at once
(``bench/bench_starts.py``: 1.875–2.75 s against 3.67–4.20 s). The palette cannot hold
it (the start is anywhere), so it is made when the task starts as the palette's
maneuvers and policies are made, in the one frame it runs in (the palette's are planned
and verified at a second placement too, a quarter turn, since the library places them
at every quarter turn): the nonic from rest at the start to the trim's start state, the
shortest on the palette's duration grid that the shape trajectory planner makes
feasible on the 3D model within the palette's lean and torque limits
(:mod:`gracenav.primitives.design`); its start domain sized by bisection and verified on
the 3D model from points on the surface of S (:func:`gracenav.policies.size_policy`), and
from the still band (:func:`gracenav.policies.catches.verify_still_start`). It is used
only where S holds the start, the trim's S holds its G (exact ellipsoid containment, the
prepares relation), its swept D' grown by the footprint is clear of the map, and its
duration plus the trim's cost-to-go is below what the start costs otherwise. It runs as
a capture whose last policy is followed by that trim (:class:`CapturePlan`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from gracenav.execution.capture import CapturePlan, PlacedPolicy, capture_for
from gracenav.policies import PrimitiveKind, domain_shape, size_policy
from gracenav.policies.catches import verify_still_start
from gracenav.policies.primitive import SampledPrimitive
from gracenav.primitives.design import passes_screen
from gracenav.primitives.motion import Maneuver, PrimitiveReport
from gracenav.primitives.references import NonicReference
from gracenav.primitives.shape_planner import plan_shape_trajectory

if TYPE_CHECKING:
    from gracenav.library import PolicyLibrary
    from gracenav.palette import Palette

__all__ = ["LaunchOptions", "launch_plan"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class LaunchOptions:
    """Which library cruise trims a start may be launched onto.

    Parameters
    ----------
    ahead : (float, float)
        Range (m) of the trim's start point ahead of the start, along the trim's
        direction of travel.
    across : float
        Largest distance (m) of the trim's start point across its direction of travel.
    candidates : int
        Trims designed and verified at most, cheapest first by cost-to-go and distance
        (a 3D plan, about 0.02 s, and the sizing of S, about 0.8 s, each; the still
        band's verification, about 2 s, only for one that would be chosen).
    """

    ahead: tuple[float, float] = (0.45, 1.0)
    across: float = 0.3
    candidates: int = 4


def launch_plan(
    library: PolicyLibrary,
    state: FloatArray,
    lean: tuple[float, float],
    cost_to_go: FloatArray,
    budget: float,
    options: LaunchOptions | None = None,
) -> CapturePlan | None:
    """The cheapest verified maneuver from the start ``state`` (x, y, ẋ, ẏ, the ball's)
        onto a library cruise trim (not a fine copy: its smaller domains leave sensor noise
    less room), as a capture plan priced below ``budget`` (s), or None.

        ``lean`` is the measured lean and lean rate (norms, rad and rad/s): a launch starts
        only within the still band it is verified from (``CatchOptions.still_lean``).
        ``cost_to_go`` is the tree's, by library row.
    """
    opts = options if options is not None else LaunchOptions()
    palette = library.palette
    catch = palette.options.catch
    p = np.asarray(state, dtype=float).reshape(4)
    if catch is None or lean[0] > catch.still_lean[0] or lean[1] > catch.still_lean[1]:
        return None
    start = p[:2]
    rows = library.trim_indices(PrimitiveKind.CRUISE)
    rows = rows[np.isfinite(cost_to_go[rows]) & ~library.is_fine(rows)]
    v = library.start_state[rows, 2:4]
    speed = np.hypot(v[:, 0], v[:, 1])
    u = v / speed[:, None]
    w = library.start_xy[rows] - start
    ahead = np.sum(w * u, axis=1)
    across = u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0]
    near = (ahead >= opts.ahead[0]) & (ahead <= opts.ahead[1]) & (np.abs(across) <= opts.across)
    price = cost_to_go[rows] + ahead / speed
    picks = sorted(zip(price[near].tolist(), rows[near].tolist(), strict=True))
    gains, vopts = palette.gains, palette.options
    shape = domain_shape(gains, horizon=vopts.shape_horizon)
    capture = capture_for(library)
    best: CapturePlan | None = None
    for _, row in picks[: opts.candidates]:
        row = int(row)
        if float(cost_to_go[row]) >= budget:
            break
        maneuver = _design(start, library.start_xy[row], library.start_state[row, 2:4], palette)
        if maneuver is None:
            continue
        # The cheap tests first: its price, then (sized) its domains and its sweep; the
        # verification from the still band (the costliest, about 2 s) last.
        cost = maneuver.duration + float(cost_to_go[row])
        if cost >= budget or (best is not None and cost >= best.cost):
            continue
        policy = size_policy(SampledPrimitive.from_primitive(maneuver), gains, vopts, shape=shape)
        if policy.report is None or not policy.report.passed:
            continue
        placed = PlacedPolicy(policy, 0.0, start.copy())
        if not placed.start_domain.contains(p):
            continue
        if not library.policy(row).start_domain.contains_domain(placed.goal_domain):
            continue
        path, reach = capture.swept(policy)
        if not bool(np.all(capture.clear(start + path, reach))):
            continue
        policy = verify_still_start(policy, vopts)
        if not policy.starts_from_still_band:
            continue
        best = CapturePlan(
            catch=PlacedPolicy(policy, 0.0, start.copy()), shifts=(), rest_row=row, cost=cost
        )
    return best


def _design(
    start: FloatArray, end: FloatArray, velocity: FloatArray, palette: Palette
) -> Maneuver | None:
    """The shortest nonic on the palette's duration grid from rest at ``start`` to
    ``end`` at ``velocity`` that is feasible on the 3D model (None if none is within
    the palette's longest maneuver)."""
    options = palette.primitive_options
    params = palette.params
    zero = np.zeros(2)
    disp = np.asarray(end, dtype=float) - start
    v1 = np.asarray(velocity, dtype=float)
    u = v1 / float(np.hypot(*v1))
    step = options.duration_step
    for m in range(1, math.floor(options.max_duration / step + 1e-9) + 1):
        duration = m * step
        ref = NonicReference.between(duration, zero, zero, disp, v1)
        t = np.linspace(0.0, duration, max(2, int(duration * 128) + 1))
        vel = ref.value(t, 1)
        if np.max(np.hypot(vel[:, 0], vel[:, 1])) > options.max_speed * (1 + 1e-9):
            continue
        if np.min(vel @ u) < -options.max_backward_speed:
            continue  # no running backwards against the trim's direction
        if not passes_screen(ref, params, options):
            continue  # the palette's screen: the 3D model only where it may pass
        res = plan_shape_trajectory(ref, params, model="3d", options=options.planner)
        if not res.within(options.max_lean, params.torque_limit):
            continue
        report = PrimitiveReport.from_result(res)
        return Maneuver(
            name="launch",
            duration=duration,
            displacement=disp,
            start_velocity=zero,
            end_velocity=v1,
            params=params,
            start_trim="rest",
            end_trim="cruise",
            plans=(res.trajectory, res.trajectory),
            reports=(report, report),
        )
    return None
