"""Physical parameters of the ballbot.

The defaults are the CMU ballbot's (Nagarajan, Kantor & Hollis, IJRR 2014,
Table I). All quantities are SI.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gracenav._util.io import atomic_write_text, load_document
from gracenav._util.validate import Fields, check_number, require_mapping

__all__ = ["BallbotParams"]

# Fields that must be strictly positive, and those that may also be zero.
_POSITIVE = (
    "ball_radius",
    "ball_mass",
    "ball_inertia",
    "body_mass",
    "body_com_height",
    "body_inertia_x",
    "body_inertia_y",
    "body_inertia_z",
    "gravity",
    "torque_limit",
    "friction_smoothing",
    "body_radius",
)
_NON_NEGATIVE = ("coulomb_friction", "viscous_friction")
_UNITS = {
    "ball_radius": "m",
    "ball_mass": "kg",
    "ball_inertia": "kg m^2",
    "body_mass": "kg",
    "body_com_height": "m",
    "body_inertia_x": "kg m^2",
    "body_inertia_y": "kg m^2",
    "body_inertia_z": "kg m^2",
    "coulomb_friction": "N m",
    "viscous_friction": "N m s/rad",
    "gravity": "m/s^2",
    "torque_limit": "N m",
    "friction_smoothing": "rad/s",
    "body_radius": "m",
}


def _limits(name: str) -> dict[str, Any]:
    """The limits of field ``name`` as keywords of :func:`gracenav._util.validate.check_number`."""
    return {
        "positive": name in _POSITIVE,
        "minimum": 0.0 if name in _NON_NEGATIVE else None,
        "unit": _UNITS[name],
    }


@dataclass(frozen=True)
class BallbotParams:
    """Physical parameters of a ballbot (a rigid cylinder on a rigid sphere).

    Parameters
    ----------
    ball_radius : float
        Ball radius r_w (m).
    ball_mass : float
        Ball mass m_w (kg).
    ball_inertia : float
        Ball moment of inertia I_w about any axis through its centre (kg m^2).
    body_mass : float
        Body mass m_b (kg).
    body_com_height : float
        Height ℓ_b of the body's centre of mass above the ball centre (m).
    body_inertia_x, body_inertia_y, body_inertia_z : float
        Body principal moments of inertia about its centre of mass, about the
        body's x (roll), y (pitch) and z (yaw) axes (kg m^2). Motion along the
        world y axis leans the body about x and uses ``body_inertia_x``; motion
        along x uses ``body_inertia_y``.
    coulomb_friction : float
        Coulomb friction torque D_c between ball and body (N m). 0 switches it off.
    viscous_friction : float
        Viscous friction coefficient D_v (N m s / rad). 0 switches it off.
    gravity : float
        Gravitational acceleration g (m/s^2).
    torque_limit : float
        Saturation of each generalised drive torque (N m). Not published for
        the CMU robot; 60 N m leaves room to cruise at 0.5 m/s (friction alone
        takes ≈21 N m there) plus feedback.
    friction_smoothing : float
        Ball relative speed ε (rad/s) of the smooth Coulomb friction model
        D_c·tanh(θ̇/ε), which replaces sgn(θ̇) to keep the dynamics non-stiff.
    body_radius : float
        Outer radius of the body (m), for drawing and collision checks.
    """

    ball_radius: float = 0.1058
    ball_mass: float = 2.44
    ball_inertia: float = 0.0174
    body_mass: float = 51.66
    body_com_height: float = 0.69
    body_inertia_x: float = 12.59
    body_inertia_y: float = 12.48
    body_inertia_z: float = 0.66
    coulomb_friction: float = 3.82
    viscous_friction: float = 3.68
    gravity: float = 9.81
    torque_limit: float = 60.0
    friction_smoothing: float = 0.05
    body_radius: float = 0.185

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = check_number(getattr(self, f.name), f.name, "BallbotParams", **_limits(f.name))
            object.__setattr__(self, f.name, value)

    # -- derived constants of the planar model (IJRR 2014, eqs. 1-5) -----------------
    def alpha(self) -> float:
        """α = I_w + (m_w + m_b) r_w² (kg m²)."""
        return self.ball_inertia + (self.ball_mass + self.body_mass) * self.ball_radius**2

    def beta(self) -> float:
        """β = m_b r_w ℓ_b (kg m²)."""
        return self.body_mass * self.ball_radius * self.body_com_height

    def gamma(self, body_inertia: float) -> float:
        """γ = I_b + m_b ℓ_b² for the given body inertia I_b (kg m²)."""
        return body_inertia + self.body_mass * self.body_com_height**2

    def without_friction(self) -> BallbotParams:
        """Return a copy with Coulomb and viscous friction switched off."""
        return dataclasses.replace(self, coulomb_friction=0.0, viscous_friction=0.0)

    def scaled(self, mass_scale: float = 1.0, inertia_scale: float = 1.0) -> BallbotParams:
        """Return a copy with body and ball masses and inertias scaled (model mismatch)."""
        return dataclasses.replace(
            self,
            ball_mass=self.ball_mass * mass_scale,
            body_mass=self.body_mass * mass_scale,
            ball_inertia=self.ball_inertia * inertia_scale,
            body_inertia_x=self.body_inertia_x * inertia_scale,
            body_inertia_y=self.body_inertia_y * inertia_scale,
            body_inertia_z=self.body_inertia_z * inertia_scale,
        )

    # -- serialisation -----------------------------------------------------------------
    def to_dict(self) -> dict[str, float]:
        """Return the parameters as a plain dict (field name -> SI value)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(
        cls,
        data: Mapping[str, Any],
        *,
        source: str = "parameters",
        base: BallbotParams | None = None,
    ) -> BallbotParams:
        """Build parameters from a mapping.

        Without ``base`` every field must be given; with ``base`` the mapping may set any
        subset of the fields (overrides; e.g. only ``body_mass``) and the others are
        ``base``'s. Unknown names are errors either way.

        Raises
        ------
        ConfigError
            On unknown keys, missing keys or non-physical values; the message
            names the field and ``source``.
        """
        names = [f.name for f in dataclasses.fields(cls)]
        fields = Fields(require_mapping(data, source, "parameter", [*names[:3], "..."]), "", source)
        fields.check_keys(names)
        if base is None:
            missing = [n for n in names if n not in fields.data]
            if missing:
                raise fields.fail(
                    f"missing parameter(s) {', '.join(missing)} (a partial file "
                    "overrides the defaults only where the defaults are given as a base)"
                )
        values = base.to_dict() if base is not None else {}
        values.update({n: fields.number(n, **_limits(n)) for n in names if n in fields.data})
        return cls(**values)

    @classmethod
    def load(cls, path: str | Path, *, base: BallbotParams | None = None) -> BallbotParams:
        """Load parameters from a YAML (``.yaml``/``.yml``) or JSON (``.json``) file.

        The file is read strictly (UTF-8, no duplicate keys). With ``base`` it may set
        only some fields, which override ``base`` (see :meth:`from_dict`).
        """
        path = Path(path)
        data = load_document(path, "parameter file")
        return cls.from_dict(data, source=str(path), base=base)

    @classmethod
    def load_overrides(cls, path: str | Path) -> BallbotParams:
        """The CMU ballbot's parameters with the fields set in ``path`` replaced.

        A file that sets only ``body_mass: 60.0`` is valid; unknown names are errors.
        """
        return cls.load(path, base=cls())

    def save(self, path: str | Path) -> None:
        """Write parameters atomically as YAML or JSON (chosen by the suffix)."""
        import yaml

        path = Path(path)
        if path.suffix == ".json":
            text = json.dumps(self.to_dict(), indent=2) + "\n"
        else:
            text = yaml.safe_dump(self.to_dict(), sort_keys=False)
        atomic_write_text(path, text)
