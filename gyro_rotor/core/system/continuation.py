"""A system file's steady motion over the field speed: Newton continuation (Campbell diagrams).

What :meth:`~gyro_rotor.core.system.generated.GeneratedSystem.speed_family` offers; the
built-in centrifuge's steady motion follows its parameters in closed form instead.
"""

from __future__ import annotations

import dataclasses

from gyro_rotor.core.newton import damped_newton
from gyro_rotor.core.system.model import GeneralModel
from gyro_rotor.errors import NoSteadyMotionError
import numpy as np

__all__ = ['Continuation']


class Continuation:
    """A system file's scene at any field speed W: drives scaled, Newton from the nearest.

    Called with W: the scene with every drive's Omega0 scaled by W / Omega0 of the first
    and its steady motion re-solved; an equilibrium (steady.qdot = 0) keeps q, a steady
    motion that moves keeps its non-moving coordinates and the pattern of its rates, whose
    size and the drive lags are solved (:func:`~gyro_rotor.core.newton.damped_newton`,
    continued from the solved speed nearest W). Raises NoSteadyMotionError where none.
    """

    def __init__(self, scene):
        """Keep the scene, its model's compiled code and the steady motion at its speed."""
        self.scene, self.ref = scene, scene.Omega0
        self.model = scene.make_model()
        self.qdot = np.asarray(scene.system.steady_qdot, dtype=float)
        self.moving = bool(np.any(self.qdot != 0))
        # unknowns: the drive lags z and (moving) the size s of the rate pattern
        self.solved = {self.ref: (np.asarray(scene.system.steady_z, dtype=float), 1.0)}

    def __call__(self, W: float):
        """Return the scene at field speed W, its steady motion solved."""
        f = W / self.ref
        drives = [d.replace(Omega0=d.Omega0 * f) for d in self.scene.system.drives]
        sc = dataclasses.replace(self.scene, system=self.scene.system.with_drives(drives))
        z, s = self._steady(sc, GeneralModel(sc.system.reduced, self.model.compiled), W)
        return dataclasses.replace(sc, system=dataclasses.replace(
            sc.system, steady_z=tuple(z.tolist()), steady_qdot=tuple((s * self.qdot).tolist())))

    def _steady(self, sc, mdl, W):
        """Return (z, s) at W: the drive lags and the size of the rate pattern."""
        if W in self.solved:
            return self.solved[W]
        near = min(self.solved, key=lambda w: abs(w - W))
        z, s = self.solved[near]
        m = mdl.m
        q = np.asarray(sc.system.steady_q, dtype=float)

        def acc(u):
            zz, ss = u[:m], (u[m] if self.moving else 1.0)
            return mdl.accelerations(mdl.state(q, ss * self.qdot, zz, np.zeros(m)))
        u = np.concatenate([z, [s]]) if self.moving else z.copy()
        tol = 1e-11 * max(1.0, float(np.abs(self.qdot).max()) ** 2 * max(s, 1.0) ** 2,
                          mdl.rate())
        u, r = damped_newton(acc, u, tol)
        if not (np.all(np.isfinite(r)) and np.abs(r).max() <= 1e3 * tol):
            raise NoSteadyMotionError(
                f'scene {self.scene.name}: no steady motion of its family at Omega0 = {W:.6g} '
                f'rad/s (the rates keep the pattern of steady.qdot, the other coordinates '
                f'stay; largest acceleration {np.abs(r).max():.3g})')
        out = (u[:m], float(u[m]) if self.moving else 1.0)
        self.solved[W] = out
        return out
