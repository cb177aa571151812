"""The friction between ball and body: D(θ̇) = D_c tanh(θ̇/ε) + D_v θ̇.

θ̇ is the ball's rate relative to the body (what the motor encoders read); the
smooth Coulomb term D_c tanh(θ̇/ε) replaces D_c sgn(θ̇) to keep the dynamics
non-stiff. The constants go as one array ``fr = [D_c, D_v, ε]``
(:func:`friction_constants`), the form the compiled kernels take.

:func:`friction_torque` is plain Python on numpy values: numpy arrays of θ̇ of any
shape, and, compiled by numba (``gracenav._kernels.friction``), the single floats of
the kernels. numba's on-disk cache notices a change of a kernel's own file only, so a
change here must be followed by clearing the cached kernels (``__pycache__/*.nbi``,
``*.nbc`` under ``gracenav``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from gracenav.params import BallbotParams

__all__ = ["friction_constants", "friction_torque"]

FloatArray = NDArray[np.float64]


def friction_constants(params: BallbotParams) -> FloatArray:
    """The friction constants ``fr = [D_c, D_v, ε]`` of ``params`` (N m, N m s/rad, rad/s)."""
    return np.array([params.coulomb_friction, params.viscous_friction, params.friction_smoothing])


def friction_torque(fr: FloatArray, thd: Any) -> Any:
    """Friction torque D_c tanh(θ̇/ε) + D_v θ̇ (N m) at the relative ball rates ``thd``
    (rad/s, an array of any shape or a float), with ``fr = [D_c, D_v, ε]``."""
    return fr[0] * np.tanh(thd / fr[2]) + fr[1] * thd
