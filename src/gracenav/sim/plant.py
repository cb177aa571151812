"""Plants: what a per-tick controller drives, simulated or real.

A :class:`Plant` holds the robot's state x = [θ_x, θ_y, φ_x, φ_y, θ̇_x, θ̇_y, φ̇_x, φ̇_y]
(the :class:`gracenav.model.Ballbot3D` convention), says what the controller
measures of it, and advances by one control period with a torque held (zero-order
hold). Two are shipped: :class:`Model3DPlant`, the compiled 3D model the palette is
verified on, and :class:`MujocoPlant`, the MuJoCo ballbot. A robot of a user's own
(another simulator, or hardware behind a bridge) is any object with the same four
members. Plants that also take the simulated disturbances
(:class:`gracenav.sim.Push`, ``BodyForce``, ``StateJump``, ``Drag``) implement
:class:`DisturbablePlant`.
"""

from __future__ import annotations

from typing import Literal, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.errors import ConfigError
from gracenav.params import BallbotParams

__all__ = [
    "DisturbablePlant",
    "Model3DPlant",
    "MujocoPlant",
    "Plant",
    "PlantKind",
    "make_plant",
]

FloatArray = NDArray[np.float64]

#: The kinds of simulated plant gracenav ships (scenario ``simulation.plant``).
PlantKind = Literal["model3d", "mujoco"]
PLANT_KINDS: tuple[PlantKind, ...] = ("model3d", "mujoco")


@runtime_checkable
class Plant(Protocol):
    """A robot a per-tick controller drives.

    Attributes
    ----------
    ball_radius : float
        The plant's true ball radius (m): its position states are r (θ + φ).
    """

    ball_radius: float

    def reset(self, x0: ArrayLike) -> None:
        """Put the robot in state ``x0`` (8,)."""
        ...

    def state(self) -> FloatArray:
        """The true state (8,) (what the episode records)."""
        ...

    def measure(self) -> FloatArray:
        """What the controller is given (8,): the state as its sensors see it."""
        ...

    def advance(self, torque: FloatArray, dt: float) -> None:
        """Hold the generalised torques ``torque`` (2,) (N m, on θ_x and θ_y) for
        ``dt`` (s)."""
        ...


@runtime_checkable
class DisturbablePlant(Plant, Protocol):
    """A plant that also takes the simulated disturbances."""

    def push(self, impulse: FloatArray) -> None:
        """A world impulse (N s) (2,) on the body centre of mass, now."""
        ...

    def jump(self, delta: FloatArray) -> None:
        """Add ``delta`` (8,) to the state, now."""
        ...

    def set_force(self, force: FloatArray, drag: FloatArray, damping: float) -> None:
        """Over the next periods, until set again: a world force ``force`` (2,) (N) on
        the body centre of mass, and while ``drag[0] > 0`` a horizontal damper
        (``damping``, N s/m) pulling the body toward the velocity ``drag[1:3]`` (m/s)."""
        ...


def _check(x: ArrayLike) -> FloatArray:
    s = np.array(x, dtype=float)
    if s.shape != (8,):
        raise ConfigError(f"a plant state has shape (8,), got {s.shape}")
    if not np.all(np.isfinite(s)):
        raise ConfigError("a plant state must be finite")
    return s


class _Sensor:
    """White noise on the measured ball position (m) and velocity (m/s), put on the
    ball angles and rates (θ, θ̇) so the position state the controller computes
    carries it; drawn per tick from one seeded generator."""

    def __init__(self, radius: float, position_std: float, velocity_std: float, seed: int):
        self.radius = radius
        self.std = np.array([position_std] * 2 + [velocity_std] * 2)
        self.on = bool(np.any(self.std > 0.0))
        self.rng = np.random.default_rng(seed)

    def measure(self, x: FloatArray) -> FloatArray:
        if not self.on:
            return x.copy()
        n = self.rng.standard_normal(4) * self.std / self.radius
        y = x.copy()
        y[0:2] += n[0:2]
        y[4:6] += n[2:4]
        return y


class _SimulatedPlant:
    """What the shipped plants share: parameters and substeps checked, the sensor, and
    the forces and drag held over the next periods (:class:`DisturbablePlant`)."""

    def __init__(
        self,
        params: BallbotParams | None,
        substeps: int,
        position_noise_std: float,
        velocity_noise_std: float,
        seed: int,
    ) -> None:
        self.params = params if params is not None else BallbotParams()
        if not (isinstance(substeps, int) and substeps >= 1):
            raise ConfigError(f"substeps must be a positive integer, got {substeps!r}")
        self.substeps = substeps
        self.ball_radius = float(self.params.ball_radius)
        self._limit = float(self.params.torque_limit)
        self._sensor = _Sensor(self.ball_radius, position_noise_std, velocity_noise_std, seed)
        self._force = np.zeros(3)
        self._drag = np.zeros(3)
        self._damping = 0.0

    def state(self) -> FloatArray:  # pragma: no cover - each plant has its own
        raise NotImplementedError

    def measure(self) -> FloatArray:
        return self._sensor.measure(self.state())

    def _clear_forces(self) -> None:
        self._force[:] = 0.0
        self._drag[:] = 0.0

    def set_force(self, force: FloatArray, drag: FloatArray, damping: float) -> None:
        self._force[:2] = force
        self._drag[:] = drag
        self._damping = float(damping)


class Model3DPlant(_SimulatedPlant):
    """The compiled 3D model (:class:`gracenav.model.Ballbot3D`) as a plant: fixed-step
    RK4, saturation at its own torque limit, the simulated disturbances, and optional
    white noise on the measured ball position and velocity.

    Parameters
    ----------
    params : BallbotParams, optional
        The plant's physical parameters (default: CMU ballbot).
    substeps : int
        RK4 steps per control period.
    position_noise_std, velocity_noise_std : float
        Measurement noise (m, m/s).
    seed : int
        Seed of the noise.
    """

    def __init__(
        self,
        params: BallbotParams | None = None,
        *,
        substeps: int = 1,
        position_noise_std: float = 0.0,
        velocity_noise_std: float = 0.0,
        seed: int = 0,
    ) -> None:
        from gracenav import _kernels
        from gracenav.model.ballbot3d import Ballbot3D
        from gracenav.model.friction import friction_constants

        super().__init__(params, substeps, position_noise_std, velocity_noise_std, seed)
        self._c = Ballbot3D(self.params).constants()
        self._fr = friction_constants(self.params)
        self._x = np.zeros(8)

        self._advance = _kernels.plant_advance
        self._kick = _kernels.plant_kick

    def reset(self, x0: ArrayLike) -> None:
        self._x = _check(x0)
        self._clear_forces()

    def state(self) -> FloatArray:
        return self._x.copy()

    def measure(self) -> FloatArray:
        return self._sensor.measure(self._x)  # (the sensor copies: no copy of the state)

    def advance(self, torque: FloatArray, dt: float) -> None:
        self._advance(
            self._c,
            self._fr,
            self._x,
            np.asarray(torque, dtype=float),
            self._limit,
            self._force,
            self._drag,
            self._damping,
            dt,
            self.substeps,
        )

    def push(self, impulse: FloatArray) -> None:
        i = np.zeros(3)
        i[:2] = impulse
        if np.any(i != 0.0):
            self._kick(self._c, self._x, i)

    def jump(self, delta: FloatArray) -> None:
        self._x += np.asarray(delta, dtype=float)


class MujocoPlant(_SimulatedPlant):
    """The MuJoCo ballbot (:class:`gracenav.sim.mujoco.MujocoBallbot`, yaw locked)
    as a plant, with the same disturbances and measurement noise as
    :class:`Model3DPlant`; a push is a force of impulse/dt over the next period.

    Parameters
    ----------
    params : BallbotParams, optional
    substeps : int
        MuJoCo RK4 steps per control period.
    position_noise_std, velocity_noise_std : float
    seed : int
    dt : float
        Control period (s): MuJoCo's step is dt / substeps.
    """

    def __init__(
        self,
        params: BallbotParams | None = None,
        *,
        substeps: int = 1,
        position_noise_std: float = 0.0,
        velocity_noise_std: float = 0.0,
        seed: int = 0,
        dt: float | None = None,
    ) -> None:
        from gracenav.model.ballbot3d import Ballbot3D
        from gracenav.sim.mujoco import MujocoBallbot

        super().__init__(params, substeps, position_noise_std, velocity_noise_std, seed)
        from gracenav.control import CONTROL_RATE

        self.dt = float(dt) if dt is not None else 1.0 / CONTROL_RATE
        self._sim = MujocoBallbot(self.params, timestep=self.dt / substeps)
        self._model = Ballbot3D(self.params)
        self._impulse = np.zeros(3)

    def reset(self, x0: ArrayLike) -> None:
        self._sim.set_state(_check(x0))
        self._clear_forces()
        self._impulse[:] = 0.0

    def state(self) -> FloatArray:
        return np.asarray(self._sim.get_state(), dtype=float)

    def advance(self, torque: FloatArray, dt: float) -> None:
        if abs(dt - self.dt) > 1e-12:
            raise ConfigError(f"this MuJoCo plant advances by {self.dt!r} s, asked {dt!r} s")
        tau = np.clip(np.asarray(torque, dtype=float), -self._limit, self._limit)
        x = self.state()
        f = np.zeros(3)
        f += self._force
        if np.any(self._impulse != 0.0):
            f += self._impulse / dt
            self._impulse[:] = 0.0
        if self._drag[0] > 0.0:
            vel = self._model.com_jacobian(x[:4]) @ x[4:]
            f[:2] += self._damping * (self._drag[1:3] - vel[:2])
        self._sim.step(tau, self.substeps, body_force=f)

    def push(self, impulse: FloatArray) -> None:
        self._impulse[:2] += impulse

    def jump(self, delta: FloatArray) -> None:
        self._sim.set_state(self.state() + np.asarray(delta, dtype=float))


def make_plant(
    kind: PlantKind,
    params: BallbotParams | None = None,
    *,
    substeps: int = 1,
    position_noise_std: float = 0.0,
    velocity_noise_std: float = 0.0,
    seed: int = 0,
) -> Model3DPlant | MujocoPlant:
    """A shipped plant of ``kind`` ("model3d" or "mujoco").

    Raises
    ------
    ConfigError
        For another kind, or "mujoco" without MuJoCo installed.
    """
    if kind not in PLANT_KINDS:
        raise ConfigError(f"plant must be 'model3d' or 'mujoco', got {kind!r}")
    cls = Model3DPlant if kind == "model3d" else MujocoPlant
    return cls(
        params,
        substeps=substeps,
        position_noise_std=position_noise_std,
        velocity_noise_std=velocity_noise_std,
        seed=seed,
    )
