"""The limits a palette is built to, stated once: lean, speeds and the maneuvers' kind of
reference, from which the primitive set's and the verification's options follow; the
torque limit is the robot's (:attr:`gracenav.BallbotParams.torque_limit`)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

from gracenav.errors import ConfigError
from gracenav.policies import CatchOptions, VerificationOptions
from gracenav.primitives import PrimitiveSetOptions

if TYPE_CHECKING:
    from gracenav.palette.palette import Palette

__all__ = ["PaletteLimits", "catch_speeds_for"]

#: Speed (m/s) the catches reach above the top cruise speed: a push of the bench's
#: largest impulse (16 N s) adds up to about 0.35 m/s to a cruising robot, and a
#: catch serves states within 0.16 m/s of its own speed.
CATCH_HEADROOM = 0.3


def catch_speeds_for(cruise_speeds: tuple[float, ...]) -> tuple[float, ...]:
    """The catches' speeds (m/s) for a palette cruising at ``cruise_speeds``: the
    default ones (0 to 1.2 m/s in steps of 0.1), continued in steps of 0.1 m/s up to
    :data:`CATCH_HEADROOM` above the top cruise speed."""
    base = CatchOptions().speeds
    fastest = max(cruise_speeds, default=0.0)
    if not math.isfinite(fastest):
        raise ConfigError(f"cruise speeds must be finite (m/s), got {cruise_speeds}")
    steps = max(0, math.ceil(round((fastest + CATCH_HEADROOM - base[-1]) / 0.1, 6)))
    return (*base, *(round(base[-1] + 0.1 * k, 6) for k in range(1, steps + 1)))


@dataclass(frozen=True)
class PaletteLimits:
    """What a palette is built to (defaults: the shipped palette's).

    Attributes
    ----------
    max_lean : float
        Largest body tilt the maneuvers and the pushed catches plan (rad); 4.5°. The
        settled and still catches plan 6° and 7.5° (their own options), and every
        policy is verified within ``verified_lean`` (8°).
    cruise_speeds : tuple of float
        The cruise trims' speeds (m/s), ascending: the first level's and those above
        it (:attr:`PrimitiveSetOptions.cruise_speeds`).
    max_speed : float
        Largest speed of a maneuver's reference (m/s), above the top cruise speed.
    reference : {"nonic", "limited"}
        The maneuvers' references (:attr:`PrimitiveSetOptions.reference`): "limited"
        (the shortest within the lean, torque and ball jerk limits) or "nonic".
    max_ball_jerk : float
        Largest ball jerk a limited reference plans (m/s³), 3.
    shift_max_ball_jerk : float or None
        Largest ball jerk of the shifts' references (m/s³, 3;
        :attr:`CatchOptions.shift_max_ball_jerk`); None: the shortest feasible nonic.
    verified_lean : float
        Lean within which every run of a verification must stay (rad), 8°.
    catch_speeds : tuple of float
        Speeds (m/s) of the catches of pushed robots (the top one bounds the speed a
        push may leave the robot with and still be caught by a verified policy).
    """

    max_lean: float = math.radians(4.5)
    cruise_speeds: tuple[float, ...] = (0.5,)
    max_speed: float = 0.8
    reference: Literal["nonic", "limited"] = "limited"
    max_ball_jerk: float = 3.0
    shift_max_ball_jerk: float | None = 3.0
    verified_lean: float = math.radians(8.0)
    catch_speeds: tuple[float, ...] = CatchOptions().speeds

    def __post_init__(self) -> None:
        for name in ("max_lean", "verified_lean", "max_speed"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise ConfigError(f"PaletteLimits.{name} must be positive, got {v!r}")
        if not self.max_lean < self.verified_lean:
            raise ConfigError(
                f"PaletteLimits.max_lean {math.degrees(self.max_lean):g}° must be below "
                f"verified_lean {math.degrees(self.verified_lean):g}°"
            )
        speeds = tuple(float(v) for v in self.cruise_speeds)
        if not speeds:
            raise ConfigError("PaletteLimits.cruise_speeds needs at least one speed")
        object.__setattr__(self, "cruise_speeds", speeds)
        object.__setattr__(self, "catch_speeds", tuple(float(v) for v in self.catch_speeds))
        self.primitive_options()  # the speeds' checks
        self.verification_options()  # the catches' checks

    def primitive_options(self) -> PrimitiveSetOptions:
        """The primitive set's options these limits give (its other options default)."""
        return PrimitiveSetOptions(
            cruise_speed=self.cruise_speeds[0],
            cruise_speeds=self.cruise_speeds[1:],
            max_lean=self.max_lean,
            max_speed=self.max_speed,
            reference=self.reference,
            max_ball_jerk=self.max_ball_jerk,
        )

    def verification_options(self) -> VerificationOptions:
        """The verification options these limits give (the others default)."""
        base = VerificationOptions()
        catch = base.catch
        if catch is not None:
            catch = dataclasses.replace(
                catch,
                max_lean=self.max_lean,
                speeds=self.catch_speeds,
                shift_max_ball_jerk=self.shift_max_ball_jerk,
            )
        return dataclasses.replace(base, lean_limit=self.verified_lean, catch=catch)

    @classmethod
    def of(cls, palette: Palette) -> PaletteLimits:
        """The limits ``palette`` was built to, read from its options."""
        prim = palette.primitive_options
        catch = palette.options.catch
        return cls(
            max_lean=prim.max_lean,
            cruise_speeds=(prim.cruise_speed, *prim.cruise_speeds),
            max_speed=prim.max_speed,
            reference=prim.reference,
            max_ball_jerk=prim.max_ball_jerk,
            shift_max_ball_jerk=catch.shift_max_ball_jerk if catch is not None else None,
            verified_lean=palette.options.lean_limit,
            catch_speeds=catch.speeds if catch is not None else (),
        )

    def describe(self, torque_limit: float) -> str:
        """The limits in one line, degrees at the edge (``torque_limit``: the robot's,
        N m)."""
        speeds = ", ".join(f"{v:g}" for v in self.cruise_speeds)
        top = max(self.catch_speeds, default=0.0)
        jerk = f" and {self.max_ball_jerk:g} m/s³" if self.reference == "limited" else ""
        if self.shift_max_ball_jerk is not None:
            jerk += f"; shifts at most {self.shift_max_ball_jerk:g} m/s³"
        return (
            f"limits: lean {math.degrees(self.max_lean):g}° planned, "
            f"{math.degrees(self.verified_lean):g}° verified; torque {torque_limit:g} N m; "
            f"cruise {speeds} m/s; references {self.reference}, at most {self.max_speed:g} "
            f"m/s{jerk}; catches from up to {top:g} m/s"
        )
