"""Damped Newton for the steady motions of a system file (and of a Campbell diagram's family).

A steady motion (q0, qdot0, z0, zdot = 0) is where the accelerations vanish with qdot
held (docs/MODEL.md section 8; Magnus 1980, the steady motions I and II of eqs. 20-22
in the centrifuge's case): :func:`solve_steady` solves for (q, z) from a scene's guess.
"""

from __future__ import annotations

from gyro_rotor.core.scene import Scene
import numpy as np

__all__ = ['damped_newton', 'solve_steady']


def damped_newton(acc, u, tol: float, *, max_iter: int = 60,
                  min_step: float = 1e-6) -> tuple:
    """Solve acc(u) = 0 for u by damped Newton; return (u, acc(u)).

    The Jacobian by central differences (steps 1e-7 max(1, |u_j|)), the Newton step by
    least squares (a rank-deficient Jacobian: a cyclic coordinate), halved down to
    ``min_step`` until |acc| falls; stops at |acc| <= tol, at a non-finite acc or after
    ``max_iter`` steps. The steady motions of a system file (:func:`solve_steady`) and of
    a Campbell diagram's family (:mod:`gyro_rotor.linear.campbell`) are solved by it.
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


def solve_steady(scene: Scene, *, max_iter: int = 50) -> tuple:
    """Newton for (q, z) with qdot = steady.qdot held: the accelerations vanish.

    Returns (q, z, largest |acceleration|) from the scene's steady guess.
    """
    model = scene.make_model()
    n, m = model.n, model.m
    x = np.concatenate([scene.steady_q, scene.steady_z]).astype(float)

    def acc(x):
        y = model.state(x[:n], scene.steady_qdot, x[n:], np.zeros(m))
        f = model.rhs(0.0, y)
        return np.concatenate([f[n:2 * n], f[2 * n + m:2 * n + 2 * m]])
    x, r = damped_newton(acc, x, 1e-13 * max(1.0, model.rate()), max_iter=max_iter,
                         min_step=1e-4)
    return x[:n], x[n:], float(np.abs(r).max())
