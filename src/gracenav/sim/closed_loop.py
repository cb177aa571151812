"""Closed-loop simulation of the ballbot under the Fig. 2 controllers.

A fixed-step RK4 integrates the 3D model; the controller runs at a fixed rate
(default 1024 Hz, a step exact in binary) and its torque is held between
ticks (zero-order hold) and saturated at the torque limit. Single runs and
batches of initial conditions run through the same compiled loop; a MuJoCo
plant runs the same control law through :mod:`gracenav.sim.mujoco`.

States are x = [θ_x, θ_y, φ_x, φ_y, θ̇_x, θ̇_y, φ̇_x, φ̇_y] (see
``docs/design/conventions.md``); position states p = [x, y, ẋ, ẏ] with x = r_w (θ_x + φ_x)."""

from __future__ import annotations

import enum
import itertools
import math
import os
import threading
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.control import CONTROL_RATE, ControllerGains, design_gains
from gracenav.errors import ConfigError
from gracenav.model.friction import friction_constants
from gracenav.params import BallbotParams
from gracenav.sim.disturbances import Disturbance, FloatArray, _disturbance_arrays
from gracenav.sim.plant import PLANT_KINDS, Model3DPlant, MujocoPlant, PlantKind, make_plant
from gracenav.sim.state import position_state, state_from_position

__all__ = [
    "DEFAULT_FALL_LEAN",
    "BatchResult",
    "Reference",
    "SimulationOptions",
    "SimulationResult",
    "StopReason",
    "limit_batch_threads",
    "simulate",
    "simulate_batch",
]

DEFAULT_FALL_LEAN = math.radians(20.0)
"""Default fall limit: |lean| (rad) in either plane beyond which a run has fallen (20°).

Measured on the 3D model with the CMU parameters (station keeping, 20 s, no fall
limit): the balancing controller recovers from initial leans up to 20.4° in both
planes (21.5° in one plane), saturating the torque and running ≈2.6 m away, and
diverges from larger ones; the palette's policies lean less than 6°. A lean past 20°
is therefore taken as a fall."""


@dataclass(frozen=True)
class Reference:
    """Reference states and feed-forward torques sampled at the control ticks.

    Attributes
    ----------
    states : ndarray, shape (T + 1, 8)
        Reference model state at ticks 0..T.
    inputs : ndarray, shape (T + 1, 2)
        Feed-forward torque (N m) at ticks 0..T, including the friction the
        plan expects at its own ball rate.
    dt : float
        Control period (s).
    """

    states: FloatArray
    inputs: FloatArray
    dt: float

    def __post_init__(self) -> None:
        s = np.ascontiguousarray(self.states, dtype=float)
        u = np.ascontiguousarray(self.inputs, dtype=float)
        if s.ndim != 2 or s.shape[1] != 8 or s.shape[0] < 1:
            raise ConfigError(f"Reference.states must have shape (T+1, 8), got {s.shape}")
        if u.shape != (s.shape[0], 2):
            raise ConfigError(f"Reference.inputs must have shape ({s.shape[0]}, 2), got {u.shape}")
        if not self.dt > 0:
            raise ConfigError(f"Reference.dt must be positive, got {self.dt!r}")
        object.__setattr__(self, "states", s)
        object.__setattr__(self, "inputs", u)

    @property
    def num_ticks(self) -> int:
        """Number of control periods T."""
        return int(self.states.shape[0] - 1)

    @property
    def duration(self) -> float:
        """T · dt (s)."""
        return self.num_ticks * self.dt

    @classmethod
    def hold(
        cls,
        position: ArrayLike,
        duration: float,
        *,
        params: BallbotParams | None = None,
        dt: float = 1.0 / CONTROL_RATE,
    ) -> Reference:
        """Station keeping: stay upright at rest at ``position`` (x, y) (m) for ``duration`` (s)."""
        params = params if params is not None else BallbotParams()
        xy = np.asarray(position, dtype=float)
        if xy.shape != (2,):
            raise ConfigError(f"position must be (x, y), got shape {xy.shape}")
        n = round(duration / dt)
        if n < 1:
            raise ConfigError(f"duration must be at least one control period, got {duration!r} s")
        x = state_from_position(np.r_[xy, 0.0, 0.0], params.ball_radius)
        return cls(np.tile(x, (n + 1, 1)), np.zeros((n + 1, 2)), dt)


@dataclass(frozen=True)
class SimulationOptions:
    """Options of :func:`simulate` and :func:`simulate_batch`.

    Parameters
    ----------
    substeps : int
        RK4 steps per control period (1 is accurate to ~1e-7 m at 1024 Hz).
    position_noise_std : float
        Standard deviation of white noise on the measured ball position (m).
    velocity_noise_std : float
        Standard deviation of white noise on the measured ball velocity (m/s).
    seed : int
        Seed of the noise generator.
    fall_lean : float
        Fall limit (rad): a run stops with :attr:`StopReason.FELL` at the first tick
        where |φ_x| or |φ_y| exceeds it (or the state is no longer finite). Default
        :data:`DEFAULT_FALL_LEAN` (20°); ``math.inf`` never stops.
    """

    substeps: int = 1
    position_noise_std: float = 0.0
    velocity_noise_std: float = 0.0
    seed: int = 0
    fall_lean: float = DEFAULT_FALL_LEAN

    def __post_init__(self) -> None:
        if not (isinstance(self.substeps, int) and self.substeps >= 1):
            raise ConfigError(f"substeps must be a positive integer, got {self.substeps!r}")
        if not self.fall_lean > 0.0:
            raise ConfigError(f"fall_lean must be positive (rad), got {self.fall_lean!r}")
        for name in ("position_noise_std", "velocity_noise_std"):
            if not getattr(self, name) >= 0.0:
                raise ConfigError(f"{name} must be >= 0, got {getattr(self, name)!r}")

    def plant(
        self, kind: PlantKind, params: BallbotParams | None = None
    ) -> Model3DPlant | MujocoPlant:
        """A shipped plant of ``kind`` (:func:`gracenav.sim.make_plant`) with these
        substeps, measurement noise and seed."""
        return make_plant(
            kind,
            params,
            substeps=self.substeps,
            position_noise_std=self.position_noise_std,
            velocity_noise_std=self.velocity_noise_std,
            seed=self.seed,
        )


class StopReason(enum.Enum):
    """Why a simulation stopped."""

    COMPLETED = "completed"
    DOMAIN_EXIT = "domain_exit"
    FELL = "fell"
    """|lean| exceeded :attr:`SimulationOptions.fall_lean`: the run stopped there."""


@dataclass(frozen=True)
class SimulationResult:
    """One closed-loop run.

    Attributes
    ----------
    time : ndarray, shape (N,)
        Control tick times (s).
    states : ndarray, shape (N, 8)
        Plant state at each tick, after any push or state jump of that tick.
    inputs : ndarray, shape (N, 2)
        Saturated torque commanded at each tick (N m), held until the next.
    radius : float
        Ball radius (m), to convert states to position states.
    max_lean : float
        Largest |φ_x| or |φ_y| (rad).
    max_torque : float
        Largest |τ| the controller asked for before saturation (N m).
    saturated_ticks : int
        Number of (tick, axis) pairs where the torque saturated.
    max_domain_value : float
        Largest (p − c)ᵀ P (p − c) of the monitored domain (0 if none).
    stop_reason : StopReason
    """

    time: FloatArray
    states: FloatArray
    inputs: FloatArray
    radius: float
    max_lean: float
    max_torque: float
    saturated_ticks: int
    max_domain_value: float
    stop_reason: StopReason

    @property
    def position_state(self) -> FloatArray:
        """[x, y, ẋ, ẏ] at each tick (m, m/s), shape (N, 4)."""
        return position_state(self.states, self.radius)

    @property
    def lean(self) -> FloatArray:
        """[φ_x, φ_y] at each tick (rad), shape (N, 2)."""
        return self.states[:, 2:4]


@dataclass(frozen=True)
class BatchResult:
    """A batch of closed-loop runs from different initial states.

    Attributes
    ----------
    final_states : ndarray, shape (B, 8)
        State at the last tick each run reached.
    last_tick : ndarray of int, shape (B,)
    max_lean, max_torque, max_domain_value : ndarray, shape (B,)
    saturated_ticks : ndarray of int, shape (B,)
    exit_tick : ndarray of int, shape (B,)
        First tick outside the monitored domain, −1 if never.
    states : ndarray, shape (B, T + 1, 8) or None
        Histories, when recorded.
    fall_tick : ndarray of int, shape (B,)
        Tick at which the run fell and stopped (see ``SimulationOptions.fall_lean``),
        −1 if it did not.
    """

    final_states: FloatArray
    last_tick: NDArray[np.int64]
    max_lean: FloatArray
    max_torque: FloatArray
    max_domain_value: FloatArray
    saturated_ticks: NDArray[np.int64]
    exit_tick: NDArray[np.int64]
    states: FloatArray | None = field(default=None)
    fall_tick: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))


def _model_constants(params: BallbotParams) -> FloatArray:
    from gracenav.model.ballbot3d import Ballbot3D

    return Ballbot3D(params).constants()


def _noise(options: SimulationOptions, runs: int, nt: int) -> FloatArray:
    if options.position_noise_std == 0.0 and options.velocity_noise_std == 0.0:
        return np.zeros((1, 0, 4))
    rng = np.random.default_rng(options.seed)
    std = np.array([options.position_noise_std] * 2 + [options.velocity_noise_std] * 2)
    return rng.standard_normal((runs, nt + 1, 4)) * std


#: Runs of a batch per kernel thread, at least: a batch of fewer than twice as many runs
#: runs on the calling thread (one run's loop is not split).
RUNS_PER_THREAD = 8
_POOL: ThreadPoolExecutor | None = None
_POOL_LOCK = threading.Lock()


def _cores() -> int:
    """Cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


_LOCAL = threading.local()


def limit_batch_threads(threads: int | None) -> None:
    """Run the batches :func:`simulate_batch` starts from the calling thread on at most
    ``threads`` threads (None: one per core, the default).

    A batch of many runs (a verification) is split over the cores this process may run
    on, each part on its own thread (the compiled loop releases the GIL; the results
    do not depend on the split). A thread that plans beside a control loop (the hybrid
    controller's ``planning="threaded"`` worker) limits itself to one, leaving the
    other cores to the loop.

    Raises
    ------
    ConfigError
        If ``threads`` is not a positive integer or None.
    """
    if threads is not None and (
        isinstance(threads, bool) or not isinstance(threads, int) or threads < 1
    ):
        raise ConfigError(f"threads must be a positive integer or None, got {threads!r}")
    _LOCAL.threads = threads


def _kernel_threads(runs: int) -> int:
    """Threads a batch of ``runs`` is split over: one per core this process may run on
    (at most the calling thread's :func:`limit_batch_threads`), at most one per
    :data:`RUNS_PER_THREAD` runs."""
    limit = getattr(_LOCAL, "threads", None)
    cores = _cores() if limit is None else min(limit, _cores())
    return max(1, min(cores, runs // RUNS_PER_THREAD))


def _forget_pool() -> None:
    """In a forked child: the parent's kernel threads do not exist there."""
    global _POOL, _POOL_LOCK
    _POOL = None
    _POOL_LOCK = threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pool)


def _pool() -> ThreadPoolExecutor:
    """The process's kernel threads, one per core (created on first use)."""
    global _POOL
    with _POOL_LOCK:
        if _POOL is None:
            _POOL = ThreadPoolExecutor(_cores(), thread_name_prefix="gracenav-closed-loop")
        return _POOL


def _run_kernel(
    x0: FloatArray,
    reference: Reference,
    gains: ControllerGains,
    plant_params: BallbotParams,
    disturbances: Sequence[Disturbance],
    options: SimulationOptions,
    monitor: tuple[FloatArray, FloatArray] | None,
    stop_on_exit: bool,
    record: bool,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    from gracenav import _kernels

    nb = x0.shape[0]
    nt = reference.num_ticks
    force, impulse, jump, tether, tgains = _disturbance_arrays(disturbances, reference.dt, nt)
    if monitor is None:
        centers = np.zeros((0, 4))
        shapes = np.zeros((0, 4, 4))
    else:
        centers = np.ascontiguousarray(monitor[0], dtype=float)
        shapes = np.ascontiguousarray(monitor[1], dtype=float)
        if centers.shape != (nt + 1, 4) or shapes.shape != (nt + 1, 4, 4):
            raise ConfigError(
                f"monitored domain must have centres ({nt + 1}, 4) and shapes ({nt + 1}, 4, 4), "
                f"got {centers.shape} and {shapes.shape}"
            )
    states = np.zeros((nb, nt + 1, 8) if record else (nb, 0, 8))
    inputs = np.zeros((nb, nt + 1, 2) if record else (nb, 0, 2))
    summary = np.zeros((nb, 7))
    final = np.zeros((nb, 8))
    starts = np.ascontiguousarray(x0, dtype=float)
    noise = _noise(options, nb, nt)
    constants = (
        _model_constants(plant_params),
        friction_constants(plant_params),
        _model_constants(gains.params),
        friction_constants(gains.params),
        gains.kernel_arrays(),
        gains.max_lean_compensation,
        _kernels.friction_mode(gains.friction_compensation, gains.friction_midpoint),
        plant_params.torque_limit,
    )

    def runs(a: int, b: int) -> None:
        """Runs a..b-1 of the batch, into their rows of the outputs (the kernel
        releases the GIL; each run depends on its own start and noise only)."""
        _kernels.closed_loop(
            *constants,
            starts[a:b],
            reference.states,
            reference.inputs,
            reference.dt,
            options.substeps,
            noise if noise.shape[0] == 1 else noise[a:b],
            force,
            impulse,
            jump,
            tether,
            tgains,
            centers,
            shapes,
            stop_on_exit,
            float(options.fall_lean),
            record,
            states[a:b],
            inputs[a:b],
            summary[a:b],
            final[a:b],
        )

    threads = _kernel_threads(nb)
    if threads == 1:
        runs(0, nb)
    else:
        bounds = np.linspace(0, nb, threads + 1).round().astype(int)
        jobs = [_pool().submit(runs, a, b) for a, b in itertools.pairwise(bounds.tolist())]
        for job in jobs:
            job.result()
    return states, inputs, summary, final


def _stop_reason(stop_on_exit: bool, exit_tick: int, fall_tick: int) -> StopReason:
    if fall_tick >= 0:
        return StopReason.FELL
    if stop_on_exit and exit_tick >= 0:
        return StopReason.DOMAIN_EXIT
    return StopReason.COMPLETED


def _check_state(x0: ArrayLike, batch: bool) -> FloatArray:
    x = np.asarray(x0, dtype=float)
    want = "(B, 8)" if batch else "(8,)"
    if (batch and (x.ndim != 2 or x.shape[1] != 8)) or (not batch and x.shape != (8,)):
        raise ConfigError(f"initial state must have shape {want}, got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ConfigError("initial state contains non-finite values")
    return x


def simulate(
    x0: ArrayLike,
    reference: Reference,
    gains: ControllerGains | None = None,
    *,
    params: BallbotParams | None = None,
    plant: PlantKind = "model3d",
    disturbances: Sequence[Disturbance] = (),
    options: SimulationOptions | None = None,
    monitor: tuple[FloatArray, FloatArray] | None = None,
    stop_on_exit: bool = False,
) -> SimulationResult:
    """Simulate one closed-loop run of the Fig. 2 controllers tracking ``reference``.

    Parameters
    ----------
    x0 : array_like, shape (8,)
        Initial plant state.
    reference : Reference
        Reference states and feed-forward torques at the control ticks; the
        run lasts ``reference.duration``.
    gains : ControllerGains, optional
        Controller (default: :func:`gracenav.control.design_gains` on ``params``).
    params : BallbotParams, optional
        Parameters of the *plant* (default: the controller's nominal ones).
        Different values from ``gains.params`` simulate model mismatch.
    plant : {"model3d", "mujoco"}
        The gracenav 3D model (compiled RK4) or the MuJoCo model.
    disturbances : sequence of Push, BodyForce, StateJump, Drag
    options : SimulationOptions, optional
    monitor : (centres (T+1, 4), shapes (T+1, 4, 4)), optional
        Outer domain D'(t) to monitor: {p : (p − c)ᵀ P (p − c) <= 1}.
    stop_on_exit : bool
        Stop at the first tick outside the monitored domain.

    Returns
    -------
    SimulationResult
    """
    x = _check_state(x0, batch=False)
    gains = gains if gains is not None else design_gains(params)
    plant_params = params if params is not None else gains.params
    options = options if options is not None else SimulationOptions()
    if plant not in PLANT_KINDS:
        raise ConfigError(f"plant must be {' or '.join(map(repr, PLANT_KINDS))}, got {plant!r}")
    if plant == "mujoco":
        return _simulate_mujoco(
            x, reference, gains, plant_params, disturbances, options, monitor, stop_on_exit
        )
    states, inputs, summary, _ = _run_kernel(
        x[None], reference, gains, plant_params, disturbances, options, monitor, stop_on_exit, True
    )
    last = int(summary[0, 0])
    return SimulationResult(
        time=np.arange(last + 1, dtype=np.float64) * np.float64(reference.dt),
        states=states[0, : last + 1],
        inputs=inputs[0, : last + 1],
        radius=plant_params.ball_radius,
        max_lean=float(summary[0, 1]),
        max_torque=float(summary[0, 2]),
        saturated_ticks=int(summary[0, 4]),
        max_domain_value=float(summary[0, 3]),
        stop_reason=_stop_reason(stop_on_exit, int(summary[0, 5]), int(summary[0, 6])),
    )


def simulate_batch(
    x0: ArrayLike,
    reference: Reference,
    gains: ControllerGains | None = None,
    *,
    params: BallbotParams | None = None,
    disturbances: Sequence[Disturbance] = (),
    options: SimulationOptions | None = None,
    monitor: tuple[FloatArray, FloatArray] | None = None,
    stop_on_exit: bool = False,
    record: bool = False,
) -> BatchResult:
    """Simulate many closed-loop runs from the initial states ``x0`` (B, 8) at once.

    Same arguments as :func:`simulate` (model3d plant only). ``record`` keeps the
    full state histories. A batch of at least twice :data:`RUNS_PER_THREAD` runs is
    split over the cores (:func:`limit_batch_threads`); each run's result is the same
    as alone.
    """
    x = _check_state(x0, batch=True)
    gains = gains if gains is not None else design_gains(params)
    plant_params = params if params is not None else gains.params
    options = options if options is not None else SimulationOptions()
    states, _, summary, final = _run_kernel(
        x, reference, gains, plant_params, disturbances, options, monitor, stop_on_exit, record
    )
    last = summary[:, 0].astype(np.int64)
    return BatchResult(
        final_states=final,
        last_tick=last,
        max_lean=summary[:, 1].copy(),
        max_torque=summary[:, 2].copy(),
        max_domain_value=summary[:, 3].copy(),
        saturated_ticks=summary[:, 4].astype(np.int64),
        exit_tick=summary[:, 5].astype(np.int64),
        states=states if record else None,
        fall_tick=summary[:, 6].astype(np.int64),
    )


def _simulate_mujoco(
    x0: FloatArray,
    reference: Reference,
    gains: ControllerGains,
    plant_params: BallbotParams,
    disturbances: Sequence[Disturbance],
    options: SimulationOptions,
    monitor: tuple[FloatArray, FloatArray] | None,
    stop_on_exit: bool,
) -> SimulationResult:
    """The closed loop with MuJoCo as the plant (same control law, Python loop)."""
    from gracenav import _kernels
    from gracenav.model.ballbot3d import Ballbot3D
    from gracenav.sim.mujoco import MujocoBallbot

    nt = reference.num_ticks
    dt = reference.dt
    force, impulse, jump, tether, tgains = _disturbance_arrays(disturbances, dt, nt)
    noise = _noise(options, 1, nt)
    plant = MujocoBallbot(plant_params, timestep=dt / options.substeps)
    model = Ballbot3D(plant_params)
    plant.set_state(x0)
    fr = friction_constants(gains.params)
    k = gains.kernel_arrays()
    r = gains.params.ball_radius
    friction = _kernels.friction_mode(gains.friction_compensation, gains.friction_midpoint)
    states = np.zeros((nt + 1, 8))
    inputs = np.zeros((nt + 1, 2))
    tau = np.zeros(2)
    zero = np.zeros(4)
    max_lean = max_tau = max_dom = 0.0
    saturated = 0
    exit_tick = -1
    fall_tick = -1
    last = nt
    for n in range(nt + 1):
        x = plant.get_state()
        if jump.shape[0]:
            x = x + jump[n]
            plant.set_state(x)
        meas = noise[0, n] if noise.shape[1] else zero
        _kernels.control_law(
            r,
            fr,
            k,
            gains.max_lean_compensation,
            friction,
            x,
            meas,
            reference.states[n],
            reference.states[min(n + 1, nt)],
            reference.inputs[n],
            tau,
        )
        max_tau = max(max_tau, float(np.max(np.abs(tau))))
        saturated += int(np.count_nonzero(np.abs(tau) > plant_params.torque_limit))
        np.clip(tau, -plant_params.torque_limit, plant_params.torque_limit, out=tau)
        max_lean = max(max_lean, float(np.max(np.abs(x[2:4]))))
        if not np.all(np.abs(x[2:4]) <= options.fall_lean):
            fall_tick = n
        if monitor is not None:
            dp = position_state(x, r) - monitor[0][n]
            val = float(dp @ monitor[1][n] @ dp)
            max_dom = max(max_dom, val)
            if val > 1.0 and exit_tick < 0:
                exit_tick = n
        states[n] = x
        inputs[n] = tau
        if (exit_tick >= 0 and stop_on_exit) or fall_tick >= 0 or n == nt:
            last = n
            break
        f = np.zeros(3)
        if force.shape[0]:
            f += force[n]
        if impulse.shape[0] and np.any(impulse[n] != 0.0):
            f += impulse[n] / dt
        if tether.shape[0] and tether[n, 0] > 0.0:
            vel = model.com_jacobian(x[:4]) @ x[4:]
            f[:2] += tgains[0] * (tether[n, 1:3] - vel[:2])
        plant.step(tau, options.substeps, body_force=f)
    return SimulationResult(
        time=np.arange(last + 1, dtype=np.float64) * np.float64(dt),
        states=states[: last + 1],
        inputs=inputs[: last + 1],
        radius=plant_params.ball_radius,
        max_lean=max_lean,
        max_torque=max_tau,
        saturated_ticks=saturated,
        max_domain_value=max_dom,
        stop_reason=_stop_reason(stop_on_exit, exit_tick, fall_tick),
    )
