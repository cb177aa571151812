"""Primitives as the policies store them: the sampled reference of a motion primitive
(states, feed-forward torques and ball references at every control tick), rebuilt from
coarse samples by quintic Hermite interpolation."""

from __future__ import annotations

import enum
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.control import CONTROL_RATE
from gracenav.errors import ConfigError
from gracenav.model.rotation import rotate_pairs, rotate_pairs_by
from gracenav.params import BallbotParams
from gracenav.sim import Reference

__all__ = ["PrimitiveKind", "SampledPrimitive"]

FloatArray = NDArray[np.float64]


class _Sample(Protocol):
    @property
    def states(self) -> FloatArray: ...
    @property
    def accelerations(self) -> FloatArray: ...
    @property
    def inputs(self) -> FloatArray: ...
    @property
    def position(self) -> FloatArray: ...


class PrimitiveLike(Protocol):
    """What :meth:`SampledPrimitive.from_primitive` needs of a motion primitive."""

    @property
    def name(self) -> str: ...
    @property
    def duration(self) -> float: ...
    @property
    def is_trim(self) -> bool: ...
    @property
    def displacement(self) -> FloatArray: ...
    @property
    def start_velocity(self) -> FloatArray: ...
    @property
    def end_velocity(self) -> FloatArray: ...
    def sample(self, timepts: ArrayLike) -> _Sample: ...


class PrimitiveKind(enum.Enum):
    """Trim primitives (rest or constant velocity) and maneuvers (paper Sec. III-A)."""

    REST = "rest"
    CRUISE = "cruise"
    MANEUVER = "maneuver"


@dataclass(frozen=True)
class SampledPrimitive:
    """A motion primitive sampled at the control ticks: what a policy executes.

    Attributes
    ----------
    name : str
    kind : PrimitiveKind
    duration : float
        t_f (s); a whole number of control periods.
    dt : float
        Control period (s).
    displacement : ndarray, shape (2,)
        Net (Δx, Δy) (m).
    start_velocity, end_velocity : ndarray, shape (2,)
        Reference ball velocity at t = 0 and t_f (m/s).
    states : ndarray, shape (T + 1, 8)
        Reference model states at the ticks, in the primitive's own frame.
    accelerations : ndarray, shape (T + 1, 4)
        Reference q̈ at the ticks (rad/s²).
    inputs : ndarray, shape (T + 1, 2)
        Feed-forward torques (N m), including the planned friction.
    position : ndarray, shape (T + 1, 6)
        Ball x, y, ẋ, ẏ, ẍ, ÿ (m, m/s, m/s²) at the ticks, starting at (0, 0).
    """

    name: str
    kind: PrimitiveKind
    duration: float
    dt: float
    displacement: FloatArray
    start_velocity: FloatArray
    end_velocity: FloatArray
    states: FloatArray
    accelerations: FloatArray
    inputs: FloatArray
    position: FloatArray

    def __post_init__(self) -> None:
        n = self.states.shape[0]
        if (
            self.states.shape != (n, 8)
            or self.accelerations.shape != (n, 4)
            or self.inputs.shape != (n, 2)
            or self.position.shape != (n, 6)
        ):
            raise ConfigError(f"primitive {self.name}: inconsistent sample shapes")
        if abs((n - 1) * self.dt - self.duration) > 1e-9:
            raise ConfigError(
                f"primitive {self.name}: duration {self.duration} s is not {n - 1} control periods"
            )

    @property
    def is_trim(self) -> bool:
        """Whether this is a trim primitive."""
        return self.kind is not PrimitiveKind.MANEUVER

    @property
    def num_ticks(self) -> int:
        """Number of control periods T."""
        return int(self.states.shape[0] - 1)

    @classmethod
    def from_primitive(
        cls, primitive: PrimitiveLike, *, control_rate: float = CONTROL_RATE
    ) -> SampledPrimitive:
        """Sample a :class:`gracenav.primitives.MotionPrimitive` at the control ticks.

        The primitive's duration must be a whole number of control periods.
        """
        p = primitive
        dt = 1.0 / control_rate
        duration = float(p.duration)
        n = round(duration / dt)
        if abs(n * dt - duration) > 1e-9:
            raise ConfigError(
                f"primitive {p.name} lasts {duration} s, not a whole number of control "
                f"periods of {dt} s"
            )
        s = p.sample(np.arange(n + 1, dtype=np.float64) * np.float64(dt))
        if p.is_trim:
            moving = bool(np.any(np.asarray(p.end_velocity) != 0.0))
            kind = PrimitiveKind.CRUISE if moving else PrimitiveKind.REST
        else:
            kind = PrimitiveKind.MANEUVER
        return cls(
            name=str(p.name),
            kind=kind,
            duration=n * dt,
            dt=dt,
            displacement=np.asarray(p.displacement, dtype=np.float64),
            start_velocity=np.asarray(p.start_velocity, dtype=np.float64),
            end_velocity=np.asarray(p.end_velocity, dtype=np.float64),
            states=np.ascontiguousarray(s.states, dtype=np.float64),
            accelerations=np.ascontiguousarray(s.accelerations, dtype=np.float64),
            inputs=np.ascontiguousarray(s.inputs, dtype=np.float64),
            position=np.ascontiguousarray(s.position, dtype=np.float64),
        )

    def rotated(self, k: int) -> SampledPrimitive:
        """The samples rotated by k·90° about the start (exact relabelling of the pairs).

        180° is an exact symmetry of the 3D model; 90° is not quite (I_xx ≠ I_yy and
        the lean's Euler order), so the rotated feed-forward torque is off by up to
        ≈0.2 N m. Verification therefore checks the 0° and the 90° placement.
        """
        if k % 4 == 0:
            return self
        return replace(
            self,
            displacement=rotate_pairs(self.displacement, k),
            start_velocity=rotate_pairs(self.start_velocity, k),
            end_velocity=rotate_pairs(self.end_velocity, k),
            states=rotate_pairs(self.states, k),
            accelerations=rotate_pairs(self.accelerations, k),
            inputs=rotate_pairs(self.inputs, k),
            position=rotate_pairs(self.position, k),
        )

    def rotated_by(self, angle: float) -> SampledPrimitive:
        """The samples rotated by ``angle`` (rad) about the start (:func:`rotate_pairs_by`;
        like :meth:`rotated`, not an exact symmetry of the 3D model, so policies placed
        at any heading are verified at several)."""
        return replace(
            self,
            displacement=rotate_pairs_by(self.displacement, angle),
            start_velocity=rotate_pairs_by(self.start_velocity, angle),
            end_velocity=rotate_pairs_by(self.end_velocity, angle),
            states=rotate_pairs_by(self.states, angle),
            accelerations=rotate_pairs_by(self.accelerations, angle),
            inputs=rotate_pairs_by(self.inputs, angle),
            position=rotate_pairs_by(self.position, angle),
        )

    def reference(self) -> Reference:
        """The reference for the closed loop, in the primitive's own frame."""
        return Reference(self.states, self.inputs, self.dt)

    def coarse(self, stride: int) -> tuple[FloatArray, FloatArray]:
        """States (M, 8) and accelerations (M, 4) at every ``stride``-th tick: enough to
        rebuild the primitive with :meth:`from_coarse` (the number of ticks must be a
        multiple of ``stride``)."""
        if self.num_ticks % stride:
            raise ConfigError(
                f"primitive {self.name}: {self.num_ticks} ticks not a multiple of {stride}"
            )
        return self.states[::stride].copy(), self.accelerations[::stride].copy()

    @classmethod
    def from_coarse(
        cls,
        states: FloatArray,
        accelerations: FloatArray,
        stride: int,
        *,
        name: str,
        kind: PrimitiveKind,
        dt: float,
        displacement: FloatArray,
        start_velocity: FloatArray,
        end_velocity: FloatArray,
        params: BallbotParams,
    ) -> SampledPrimitive:
        """Rebuild the samples at every tick from every ``stride``-th one.

        q, q̇ and q̈ between stored ticks come from the quintic Hermite interpolant
        (:mod:`gracenav._util.hermite`) of (q, q̇, q̈) at both ends (error ~h⁶ q⁽⁶⁾, below
        1e-10 rad for these smooth trajectories); the torques are recomputed from the 3D
        equations of motion so the rebuilt samples satisfy them. See :meth:`from_coarse_many`.
        """
        meta = {
            "name": name,
            "kind": kind,
            "dt": dt,
            "displacement": displacement,
            "start_velocity": start_velocity,
            "end_velocity": end_velocity,
        }
        (out,) = cls.from_coarse_many([(states, accelerations, stride, meta)], params)
        return out

    @classmethod
    def from_coarse_many(
        cls,
        items: Sequence[tuple[FloatArray, FloatArray, int, dict[str, Any]]],
        params: BallbotParams,
    ) -> list[SampledPrimitive]:
        """:meth:`from_coarse` for many primitives at once (one interpolation per
        stride and one evaluation of the equations of motion for all samples).

        ``items``: (states, accelerations, stride, meta) with ``meta`` holding the
        keyword arguments name, kind, dt, displacement, start_velocity, end_velocity.
        """
        from gracenav._kernels import rebuild_fine
        from gracenav._util.hermite import quintic_hermite_basis
        from gracenav.model.ballbot3d import Ballbot3D
        from gracenav.model.friction import friction_constants

        intervals = np.array([it[0].shape[0] - 1 for it in items], dtype=np.int64)
        strides = np.array([int(it[2]) for it in items], dtype=np.int64)
        rows = intervals * strides + 1
        ffirst = np.concatenate([[0], np.cumsum(rows)[:-1]]).astype(np.int64)
        total = int(rows.sum())
        st = np.empty((total, 8))
        acc = np.empty((total, 4))
        tau = np.empty((total, 2))
        pos = np.empty((total, 6))
        c = Ballbot3D(params).constants()
        fr = friction_constants(params)
        by_step: dict[tuple[int, float], list[int]] = {}
        for k, (_, _, stride, meta) in enumerate(items):
            by_step.setdefault((int(stride), float(meta["dt"])), []).append(k)
        for (stride, dt), ks in by_step.items():
            coarse = [np.asarray(items[k][0], dtype=np.float64) for k in ks]
            cfirst = np.concatenate([[0], np.cumsum([a.shape[0] for a in coarse])[:-1]])
            rebuild_fine(
                np.ascontiguousarray(np.concatenate(coarse)),
                np.ascontiguousarray(np.concatenate([items[k][1] for k in ks]), dtype=np.float64),
                cfirst.astype(np.int64),
                ffirst[ks],
                intervals[ks],
                np.ascontiguousarray(quintic_hermite_basis(np.arange(stride) / stride)),
                stride * dt,
                c,
                fr,
                float(params.ball_radius),
                st,
                acc,
                tau,
                pos,
            )
        out = []
        for k, (_, _, _, meta) in enumerate(items):
            sl = slice(int(ffirst[k]), int(ffirst[k] + rows[k]))
            out.append(
                cls(
                    duration=(int(rows[k]) - 1) * float(meta["dt"]),
                    states=st[sl],
                    accelerations=acc[sl],
                    inputs=tau[sl],
                    position=pos[sl],
                    **meta,
                )
            )
        return out

    def position_state(self, t: ArrayLike) -> FloatArray:
        """Reference position state (x, y, ẋ, ẏ) at times ``t`` (s), linear between ticks
        and clamped to [0, t_f]. Shape (..., 4)."""
        tt: FloatArray = np.clip(np.asarray(t, dtype=np.float64), 0.0, self.duration)
        k = tt / self.dt
        i = np.clip(np.floor(k).astype(np.int64), 0, max(self.num_ticks - 1, 0))
        w = np.clip(k - i, 0.0, 1.0)[..., None]
        a = self.position[i, :4]
        b = self.position[np.minimum(i + 1, self.num_ticks), :4]
        out: FloatArray = (1.0 - w) * a + w * b
        return out
