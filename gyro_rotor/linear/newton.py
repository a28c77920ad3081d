"""Damped Newton for the steady motions of a system file (and of a Campbell diagram's family).

A steady motion (q0, qdot0, z0, zdot = 0) is where the accelerations vanish with qdot
held (docs/MODEL.md section 8; Magnus 1980, the steady motions I and II of eqs. 20-22
in the centrifuge's case): :func:`solve_steady` solves for (q, z) from a scene's guess.
"""

from __future__ import annotations

import dataclasses
import math

from gyro_rotor.core.scene import Scene
import numpy as np

__all__ = ['damped_newton', 'solve_steady', 'steady_motions', 'SteadyMotions']


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
    x = np.concatenate([scene.system.steady_q, scene.system.steady_z]).astype(float)

    def acc(x):
        return model.accelerations(model.state(x[:n], scene.system.steady_qdot, x[n:],
                                               np.zeros(m)))
    x, r = damped_newton(acc, x, 1e-13 * max(1.0, model.rate()), max_iter=max_iter,
                         min_step=1e-4)
    return x[:n], x[n:], float(np.abs(r).max())


@dataclasses.dataclass(frozen=True)
class SteadyMotions:
    """A scene's steady motions in words (:func:`steady_motions`).

    ``head``: the parameters or the guess they come from; ``lines``: one per motion (and
    note); ``found``: every motion asked for exists.
    """

    head: str
    lines: list
    found: bool


def steady_motions(scene: Scene, theta0: float | None = None) -> SteadyMotions:
    """Return the steady motions the scene's system offers.

    The built-in centrifuge: solution I and solution II on both branches in closed form
    (Magnus 1980, eqs. 20-22; ``theta0``: the tilt of II, default the scene's, else 0.1);
    a system file: Newton from the scene's guess (:func:`solve_steady`).
    """
    return (_closed_form if scene.builtin else _from_guess)(scene, theta0)


def _closed_form(scene: Scene, theta0: float | None) -> SteadyMotions:
    """Solutions I and II (both branches) of the centrifuge, exact and by eq. (22)."""
    from gyro_rotor.core.steady import steady_motion
    from gyro_rotor.errors import NoSteadyMotionError
    p = scene.system.params
    if theta0 is None:
        theta0 = scene.system.initial.theta0 if scene.system.initial.theta0 > 0 else 0.1
    lines = ['I:  theta = 0, psidot = 0, rotor at Omega0 about the vertical, housing at rest']
    found = True
    for branch in (1, 2):
        try:
            sm = steady_motion(p, theta0, branch)
        except NoSteadyMotionError as err:
            lines.append(f'II branch {branch}: {err}')
            found = False
            continue
        eq22 = (f'eq. (22) corrected: {sm.psidot0_eq22:.12g} rad/s; relative difference '
                f'{sm.relative_difference:+.3e}' if math.isfinite(sm.psidot0_eq22) else
                'eq. (22) corrected: not defined here (no real root, or cos(theta0) = 0)')
        lines.append(f'{sm.name}: theta0 = {sm.theta0:.6g} rad, psidot0 = {sm.psidot0:.12g} '
                     f'rad/s (exact); {eq22}')
    return SteadyMotions(f'Omega0 = {p.Omega0:g} rad/s, I = {p.I:g} kg m^2, C_R = {p.C_R:g}, '
                         f'G s = {p.Gs:g} N m, c_theta = {p.c_theta:g} N m/rad', lines, found)


def _from_guess(scene: Scene, theta0: float | None) -> SteadyMotions:
    """Return the accelerations at the scene's guess and the steady motion Newton finds.

    Raises ParameterError for a ``theta0`` (the tilt of the centrifuge's solution II).
    """
    import json
    from gyro_rotor.core.scene import steady_residual
    from gyro_rotor.errors import ParameterError
    if theta0 is not None:
        raise ParameterError(
            f'--theta0 applies to the centrifuge (its solution II, tilted by theta0); scene '
            f'{scene.name} runs system {scene.system_name}, whose steady motion Newton solves '
            "from the scene's steady guess: set that with --set steady.q=[...]")
    acc = steady_residual(scene)
    names = [f'{c}_ddot' for c in scene.system.coordinates] + [
        f'zddot_{r}' for r in scene.system.rotors]
    q, z, res = solve_steady(scene)
    ok = res <= 1e-9 * max(1.0, scene.make_model().rate())
    lines = ['accelerations there: ' + ', '.join(f'{a} = {v:.3g}' for a, v in zip(names, acc)),
             f'{"steady motion" if ok else "no steady motion found"} (Newton, qdot held): '
             f'q = {q.tolist()}, z = {z.tolist()}, largest acceleration {res:.3g}']
    if ok:
        lines.append('for the scene: steady: {q: ' + json.dumps(q.tolist()) + ', z: '
                     + json.dumps(z.tolist()) + '}')
    sm = scene.system
    return SteadyMotions(f'steady guess q = {list(sm.steady_q)}, qdot = '
                         f'{list(sm.steady_qdot)}, z = {list(sm.steady_z)}', lines, ok)
