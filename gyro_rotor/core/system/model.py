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

__all__ = ['GeneralModel', 'system_rate', 'joint_names', 'KICK_KEYS']

#: the parts of the state a kick (``perturbation.KEY``) adds to: lengths n, n, m, m
KICK_KEYS = ('q', 'qdot', 'z', 'zdot')


def system_rate(system: RotorSystem) -> float:
    """Return a typical fastest rate [1/s] of a system: the largest field speed, at least 1."""
    return max([1.0] + [abs(d.Omega0) for d in system.drives])


def joint_names(system: RotorSystem) -> tuple:
    """Joint names of a system: its coordinates, then z_ROTOR for each rotor."""
    return tuple(system.coordinates) + tuple(f'z_{r}' for r in system.rotors)


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

    #: the symplectic method of long conservative runs (auto)
    symplectic_method = 'gauss6'

    def drive_rates(self, y) -> tuple[float, float]:
        """Return (drive damping root, fastest oscillation) [1/s] of the linearization at y.

        The root K_D lambda_max(Mbar^-1 on z) (the largest rate of the drive damping, eq. 8,
        through the mass matrix) and the largest |eigenvalue| of the conservative
        linearization at y (at least 1): what auto weighs.
        """
        n, m, N = self.n, self.m, self.N
        Mbar, Fq, Fv = self.lin(y)
        Minv = np.linalg.inv(Mbar)
        Gx = np.zeros((N, N))
        Gx[:, :n] = Fq
        for k, d in enumerate(self.system.drives):
            Gx[n + k, n + k] = -d.K_S
        A = np.block([[np.zeros((N, N)), np.eye(N)], [Minv @ Gx, Minv @ Fv]])
        osc = max(1.0, float(np.abs(np.linalg.eigvals(A)).max()))
        mu = float(np.linalg.eigvalsh(Minv[n:, n:]).max()) if m else 0.0
        return max(d.K_D for d in self.system.drives) * mu, osc

    @property
    def conservative(self) -> bool:
        """Return True without drive damping (every K_D = 0): E* is conserved (eq. 17)."""
        return all(d.K_D == 0.0 for d in self.system.drives)

    # -- the live simulation's interface (gyro_rotor.numerics.live) ------------------------
    #: fields of the ``energy`` array (z and zdot of each rotor are joints)
    energy_fields = ('t_sim', 'E_star', 'dE_dt', 'dissipation', 'residual', 'seq', 'D', 'k')

    @property
    def joint_names(self) -> tuple:
        """Names of the joint_states columns (:func:`joint_names`)."""
        return joint_names(self.system)

    def field_speeds(self) -> np.ndarray:
        """Return the speed Omega0 of each rotor's field (eq. 7)."""
        return np.array([d.Omega0 for d in self.system.drives])

    def state_fields(self, Y) -> dict:
        """Return the ``energy`` fields read off the states: none (z, zdot are joints)."""
        return {}

    def kick(self, y, perturbation) -> np.ndarray:
        """Return the state y with ``perturbation``'s q, qdot, z, zdot added (n, n, m, m)."""
        y = np.array(y, dtype=float)
        for key, sl in zip(KICK_KEYS, self.slices()):
            y[sl] += np.asarray(perturbation[key], dtype=float)
        return y

    def carried_state(self, old: 'GeneralModel', y) -> np.ndarray:
        """Return the state y of the model ``old`` under this model's drives.

        Each rotor keeps its absolute spin Omega0 + zdot (eq. 7): zdot_k jumps by
        -(Omega0_k new - old); every other component is kept.
        """
        y = np.array(y, dtype=float)
        y[self.slices()[3]] -= self.field_speeds() - old.field_speeds()
        return y

    def coordinate_errors(self, Y, R) -> tuple[float, float]:
        """Return the largest (|q - q_ref|, |z - z_ref|) of states Y against R (same times).

        A system file's coordinates q are its own generalized coordinates: compared as
        numbers, as its joints are (:attr:`joint_angles`).
        """
        Y, R = np.asarray(Y, dtype=float), np.asarray(R, dtype=float)
        q, _, z, _ = self.slices()
        return (float(np.max(np.abs(Y[:, q] - R[:, q]), initial=0.0)),
                float(np.max(np.abs(Y[:, z] - R[:, z]), initial=0.0)))

    def quaternion_norm_error(self, Y) -> np.ndarray:
        """Zero: a system file's state holds no quaternion."""
        return np.zeros(np.asarray(Y, dtype=float).shape[:-1])

    #: the joint positions (q, z) are compared as numbers, not modulo 2 pi
    joint_angles = False

    def singular_joints(self, positions) -> frozenset:
        """None: the joints (q, z) always determine the state."""
        return frozenset()

    def state_from_joints(self, positions, velocities, z: float, zdot: float):
        """Return the state of a published joint_states message, the inverse of :meth:`joints`.

        ``positions``/``velocities``: (q, z) and their rates; the separate ``z``, ``zdot``
        are not used (the lags are joints). None for another layout.
        """
        sq, sqd, sz, szd = self.slices()
        n, m = sq.stop - sq.start, sz.stop - sz.start
        if len(positions) != n + m or len(velocities) != n + m:
            return None
        y = np.zeros(self.size)
        y[sq], y[sz] = positions[:n], positions[n:]
        y[sqd], y[szd] = velocities[:n], velocities[n:]
        return y

    def joints(self, Y, field) -> tuple:
        """Return the joint_states of rows of states: (positions, velocities, efforts, None).

        Positions q and the rotor lags z = phi - Omega0 t (eq. 7), as integrated (not
        wrapped: a lag or a coordinate may pass pi), their rates; no efforts and no 3-D
        pose. (``field`` is not used: after a live Omega0 change z is phi minus the field
        angle, continuous, no longer phi - Omega0 t.)
        """
        sq, sqd, sz, szd = self.slices()
        return (np.column_stack([Y[:, sq], Y[:, sz]]), np.column_stack([Y[:, sqd], Y[:, szd]]),
                np.zeros((len(Y), 0)), None)

    def rhs(self, t: float, y) -> np.ndarray:
        """dy/dt at y (the system is autonomous; t is ignored)."""
        out = np.empty(self.size)
        self.compiled.rhs(np.asarray(y, dtype=float), self.P, out)
        return out

    def accelerations(self, y) -> np.ndarray:
        """Return (qddot, zddot) at the state y (zero on a steady motion)."""
        f, (_, sqd, _, szd) = self.rhs(0.0, y), self.slices()
        return np.concatenate([f[sqd], f[szd]])

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

    def singular_at(self, y) -> str:
        """Return '': the mass matrix of a loaded system is positive definite (checked)."""
        return ''

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
