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

    # -- outputs of a trajectory (the interface the centrifuge's models present too) --------
    def outputs(self, t, Y) -> dict:
        """Return the outputs of a trajectory (``t`` (k,), states ``Y`` (k, 2 N + 1)).

        Each coordinate NAME and its rate NAME_dot, each rotor's lag z_ROTOR (eq. 7) and
        z_ROTOR_dot, E* (eq. 13), dE*/dt = -zdot' K_D zdot (eq. 17), the dissipation and
        the energy-balance residual.
        """
        Y = np.atleast_2d(np.asarray(Y, dtype=float))
        sq, sqd, sz, szd = self.slices()
        s = self.system
        out = {'t': np.asarray(t, dtype=float)}
        for i, c in enumerate(s.coordinates):
            out[c], out[f'{c}_dot'] = Y[:, sq][:, i], Y[:, sqd][:, i]
        for k, r in enumerate(s.rotors):
            out[f'z_{r}'], out[f'z_{r}_dot'] = Y[:, sz][:, k], Y[:, szd][:, k]
        diss = self.dissipation(Y)
        out.update({'E_star': self.energy(Y), 'dE_dt': -diss, 'dissipation': diss,
                    'residual': self.residual(Y)})
        return out

    def csv_columns(self) -> tuple:
        """Return the CSV columns (name, unit, output key, None), as the centrifuge's.

        A system file gives no units: a coordinate is in SI units (rad or m, as its
        constants make it), its rate in SI/s.
        """
        s = self.system
        return (('t', 's', 't', None),
                *((c, 'SI', c, None) for c in s.coordinates),
                *((f'{c}_dot', 'SI/s', f'{c}_dot', None) for c in s.coordinates),
                *((f'z_{r}', 'rad', f'z_{r}', None) for r in s.rotors),
                *((f'z_{r}_dot', 'rad/s', f'z_{r}_dot', None) for r in s.rotors),
                ('E_star', 'J', 'E_star', None), ('dE_dt', 'W', 'dE_dt', None),
                ('residual', 'J', 'residual', None))

    def final_state(self) -> tuple:
        """Return the names of the CSV columns a summary prints at the end of a run."""
        return tuple(n for n, *_ in self.csv_columns()[1:-3])
