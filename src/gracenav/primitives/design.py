"""Designing the primitive set Σ(d): the trims at lattice velocities, and the maneuvers
between them planned feasible by the shape trajectory planner (screened by a
linearised estimate first)."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np

from gracenav.errors import ConfigError
from gracenav.model.rotation import quarter_turn
from gracenav.params import BallbotParams
from gracenav.primitives.limited import (
    LimitedReferenceOptions,
    PolynomialReference,
    limited_reference,
)
from gracenav.primitives.motion import (
    _CATALOGUE,
    FloatArray,
    Maneuver,
    MotionPrimitive,
    PrimitiveReport,
    PrimitiveSet,
    PrimitiveSetOptions,
    TrimPrimitive,
    _frozen,
    speed_catalogue,
    trim_names,
)
from gracenav.primitives.shape_planner import (
    NonicReference,
    PositionReference,
    ShapePlannerResult,
    flat_output_gain,
    flat_output_lengths,
    plan_shape_trajectory,
)

__all__ = ["passes_screen"]


def _level_cells(level: int, options: PrimitiveSetOptions) -> int:
    """m: the cruise trims of ``level`` move m d along an axis (1 for the first level,
    the ceiling of the speed ratio above it)."""
    if level == 1:
        return 1
    return math.ceil(options.cruise_speeds[level - 2] / options.cruise_speed - 1e-9)


def _trim_velocities(d: float, options: PrimitiveSetOptions) -> dict[str, FloatArray]:
    """Velocity (m/s) of every trim by name: each cruise speed adjusted so that its
    displacement takes a whole number of planner steps."""
    tick = options.planner.step
    out = {"rest": np.zeros(2)}
    for level, speed in enumerate((options.cruise_speed, *options.cruise_speeds), start=1):
        m = _level_cells(level, options)
        t_axis = max(1, round(m * d / speed / tick)) * tick
        t_diag = max(1, round(m * d * math.sqrt(2.0) / speed / tick)) * tick
        vx = m * d / t_axis
        vd = m * d / t_diag
        x, y, xy = trim_names(level)
        out[x] = np.array([vx, 0.0])
        out[y] = np.array([0.0, vx])
        out[xy] = np.array([vd, vd])
        if level == 1:  # the U-turns' ends
            out["cruise_nx"] = np.array([-vx, 0.0])
            out["cruise_ny"] = np.array([0.0, -vx])
    return out


def _trims(d: float, params: BallbotParams, options: PrimitiveSetOptions) -> list[TrimPrimitive]:
    vel = _trim_velocities(d, options)
    out = [
        TrimPrimitive(
            "rest",
            options.rest_duration,
            _frozen([0.0, 0.0]),
            _frozen(vel["rest"]),
            _frozen(vel["rest"]),
            params,
        ),
        TrimPrimitive(
            "capture",
            options.capture_duration,
            _frozen([0.0, 0.0]),
            _frozen(vel["rest"]),
            _frozen(vel["rest"]),
            params,
        ),
    ]
    for level in range(1, len(options.cruise_speeds) + 2):
        m = _level_cells(level, options) * d
        for name, disp in zip(trim_names(level), ((m, 0.0), (0.0, m), (m, m)), strict=True):
            v = vel[name]
            duration = float(np.max(np.abs(disp)) / np.max(np.abs(v)))
            out.append(TrimPrimitive(name, duration, _frozen(disp), _frozen(v), _frozen(v), params))
    return out


_SCREEN_MARGIN = 0.03


def _maneuver_name(start: str, end: str, cells: tuple[int, int]) -> str:
    return f"{start}_to_{end}_{cells[0]}_{cells[1]}"


def _linear_estimate(ref: NonicReference, params: BallbotParams) -> tuple[float, float]:
    """Peak tilt (rad) and |τ| (N m) of the linearised model's flat-output solution."""
    kappa = flat_output_gain(params)
    lengths = flat_output_lengths(params)
    r = params.ball_radius
    alpha, beta = params.alpha(), params.beta()
    t = np.linspace(0.0, ref.duration, max(2, int(ref.duration * 128) + 1))
    yd, ydd, y3, y4 = (ref.value(t, o) for o in (1, 2, 3, 4))
    ph, phd, phdd = ydd / kappa, y3 / kappa, y4 / kappa
    thd = (yd - lengths * phd) / r - phd
    thdd = (ydd - lengths * phdd) / r - phdd
    # The friction law of gracenav.model.friction written out: its two terms enter this
    # sum one by one, and friction_torque's own sum would round differently.
    fric = params.coulomb_friction * np.tanh(thd / params.friction_smoothing)
    tau = alpha * thdd + (alpha + beta) * phdd + fric + params.viscous_friction * thd
    return float(np.max(np.hypot(ph[:, 0], ph[:, 1]))), float(np.max(np.abs(tau)))


def passes_screen(ref: NonicReference, params: BallbotParams, options: PrimitiveSetOptions) -> bool:
    """Whether a reference is worth planning on the 3D model: the linearised model's
    flat-output solution keeps the lean and the torque within ``options.max_lean`` and
    the torque limit, with :data:`_SCREEN_MARGIN` to spare (cheap; the 3D model's peaks
    differ from it by < 1 %)."""
    lean, tau = _linear_estimate(ref, params)
    return max(lean / options.max_lean, tau / params.torque_limit) <= 1.0 + _SCREEN_MARGIN


def _reference_ok(
    ref: NonicReference, v0: FloatArray, v1: FloatArray, options: PrimitiveSetOptions
) -> bool:
    """Speed cap, and no more than a slight backward motion (``options.max_backward_speed``)
    along an axis whose two end velocities are >= 0."""
    t = np.linspace(0.0, ref.duration, max(2, int(ref.duration * 128) + 1))
    vel = ref.value(t, 1)
    if np.max(np.hypot(vel[:, 0], vel[:, 1])) > options.max_speed * (1 + 1e-9):
        return False
    for i in range(2):
        if v0[i] >= 0 and v1[i] >= 0 and np.min(vel[:, i]) < -options.max_backward_speed:
            return False
    return True


def _plan_pair(
    ref: NonicReference | PolynomialReference,
    v0: FloatArray,
    disp: FloatArray,
    v1: FloatArray,
    params: BallbotParams,
    options: PrimitiveSetOptions,
) -> tuple[ShapePlannerResult, ShapePlannerResult] | None:
    """Plan a maneuver in its frame and rotated by 90°; None if either is infeasible."""

    def feasible(res: ShapePlannerResult) -> bool:
        return res.within(options.max_lean, params.torque_limit)

    res0 = plan_shape_trajectory(ref, params, model="3d", options=options.planner)
    if not feasible(res0):
        return None
    rot = quarter_turn(1)
    ref1: PositionReference
    if isinstance(ref, PolynomialReference):
        ref1 = ref.rotated(rot)
    else:
        ref1 = NonicReference.between(ref.duration, np.zeros(2), rot @ v0, rot @ disp, rot @ v1)
    res1 = plan_shape_trajectory(ref1, params, model="3d", options=options.planner)
    if not feasible(res1):
        return None
    return res0, res1


def _plan_maneuver(
    start: str,
    end: str,
    cells: tuple[int, int],
    d: float,
    params: BallbotParams,
    options: PrimitiveSetOptions,
) -> Maneuver | None:
    """Shortest feasible duration on the grid; None if none within ``max_duration``."""
    vel = _trim_velocities(d, options)
    v0, v1 = vel[start], vel[end]
    disp = np.array(cells, dtype=float) * d
    zero = np.zeros(2)
    step = options.duration_step
    grid = [m * step for m in range(1, math.floor(options.max_duration / step + 1e-9) + 1)]

    def ref_at(duration: float) -> NonicReference:
        return NonicReference.between(duration, zero, v0, disp, v1)

    def candidates() -> Iterator[float]:
        # Plan the 3D model from the shortest duration that passes the screen.
        for duration in grid:
            ref = ref_at(duration)
            if not _reference_ok(ref, v0, v1, options):
                continue
            if passes_screen(ref, params, options):
                yield duration

    chosen: tuple[float, tuple[ShapePlannerResult, ShapePlannerResult]] | None = None
    if options.reference == "limited":
        chosen = _plan_limited(v0, disp, v1, grid, params, options)
    else:
        for duration in candidates():
            pair = _plan_pair(ref_at(duration), v0, disp, v1, params, options)
            if pair is not None:
                chosen = (duration, pair)
                break
    if chosen is None:
        return None
    duration, (res0, res1) = chosen
    return Maneuver(
        name=_maneuver_name(start, end, cells),
        duration=duration,
        displacement=_frozen(disp),
        start_velocity=_frozen(v0),
        end_velocity=_frozen(v1),
        params=params,
        start_trim=start,
        end_trim=end,
        plans=(res0.trajectory, res1.trajectory),
        reports=(PrimitiveReport.from_result(res0), PrimitiveReport.from_result(res1)),
    )


def _plan_limited(
    v0: FloatArray,
    disp: FloatArray,
    v1: FloatArray,
    grid: list[float],
    params: BallbotParams,
    options: PrimitiveSetOptions,
) -> tuple[float, tuple[ShapePlannerResult, ShapePlannerResult]] | None:
    """The shortest duration of ``grid`` whose limited reference (degree 15, the lean,
    torque and ball jerk within the limits on the linearised model) the shape trajectory planner
    makes feasible on the 3D model in both frames, with its plans; the grid is bisected
    for the linear program's shortest duration first, then climbed until the plans
    are feasible."""
    lim = LimitedReferenceOptions(
        max_speed=options.max_speed,
        max_backward_speed=options.max_backward_speed,
        max_ball_jerk=options.max_ball_jerk,
    )

    def reference(duration: float) -> PolynomialReference | None:
        return limited_reference(
            v0, disp, v1, params, max_lean=options.max_lean, durations=[duration], options=lim
        )

    first = limited_reference(
        v0, disp, v1, params, max_lean=options.max_lean, durations=grid, options=lim
    )
    if first is None:
        return None
    hi = next(k for k, g in enumerate(grid) if g == first.duration)
    for k in range(hi, len(grid)):
        ref = first if k == hi else reference(grid[k])
        if ref is None:
            continue
        pair = _plan_pair(ref, v0, disp, v1, params, options)
        if pair is not None:
            return grid[k], pair
    return None


def _check_trim_durations(d: float, options: PrimitiveSetOptions) -> None:
    """Refuse cruise trims that would outlast the longest maneuver (a diagonal trim
    lasts √2 m d / v), before anything is sampled: a cruise speed near zero, or a huge
    d, would otherwise make trims, and the policies sampled from them at the control
    rate, of any length."""
    for level, speed in enumerate((options.cruise_speed, *options.cruise_speeds), start=1):
        lasts = math.sqrt(2.0) * _level_cells(level, options) * d / speed
        if lasts > options.max_duration:
            raise ConfigError(
                f"a cruise trim at {speed:g} m/s over d = {d:g} m would last {lasts:.3g} s, "
                f"longer than the longest maneuver ({options.max_duration:g} s): raise the "
                "cruise speed or lower d"
            )


def _build(d: float, params: BallbotParams, options: PrimitiveSetOptions) -> PrimitiveSet:
    _check_trim_durations(d, options)
    prims: list[MotionPrimitive] = list(_trims(d, params, options))
    omitted: list[str] = []
    for start, end, cells in _CATALOGUE:
        m = _plan_maneuver(start, end, cells, d, params, options)
        if m is None:
            omitted.append(_maneuver_name(start, end, cells))
        else:
            prims.append(m)
    for level in range(2, len(options.cruise_speeds) + 2):
        for start, end, candidates in speed_catalogue(level):
            for cells in candidates:
                m = _plan_maneuver(start, end, cells, d, params, options)
                if m is not None:
                    prims.append(m)
                    break
            else:
                omitted.append(f"{start}_to_{end}")
    return PrimitiveSet(d, params, options, tuple(prims), tuple(omitted))
