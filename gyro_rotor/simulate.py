"""Simulation driver: a scene in, a :class:`Trajectory` out (pure Python, no rclpy).

``simulate(scene)`` integrates the scene's model from its initial condition and samples
the solution at ``rate`` Hz with the integrator's dense output. The integrator is scipy's
``solve_ivp`` with DOP853 (order 8) by default (Radau IIA where the drive damping makes
the scene stiff, see :func:`choose_method`), at tolerances tight enough that every
shipped scene is accurate to 1e-8 or better in the symmetry-axis direction over its
duration (``test/test_simulate.py`` checks it against a run at 100 times tighter
tolerances); ``method``, ``rtol`` and ``atol`` override.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any, Mapping

import numpy as np

from gyro_rotor.errors import IntegrationError, ParameterError
from gyro_rotor.model import Model
from gyro_rotor.scene import Scene, load_scene

__all__ = ['Trajectory', 'simulate', 'DEFAULT_METHOD', 'DEFAULT_RTOL', 'DEFAULT_ATOL',
           'CSV_COLUMNS', 'check_tolerances']

DEFAULT_METHOD = 'auto'
#: stiffness indicator K_D (1/C_R + 1/C_M) [1/s] above which 'auto' takes an implicit method
STIFF_RATE = 1e4
DEFAULT_RTOL = 1e-11
DEFAULT_ATOL = 1e-12
DEFAULT_RATE = 100.0

CSV_COLUMNS = ('t', 'theta', 'psi', 'phi_R', 'phi_M', 'thetadot', 'psidot', 'phi_R_dot',
               'phi_M_dot', 'axis_x', 'axis_y', 'axis_z', 'chi', 'z', 'zdot', 'Q', 'E_star',
               'dE_dt', 'residual', 'qnorm_error')


@dataclasses.dataclass
class Trajectory:
    """A sampled solution: times ``t`` (m,), states ``y`` (m, n) and derived outputs."""

    scene: Scene
    model: Model
    t: np.ndarray
    y: np.ndarray
    out: dict
    method: str
    rtol: float
    atol: float
    nfev: int
    nsteps: int
    wall_time: float
    success: bool = True
    message: str = ''

    def __getattr__(self, name: str) -> Any:
        out = self.__dict__.get('out')
        if out is not None and name in out:
            return out[name]
        raise AttributeError(name)

    @property
    def max_abs_residual(self) -> float:
        """max |r(t)| over the samples."""
        return float(np.max(np.abs(self.out['residual'])))

    @property
    def max_qnorm_drift(self) -> float:
        """max ||q| - 1| over the samples."""
        return float(np.max(np.abs(self.out['qnorm_error'])))

    def columns(self) -> dict:
        """The CSV columns (see CSV_COLUMNS) as arrays."""
        o = self.out
        cols = {k: o[k] for k in CSV_COLUMNS if k in o}
        cols['axis_x'], cols['axis_y'], cols['axis_z'] = o['axis'].T
        return {k: np.asarray(cols[k]) for k in CSV_COLUMNS}

    def save(self, path: str) -> None:
        """Write a CSV (header row) or NPZ file, by the suffix of ``path``."""
        cols = self.columns()
        if str(path).endswith('.npz'):
            np.savez_compressed(path, y=self.y, state_names=np.array(self.model.state_names),
                                **cols)
        elif str(path).endswith('.csv'):
            data = np.column_stack([cols[k] for k in CSV_COLUMNS])
            np.savetxt(path, data, delimiter=',', header=','.join(CSV_COLUMNS), comments='',
                       fmt='%.17g')
        else:
            raise ParameterError(f'--out must end in .csv or .npz, got {path}')

    def summary(self) -> dict:
        """Numbers for a printed summary."""
        o = self.out
        return {
            'scene': self.scene.name, 'model': self.model.name, 'method': self.method,
            'rtol': self.rtol, 'atol': self.atol, 't_end': float(self.t[-1]),
            'samples': len(self.t), 'theta_end': float(o['theta'][-1]),
            'psidot_end': float(o['psidot'][-1]), 'chi_end': float(o['chi'][-1]),
            'z_end': float(o['z'][-1]), 'zdot_end': float(o['zdot'][-1]),
            'E_star_first': float(o['E_star'][0]), 'E_star_last': float(o['E_star'][-1]),
            'max_abs_residual': self.max_abs_residual,
            'max_qnorm_drift': self.max_qnorm_drift, 'nfev': self.nfev,
            'nsteps': self.nsteps, 'wall_time': self.wall_time,
        }


def choose_method(scene: Scene) -> str:
    """'auto': DOP853, or Radau where the drive damping makes the scene stiff.

    The drive has a real root near -K_D (1/C_R + 1/C_M); above STIFF_RATE an explicit
    method would need steps near its inverse.
    """
    return 'Radau' if scene.params.stiff_rate() > STIFF_RATE else 'DOP853'


def check_tolerances(rtol: float, atol: float) -> None:
    """Refuse non-positive or non-finite tolerances (scipy would only warn)."""
    for name, v in (('rtol', rtol), ('atol', atol)):
        if not (np.isfinite(v) and v > 0):
            raise ParameterError(f'{name} must be positive and finite, got {v!r}')


def simulate(scene: Scene | str = 'precession', *, t_end: float | None = None,
             rate: float = DEFAULT_RATE, method: str = DEFAULT_METHOD,
             rtol: float | None = None, atol: float | None = None,
             overrides: Mapping[str, Any] | None = None,
             y0: np.ndarray | None = None) -> Trajectory:
    """Integrate a scene and return its sampled trajectory.

    Parameters
    ----------
    scene : Scene or str
        A loaded scene, or a scene name / path for :func:`~gyro_rotor.scene.load_scene`.
    t_end : float, optional
        Duration [s]; default the scene's ``t_end``.
    rate : float
        Sample rate of the output [Hz] (the integrator's steps are independent of it).
    method, rtol, atol
        Integrator (a scipy ``solve_ivp`` method name) and tolerances.
    overrides : mapping, optional
        Flat scene keys to change (e.g. ``{'K_D': 0.1}``), validated like the file.
    y0 : ndarray, optional
        Initial state instead of the scene's.
    """
    from scipy.integrate import solve_ivp
    if isinstance(scene, Scene):
        if overrides:
            raise ParameterError('overrides need a scene name or path, not a loaded Scene')
    else:
        scene = load_scene(scene, overrides=overrides)
    t_end = scene.t_end if t_end is None else float(t_end)
    if not (np.isfinite(t_end) and t_end > 0):
        raise ParameterError(f't_end must be positive and finite, got {t_end!r}')
    if not (np.isfinite(rate) and rate > 0):
        raise ParameterError(f'rate must be positive and finite, got {rate!r}')
    rtol = DEFAULT_RTOL if rtol is None else float(rtol)
    atol = DEFAULT_ATOL if atol is None else float(atol)
    check_tolerances(rtol, atol)
    method = choose_method(scene) if method == 'auto' else method
    model = scene.make_model()
    y_init = scene.initial_state(model) if y0 is None else np.asarray(y0, dtype=float)
    if y_init.shape != (model.n,) or not np.all(np.isfinite(y_init)):
        raise ParameterError(f'the initial state must be {model.n} finite numbers')
    n = int(np.floor(t_end * rate + 1e-9))
    t_eval = np.arange(n + 1) / rate
    if t_eval[-1] < t_end - 1e-12:
        t_eval = np.append(t_eval, t_end)
    t0 = time.perf_counter()
    try:
        sol = solve_ivp(model.rhs, (0.0, t_end), y_init, method=method, t_eval=t_eval,
                        rtol=rtol, atol=atol)
    except ValueError as err:
        raise ParameterError(f'integrator {method}: {err}') from err
    wall = time.perf_counter() - t0
    if sol.status < 0 or not np.all(np.isfinite(sol.y)):
        raise IntegrationError(f'integration of scene {scene.name} failed at '
                               f't = {sol.t[-1] if sol.t.size else 0.0}: {sol.message}')
    Y = sol.y.T
    return Trajectory(scene=scene, model=model, t=sol.t, y=Y, out=model.outputs(sol.t, Y),
                      method=method, rtol=rtol, atol=atol, nfev=int(sol.nfev),
                      nsteps=int(getattr(sol, 'nsteps', 0) or 0), wall_time=wall,
                      success=sol.success, message=sol.message)
