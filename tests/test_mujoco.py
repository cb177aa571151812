"""MuJoCo plant: an independent physics cross-check of the planar and 3D models.

The models are integrated with a fixed-step RK4 at a small step and compared
with MuJoCo on physical quantities (ball centre position, body axis vector),
relative to the size of the motion. Required agreement: 0.1 % with yaw locked
(the same constrained system), 1 % with a free-yaw body.
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from gracenav import BallbotParams  # noqa: E402
from gracenav.errors import ConfigError  # noqa: E402
from gracenav.model import Ballbot3D, PlanarBallbot  # noqa: E402
from gracenav.sim.mujoco import MujocoBallbot, build_mjcf, drive_torque  # noqa: E402

TOL = {"locked": 1e-3, "free": 1e-2}
"""Required relative agreement with the model, per MuJoCo variant."""

T_END = 0.5  # s
H_MUJOCO = 1.0 / 1024.0  # s, the plant's default step
N_CHECK = 8  # comparison points along each trajectory
YAWS = ("locked", "free")


def make_params(friction: bool) -> BallbotParams:
    p = BallbotParams()
    return p if friction else p.without_friction()


def rk4(f: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, h: float, n: int) -> np.ndarray:
    """Fixed-step RK4 from x0; the states at steps 0, n/N_CHECK, ..., n, (N_CHECK+1, dim)."""
    x = np.array(x0, dtype=float)
    out = [x.copy()]
    every = n // N_CHECK
    for k in range(1, n + 1):
        k1 = f(x)
        k2 = f(x + 0.5 * h * k1)
        k3 = f(x + 0.5 * h * k2)
        k4 = f(x + h * k3)
        x = x + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        if k % every == 0:
            out.append(x.copy())
    return np.array(out)


def run_plant(
    plant: MujocoBallbot, x0: np.ndarray, tau: np.ndarray, body_force: np.ndarray | None = None
) -> np.ndarray:
    """Run the plant for T_END; the states at the points of :func:`rk4`, (N_CHECK+1, 8)."""
    plant.set_state(x0)
    n = round(T_END / plant.timestep)
    out = [plant.get_state()]
    for _ in range(N_CHECK):
        out.append(plant.step(tau, n // N_CHECK, body_force=body_force))
    assert plant.time == pytest.approx(T_END, abs=1e-12)
    return np.array(out)


def relative_error(ref_pos: np.ndarray, ref_axis: np.ndarray, x_mj: np.ndarray) -> float:
    """Max over the trajectory of the ball-position and body-axis errors, each relative to
    the largest excursion of that quantity from its start in the reference motion."""
    model = Ballbot3D()  # kinematics only: params do not matter for the axis
    p = BallbotParams()
    mj_pos = p.ball_radius * (x_mj[:, 0:2] + x_mj[:, 2:4])
    mj_axis = model.body_axis(x_mj[:, :4])
    pos_scale = np.max(np.linalg.norm(ref_pos - ref_pos[0], axis=-1))
    axis_scale = np.max(np.linalg.norm(ref_axis - ref_axis[0], axis=-1))
    e_pos = np.max(np.linalg.norm(mj_pos - ref_pos, axis=-1)) / pos_scale
    e_axis = np.max(np.linalg.norm(mj_axis - ref_axis, axis=-1)) / axis_scale
    return float(max(e_pos, e_axis))


# -- the MJCF ---------------------------------------------------------------------------
@pytest.mark.parametrize("yaw", YAWS)
def test_mjcf_masses_inertias_and_joints(yaw: str) -> None:
    p = BallbotParams()
    m = mujoco.MjModel.from_xml_string(build_mjcf(p, yaw=yaw))  # type: ignore[arg-type]
    total = p.ball_mass + p.body_mass
    assert float(np.sum(m.body_mass)) == pytest.approx(total, rel=1e-14)
    body = m.body("body").id
    np.testing.assert_allclose(
        m.body_inertia[body], [p.body_inertia_x, p.body_inertia_y, p.body_inertia_z], rtol=1e-14
    )
    np.testing.assert_allclose(m.body_ipos[body], [0.0, 0.0, p.body_com_height], atol=1e-14)
    np.testing.assert_allclose(m.body_inertia[m.body("ball").id], [p.ball_inertia] * 3, rtol=1e-14)
    np.testing.assert_allclose(m.opt.gravity, [0.0, 0.0, -p.gravity], rtol=1e-14)
    # no rolling friction; sliding and torsional friction high
    floor = m.geom("floor").id
    assert m.geom_condim[floor] == 4
    assert m.geom_friction[floor][2] == 0.0
    assert m.geom_friction[floor][0] >= 1.0
    # locked: 3 slides + ball joint + 2 hinges (no yaw); free: free joint + ball joint
    assert m.nv == (8 if yaw == "locked" else 9)


def test_invalid_options_raise_config_error() -> None:
    with pytest.raises(ConfigError, match="yaw must be 'locked' or 'free'"):
        build_mjcf(BallbotParams(), yaw="sideways")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="timestep must be a positive"):
        MujocoBallbot(timestep=0.0)
    plant = MujocoBallbot()
    with pytest.raises(ConfigError, match=r"tau must be a finite array of shape \(2,\)"):
        plant.step([1.0, 2.0, 3.0])
    with pytest.raises(ConfigError, match=r"state must be a finite array of shape \(8,\)"):
        plant.set_state(np.zeros(4))
    with pytest.raises(ConfigError, match="body_force"):
        plant.step([0.0, 0.0], body_force=[1.0, 0.0])


def test_missing_mujoco_says_how_to_install(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "mujoco", None)  # makes `import mujoco` fail
    with pytest.raises(ConfigError, match=r"pip install gracenav\[mujoco\]"):
        MujocoBallbot()


def test_package_imports_without_mujoco() -> None:
    code = (
        "import sys; sys.modules['mujoco'] = None\n"
        "import gracenav, gracenav.sim.mujoco as mp\n"
        "assert '<mujoco' in mp.build_mjcf(gracenav.BallbotParams())\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)


# -- state map and the physical meaning of the inputs --------------------------------------
def random_states(n: int, seed: int) -> np.ndarray:
    """States with ball angles up to 1 rad, leans up to 10 deg, rates up to 1 rad/s, (n, 8)."""
    rng = np.random.default_rng(seed)
    lean = np.deg2rad(10.0)
    return np.concatenate(
        [rng.uniform(-1, 1, (n, 2)), rng.uniform(-lean, lean, (n, 2)), rng.uniform(-1, 1, (n, 4))],
        axis=1,
    )


@pytest.mark.parametrize("yaw", YAWS)
def test_state_round_trip_and_kinematics(yaw: str) -> None:
    p = BallbotParams()
    plant = MujocoBallbot(p, yaw=yaw)  # type: ignore[arg-type]
    model = Ballbot3D(p)
    for x in random_states(10, seed=3):
        plant.set_state(x)
        np.testing.assert_allclose(plant.get_state(), x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(plant.ball_position(), model.ball_position(x[:4]), atol=1e-14)
        np.testing.assert_allclose(plant.body_axis(), model.body_axis(x[:4]), atol=1e-14)
        com = plant.data.xipos[plant.model.body("body").id]
        # the ball is set 1 nm into the floor
        np.testing.assert_allclose(com, model.com_position(x[:4]), atol=2e-9)


def velocity_map(plant: MujocoBallbot, q: np.ndarray) -> np.ndarray:
    """G(q), (nv, 4): MuJoCo's qvel for unit model rates (set_state is linear in q̇)."""
    cols = []
    for j in range(4):
        x = np.concatenate([q, np.eye(4)[j]])
        plant.set_state(x)
        cols.append(plant.data.qvel.copy())
    return np.array(cols).T


def generalised_force(plant: MujocoBallbot, wrenches: dict[str, np.ndarray]) -> np.ndarray:
    """MuJoCo generalised force (nv,) of world wrenches [force, torque] at each body's COM."""
    m, d = plant.model, plant.data
    qfrc = np.zeros(m.nv)
    for name, w in wrenches.items():
        b = m.body(name).id
        mujoco.mj_applyFT(m, d, w[:3].copy(), w[3:].copy(), d.xipos[b].copy(), b, qfrc)
    return qfrc


@pytest.mark.parametrize("yaw", YAWS)
def test_drive_torque_is_the_generalised_input(yaw: str) -> None:
    """Gᵀ Jᵀ (τ_w on ball, −τ_w on body) = [τ_x, τ_y, 0, 0] for rolling without slip or spin."""
    p = BallbotParams()
    plant = MujocoBallbot(p, yaw=yaw)  # type: ignore[arg-type]
    rng = np.random.default_rng(5)
    for x in random_states(10, seed=4):
        q = x[:4]
        tau = rng.uniform(-40, 40, 2)
        g = velocity_map(plant, q)
        plant.set_state(np.concatenate([q, np.zeros(4)]))
        tw = drive_torque(tau, q[2])
        qfrc = generalised_force(plant, {"ball": np.r_[0, 0, 0, tw], "body": np.r_[0, 0, 0, -tw]})
        np.testing.assert_allclose(g.T @ qfrc, [tau[0], tau[1], 0.0, 0.0], rtol=0, atol=1e-12)
        # without the vertical component the torque would load the lean equations
        tw_flat = tw * np.array([1.0, 1.0, 0.0])
        qfrc = generalised_force(
            plant, {"ball": np.r_[0, 0, 0, tw_flat], "body": np.r_[0, 0, 0, -tw_flat]}
        )
        lean_load = (g.T @ qfrc)[2:]
        want = -tw[2] * np.array([0.0, -np.sin(q[2])])  # ω_b,z = φ̇_y sin φ_x
        np.testing.assert_allclose(lean_load, want, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("yaw", YAWS)
def test_body_force_is_the_com_jacobian_transpose(yaw: str) -> None:
    p = BallbotParams()
    plant = MujocoBallbot(p, yaw=yaw)  # type: ignore[arg-type]
    model = Ballbot3D(p)
    rng = np.random.default_rng(6)
    for x in random_states(10, seed=7):
        q = x[:4]
        force = rng.uniform(-50, 50, 3)
        g = velocity_map(plant, q)
        plant.set_state(np.concatenate([q, np.zeros(4)]))
        qfrc = generalised_force(plant, {"body": np.r_[force, 0, 0, 0]})
        want = model.com_jacobian(q).T @ force
        np.testing.assert_allclose(g.T @ qfrc, want, rtol=1e-12, atol=1e-10)


# -- trajectories against the planar model ---------------------------------------------------
PLANAR_CASES = {
    # name: (initial lean (rad), torque (N m)) -- constant torques small enough that the ball
    # stays on the floor for 0.5 s (larger ones throw the robot into the air, which neither
    # model describes)
    "passive fall": (0.05, 0.0),
    "constant torque": (0.0, 8.0),
}


@pytest.mark.parametrize("friction", [False, True], ids=["no friction", "friction"])
@pytest.mark.parametrize("yaw", YAWS)
@pytest.mark.parametrize("plane", ["x", "y"])
@pytest.mark.parametrize("case", list(PLANAR_CASES))
def test_planar_motion_matches_planar_model(
    case: str, plane: str, yaw: str, friction: bool
) -> None:
    p = make_params(friction)
    lean, torque = PLANAR_CASES[case]
    planar = PlanarBallbot(p, plane=plane)  # type: ignore[arg-type]

    def f(xp: np.ndarray) -> np.ndarray:
        return np.concatenate([xp[2:], planar.accelerations(xp[:2], xp[2:], torque)])

    h = 1.0 / 4096.0
    ref = rk4(f, np.array([0.0, lean, 0.0, 0.0]), h, round(T_END / h))
    i = 0 if plane == "x" else 1
    # the planar trajectory embedded in 3D
    ref_pos = np.zeros((len(ref), 2))
    ref_pos[:, i] = planar.ball_position(ref[:, :2])
    ref_axis = np.zeros((len(ref), 3))
    ref_axis[:, i] = np.sin(ref[:, 1])
    ref_axis[:, 2] = np.cos(ref[:, 1])

    x0 = np.zeros(8)
    x0[2 + i] = lean
    tau = np.zeros(2)
    tau[i] = torque
    got = run_plant(MujocoBallbot(p, yaw=yaw), x0, tau)  # type: ignore[arg-type]
    assert relative_error(ref_pos, ref_axis, got) < TOL[yaw]
    # the other plane stays at rest
    np.testing.assert_allclose(got[:, [1 - i, 3 - i, 5 - i, 7 - i]], 0.0, atol=1e-9)


# -- 3D motion against Ballbot3D -------------------------------------------------------------
def model_rhs(
    model: Ballbot3D, tau: np.ndarray, body_force: np.ndarray | None = None
) -> Callable[[np.ndarray], np.ndarray]:
    """x' = f(x) of the 3D model with constant τ (and a constant world force at the COM)."""

    def f(x: np.ndarray) -> np.ndarray:
        q, qd = x[:4], x[4:]
        if body_force is None:
            qdd = model.accelerations(q, qd, tau)
        else:
            rhs = -model.bias(q, qd) + model.com_jacobian(q).T @ body_force
            rhs[:2] += tau - model.friction(qd)
            qdd = np.linalg.solve(model.mass_matrix(q), rhs)
        return np.concatenate([qd, qdd])

    return f


X0_3D = np.array([0.1, -0.2, 0.06, -0.04, 0.5, -0.3, 0.3, 0.4])
TAU_3D = np.array([4.0, -6.0])


def compare_3d(
    params: BallbotParams, yaw: str, body_force: np.ndarray | None = None
) -> tuple[float, np.ndarray]:
    model = Ballbot3D(params)
    h = 1.0 / 2048.0
    ref = rk4(model_rhs(model, TAU_3D, body_force), X0_3D, h, round(T_END / h))
    plant = MujocoBallbot(params, yaw=yaw)  # type: ignore[arg-type]
    got = run_plant(plant, X0_3D, TAU_3D, body_force)
    err = relative_error(model.ball_position(ref[:, :4]), model.body_axis(ref[:, :4]), got)
    # the ball's spin about the vertical, relative to its rolling rate
    w_ball = np.zeros(6)
    mujoco.mj_objectVelocity(
        plant.model, plant.data, mujoco.mjtObj.mjOBJ_BODY, plant.model.body("ball").id, w_ball, 0
    )
    return err, w_ball[:3]


@pytest.mark.parametrize("friction", [False, True], ids=["no friction", "friction"])
@pytest.mark.parametrize("yaw", YAWS)
def test_3d_motion_matches_ballbot3d(yaw: str, friction: bool) -> None:
    """Lean in both planes with rates in all coordinates and a torque on both axes."""
    err, w_ball = compare_3d(make_params(friction), yaw)
    assert err < TOL[yaw]
    # no spin about the vertical (torsional contact friction takes τ_w,z)
    assert abs(w_ball[2]) < 1e-3 * np.linalg.norm(w_ball[:2])


def test_3d_motion_with_body_force_matches_ballbot3d() -> None:
    err, _ = compare_3d(BallbotParams(), "locked", body_force=np.array([30.0, -20.0, 10.0]))
    assert err < TOL["locked"]


# -- instantaneous accelerations -------------------------------------------------------------
@pytest.mark.parametrize("friction", [False, True], ids=["no friction", "friction"])
@pytest.mark.parametrize("yaw", YAWS)
def test_accelerations_match_ballbot3d(yaw: str, friction: bool) -> None:
    p = make_params(friction)
    model = Ballbot3D(p)
    plant = MujocoBallbot(p, yaw=yaw)  # type: ignore[arg-type]
    plant.set_state(X0_3D)
    before = plant.get_state()
    states = random_states(20, seed=11)
    taus = np.random.default_rng(12).uniform(-30, 30, (20, 2))
    want = model.accelerations(states[:, :4], states[:, 4:], taus)
    for x, tau, w in zip(states, taus, want, strict=True):
        got = plant.accelerations(x[:4], x[4:], tau)
        assert np.max(np.abs(got - w)) < TOL[yaw] * np.max(np.abs(w))
    # the simulation state is not touched
    np.testing.assert_array_equal(plant.get_state(), before)


@pytest.mark.parametrize("plane", ["x", "y"])
def test_planar_accelerations_match_planar_model(plane: str) -> None:
    p = BallbotParams()
    planar = PlanarBallbot(p, plane=plane)  # type: ignore[arg-type]
    plant = MujocoBallbot(p)
    rng = np.random.default_rng(13)
    i = 0 if plane == "x" else 1
    for _ in range(10):
        qp = np.array([rng.uniform(-1, 1), rng.uniform(-0.17, 0.17)])
        qdp = rng.uniform(-1, 1, 2)
        tau_p = rng.uniform(-30, 30)
        q, qd, tau = np.zeros(4), np.zeros(4), np.zeros(2)
        q[[i, 2 + i]] = qp
        qd[[i, 2 + i]] = qdp
        tau[i] = tau_p
        got = plant.accelerations(q, qd, tau)
        want = planar.accelerations(qp, qdp, tau_p)
        assert np.max(np.abs(got[[i, 2 + i]] - want)) < TOL["locked"] * np.max(np.abs(want))
        np.testing.assert_allclose(got[[1 - i, 3 - i]], 0.0, atol=1e-9)


def test_locked_passive_motion_conserves_the_model_energy() -> None:
    """Without friction or input, Ballbot3D's energy along the MuJoCo motion is constant."""
    p = BallbotParams().without_friction()
    model = Ballbot3D(p)
    plant = MujocoBallbot(p)
    plant.set_state(X0_3D)
    e0 = model.energy(X0_3D[:4], X0_3D[4:])
    scale = p.body_mass * p.gravity * p.body_com_height  # J
    for _ in range(16):
        x = plant.step([0.0, 0.0], 32)
        assert abs(model.energy(x[:4], x[4:]) - e0) < 1e-6 * scale
