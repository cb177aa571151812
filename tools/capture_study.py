"""Measurements for capture policies and scaled domains
(``docs/design/capture-measurements.md``).

Every number of that section comes from one subcommand of this script, run on the
3D model through the compiled closed loop (:func:`gracenav.sim.simulate_batch`)
with the shipped palette's controller (Fig. 2 cascade, friction compensation):

``push``
    What lean and lean rate a push (an impulse on the body COM, as
    :class:`gracenav.sim.Push` applies it) leaves 0-0.3 s later, under the
    rest regulator. The table is the lean model the other subcommands start from.
``regulator``
    Regulator to a rest trim at the robot's own position: stopping distance,
    settling time into G, peak lean and torque, saturation, time the tracking
    controller's lean compensation is saturated, for speeds 0-1 m/s, and with the
    compensation limit raised.
``roa``
    The largest correlated ellipsoid S centred at (p_c, 0) from whose boundary the
    rest regulator verifies (bisection on the size for a grid of shapes).
``braking``
    A braking maneuver (nonic flat output from the robot's own (p0, v0) to rest,
    planned by the shape planner) per initial velocity; the largest S around each.
``scaled``
    Palette policies verified at start domains S = s G, s in {0.5, 1, 2, 4, 8},
    and the swept D' each needs.
``coverage``
    Monte Carlo coverage of free-space position states by a lattice of capture
    policies.
``room``
    Which states of the coverage target (5 m x 5 m room, central box) can stop on a
    straight path clear of obstacles, for the measured stopping distances: an upper
    bound of what any capture design with those distances can cover.

Usage::

    PYTHONPATH=src OPENBLAS_NUM_THREADS=1 python tools/capture_study.py <subcommand> [options]

All randomness is seeded (``--seed``); the simulations are deterministic.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from gracenav.control import ControllerGains, design_gains
from gracenav.palette import load_palette
from gracenav.params import BallbotParams
from gracenav.policies import (
    DomainRadii,
    MotionPolicy,
    PrimitiveKind,
    SampledPrimitive,
    VerificationOptions,
    verify_placements,
)
from gracenav.policies.domains import sphere_points
from gracenav.primitives.shape_planner import (
    NonicReference,
    flat_output_gain,
    plan_shape_trajectory,
)
from gracenav.sim import (
    Push,
    Reference,
    position_state,
    simulate,
    simulate_batch,
    state_from_position,
)

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: Times after a push at which its lean is sampled (s).
PUSH_TIMES = (0.0, 0.1, 0.2, 0.3)
#: Impulses of the push table (N s), along +x.
PUSH_IMPULSES = (4.0, 8.0, 12.0, 16.0, 20.0, 24.0, 28.0, 32.0, 40.0)
#: Position factors f_p of a non-shrinking, uncorrelated D' (extents f_p e_p(S),
#: f_v e_v(S), r = 0, centred on the reference) for which the smallest sufficient
#: velocity factor f_v (from PROBE_FV) is reported. Its XY projection is a disc of
#: radius f_p e_p(S) around the reference.
PROBE_FP = (1.0, 1.1, 1.25, 1.5)
PROBE_FV = (1.0, 1.25, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0)
#: Runs per compiled batch when histories are recorded (memory: 64 x T x 8 floats).
CHUNK = 64


# --------------------------------------------------------------------------------------
# Common set-up
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Setup:
    """The shipped palette's controller and goal domain.

    Attributes
    ----------
    gains : ControllerGains
        The Fig. 2 cascade of every palette policy.
    params : BallbotParams
        Nominal robot parameters.
    goal : DomainRadii
        Extents of the shared goal domain G (m, m/s).
    correlation : float
        Position-velocity correlation r of the palette's domains.
    options : VerificationOptions
        The palette's verification options (lean limit, D' factors).
    """

    gains: ControllerGains
    params: BallbotParams
    goal: DomainRadii
    correlation: float
    options: VerificationOptions

    @property
    def dt(self) -> float:
        """Control period (s)."""
        return 1.0 / 1024.0

    @property
    def radius(self) -> float:
        """Ball radius r_w (m)."""
        return self.params.ball_radius


def load_setup() -> Setup:
    """The controller, goal size and verification options of the shipped palette."""
    palette = load_palette()
    rest = palette["rest"]
    return Setup(
        gains=palette.gains,
        params=palette.gains.params,
        goal=rest.goal_radii,
        correlation=rest.correlation,
        options=VerificationOptions(),
    )


def correlated_shapes(ep: FloatArray, ev: FloatArray, r: FloatArray) -> FloatArray:
    """Shape matrices (N, 4, 4) of correlated domains with extents ``ep`` (m), ``ev``
    (m/s) and correlation ``r``, each (N,): (Σ ⊗ I₂)⁻¹ as
    :func:`gracenav.policies.domains.correlated_shape`."""
    det = ep**2 * ev**2 * (1.0 - r**2)
    a = ev**2 / det
    b = -r * ep * ev / det
    c = ep**2 / det
    out = np.zeros((ep.size, 4, 4))
    for i in range(2):
        out[:, i, i] = a
        out[:, 2 + i, 2 + i] = c
        out[:, i, 2 + i] = b
        out[:, 2 + i, i] = b
    return out


@dataclass(frozen=True)
class DomainFamily:
    """Time-varying domain D(t) from S to G along a reference.

    Extents shrink geometrically from S to G over [0, t_f] (as
    :meth:`gracenav.policies.MotionPolicy.radii`); the correlation moves linearly.
    D'(t) stretches D(t) by ``outer`` = (position, velocity) factors, or, with
    ``hold``, stretches S for every t (an outer domain that does not shrink).
    ``outer=None`` leaves D' unchecked (only the physical limits and G count).

    Attributes
    ----------
    start : tuple of float
        (e_p, e_v, r) of S.
    goal : tuple of float
        (e_p, e_v, r) of G.
    outer : tuple of float
        D'(t) over D(t) extents.
    """

    start: tuple[float, float, float]
    goal: tuple[float, float, float]
    outer: tuple[float, float] | None
    hold: bool = False

    def extents(self, n_ticks: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        """e_p (m), e_v (m/s) and r of D(t) at ticks 0..n_ticks, each (n_ticks + 1,)."""
        s = np.linspace(0.0, 1.0, n_ticks + 1)
        (p0, v0, r0), (p1, v1, r1) = self.start, self.goal
        return p0 * (p1 / p0) ** s, v0 * (v1 / v0) ** s, r0 + (r1 - r0) * s

    def shapes(self, n_ticks: int, *, outer: bool) -> FloatArray:
        """Shape matrices (n_ticks + 1, 4, 4) of D(t) or, with ``outer``, of D'(t)."""
        ep, ev, r = self.extents(n_ticks)
        if outer:
            if self.outer is None:
                return np.zeros((n_ticks + 1, 4, 4))
            if self.hold:
                ep, ev, r = (np.full(n_ticks + 1, x[0]) for x in (ep, ev, r))
            ep, ev = ep * self.outer[0], ev * self.outer[1]
        return correlated_shapes(ep, ev, r)

    def start_shape(self) -> FloatArray:
        """Shape matrix (4, 4) of S."""
        return correlated_shapes(*(np.array([x]) for x in self.start))[0]

    def goal_shape(self) -> FloatArray:
        """Shape matrix (4, 4) of G."""
        p, v, r = self.goal
        return correlated_shapes(np.array([p]), np.array([v]), np.array([r]))[0]

    def boundary(self, n: int) -> FloatArray:
        """``n`` deterministic offsets (n, 4) on the surface of S (axis extremes first)."""
        u = sphere_points(n)
        shape = correlated_shapes(*(np.array([x]) for x in self.start))[0]
        ell = np.linalg.cholesky(np.linalg.inv(shape))
        out: FloatArray = u @ ell.T
        return out


# --------------------------------------------------------------------------------------
# The lean a push leaves
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PushTable:
    """Speed, lean and lean rate along the push, ``times`` after pushes of ``impulses``.

    Attributes
    ----------
    impulses : ndarray, shape (J,)
        Push impulses (N s).
    times : ndarray, shape (K,)
        Times after the push (s).
    speed, lean, lean_rate : ndarray, shape (J, K)
        Ball speed (m/s), lean (rad) and lean rate (rad/s) along the push direction.
    max_lean, max_torque, travel : ndarray, shape (J,)
        Peak |lean| (rad), peak |τ| (N m) and largest ball displacement (m) of the
        whole regulated response.
    saturated : ndarray of int, shape (J,)
        Saturated (tick, axis) pairs.
    """

    impulses: FloatArray
    times: FloatArray
    speed: FloatArray
    lean: FloatArray
    lean_rate: FloatArray
    max_lean: FloatArray
    max_torque: FloatArray
    travel: FloatArray
    saturated: NDArray[np.int64]

    def lean_at(self, k: int, speed: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Lean (rad) and lean rate (rad/s) along the motion that a push leaves at time
        ``times[k]`` for ball speeds ``speed`` (N,): linear interpolation over the
        table (through (0, 0, 0)), held constant beyond its fastest entry."""
        order = np.argsort(self.speed[:, k])
        v = np.concatenate([[0.0], self.speed[order, k]])
        lean = np.concatenate([[0.0], self.lean[order, k]])
        rate = np.concatenate([[0.0], self.lean_rate[order, k]])
        return np.interp(speed, v, lean), np.interp(speed, v, rate)


def push_table(setup: Setup, duration: float = 4.0) -> PushTable:
    """Push the robot at rest (regulated to its position) along +x and sample the state.

    Parameters
    ----------
    setup : Setup
    duration : float
        Length of each run (s).

    Returns
    -------
    PushTable
    """
    ref = Reference.hold((0.0, 0.0), duration, params=setup.params)
    times = np.array(PUSH_TIMES)
    n_j, n_k = len(PUSH_IMPULSES), times.size
    speed, lean, rate = (np.zeros((n_j, n_k)) for _ in range(3))
    max_lean, max_tau, travel = (np.zeros(n_j) for _ in range(3))
    sat = np.zeros(n_j, dtype=np.int64)
    for j, imp in enumerate(PUSH_IMPULSES):
        res = simulate(np.zeros(8), ref, setup.gains, disturbances=[Push(0.0, (imp, 0.0))])
        ps = res.position_state
        ticks = np.round(times / setup.dt).astype(int)
        speed[j] = ps[ticks, 2]
        lean[j] = res.states[ticks, 2]
        rate[j] = res.states[ticks, 6]
        max_lean[j], max_tau[j] = res.max_lean, res.max_torque
        travel[j] = float(np.max(np.hypot(ps[:, 0], ps[:, 1])))
        sat[j] = res.saturated_ticks
    return PushTable(
        np.array(PUSH_IMPULSES), times, speed, lean, rate, max_lean, max_tau, travel, sat
    )


LEAN_VARIANTS = ("plan", *(f"push+{t:.1f}s" for t in PUSH_TIMES))


def initial_states(
    setup: Setup,
    table: PushTable,
    p: FloatArray,
    plan_lean: FloatArray,
    plan_rate: FloatArray,
    variants: Sequence[str] = LEAN_VARIANTS,
) -> tuple[FloatArray, NDArray[np.int64]]:
    """Model states for position states ``p`` (N, 4) with every lean variant.

    ``plan``: the lean and lean rate of the reference at t = 0 (``plan_lean``,
    ``plan_rate``, (2,)), as verification does. ``push+Ts``: that plus the lean and
    lean rate a push leaves T s after it, at the state's speed, along its velocity.

    Returns
    -------
    x0 : ndarray, shape (V N, 8)
    variant : ndarray of int, shape (V N,)
        Index into ``variants`` of each row.
    """
    speed = np.hypot(p[:, 2], p[:, 3])
    unit = np.where(speed[:, None] > 0, p[:, 2:4] / np.maximum(speed, 1e-12)[:, None], 0.0)
    rows, which = [], []
    for i, name in enumerate(variants):
        if name == "plan":
            lean = np.broadcast_to(plan_lean, p[:, :2].shape)
            rate = np.broadcast_to(plan_rate, p[:, :2].shape)
        else:
            k = PUSH_TIMES.index(float(name[5:-1]))
            dl, dr = table.lean_at(k, speed)
            lean = plan_lean + unit * dl[:, None]
            rate = plan_rate + unit * dr[:, None]
        rows.append(state_from_position(p, setup.radius, lean=lean, lean_rate=rate))
        which.append(np.full(p.shape[0], i, dtype=np.int64))
    return np.concatenate(rows), np.concatenate(which)


# --------------------------------------------------------------------------------------
# Closed-loop evaluation
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RunMetrics:
    """Per-run outcome of :func:`evaluate` (all arrays of shape (N,)).

    Attributes
    ----------
    outer_value : ndarray
        Largest value of D'(t) (<= 1: stayed inside).
    goal_value : ndarray
        Value of G at t_f.
    max_lean : ndarray
        Peak |φ_x|, |φ_y| (rad).
    max_torque : ndarray
        Peak |τ| commanded (N m).
    saturated : ndarray of int
        Saturated (tick, axis) pairs.
    passed : ndarray of bool
        Verification semantics: inside D'(t), in G at t_f, lean within the limit,
        no saturation.
    stretch : ndarray or None
        sqrt of the largest value of D(t): the uniform D'/D factor this run needs.
    stretch_hold : ndarray or None
        sqrt of the largest value of S (centred on the reference): the uniform
        factor a D'(t) that does not shrink (S stretched) needs.
    probe : ndarray or None, shape (N, len(PROBE_FP), len(PROBE_FV))
        Largest value of a non-shrinking uncorrelated D' with extents (f_p e_p(S),
        f_v e_v(S)), centred on the reference.
    settle_time : ndarray or None
        Time (s) after which the state stays in G.
    excursion : ndarray or None
        Largest distance (m) of the ball from the reference position.
    travel : ndarray or None
        Largest ball displacement (m) from its start along its initial velocity.
    comp_saturated : ndarray or None
        Fraction of ticks with a saturated lean compensation (either axis).
    """

    outer_value: FloatArray
    goal_value: FloatArray
    max_lean: FloatArray
    max_torque: FloatArray
    saturated: NDArray[np.int64]
    passed: BoolArray
    stretch: FloatArray | None = None
    stretch_hold: FloatArray | None = None
    probe: FloatArray | None = None
    settle_time: FloatArray | None = None
    excursion: FloatArray | None = None
    travel: FloatArray | None = None
    comp_saturated: FloatArray | None = None


def evaluate(
    setup: Setup,
    x0: FloatArray,
    reference: Reference,
    centre: FloatArray,
    family: DomainFamily,
    *,
    gains: ControllerGains | None = None,
    detail: bool = False,
) -> RunMetrics:
    """Run the closed loop from ``x0`` (N, 8) and check the verification conditions.

    Parameters
    ----------
    setup : Setup
    x0 : ndarray, shape (N, 8)
    reference : Reference
    centre : ndarray, shape (T + 1, 4)
        Reference position state at the ticks: the centre of D(t).
    family : DomainFamily
    gains : ControllerGains, optional
        Default: the palette's.
    detail : bool
        Record histories (in chunks) for stretch, settling time, excursion, travel
        and lean compensation saturation.

    Returns
    -------
    RunMetrics
    """
    gains = gains if gains is not None else setup.gains
    nt = reference.num_ticks
    outer = family.shapes(nt, outer=True)
    goal = family.goal_shape()
    lim = setup.options.lean_limit
    if not detail:
        res = simulate_batch(x0, reference, gains, monitor=(centre, outer))
        d = position_state(res.final_states, setup.radius) - centre[-1]
        gv = np.einsum("ni,ij,nj->n", d, goal, d)
        return RunMetrics(
            res.max_domain_value,
            gv,
            res.max_lean,
            res.max_torque,
            res.saturated_ticks,
            (res.max_domain_value <= 1)
            & (gv <= 1)
            & (res.max_lean <= lim)
            & (res.saturated_ticks == 0),
        )
    inner = family.shapes(nt, outer=False)
    start = family.start_shape()
    k = gains.kernel_arrays()
    parts: list[dict[str, FloatArray]] = []
    for a in range(0, x0.shape[0], CHUNK):
        res = simulate_batch(
            x0[a : a + CHUNK], reference, gains, monitor=(centre, outer), record=True
        )
        assert res.states is not None
        ps = position_state(res.states, setup.radius)  # (B, T+1, 4)
        d = ps - centre[None]
        dval = np.einsum("bti,tij,btj->bt", d, inner, d)
        sval = np.einsum("bti,ij,btj->bt", d, start, d)
        probe = np.zeros((d.shape[0], len(PROBE_FP), len(PROBE_FV)))
        for i, fp in enumerate(PROBE_FP):
            for j, fv in enumerate(PROBE_FV):
                e = family.start
                sh = correlated_shapes(
                    np.array([e[0] * fp]), np.array([e[1] * fv]), np.array([0.0])
                )[0]
                probe[:, i, j] = np.einsum("bti,ij,btj->bt", d, sh, d).max(axis=1)
        gval = np.einsum("bti,ij,btj->bt", d, goal, d)
        outside = gval > 1.0
        last_out = np.where(outside.any(axis=1), nt - np.argmax(outside[:, ::-1], axis=1), 0)
        v0 = ps[:, 0, 2:4]
        sp = np.hypot(v0[:, 0], v0[:, 1])
        u = np.where(sp[:, None] > 0, v0 / np.maximum(sp, 1e-12)[:, None], 0.0)
        along = np.einsum("bti,bi->bt", ps[:, :, :2] - ps[:, :1, :2], u)
        err_p = centre[None, :, :2] - ps[:, :, :2]
        err_v = centre[None, :, 2:] - ps[:, :, 2:]
        comp = k[None, None, :, 0] * err_p + k[None, None, :, 1] * err_v
        comp_sat = np.any(np.abs(comp) >= gains.max_lean_compensation * (1 - 1e-9), axis=2)
        parts.append(
            {
                "outer": res.max_domain_value,
                "goal": gval[:, -1],
                "lean": res.max_lean,
                "tau": res.max_torque,
                "sat": res.saturated_ticks.astype(float),
                "stretch": np.sqrt(dval.max(axis=1)),
                "hold": np.sqrt(sval.max(axis=1)),
                "probe": probe,
                "settle": last_out * reference.dt,
                "exc": np.hypot(d[:, :, 0], d[:, :, 1]).max(axis=1),
                "travel": along.max(axis=1),
                "comp": comp_sat.mean(axis=1),
            }
        )
    cat = {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
    sat = cat["sat"].astype(np.int64)
    return RunMetrics(
        cat["outer"],
        cat["goal"],
        cat["lean"],
        cat["tau"],
        sat,
        (cat["outer"] <= 1) & (cat["goal"] <= 1) & (cat["lean"] <= lim) & (sat == 0),
        cat["stretch"],
        cat["hold"],
        cat["probe"],
        cat["settle"],
        cat["exc"],
        cat["travel"],
        cat["comp"],
    )


def hold_reference(setup: Setup, duration: float) -> tuple[Reference, FloatArray]:
    """Rest at the origin for ``duration`` (s): reference and D(t) centres (T + 1, 4)."""
    ref = Reference.hold((0.0, 0.0), duration, params=setup.params)
    return ref, np.zeros((ref.num_ticks + 1, 4))


def bisect(passes: Callable[[float], bool], lo: float, hi: float, steps: int) -> float:
    """Largest x in [lo, hi] (geometric bisection) with ``passes(x)``; 0 if ``lo`` fails."""
    if not passes(lo):
        return 0.0
    if passes(hi):
        return hi
    for _ in range(steps):
        mid = math.sqrt(lo * hi)
        if passes(mid):
            lo = mid
        else:
            hi = mid
    return lo


def deg(x: float | FloatArray) -> float | FloatArray:
    """Radians to degrees."""
    return np.rad2deg(x)


# --------------------------------------------------------------------------------------
# Subcommands
# --------------------------------------------------------------------------------------
def cmd_push(args: argparse.Namespace) -> None:
    """Print the push table."""
    setup = load_setup()
    tab = push_table(setup)
    print("| impulse N s | t after push s | speed m/s | lean deg | lean rate deg/s |")
    print("|---|---|---|---|---|")
    for j, imp in enumerate(tab.impulses):
        for k, t in enumerate(tab.times):
            print(
                f"| {imp:g} | {t:.1f} | {tab.speed[j, k]:.3f} | {deg(tab.lean[j, k]):.2f} "
                f"| {deg(tab.lean_rate[j, k]):.1f} |"
            )
    print()
    print("| impulse N s | peak speed m/s | travel m | peak lean deg | peak torque N m | sat |")
    print("|---|---|---|---|---|---|")
    for j, imp in enumerate(tab.impulses):
        print(
            f"| {imp:g} | {tab.speed[j].max():.3f} | {tab.travel[j]:.3f} | "
            f"{deg(tab.max_lean[j]):.2f} | {tab.max_torque[j]:.1f} | {tab.saturated[j]} |"
        )


def probe_text(probe: FloatArray) -> str:
    """Smallest velocity factor f_v of a non-shrinking D' per position factor f_p."""
    worst = probe.max(axis=0)
    out = []
    for i, fp in enumerate(PROBE_FP):
        ok = np.flatnonzero(worst[i] <= 1.0)
        out.append(f"({fp:g}, {PROBE_FV[ok[0]]:g})" if ok.size else f"({fp:g}, >{PROBE_FV[-1]:g})")
    return " ".join(out)


def _goal_tuple(setup: Setup) -> tuple[float, float, float]:
    return (setup.goal.position, setup.goal.velocity, setup.correlation)


def cmd_regulator(args: argparse.Namespace) -> None:
    """Rest regulator at the robot's own position: stop from speed v."""
    setup = load_setup()
    tab = push_table(setup)
    ref, centre = hold_reference(setup, args.duration)
    speeds = np.round(np.arange(0.1, args.max_speed + 1e-9, 0.1), 3)
    angles = np.deg2rad([0.0, 45.0, 90.0])
    p = np.array([[0.0, 0.0, s * math.cos(a), s * math.sin(a)] for s in speeds for a in angles])
    fam = DomainFamily(_goal_tuple(setup), _goal_tuple(setup), (1e3, 1e3))
    for comp_deg in args.compensation:
        gains = (
            setup.gains
            if comp_deg == 5.0
            else design_gains(
                setup.params, setup.gains.weights, max_lean_compensation=float(np.deg2rad(comp_deg))
            )
        )
        x0, which = initial_states(setup, tab, p, np.zeros(2), np.zeros(2))
        m = evaluate(setup, x0, ref, centre, fam, gains=gains, detail=True)
        assert m.travel is not None and m.settle_time is not None and m.comp_saturated is not None
        print(
            f"\nlean compensation limit {comp_deg:g} deg, hold {args.duration:g} s "
            "(worst over 0/45/90 deg and over the lean variants "
            f"{', '.join(LEAN_VARIANTS)})"
        )
        print(
            "| speed m/s | stop distance m (plan lean .. worst) | settle into G s | "
            "peak lean deg | peak torque N m | saturated runs | comp. saturated % of time |"
        )
        print("|---|---|---|---|---|---|---|")
        n_a = angles.size
        for i, s in enumerate(speeds):
            rows = np.flatnonzero((np.arange(x0.shape[0]) % p.shape[0]) // n_a == i)
            plan = rows[which[rows] == 0]
            print(
                f"| {s:.1f} | {m.travel[plan].max():.3f} .. {m.travel[rows].max():.3f} | "
                f"{m.settle_time[rows].max():.2f} | {deg(m.max_lean[rows].max()):.2f} | "
                f"{m.max_torque[rows].max():.1f} | {np.count_nonzero(m.saturated[rows])}/"
                f"{rows.size} | {100 * m.comp_saturated[rows].max():.0f} |"
            )


def _roa_check(
    setup: Setup,
    tab: PushTable,
    ep: float,
    ratio: float,
    r: float,
    duration: float,
    n_points: int,
    outer: tuple[float, float] | None,
    hold: bool,
    variants: Sequence[str],
    detail: bool = False,
) -> tuple[bool, RunMetrics]:
    ref, centre = hold_reference(setup, duration)
    fam = DomainFamily((ep, ep * ratio, r), _goal_tuple(setup), outer, hold)
    p = fam.boundary(n_points)
    x0, _ = initial_states(setup, tab, p, np.zeros(2), np.zeros(2), variants)
    m = evaluate(setup, x0, ref, centre, fam, detail=detail)
    return bool(np.all(m.passed)), m


def _summary(m: RunMetrics) -> str:
    parts = [
        f"max D' value {m.outer_value.max():.3f}",
        f"max G value at t_f {m.goal_value.max():.3f}",
        f"peak lean {deg(m.max_lean.max()):.2f} deg",
        f"peak torque {m.max_torque.max():.1f} N m",
        f"saturated runs {np.count_nonzero(m.saturated)}/{m.saturated.size}",
    ]
    if m.stretch is not None and m.stretch_hold is not None:
        parts.append(f"needed uniform D'/D(t) {m.stretch.max():.2f}")
        parts.append(f"needed uniform D'/S (non-shrinking D') {m.stretch_hold.max():.2f}")
    if m.probe is not None:
        parts.append("non-shrinking r = 0 D' (f_p, smallest f_v): " + probe_text(m.probe))
    if m.excursion is not None:
        parts.append(f"largest distance from p_c {m.excursion.max():.3f} m")
    if m.settle_time is not None:
        parts.append(f"settle into G {m.settle_time.max():.2f} s")
    return "; ".join(parts)


def cmd_roa(args: argparse.Namespace) -> None:
    """Largest correlated S around a rest point from which the rest regulator verifies."""
    setup = load_setup()
    tab = push_table(setup)
    outer = None if args.outer is None else (args.outer[0], args.outer[1])
    variants = args.variants
    t0 = time.process_time()
    if args.shape:
        for ep, ev, r in args.shape:
            passed, m = _roa_check(
                setup,
                tab,
                ep,
                ev / ep,
                r,
                args.duration,
                args.check_points,
                outer,
                args.hold,
                variants,
                detail=True,
            )
            print(
                f"S (e_p {ep:g} m, e_v {ev:g} m/s, r {r:g}), t_f {args.duration:g} s, "
                f"{args.check_points} x {len(variants)} states, D' "
                f"{_outer_text(outer, args.hold)}: {'PASS' if passed else 'FAIL'}"
            )
            print("  " + _summary(m))
        print(f"{time.process_time() - t0:.0f} s CPU")
        return
    runs = 0
    best: dict[str, tuple[float, float, float, float]] = {}
    print(
        f"t_f {args.duration:g} s, {args.points} boundary points x lean variants "
        f"{', '.join(variants)}; D' {_outer_text(outer, args.hold)}; pass: G at t_f, "
        "lean <= 8 deg, no torque saturation"
    )
    print(
        "| r | e_v/e_p 1/s | e_p m | e_v m/s | lattice spacing covering all |v|<=0.5 m | "
        "covering all |v|<=0.8 m |"
    )
    print("|---|---|---|---|---|---|")
    for r in args.correlations:
        for ratio in args.ratios:

            def ok(ep: float, r: float = r, ratio: float = ratio) -> bool:
                nonlocal runs
                runs += args.points * len(variants)
                return _roa_check(
                    setup, tab, ep, ratio, r, args.duration, args.points, outer, args.hold, variants
                )[0]

            ep = bisect(ok, 0.08, args.max_extent, args.steps)
            ev = ep * ratio
            d5 = _covering_spacing(ep, ev, r, 0.5)
            d8 = _covering_spacing(ep, ev, r, 0.8)
            print(f"| {r:g} | {ratio:g} | {ep:.3f} | {ev:.3f} | {d5:.3f} | {d8:.3f} |")
            for key, fits in (
                ("largest covering spacing for |v| <= 0.5", True),
                (f"largest covering spacing with e_v >= {args.min_speed}", ev >= args.min_speed),
            ):
                if fits and ep > 0 and (key not in best or d5 > best[key][3]):
                    best[key] = (r, ratio, ep, d5)
    cpu = time.process_time() - t0
    print(f"\n{runs} runs in {cpu:.0f} s CPU")
    if not best:
        print("no shape verifies")
    for key, (r, ratio, ep, _) in best.items():
        ok_all, m = _roa_check(
            setup,
            tab,
            ep,
            ratio,
            r,
            args.duration,
            args.check_points,
            outer,
            args.hold,
            variants,
            detail=True,
        )
        print(
            f"\n{key}: r {r:g}, e_p {ep:.3f} m, e_v {ep * ratio:.3f} m/s; re-checked from "
            f"{args.check_points} x {len(variants)} states: {'PASS' if ok_all else 'FAIL'}"
        )
        print(_summary(m))
    print(f"{time.process_time() - t0:.0f} s CPU in total")


def _outer_text(outer: tuple[float, float] | None, hold: bool) -> str:
    if outer is None:
        return "not checked"
    what = "S" if hold else "D(t)"
    return f"= {what} x {outer} (position, velocity)"


def _covering_spacing(ep: float, ev: float, r: float, v_max: float) -> float:
    """Largest square-lattice spacing d whose lattice of domains (e_p, e_v, r), centred
    at rest on every lattice point, covers every position with |v| <= v_max: the position
    slice at velocity v is a disc (centred at r e_p v/e_v) of radius
    e_p sqrt(1 − r²) sqrt(1 − |v|²/e_v²), which must reach the covering radius d/√2 of
    the lattice."""
    if ev <= v_max:
        return 0.0
    return math.sqrt(2.0) * ep * math.sqrt(1.0 - r**2) * math.sqrt(1.0 - (v_max / ev) ** 2)


# --------------------------------------------------------------------------------------
# Braking maneuvers
# --------------------------------------------------------------------------------------
def braking_primitive(
    setup: Setup, v0: FloatArray, max_lean: float, tail: float, min_duration: float = 1.0
) -> tuple[SampledPrimitive, float, float, float] | None:
    """Shortest braking maneuver from velocity ``v0`` (m/s, (2,)) to rest, plus a rest tail.

    The desired flat output is the nonic from (0, v0) to (v0 T/2, 0) (the C⁴ smooth-step
    deceleration, monotone); T is the shortest duration on the 1/8 s grid, at least
    ``min_duration`` (s), whose 3D shape plan converges with peak lean <= ``max_lean``
    (rad) and torque within the limit. The rest trim held ``tail`` s afterwards lets the
    error settle into G.

    Returns
    -------
    (primitive, T, peak planned lean (rad), peak planned torque (N m)) or None.
    """
    speed = float(np.hypot(*v0))
    kappa = flat_output_gain(setup.params)
    t_min = 2.1875 * speed / (kappa * max_lean)  # peak of the smooth-step deceleration
    step = 0.125
    duration = max(min_duration, math.ceil(t_min / step - 1e-9) * step)
    for _ in range(24):
        ref = NonicReference.between(duration, np.zeros(2), v0, v0 * duration / 2, np.zeros(2))
        res = plan_shape_trajectory(ref, setup.params, model="3d")
        if (
            res.converged
            and res.peak_lean <= max_lean
            and res.peak_torque <= setup.params.torque_limit
        ):
            break
        duration += step
    else:
        return None
    n = round(duration / setup.dt)
    tt = np.arange(n + 1) * setup.dt
    s = res.trajectory.sample(np.minimum(tt, duration))
    m = round(tail / setup.dt)
    states = np.concatenate([s.states, np.repeat(s.states[-1:], m, axis=0)])
    states[n + 1 :, 4:] = 0.0
    states[n + 1 :, 2:4] = 0.0
    acc = np.concatenate([s.accelerations, np.zeros((m, 4))])
    inputs = np.concatenate([s.inputs, np.zeros((m, 2))])
    pos = np.concatenate([s.position, np.repeat(s.position[-1:], m, axis=0)])
    pos[n + 1 :, 2:] = 0.0
    prim = SampledPrimitive(
        name=f"brake_{v0[0]:+.2f}_{v0[1]:+.2f}",
        kind=PrimitiveKind.MANEUVER,
        duration=(n + m) * setup.dt,
        dt=setup.dt,
        displacement=pos[-1, :2].copy(),
        start_velocity=np.asarray(v0, dtype=float),
        end_velocity=np.zeros(2),
        states=np.ascontiguousarray(states),
        accelerations=np.ascontiguousarray(acc),
        inputs=np.ascontiguousarray(inputs),
        position=np.ascontiguousarray(pos),
    )
    return prim, duration, res.peak_lean, res.peak_torque


def _brake_check(
    setup: Setup,
    tab: PushTable,
    prim: SampledPrimitive,
    scale: float,
    n_points: int,
    outer: tuple[float, float] | None,
    hold: bool,
    variants: Sequence[str],
    detail: bool = False,
) -> tuple[bool, RunMetrics]:
    g = _goal_tuple(setup)
    fam = DomainFamily((g[0] * scale, g[1] * scale, g[2]), g, outer, hold)
    centre = np.ascontiguousarray(prim.position[:, :4])
    p = centre[0] + fam.boundary(n_points)
    x0, _ = initial_states(setup, tab, p, prim.states[0, 2:4], prim.states[0, 6:8], variants)
    m = evaluate(setup, x0, prim.reference(), centre, fam, detail=detail)
    return bool(np.all(m.passed)), m


def cmd_braking(args: argparse.Namespace) -> None:
    """Braking maneuvers per initial velocity: duration, distance and largest S."""
    setup = load_setup()
    tab = push_table(setup)
    outer = None if args.outer is None else (args.outer[0], args.outer[1])
    variants = args.variants
    t0 = time.process_time()
    g = setup.goal
    print(
        f"planned lean <= {args.max_lean:g} deg, T >= {args.min_duration:g} s, "
        f"rest tail {args.tail:g} s, "
        f"{args.points} boundary points x lean variants {', '.join(variants)}; "
        f"D' {_outer_text(outer, args.hold)}; S = s G (library shape)"
    )
    print(
        "| speed m/s | direction deg | T s | stop distance m | planned lean deg | "
        "planned torque N m | largest s | e_p m | e_v m/s | velocity slice radius m/s | "
        "peak lean deg | peak torque N m | needed D'/D(t) | needed D'/S | "
        "non-shrinking r=0 D' (f_p, f_v) | largest distance from ref m |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for speed in args.speeds:
        for a in args.directions:
            v0 = speed * np.array([math.cos(math.radians(a)), math.sin(math.radians(a))])
            out = braking_primitive(
                setup, v0, float(np.deg2rad(args.max_lean)), args.tail, args.min_duration
            )
            if out is None:
                print(f"| {speed:.1f} | {a:g} | infeasible |")
                continue
            prim, dur, lean, tau = out

            def ok(s: float, prim: SampledPrimitive = prim) -> bool:
                return _brake_check(setup, tab, prim, s, args.points, outer, args.hold, variants)[0]

            scales = args.fixed_scales or [bisect(ok, 1.0, args.max_scale, args.steps)]
            for s in scales:
                if s > 0:
                    passed, m = _brake_check(
                        setup, tab, prim, s, args.points, outer, args.hold, variants, detail=True
                    )
                    assert m.stretch is not None and m.stretch_hold is not None
                    assert m.excursion is not None
                    extra = (
                        f"{deg(m.max_lean.max()):.2f} | {m.max_torque.max():.1f} | "
                        f"{m.stretch.max():.2f} | {m.stretch_hold.max():.2f} | "
                        f"{probe_text(m.probe) if m.probe is not None else '-'} | "
                        f"{m.excursion.max():.3f}"
                    )
                    if args.fixed_scales:
                        extra += f" {'pass' if passed else 'FAIL'}"
                else:
                    extra = "- | - | - | - | - | -"
                ev = g.velocity * s
                print(
                    f"| {speed:.1f} | {a:g} | {dur:.3f} | {np.hypot(*prim.displacement):.3f} | "
                    f"{deg(lean):.2f} | {tau:.1f} | {s:.2f} | {g.position * s:.3f} | "
                    f"{ev:.3f} | {ev * math.sqrt(1 - setup.correlation**2):.3f} | {extra} |"
                )
    print(f"\n{time.process_time() - t0:.0f} s CPU")


# --------------------------------------------------------------------------------------
# Scaled palette policies
# --------------------------------------------------------------------------------------
def _rest_of(prim: SampledPrimitive, duration: float) -> SampledPrimitive:
    """The rest trim held for ``duration`` (s)."""
    n = round(duration / prim.dt)
    return replace(
        prim,
        name=f"rest_{duration:g}s",
        duration=n * prim.dt,
        states=np.repeat(prim.states[:1], n + 1, axis=0),
        accelerations=np.repeat(prim.accelerations[:1], n + 1, axis=0),
        inputs=np.repeat(prim.inputs[:1], n + 1, axis=0),
        position=np.repeat(prim.position[:1], n + 1, axis=0),
    )


def swept_reach(policy: MotionPolicy) -> tuple[float, float]:
    """Radius of D'(0)'s XY projection and the swept reach of D' (m): the largest
    distance from the start point of any point of the XY projection of D'(t),
    t in [0, t_f] (discs of radius outer factor x e_p(t) around the reference)."""
    prim = policy.primitive
    t = np.arange(prim.num_ticks + 1) * prim.dt
    rp, _ = policy.radii(t)
    cp = policy.outer_factors[0]
    dist = np.hypot(*(prim.position[:, :2] - prim.position[0, :2]).T)
    return float(cp * rp[0]), float(np.max(dist + cp * rp))


def cmd_scaled(args: argparse.Namespace) -> None:
    """Verify palette policies with S = s G and report the swept D'."""
    setup = load_setup()
    palette = load_palette()
    options = replace(setup.options, boundary_points=args.points)
    prims = [palette[name].primitive for name in args.policies]
    prims += [_rest_of(palette["rest"].primitive, d) for d in args.rest_durations]
    print(
        f"{args.points} boundary points at 0 and 90 deg, plan lean; D' = D x "
        f"({options.outer_position_factor}, {options.outer_velocity_factor}); G fixed "
        f"(e_p {setup.goal.position} m)"
    )
    print(
        "| policy | t_f s | s = S/G | S e_p m | pass | max D' value | max G value | "
        "peak lean deg | peak torque N m | sat runs | D'(0) radius m | swept D' reach m |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    t0 = time.process_time()
    for prim in prims:
        base = palette["rest"]
        for s in args.scales:
            pol = MotionPolicy(
                prim,
                setup.gains,
                setup.goal.scaled(s),
                setup.goal,
                base.outer_factors,
                base.correlation,
            )
            rep = verify_placements(pol, options)
            r0, reach = swept_reach(pol)
            print(
                f"| {prim.name} | {prim.duration:.3f} | {s:g} | {setup.goal.position * s:.3f} | "
                f"{'yes' if rep.passed else 'no'} | {rep.max_outer_value:.3f} | "
                f"{rep.max_goal_value:.3f} | {deg(rep.max_lean):.2f} | {rep.max_torque:.1f} | "
                f"{rep.saturated_runs} | {r0:.3f} | {reach:.3f} |"
            )
    print(f"\n{time.process_time() - t0:.1f} s CPU")


# --------------------------------------------------------------------------------------
# Coverage arithmetic
# --------------------------------------------------------------------------------------
def lattice_coverage(
    centres_v: FloatArray,
    shapes: FloatArray,
    spacing: float,
    v_max: float,
    n: int,
    seed: int,
    *,
    disc: bool = True,
) -> float:
    """Fraction of free-space position states covered by a square lattice of domains.

    Every lattice point q carries one domain per row of ``centres_v`` (velocity centre
    (2,), shape (4, 4)): {(p, v) : (p − q, v − c_v)ᵀ P (p − q, v − c_v) <= 1}.
    Positions are uniform in a lattice cell (free space is periodic), velocities uniform
    in the disc |v| <= ``v_max`` (``disc``) or the square [−v_max, v_max]².

    Parameters
    ----------
    centres_v : ndarray, shape (M, 2)
    shapes : ndarray, shape (M, 4, 4)
    spacing : float
        Lattice spacing d (m).
    v_max : float
    n : int
        Monte Carlo samples.
    seed : int

    Returns
    -------
    float
    """
    rng = np.random.default_rng(seed)
    pos = rng.uniform(0.0, spacing, size=(n, 2))
    if disc:
        rad = v_max * np.sqrt(rng.uniform(size=n))
        ang = rng.uniform(0.0, 2 * math.pi, size=n)
        vel = np.column_stack([rad * np.cos(ang), rad * np.sin(ang)])
    else:
        vel = rng.uniform(-v_max, v_max, size=(n, 2))
    # Largest position extent of any domain bounds the lattice points to try; the points
    # nearest the cell go first.
    reach = max(float(np.sqrt(np.linalg.inv(s)[0, 0])) for s in shapes)
    k = math.ceil(reach / spacing) + 1
    grid = np.arange(-k, k + 1) * spacing
    qs = np.array([(qx, qy) for qx in grid for qy in grid])
    dist = np.hypot(*(qs - spacing / 2).T)
    keep = dist <= reach + spacing
    qs = qs[keep][np.argsort(dist[keep])]
    covered = np.zeros(n, dtype=bool)
    for q in qs:
        for cv, shape in zip(centres_v, shapes, strict=True):
            todo = np.flatnonzero(~covered)
            if todo.size == 0:
                return 1.0
            d = np.column_stack([pos[todo] - q, vel[todo] - cv])
            covered[todo[np.einsum("ni,ij,nj->n", d, shape, d) <= 1.0]] = True
    return float(covered.mean())


def braking_family(
    scales: Sequence[float], speeds: Sequence[float], directions: int, setup: Setup
) -> tuple[FloatArray, FloatArray]:
    """Velocity centres (M, 2) and shapes (M, 4, 4) of a braking family: the rest trim
    (S = 2 G) plus one member per speed and direction, S = scale x G (library shape)."""
    g = setup.goal
    cv = [np.zeros(2)]
    sh = [
        correlated_shapes(
            np.array([2 * g.position]), np.array([2 * g.velocity]), np.array([setup.correlation])
        )[0]
    ]
    for speed, s in zip(speeds, scales, strict=True):
        shape = correlated_shapes(
            np.array([g.position * s]), np.array([g.velocity * s]), np.array([setup.correlation])
        )[0]
        for j in range(directions):
            a = 2 * math.pi * j / directions
            cv.append(speed * np.array([math.cos(a), math.sin(a)]))
            sh.append(shape)
    return np.array(cv), np.array(sh)


def cmd_coverage(args: argparse.Namespace) -> None:
    """Monte Carlo coverage of free space by lattices of capture policies."""
    setup = load_setup()
    designs: list[tuple[str, FloatArray, FloatArray]] = []
    for ep, ev, r in args.regulator or [(0.79, 0.79, -0.95)]:
        designs.append(
            (
                f"regulator S (e_p {ep:.3f}, e_v {ev:.3f}, r {r:g})",
                np.zeros((1, 2)),
                correlated_shapes(np.array([ep]), np.array([ev]), np.array([r])),
            )
        )
    if args.brake_scales:
        speeds = [0.1 * (i + 1) for i in range(len(args.brake_scales))]
        for dirs in args.brake_directions:
            cv, sh = braking_family(args.brake_scales, speeds, dirs, setup)
            designs.append(
                (f"braking family, {dirs} directions x {len(speeds)} speeds + rest", cv, sh)
            )
    g = setup.goal
    designs.append(
        (
            "palette rest trim only (S = 2 G)",
            np.zeros((1, 2)),
            correlated_shapes(
                np.array([2 * g.position]),
                np.array([2 * g.velocity]),
                np.array([setup.correlation]),
            ),
        )
    )
    print(
        f"{args.samples} samples per cell (seed {args.seed}); velocities uniform in the "
        f"disc |v| <= {args.v_max} (and the square [-{args.v_max}, {args.v_max}]^2)"
    )
    print("| design | d m | disc % | square % |")
    print("|---|---|---|---|")
    t0 = time.process_time()
    for name, cv, sh in designs:
        for d in args.spacings:
            c1 = lattice_coverage(cv, sh, d, args.v_max, args.samples, args.seed)
            c2 = lattice_coverage(cv, sh, d, args.v_max, args.samples, args.seed, disc=False)
            print(f"| {name} | {d:g} | {100 * c1:.2f} | {100 * c2:.2f} |")
        # Largest spacing reaching the target (bisection on d, disc velocities).
        lo, hi = 0.02, 2.0
        if lattice_coverage(cv, sh, lo, args.v_max, args.samples, args.seed) < args.target:
            print(f"| {name} | none reaches {100 * args.target:g} % | | |")
            continue
        for _ in range(args.steps):
            mid = 0.5 * (lo + hi)
            if lattice_coverage(cv, sh, mid, args.v_max, args.samples, args.seed) >= args.target:
                lo = mid
            else:
                hi = mid
        print(f"| {name} | largest d for {100 * args.target:g} %: {lo:.3f} | | |")
    print(f"\n{time.process_time() - t0:.1f} s CPU")


# --------------------------------------------------------------------------------------
# The room of the coverage target: what stopping distance allows
# --------------------------------------------------------------------------------------
def room_clearance(xy: FloatArray, size: float, box: float) -> FloatArray:
    """Distance (m) from points ``xy`` (N, 2) to the walls of the ``size`` x ``size`` room
    [0, size]² and to the ``box`` x ``box`` box at its centre (negative inside the box)."""
    walls = np.minimum(np.minimum(xy[:, 0], size - xy[:, 0]), np.minimum(xy[:, 1], size - xy[:, 1]))
    q = np.abs(xy - size / 2) - box / 2
    outside = np.hypot(np.maximum(q[:, 0], 0.0), np.maximum(q[:, 1], 0.0))
    inside = np.minimum(np.maximum(q[:, 0], q[:, 1]), 0.0)
    out: FloatArray = np.minimum(walls, outside + inside)
    return out


def stoppable(
    p: FloatArray, distance: FloatArray, size: float, box: float, footprint: float
) -> BoolArray:
    """Whether the straight stopping path of each state stays clear.

    The ball travels ``distance`` (N,) (m) along its velocity from the position of each
    state ``p`` (N, 4); the path (sampled every 1 cm) must keep clearance >=
    ``footprint`` (pass the footprint plus the XY radius of D' around the path). A
    capture policy's D' must contain this path, and D' grown by the footprint must be
    obstacle free, so this bounds the coverage any capture design with that stopping
    distance can reach.
    """
    speed = np.hypot(p[:, 2], p[:, 3])
    unit = p[:, 2:4] / np.maximum(speed, 1e-12)[:, None]
    ok = np.ones(p.shape[0], dtype=bool)
    steps = int(np.ceil(distance.max() / 0.01)) + 1
    for k in range(steps + 1):
        u = np.minimum(k * 0.01, distance)
        ok &= room_clearance(p[:, :2] + unit * u[:, None], size, box) >= footprint
    return ok


def _interpolator(x: FloatArray, y: FloatArray) -> Callable[[FloatArray], FloatArray]:
    """Piecewise-linear y(x) (held beyond the ends)."""

    def f(v: FloatArray) -> FloatArray:
        out: FloatArray = np.interp(v, x, y)
        return out

    return f


def cmd_room(args: argparse.Namespace) -> None:
    """Fraction of the coverage target's states that can stop clear of obstacles."""
    rng = np.random.default_rng(args.seed)
    kappa = flat_output_gain(BallbotParams())
    ideal = math.tan(math.radians(8.0)) * kappa
    models: dict[str, Callable[[FloatArray], FloatArray]] = {}
    for name, table in (
        ("regulator, plan lean", args.regulator_plan),
        ("regulator, worst push lean", args.regulator_worst),
        ("braking maneuver, 4.5 deg planned", args.braking),
    ):
        sp = np.concatenate([[0.0], 0.1 * np.arange(1, len(table) + 1)])
        dist = np.concatenate([[0.0], table])
        models[name] = _interpolator(sp, dist)
    models["constant 8 deg lean, no delay (physical bound)"] = _interpolator(
        np.linspace(0.0, 1.0, 101), np.linspace(0.0, 1.0, 101) ** 2 / (2 * ideal)
    )
    print(
        f"room {args.size:g} m x {args.size:g} m, central box {args.box:g} m, footprint "
        f"{args.footprint:g} m; {args.samples} states (seed {args.seed}), |v| <= "
        f"{args.v_max:g} m/s uniform in the disc; path sampled every 1 cm"
    )
    print("| stopping model | margin m | D' radius m | states that stop clear % |")
    print("|---|---|---|---|")
    for margin in args.margins:
        xy = np.zeros((0, 2))
        while xy.shape[0] < args.samples:
            cand = rng.uniform(0.0, args.size, size=(2 * args.samples, 2))
            keep = room_clearance(cand, args.size, args.box) >= args.footprint + margin
            xy = np.concatenate([xy, cand[keep]])
        xy = xy[: args.samples]
        rad = args.v_max * np.sqrt(rng.uniform(size=args.samples))
        ang = rng.uniform(0.0, 2 * math.pi, size=args.samples)
        p = np.column_stack([xy, rad * np.cos(ang), rad * np.sin(ang)])
        for radius in args.radii:
            for name, model in models.items():
                ok = stoppable(p, model(rad), args.size, args.box, args.footprint + radius)
                print(f"| {name} | {margin:g} | {radius:g} | {100 * ok.mean():.2f} |")


# --------------------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------------------
def _outer_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--outer",
        type=float,
        nargs=2,
        default=None,
        metavar=("F_P", "F_V"),
        help="check D' = D(t) (or S, with --hold) stretched by these position and "
        "velocity factors; default: D' unchecked, the needed factors are reported",
    )
    p.add_argument("--hold", action="store_true", help="D' stretches S and does not shrink")
    p.add_argument(
        "--variants",
        nargs="+",
        default=list(LEAN_VARIANTS),
        choices=list(LEAN_VARIANTS),
        help="initial lean variants",
    )


def build_parser() -> argparse.ArgumentParser:
    """The command-line parser."""
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    sub = ap.add_subparsers(dest="command", required=True)

    p = sub.add_parser("push", help="lean and lean rate a push leaves")
    p.set_defaults(func=cmd_push)

    p = sub.add_parser("regulator", help="stop in place with the rest regulator")
    p.add_argument("--duration", type=float, default=6.0, help="hold time (s)")
    p.add_argument("--max-speed", type=float, default=1.0, help="largest initial speed (m/s)")
    p.add_argument(
        "--compensation",
        type=float,
        nargs="+",
        default=[5.0, 7.0, 10.0],
        help="lean compensation limits to compare (deg)",
    )
    p.set_defaults(func=cmd_regulator)

    p = sub.add_parser("roa", help="largest verified S around a rest point")
    p.add_argument("--duration", type=float, default=4.0, help="t_f (s)")
    p.add_argument("--points", type=int, default=32, help="boundary points in the search")
    p.add_argument("--check-points", type=int, default=128, help="boundary points re-checked")
    p.add_argument(
        "--correlations", type=float, nargs="+", default=[-0.95, -0.9, -0.8, -0.6, -0.3, 0.0]
    )
    p.add_argument(
        "--ratios", type=float, nargs="+", default=[1.0, 1.34, 2.0, 3.0], help="e_v/e_p (1/s)"
    )
    p.add_argument("--max-extent", type=float, default=1.6, help="largest e_p tried (m)")
    p.add_argument("--steps", type=int, default=6, help="bisection steps")
    p.add_argument(
        "--shape",
        type=float,
        nargs=3,
        action="append",
        default=None,
        metavar=("E_P", "E_V", "R"),
        help="check this S (repeatable) from --check-points points instead of searching",
    )
    p.add_argument(
        "--min-speed",
        type=float,
        default=0.8,
        help="required velocity extent of the best shape (m/s)",
    )
    _outer_options(p)
    p.set_defaults(func=cmd_roa)

    p = sub.add_parser("braking", help="braking maneuvers from the robot's own state")
    p.add_argument(
        "--speeds", type=float, nargs="+", default=[0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8]
    )
    p.add_argument(
        "--directions",
        type=float,
        nargs="+",
        default=[0.0, 45.0, 90.0],
        help="directions of the initial velocity (deg)",
    )
    p.add_argument("--max-lean", type=float, default=4.5, help="largest planned lean (deg)")
    p.add_argument("--tail", type=float, default=1.0, help="rest held after stopping (s)")
    p.add_argument("--min-duration", type=float, default=1.0, help="shortest braking maneuver (s)")
    p.add_argument("--points", type=int, default=32)
    p.add_argument("--max-scale", type=float, default=8.0, help="largest S/G tried")
    p.add_argument(
        "--fixed-scales",
        type=float,
        nargs="*",
        default=None,
        help="evaluate these S/G instead of bisecting for the largest",
    )
    p.add_argument("--steps", type=int, default=5, help="bisection steps")
    _outer_options(p)
    p.set_defaults(func=cmd_braking)

    p = sub.add_parser("scaled", help="palette policies at S = s G")
    p.add_argument("--policies", nargs="+", default=["rest", "cruise_x", "rest_to_cruise_x_1_0"])
    p.add_argument(
        "--rest-durations",
        type=float,
        nargs="*",
        default=[2.0, 4.0],
        help="also the rest trim held this long (s)",
    )
    p.add_argument("--scales", type=float, nargs="+", default=[0.5, 1.0, 2.0, 4.0, 8.0])
    p.add_argument("--points", type=int, default=64)
    p.set_defaults(func=cmd_scaled)

    p = sub.add_parser("coverage", help="Monte Carlo coverage by lattices of capture policies")
    p.add_argument(
        "--regulator",
        type=float,
        nargs=3,
        action="append",
        default=None,
        metavar=("E_P", "E_V", "R"),
        help="regulator capture domain S (repeatable; default 0.79 0.79 -0.95)",
    )
    p.add_argument("--steps", type=int, default=8, help="bisection steps on d")
    p.add_argument(
        "--brake-scales",
        type=float,
        nargs="*",
        default=[],
        help="S/G of the braking members at 0.1, 0.2, ... m/s",
    )
    p.add_argument("--brake-directions", type=int, nargs="+", default=[8, 16, 32])
    p.add_argument("--spacings", type=float, nargs="+", default=[0.5, 0.25, 0.125])
    p.add_argument("--v-max", type=float, default=0.5)
    p.add_argument("--samples", type=int, default=100_000)
    p.add_argument("--target", type=float, default=0.99)
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=cmd_coverage)

    p = sub.add_parser("room", help="states of the room that can stop clear of obstacles")
    p.add_argument("--size", type=float, default=5.0, help="room side (m)")
    p.add_argument("--box", type=float, default=1.0, help="side of the central box (m)")
    p.add_argument("--footprint", type=float, default=0.2)
    p.add_argument(
        "--margins",
        type=float,
        nargs="+",
        default=[0.3, 0.1],
        help="clearance beyond the footprint of the sampled states (m)",
    )
    p.add_argument("--v-max", type=float, default=0.5)
    p.add_argument("--samples", type=int, default=100_000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--radii",
        type=float,
        nargs="+",
        default=[0.0, 0.08, 0.235],
        help="XY radius of D' around the stopping path, beyond the footprint (m)",
    )
    p.add_argument(
        "--regulator-plan",
        type=float,
        nargs="+",
        default=[0.058, 0.116, 0.182, 0.266, 0.362],
        help="stop distance (m) at 0.1, 0.2, ... m/s (`regulator`, plan lean)",
    )
    p.add_argument(
        "--regulator-worst",
        type=float,
        nargs="+",
        default=[0.071, 0.143, 0.238, 0.353, 0.483],
        help="stop distance (m) at 0.1, 0.2, ... m/s (`regulator`, worst lean)",
    )
    p.add_argument(
        "--braking",
        type=float,
        nargs="+",
        default=[0.05, 0.1, 0.15, 0.275, 0.437],
        help="stop distance (m) at 0.1, 0.2, ... m/s (`braking`)",
    )
    p.set_defaults(func=cmd_room)
    return ap


def main(argv: Sequence[str] | None = None) -> None:
    """Run one subcommand."""
    args = build_parser().parse_args(argv)
    args.func(args)


if __name__ == "__main__":
    main()
