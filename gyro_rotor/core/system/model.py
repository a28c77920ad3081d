"""The model of a rotor system: compiled equations with numbers bound (Magnus 1980, eqs. 1-17).

State ``y = (q, qdot, z, zdot, D)``, length 2 (n + m) + 1, with z = phi - Omega0 t
(eq. 7) and D the work dissipated by the drives (dD/dt = zdot' K_D zdot). The
energy-balance residual r = E* - E*(0) + D is zero along exact solutions of any system
(eq. 17: E* is the Jacobi integral in (q, z)), so it measures the integration error.
"""

from __future__ import annotations

from gyro_rotor.core.system.codegen import compile_system, CompiledSystem, pack
from gyro_rotor.core.system.system_file import RotorSystem
from gyro_rotor.errors import ParameterError
import numpy as np

__all__ = ['GeneralModel', 'system_rate']


def system_rate(system: RotorSystem) -> float:
    """Return a typical fastest rate [1/s] of a system: the largest field speed, at least 1."""
    return max([1.0] + [abs(d.Omega0) for d in system.drives])


class GeneralModel:
    """Equations of motion of a :class:`RotorSystem` with its numbers bound (module doc)."""

    def __init__(self, system: RotorSystem, compiled: CompiledSystem | None = None):
        """Bind the numbers of ``system`` to its compiled equations (compiled if needed)."""
        self.system = system
        self.compiled = compiled or compile_system(system)
        self.P = pack(system)
        self.n, self.m = system.n, system.m
        self.N = self.n + self.m
        self.size = 2 * self.N + 1
        self.iD = 2 * self.N

    @property
    def name(self) -> str:
        """Return the model's name: ``system NAME``."""
        return f'system {self.system.name}'

    @property
    def params(self) -> RotorSystem:
        """Return the system with its numbers (what the centrifuge model calls params)."""
        return self.system

    @property
    def idiss(self) -> int:
        """Return the index of the dissipated work D in the state."""
        return self.iD

    @property
    def state_names(self) -> tuple:
        """Names of the state components: q, NAME_dot, z_ROTOR, zdot_ROTOR, D."""
        s = self.system
        return (tuple(s.coordinates) + tuple(f'{c}_dot' for c in s.coordinates)
                + tuple(f'z_{r}' for r in s.rotors) + tuple(f'zdot_{r}' for r in s.rotors)
                + ('D',))

    def slices(self) -> tuple:
        """Slices of q, qdot, z, zdot in the state."""
        n, m = self.n, self.m
        return (slice(0, n), slice(n, 2 * n), slice(2 * n, 2 * n + m),
                slice(2 * n + m, 2 * n + 2 * m))

    def state(self, q=(), qdot=(), z=(), zdot=(), D: float = 0.0) -> np.ndarray:
        """Pack a state vector (lengths n, n, m, m)."""
        return np.concatenate([np.asarray(q, float).reshape(self.n),
                               np.asarray(qdot, float).reshape(self.n),
                               np.asarray(z, float).reshape(self.m),
                               np.asarray(zdot, float).reshape(self.m), [D]])

    def rhs(self, t: float, y) -> np.ndarray:
        """dy/dt at y (the system is autonomous; t is ignored)."""
        out = np.empty(self.size)
        self.compiled.rhs(np.asarray(y, dtype=float), self.P, out)
        return out

    def lin(self, y) -> tuple:
        """(Mbar, dF/dq, dF/dv) at the state y as arrays (exact derivatives, no drive terms).

        Raises :class:`ParameterError` where an expression of the system is not defined
        (a square root or logarithm of a negative number, a division by zero).
        """
        N, n = self.N, self.n
        try:
            parts = self.compiled.module.lin(np.asarray(y, dtype=float), self.P)
        except (ValueError, ZeroDivisionError, OverflowError) as err:
            raise ParameterError(f'system {self.system.name}: an expression is not defined at '
                                 f'q = {np.asarray(y)[:n].tolist()}: {err}') from None
        return tuple(np.array(a, dtype=float).reshape(s)
                     for a, s in zip(parts, ((N, N), (N, n), (N, N))))

    def energy(self, Y) -> np.ndarray:
        """E* (eq. 13) of one state or of rows of states."""
        Y = np.asarray(Y, dtype=float)
        if Y.ndim == 1:
            return np.float64(self.compiled.energy(Y, self.P))
        return np.array([self.compiled.energy(y, self.P) for y in Y])

    def dissipation(self, Y) -> np.ndarray:
        """Power of the drive damping zdot' K_D zdot (= -dE*/dt, eq. 17) of rows of states."""
        Y = np.atleast_2d(np.asarray(Y, dtype=float))
        zdot = Y[:, self.slices()[3]]
        return (zdot * zdot) @ np.array([d.K_D for d in self.system.drives])

    def residual(self, Y, E0: float | None = None) -> np.ndarray:
        """Energy-balance residual r = E* - E*(0) + D of rows of states (eq. 17)."""
        Y = np.atleast_2d(np.asarray(Y, dtype=float))
        E = self.energy(Y)
        if E0 is None:
            E0 = E[0] + Y[0, self.iD]
        return E - E0 + Y[:, self.iD]

    def rate(self) -> float:
        """Return a typical fastest rate [1/s] of the system, for the first step size."""
        return system_rate(self.system)
