"""Options of the policies' design: domain sizes, regulators, braking maneuvers, catches,
the push-lean table and verification."""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike

from gracenav.control import CONTROL_RATE, ControllerGains
from gracenav.errors import ConfigError
from gracenav.params import BallbotParams
from gracenav.policies.primitive import FloatArray
from gracenav.sim import Reference, position_state, simulate

__all__ = [
    "BrakingOptions",
    "CatchOptions",
    "DomainRadii",
    "PushLeanTable",
    "RegulatorOptions",
    "VerificationOptions",
    "push_lean_table",
]


@dataclass(frozen=True)
class DomainRadii:
    """Extents of a domain: largest position deviation (m) and velocity deviation (m/s)
    along an axis. Of two concentric domains of one shape (:func:`domain_shape`), the
    one with the larger extents contains the other."""

    position: float
    velocity: float

    def __post_init__(self) -> None:
        if not (self.position > 0 and self.velocity > 0):
            raise ConfigError(f"domain radii must be positive, got {self!r}")

    def scaled(self, factor: float) -> DomainRadii:
        """Both radii multiplied by ``factor``."""
        return DomainRadii(self.position * factor, self.velocity * factor)

    def contains(self, other: DomainRadii) -> bool:
        """Whether a concentric domain of radii ``other`` lies inside one of these radii."""
        return other.position <= self.position * (1 + 1e-12) and other.velocity <= self.velocity * (
            1 + 1e-12
        )


@dataclass(frozen=True)
class RegulatorOptions:
    """Capture regulators: policies that catch a moving robot and bring it to rest.

    A capture regulator holds a rest reference at its instantiation point p_c for
    ``duration`` (s). Its start domain S is centred on (p_c, 0) with its own shape
    (velocity extent ``velocity_per_position`` × position extent, correlation
    ``correlation`` < 0: the rest point lies ahead of a robot moving toward it), so one
    policy catches robots moving in any direction; its goal domain is the palette's G.
    Its outer domain D' does not shrink: uncorrelated, centred on the reference, with
    extents ``outer_position_factor`` e_p(S) and ``outer_velocity_factor`` e_v(S) (the
    error a push leaves does not decay geometrically while the lean settles). It is
    verified at each size of ``position_extents`` from ``boundary_points`` states on
    the surface of S, each started with the reference's lean and with the lean and
    lean rate a push leaves ``push_times`` after the impulse (:func:`push_lean_table`).

    Parameters
    ----------
    duration : float
        t_f (s).
    velocity_per_position : float
        e_v / e_p of S (1/s).
    correlation : float
        Position-velocity correlation r of S.
    position_extents : tuple of float
        Sizes e_p of S to verify (m), ascending; each that passes becomes a palette
        policy and instantiation places the largest whose swept D' fits.
    outer_position_factor, outer_velocity_factor : float
        D' extents over S extents.
    boundary_points : int
        Initial states on the surface of S per lean variant and placement.
    push_impulses : tuple of float
        Impulses (N s) of the push table, along one axis on the robot at rest.
    push_times : tuple of float
        Times after the impulse (s) whose lean and lean rate start verification runs.
    """

    duration: float = 4.0
    velocity_per_position: float = 0.8
    correlation: float = -0.8
    position_extents: tuple[float, ...] = (0.2, 0.35, 0.55, 0.75, 0.9)
    outer_position_factor: float = 1.1
    outer_velocity_factor: float = 3.0
    boundary_points: int = 128
    push_impulses: tuple[float, ...] = (4.0, 8.0, 12.0, 16.0, 20.0, 24.0, 28.0, 32.0, 40.0)
    push_times: tuple[float, ...] = (0.0, 0.1, 0.2, 0.3)

    def __post_init__(self) -> None:
        for name in ("position_extents", "push_impulses", "push_times"):
            object.__setattr__(self, name, tuple(float(v) for v in getattr(self, name)))
        ext = self.position_extents
        ascending = all(b > a for a, b in itertools.pairwise(ext))
        if not ext or any(not v > 0 for v in ext) or not ascending:
            raise ConfigError(f"regulator position_extents must ascend and be > 0, got {ext}")
        if not (self.duration > 0 and self.velocity_per_position > 0):
            raise ConfigError("regulator duration and velocity_per_position must be positive")
        if not -1.0 < self.correlation < 1.0:
            raise ConfigError(f"regulator correlation must lie in (-1, 1), got {self.correlation}")
        if self.outer_position_factor < 1 or self.outer_velocity_factor < 1:
            raise ConfigError("regulator outer factors must be >= 1")
        if self.boundary_points < 8:
            raise ConfigError("regulator boundary_points must be >= 8 (the axis extremes)")
        if any(t < 0 for t in self.push_times) or any(v <= 0 for v in self.push_impulses):
            raise ConfigError("regulator push_times must be >= 0 and push_impulses > 0")

    def start_radii(self, position_extent: float) -> DomainRadii:
        """Extents of S of the regulator of size ``position_extent`` (m)."""
        return DomainRadii(position_extent, position_extent * self.velocity_per_position)

    @classmethod
    def from_dict(cls, data: dict[str, object]) -> RegulatorOptions:
        """Inverse of :func:`dataclasses.asdict` (lists become tuples)."""
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in data.items()})  # type: ignore[arg-type]


@dataclass(frozen=True)
class BrakingOptions:
    """The palette's braking maneuvers (see :mod:`gracenav.policies.braking`).

    Parameters
    ----------
    speeds : tuple of float
        Nominal initial speeds (m/s), ascending.
    directions : tuple of (int, int)
        Lattice directions (i, j) of the first quadrant; instantiation adds the other
        three by rotation.
    lattice_divisions : int
        The stopping distance is a whole multiple of d / lattice_divisions along the
        direction's lattice vector (so the rest point is an instantiation point once
        the lattice is refined that far).
    max_lean : float
        Largest planned body tilt (rad).
    min_duration, max_duration : float
        Bounds of the deceleration time T (s).
    tail : float
        Rest held after the deceleration (s).
    scales : tuple of float
        Start domain sizes S/G, ascending; the palette keeps the largest that verifies.
    outer_position_factor, outer_position_floor : float
        D' position extent: max(factor e_p(S), floor) (m).
    outer_velocity_factor, outer_velocity_floor : float
        D' velocity extent: max(factor e_v(S), floor) (m/s). The error a push leaves
        is mostly in velocity (a lean that settles); the velocity extent costs nothing
        near obstacles, the position extent does.
    boundary_points : int
        Initial states on the surface of S per lean variant and placement.
    """

    speeds: tuple[float, ...] = (0.2, 0.35, 0.5, 0.65, 0.8)
    directions: tuple[tuple[int, int], ...] = ((1, 0), (2, 1), (1, 1), (1, 2))
    lattice_divisions: int = 2
    max_lean: float = math.radians(4.5)
    min_duration: float = 1.0
    max_duration: float = 6.0
    tail: float = 1.0
    scales: tuple[float, ...] = (2.0, 3.0)
    outer_position_factor: float = 1.1
    outer_position_floor: float = 0.32
    outer_velocity_factor: float = 3.0
    outer_velocity_floor: float = 1.2
    boundary_points: int = 64

    def __post_init__(self) -> None:
        object.__setattr__(self, "speeds", tuple(float(v) for v in self.speeds))
        object.__setattr__(self, "scales", tuple(float(v) for v in self.scales))
        object.__setattr__(self, "directions", tuple((int(i), int(j)) for i, j in self.directions))
        if not self.speeds or any(not v > 0 for v in self.speeds):
            raise ConfigError(f"braking speeds must be positive, got {self.speeds}")
        if any(i < 0 or j < 0 or i == j == 0 for i, j in self.directions):
            raise ConfigError(
                f"braking directions must be non-zero first-quadrant lattice vectors, got "
                f"{self.directions}"
            )
        if not self.scales or any(s < 1 for s in self.scales):
            raise ConfigError(f"braking scales must be >= 1 (S ⊇ G), got {self.scales}")
        if self.lattice_divisions < 1:
            raise ConfigError("braking lattice_divisions must be >= 1")
        if not (0 < self.min_duration <= self.max_duration and self.tail > 0):
            raise ConfigError("braking durations must be positive, min <= max")
        if self.outer_position_factor < 1 or self.outer_velocity_factor < 1:
            raise ConfigError("braking outer factors must be >= 1")
        if self.boundary_points < 8:
            raise ConfigError("braking boundary_points must be >= 8 (the axis extremes)")

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> BrakingOptions:
        """Inverse of :func:`dataclasses.asdict` (lists become tuples)."""
        out = dict(data)
        out["speeds"] = tuple(out["speeds"])
        out["scales"] = tuple(out["scales"])
        out["directions"] = tuple(tuple(d) for d in out["directions"])
        return cls(**out)


@dataclass(frozen=True)
class CatchOptions:
    """The palette's catches and shifts: capture at the robot's own state (see
    :mod:`gracenav.policies.catches`).

    Parameters
    ----------
    speeds : tuple of float
        Speeds (m/s) of the catches of both lean classes, ascending; 0 is a rest hold.
    settled_speeds : tuple of float
        Further speeds (m/s) with a settled catch only: the settled class acts near
        walls, where a catch planned for a speed closer to the state's stops shorter.
    max_lean : float
        Largest planned body tilt of a catch or shift (rad).
    min_duration, max_duration : float
        Bounds of a catch's deceleration time (s).
    ramps : tuple of float
        Rise times (s) of the smooth trapezoidal decelerations
        (:class:`~gracenav.primitives.shape_planner.BrakeReference`) planned for each catch
        besides the nonic smooth step and the shortest-reach braking
        (:class:`~gracenav.primitives.shape_planner.ShortestBrakeReference`, one per torque
        share); the candidates are verified in the order of how far ahead their path
        reaches, and the first that verifies is kept.
    pushed_torque_shares, settled_torque_shares : tuple of float
        Largest planned torques of a class's shortest-reach and trapezoidal catches, as
        shares of the torque limit (one candidate per share, and per ramp and share):
        the rest is left to the feedback (a short ramp otherwise saturates the motor
        once a push's lean is corrected).
    max_candidates : int
        Candidates verified per size, shortest reach first.
    tail : float
        Rest held after a catch's deceleration and after a shift (s).
    scales : tuple of float
        Sizes S/G of a pushed catch's start domain, tried from the largest; the first
        that verifies is kept.
    settled_scales : tuple of float
        The same for a settled catch.
    headings : int
        Placements verified, evenly spaced over [0°, 180°) (180° is an exact symmetry).
    boundary_points : int
        Initial states on the surface of S per lean variant and placement.
    grid_divisions : int
        Catches end on the grid of spacing d / grid_divisions, anchored where the
        library's lattice is; shifts move between that grid and the lattice.
    pushed_outer : tuple of float
        D' extents of a catch verified with the lean a push leaves: position along and
        across the motion (m), velocity (m/s); the hybrid controller uses such a catch
        whatever the measured lean. Its S holds the flat output's position state
        (:attr:`MotionPolicy.flat_start`), so a push's lean variants start with the
        flat output, not the ball, on S's boundary.
    settled_outer : tuple of float
        The same for a catch verified with the lean within ``settled_lean`` of the plan's.
    settled_max_lean : float
        Largest planned body tilt of a settled catch (rad): shorter stops, as the lean
        left for feedback is not taken by a push.
    settled_lean : tuple of float
        Largest lean (rad) and lean rate (rad/s) deviation from the plan's of a settled
        catch (verified at the corners of that band, along the motion).
    shift_radius : float
        Largest shift (m): at least the distance from a grid point to the nearest
        point of the unhalved lattice (d/√2 = 0.354 m at d = 0.5 m), since rest
        trims on the other sub-lattices of a halved lattice cannot reach every goal.
    shift_scale : float
        S/G of a shift (S ⊇ G, so a shift placed at a catch's end contains its G).
    shift_outer : tuple of float
        Least D' position (m) and velocity (m/s) extents of a shift (round), verified
        from the plan lean and the settled band; D' is also at least 1.1 and 3 times S's
        (0.11 m at ``shift_scale`` 1.25).
    shift_max_ball_jerk : float or None
        Largest ball jerk (m/s³) of a shift's reference on the linearised model (the
        ball moves against the lean: x⃛ = y⃛ − (L/κ) y⁽⁵⁾): the shift lasts at least
        as long as its nonic needs to stay within it: 12 m/s³ by default (the
        maneuvers' largest ball jerk on the random pairs of ``bench/bench_speed.py
        --breakdown`` reaches 11.9 m/s³) makes a 3 cm shift last 1.36 s. None (every
        palette built before the option): no bound, the shortest feasible nonic, whose
        ball jerk reaches 55 m/s³ for a 3 cm shift in its least 1 s.
    still_speeds : tuple of float
        Speeds (m/s) of the catches of the *still* class: verified from a small S
        (``still_scale``) with the lean within ``still_lean`` of the plan's, so that
        their D' (``still_outer``) is about half the settled one. They serve states
        whose lean is the plan's (starts, and the position states coverage counts),
        near walls.
    still_max_lean : float
        Largest planned body tilt of a still catch (rad): the tight band leaves the
        feedback little to correct.
    still_torque_shares : tuple of float
        Largest planned torques of the still class's shortest-reach and trapezoidal
        catches, as shares of the torque limit: a larger share than the settled
        class's leans the body back sooner, so the path reaches less far ahead.
    still_scale : float
        S and G of a still catch, as a share of the palette's G (in (0, 1]).
    still_outer : tuple of float
        D' position (m) and velocity (m/s) extents of a still catch (round); also at
        least 1.1 and 3 times S's. From the tight band the tracking error never grows
        beyond where it starts on S's boundary, so D' is S's floor (1.1 × 0.04 m).
    still_lean : tuple of float
        Largest lean (rad) and lean rate (rad/s) deviation from the plan's of a still
        catch or shift (verified at the corners of that band).
    still_shift_scale : float
        S/G of a still shift, at least ``still_scale`` (its S ⊇ a still catch's G); the
        same shifts, verified from that S and the still band, with D' ``still_shift_outer``.
    still_shift_outer : tuple of float
        Least D' position (m) and velocity (m/s) extents of a still shift (round):
        also just above S's floor (1.1 × 0.048 m), for the same reason.
    """

    speeds: tuple[float, ...] = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2)
    settled_speeds: tuple[float, ...] = (0.05, 0.15, 0.25, 0.35, 0.45, 0.55, 0.65, 0.75)
    max_lean: float = math.radians(4.5)
    min_duration: float = 0.5
    max_duration: float = 6.0
    ramps: tuple[float, ...] = (0.2, 0.3, 0.45, 0.6, 0.8, 1.0)
    pushed_torque_shares: tuple[float, ...] = (0.75, 0.65)
    settled_torque_shares: tuple[float, ...] = (0.8,)
    max_candidates: int = 4
    tail: float = 1.0
    scales: tuple[float, ...] = (1.5, 1.0)
    settled_scales: tuple[float, ...] = (1.0,)
    headings: int = 6
    boundary_points: int = 48
    grid_divisions: int = 16
    pushed_outer: tuple[float, float, float] = (0.24, 0.14, 1.0)
    settled_outer: tuple[float, float, float] = (0.10, 0.10, 0.5)
    settled_max_lean: float = math.radians(6.0)
    settled_lean: tuple[float, float] = (math.radians(0.5), math.radians(3.0))
    shift_radius: float = 0.375
    shift_scale: float = 1.25
    shift_outer: tuple[float, float] = (0.10, 0.5)
    shift_max_ball_jerk: float | None = 12.0
    #: Options added after palettes were first written, each with the value that
    #: reproduces those palettes: a stored file without one reads as that value, and
    #: that value is left out of the palette key, so the keys of those files hold.
    ADDED_LATER: ClassVar[dict[str, Any]] = {"shift_max_ball_jerk": None}
    still_speeds: tuple[float, ...] = (
        0.0, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5, 0.55, 0.6,
    )  # fmt: skip
    still_max_lean: float = math.radians(7.5)
    still_torque_shares: tuple[float, ...] = (0.9, 0.8)
    still_scale: float = 0.5
    still_outer: tuple[float, float] = (0.044, 0.5)
    still_lean: tuple[float, float] = (math.radians(0.1), math.radians(0.5))
    still_shift_scale: float = 0.6
    still_shift_outer: tuple[float, float] = (0.053, 0.5)

    def __post_init__(self) -> None:
        for name in (
            "speeds",
            "settled_speeds",
            "ramps",
            "pushed_torque_shares",
            "settled_torque_shares",
            "scales",
            "settled_scales",
            "pushed_outer",
            "settled_outer",
            "settled_lean",
            "shift_outer",
            "still_speeds",
            "still_torque_shares",
            "still_outer",
            "still_lean",
            "still_shift_outer",
        ):
            object.__setattr__(self, name, tuple(float(v) for v in getattr(self, name)))
        if not self.speeds or any(v < 0 for v in self.speeds):
            raise ConfigError(f"catch speeds must be >= 0, got {self.speeds}")
        if any(r <= 0 for r in self.ramps):
            raise ConfigError(f"catch ramps must be > 0 s, got {self.ramps}")
        for lean in (self.max_lean, self.settled_max_lean, self.still_max_lean):
            if not 0 < lean < math.pi / 2:
                raise ConfigError(f"catch plan leans must be in (0, π/2) rad, got {lean}")
        for shares in (
            self.pushed_torque_shares,
            self.settled_torque_shares,
            self.still_torque_shares,
        ):
            if not all(0 < f <= 1 for f in shares):
                raise ConfigError(f"catch torque shares must be in (0, 1], got {shares}")
        if any(v <= 0 for v in self.settled_speeds):
            raise ConfigError(f"catch settled_speeds must be > 0, got {self.settled_speeds}")
        if self.max_candidates < 1:
            raise ConfigError(f"catch max_candidates must be >= 1, got {self.max_candidates}")
        for scales in (self.scales, self.settled_scales):
            if not scales or any(s < 1 for s in scales):
                raise ConfigError(f"catch scales must be >= 1 (S ⊇ G), got {scales}")
        if self.headings < 1 or self.grid_divisions < 1 or self.boundary_points < 1:
            raise ConfigError("catch headings, grid_divisions and boundary_points must be >= 1")
        for outer in (self.pushed_outer, self.settled_outer):
            if len(outer) != 3 or not 0 < outer[1] <= outer[0] or not outer[2] > 0:
                raise ConfigError(
                    f"catch outer extents must be (along, across <= along, velocity) > 0, "
                    f"got {outer}"
                )
        if not self.shift_scale >= 1:
            raise ConfigError(f"shift_scale must be >= 1 (S ⊇ G), got {self.shift_scale}")
        if self.shift_max_ball_jerk is not None and not self.shift_max_ball_jerk > 0:
            raise ConfigError(
                f"shift_max_ball_jerk must be > 0 m/s³ or None, got {self.shift_max_ball_jerk}"
            )
        if any(v < 0 for v in self.still_speeds):
            raise ConfigError(f"catch still_speeds must be >= 0, got {self.still_speeds}")
        if not 0 < self.still_scale <= 1 or not self.still_shift_scale >= self.still_scale:
            raise ConfigError(
                "catch still_scale must be in (0, 1] and still_shift_scale at least it "
                f"(a still shift's S ⊇ a still catch's G), got {self.still_scale} and "
                f"{self.still_shift_scale}"
            )
        for pair in (self.still_outer, self.still_lean, self.still_shift_outer):
            if len(pair) != 2 or not all(v > 0 for v in pair):
                raise ConfigError(
                    f"catch still extents and band must be two values > 0, got {pair}"
                )

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> CatchOptions:
        """Inverse of :func:`dataclasses.asdict` (lists become tuples); an option of
        :attr:`ADDED_LATER` that ``data`` lacks takes its value from there."""
        data = {**cls.ADDED_LATER, **data}
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in data.items()})  # type: ignore[arg-type]


@dataclass(frozen=True)
class PushLeanTable:
    """Lean and lean rate a push leaves, tabulated by the ball speed it causes.

    The robot at rest, regulated to its position, is pushed along +x; ``speed``,
    ``lean`` and ``lean_rate`` are sampled ``times`` after the impulse, one row per
    impulse. Along the push direction: lean φ (rad, positive leaning forward),
    lean rate (rad/s).

    Attributes
    ----------
    times : ndarray, shape (K,)
    speed, lean, lean_rate : ndarray, shape (J, K)
    """

    times: FloatArray
    speed: FloatArray
    lean: FloatArray
    lean_rate: FloatArray

    def lean_at(
        self, k: int, speed: ArrayLike, *, flat_length: float | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Lean (rad) and lean rate (rad/s) along the motion ``times[k]`` after a push,
        for ball speeds ``speed`` (m/s): linear in speed through (0, 0, 0), held beyond
        the fastest entry. With ``flat_length`` L (m), ``speed`` is that of the flat
        output instead, the ball's plus L times the lean rate."""
        v = np.asarray(speed, dtype=float)
        table = self.speed[:, k]
        if flat_length is not None:
            table = table + flat_length * self.lean_rate[:, k]
        order = np.argsort(table)
        sv = np.concatenate([[0.0], table[order]])
        lean = np.concatenate([[0.0], self.lean[order, k]])
        rate = np.concatenate([[0.0], self.lean_rate[order, k]])
        return np.interp(v, sv, lean), np.interp(v, sv, rate)


def push_lean_table(
    gains: ControllerGains,
    impulses: Sequence[float],
    times: Sequence[float],
    *,
    params: BallbotParams | None = None,
) -> PushLeanTable:
    """Push the regulated robot at rest along +x with each impulse (N s) and sample its
    speed, lean and lean rate ``times`` (s) after the push (see :class:`PushLeanTable`).
    """
    from gracenav.sim import Push

    plant = params if params is not None else gains.params
    r = gains.params.ball_radius
    dt = 1.0 / CONTROL_RATE
    t = np.asarray(times, dtype=float)
    ticks = np.round(t / dt).astype(int)
    ref = Reference.hold((0.0, 0.0), float(t.max(initial=0.0)) + 0.25, params=gains.params)
    rows = []
    for imp in impulses:
        res = simulate(np.zeros(8), ref, gains, params=plant, disturbances=[Push(0.0, (imp, 0.0))])
        ps = position_state(res.states, r)
        rows.append((ps[ticks, 2], res.states[ticks, 2], res.states[ticks, 6]))
    speed, lean, rate = (np.array([row[i] for row in rows]) for i in range(3))
    return PushLeanTable(t, speed, lean, rate)


@dataclass(frozen=True)
class VerificationOptions:
    """Options of policy verification and sizing.

    Parameters
    ----------
    boundary_points : int
        Initial states on the surface of S (>= 64 recommended; the first 8 are the axis
        extremes).
    goal_position_extent : float
        Position extent e_p of the goal domain G shared by every policy (m); its
        velocity extent follows from :func:`domain_shape`.
    outer_position_factor, outer_velocity_factor : float
        D'(t) extents over D(t) extents.
    lean_limit : float
        The balancing controller's domain: largest |φ_x|, |φ_y| allowed (rad).
    max_scale : float
        Upper end of the bisection on the start domain's size S/G.
    bisection_steps : int
        Bisection iterations on S's size.
    shape_horizon : float
        Time (s) over which :func:`domain_shape` maximises the contraction: the
        shortest trim.
    scale_ladder : tuple of float
        Larger start domain sizes S/G, ascending, each > ``max_scale``, at which a
        policy is verified again after its bisection (:func:`scaled_variants`).
        Instantiation places the largest verified size whose swept D' fits the map:
        large domains in open space, the bisected size near walls.
    fine_scales : tuple of float
        Factors λ in (0, 1), descending, of the *fine* copies of every lattice policy
        sized by bisection: S, G and D'(t) all λ times the policy's, the same reference
        and control law, verified again at both placements (:func:`fine_variants`). A
        copy's swept D' is λ times as wide, so it fits passages and nears walls the
        policy itself does not; since its S is λ times 2 G, a policy of one level
        prepares one of the next level down (G ⊂ λ · 2 G for λ >= 1/2) and every level
        prepares the unscaled policies (λ G ⊂ S). Instantiation places them only where
        the unscaled policy may not fit.
    regulator : RegulatorOptions or None
        The palette's capture regulators (None: none).
    braking : BrakingOptions or None
        The palette's braking maneuvers (None, the default: none; see
        :mod:`gracenav.policies.braking` for what they add and what they cost).
    catch : CatchOptions or None
        The palette's catches and shifts, placed at the robot's own state
        (:mod:`gracenav.policies.catches`); None: none.
    """

    boundary_points: int = 64
    goal_position_extent: float = 0.08
    outer_position_factor: float = 1.6
    outer_velocity_factor: float = 3.2
    lean_limit: float = float(np.deg2rad(8.0))
    max_scale: float = 2.0
    bisection_steps: int = 6
    shape_horizon: float = 1.0
    scale_ladder: tuple[float, ...] = (3.0, 4.0, 6.0, 8.0)
    fine_scales: tuple[float, ...] = (0.5, 0.25)
    regulator: RegulatorOptions | None = field(default_factory=RegulatorOptions)
    braking: BrakingOptions | None = None
    catch: CatchOptions | None = field(default_factory=CatchOptions)

    def __post_init__(self) -> None:
        if isinstance(self.regulator, dict):
            object.__setattr__(self, "regulator", RegulatorOptions.from_dict(self.regulator))
        if isinstance(self.braking, dict):
            object.__setattr__(self, "braking", BrakingOptions.from_dict(self.braking))
        if isinstance(self.catch, dict):
            object.__setattr__(self, "catch", CatchOptions.from_dict(self.catch))
        ladder = tuple(float(v) for v in self.scale_ladder)
        object.__setattr__(self, "scale_ladder", ladder)
        if any(not b > a for a, b in zip((self.max_scale, *ladder), ladder, strict=False)):
            raise ConfigError(
                f"scale_ladder must ascend from above max_scale {self.max_scale:g}, got {ladder}"
            )
        fine = tuple(float(v) for v in self.fine_scales)
        object.__setattr__(self, "fine_scales", fine)
        if any(not 0 < v < 1 for v in fine) or any(not b < a for a, b in itertools.pairwise(fine)):
            raise ConfigError(f"fine_scales must descend within (0, 1), got {fine}")
        if self.boundary_points < 8:
            raise ConfigError("boundary_points must be >= 8 (the axis extremes)")
        if self.outer_position_factor < 1 or self.outer_velocity_factor < 1:
            raise ConfigError("outer domain factors must be >= 1 (D(t) ⊂ D'(t))")
        if not self.lean_limit > 0:
            raise ConfigError("lean_limit must be positive")
        if not self.goal_position_extent > 0:
            raise ConfigError("goal_position_extent must be positive")
        if not self.max_scale >= 1:
            raise ConfigError("max_scale must be >= 1 (S ⊇ G)")
