"""The equations of motion of a rotor system, derived with sympy (Magnus 1980, eqs. 1-7).

Carrier coordinates q (n), rotor angles relative to the field z = phi - Omega0 t (eq. 7,
m of them). With v = (qdot, zdot), the rotors' spins omega = zdot + Omega0 + B(q) qdot
(eq. 2) and A = diag(rotor_inertia), the kinetic energy (eq. 1) is

    T = 1/2 v' Mbar(q) v + v' p0(q) + 1/2 Omega0' A Omega0,
    Mbar = [[M + B'AB, B'A], [AB, A]],   p0 = [B'A Omega0; A Omega0],

and L = T - V(q) does not depend on time. Lagrange's equations (eq. 4; eqs. 5, 6 of the
paper) with the drive torques Q (eq. 8) as the generalized forces of z read

    Mbar(q) vdot = F(q, v) + [0; Q(z, zdot)],
    F_i = dL/dx_i - sum_j (d p_i / d q_j) qdot_j,     p = Mbar v + p0,

(x = (q, z); L does not depend on z). The Jacobi integral of L is

    E* = 1/2 v' Mbar v + V(q) + U(z)                                    (eq. 13)

(the constant 1/2 Omega0' A Omega0 dropped), and dE*/dt = -zdot' K_D zdot (eq. 17).
This module returns the symbolic pieces; :mod:`gyro_rotor.core.system.codegen` turns
them into compiled code.
"""

from __future__ import annotations

import dataclasses

from gyro_rotor.core.system.system_file import RotorSystem
import sympy

__all__ = ['Equations', 'derive', 'internal_symbols']


@dataclasses.dataclass(frozen=True)
class Equations:
    """Symbolic equations in the internal symbols (see :func:`internal_symbols`).

    ``Mbar`` (N x N), ``F`` (N), ``kinetic`` = 1/2 v' Mbar v, ``V``, and the Jacobians
    ``F_q`` (N x n) and ``F_v`` (N x N) for the linearization; N = n + m.
    """

    n: int
    m: int
    q: tuple
    v: tuple
    consts: tuple
    Omega0: tuple
    Mbar: sympy.Matrix
    F: sympy.Matrix
    kinetic: sympy.Expr
    V: sympy.Expr
    F_q: sympy.Matrix
    F_v: sympy.Matrix


def internal_symbols(system: RotorSystem) -> tuple:
    """Return (q, v, consts, Omega0): the symbols of the generated code, all real."""
    n, m = system.n, system.m
    q = tuple(sympy.Symbol(f'q{i}', real=True) for i in range(n))
    v = tuple(sympy.Symbol(f'v{i}', real=True) for i in range(n + m))
    consts = tuple(sympy.Symbol(f'c{k}', real=True) for k in range(len(system.constants)))
    Omega0 = tuple(sympy.Symbol(f'O{k}', real=True) for k in range(m))
    return q, v, consts, Omega0


def derive(system: RotorSystem, *, jacobians: bool = True) -> Equations:
    """Derive the equations of motion of ``system`` (see module doc)."""
    n, m = system.n, system.m
    q, v, consts, Om = internal_symbols(system)
    rename = {**dict(zip(system.q_symbols(), q)),
              **dict(zip(system.constant_symbols(), consts))}
    M = sympy.Matrix(system.mass_matrix).xreplace(rename)
    B = sympy.Matrix(system.guidance).xreplace(rename)
    A = sympy.diag(*[a.xreplace(rename) for a in system.rotor_inertia])
    V = system.potential.xreplace(rename)
    Omega = sympy.Matrix(Om)
    Bt = B.T
    if n:
        Mbar = sympy.BlockMatrix([[M + Bt * A * B, Bt * A], [A * B, A]]).as_explicit()
        p0 = sympy.Matrix.vstack(Bt * A * Omega, A * Omega)
    else:
        Mbar, p0 = A, A * Omega
    vv = sympy.Matrix(v)
    p = Mbar * vv + p0
    L = (vv.T * Mbar * vv)[0, 0] / 2 + (vv.T * p0)[0, 0] - V
    F = []
    for i in range(n + m):
        fi = sympy.diff(L, q[i]) if i < n else sympy.Integer(0)
        fi -= sum((sympy.diff(p[i], q[j]) * v[j] for j in range(n)), sympy.Integer(0))
        F.append(fi)
    F = sympy.Matrix(F)
    kinetic = (vv.T * Mbar * vv)[0, 0] / 2
    if jacobians:
        F_q = F.jacobian(sympy.Matrix(q)) if n else sympy.zeros(n + m, 0)
        F_v = F.jacobian(vv)
    else:
        F_q = F_v = sympy.zeros(0, 0)
    return Equations(n=n, m=m, q=q, v=v, consts=consts, Omega0=Om, Mbar=Mbar, F=F,
                     kinetic=kinetic, V=V, F_q=F_q, F_v=F_v)
