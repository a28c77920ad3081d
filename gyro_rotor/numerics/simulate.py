"""Simulation driver: a scene of any system in, a :class:`Trajectory` out (no rclpy).

``simulate(scene)`` integrates the scene's model from its initial condition and samples
the solution at ``rate`` Hz. The integrator is chosen per scene by default
(:func:`auto_method`, one rule for every system: the cheapest compiled explicit pair of
:mod:`gyro_rotor.numerics.integrators` for the tolerance and sample rate by its measured
cost model, Radau9 where the drive damping makes the scene stiff, the symplectic method
for long conservative runs), at
tolerances tight enough that every shipped scene is accurate to 1e-8 or better in the
symmetry-axis direction over its duration (``test/test_accuracy.py`` checks it against a
run at 100 times tighter tolerances); ``method``, ``rtol``, ``atol`` and ``step``
override, and scipy's ``solve_ivp`` methods stay selectable by their names.

One CSV format for every system (:meth:`Trajectory.save`): a header row of ``name [unit]``,
then one row per sample; the columns are the model's (``model.csv_columns()``): ``t``, the
coordinates by name and their rates ``NAME_dot``, then the rotor lags (``z``, or
``z_ROTOR`` for each rotor of a system file) and their rates, E*, dE*/dt and the
energy-balance residual (the centrifuge adds its axis, twist chi, drive torque Q and the
quaternion's norm error).
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any, Mapping

from gyro_rotor.core.model import AXIS_DOWN, Model
from gyro_rotor.core.scene import load_scene, Scene
from gyro_rotor.errors import IntegrationError, ParameterError
from gyro_rotor.numerics.defaults import (DEFAULT_ATOL, DEFAULT_RATE, DEFAULT_RTOL,
                                          SCIPY_METHODS)
from gyro_rotor.numerics.integrators import (choose_method as choose_integrator,
                                             integrate as integrate_kernels, make_integrator)
from gyro_rotor.numerics.integrators.primitives import Status
from gyro_rotor.numerics.kernel_system import kernel_model, methods_for
import numpy as np

__all__ = ['Trajectory', 'simulate', 'integrate', 'Run', 'DEFAULT_METHOD', 'DEFAULT_RTOL',
           'DEFAULT_ATOL', 'check_tolerances', 'auto_method', 'SCIPY_METHODS']

DEFAULT_METHOD = 'auto'
#: most output samples of one simulate() call (t_end x rate)
MAX_SAMPLES = 5e7


@dataclasses.dataclass
class Trajectory:
    """A sampled solution: times ``t`` (m,), states ``y`` (m, n) and derived outputs."""

    scene: Scene
    model: Model
    t: np.ndarray
    y: np.ndarray
    out: dict
    method: str
    #: tolerances the method used (None for a fixed-step method, which uses ``step``)
    rtol: float | None
    atol: float | None
    nfev: int
    nsteps: int
    wall_time: float
    success: bool = True
    message: str = ''
    #: why 'auto' chose this method ('' when the method was given)
    method_reason: str = ''
    #: step of a fixed-step method [s] (None for adaptive methods)
    step: float | None = None
    #: the run stopped early because its step budget ran out (not a divergence)
    budget: bool = False

    @property
    def setting(self) -> str:
        """Return the method's setting as text: its tolerances, or its fixed step."""
        parts = []
        if self.rtol is not None:
            parts.append(f'rtol {self.rtol:g}, atol {self.atol:g}')
        if self.step is not None:
            parts.append(f'fixed step {self.step:.3g} s')
        return '; '.join(parts)

    def __getattr__(self, name: str) -> Any:
        out = self.__dict__.get('out')
        if out is not None and name in out:
            return out[name]
        raise AttributeError(name)

    @property
    def max_abs_residual(self) -> float:
        """Return max |r(t)| over the samples."""
        return float(np.max(np.abs(self.out['residual'])))

    @property
    def max_qnorm_drift(self) -> float:
        """Return max ||q| - 1| over the samples (0 for a model without a quaternion)."""
        q = self.out.get('qnorm_error')
        return 0.0 if q is None else float(np.max(np.abs(q)))

    def head(self, n: int) -> 'Trajectory':
        """Return the trajectory of the first ``n`` samples (every output cut with them)."""
        m = len(self.t)
        out = {k: v[:n] if isinstance(v, np.ndarray) and v.ndim and len(v) == m else v
               for k, v in self.out.items()}
        return dataclasses.replace(self, t=self.t[:n], y=self.y[:n], out=out)

    def columns(self) -> dict:
        """Return the CSV columns as arrays, by name (those the model lists)."""
        o = self.out
        return {name: np.asarray(o[key] if comp is None else o[key][:, comp])
                for name, _, key, comp in self.model.csv_columns()}

    def units(self) -> dict:
        """Return the unit of each CSV column, by name."""
        return {name: unit for name, unit, *_ in self.model.csv_columns()}

    def save(self, path: str) -> None:
        """Write a CSV (a header row of name [unit]) or NPZ file, by the suffix of ``path``."""
        cols = self.columns()
        if str(path).endswith('.npz'):
            np.savez_compressed(path, y=self.y, state_names=np.array(self.model.state_names),
                                **cols)
        elif str(path).endswith('.csv'):
            units = self.units()
            np.savetxt(path, np.column_stack(list(cols.values())), delimiter=',',
                       header=','.join(f'{k} [{units[k]}]' for k in cols), comments='',
                       fmt='%.17g')
        else:
            raise ParameterError(f'--out must end in .csv or .npz, got {path}')

    def summary(self) -> dict:
        """Numbers for a printed summary; ``final``: (name, value, unit) at the end."""
        cols, units = self.columns(), self.units()
        return {
            'scene': self.scene.name, 'model': self.model.name, 'method': self.method,
            'rtol': self.rtol, 'atol': self.atol, 'step': self.step, 'setting': self.setting,
            't_end': float(self.t[-1]), 'samples': len(self.t),
            'final': [(k, float(cols[k][-1]), units[k]) for k in self.model.final_state()],
            'E_star_first': float(self.out['E_star'][0]),
            'E_star_last': float(self.out['E_star'][-1]),
            'max_abs_residual': self.max_abs_residual,
            'max_qnorm_drift': self.max_qnorm_drift, 'nfev': self.nfev,
            'nsteps': self.nsteps, 'wall_time': self.wall_time,
            'method_reason': self.method_reason,
        }


def auto_method(scene: Scene, t_end: float | None = None, rtol: float | None = None,
                rate: float = 0.0, model=None, y0: np.ndarray | None = None) -> tuple[str, str]:
    """Return the integrator for this scene and the reason (method 'auto').

    :func:`gyro_rotor.numerics.integrators.choose_method`, one rule for every system:
    radau9 where the drive damping makes the run stiff, the symplectic method for long
    conservative runs, otherwise the cheapest of dop853, vern7, vern8, vern9 for ``rtol``
    (default DEFAULT_RTOL) with samples at ``rate`` Hz by the measured cost model; a system
    file's model is judged at ``y0`` (default: the scene's initial state).
    """
    model = model or scene.make_model()
    return choose_integrator(model, scene.t_end if t_end is None else t_end,
                             DEFAULT_RTOL if rtol is None else rtol, rate,
                             scene.initial_state(model) if y0 is None else y0)


def check_tolerances(rtol: float, atol: float) -> None:
    """Refuse non-positive or non-finite tolerances (scipy would only warn)."""
    for name, v in (('rtol', rtol), ('atol', atol)):
        if not (np.isfinite(v) and v > 0):
            raise ParameterError(f'{name} must be positive and finite, got {v!r}')


def _initial_state(scene: Scene, model: Model, y0) -> np.ndarray:
    """Return the initial state (``y0`` or the scene's), refused unless it and E* are finite."""
    y_init = scene.initial_state(model) if y0 is None else np.asarray(y0, dtype=float)
    size = len(model.state_names)
    if y_init.shape != (size,) or not np.all(np.isfinite(y_init)):
        raise ParameterError(f'the initial state must be {size} finite numbers')
    with np.errstate(over='ignore', invalid='ignore'):
        E_init = float(np.asarray(model.energy(y_init)).reshape(-1)[0])
    if not np.isfinite(E_init):
        raise ParameterError(f'the initial state has E* = {E_init} J (eq. 13), not a finite '
                             'number: its values are too large')
    return y_init


def simulate(scene: Scene | str = 'precession', *, t_end: float | None = None,
             rate: float = DEFAULT_RATE, method: str = DEFAULT_METHOD,
             rtol: float | None = None, atol: float | None = None,
             overrides: Mapping[str, Any] | None = None,
             y0: np.ndarray | None = None, step: float | None = None,
             keep_failed: bool = False) -> Trajectory:
    """Integrate a scene and return its sampled trajectory.

    Parameters
    ----------
    scene : Scene or str
        A loaded scene, or a scene name / path for :func:`~gyro_rotor.core.scene.load_scene`.
    t_end : float, optional
        Duration [s]; default the scene's ``t_end``.
    rate : float
        Sample rate of the output [Hz] (the integrator's steps are independent of it).
    method : str
        'auto' (:func:`auto_method`, the reason lands in ``Trajectory.method_reason``), a
        method of :mod:`gyro_rotor.numerics.integrators` (rk4, rk8, dop853, vern7, vern8,
        vern9, gauss6, rodas4, radau9, split8) or a
        scipy ``solve_ivp`` name (DOP853, RK45, RK23, Radau, BDF, LSODA) as a baseline.
    rtol, atol : float, optional
        Tolerances of adaptive methods (split8 derives its step from rtol); a fixed-step
        method's trajectory reports None for them.
    step : float, optional
        Step of the fixed-step methods (rk4, rk8, gauss6, split8) [s]; default from the
        model's fastest rate.
    overrides : mapping, optional
        Flat scene keys to change (e.g. ``{'K_D': 0.1}``), validated like the file.
    y0 : ndarray, optional
        Initial state instead of the scene's.
    keep_failed : bool
        A run that stops early (a non-finite state, the model's singularity) raises
        :class:`IntegrationError`; with ``keep_failed`` it returns its finite samples up to
        there instead, ``success`` False and ``message`` saying why.
    """
    scene = _load(scene, overrides)
    t_end = scene.t_end if t_end is None else float(t_end)
    if not (np.isfinite(t_end) and t_end > 0):
        raise ParameterError(f't_end must be positive and finite, got {t_end!r}')
    if not (np.isfinite(rate) and rate > 0):
        raise ParameterError(f'rate must be positive and finite, got {rate!r}')
    rtol = DEFAULT_RTOL if rtol is None else float(rtol)
    atol = DEFAULT_ATOL if atol is None else float(atol)
    check_tolerances(rtol, atol)
    reason = ''
    model = scene.make_model()
    own = methods_for(model)
    if method not in ('auto',) + own and method not in SCIPY_METHODS:
        raise ParameterError(f"unknown integrator '{method}' for system {scene.system_name}; "
                             f"valid: auto, {', '.join(own)}, {', '.join(SCIPY_METHODS)}")
    y_init = _initial_state(scene, model, y0)
    if method == 'auto':
        method, reason = auto_method(scene, t_end, rtol, rate, model, y_init)
    t_eval = _sample_times(t_end, rate)
    if method in own:
        run = _run_own(kernel_model(model), y_init, t_eval, method, rtol, atol, step)
    else:
        run = _run_scipy(scene, model, y_init, t_eval, method, rtol, atol)
    success = not (run.status < 0 or not np.all(np.isfinite(run.y)))
    message = run.message
    if not success:
        message = _failure(scene, model, method, run)
        finite = np.all(np.isfinite(run.y), axis=1) if run.y.size else np.zeros(0, bool)
        n = int(np.argmin(finite)) if not finite.all() else len(finite)
        if not (keep_failed and n):
            raise IntegrationError(message)
        run.t, run.y = run.t[:n], run.y[:n]
    return Trajectory(scene=scene, model=model, t=run.t, y=run.y,
                      out=model.outputs(run.t, run.y), method=method, rtol=run.rtol,
                      atol=run.atol, nfev=int(run.nfev), nsteps=int(run.nsteps),
                      wall_time=run.wall, success=success, message=message,
                      method_reason=reason, step=run.step,
                      budget=method in own and run.status == Status.BUDGET)


@dataclasses.dataclass
class Run:
    """Samples of one :func:`integrate` run: times ``t`` (k,), states ``y`` (k, n), counters."""

    t: np.ndarray
    y: np.ndarray
    method: str
    nfev: int
    nsteps: int
    nrejected: int


def integrate(model, y0, t_eval, *, method: str = 'auto', rtol: float = 1e-9,
              atol: float = 1e-12, step: float | None = None,
              max_steps: int = 50_000_000) -> Run:
    """Integrate any model from ``y0`` at ``t_eval[0]``, sampled at ``t_eval`` (2 or more times).

    ``model``: a centrifuge model or a system file's
    (:class:`~gyro_rotor.core.system.model.GeneralModel`); ``method`` 'auto' is the one rule
    of every system (:func:`gyro_rotor.numerics.integrators.choose_method`), otherwise one
    of :func:`~gyro_rotor.numerics.kernel_system.methods_for` the model. Raises
    :class:`IntegrationError` if the run stops early (the message says why).
    """
    size = len(model.state_names)
    y0 = np.asarray(y0, dtype=float).reshape(-1)
    te = np.asarray(t_eval, dtype=float).reshape(-1)
    if y0.size != size or not np.all(np.isfinite(y0)):
        raise ParameterError(f'the initial state must be {size} finite numbers, got '
                             f'{y0.tolist()}')
    if te.size < 2 or not np.all(np.isfinite(te)) or np.any(np.diff(te) <= 0):
        raise ParameterError('t_eval must be a finite, increasing array of 2 or more times')
    if method == 'auto':
        method = choose_integrator(model, te[-1] - te[0], rtol, 0.0, y0)[0]
    view = kernel_model(model)
    own = methods_for(model)
    if method not in own:
        raise ParameterError(f"model '{model.name}' integrates with auto, {', '.join(own)}; "
                             f'got {method!r}')
    res = integrate_kernels(view, y0, (te[0], te[-1]), te, method=method, rtol=rtol,
                            atol=atol, step=step, max_steps=max_steps)
    if not res.success:
        last = res.t[-1] if res.t.size else te[0]
        raise IntegrationError(f'{view.name} ({method}): the integration stopped after '
                               f't = {last:.6g} s: {res.message}')
    return Run(t=res.t, y=res.y, method=method, nfev=res.nfev, nsteps=res.nsteps,
               nrejected=res.nrejected)


def _load(scene: Scene | str, overrides: Mapping[str, Any] | None) -> Scene:
    """Return the scene itself, or the one loaded from a name or path (with ``overrides``)."""
    if isinstance(scene, Scene):
        if overrides:
            raise ParameterError('overrides need a scene name or path, not a loaded Scene')
        return scene
    return load_scene(scene, overrides=overrides)


def _sample_times(t_end: float, rate: float) -> np.ndarray:
    """Sample times 0, 1/rate, ... and t_end itself."""
    if t_end * rate > MAX_SAMPLES:
        raise ParameterError(f't_end x rate = {t_end * rate:.3g} samples is more than '
                             f'{MAX_SAMPLES:g}: lower --rate or --t-end')
    n = int(np.floor(t_end * rate + 1e-9))
    t_eval = np.arange(n + 1) / rate
    if t_eval[-1] < t_end - 1e-12:
        t_eval = np.append(t_eval, t_end)
    return t_eval


@dataclasses.dataclass
class _Run:
    """What one integrator run gave: samples, counts, status and the setting it used."""

    t: np.ndarray
    y: np.ndarray
    nfev: int
    nsteps: int
    status: int
    message: str
    wall: float
    rtol: float | None
    atol: float | None
    step: float | None = None


def _run_own(model: Model, y_init: np.ndarray, t_eval: np.ndarray, method: str,
             rtol: float, atol: float, step: float | None) -> _Run:
    """Run one of gyro_rotor's compiled integrators (their failures come as a status)."""
    t0 = time.perf_counter()
    solver = make_integrator(method, model, y_init, 0.0, float(t_eval[-1]), rtol=rtol,
                             atol=atol, step=step)
    res = solver.run(t_eval)
    run = _Run(res.t, res.y, res.nfev, res.nsteps, res.status, res.message,
               time.perf_counter() - t0, rtol, atol)
    if not solver.adaptive:
        run.step = solver.h
        if not solver.step_from_tolerance or step is not None:
            run.rtol = run.atol = None      # rk4, rk8, gauss6 do not use tolerances
    return run


def _run_scipy(scene: Scene, model: Model, y_init: np.ndarray, t_eval: np.ndarray,
               method: str, rtol: float, atol: float) -> _Run:
    """Run scipy's ``solve_ivp`` (a baseline) on the model's plain right-hand side."""
    from scipy.integrate import solve_ivp
    t0 = time.perf_counter()
    try:
        sol = solve_ivp(model.rhs, (0.0, float(t_eval[-1])), y_init, method=method,
                        t_eval=t_eval, rtol=rtol, atol=atol)
    except ValueError as err:
        raise ParameterError(f'integrator {method}: {err}') from err
    except ZeroDivisionError as err:
        raise IntegrationError(f'integration of scene {scene.name} failed: {AXIS_DOWN} '
                               f'({err})') from err
    return _Run(sol.t, sol.y.T, int(sol.nfev), 0, sol.status, sol.message,
                time.perf_counter() - t0, rtol, atol)


def _failure(scene: Scene, model: Model, method: str, run: _Run) -> str:
    """Return the error text of a failed run, naming the model's singularity if it got there."""
    good = np.all(np.isfinite(run.y), axis=1) if run.y.size else np.zeros(0, bool)
    t_fail = run.t[-1] if run.t.size else 0.0
    text = f'integration of scene {scene.name} with {method} failed at t = {t_fail}'
    why = model.singular_at(run.y[np.flatnonzero(good)[-1]]) if np.any(good) else ''
    return f'{text}: {why}; {run.message}' if why else f'{text}: {run.message}'
