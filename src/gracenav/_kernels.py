"""Compiled (numba) kernels: 3D dynamics, the Fig. 2 control law and the closed loop.

Everything here works on plain float64 arrays so that one compiled loop can
run a single closed-loop simulation or a batch of them; the public, typed
interface is :mod:`gracenav.sim` and :mod:`gracenav.model`.

Kernels use numpy's floating-point error model: a division by zero (a singular mass
matrix of non-physical parameters) gives inf or NaN, which the closed loop reports as a
fall, instead of raising inside compiled code.

Array conventions: state x = [θ_x, θ_y, φ_x, φ_y, θ̇_x, θ̇_y, φ̇_x, φ̇_y];
model constants ``c`` as ``Ballbot3D.constants()``; friction constants
``fr = [D_c, D_v, ε]`` (:func:`gracenav.model.friction.friction_constants`); controller
gains ``k`` (2, 4) with rows [k_p, k_v, k_φ, k_φ̇] per plane (see
:class:`gracenav.control.ControllerGains`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from gracenav.model import _ballbot3d_generated as _gen
from gracenav.model.friction import friction_torque

__all__ = [
    "FRICTION_MEASURED",
    "FRICTION_MIDPOINT",
    "FRICTION_OFF",
    "closed_loop",
    "control_law",
    "dynamics",
    "friction_mode",
    "mass_matrix",
    "rebuild_fine",
]

#: The control law's friction feed-forward: none.
FRICTION_OFF = 0
#: The control law's friction feed-forward at the measured ball rate.
FRICTION_MEASURED = 1
#: The control law's friction feed-forward at the ball rate predicted for the middle of
#: the control period (the measured rate plus half the reference's change over it).
FRICTION_MIDPOINT = 2


def friction_mode(compensation: bool, midpoint: bool) -> int:
    """The control law's ``friction_comp`` argument for the gains'
    ``friction_compensation`` and ``friction_midpoint``."""
    if not compensation:
        return FRICTION_OFF
    return FRICTION_MIDPOINT if midpoint else FRICTION_MEASURED


mass_matrix = njit(cache=True, error_model="numpy")(_gen.mass_matrix)
bias = njit(cache=True, error_model="numpy")(_gen.bias)
com_jacobian = njit(cache=True, error_model="numpy")(_gen.com_jacobian)
com_position = njit(cache=True, error_model="numpy")(_gen.com_position)
#: Smooth friction torque D_c tanh(θ̇/ε) + D_v θ̇ (N m) of one relative ball rate.
friction = njit(cache=True, error_model="numpy")(friction_torque)


@njit(cache=True, error_model="numpy")
def solve_spd(m, b, out):
    """Solve m @ out = b for a small symmetric positive definite m (Cholesky, in place)."""
    n = b.shape[0]
    for j in range(n):
        s = m[j, j]
        for k in range(j):
            s -= m[j, k] * m[j, k]
        m[j, j] = np.sqrt(s)
        for i in range(j + 1, n):
            s = m[i, j]
            for k in range(j):
                s -= m[i, k] * m[j, k]
            m[i, j] = s / m[j, j]
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= m[i, k] * out[k]
        out[i] = s / m[i, i]
    for i in range(n - 1, -1, -1):
        s = out[i]
        for k in range(i + 1, n):
            s -= m[k, i] * out[k]
        out[i] = s / m[i, i]


@njit(cache=True, error_model="numpy")
def dynamics(c, fr, x, tau, force, wm, wh, wj, wr, xdot):
    """State derivative of the 3D model with drive torque ``tau`` (2,) and a world force
    ``force`` (3,) on the body centre of mass. ``wm`` (4,4), ``wh`` (4,), ``wj`` (3,4),
    ``wr`` (4,) are workspaces; the result is written to ``xdot`` (8,)."""
    q = x[:4]
    qd = x[4:]
    mass_matrix(c, q, wm)
    bias(c, q, qd, wh)
    com_jacobian(c, q, wj)
    for i in range(4):
        wr[i] = -wh[i] + wj[0, i] * force[0] + wj[1, i] * force[1] + wj[2, i] * force[2]
    wr[0] += tau[0] - friction(fr, qd[0])
    wr[1] += tau[1] - friction(fr, qd[1])
    for i in range(4):
        xdot[i] = qd[i]
    solve_spd(wm, wr, xdot[4:])


@njit(cache=True, error_model="numpy", nogil=True)
def rebuild_fine(cstates, cacc, cfirst, ffirst, intervals, basis, h, c, fr, r, st, acc, tau, pos):
    """Samples at every tick from every ``stride``-th one, for several primitives.

    Primitive k has ``intervals[k]`` coarse intervals whose (q, q̇) and q̈ are the rows
    ``cfirst[k]`` on of ``cstates`` (·, 8) and ``cacc`` (·, 4); its fine samples are
    the rows ``ffirst[k]`` on of ``st`` (·, 8: q, q̇), ``acc`` (·, 4), ``tau`` (·, 2,
    :func:`inverse_dynamics`) and ``pos`` (·, 6: ball position, velocity and
    acceleration, r (θ + φ) and its derivatives). Between coarse samples q, q̇, q̈ come
    from the quintic Hermite interpolant with ``basis`` (3, stride, 6) (values, first and
    second derivatives in the unit interval, :func:`gracenav._util.hermite.quintic_hermite_basis`);
    ``h`` is the coarse step (s)."""
    stride = basis.shape[1]
    wm = np.empty((4, 4))
    wh = np.empty(4)
    for k in range(cfirst.shape[0]):
        for m in range(intervals[k] + 1):
            a = cfirst[k] + m
            last = m == intervals[k]
            for j in range(1 if last else stride):
                row = ffirst[k] + m * stride + j
                for i in range(4):
                    if j == 0:
                        st[row, i] = cstates[a, i]
                        st[row, 4 + i] = cstates[a, 4 + i]
                        acc[row, i] = cacc[a, i]
                        continue
                    e0 = cstates[a, i]
                    e1 = h * cstates[a, 4 + i]
                    e2 = h * h * cacc[a, i]
                    e3 = cstates[a + 1, i]
                    e4 = h * cstates[a + 1, 4 + i]
                    e5 = h * h * cacc[a + 1, i]
                    b = basis[0, j]
                    st[row, i] = (
                        b[0] * e0 + b[1] * e1 + b[2] * e2 + b[3] * e3 + b[4] * e4 + b[5] * e5
                    )
                    b = basis[1, j]
                    st[row, 4 + i] = (
                        b[0] * e0 + b[1] * e1 + b[2] * e2 + b[3] * e3 + b[4] * e4 + b[5] * e5
                    ) / h
                    b = basis[2, j]
                    acc[row, i] = (
                        b[0] * e0 + b[1] * e1 + b[2] * e2 + b[3] * e3 + b[4] * e4 + b[5] * e5
                    ) / (h * h)
                mass_matrix(c, st[row, :4], wm)
                bias(c, st[row, :4], st[row, 4:], wh)
                for i in range(2):
                    s = wh[i] + friction(fr, st[row, 4 + i])
                    for jj in range(4):
                        s += wm[i, jj] * acc[row, jj]
                    tau[row, i] = s
                    pos[row, i] = r * (st[row, i] + st[row, 2 + i])
                    pos[row, 2 + i] = r * (st[row, 4 + i] + st[row, 6 + i])
                    pos[row, 4 + i] = r * (acc[row, i] + acc[row, 2 + i])


@njit(cache=True, error_model="numpy")
def control_law(r, fr, k, max_comp, friction_comp, x, meas_noise, x_ref, x_next, tau_ff, out):
    """Fig. 2 cascade for both planes; writes the (unsaturated) torque to ``out`` (2,).

    ``meas_noise`` (4,) is added to the measured [p_x, p_y, ṗ_x, ṗ_y]. ``friction_comp``
    (:data:`FRICTION_OFF`, :data:`FRICTION_MEASURED`, :data:`FRICTION_MIDPOINT`) says
    at which ball rate the friction is fed forward: none, the measured one, or the
    measured one plus half the reference's change over the period (``x_next`` the
    reference state of the next tick), the rate in the middle of the period over which
    the torque is held."""
    for i in range(2):
        p = r * (x[i] + x[2 + i]) + meas_noise[i]
        v = r * (x[4 + i] + x[6 + i]) + meas_noise[2 + i]
        p_ref = r * (x_ref[i] + x_ref[2 + i])
        v_ref = r * (x_ref[4 + i] + x_ref[6 + i])
        comp = k[i, 0] * (p_ref - p) + k[i, 1] * (v_ref - v)
        if comp > max_comp:
            comp = max_comp
        elif comp < -max_comp:
            comp = -max_comp
        lean_des = x_ref[2 + i] + comp
        tau = tau_ff[i] - k[i, 2] * (x[2 + i] - lean_des) - k[i, 3] * (x[6 + i] - x_ref[6 + i])
        if friction_comp == FRICTION_MEASURED:
            tau += friction(fr, x[4 + i]) - friction(fr, x_ref[4 + i])
        elif friction_comp == FRICTION_MIDPOINT:
            mid = x[4 + i] + 0.5 * (x_next[4 + i] - x_ref[4 + i])
            tau += friction(fr, mid) - friction(fr, x_ref[4 + i])
        out[i] = tau


@njit(cache=True, error_model="numpy")
def _rk4(c, fr, x, tau, force, h, wm, wh, wj, wr, k1, k2, k3, k4, xt):
    dynamics(c, fr, x, tau, force, wm, wh, wj, wr, k1)
    for i in range(8):
        xt[i] = x[i] + 0.5 * h * k1[i]
    dynamics(c, fr, xt, tau, force, wm, wh, wj, wr, k2)
    for i in range(8):
        xt[i] = x[i] + 0.5 * h * k2[i]
    dynamics(c, fr, xt, tau, force, wm, wh, wj, wr, k3)
    for i in range(8):
        xt[i] = x[i] + h * k3[i]
    dynamics(c, fr, xt, tau, force, wm, wh, wj, wr, k4)
    for i in range(8):
        x[i] += h * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]) / 6.0


@njit(cache=True, error_model="numpy")
def _kick(c, x, impulse, wm, wj, wr, dq):
    """Velocity jump M⁻¹ Jᵀ i of a world impulse ``impulse`` (3,) (N s) on the body
    centre of mass, added to ``x`` (8,) in place; the rest are workspaces."""
    mass_matrix(c, x[:4], wm)
    com_jacobian(c, x[:4], wj)
    for i in range(4):
        wr[i] = wj[0, i] * impulse[0] + wj[1, i] * impulse[1] + wj[2, i] * impulse[2]
    solve_spd(wm, wr, dq)
    for i in range(4):
        x[4 + i] += dq[i]


@njit(cache=True, error_model="numpy")
def _period(c, fr, x, tau, f, base, tethered, drag, drag_gain, h, substeps, ws):
    """``substeps`` RK4 steps of ``h`` (s) with ``tau`` (2,) held and the world force
    ``f`` (3,) on the body; while ``tethered``, f[0:2] is ``base`` (3,) plus a damper of
    ``drag_gain`` toward the velocity ``drag[1:3]``, re-evaluated every step. ``ws``:
    workspaces (wm, wh, wj, wr, k1, k2, k3, k4, xt). One period of the plant, shared by
    :func:`closed_loop` and :func:`plant_advance`."""
    wm, wh, wj, wr, k1, k2, k3, k4, xt = ws
    for _s in range(substeps):
        if tethered:
            com_jacobian(c, x[:4], wj)
            for i in range(2):
                vel = 0.0
                for j in range(4):
                    vel += wj[i, j] * x[4 + j]
                f[i] = base[i] + drag_gain * (drag[1 + i] - vel)
        _rk4(c, fr, x, tau, f, h, wm, wh, wj, wr, k1, k2, k3, k4, xt)


@njit(cache=True, error_model="numpy", nogil=True)
def closed_loop(
    c_plant,
    fr_plant,
    c_ctrl,
    fr_ctrl,
    k,
    max_comp,
    friction_comp,
    torque_limit,
    x0,
    x_ref,
    tau_ff,
    dt,
    substeps,
    noise,
    force,
    impulse,
    jump,
    tether,
    tether_gains,
    domain_center,
    domain_shape,
    stop_on_exit,
    fall_lean,
    record,
    states_out,
    inputs_out,
    summary_out,
    final_out,
):
    """Run a batch of closed-loop simulations.

    Shapes: x0 (B, 8); x_ref (T+1, 8) and tau_ff (T+1, 2) at the control ticks;
    noise (B or 1, T+1, 4); force (T, 3) world force on the body COM held over
    each tick; impulse (T+1, 3) world impulse on the body COM applied at a tick;
    jump (T+1, 8) state increment applied at a tick; tether (T, 3) rows
    [active, v_x, v_y]: while active a horizontal damper, tether_gains[0]
    (N s/m), drags the body COM toward the velocity (v_x, v_y); domain_center
    (T+1, 4) and domain_shape (T+1, 4, 4) the monitored outer domain D'(t) (pass
    zero-size arrays for none); a run stops at the first tick where |φ_x| or |φ_y|
    exceeds ``fall_lean`` (rad) or is not finite (a fall); states_out (B, T+1, 8)
    and inputs_out (B, T+1, 2) when ``record``; summary_out (B, 7): [last tick
    reached, max |lean| (rad), max |τ| commanded (N m), max D'(t) value, saturated
    ticks, exit tick or -1, fall tick or -1]; final_out (B, 8) the state at the last
    tick reached.
    """
    nb = x0.shape[0]
    nt = x_ref.shape[0] - 1
    h = dt / substeps
    r = c_ctrl[0]
    monitor = domain_center.shape[0] > 0
    use_force = force.shape[0] > 0
    use_tether = tether.shape[0] > 0
    use_impulse = impulse.shape[0] > 0
    use_jump = jump.shape[0] > 0
    one_noise = noise.shape[0] == 1
    use_noise = noise.shape[1] > 0
    wm = np.empty((4, 4))
    wh = np.empty(4)
    wj = np.empty((3, 4))
    wr = np.empty(4)
    k1 = np.empty(8)
    k2 = np.empty(8)
    k3 = np.empty(8)
    k4 = np.empty(8)
    xt = np.empty(8)
    tau = np.empty(2)
    f = np.zeros(3)
    zero3 = np.zeros(3)
    zero4 = np.zeros(4)
    dq = np.empty(4)
    pv = np.empty(4)
    ws = (wm, wh, wj, wr, k1, k2, k3, k4, xt)
    for b in range(nb):
        x = x0[b].copy()
        max_lean = 0.0
        max_tau = 0.0
        max_dom = 0.0
        saturated = 0
        exit_tick = -1
        fall_tick = -1
        last = nt
        for n in range(nt + 1):
            if use_jump:
                for i in range(8):
                    x[i] += jump[n, i]
            if use_impulse and (
                impulse[n, 0] != 0.0 or impulse[n, 1] != 0.0 or impulse[n, 2] != 0.0
            ):
                _kick(c_plant, x, impulse[n], wm, wj, wr, dq)
            meas = zero4
            if use_noise:
                meas = noise[0, n] if one_noise else noise[b, n]
            control_law(
                r,
                fr_ctrl,
                k,
                max_comp,
                friction_comp,
                x,
                meas,
                x_ref[n],
                x_ref[n + 1 if n < nt else nt],
                tau_ff[n],
                tau,
            )
            for i in range(2):
                a = abs(tau[i])
                if a > max_tau:
                    max_tau = a
                if tau[i] > torque_limit:
                    tau[i] = torque_limit
                    saturated += 1
                elif tau[i] < -torque_limit:
                    tau[i] = -torque_limit
                    saturated += 1
                a = abs(x[2 + i])
                if a > max_lean:
                    max_lean = a
                if not a <= fall_lean and fall_tick < 0:
                    fall_tick = n
            if monitor:
                for i in range(2):
                    pv[i] = r * (x[i] + x[2 + i]) - domain_center[n, i]
                    pv[2 + i] = r * (x[4 + i] + x[6 + i]) - domain_center[n, 2 + i]
                val = 0.0
                for i in range(4):
                    for j in range(4):
                        val += pv[i] * domain_shape[n, i, j] * pv[j]
                if val > max_dom:
                    max_dom = val
                if val > 1.0 and exit_tick < 0:
                    exit_tick = n
            if record:
                for i in range(8):
                    states_out[b, n, i] = x[i]
                inputs_out[b, n, 0] = tau[0]
                inputs_out[b, n, 1] = tau[1]
            if (exit_tick >= 0 and stop_on_exit) or fall_tick >= 0 or n == nt:
                last = n
                break
            base = force[n] if use_force else zero3
            for i in range(3):
                f[i] = base[i]
            tethered = use_tether and tether[n, 0] > 0.0
            drag = tether[n] if use_tether else zero3
            _period(
                c_plant,
                fr_plant,
                x,
                tau,
                f,
                base,
                tethered,
                drag,
                tether_gains[0],
                h,
                substeps,
                ws,
            )
        summary_out[b, 0] = last
        summary_out[b, 1] = max_lean
        summary_out[b, 2] = max_tau
        summary_out[b, 3] = max_dom
        summary_out[b, 4] = saturated
        summary_out[b, 5] = exit_tick
        summary_out[b, 6] = fall_tick
        for i in range(8):
            final_out[b, i] = x[i]


@njit(cache=True, error_model="numpy")
def tracking_tick(
    r, fr, k, max_comp, friction_comp, torque_limit, x, x_ref, x_next, tau_ff, center, shape, out
):
    """One tick of the Fig. 2 cascade on the measured state ``x`` (8,): the torque,
    saturated at ``torque_limit``, is written to ``out`` (2,); returns the value
    (p − c)ᵀ P (p − c) of the monitored outer domain (``center`` (4,), ``shape``
    (4, 4); 0 when ``center`` is empty), with p the position state of ``x`` (radius
    ``r``). The same arithmetic as one tick of :func:`closed_loop` without noise."""
    control_law(r, fr, k, max_comp, friction_comp, x, np.zeros(4), x_ref, x_next, tau_ff, out)
    for i in range(2):
        if out[i] > torque_limit:
            out[i] = torque_limit
        elif out[i] < -torque_limit:
            out[i] = -torque_limit
    val = 0.0
    if center.shape[0] > 0:
        pv = np.empty(4)
        for i in range(2):
            pv[i] = r * (x[i] + x[2 + i]) - center[i]
            pv[2 + i] = r * (x[4 + i] + x[6 + i]) - center[2 + i]
        for i in range(4):
            for j in range(4):
                val += pv[i] * shape[i, j] * pv[j]
    return val


@njit(cache=True, error_model="numpy")
def plant_kick(c, x, impulse):
    """Apply a world impulse ``impulse`` (3,) (N s) on the body centre of mass to the
    state ``x`` (8,) in place (the velocity jump M⁻¹ Jᵀ i), as :func:`closed_loop`."""
    _kick(c, x, impulse, np.empty((4, 4)), np.empty((3, 4)), np.empty(4), np.empty(4))


@njit(cache=True, error_model="numpy")
def plant_advance(c, fr, x, torque, limit, force, drag, drag_gain, dt, substeps):
    """Advance the state ``x`` (8,) in place by one control period ``dt`` (s) of
    ``substeps`` RK4 steps with the torque ``torque`` (2,) saturated at ``limit`` (N m)
    and held, a world force ``force``
    (3,) (N) on the body centre of mass, and while ``drag[0] > 0`` a horizontal damper
    of ``drag_gain`` (N s/m) pulling the body toward the velocity ``drag[1:3]`` (m/s);
    the same arithmetic as one period of :func:`closed_loop`."""
    ws = (
        np.empty((4, 4)),
        np.empty(4),
        np.empty((3, 4)),
        np.empty(4),
        np.empty(8),
        np.empty(8),
        np.empty(8),
        np.empty(8),
        np.empty(8),
    )
    tau = np.empty(2)
    for i in range(2):
        tau[i] = min(max(torque[i], -limit), limit)
    _period(
        c,
        fr,
        x,
        tau,
        force.copy(),
        force,
        drag[0] > 0.0,
        drag,
        drag_gain,
        dt / substeps,
        substeps,
        ws,
    )
