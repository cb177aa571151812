"""MuJoCo model of the ballbot: an independent physics check and an alternative plant.

The robot is built from rigid bodies and a soft-contact floor in MuJoCo
(optional dependency, ``pip install gracenav[mujoco]``) and driven through
the coordinates of the 3D model (:class:`gracenav.model.Ballbot3D`,
conventions in docs/design/conventions.md, "3D model"): the state is x = [q, q̇] (8,) with
q = [θ_x, θ_y, φ_x, φ_y] (rad) and the input τ = [τ_x, τ_y] (N m), the
generalised forces on θ_x and θ_y.

Two variants are built by :func:`build_mjcf`:

``yaw="locked"``
    A *carrier* on x, y, z slides; the ball on a ``ball`` joint at
    the carrier origin; the body on two hinges at the carrier origin in the
    Euler order of the 3D model, R = R_y(φ_x) R_x(−φ_y): hinge ``phi_x`` about
    the world y axis with angle φ_x, then hinge ``phi_y`` about the
    once-rotated −x axis with angle φ_y. The body cannot yaw, exactly as in
    the 3D model. The ball mass is split evenly between the carrier and the
    ball body (both only translate with the ball centre, so the split is
    exact; the carrier never rotates, so its rotational inertia, which
    MuJoCo requires to be non-zero, has no effect).
``yaw="free"``
    The ball on a free joint and the body on a ``ball`` joint at the ball
    centre: the body may yaw, which the 3D model cannot. Agreement with the
    3D model is then approximate (≈0.5 % over 0.5 s) in genuinely 3D motions;
    motion in one vertical plane excites no yaw and agrees as closely as the
    locked variant.

Physical torque of the drive
----------------------------
The generalised inputs τ = [τ_x, τ_y] are realised as the torque

    τ_w = (−τ_y, τ_x, τ_y tan(φ_x / 2))   (N m, world frame)

applied to the ball, and −τ_w applied to the body (its reaction), see
:func:`drive_torque`. Its power on the relative ball/body angular velocity
is τ_w · (ω_w − ω_b) = τ_x θ̇_x + τ_y θ̇_y for every motion that rolls
without slip or spin, so it is exactly the generalised force [τ_x, τ_y, 0, 0]
of the 3D model. The vertical component is taken up by the torsional
friction of the contact (``condim=4``). Drive friction
D_i = D_c tanh(θ̇_i / ε) + D_v θ̇_i is not part of the MJCF: the plant
subtracts it from τ_i, using the relative rates θ̇_i computed from the
physical state, before converting to τ_w.

Integration
-----------
:meth:`MujocoBallbot.step` integrates MuJoCo's forward dynamics
(``mj_forward``: rigid-body dynamics plus the soft-contact constraint solve)
with a classical fixed-step RK4 of its own, re-evaluating the drive torque,
friction and tan(φ_x/2) at every stage. ``mj_step`` with MuJoCo's RK4 would
hold ``xfrc_applied`` constant over the step, which makes the stiff smoothed
Coulomb friction (slope D_c/ε ≈ 76 N m s/rad) first-order accurate only.
The MJCF itself asks for MuJoCo's RK4 integrator, for use outside this class.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.control import CONTROL_RATE
from gracenav.errors import ConfigError
from gracenav.model.friction import friction_constants, friction_torque
from gracenav.params import BallbotParams

if TYPE_CHECKING:  # pragma: no cover
    import mujoco

__all__ = ["CONTACT_SINK", "MujocoBallbot", "build_mjcf", "drive_torque"]

FloatArray = NDArray[np.float64]
YawMode = Literal["locked", "free"]

CONTACT_SINK = 1e-9
"""Depth (m) the ball is placed into the floor by ``set_state``.

``mj_forward`` at a contact distance of exactly 0 produces no contact force;
a 1 nm penetration makes the contact active without a measurable spring force.
"""

# Contact: high sliding and torsional friction (no slip, no spin about the
# vertical), zero rolling friction (any rolling resistance stops the ball), an
# elliptic cone, and a nearly hard constraint (impedance 0.9999, time constant
# of two steps: the stiffest MuJoCo's refsafe clamp allows).
_SLIDING_FRICTION = 10.0
_TORSIONAL_FRICTION = 10.0  # m: the torsional torque bound is this times the normal force
_SOLIMP = "0.9999 0.9999 0.001 0.5 2"
_CARRIER_INERTIA = 1e-6  # kg m², never excited (the carrier only translates)
_SOLVER_TOLERANCE = 1e-12


def _require_mujoco() -> Any:
    """Import and return the ``mujoco`` module, or raise a ConfigError saying how to install it."""
    try:
        import mujoco
    except ImportError:
        raise ConfigError(
            "the MuJoCo plant needs the optional 'mujoco' package: pip install gracenav[mujoco]"
        ) from None
    return mujoco


def _check_options(yaw: str, timestep: float) -> None:
    if yaw not in ("locked", "free"):
        raise ConfigError(f"yaw must be 'locked' or 'free', got {yaw!r}")
    if not (isinstance(timestep, (int, float)) and math.isfinite(timestep) and timestep > 0):
        raise ConfigError(f"timestep must be a positive number of seconds, got {timestep!r}")


def _f(value: float) -> str:
    """Format a float for MJCF without losing precision."""
    return repr(float(value))


def build_mjcf(
    params: BallbotParams, *, yaw: YawMode = "locked", timestep: float = 1.0 / CONTROL_RATE
) -> str:
    """Return the MJCF (MuJoCo XML) text of the ballbot.

    Parameters
    ----------
    params : BallbotParams
        Physical parameters. Ball: sphere of radius r_w, mass m_w, inertia
        I_w about every axis. Body: mass m_b, centre of mass ℓ_b above the
        ball centre on the body axis, inertia diag(I_xx, I_yy, I_zz) about
        its COM in the body frame. Gravity (0, 0, −g). Drive friction is not
        in the MJCF (see the module docstring).
    yaw : {"locked", "free"}
        ``"locked"``: carrier with x/y/z slides, ball on a ball joint, body
        on hinges φ_x (about y) then φ_y (about −x), no yaw. ``"free"``: ball
        on a free joint, body on a ball joint at the ball centre (can yaw).
    timestep : float
        Integration step (s); also sets the contact time constant to two
        steps. Prefer a power of two (1/1024 s by default).

    Returns
    -------
    str
        MJCF text, loadable with ``mujoco.MjModel.from_xml_string``.
        Bodies are named ``ball`` and ``body``; the world floor geom
        ``floor``; in the locked variant the joints are ``x``, ``y``, ``z``,
        ``ball``, ``phi_x``, ``phi_y``, in the free variant ``ball`` (free)
        and ``body`` (ball joint).

    Raises
    ------
    ConfigError
        If ``yaw`` or ``timestep`` is invalid.
    """
    _check_options(yaw, timestep)
    p = params
    r = p.ball_radius
    solref = f"{_f(2.0 * timestep)} 1"
    contact = (
        f'condim="4" friction="{_f(_SLIDING_FRICTION)} {_f(_TORSIONAL_FRICTION)} 0" '
        f'solref="{solref}" solimp="{_SOLIMP}"'
    )
    iw = _f(p.ball_inertia)
    ball_geom = f'<geom name="ball" type="sphere" size="{_f(r)}" {contact} rgba="0.8 0.3 0.2 1"/>'
    body_height = 2.0 * p.body_com_height
    body_inertial = (
        f'<inertial pos="0 0 {_f(p.body_com_height)}" mass="{_f(p.body_mass)}" '
        f'diaginertia="{_f(p.body_inertia_x)} {_f(p.body_inertia_y)} {_f(p.body_inertia_z)}"/>'
    )
    # Visual only: no collisions, no mass (the explicit <inertial> defines the body).
    body_geom = (
        f'<geom name="body" type="cylinder" size="{_f(p.body_radius)} {_f(body_height / 2 - r)}" '
        f'pos="0 0 {_f(body_height / 2 + r)}" contype="0" conaffinity="0" mass="0" '
        f'rgba="0.3 0.4 0.7 0.6"/>'
    )
    if yaw == "locked":
        half = _f(p.ball_mass / 2.0)
        ci = _f(_CARRIER_INERTIA)
        robot = f"""
    <body name="carrier" pos="0 0 {_f(r)}">
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="y" type="slide" axis="0 1 0"/>
      <joint name="z" type="slide" axis="0 0 1"/>
      <inertial pos="0 0 0" mass="{half}" diaginertia="{ci} {ci} {ci}"/>
      <body name="ball">
        <joint name="ball" type="ball"/>
        <inertial pos="0 0 0" mass="{half}" diaginertia="{iw} {iw} {iw}"/>
        {ball_geom}
      </body>
      <body name="body">
        <joint name="phi_x" type="hinge" axis="0 1 0"/>
        <joint name="phi_y" type="hinge" axis="-1 0 0"/>
        {body_inertial}
        {body_geom}
      </body>
    </body>"""
    else:
        robot = f"""
    <body name="ball" pos="0 0 {_f(r)}">
      <freejoint name="ball"/>
      <inertial pos="0 0 0" mass="{_f(p.ball_mass)}" diaginertia="{iw} {iw} {iw}"/>
      {ball_geom}
      <body name="body">
        <joint name="body" type="ball"/>
        {body_inertial}
        {body_geom}
      </body>
    </body>"""
    return f"""<mujoco model="gracenav_ballbot_{yaw}_yaw">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{_f(timestep)}" gravity="0 0 {_f(-p.gravity)}" integrator="RK4"
          cone="elliptic" solver="Newton" tolerance="{_f(_SOLVER_TOLERANCE)}" iterations="100"/>
  <worldbody>
    <light pos="0 0 4" dir="0 0 -1"/>
    <geom name="floor" type="plane" size="0 0 1" {contact} rgba="0.85 0.85 0.85 1"/>{robot}
  </worldbody>
</mujoco>
"""


def drive_torque(tau: ArrayLike, phi_x: ArrayLike) -> FloatArray:
    """World-frame torque the drive applies to the ball for generalised inputs τ.

    Parameters
    ----------
    tau : array_like, shape (..., 2)
        Generalised forces [τ_x, τ_y] on θ_x, θ_y (N m).
    phi_x : array_like, shape (...)
        Body lean toward +x (rad).

    Returns
    -------
    ndarray, shape (..., 3)
        τ_w = (−τ_y, τ_x, τ_y tan(φ_x/2)) (N m), world frame. The body receives
        −τ_w. Its power on ω_w − ω_b is τ_x θ̇_x + τ_y θ̇_y for rolling without
        slip or spin (docs/design/conventions.md, "3D model").
    """
    tau = np.asarray(tau, dtype=float)
    phi_x = np.asarray(phi_x, dtype=float)
    return np.stack([-tau[..., 1], tau[..., 0], tau[..., 1] * np.tan(0.5 * phi_x)], axis=-1)


def _cross(u: FloatArray, v: FloatArray) -> FloatArray:
    """u × v for 3-vectors (np.cross costs ~30 µs of call overhead here)."""
    return np.array(
        [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
    )


def _body_quaternion(phi_x: float, phi_y: float) -> FloatArray:
    """Quaternion (w, x, y, z) of R = R_y(φ_x) R_x(−φ_y)."""
    cy, sy = math.cos(0.5 * phi_x), math.sin(0.5 * phi_x)
    cx, sx = math.cos(0.5 * phi_y), -math.sin(0.5 * phi_y)
    # q_y ⊗ q_x with q_y = (cy, 0, sy, 0), q_x = (cx, sx, 0, 0)
    return np.array([cy * cx, cy * sx, sy * cx, -sy * sx])


def _body_rotation(phi_x: float, phi_y: float) -> FloatArray:
    """Rotation matrix R = R_y(φ_x) R_x(−φ_y), shape (3, 3)."""
    c1, s1 = math.cos(phi_x), math.sin(phi_x)
    c2, s2 = math.cos(phi_y), math.sin(phi_y)
    ry = np.array([[c1, 0.0, s1], [0.0, 1.0, 0.0], [-s1, 0.0, c1]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, c2, s2], [0.0, -s2, c2]])
    return ry @ rx


def _leans_from_axis(a: FloatArray, adot: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Leans φ = [φ_x, φ_y] (rad) and rates φ̇ (rad/s) from the body axis a = R ẑ and ȧ.

    a = (sin φ_x cos φ_y, sin φ_y, cos φ_x cos φ_y), so φ_y = asin(a_y) and
    φ_x = atan2(a_x, a_z); differentiating, φ̇_y = ȧ_y / cos φ_y and
    φ̇_x = (a_z ȧ_x − a_x ȧ_z) / (a_x² + a_z²).
    """
    phi_y = math.asin(max(-1.0, min(1.0, float(a[1]))))
    phi_x = math.atan2(float(a[0]), float(a[2]))
    rho2 = a[0] ** 2 + a[2] ** 2
    phid_x = (a[2] * adot[0] - a[0] * adot[2]) / rho2
    phid_y = adot[1] / math.cos(phi_y)
    return np.array([phi_x, phi_y]), np.array([phid_x, phid_y])


def _lean_accelerations(
    a: FloatArray, adot: FloatArray, addot: FloatArray, phi: FloatArray, phid: FloatArray
) -> FloatArray:
    """Lean accelerations φ̈ (rad/s²) from the body axis and its first two derivatives.

    The derivative of the formulas of :func:`_leans_from_axis`:
    φ̈_y = (ä_y + sin φ_y φ̇_y²) / cos φ_y and
    φ̈_x = [a_z ä_x − a_x ä_z − 2 φ̇_x (a_x ȧ_x + a_z ȧ_z)] / (a_x² + a_z²).
    """
    rho2 = a[0] ** 2 + a[2] ** 2
    phidd_x = (
        a[2] * addot[0] - a[0] * addot[2] - 2.0 * phid[0] * (a[0] * adot[0] + a[2] * adot[2])
    ) / rho2
    phidd_y = (addot[1] + math.sin(phi[1]) * phid[1] ** 2) / math.cos(phi[1])
    return np.array([phidd_x, phidd_y])


class MujocoBallbot:
    """The ballbot simulated by MuJoCo, in the coordinates of the 3D model.

    Parameters
    ----------
    params : BallbotParams, optional
        Physical parameters (Table I defaults). Drive friction is applied by
        this class; use ``params.without_friction()`` to switch it off.
    yaw : {"locked", "free"}
        MuJoCo model variant, see :func:`build_mjcf`.
    timestep : float
        MuJoCo integration step h (s). The drive torque and friction are
        re-evaluated at every RK4 stage; at 1/1024 s the locked variant
        reproduces a 0.5 s trajectory of the 3D model to ≈1e-7 (relative).
        Also sets the contact time constant (two steps).

    Attributes
    ----------
    model : mujoco.MjModel
        The compiled model.
    data : mujoco.MjData
        The simulation state advanced by :meth:`step`.

    Notes
    -----
    Inputs τ = [τ_x, τ_y] (N m) are the generalised forces on θ_x, θ_y of the
    3D model, realised as the world torque τ_w = (−τ_y, τ_x, τ_y tan(φ_x/2))
    on the ball and −τ_w on the body (:func:`drive_torque`). They are held
    constant over each call to :meth:`step` (zero-order hold); friction, the
    conversion to τ_w and ``body_force`` are evaluated at every RK4 stage.

    Raises
    ------
    ConfigError
        If MuJoCo is not installed (``pip install gracenav[mujoco]``) or an
        option is invalid.
    """

    def __init__(
        self,
        params: BallbotParams | None = None,
        *,
        yaw: YawMode = "locked",
        timestep: float = 1.0 / CONTROL_RATE,
    ) -> None:
        mj = _require_mujoco()
        _check_options(yaw, timestep)
        self.params = params if params is not None else BallbotParams()
        self.yaw: YawMode = yaw
        self.timestep = float(timestep)
        self._mj = mj
        self.model: mujoco.MjModel = mj.MjModel.from_xml_string(
            build_mjcf(self.params, yaw=yaw, timestep=self.timestep)
        )
        self.data: mujoco.MjData = mj.MjData(self.model)
        self._scratch: mujoco.MjData = mj.MjData(self.model)
        self._ball = self.model.body("ball").id
        self._body = self.model.body("body").id
        self._vel = np.zeros(6)
        self.set_state(np.zeros(8))

    # -- state conversion ---------------------------------------------------------
    @property
    def time(self) -> float:
        """Simulated time (s) since the last :meth:`set_state`."""
        return float(self.data.time)

    def _write_state(self, data: mujoco.MjData, x: FloatArray) -> None:
        """Write the 3D-model state x (8,) into ``data.qpos``/``qvel`` (no forward pass)."""
        r = self.params.ball_radius
        th, ph, thd, phd = x[0:2], x[2:4], x[4:6], x[6:8]
        pos = r * (th + ph)
        vel = r * (thd + phd)
        # Rolling without slip or spin: ω_w = (−ẏ/r, ẋ/r, 0) (world = ball frame at identity).
        w_ball = np.array([-vel[1] / r, vel[0] / r, 0.0])
        data.qpos[:] = 0.0
        data.qvel[:] = 0.0
        data.qpos[0:2] = pos
        if self.yaw == "locked":
            # carrier slides x, y, z (relative to the carrier's home at height r_w)
            data.qpos[2] = -CONTACT_SINK
            data.qpos[3:7] = (1.0, 0.0, 0.0, 0.0)
            data.qpos[7:9] = ph
            data.qvel[0:2] = vel
            data.qvel[3:6] = w_ball
            data.qvel[6:8] = phd
        else:
            # free joint: world position and quaternion; body ball joint: quaternion
            # relative to the ball (= world orientation, the ball being at identity).
            data.qpos[2] = r - CONTACT_SINK
            data.qpos[3:7] = (1.0, 0.0, 0.0, 0.0)
            data.qpos[7:11] = _body_quaternion(float(ph[0]), float(ph[1]))
            data.qvel[0:2] = vel
            data.qvel[3:6] = w_ball
            # body ω_b = φ̇_x ŷ − φ̇_y (cos φ_x, 0, −sin φ_x); the ball joint's velocity is
            # the relative angular velocity in the body frame.
            c, s = math.cos(ph[0]), math.sin(ph[0])
            w_body = np.array([-phd[1] * c, phd[0], phd[1] * s])
            rot = _body_rotation(float(ph[0]), float(ph[1]))
            data.qvel[6:9] = rot.T @ (w_body - w_ball)
        data.qacc_warmstart[:] = 0.0

    def _read_state(self, data: mujoco.MjData) -> tuple[FloatArray, FloatArray, FloatArray]:
        """3D-model state from the physical quantities of ``data``.

        Requires position and velocity stages to be up to date. Returns
        (x (8,), body axis a (3,), body angular velocity ω_b (3,)).
        """
        mj = self._mj
        r = self.params.ball_radius
        centre = data.xpos[self._ball]
        mj.mj_objectVelocity(self.model, data, mj.mjtObj.mjOBJ_BODY, self._ball, self._vel, 0)
        v_ball = self._vel[3:6].copy()
        mj.mj_objectVelocity(self.model, data, mj.mjtObj.mjOBJ_BODY, self._body, self._vel, 0)
        w_body = self._vel[0:3].copy()
        a = data.xmat[self._body].reshape(3, 3)[:, 2].copy()
        adot = _cross(w_body, a)
        phi, phid = _leans_from_axis(a, adot)
        x = np.empty(8)
        x[0:2] = centre[0:2] / r - phi
        x[2:4] = phi
        x[4:6] = v_ball[0:2] / r - phid
        x[6:8] = phid
        return x, a, w_body

    def set_state(self, x: ArrayLike) -> None:
        """Place the robot in the 3D-model state x and reset the time to 0.

        Parameters
        ----------
        x : array_like, shape (8,)
            [θ_x, θ_y, φ_x, φ_y, θ̇_x, θ̇_y, φ̇_x, φ̇_y] (rad, rad/s). The ball
            centre goes to (r_w(θ_x + φ_x), r_w(θ_y + φ_y), r_w − 1 nm), rolling
            without slip or spin, the body to R = R_y(φ_x) R_x(−φ_y) (no yaw).
        """
        x = self._check_state(x)
        self._write_state(self.data, x)
        self.data.time = 0.0
        self.data.xfrc_applied[:] = 0.0
        self._mj.mj_forward(self.model, self.data)

    def get_state(self) -> FloatArray:
        """The 3D-model state computed from physical quantities, shape (8,).

        Ball centre position and velocity give x = r_w(θ_x + φ_x),
        y = r_w(θ_y + φ_y); the body axis a (unit vector from the ball centre
        toward the body COM) gives φ_y = asin(a_y), φ_x = atan2(a_x, a_z),
        and its rate ω_b × a the lean rates. Body yaw (free variant) does not
        enter.
        """
        mj = self._mj
        mj.mj_kinematics(self.model, self.data)
        mj.mj_comPos(self.model, self.data)
        mj.mj_comVel(self.model, self.data)
        return self._read_state(self.data)[0]

    def body_axis(self) -> FloatArray:
        """Unit vector from the ball centre toward the body COM (world frame), shape (3,)."""
        mj = self._mj
        mj.mj_kinematics(self.model, self.data)
        return np.array(self.data.xmat[self._body].reshape(3, 3)[:, 2])

    def ball_position(self) -> FloatArray:
        """Ball centre position in the floor plane (m), shape (2,)."""
        mj = self._mj
        mj.mj_kinematics(self.model, self.data)
        return np.array(self.data.xpos[self._ball][0:2])

    # -- forces ------------------------------------------------------------------
    def _friction(self, thd: FloatArray) -> FloatArray:
        out: FloatArray = friction_torque(friction_constants(self.params), thd)
        return out

    def _apply_inputs(
        self, data: mujoco.MjData, x: FloatArray, tau: FloatArray, body_force: FloatArray | None
    ) -> None:
        """Set ``data.xfrc_applied`` for the state x: drive torque minus friction, body force."""
        tw = drive_torque(tau - self._friction(x[4:6]), x[2])
        data.xfrc_applied[:] = 0.0
        data.xfrc_applied[self._ball, 3:6] = tw
        data.xfrc_applied[self._body, 3:6] = -tw
        if body_force is not None:
            data.xfrc_applied[self._body, 0:3] = body_force

    def _forward(
        self, data: mujoco.MjData, tau: FloatArray, body_force: FloatArray | None
    ) -> FloatArray:
        """Forward dynamics at the state in ``data``: returns the physical state x (8,).

        Leaves ``data.qacc`` (and the rest of ``data``) evaluated with the inputs applied.
        """
        mj = self._mj
        mj.mj_fwdPosition(self.model, data)
        mj.mj_fwdVelocity(self.model, data)
        x, _, _ = self._read_state(data)
        self._apply_inputs(data, x, tau, body_force)
        mj.mj_forwardSkip(self.model, data, mj.mjtStage.mjSTAGE_VEL, 1)
        return x

    # -- dynamics ----------------------------------------------------------------
    def step(
        self, tau: ArrayLike, n_steps: int = 1, *, body_force: ArrayLike | None = None
    ) -> FloatArray:
        """Advance by ``n_steps`` steps of h = ``timestep`` with the input held constant.

        Parameters
        ----------
        tau : array_like, shape (2,)
            Generalised drive torques [τ_x, τ_y] (N m) on θ_x, θ_y (before
            friction), realised as the world torque of :func:`drive_torque`
            on the ball and its reaction on the body.
        n_steps : int
            Number of RK4 steps.
        body_force : array_like, shape (3,), optional
            World-frame force (N) applied at the body centre of mass (a push).

        Returns
        -------
        ndarray, shape (8,)
            The state after the steps (as :meth:`get_state`).
        """
        tau_a = self._check_input(tau)
        force = None
        if body_force is not None:
            force = np.asarray(body_force, dtype=float)
            if force.shape != (3,) or not np.all(np.isfinite(force)):
                raise ConfigError(f"body_force must be a finite array of shape (3,), got {force!r}")
        if int(n_steps) != n_steps or n_steps < 0:
            raise ConfigError(f"n_steps must be a non-negative integer, got {n_steps!r}")
        mj = self._mj
        m, d = self.model, self.data
        h = self.timestep
        qpos0 = np.empty(m.nq)
        qvel0 = np.empty(m.nv)
        dv = np.empty(m.nv)
        for _ in range(int(n_steps)):
            qpos0[:] = d.qpos
            qvel0[:] = d.qvel
            # stage 1 at (q0, v0)
            self._forward(d, tau_a, force)
            k1v, k1a = qvel0.copy(), d.qacc.copy()
            # stage 2 at (q0 + h/2 k1v, v0 + h/2 k1a)
            mj.mj_integratePos(m, d.qpos, k1v, 0.5 * h)
            d.qvel[:] = qvel0 + 0.5 * h * k1a
            self._forward(d, tau_a, force)
            k2v, k2a = d.qvel.copy(), d.qacc.copy()
            # stage 3
            d.qpos[:] = qpos0
            mj.mj_integratePos(m, d.qpos, k2v, 0.5 * h)
            d.qvel[:] = qvel0 + 0.5 * h * k2a
            self._forward(d, tau_a, force)
            k3v, k3a = d.qvel.copy(), d.qacc.copy()
            # stage 4
            d.qpos[:] = qpos0
            mj.mj_integratePos(m, d.qpos, k3v, h)
            d.qvel[:] = qvel0 + h * k3a
            self._forward(d, tau_a, force)
            k4v, k4a = d.qvel.copy(), d.qacc.copy()
            # combine; positions on the manifold (quaternions) via mj_integratePos
            dv[:] = (k1v + 2.0 * k2v + 2.0 * k3v + k4v) / 6.0
            d.qpos[:] = qpos0
            mj.mj_integratePos(m, d.qpos, dv, h)
            d.qvel[:] = qvel0 + h * (k1a + 2.0 * k2a + 2.0 * k3a + k4a) / 6.0
            mj.mj_normalizeQuat(m, d.qpos)
            d.time += h
        return self.get_state()

    def accelerations(self, q: ArrayLike, qd: ArrayLike, tau: ArrayLike) -> FloatArray:
        """Instantaneous generalised accelerations q̈ of the 3D model's coordinates.

        The state is placed (ball 1 nm into the floor so that the contact is
        active) in a scratch copy of the data, the drive torque minus friction
        applied, and ``mj_forward`` solves the dynamics with the contact
        constraint; q̈ is computed from the ball-centre acceleration and the
        body's angular acceleration. The simulation state is not touched.

        Parameters
        ----------
        q : array_like, shape (4,)
            [θ_x, θ_y, φ_x, φ_y] (rad).
        qd : array_like, shape (4,)
            Rates (rad/s).
        tau : array_like, shape (2,)
            Generalised drive torques [τ_x, τ_y] (N m).

        Returns
        -------
        ndarray, shape (4,)
            [θ̈_x, θ̈_y, φ̈_x, φ̈_y] (rad/s²).
        """
        q_a = np.asarray(q, dtype=float)
        qd_a = np.asarray(qd, dtype=float)
        if q_a.shape != (4,) or qd_a.shape != (4,):
            raise ConfigError(f"q and qd must have shape (4,), got {q_a.shape} and {qd_a.shape}")
        x = self._check_state(np.concatenate([q_a, qd_a]))
        tau_a = self._check_input(tau)
        mj = self._mj
        d = self._scratch
        self._write_state(d, x)
        d.xfrc_applied[:] = 0.0
        self._forward(d, tau_a, None)
        mj.mj_rnePostConstraint(self.model, d)
        x_now, a, w_body = self._read_state(d)
        # Ball centre: slides (locked) or the free joint's world linear velocity (free),
        # so qacc[0:2] is its horizontal acceleration in both variants. Body: the
        # angular part of cacc is its world angular acceleration ω̇_b.
        acc_ball = d.qacc[0:2]
        wdot = d.cacc[self._body][0:3]
        adot = np.cross(w_body, a)
        addot = np.cross(wdot, a) + np.cross(w_body, adot)
        phidd = _lean_accelerations(a, adot, addot, x_now[2:4], x_now[6:8])
        out = np.empty(4)
        out[0:2] = acc_ball / self.params.ball_radius - phidd
        out[2:4] = phidd
        return out

    # -- validation ----------------------------------------------------------------
    @staticmethod
    def _check_state(x: ArrayLike) -> FloatArray:
        x_a = np.asarray(x, dtype=float)
        if x_a.shape != (8,) or not np.all(np.isfinite(x_a)):
            raise ConfigError(f"state must be a finite array of shape (8,), got {x_a!r}")
        if abs(x_a[3]) >= 0.5 * math.pi or abs(x_a[2]) >= 0.5 * math.pi:
            raise ConfigError(f"leans must be within (-pi/2, pi/2) rad, got {x_a[2:4]!r}")
        return x_a

    @staticmethod
    def _check_input(tau: ArrayLike) -> FloatArray:
        tau_a = np.asarray(tau, dtype=float)
        if tau_a.shape != (2,) or not np.all(np.isfinite(tau_a)):
            raise ConfigError(f"tau must be a finite array of shape (2,), got {tau_a!r}")
        return tau_a
