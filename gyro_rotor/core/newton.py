"""Damped Newton, and a system's steady motions in words (:class:`SteadyMotions`).

A steady motion (q0, qdot0, z0, zdot = 0) is where the accelerations vanish with qdot
held (docs/MODEL.md section 8). Every system offers its own as
:class:`SteadyMotions` (``steady_motions``): the built-in centrifuge in closed form (Magnus
1980, solutions I and II, eqs. 20-22), a system file's by :func:`damped_newton` from its
scene's guess.
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ['damped_newton', 'SteadyMotions']


def damped_newton(acc, u, tol: float, *, max_iter: int = 60,
                  min_step: float = 1e-6) -> tuple:
    """Solve acc(u) = 0 for u by damped Newton; return (u, acc(u)).

    The Jacobian by central differences (steps 1e-7 max(1, |u_j|)), the Newton step by
    least squares (a rank-deficient Jacobian: a cyclic coordinate), halved down to
    ``min_step`` until |acc| falls; stops at |acc| <= tol, at a non-finite acc or after
    ``max_iter`` steps. The steady motions of a system file
    (:meth:`~gyro_rotor.core.system.generated.GeneratedSystem.steady_motions`) and of a
    Campbell diagram's family (:mod:`gyro_rotor.linear.campbell`) are solved by it.
    """
    u = np.array(u, dtype=float)
    r = acc(u)
    for _ in range(max_iter):
        if not np.all(np.isfinite(r)) or np.abs(r).max() <= tol:
            break
        J = np.empty((len(r), len(u)))
        for j in range(len(u)):
            h = 1e-7 * max(1.0, abs(u[j]))
            e = np.zeros(len(u))
            e[j] = h
            J[:, j] = (acc(u + e) - acc(u - e)) / (2 * h)
        du = np.linalg.lstsq(J, -r, rcond=None)[0]
        step = 1.0
        while step > min_step:
            r_new = acc(u + step * du)
            if np.all(np.isfinite(r_new)) and np.abs(r_new).max() < np.abs(r).max():
                break
            step *= 0.5
        u = u + step * du
        r = acc(u)
    return u, r


@dataclasses.dataclass(frozen=True)
class SteadyMotions:
    """A scene's steady motions in words (its system's ``steady_motions``).

    ``head``: the parameters or the guess they come from; ``lines``: one per motion (and
    note); ``found``: every motion asked for exists.
    """

    head: str
    lines: list
    found: bool
