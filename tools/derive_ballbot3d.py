"""Derive the 3D ballbot model (no yaw, no slip) and generate its numeric code.

The conventions are those of ``docs/design/conventions.md`` ("3D model"):

* q = [θ_x, θ_y, φ_x, φ_y]; ball centre at (r_w (θ_x + φ_x), r_w (θ_y + φ_y), r_w);
* ball angular velocity ω_w = (−ẏ/r_w, ẋ/r_w, 0) (rolling, no slip, no spin);
* body orientation R = R_y(φ_x) R_x(−φ_y), body COM at ℓ_b R ẑ above the ball centre;
* V = m_b g ℓ_b cos φ_x cos φ_y.

Kinematics are built with :mod:`sympy.physics.mechanics`; the equations come
from Lagrange's equations

    M(q) q̈ + h(q, q̇) = [τ_x − D_x, τ_y − D_y, 0, 0]ᵀ,   h = C(q, q̇) q̇ + G(q),

and the script checks, symbolically, every convention it relies on (rolling
contact, body axis and angular velocity, potential, the claimed drive torque
τ_w = (−τ_y, τ_x, τ_y tan(φ_x/2)) whose power is τ_x θ̇_x + τ_y θ̇_y, and the
absence of inputs in the φ equations) before writing
``src/gracenav/model/_ballbot3d_generated.py``.

Usage::

    python tools/derive_ballbot3d.py [--out PATH]
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import sympy as sp
from sympy.physics import mechanics as me
from sympy.printing.pycode import PythonCodePrinter

DEFAULT_OUT = Path(__file__).resolve().parents[1] / "src/gracenav/model/_ballbot3d_generated.py"

# Model constants, in the order of ``Ballbot3D.constants()``.
CONSTANT_NAMES = ("r_w", "m_w", "I_w", "m_b", "l_b", "I_xx", "I_yy", "I_zz", "g")
Q_NAMES = ("theta_x", "theta_y", "phi_x", "phi_y")
QD_NAMES = ("theta_x_dot", "theta_y_dot", "phi_x_dot", "phi_y_dot")


class Model:
    """Symbolic 3D ballbot: energies, equations of motion and kinematics.

    Attributes are plain sympy expressions in the symbols ``consts``, ``q``
    and ``qd`` (no functions of time).
    """

    def __init__(self) -> None:
        self.consts = sp.symbols(CONSTANT_NAMES, positive=True)
        r_w, m_w, i_w, m_b, l_b, i_xx, i_yy, i_zz, g = self.consts
        self.q = sp.symbols(Q_NAMES, real=True)
        self.qd = sp.symbols(QD_NAMES, real=True)
        self.qdd = sp.symbols(tuple(n + "_ddot" for n in Q_NAMES), real=True)
        self.tau = sp.symbols("tau_x tau_y", real=True)

        t = me.dynamicsymbols._t
        qt = me.dynamicsymbols(" ".join(Q_NAMES))
        qdt = [qi.diff(t) for qi in qt]
        qddt = [qi.diff(t) for qi in qdt]
        th_x, th_y, ph_x, ph_y = qt
        self._to_plain = dict(zip([*qddt, *qdt, *qt], [*self.qdd, *self.qd, *self.q], strict=True))

        # Frames: world N, intermediate A (lean toward +x, about N.y), body B.
        n = me.ReferenceFrame("N")
        a = n.orientnew("A", "Axis", (ph_x, n.y))
        b = a.orientnew("B", "Axis", (-ph_y, a.x))

        # Ball: centre W, no-slip, no-spin angular velocity.
        origin = me.Point("O")
        origin.set_vel(n, 0)
        x = r_w * (th_x + ph_x)
        y = r_w * (th_y + ph_y)
        centre = origin.locatenew("W", x * n.x + y * n.y + r_w * n.z)
        centre.set_vel(n, centre.pos_from(origin).dt(n))
        omega_w = -y.diff(t) / r_w * n.x + x.diff(t) / r_w * n.y
        contact_velocity = centre.vel(n) + omega_w.cross(-r_w * n.z)

        # Body: COM at l_b along the body axis.
        com = centre.locatenew("C", l_b * b.z)
        com.v2pt_theory(centre, n, b)
        omega_b = b.ang_vel_in(n)

        # The ball's inertia is isotropic, so its kinetic energy needs only ω_w (the
        # ball's orientation is not a coordinate: rolling without spin is nonholonomic).
        ball_kinetic = (m_w * centre.vel(n).dot(centre.vel(n)) + i_w * omega_w.dot(omega_w)) / 2
        body = me.RigidBody("body", com, b, m_b, (me.inertia(b, i_xx, i_yy, i_zz), com))
        kinetic = ball_kinetic + body.kinetic_energy(n)
        potential = m_b * g * l_b * sp.cos(ph_x) * sp.cos(ph_y)

        # --- checks of the conventions (docs/design/conventions.md, "3D model") ------------------
        _require_zero(contact_velocity.to_matrix(n), "rolling contact point velocity")
        axis = [sp.sin(ph_x) * sp.cos(ph_y), sp.sin(ph_y), sp.cos(ph_x) * sp.cos(ph_y)]
        _require_zero(b.z.to_matrix(n) - sp.Matrix(axis), "body axis R z")
        omega_b_doc = qdt[2] * n.y - qdt[3] * (sp.cos(ph_x) * n.x - sp.sin(ph_x) * n.z)
        _require_zero((omega_b - omega_b_doc).to_matrix(n), "body angular velocity")
        _require_zero(
            sp.Matrix([potential - m_b * g * (com.pos_from(origin).dot(n.z) - r_w)]),
            "potential energy",
        )
        # The physical drive torque on the ball (world axes); its reaction acts on the body.
        tau_x, tau_y = self.tau
        drive = -tau_y * n.x + tau_x * n.y + tau_y * sp.tan(ph_x / 2) * n.z
        relative = (omega_w - omega_b).to_matrix(n)
        power = drive.to_matrix(n).dot(relative)
        _require_zero(sp.Matrix([power - tau_x * qdt[0] - tau_y * qdt[1]]), "drive torque power")
        generalised = [sp.diff(power, qi) for qi in qdt]
        _require_zero(
            sp.Matrix(generalised) - sp.Matrix([tau_x, tau_y, 0, 0]), "generalised drive forces"
        )

        # --- Lagrange's equations ------------------------------------------------------
        lagrangian = kinetic - potential
        eqs = [
            sp.diff(sp.diff(lagrangian, qdi), t) - sp.diff(lagrangian, qi)
            for qi, qdi in zip(qt, qdt, strict=True)
        ]
        eqs = [self._plain(e) for e in eqs]
        kinetic_p = self._plain(kinetic)
        self.mass = sp.Matrix(
            4, 4, lambda i, j: _simplify(sp.diff(kinetic_p, self.qd[i], self.qd[j]))
        )
        mass_from_eqs = sp.Matrix(4, 4, lambda i, j: sp.diff(eqs[i], self.qdd[j]))
        _require_zero(mass_from_eqs - self.mass, "mass matrix from Lagrange's equations")
        zero_acc = dict.fromkeys(self.qdd, 0)
        self.bias = sp.Matrix([_simplify(e.subs(zero_acc)) for e in eqs])
        # h = C(q, q̇) q̇ + G(q): G = ∂V/∂q and the rest homogeneous quadratic in q̇.
        potential_p = self._plain(potential)
        gravity = sp.Matrix([sp.diff(potential_p, qi) for qi in self.q])
        _require_zero(self.bias.subs(dict.fromkeys(self.qd, 0)) - gravity, "gravity terms")
        s = sp.Symbol("s", positive=True)
        scaled = self.bias.subs({qdi: s * qdi for qdi in self.qd}, simultaneous=True)
        _require_zero(scaled - gravity - s**2 * (self.bias - gravity), "quadratic rate terms")
        self.energy = _simplify(kinetic_p + potential_p)
        self.com_position = sp.Matrix(
            [_simplify(self._plain(e)) for e in com.pos_from(origin).to_matrix(n)]
        )
        self.com_jacobian = self.com_position.jacobian(sp.Matrix(self.q))

    def _plain(self, expr: sp.Expr) -> sp.Expr:
        """Replace the functions of time by plain symbols (accelerations first)."""
        return sp.expand(sp.sympify(expr).subs(self._to_plain))


def _simplify(expr: sp.Expr) -> sp.Expr:
    """Canonical compact form: collect over the rates, simplify each coefficient."""
    expr = sp.expand(sp.trigsimp(sp.expand(expr)))
    return sp.factor_terms(sp.collect(expr, sp.symbols(QD_NAMES, real=True), evaluate=True))


def _require_zero(matrix: sp.Matrix, what: str) -> None:
    """Raise AssertionError unless every entry of ``matrix`` simplifies to zero."""
    residue = sp.simplify(matrix)
    if residue != sp.zeros(*matrix.shape):
        # Half-angle identities (tan(φ/2) sin φ = 1 − cos φ) need the exponential form.
        residue = sp.simplify(residue.applyfunc(lambda e: e.rewrite(sp.exp)))
    if residue != sp.zeros(*matrix.shape):
        raise AssertionError(f"derivation check failed ({what}): residue {residue}")


class _Printer(PythonCodePrinter):
    """Python printer that calls numpy's ufuncs as ``np.sin`` etc."""

    def _print_sin(self, expr: sp.Expr) -> str:
        return f"np.sin({self._print(expr.args[0])})"

    def _print_cos(self, expr: sp.Expr) -> str:
        return f"np.cos({self._print(expr.args[0])})"

    def _print_tan(self, expr: sp.Expr) -> str:
        return f"np.tan({self._print(expr.args[0])})"


HEADER = '''\
"""GENERATED by tools/derive_ballbot3d.py -- do not edit; run the script to regenerate.

3D ballbot model without yaw and without slip; conventions in docs/design/conventions.md
("3D model"). Equations of motion

    M(q) q̈ + h(q, q̇) = [τ_x − D_x, τ_y − D_y, 0, 0]ᵀ

with q = [θ_x, θ_y, φ_x, φ_y] (rad) and h = C(q, q̇) q̇ + G(q) (friction D is
not included here).

Every function takes the model constants
``c = [r_w, m_w, I_w, m_b, l_b, I_xx, I_yy, I_zz, g]`` (SI) and works both on
single states (q of shape (4,), out of shape (4, 4) etc.; compiled with numba)
and on batches with the batch axis last (q of shape (4, N), out of shape
(4, 4, N) etc.; numpy).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["bias", "com_jacobian", "com_position", "energy", "mass_matrix"]

FloatArray = NDArray[np.float64]
'''


def _function(
    name: str,
    args: Sequence[str],
    doc: str,
    model: Model,
    targets: Sequence[str],
    exprs: Sequence[sp.Expr],
    returns: bool = False,
) -> str:
    """Source of one generated function: unpack the used inputs, cse, assign."""
    printer = _Printer({"standard": "python3"})
    used = set().union(*(sp.sympify(e).free_symbols for e in exprs))
    temps = sp.numbered_symbols("x")
    replacements, reduced = sp.cse(list(exprs), symbols=temps, optimizations="basic")
    signature = ", ".join(f"{a}: FloatArray" for a in args)
    result = "Any" if returns else "None"
    lines = [f"def {name}({signature}) -> {result}:", f'    """{doc}"""']
    sources = [("c", model.consts), ("q", model.q), ("qd", model.qd)]
    for arg, symbols in sources:
        if arg not in args:
            continue
        for i, s in enumerate(symbols):
            if s in used:
                lines.append(f"    {s.name} = {arg}[{i}]")
    for sym, expr in replacements:
        lines.append(f"    {sym} = {printer.doprint(expr)}")
    for target, expr in zip(targets, reduced, strict=True):
        text = printer.doprint(expr)
        if expr.is_number:
            text = repr(float(expr))
        lines.append(f"    {target} = {text}")
    code = "\n".join(lines) + "\n"
    if "math." in code or "mpmath" in code:
        raise AssertionError(f"{name}: non-numpy function in generated code")
    return code


def generate(model: Model) -> str:
    """Return the text of the generated module."""
    mass_targets = [f"out[{i}, {j}]" for i in range(4) for j in range(i, 4)]
    mass_exprs = [model.mass[i, j] for i in range(4) for j in range(i, 4)]
    mass_code = _function(
        "mass_matrix",
        ("c", "q", "out"),
        "Mass matrix M(q) (kg m², symmetric), written to ``out`` (4, 4[, N]).",
        model,
        mass_targets,
        mass_exprs,
    )
    # Mirror the strict upper triangle.
    mirror = [f"    out[{j}, {i}] = out[{i}, {j}]" for i in range(4) for j in range(i + 1, 4)]
    mass_code += "\n".join(mirror) + "\n"
    functions = [
        mass_code,
        _function(
            "bias",
            ("c", "q", "qd", "out"),
            "h = C(q, q̇) q̇ + G(q): Coriolis, centrifugal, gravity (N m), to ``out`` (4[, N]).",
            model,
            [f"out[{i}]" for i in range(4)],
            list(model.bias),
        ),
        _function(
            "energy",
            ("c", "q", "qd"),
            "Total energy T + V (J); V is zero with the body COM at ball-centre height.",
            model,
            ["result"],
            [model.energy],
            returns=True,
        ).rstrip("\n")
        + "\n    return result\n",
        _function(
            "com_position",
            ("c", "q", "out"),
            "Body centre of mass in the world frame (m), written to ``out`` (3[, N]).",
            model,
            [f"out[{i}]" for i in range(3)],
            list(model.com_position),
        ),
        _function(
            "com_jacobian",
            ("c", "q", "out"),
            "Jacobian d com_position / d q (m/rad), written to ``out`` (3, 4[, N]).",
            model,
            [f"out[{i}, {j}]" for i in range(3) for j in range(4)],
            list(model.com_jacobian),
        ),
    ]
    return HEADER + "".join("\n\n" + f for f in functions)


def main(argv: Sequence[str] | None = None) -> None:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output file")
    args = parser.parse_args(argv)
    text = generate(Model())
    args.out.write_text(text)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
