"""Sweeps over general scenes (a ``system`` key): constants and drive values of a rotor system.

Sweepable keys: ``constants.NAME`` (a constant of the system), ``K_S``, ``K_D``, ``Omega0``
(every rotor's drive) and ``drive.ROTOR.KEY`` (one rotor's). Each value of each axis is
loaded with :func:`~gyro_rotor.core.scene.load_scene` (the loader's own
checks) before any work. A block of points is one call of
:func:`gyro_rotor.numerics.general.run_ensemble` (RK4, lockstep, compiled; one system per
trajectory, all of the scene's structure) with the step common to the sweep, so the numbers
do not depend on the block or the scheduler, as for centrifuge scenes.

Metrics (eqs. 1-17 of any system; the deviation amplitude a = max_i |q_i - steady.q_i| over
the coordinates that move): ``peak`` (max a), ``settling`` (first time after which a stays
<= tol), ``decay`` (least-squares decay rate of a over the run), ``energy`` (E* at t_end,
eq. 13). ``well`` and ``abscissa`` are not computed for general scenes (refused up front).
"""

from __future__ import annotations

import time
from typing import Mapping, Sequence
import warnings

from gyro_rotor.analysis.sweep.grid import SweepGrid
from gyro_rotor.analysis.sweep.metrics import Metric, METRIC_COLUMNS, PointStatus, settle_time
from gyro_rotor.errors import GyroRotorError, ParameterError
import numpy as np

__all__ = ['GENERAL_METRICS', 'check_general_grid', 'general_block']

#: the metric groups a general scene's sweep computes
GENERAL_METRICS = (Metric.SETTLING, Metric.PEAK, Metric.DECAY, Metric.ENERGY)
_DRIVE = ('K_S', 'K_D', 'Omega0')


def _load(scene: str, overrides: Mapping):
    from gyro_rotor.core.scene import load_scene
    return load_scene(scene, overrides=dict(overrides))


def check_general_grid(scene: str, grid: SweepGrid, metrics: Sequence) -> float:
    """Refuse unsweepable keys, refused values, metrics not done; return the fastest rate.

    The rate is :func:`~gyro_rotor.core.system.model.system_rate` (the largest field
    speed) over the base scene and every value of every axis.
    """
    from gyro_rotor.core.system.model import system_rate
    for m in metrics:
        if Metric(m) not in GENERAL_METRICS:
            raise ParameterError(f"metric '{m}' is not computed for general scenes; valid: "
                                 f"{', '.join(x.value for x in GENERAL_METRICS)}")
    fastest = system_rate(_load(scene, {}).system)
    for a in grid.axes:
        parts = a.key.split('.')
        ok = (a.key in _DRIVE or (parts[0] == 'constants' and len(parts) == 2)
              or (parts[0] == 'drive' and len(parts) == 3 and parts[2] in _DRIVE))
        if not ok:
            raise ParameterError(f"--grid: key '{a.key}' cannot be swept in a general scene; "
                                 'sweepable: constants.NAME, K_S, K_D, Omega0, '
                                 'drive.ROTOR.{K_S,K_D,Omega0}')
        for v in np.unique(a.values):
            try:
                sc = _load(scene, {a.key: float(v)})
            except GyroRotorError as err:
                raise ParameterError(f'--grid {a.spec}: the value {a.key} = {v:g} is '
                                     f'refused: {err}') from None
            fastest = max(fastest, system_rate(sc.system))
    return fastest


def _metrics(model, steady_q, t, y, metrics, tol: float) -> dict:
    from gyro_rotor.analysis.sweep.metrics import fit_decay
    q = y[:, model.slices()[0]]
    a = np.max(np.abs(q - steady_q), axis=1) if q.shape[1] else np.zeros(t.size)
    out: dict = {}
    if Metric.PEAK in metrics:
        out['peak_deviation'] = float(np.max(a))
    if Metric.SETTLING in metrics:
        out['settling_time'] = settle_time(t, a, tol)
    if Metric.DECAY in metrics:
        out['decay_rate'] = fit_decay(t, a)
    if Metric.ENERGY in metrics:
        out['final_E_star'] = float(model.energy(y[-1:])[0])
    return out


def _integrate(model, systems: list, Y0: np.ndarray, t_eval, h: float):
    from gyro_rotor.numerics.general import run_ensemble
    try:
        res = run_ensemble(model, Y0, t_eval, systems=systems, method='rk4', step=h)
        return res.y, int(res.nsteps), {}
    except (ArithmeticError, ValueError, GyroRotorError):
        pass
    out = np.full((len(t_eval), len(systems), model.size), np.nan)
    errors, nsteps = {}, 0
    for c, s in enumerate(systems):
        try:
            r = run_ensemble(model, Y0[c:c + 1], t_eval, systems=[s], method='rk4', step=h)
            out[:, c, :], nsteps = r.y[:, 0, :], int(r.nsteps)
        except (ArithmeticError, ValueError, GyroRotorError) as err:
            errors[c] = f'integration: {type(err).__name__}: {err}'
    return out, nsteps, errors


def general_block(spec, b: int):
    """Integrate block ``b`` of a general scene's sweep (a row per point, always)."""
    from gyro_rotor.analysis.sweep.task import BlockResult
    from gyro_rotor.core.system.model import GeneralModel
    t0 = time.perf_counter()
    grid = spec.sweep_grid
    points = spec.block_points(b)
    n = points.size
    coords = grid.coordinates(points)
    msg = [''] * n
    scenes: list = [None] * n
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        for j in range(n):
            try:
                scenes[j] = _load(spec.scene, grid.overrides(coords, j))
            except (GyroRotorError, ArithmeticError, ValueError) as err:
                msg[j] = f'set-up: {err}'
    idx = [j for j in range(n) if scenes[j] is not None]
    metrics = {Metric(m) for m in spec.metrics}
    names = [c for m in Metric if m in metrics for c in METRIC_COLUMNS[m]]
    cols = {c: np.full(n, np.nan) for c in names}
    status = np.full(n, int(PointStatus.FAILED), dtype=np.int8)
    nsteps = 0
    if idx:
        model = scenes[idx[0]].make_model()
        Y0 = np.array([scenes[j].initial_state(model) for j in idx])
        Y, nsteps, errors = _integrate(model, [scenes[j].system for j in idx], Y0,
                                       spec.t_eval, spec.step)
        for c, j in enumerate(idx):
            if c in errors:
                msg[j] = errors[c]
                continue
            y = Y[:, c, :]
            fin = np.all(np.isfinite(y), axis=1)
            if not np.all(fin):
                status[j] = PointStatus.DIVERGED
                msg[j] = f'non-finite state at t = {spec.t_eval[np.argmin(fin)]:.6g} s'
                continue
            bound = GeneralModel(scenes[j].system, compiled=model.compiled)
            steady_q = np.asarray(scenes[j].steady_q, dtype=float)
            for k, v in _metrics(bound, steady_q, spec.t_eval, y, metrics, spec.tol).items():
                cols[k][j] = v
            status[j] = PointStatus.OK
    columns = {'point': points.astype(np.int64), 'block': np.full(n, b, dtype=np.int32),
               **coords, 'status': status, 'message': np.array(msg, dtype=object), **cols}
    return BlockResult(block=b, columns=columns, work_s=time.perf_counter() - t0,
                       steps=nsteps * len(idx))
