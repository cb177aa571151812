"""Motion primitives and the motion primitive set Σ(d) (paper Sec. III-A).

A motion primitive is a feasible reference state trajectory of the 3D model.
*Trim primitives* are steady states: rest (constant position) or cruise
(constant velocity), upright, of arbitrary duration. *Maneuvers* have a fixed
duration and connect two trims: their desired position trajectory is a nonic
polynomial per axis (position and velocity of the two trims at the ends;
acceleration, jerk and snap zero), treated as the flat output and turned into
a feasible state trajectory by :func:`gracenav.primitives.shape_planner.plan_shape_trajectory`.

Every primitive of Σ(d) has a net displacement (Δx, Δy) that is an integer
multiple of d with both components >= 0 (first quadrant); instantiation
rotates primitives by multiples of 90°.

Rotations. A rotation by 180° maps a feasible trajectory of the 3D model to a
feasible one exactly (negate θ, φ, rates, accelerations and torques). A
rotation by 90° does *not*: the body's roll and pitch inertias differ
(I_xx ≠ I_yy) and the lean coordinates have a fixed Euler order, so the
rotated samples would violate the equations of motion by ~0.2 N m. Each
maneuver is therefore planned twice, for its own frame and for the frame
rotated by 90° (the rotated nonic as the desired flat output, same duration);
rotations by 180° and 270° negate those two plans. The two plans' ball paths
differ from exact rotations of each other by a fraction of a millimetre.

The set is cached on disk (in :func:`gracenav._util.cache.cache_dir`) as one ``.npz``
file (no pickle) per key, the key being a hash of the inputs only (parameters,
d, the options and :data:`CODE_VERSION`), never of a computed result.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import math
import zipfile
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav._util.cache import cache_dir
from gracenav._util.io import atomic_write_bytes
from gracenav.errors import CacheError, ConfigError
from gracenav.model.friction import friction_constants, friction_torque
from gracenav.params import BallbotParams
from gracenav.primitives.shape_planner import (
    NonicReference,
    ShapePlannerOptions,
    ShapePlannerResult,
    ShapeTrajectory,
    TrajectorySample,
    flat_output_gain,
    flat_output_lengths,
    plan_shape_trajectory,
)

__all__ = [
    "CODE_VERSION",
    "Maneuver",
    "MotionPrimitive",
    "PrimitiveReport",
    "PrimitiveSample",
    "PrimitiveSet",
    "PrimitiveSetOptions",
    "TrimPrimitive",
    "cache_dir",
    "primitive_set",
    "rotation_matrix",
]

FloatArray = NDArray[np.float64]

CODE_VERSION = "primitives-1"
"""Version of the primitive-set construction; part of the cache key."""

PrimitiveSample = TrajectorySample
"""Samples of a primitive: time (N,), states (N, 8), accelerations (N, 4),
inputs (N, 2) and ball position state (N, 6) = x, y, ẋ, ẏ, ẍ, ÿ in the
primitive's own frame (see :class:`gracenav.primitives.shape_planner.TrajectorySample`)."""


def rotation_matrix(k: int) -> FloatArray:
    """Rotation by k·90° counter-clockwise, shape (2, 2), exact integers."""
    k %= 4
    c = (1.0, 0.0, -1.0, 0.0)[k]
    s = (0.0, 1.0, 0.0, -1.0)[k]
    return np.array([[c, -s], [s, c]])


def _rotate_pairs(a: FloatArray, k: int) -> FloatArray:
    """Rotate every consecutive (x, y) pair of the last axis by k·90°."""
    rot = rotation_matrix(k)
    shape = a.shape
    pairs = a.reshape(*shape[:-1], shape[-1] // 2, 2)
    return np.asarray(pairs @ rot.T, dtype=float).reshape(shape)


def _frozen(a: ArrayLike) -> FloatArray:
    out = np.array(a, dtype=float)
    out.setflags(write=False)
    return out


# --------------------------------------------------------------------------------------
# Primitives
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PrimitiveReport:
    """Quality figures of one planned maneuver (one orientation).

    Attributes
    ----------
    peak_lean : float
        Largest body tilt from vertical (rad).
    peak_torque : float
        Largest |τ_x|, |τ_y| (N m), friction included.
    tracking_rms, tracking_max : float
        Achieved flat output against the nonic (m), over the integration nodes.
    ball_max : float
        Largest |ball position − nonic| (m): the physical roll-back / overshoot.
    end_error : float
        End position (m) / velocity (m/s) error against the connected trim.
    dynamics_residual : float
        Largest equation-of-motion residual over the nodes (N m).
    integration_error : float
        Richardson estimate of the integration error of θ at t_f (rad).
    iterations : int
        Gauss–Newton iterations of the shape planner.
    """

    peak_lean: float
    peak_torque: float
    tracking_rms: float
    tracking_max: float
    ball_max: float
    end_error: float
    dynamics_residual: float
    integration_error: float
    iterations: int

    @classmethod
    def from_result(cls, res: ShapePlannerResult) -> PrimitiveReport:
        """Extract the figures of a shape planner result."""
        return cls(
            res.peak_lean,
            res.peak_torque,
            res.tracking_rms,
            res.tracking_max,
            res.ball_max,
            res.end_error,
            res.dynamics_residual,
            res.integration_error,
            res.iterations,
        )


@dataclass(frozen=True, eq=False)
class MotionPrimitive:
    """A feasible reference state trajectory of the 3D model (paper Sec. III-A).

    Attributes
    ----------
    name : str
        Name within its set (the same for every rotation).
    duration : float
        Nominal duration t_f (s), a whole number of 1/1024 s.
    displacement : ndarray, shape (2,)
        Net ball displacement (Δx, Δy) (m) over ``duration``.
    start_velocity, end_velocity : ndarray, shape (2,)
        Ball velocity at t = 0 and t_f (m/s).
    params : BallbotParams
        Model parameters the primitive is feasible for.
    rotation : int
        Orientation k ∈ {0, 1, 2, 3}: rotated by k·90° from the set's frame.
    """

    name: str
    duration: float
    displacement: FloatArray
    start_velocity: FloatArray
    end_velocity: FloatArray
    params: BallbotParams
    rotation: int = 0

    @property
    def is_trim(self) -> bool:
        """Whether this is a trim primitive (steady state, arbitrary duration)."""
        return False

    def sample(self, timepts: ArrayLike) -> PrimitiveSample:
        """Sample the primitive at ``timepts`` (s), shape (N,), in its own frame."""
        raise NotImplementedError

    def rotated(self, k: int) -> MotionPrimitive:
        """This primitive rotated by a further k·90° counter-clockwise."""
        raise NotImplementedError

    def _rotated_fields(self, k: int) -> dict[str, Any]:
        return {
            "displacement": _frozen(rotation_matrix(k) @ self.displacement),
            "start_velocity": _frozen(rotation_matrix(k) @ self.start_velocity),
            "end_velocity": _frozen(rotation_matrix(k) @ self.end_velocity),
            "rotation": (self.rotation + k) % 4,
        }


@dataclass(frozen=True, eq=False)
class TrimPrimitive(MotionPrimitive):
    """Trim primitive: upright at rest or at constant velocity.

    ``duration`` is nominal (rest: a hold time; cruise: the time to travel
    ``displacement``); trims may be cut to any duration, and :meth:`sample`
    accepts any t >= 0. The ball angles grow linearly, θ = v t / r_w, and the
    torque is the friction at that ball rate.
    """

    @property
    def is_trim(self) -> bool:
        """Always True."""
        return True

    @property
    def velocity(self) -> FloatArray:
        """Constant ball velocity (m/s), shape (2,)."""
        return self.start_velocity

    def sample(self, timepts: ArrayLike) -> PrimitiveSample:
        """Sample at ``timepts`` (s), shape (N,), any t >= 0."""
        t = np.atleast_1d(np.asarray(timepts, dtype=float))
        if t.ndim != 1:
            raise ConfigError(f"timepts must be one-dimensional, got shape {t.shape}")
        if t.size and t.min() < -1e-9:
            raise ConfigError(f"sample times must be >= 0 s, got {t.min()}")
        r = self.params.ball_radius
        v = self.velocity
        n = t.size
        states = np.zeros((n, 8))
        states[:, 0:2] = t[:, None] * v / r
        states[:, 4:6] = v / r
        p = self.params
        inputs = friction_torque(friction_constants(p), states[:, 4:6])
        position = np.zeros((n, 6))
        position[:, 0:2] = t[:, None] * v
        position[:, 2:4] = v
        return PrimitiveSample(t, states, np.zeros((n, 4)), inputs, position)

    def rotated(self, k: int) -> TrimPrimitive:
        """This trim rotated by a further k·90° (exact)."""
        return dataclasses.replace(self, **self._rotated_fields(k))


@dataclass(frozen=True, eq=False)
class Maneuver(MotionPrimitive):
    """Maneuver: fixed-duration feasible trajectory between two trims.

    Attributes
    ----------
    start_trim, end_trim : str
        Names of the connected trims; ``end_trim`` may be a reversed cruise
        (``"cruise_nx"``, ``"cruise_ny"``: the cruise trim rotated by 180°).
    plans : tuple of ShapeTrajectory
        The planned trajectory in the set's frame and in the frame rotated by
        90° (see the module notes on rotations).
    reports : tuple of PrimitiveReport
        Quality figures of the two plans.
    """

    start_trim: str = ""
    end_trim: str = ""
    plans: tuple[ShapeTrajectory, ShapeTrajectory] | None = None
    reports: tuple[PrimitiveReport, PrimitiveReport] | None = None

    def _plans(self) -> tuple[ShapeTrajectory, ShapeTrajectory]:
        if self.plans is None:
            raise ConfigError(f"maneuver {self.name} has no planned trajectory")
        return self.plans

    @property
    def report(self) -> PrimitiveReport:
        """Quality figures of the plan used at this orientation."""
        if self.reports is None:
            raise ConfigError(f"maneuver {self.name} has no report")
        return self.reports[self.rotation % 2]

    @property
    def peak_lean(self) -> float:
        """Largest body tilt at this orientation (rad)."""
        return self.report.peak_lean

    @property
    def peak_torque(self) -> float:
        """Largest |τ| at this orientation (N m)."""
        return self.report.peak_torque

    def sample(self, timepts: ArrayLike) -> PrimitiveSample:
        """Sample at ``timepts`` (s), shape (N,), within [0, t_f]."""
        s = self._plans()[self.rotation % 2].sample(timepts)
        if self.rotation >= 2:
            return PrimitiveSample(s.time, -s.states, -s.accelerations, -s.inputs, -s.position)
        return s

    def rotated(self, k: int) -> Maneuver:
        """This maneuver rotated by a further k·90° (a feasible 3D trajectory at every k)."""
        return dataclasses.replace(self, **self._rotated_fields(k))


# --------------------------------------------------------------------------------------
# The set
# --------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class PrimitiveSet:
    """The motion primitive set Σ(d): an ordered, immutable collection.

    Index by position or by name (``pset["rest"]``); iterate in order.

    Attributes
    ----------
    d : float
        Distance parameter (m): every displacement is an integer multiple of d.
    params : BallbotParams
    options : PrimitiveSetOptions
    primitives : tuple of MotionPrimitive
        Trims first, then maneuvers.
    omitted : tuple of str
        Maneuvers of the catalogue with no feasible duration within the limits.
    """

    d: float
    params: BallbotParams
    options: PrimitiveSetOptions
    primitives: tuple[MotionPrimitive, ...]
    omitted: tuple[str, ...] = ()
    _by_name: dict[str, int] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        names = [p.name for p in self.primitives]
        if len(set(names)) != len(names):
            raise ConfigError("primitive names must be unique")
        object.__setattr__(self, "_by_name", {n: i for i, n in enumerate(names)})

    def __len__(self) -> int:
        return len(self.primitives)

    def __iter__(self) -> Iterator[MotionPrimitive]:
        return iter(self.primitives)

    def __contains__(self, name: object) -> bool:
        return name in self._by_name

    def __getitem__(self, key: int | str) -> MotionPrimitive:
        if isinstance(key, str):
            try:
                return self.primitives[self._by_name[key]]
            except KeyError:
                raise KeyError(
                    f"no primitive named {key!r}; known: {', '.join(self.names)}"
                ) from None
        return self.primitives[key]

    @property
    def names(self) -> tuple[str, ...]:
        """Primitive names in order."""
        return tuple(p.name for p in self.primitives)

    @property
    def trims(self) -> tuple[TrimPrimitive, ...]:
        """The trim primitives."""
        return tuple(p for p in self.primitives if isinstance(p, TrimPrimitive))

    @property
    def maneuvers(self) -> tuple[Maneuver, ...]:
        """The maneuvers."""
        return tuple(p for p in self.primitives if isinstance(p, Maneuver))


@dataclass(frozen=True)
class PrimitiveSetOptions:
    """Options of :func:`primitive_set`.

    Parameters
    ----------
    cruise_speed : float
        Nominal cruise speed (m/s). The cruise trims' speeds are adjusted so
        that their displacement (d along an axis, (d, d) on the diagonal) takes
        a whole number of 1/1024 s (for d = 0.5: 0.5 m/s along the axes,
        0.50006 m/s on the diagonal).
    rest_duration : float
        Nominal hold time of the rest trim (s).
    capture_duration : float
        Hold time of the capture trim (s): a rest trim long enough for the
        closed loop to bring a robot that moves (after a push, say) from a large
        start domain into the rest trim's goal domain; see
        :func:`gracenav.policies.scaled_variants`.
    max_lean : float
        Largest body tilt a maneuver may plan (rad); 4.5°.
    max_speed : float
        Largest speed of a maneuver's desired trajectory (m/s): keeps the
        shortest-duration search from sprinting between cruise trims.
    max_backward_speed : float
        Largest backward speed (m/s) of the desired trajectory along an axis
        whose end velocities are both >= 0 (a nonic that is too long for its
        displacement runs backwards).
    duration_step : float
        Grid of maneuver durations (s); 1/8 s, a whole number of control
        periods (1/1024 s).
    max_duration : float
        Longest maneuver (s): longer nonics run backwards between trims.
    planner : ShapePlannerOptions
        Options of the shape trajectory planner.
    """

    cruise_speed: float = 0.5
    rest_duration: float = 1.0
    capture_duration: float = 3.0
    max_lean: float = math.radians(4.5)
    max_speed: float = 0.8
    max_backward_speed: float = 0.02
    duration_step: float = 0.125
    max_duration: float = 4.5
    planner: ShapePlannerOptions = field(default_factory=ShapePlannerOptions)

    def __post_init__(self) -> None:
        for name in (
            "cruise_speed",
            "rest_duration",
            "capture_duration",
            "max_lean",
            "max_speed",
            "max_backward_speed",
            "duration_step",
            "max_duration",
        ):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ConfigError(f"PrimitiveSetOptions.{name} must be positive, got {v!r}")
        ratio = self.duration_step / self.planner.step
        if abs(ratio - round(ratio)) > 1e-9:
            raise ConfigError(
                "PrimitiveSetOptions.duration_step must be a whole number of planner steps "
                f"({self.planner.step} s), got {self.duration_step}"
            )

    def to_dict(self) -> dict[str, Any]:
        """Plain-dict form (for cache keys and file headers)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> PrimitiveSetOptions:
        """Inverse of :meth:`to_dict`."""
        fields = dict(data)
        fields["planner"] = ShapePlannerOptions(**fields["planner"])
        return cls(**fields)


# Catalogue: (start trim, end trim, (i, j) displacement in units of d).
# Trims: rest, cruise_x (+x), cruise_y (+y), cruise_xy (+x+y); cruise_nx / cruise_ny
# are cruise_x / cruise_y reversed (end of U-turns).
_CATALOGUE: tuple[tuple[str, str, tuple[int, int]], ...] = (
    # rest -> rest
    ("rest", "rest", (1, 0)),
    ("rest", "rest", (2, 0)),
    ("rest", "rest", (1, 1)),
    ("rest", "rest", (2, 1)),
    ("rest", "rest", (1, 2)),
    ("rest", "rest", (2, 2)),
    # start and stop, along an axis and along the diagonal
    ("rest", "cruise_x", (1, 0)),
    ("rest", "cruise_x", (2, 0)),
    ("rest", "cruise_x", (3, 0)),
    ("rest", "cruise_xy", (1, 1)),
    ("rest", "cruise_xy", (2, 2)),
    ("cruise_x", "rest", (1, 0)),
    ("cruise_x", "rest", (2, 0)),
    ("cruise_x", "rest", (3, 0)),
    ("cruise_xy", "rest", (1, 1)),
    ("cruise_xy", "rest", (2, 2)),
    # 45° turns, left and right (rotations cover every heading)
    ("cruise_x", "cruise_xy", (2, 1)),
    ("cruise_x", "cruise_xy", (3, 2)),
    ("cruise_y", "cruise_xy", (1, 2)),
    ("cruise_y", "cruise_xy", (2, 3)),
    ("cruise_xy", "cruise_x", (2, 1)),
    ("cruise_xy", "cruise_x", (3, 2)),
    ("cruise_xy", "cruise_y", (1, 2)),
    ("cruise_xy", "cruise_y", (2, 3)),
    # 90° turns, left (+x -> +y) and right (+y -> +x)
    ("cruise_x", "cruise_y", (1, 1)),
    ("cruise_x", "cruise_y", (2, 2)),
    ("cruise_y", "cruise_x", (1, 1)),
    ("cruise_y", "cruise_x", (2, 2)),
    # lane changes, left (heading +x) and right (heading +y)
    ("cruise_x", "cruise_x", (3, 1)),
    ("cruise_x", "cruise_x", (4, 1)),
    ("cruise_y", "cruise_y", (1, 3)),
    ("cruise_y", "cruise_y", (1, 4)),
    # U-turns, left (heading +x, back along -x) and right (heading +y, back along -y)
    ("cruise_x", "cruise_nx", (0, 1)),
    ("cruise_x", "cruise_nx", (0, 2)),
    ("cruise_y", "cruise_ny", (1, 0)),
    ("cruise_y", "cruise_ny", (2, 0)),
)


def _trim_velocities(d: float, options: PrimitiveSetOptions) -> dict[str, FloatArray]:
    tick = options.planner.step
    t_axis = max(1, round(d / options.cruise_speed / tick)) * tick
    t_diag = max(1, round(d * math.sqrt(2.0) / options.cruise_speed / tick)) * tick
    vx = d / t_axis
    vd = d / t_diag
    return {
        "rest": np.zeros(2),
        "cruise_x": np.array([vx, 0.0]),
        "cruise_y": np.array([0.0, vx]),
        "cruise_xy": np.array([vd, vd]),
        "cruise_nx": np.array([-vx, 0.0]),
        "cruise_ny": np.array([0.0, -vx]),
    }


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
    for name, disp in (("cruise_x", (d, 0.0)), ("cruise_y", (0.0, d)), ("cruise_xy", (d, d))):
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
    ref: NonicReference,
    v0: FloatArray,
    disp: FloatArray,
    v1: FloatArray,
    params: BallbotParams,
    options: PrimitiveSetOptions,
) -> tuple[ShapePlannerResult, ShapePlannerResult] | None:
    """Plan a maneuver in its frame and rotated by 90°; None if either is infeasible."""

    def feasible(res: ShapePlannerResult) -> bool:
        return (
            res.converged
            and res.peak_lean <= options.max_lean
            and res.peak_torque <= params.torque_limit
        )

    res0 = plan_shape_trajectory(ref, params, model="3d", options=options.planner)
    if not feasible(res0):
        return None
    rot = rotation_matrix(1)
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
    limit_lean, limit_tau = options.max_lean, params.torque_limit
    grid = [m * step for m in range(1, math.floor(options.max_duration / step + 1e-9) + 1)]

    def ref_at(duration: float) -> NonicReference:
        return NonicReference.between(duration, zero, v0, disp, v1)

    def candidates() -> Iterator[float]:
        # Screen the grid with the linearised model's flat-output solution (cheap); plan
        # the 3D model from the shortest duration whose estimate is within a small margin
        # of the limits (the 3D model's peaks differ from the estimate by < 1 %).
        for duration in grid:
            ref = ref_at(duration)
            if not _reference_ok(ref, v0, v1, options):
                continue
            lean, tau = _linear_estimate(ref, params)
            if max(lean / limit_lean, tau / limit_tau) <= 1.0 + _SCREEN_MARGIN:
                yield duration

    chosen: tuple[float, tuple[ShapePlannerResult, ShapePlannerResult]] | None = None
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


def _build(d: float, params: BallbotParams, options: PrimitiveSetOptions) -> PrimitiveSet:
    prims: list[MotionPrimitive] = list(_trims(d, params, options))
    omitted: list[str] = []
    for start, end, cells in _CATALOGUE:
        m = _plan_maneuver(start, end, cells, d, params, options)
        if m is None:
            omitted.append(_maneuver_name(start, end, cells))
        else:
            prims.append(m)
    return PrimitiveSet(d, params, options, tuple(prims), tuple(omitted))


# --------------------------------------------------------------------------------------
# Cache
# --------------------------------------------------------------------------------------
def _cache_key(d: float, params: BallbotParams, options: PrimitiveSetOptions) -> str:
    payload = json.dumps(
        {
            "version": CODE_VERSION,
            "d": float(d),
            "params": params.to_dict(),
            "options": options.to_dict(),
        },
        sort_keys=True,
    )
    return hashlib.sha256(payload.encode()).hexdigest()


def _digest(arrays: Mapping[str, FloatArray]) -> str:
    h = hashlib.blake2b(digest_size=32)
    for key in sorted(arrays):
        a = np.ascontiguousarray(arrays[key])
        h.update(key.encode())
        h.update(str(a.dtype).encode())
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


_TRAJ_FIELDS = ("knots", "coefficients", "theta", "theta_dot", "theta_ddot")


def _encode(pset: PrimitiveSet, key: str) -> bytes:
    arrays: dict[str, FloatArray] = {}
    records: list[dict[str, Any]] = []
    for i, p in enumerate(pset.primitives):
        rec: dict[str, Any] = {
            "name": p.name,
            "type": "trim" if isinstance(p, TrimPrimitive) else "maneuver",
            "duration": p.duration,
            "displacement": p.displacement.tolist(),
            "start_velocity": p.start_velocity.tolist(),
            "end_velocity": p.end_velocity.tolist(),
        }
        if isinstance(p, Maneuver):
            rec["start_trim"] = p.start_trim
            rec["end_trim"] = p.end_trim
            rec["reports"] = [dataclasses.asdict(r) for r in p.reports or ()]
            for o, traj in enumerate(p._plans()):
                for f in _TRAJ_FIELDS:
                    arrays[f"p{i}_o{o}_{f}"] = getattr(traj, f)
        records.append(rec)
    meta = {
        "key": key,
        "version": CODE_VERSION,
        "step": pset.options.planner.step,
        "primitives": records,
        "omitted": list(pset.omitted),
        "digest": _digest(arrays),
    }
    buf = io.BytesIO()
    members: dict[str, Any] = dict(arrays)
    members["__meta__"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    np.savez(buf, **members)
    return buf.getvalue()


def _decode(
    data: bytes, key: str, d: float, params: BallbotParams, options: PrimitiveSetOptions
) -> PrimitiveSet:
    """Rebuild a set from cache bytes; raises CacheError if anything does not match."""
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        meta = json.loads(arrays.pop("__meta__").tobytes().decode())
    except (OSError, ValueError, KeyError, zipfile.BadZipFile, EOFError) as exc:
        raise CacheError(f"unreadable primitive cache: {exc}") from None
    if not isinstance(meta, dict):
        raise CacheError("primitive cache metadata is not a mapping")
    if meta.get("key") != key or meta.get("version") != CODE_VERSION:
        raise CacheError("primitive cache key does not match")
    if meta.get("digest") != _digest(arrays):
        raise CacheError("primitive cache arrays do not match their digest")
    try:
        prims: list[MotionPrimitive] = []
        for i, rec in enumerate(meta["primitives"]):
            common = {
                "name": rec["name"],
                "duration": float(rec["duration"]),
                "displacement": _frozen(rec["displacement"]),
                "start_velocity": _frozen(rec["start_velocity"]),
                "end_velocity": _frozen(rec["end_velocity"]),
                "params": params,
            }
            if rec["type"] == "trim":
                prims.append(TrimPrimitive(**common))
                continue
            plans = tuple(
                ShapeTrajectory(
                    params,
                    "3d",
                    float(rec["duration"]),
                    float(meta["step"]),
                    *(arrays[f"p{i}_o{o}_{f}"] for f in _TRAJ_FIELDS),
                )
                for o in range(2)
            )
            reports = tuple(PrimitiveReport(**r) for r in rec["reports"])
            prims.append(
                Maneuver(
                    **common,
                    start_trim=rec["start_trim"],
                    end_trim=rec["end_trim"],
                    plans=plans,  # type: ignore[arg-type]
                    reports=reports,  # type: ignore[arg-type]
                )
            )
        return PrimitiveSet(d, params, options, tuple(prims), tuple(meta["omitted"]))
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
        raise CacheError(f"malformed primitive cache: {exc}") from None


def _cache_path(key: str) -> Path:
    return cache_dir() / f"primitives-{key[:24]}.npz"


def primitive_set(
    d: float = 0.5,
    params: BallbotParams | None = None,
    *,
    options: PrimitiveSetOptions | None = None,
    cache: bool = True,
) -> PrimitiveSet:
    """The motion primitive set Σ(d) (about 40 primitives).

    Trims: ``rest``, ``capture`` (a longer rest trim for catching a moving robot),
    ``cruise_x``, ``cruise_y``, ``cruise_xy``. Maneuvers,
    named ``<start>_to_<end>_<i>_<j>`` with displacement (i d, j d): rest to
    rest; start and stop along an axis and the diagonal; 45° and 90° turns in
    both directions; lane changes; U-turns. Each maneuver has the shortest
    duration on the ``options.duration_step`` grid (at most
    ``options.max_duration``) for which its 3D plans in both frames (0° and
    90°) keep the tilt within ``options.max_lean`` and the torque within
    ``params.torque_limit``, with friction.

    Parameters
    ----------
    d : float
        Distance parameter (m).
    params : BallbotParams, optional
        Model parameters (default: the CMU ballbot).
    options : PrimitiveSetOptions, optional
    cache : bool
        Read and write the on-disk cache (see :func:`cache_dir`). A cache file
        that is unreadable, corrupt or for another key is ignored, recomputed
        and overwritten.

    Returns
    -------
    PrimitiveSet
    """
    if not (isinstance(d, (int, float)) and math.isfinite(d) and d > 0):
        raise ConfigError(f"distance parameter d must be positive, got {d!r}")
    params = params if params is not None else BallbotParams()
    options = options if options is not None else PrimitiveSetOptions()
    d = float(d)
    key = _cache_key(d, params, options)
    path = _cache_path(key)
    if cache and path.is_file():
        try:
            return _decode(path.read_bytes(), key, d, params, options)
        except (CacheError, OSError):
            pass  # recompute and overwrite below
    pset = _build(d, params, options)
    if cache:
        try:
            atomic_write_bytes(path, _encode(pset, key))
        except OSError:
            pass  # a read-only cache directory only costs the recomputation
    return pset
