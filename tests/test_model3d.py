"""3D model: generated code, reduction to the planar model, linearisation, energy,
power balance, Jacobians, Newton-Euler (Kane) and MuJoCo cross-checks, drive torque, numba."""

from __future__ import annotations

import ast
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numba
import numpy as np
import pytest

from gracenav import BallbotParams, _kernels
from gracenav.model import Ballbot3D, PlanarBallbot
from gracenav.model import _ballbot3d_generated as gen
from gracenav.model.friction import friction_constants, friction_torque

ROOT = Path(__file__).resolve().parents[1]
PARAMS = BallbotParams()
MODEL = Ballbot3D(PARAMS)
C = MODEL.constants()
H_CS = 1e-20  # complex-step size

# Rows/columns of each plane in q (4,) and in the state x = [q, q̇] (8,).
PLANE_Q = {"x": [0, 2], "y": [1, 3]}
PLANE_X = {"x": [0, 2, 4, 6], "y": [1, 3, 5, 7]}


def random_states(rng: np.random.Generator, n: int, lean: float = 0.6) -> tuple[Any, Any]:
    """Random configurations (n, 4) and velocities (n, 4), leans up to ``lean`` rad."""
    q = np.concatenate([rng.uniform(-3, 3, (n, 2)), rng.uniform(-lean, lean, (n, 2))], axis=1)
    qd = rng.uniform(-2.0, 2.0, (n, 4))
    return q, qd


# --- independent world-frame kinematics straight from docs/design/conventions.md ------------------
def rot_x(a: Any) -> Any:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a: Any) -> Any:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rotation(q: Any) -> Any:
    """Body orientation R = R_y(φ_x) R_x(−φ_y)."""
    return rot_y(q[2]) @ rot_x(-q[3])


def ball_centre(q: Any) -> Any:
    r = PARAMS.ball_radius
    return np.array([r * (q[0] + q[2]), r * (q[1] + q[3]), r + 0 * q[0]])


def body_com(q: Any) -> Any:
    return ball_centre(q) + PARAMS.body_com_height * rotation(q)[:, 2]


def velocities(q: np.ndarray, qd: np.ndarray) -> dict[str, np.ndarray]:
    """World-frame velocities of ball and body, by complex-step differentiation of positions
    and of R along q̇ (exact to rounding); ω from the skew matrix Ṙ Rᵀ."""
    qc = q + 1j * H_CS * qd
    v_w = ball_centre(qc).imag / H_CS
    v_c = body_com(qc).imag / H_CS
    rdot = rotation(qc).imag / H_CS
    omega = rdot @ rotation(q).T
    r = PARAMS.ball_radius
    return {
        "v_w": v_w,
        "w_w": np.array([-v_w[1] / r, v_w[0] / r, 0.0]),  # rolling, no spin
        "v_c": v_c,
        "w_b": np.array([omega[2, 1], omega[0, 2], omega[1, 0]]),
    }


def kinetic_energy(q: np.ndarray, qd: np.ndarray) -> float:
    p = PARAMS
    v = velocities(q, qd)
    rot = rotation(q)
    inertia = rot @ np.diag([p.body_inertia_x, p.body_inertia_y, p.body_inertia_z]) @ rot.T
    return 0.5 * float(
        p.ball_mass * v["v_w"] @ v["v_w"]
        + p.ball_inertia * v["w_w"] @ v["w_w"]
        + p.body_mass * v["v_c"] @ v["v_c"]
        + v["w_b"] @ inertia @ v["w_b"]
    )


# --- (a) generated code --------------------------------------------------------------
@pytest.mark.slow
def test_generated_module_is_up_to_date(tmp_path: Path) -> None:
    pytest.importorskip("sympy")
    out = tmp_path / "gen.py"
    subprocess.run(
        [sys.executable, str(ROOT / "tools/derive_ballbot3d.py"), "--out", str(out)],
        check=True,
        capture_output=True,
        timeout=120,
    )
    committed = (ROOT / "src/gracenav/model/_ballbot3d_generated.py").read_text()
    assert out.read_text() == committed, "run `python tools/derive_ballbot3d.py` and commit"


def test_generated_code_uses_only_numpy_arithmetic() -> None:
    """Only scalar arithmetic, np.sin/cos/tan and indexing of the arguments (numba and
    numpy batch both need this): no array construction, no sympy, no other calls."""
    tree = ast.parse((ROOT / "src/gracenav/model/_ballbot3d_generated.py").read_text())
    functions = [f for f in tree.body if isinstance(f, ast.FunctionDef)]
    assert sorted(f.name for f in functions) == sorted(gen.__all__)
    allowed = (
        ast.Assign, ast.Return, ast.Expr, ast.Name, ast.Constant, ast.BinOp, ast.UnaryOp,
        ast.operator, ast.unaryop, ast.expr_context, ast.Call, ast.Attribute, ast.Subscript,
        ast.Tuple,
    )  # fmt: skip
    for func in functions:
        for stmt in func.body:
            for node in ast.walk(stmt):
                assert isinstance(node, allowed), (func.name, ast.dump(node))
                if isinstance(node, ast.Call):
                    assert ast.unparse(node.func) in {"np.sin", "np.cos", "np.tan"}
                if isinstance(node, ast.Subscript):
                    assert ast.unparse(node.value) in {"c", "q", "qd", "out"}
                    index = node.slice.elts if isinstance(node.slice, ast.Tuple) else [node.slice]
                    assert all(isinstance(i, ast.Constant) for i in index)
                if isinstance(node, ast.Tuple):
                    assert any(
                        isinstance(s, ast.Subscript) and s.slice is node for s in ast.walk(stmt)
                    )


# --- (b) reduction to the planar model -------------------------------------------------
@pytest.mark.parametrize("plane", ["x", "y"])
def test_motion_in_one_plane_is_the_planar_model(plane: str) -> None:
    rng = np.random.default_rng(11)
    n = 200
    on, off = PLANE_Q[plane], PLANE_Q["y" if plane == "x" else "x"]
    q2, qd2 = random_states(rng, n)
    q2, qd2 = q2[:, [0, 2]], qd2[:, [0, 2]] * 3.0  # up to 6 rad/s, beyond the 5 cm/s
    tau1 = rng.uniform(-60, 60, n)  # friction smoothing, so both tanh regimes occur
    q = np.zeros((n, 4))
    qd = np.zeros((n, 4))
    tau = np.zeros((n, 2))
    q[:, on], qd[:, on] = q2, qd2
    tau[:, 0 if plane == "x" else 1] = tau1
    planar = PlanarBallbot(PARAMS, plane=plane)  # type: ignore[arg-type]

    acc = MODEL.accelerations(q, qd, tau)
    want = planar.accelerations(q2, qd2, tau1)
    np.testing.assert_allclose(acc[:, on], want, rtol=1e-10, atol=1e-10 * np.abs(want).max())
    assert np.all(acc[:, off] == 0.0)
    np.testing.assert_allclose(
        MODEL.mass_matrix(q)[:, on][:, :, on], planar.mass_matrix(q2), rtol=1e-14, atol=0
    )
    np.testing.assert_allclose(MODEL.energy(q, qd), planar.energy(q2, qd2), rtol=1e-13)
    np.testing.assert_array_equal(
        MODEL.friction(qd)[:, 0 if plane == "x" else 1], planar.friction(qd2)
    )
    np.testing.assert_allclose(
        MODEL.ball_position(q)[:, 0 if plane == "x" else 1], planar.ball_position(q2), rtol=1e-15
    )


# --- (c) linearisation -----------------------------------------------------------------
@pytest.mark.parametrize("viscous", [False, True])
def test_linearization_is_two_decoupled_planar_models(viscous: bool) -> None:
    a, b = MODEL.linearize(viscous=viscous)
    assert a.shape == (8, 8) and b.shape == (8, 2)
    want_a = np.zeros((8, 8))
    want_b = np.zeros((8, 2))
    for k, plane in enumerate(("x", "y")):
        pa, pb = PlanarBallbot(PARAMS, plane=plane).linearize(viscous=viscous)  # type: ignore[arg-type]
        idx = PLANE_X[plane]
        want_a[np.ix_(idx, idx)] = pa
        want_b[idx, k] = pb[:, 0]
    np.testing.assert_allclose(a, want_a, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(b, want_b, rtol=1e-12, atol=1e-12)


def test_linearization_matches_finite_differences_of_the_nonlinear_model() -> None:
    """A and B by central differences of q̈(q, q̇, τ) at upright (Coulomb friction off)."""
    model = Ballbot3D(BallbotParams(coulomb_friction=0.0))
    a, b = model.linearize(viscous=True)
    eps = 1e-6
    x0 = np.zeros(8)
    for j in range(8):
        dx = np.zeros(8)
        dx[j] = eps
        xp, xm = x0 + dx, x0 - dx
        col = (
            model.accelerations(xp[:4], xp[4:], np.zeros(2))
            - model.accelerations(xm[:4], xm[4:], np.zeros(2))
        ) / (2 * eps)
        np.testing.assert_allclose(a[4:, j], col, rtol=1e-7, atol=1e-7)
    for j in range(2):
        du = np.zeros(2)
        du[j] = eps
        col = model.accelerations(x0[:4], x0[4:], du) - model.accelerations(x0[:4], x0[4:], -du)
        np.testing.assert_allclose(b[4:, j], col / (2 * eps), rtol=1e-7, atol=1e-9)


def test_open_loop_eigenvalues() -> None:
    a, _ = MODEL.linearize()
    eig = np.linalg.eigvals(a)
    np.testing.assert_allclose(eig.imag, 0.0, atol=1e-9)
    np.testing.assert_allclose(
        np.sort(eig.real), [-4.955, -4.935, 0, 0, 0, 0, 4.935, 4.955], atol=5e-4
    )
    # Closed form per plane, λ² = (β g / r_w) α / det M(0), with that plane's body inertia.
    lams = []
    for plane in ("x", "y"):
        pm = PlanarBallbot(PARAMS, plane=plane)  # type: ignore[arg-type]
        det = pm.alpha * (pm.alpha + pm.gamma + 2 * pm.beta) - (pm.alpha + pm.beta) ** 2
        lams.append(np.sqrt(pm.beta * PARAMS.gravity / PARAMS.ball_radius * pm.alpha / det))
    np.testing.assert_allclose(np.sort(eig.real)[-2:], sorted(lams), rtol=1e-12)
    assert lams[0] == pytest.approx(4.955, abs=5e-4)  # x plane: I_yy = 12.48
    assert lams[1] == pytest.approx(4.935, abs=5e-4)  # y plane: I_xx = 12.59


# --- (d) energy conservation (compiled RK4 loop) -----------------------------------------
@pytest.fixture(scope="module")
def compiled() -> dict[str, Callable[..., Any]]:
    return {
        name: numba.njit(getattr(gen, name))
        for name in ("mass_matrix", "bias", "energy", "com_position", "com_jacobian")
    }


def make_rk4(mass_matrix: Callable[..., Any], bias: Callable[..., Any]) -> Callable[..., Any]:
    @numba.njit
    def deriv(c, x, m, h, out):  # type: ignore[no-untyped-def]
        mass_matrix(c, x[:4], m)
        bias(c, x[:4], x[4:], h)
        out[:4] = x[4:]
        # Gaussian elimination without pivoting (M is SPD); faster to compile than LAPACK.
        for j in range(4):
            for i in range(j + 1, 4):
                f = m[i, j] / m[j, j]
                m[i, j:] -= f * m[j, j:]
                h[i] -= f * h[j]
        for i in range(3, -1, -1):
            s = -h[i]
            for k in range(i + 1, 4):
                s -= m[i, k] * out[4 + k]
            out[4 + i] = s / m[i, i]

    @numba.njit
    def rk4(c, x0, dt, steps):  # type: ignore[no-untyped-def]
        xs = np.empty((steps + 1, 8))
        xs[0] = x0
        m = np.empty((4, 4))
        h = np.empty(4)
        k1, k2, k3, k4 = np.empty(8), np.empty(8), np.empty(8), np.empty(8)
        x = x0.copy()
        for n in range(steps):
            deriv(c, x, m, h, k1)
            deriv(c, x + 0.5 * dt * k1, m, h, k2)
            deriv(c, x + 0.5 * dt * k2, m, h, k3)
            deriv(c, x + dt * k3, m, h, k4)
            x = x + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
            xs[n + 1] = x
        return xs

    return rk4  # type: ignore[no-any-return]


@pytest.mark.slow
def test_energy_conserved_without_friction_and_input(compiled: dict[str, Any]) -> None:
    rk4 = make_rk4(compiled["mass_matrix"], compiled["bias"])
    x0 = np.array([0.3, -0.2, 0.15, -0.1, 0.5, -0.3, 0.4, 0.6])  # leaning and turning
    xs = rk4(C, x0, 1.0 / 4096, 10 * 4096)
    e = MODEL.energy(xs[:, :4], xs[:, 4:])
    assert np.max(np.abs(e - e[0])) / abs(e[0]) < 1e-6
    # Genuinely 3D: it falls over diagonally and both leans go beyond 1 rad (the model has
    # no floor for the body, which swings on as a pendulum).
    assert np.max(np.abs(xs[:, 2])) > 1.0 and np.max(np.abs(xs[:, 3])) > 1.0
    # The planar motions are coupled: the mixed Coriolis terms matter.
    x_plane_only = x0.copy()
    x_plane_only[[1, 3, 5, 7]] = 0.0
    solo = rk4(C, x_plane_only, 1.0 / 4096, 4096)
    assert np.max(np.abs(solo[:, [1, 3, 5, 7]])) == 0.0
    assert np.max(np.abs(solo[-1, [0, 2]] - xs[4096, [0, 2]])) > 0.01


# --- (e) power balance ---------------------------------------------------------------------
def test_power_balance_with_friction_and_input() -> None:
    """d/dt (T + V) = τ·θ̇ − D·θ̇ along the dynamics, dE/dt by complex step (exact)."""
    rng = np.random.default_rng(5)
    q, qd = random_states(rng, 300, lean=1.2)
    tau = rng.uniform(-60, 60, (300, 2))
    qdd = MODEL.accelerations(q, qd, tau)
    e = gen.energy(C, (q + 1j * H_CS * qd).T, (qd + 1j * H_CS * qdd).T)
    de_dt = e.imag / H_CS
    input_power = np.sum(tau * qd[:, :2], axis=1)
    friction_power = np.sum(MODEL.friction(qd) * qd[:, :2], axis=1)
    scale = np.abs(input_power) + np.abs(friction_power)
    assert np.all(np.abs(de_dt - (input_power - friction_power)) <= 1e-9 * scale)


# --- (f) Jacobians, mass matrix, and an independent check of the equations -----------------
def test_com_jacobian_is_derivative_of_com_position() -> None:
    rng = np.random.default_rng(2)
    q, _ = random_states(rng, 50, lean=1.5)
    jac = MODEL.com_jacobian(q)
    h = 1e-6
    for k in range(4):
        dq = np.zeros(4)
        dq[k] = h
        fd = (MODEL.com_position(q + dq) - MODEL.com_position(q - dq)) / (2 * h)
        np.testing.assert_allclose(jac[..., k], fd, rtol=1e-6, atol=1e-9)
    # And the kinematics themselves, from R = R_y(φ_x) R_x(−φ_y).
    for qi in q[:5]:
        np.testing.assert_allclose(MODEL.com_position(qi), body_com(qi), rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose(MODEL.body_axis(qi), rotation(qi)[:, 2], atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(MODEL.body_axis(q), axis=-1), 1.0, rtol=1e-15)
    np.testing.assert_allclose(
        MODEL.com_position(q),
        np.concatenate([MODEL.ball_position(q), np.full((50, 1), PARAMS.ball_radius)], axis=1)
        + PARAMS.body_com_height * MODEL.body_axis(q),
        rtol=1e-14,
        atol=1e-15,
    )


def test_mass_matrix_is_spd_hessian_of_kinetic_energy() -> None:
    rng = np.random.default_rng(3)
    q, qd = random_states(rng, 40, lean=3.0)
    m = MODEL.mass_matrix(q)
    np.testing.assert_array_equal(m, np.swapaxes(m, -1, -2))
    assert np.all(np.linalg.eigvalsh(m) > 1e-3)
    # Energy is quadratic in q̇, so a central second difference with a unit step is exact.
    hess = np.empty_like(m)
    eye = np.eye(4)
    for i in range(4):
        for j in range(4):
            ei, ej = eye[i], eye[j]
            hess[:, i, j] = (
                MODEL.energy(q, qd + ei + ej)
                - MODEL.energy(q, qd + ei - ej)
                - MODEL.energy(q, qd - ei + ej)
                + MODEL.energy(q, qd - ei - ej)
            ) / 4.0
    np.testing.assert_allclose(hess, m, rtol=1e-9, atol=1e-9 * np.abs(m).max())


def test_kinetic_energy_matches_world_frame_kinematics() -> None:
    """T from the documented conventions (R, ball rolling without spin), independently of sympy."""
    rng = np.random.default_rng(4)
    q, qd = random_states(rng, 30, lean=1.5)
    height = np.array([body_com(qi)[2] - PARAMS.ball_radius for qi in q])
    t = MODEL.energy(q, qd) - PARAMS.body_mass * PARAMS.gravity * height
    want = np.array([kinetic_energy(qi, qdi) for qi, qdi in zip(q, qd, strict=True)])
    np.testing.assert_allclose(t, want, rtol=1e-12)


def test_bias_from_christoffel_symbols_of_the_mass_matrix() -> None:
    """h_i = Σ (∂M_ij/∂q_k − ½ ∂M_jk/∂q_i) q̇_j q̇_k + ∂V/∂q_i, derivatives by complex step."""
    rng = np.random.default_rng(6)
    n = 50
    q, qd = random_states(rng, n, lean=1.5)
    dm = np.empty((4, 4, 4, n))  # [k, i, j, sample] = ∂M_ij/∂q_k
    dv = np.empty((4, n))
    for k in range(4):
        qc = q.T.astype(complex)
        qc[k] += 1j * H_CS
        out = np.empty((4, 4, n), dtype=complex)
        gen.mass_matrix(C, qc, out)
        dm[k] = out.imag / H_CS
        dv[k] = gen.energy(C, qc, np.zeros((4, n))).imag / H_CS
    w = qd.T
    h = np.einsum("kijn,jn,kn->in", dm, w, w) - 0.5 * np.einsum("ijkn,jn,kn->in", dm, w, w) + dv
    np.testing.assert_allclose(MODEL.bias(q, qd), h.T, rtol=1e-10, atol=1e-10 * np.abs(h).max())


def test_kane_equations_from_world_frame_kinematics() -> None:
    """Newton-Euler projected on the partial velocities (Kane), valid for the nonholonomic
    rolling-without-spin ball: F_r + F*_r = 0 with the model's accelerations."""
    p = PARAMS
    rng = np.random.default_rng(8)
    q, qd = random_states(rng, 20, lean=1.2)
    tau = rng.uniform(-60, 60, (20, 2))
    qdd = MODEL.accelerations(q, qd, tau)
    fric = MODEL.friction(qd)
    s = 1e-3
    for qi, qdi, qddi, ti, di in zip(q, qd, qdd, tau, fric, strict=True):
        # Accelerations: d/dt of the velocities along (q̇, q̈), 4th-order central differences.
        vs = [velocities(qi + k * s * qdi, qdi + k * s * qddi) for k in (-2, -1, 1, 2)]
        acc = {
            key: (vs[0][key] - 8 * vs[1][key] + 8 * vs[2][key] - vs[3][key]) / (12 * s)
            for key in vs[0]
        }
        v = velocities(qi, qdi)
        rot = rotation(qi)
        inertia = rot @ np.diag([p.body_inertia_x, p.body_inertia_y, p.body_inertia_z]) @ rot.T
        body_moment = inertia @ acc["w_b"] + np.cross(v["w_b"], inertia @ v["w_b"])
        residual = np.empty(4)
        scale = np.empty(4)
        for r in range(4):
            part = velocities(qi, np.eye(4)[r])  # partial velocities (velocities are linear)
            terms = [
                -p.ball_mass * acc["v_w"] @ part["v_w"],
                -p.ball_inertia * acc["w_w"] @ part["w_w"],
                -p.body_mass * acc["v_c"] @ part["v_c"],
                -body_moment @ part["w_b"],
                -p.body_mass * p.gravity * part["v_c"][2],
                (ti[r] - di[r]) if r < 2 else 0.0,
            ]
            residual[r] = sum(terms)
            scale[r] = sum(abs(t) for t in terms)
        assert np.all(np.abs(residual) <= 1e-8 * scale), (residual, scale)


# --- (g) the physical drive torque ------------------------------------------------------
def test_drive_torque_power_identity() -> None:
    """τ_w = (−τ_y, τ_x, τ_y tan(φ_x/2)) on the ball (reaction on the body) has power
    τ_w·(ω_w − ω_b) = τ_x θ̇_x + τ_y θ̇_y for all rates (docs/design/conventions.md)."""
    rng = np.random.default_rng(9)
    q, qd = random_states(rng, 100, lean=1.5)
    tau = rng.uniform(-60, 60, (100, 2))
    for qi, qdi, (tx, ty) in zip(q, qd, tau, strict=True):
        tau_w = np.array([-ty, tx, ty * np.tan(qi[2] / 2)])
        v = velocities(qi, qdi)
        power = tau_w @ (v["w_w"] - v["w_b"])
        want = tx * qdi[0] + ty * qdi[1]
        assert power == pytest.approx(want, rel=1e-12, abs=1e-12 * np.abs(tau_w).sum())
        # Equivalently, its generalised forces are [τ_x, τ_y, 0, 0].
        gen_force = [tau_w @ (lambda p: p["w_w"] - p["w_b"])(velocities(qi, e)) for e in np.eye(4)]
        np.testing.assert_allclose(gen_force, [tx, ty, 0, 0], atol=1e-12 * np.abs(tau_w).sum())
    # Without the vertical component the φ_y equation would see the input.
    qi = np.array([0.0, 0.0, 0.3, 0.0])
    v = velocities(qi, np.eye(4)[3])
    assert abs(np.array([-1.0, 0.0, 0.0]) @ (v["w_w"] - v["w_b"])) > 0.01


# --- (h) numba and numpy agree -------------------------------------------------------------
def test_numba_compiled_functions_agree_with_numpy_batch(compiled: dict[str, Any]) -> None:
    rng = np.random.default_rng(10)
    n = 25
    q, qd = random_states(rng, n, lean=1.5)
    qb, qdb = np.ascontiguousarray(q.T), np.ascontiguousarray(qd.T)
    shapes = {"mass_matrix": (4, 4), "bias": (4,), "com_position": (3,), "com_jacobian": (3, 4)}
    for name, shape in shapes.items():
        args_b = (C, qb, qdb) if name == "bias" else (C, qb)
        batch = np.empty((*shape, n))
        getattr(gen, name)(*args_b, batch)
        for k in range(n):
            args = (C, q[k], qd[k]) if name == "bias" else (C, q[k])
            single = np.empty(shape)
            compiled[name](*args, single)
            np.testing.assert_allclose(single, batch[..., k], rtol=1e-13, atol=1e-13, err_msg=name)
    e_batch = gen.energy(C, qb, qdb)
    e_single = np.array([compiled["energy"](C, q[k], qd[k]) for k in range(n)])
    np.testing.assert_allclose(e_single, e_batch, rtol=1e-13)


def test_one_friction_law_for_models_and_kernels() -> None:
    """D_c tanh(θ̇/ε) + D_v θ̇ in that order, from gracenav.model.friction: the models'
    numpy friction and the kernels' compiled one."""
    p = BallbotParams(coulomb_friction=2.5, viscous_friction=1.5, friction_smoothing=0.02)
    fr = friction_constants(p)
    np.testing.assert_array_equal(fr, [2.5, 1.5, 0.02])
    thd = np.random.default_rng(3).uniform(-2.0, 2.0, (40, 2))
    want = p.coulomb_friction * np.tanh(thd / p.friction_smoothing) + p.viscous_friction * thd
    np.testing.assert_array_equal(friction_torque(fr, thd), want)
    qd = np.concatenate([thd, np.zeros((40, 2))], axis=1)
    np.testing.assert_array_equal(Ballbot3D(p).friction(qd), want)
    np.testing.assert_array_equal(PlanarBallbot(p, "y").friction(qd[:, 1::2]), want[:, 1])
    compiled = np.array([[_kernels.friction(fr, v) for v in row] for row in thd])
    np.testing.assert_allclose(compiled, want, rtol=1e-15, atol=1e-15)


def test_class_methods_accept_any_leading_shape() -> None:
    rng = np.random.default_rng(12)
    q, qd = random_states(rng, 6)
    q, qd = q.reshape(2, 3, 4), qd.reshape(2, 3, 4)
    tau = rng.uniform(-10, 10, (2, 3, 2))
    acc = MODEL.accelerations(q, qd, tau)
    assert acc.shape == (2, 3, 4)
    assert MODEL.mass_matrix(q).shape == (2, 3, 4, 4)
    assert MODEL.com_jacobian(q).shape == (2, 3, 3, 4)
    assert MODEL.energy(q, qd).shape == (2, 3)
    assert MODEL.energy(q[0, 0], qd[0, 0]).shape == ()
    np.testing.assert_allclose(
        MODEL.accelerations(q[1, 2], qd[1, 2], tau[1, 2]), acc[1, 2], rtol=1e-14
    )
    # Broadcasting one torque over a batch.
    np.testing.assert_allclose(
        MODEL.accelerations(q, qd, tau[0, 0]),
        MODEL.accelerations(q, qd, np.broadcast_to(tau[0, 0], (2, 3, 2))),
        rtol=0,
    )
    with pytest.raises(ValueError, match=r"q must have shape \(\.\.\., 4\)"):
        MODEL.mass_matrix(np.zeros(3))
    assert MODEL.constants().shape == (9,)


# --- independent physics: MuJoCo with contacts and the physical drive torque ------------------
def mujoco_ballbot(p: BallbotParams) -> tuple[Any, Any]:
    """Ball on the floor (contact with torsional friction: rolls without slip or spin) under a
    carrier on x/y/z slides; body on two hinges in the model's order, R_y(φ_x) R_x(−φ_y)."""
    mujoco = pytest.importorskip("mujoco")
    r, lb, iw = p.ball_radius, p.body_com_height, p.ball_inertia
    tiny = 'mass="1e-9" diaginertia="1e-9 1e-9 1e-9"'
    xml = f"""
    <mujoco>
     <option gravity="0 0 -{p.gravity}" cone="elliptic" impratio="100">
      <flag warmstart="disable"/>
     </option>
     <default><geom solref="0.0005 1" solimp="0.99999 0.99999 0.0001"/></default>
     <worldbody>
      <geom type="plane" size="10 10 0.1" condim="4" friction="5 0.5 0"/>
      <body name="carrier" pos="0 0 {r}">
       <joint type="slide" axis="1 0 0"/><joint type="slide" axis="0 1 0"/>
       <joint type="slide" axis="0 0 1"/>
       <inertial pos="0 0 0" mass="{p.ball_mass}" diaginertia="1e-9 1e-9 1e-9"/>
       <body name="ball">
        <joint type="ball"/>
        <inertial pos="0 0 0" mass="1e-9" diaginertia="{iw} {iw} {iw}"/>
        <geom type="sphere" size="{r}" mass="0" condim="4" friction="5 0.5 0"/>
       </body>
       <body name="gimbal">
        <joint type="hinge" axis="0 1 0"/>
        <inertial pos="0 0 0" {tiny}/>
        <body name="body">
         <joint type="hinge" axis="-1 0 0"/>
         <inertial pos="0 0 {lb}" mass="{p.body_mass}"
          diaginertia="{p.body_inertia_x} {p.body_inertia_y} {p.body_inertia_z}"/>
        </body>
       </body>
      </body>
     </worldbody>
    </mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    return mujoco, model


def test_accelerations_match_mujoco_with_physical_drive_torque() -> None:
    """MuJoCo's accelerations with τ_w on the ball and −τ_w on the body agree with the model
    (soft contact leaves ~1e-4); without τ_w's vertical component the input response does not."""
    p = PARAMS.without_friction()
    mujoco, mj_model = mujoco_ballbot(p)
    data = mujoco.MjData(mj_model)
    ball, body = mj_model.body("ball").id, mj_model.body("body").id
    model = Ballbot3D(p)
    r = p.ball_radius

    def mj_accelerations(q: np.ndarray, qd: np.ndarray, tau_w: np.ndarray) -> np.ndarray:
        v = r * (qd[:2] + qd[2:])
        data.qpos[:] = [*model.ball_position(q), -1e-9, 1, 0, 0, 0, q[2], q[3]]  # sunk 1 nm
        data.qvel[:] = [v[0], v[1], 0, -v[1] / r, v[0] / r, 0, qd[2], qd[3]]
        data.xfrc_applied[:] = 0.0
        data.xfrc_applied[ball, 3:] = tau_w
        data.xfrc_applied[body, 3:] = -tau_w
        mujoco.mj_forward(mj_model, data)
        a = data.qacc
        return np.array([a[0] / r - a[6], a[1] / r - a[7], a[6], a[7]])

    rng = np.random.default_rng(13)
    errors_without_vertical = []
    for _ in range(5):
        q = np.concatenate([rng.uniform(-1, 1, 2), rng.uniform(-0.5, 0.5, 2)])
        qd = rng.uniform(-1, 1, 4)
        tau = rng.uniform(-40, 40, 2)
        tau_w = np.array([-tau[1], tau[0], tau[1] * np.tan(q[2] / 2)])
        acc = model.accelerations(q, qd, tau)
        acc_mj = mj_accelerations(q, qd, tau_w)
        assert np.max(np.abs(acc_mj - acc)) < 1e-3 * np.max(np.abs(acc))
        # Response to the input alone (contact softness largely cancels).
        free_mj = mj_accelerations(q, qd, np.zeros(3))
        response = acc - model.accelerations(q, qd, np.zeros(2))
        scale = np.max(np.abs(response))
        assert np.max(np.abs(acc_mj - free_mj - response)) < 1e-4 * scale
        horizontal = mj_accelerations(q, qd, tau_w * [1, 1, 0]) - free_mj
        errors_without_vertical.append(np.max(np.abs(horizontal - response)) / scale)
    assert max(errors_without_vertical) > 1e-3
