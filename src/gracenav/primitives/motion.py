"""Motion primitives (paper Sec. IV-A): trims (steady motions of any duration) and
maneuvers (nonic transitions between trims) with their planned state trajectories, and
the primitive set Σ(d) with its options."""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.errors import ConfigError
from gracenav.model.friction import friction_constants, friction_torque
from gracenav.model.rotation import quarter_turn
from gracenav.params import BallbotParams
from gracenav.primitives.shape_planner import (
    ShapePlannerOptions,
    ShapePlannerResult,
    ShapeTrajectory,
    TrajectorySample,
)

__all__ = [
    "Maneuver",
    "MotionPrimitive",
    "PrimitiveReport",
    "PrimitiveSample",
    "PrimitiveSet",
    "PrimitiveSetOptions",
    "TrimPrimitive",
]

FloatArray = NDArray[np.float64]

PrimitiveSample = TrajectorySample
"""Samples of a primitive: time (N,), states (N, 8), accelerations (N, 4),
inputs (N, 2) and ball position state (N, 6) = x, y, ẋ, ẏ, ẍ, ÿ in the
primitive's own frame (see :class:`gracenav.primitives.shape_planner.TrajectorySample`)."""


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
            "displacement": _frozen(quarter_turn(k) @ self.displacement),
            "start_velocity": _frozen(quarter_turn(k) @ self.start_velocity),
            "end_velocity": _frozen(quarter_turn(k) @ self.end_velocity),
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
    reference : {"nonic", "limited"}
        Desired flat output of the maneuvers: the nonic of fixed form (the paper's), or
        the polynomial of degree 15 that keeps the lean and torque within their limits
        for the shortest duration (:mod:`gracenav.primitives.limited`).
    cruise_speeds : tuple of float
        Further cruise speeds (m/s), ascending, above ``cruise_speed``: level k (from 2)
        has the trims ``cruiseK_x``, ``cruiseK_y`` and ``cruiseK_xy``, whose
        displacement is m d along an axis (m d, m d on the diagonal) with m the ceiling
        of the speed over ``cruise_speed`` (so that a trim lasts about as long as the
        first level's), and the maneuvers of :func:`speed_catalogue` (starts and stops,
        speed changes from the level below, 45° and 90° turns, lane changes), each at
        the smallest displacement of its candidates that the reference makes feasible.
        ``max_speed`` must exceed the top speed.
    max_ball_jerk : float
        Largest jerk of the ball (m/s³) a limited reference may plan
        (:class:`~gracenav.primitives.limited.LimitedReferenceOptions`); the nonic's
        rest to rest over 0.5 m reaches 5.6 m/s³.
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
    reference: Literal["nonic", "limited"] = "nonic"
    cruise_speeds: tuple[float, ...] = ()
    max_ball_jerk: float = 6.0

    def __post_init__(self) -> None:
        speeds = tuple(float(v) for v in self.cruise_speeds)
        object.__setattr__(self, "cruise_speeds", speeds)
        ladder = (self.cruise_speed, *speeds)
        if any(not (math.isfinite(b) and b > a) for a, b in itertools.pairwise(ladder)):
            raise ConfigError(
                "PrimitiveSetOptions.cruise_speeds must be ascending and above cruise_speed "
                f"({self.cruise_speed} m/s), got {self.cruise_speeds}"
            )
        if speeds and not self.max_speed > speeds[-1]:
            raise ConfigError(
                f"PrimitiveSetOptions.max_speed {self.max_speed} m/s must exceed the top cruise "
                f"speed {speeds[-1]} m/s"
            )
        if self.reference not in ("nonic", "limited"):
            raise ConfigError(
                f"PrimitiveSetOptions.reference must be 'nonic' or 'limited', got "
                f"{self.reference!r}"
            )
        for name in (
            "cruise_speed",
            "rest_duration",
            "capture_duration",
            "max_lean",
            "max_speed",
            "max_backward_speed",
            "duration_step",
            "max_duration",
            "max_ball_jerk",
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
        """Plain-dict form (for cache keys and file headers); ``reference`` and
        ``max_ball_jerk`` only for limited references, ``cruise_speeds`` only when there
        are any, so that the keys of sets and palettes built before they existed stay
        what they were."""
        out = dataclasses.asdict(self)
        if out["reference"] == "nonic":  # the ball jerk bound is the limited references'
            del out["reference"], out["max_ball_jerk"]
        if not out["cruise_speeds"]:
            del out["cruise_speeds"]
        else:
            out["cruise_speeds"] = list(out["cruise_speeds"])
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> PrimitiveSetOptions:
        """Inverse of :meth:`to_dict`."""
        fields = dict(data)
        fields["planner"] = ShapePlannerOptions(**fields["planner"])
        if "cruise_speeds" in fields:
            fields["cruise_speeds"] = tuple(fields["cruise_speeds"])
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


def trim_names(level: int) -> tuple[str, str, str]:
    """Names of the cruise trims of speed level ``level`` (1: ``cruise_x``, ``cruise_y``,
    ``cruise_xy``; k > 1: ``cruisek_x``, ...)."""
    tag = "cruise" if level == 1 else f"cruise{level}"
    return f"{tag}_x", f"{tag}_y", f"{tag}_xy"


def speed_catalogue(level: int) -> tuple[tuple[str, str, tuple[tuple[int, int], ...]], ...]:
    """The maneuvers of cruise level ``level`` >= 2: (start trim, end trim, candidate
    displacements in units of d, smallest first); the primitive set keeps each at its
    first feasible candidate. Starts and stops along an axis and the diagonal; speed
    changes with the level below, up and down; 45° turns to and from the diagonal, left
    and right; 90° turns; lane changes. No U-turns: the tree slows down first."""
    x, y, xy = trim_names(level)
    bx, _, bxy = trim_names(level - 1)
    ax = tuple((i, 0) for i in range(1, 16))
    diag = tuple((i, i) for i in range(1, 12))
    ahead = tuple(c for i in range(2, 14) for c in ((i, i - 1), (i + 1, i - 1)))
    beside = tuple((j, i) for i, j in ahead)
    return (
        ("rest", x, ax),
        (x, "rest", ax),
        ("rest", xy, diag),
        (xy, "rest", diag),
        (bx, x, ax),
        (x, bx, ax),
        (bxy, xy, diag),
        (xy, bxy, diag),
        (x, xy, ahead),
        (y, xy, beside),
        (xy, x, ahead),
        (xy, y, beside),
        (x, y, diag),
        (y, x, diag),
        (x, x, tuple((i, 1) for i in range(3, 16))),
        (y, y, tuple((1, i) for i in range(3, 16))),
    )
