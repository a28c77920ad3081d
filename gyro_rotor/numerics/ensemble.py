"""Ensembles: many trajectories of one model in lockstep (Monte Carlo, parameter sweeps).

All N trajectories take the same fixed steps (RK4 or RK8) from their own initial states,
optionally with their own parameters, and are sampled on a common time grid. Two
backends run the same equations:

``numba``   one compiled loop over trajectories calling the same right-hand side kernel as
            the single-trajectory integrators (:mod:`gyro_rotor.numerics.integrators.kernels`);
``numpy``   the same right-hand side (core.model.full_rhs) run elementwise on arrays of
            shape (N,), for installs without numba.

The quaternion hook of the integrators (renormalization after each step) applies too.
A system file's model runs on the numba backend through its generated right-hand side
(:class:`~gyro_rotor.numerics.kernel_system.KernelSystem`), with one
:class:`~gyro_rotor.core.system.system_file.RotorSystem` per trajectory (the same system with
other constants or drives) in place of the centrifuge's parameters.
"""

from __future__ import annotations

import dataclasses
import math
import time

from gyro_rotor.core.model import full_rhs, Model
from gyro_rotor.core.params import RotorParams
from gyro_rotor.errors import ParameterError
from gyro_rotor.numerics.integrators import kernels, tableaux as tb
from gyro_rotor.numerics.integrators.base import kernel_args
from gyro_rotor.numerics.integrators.kernels import njit
from gyro_rotor.numerics.kernel_system import kernel_model
import numpy as np

__all__ = ['EnsembleResult', 'run_ensemble', 'BACKENDS']

BACKENDS = ('auto', 'numba', 'numpy')
_TABLEAUX = {'rk4': (tb.RK4_A, tb.RK4_B, 0.02),
             'rk8': (np.ascontiguousarray(tb.DOP853_A[:12, :12]), tb.DOP853_B, 0.2)}


@dataclasses.dataclass
class EnsembleResult:
    """Samples ``y`` (m, N, n) at times ``t`` (m,), the step and the cost."""

    t: np.ndarray
    y: np.ndarray
    method: str
    backend: str
    step: float
    nsteps: int
    wall_time: float


@njit(cache=True)
def _ens_run(kind, P, Y, t_eval, h_max, A, B, renorm, Y_out):
    N = Y.shape[0]
    n = Y.shape[1]
    s = B.shape[0]
    f = np.empty(n)
    ytmp = np.empty(n)
    y = np.empty(n)
    y_new = np.empty(n)
    K = np.empty((s, n))
    nsteps = 0
    for r in range(N):
        Pr = P[r]
        for j in range(n):
            y[j] = Y[r, j]
        t = t_eval[0]
        for j in range(n):
            Y_out[0, r, j] = y[j]
        cnt = 0
        for k in range(1, t_eval.shape[0]):
            span = t_eval[k] - t
            m = int(math.ceil(span / h_max * (1.0 - 1e-12)))
            if m < 1:
                m = 1
            h = span / m
            for i in range(m):
                kernels.rhs(kind, y, Pr, f)
                kernels.rk_step(kind, Pr, y, f, h, A, B, K, ytmp, y_new)
                if renorm:
                    kernels.normalize_quaternion(kind, y_new, f)
                for j in range(n):
                    y[j] = y_new[j]
            cnt += m
            t = t_eval[k]
            for j in range(n):
                Y_out[k, r, j] = y[j]
        nsteps = cnt
    return nsteps


def _rhs_full_vec(Y: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Evaluate the full model's right-hand side on columns: Y (10, N), P (10, N) -> (10, N).

    The same function as the compiled kernels and the model (core.model.full_rhs), run
    elementwise on arrays.
    """
    out = np.empty_like(Y)
    full_rhs(Y, P, out)
    return out


def _numpy_run(P, Y0, t_eval, h_max, A, B, renorm):
    Y = Y0.T.copy()
    Pc = np.ascontiguousarray(P.T)
    s = B.shape[0]
    out = np.empty((t_eval.size, Y0.shape[0], Y0.shape[1]))
    out[0] = Y.T
    t = t_eval[0]
    nsteps = 0
    K = [None] * s
    for k in range(1, t_eval.size):
        span = t_eval[k] - t
        m = max(1, int(math.ceil(span / h_max * (1.0 - 1e-12))))
        h = span / m
        for _ in range(m):
            for i in range(s):
                Yi = Y
                for j in range(i):
                    if A[i, j] != 0.0:
                        Yi = Yi + (h * A[i, j]) * K[j]
                K[i] = _rhs_full_vec(Yi, Pc)
            inc = B[0] * K[0]
            for j in range(1, s):
                if B[j] != 0.0:
                    inc = inc + B[j] * K[j]
            Y = Y + h * inc
            if renorm:
                Y[0:4] /= np.sqrt((Y[0:4] ** 2).sum(axis=0))
        nsteps += m
        t = t_eval[k]
        out[k] = Y.T
    return out, nsteps


def run_ensemble(model: Model, Y0, t_eval, *, method: str = 'rk4', step: float | None = None,
                 params: list[RotorParams] | None = None, backend: str = 'auto',
                 renormalize: bool = True) -> EnsembleResult:
    """Integrate N trajectories in lockstep from the rows of ``Y0`` (N, n).

    Parameters
    ----------
    model : Model or GeneralModel
        The equations (its parameters unless ``params`` gives one set per trajectory: a
        RotorParams, or for a system file's model a RotorSystem, per trajectory).
    Y0 : array_like, shape (N, n)
        Initial states, all finite.
    t_eval : array_like, shape (m,)
        Increasing sample times; the run starts at ``t_eval[0]``.
    method : {'rk4', 'rk8'}
        Fixed-step explicit method; ``step`` [s] defaults as for the single integrators.
    backend : {'auto', 'numba', 'numpy'}
        'auto' = numba when installed; 'numpy' works for the full model only.
    """
    model = kernel_model(model)
    if method not in _TABLEAUX:
        raise ParameterError(f"ensemble method must be one of {', '.join(_TABLEAUX)}, got "
                             f'{method!r}')
    if backend not in BACKENDS:
        raise ParameterError(f"backend must be one of {', '.join(BACKENDS)}, got {backend!r}")
    Y0 = np.atleast_2d(np.asarray(Y0, dtype=float))
    if Y0.ndim != 2 or Y0.shape[1] != model.n:
        raise ParameterError(f'Y0 must have shape (N, {model.n}), got {Y0.shape}')
    if not np.all(np.isfinite(Y0)):
        raise ParameterError('all initial states Y0 must be finite')
    te = np.asarray(t_eval, dtype=float).reshape(-1)
    if te.size < 2 or not np.all(np.isfinite(te)) or np.any(np.diff(te) <= 0):
        raise ParameterError('t_eval must be a finite, increasing array of 2 or more times')
    A, B, factor = _TABLEAUX[method]
    plist = params if params is not None else [model.params]
    if params is not None and len(params) != Y0.shape[0]:
        raise ParameterError(f'params must give one RotorParams per trajectory '
                             f'({Y0.shape[0]}), got {len(params)}')
    args = [kernel_args(model, p) for p in plist]   # (kind, P, rate) per parameter set
    kind = args[0][0]
    P = np.array([a[1] for a in args])
    if params is None:
        P = np.repeat(P, Y0.shape[0], axis=0)
    if step is None:
        h = factor / max(a[2] for a in args)
    else:
        h = float(step)
        if not (math.isfinite(h) and h > 0):
            raise ParameterError(f'step must be positive and finite, got {step!r}')
    if backend == 'auto':
        backend = 'numba' if kernels.HAVE_NUMBA else 'numpy'
    if backend == 'numpy' and model.name != 'full':
        raise ParameterError('the numpy backend vectorizes the full model only')
    t0 = time.perf_counter()
    if backend == 'numba':
        out = np.empty((te.size, Y0.shape[0], model.n))
        nsteps = int(_ens_run(kind, P, Y0, te, h, A, B, renormalize and model.name == 'full',
                              out))
    else:
        out, nsteps = _numpy_run(P, Y0, te, h, A, B, renormalize)
    wall = time.perf_counter() - t0
    return EnsembleResult(t=te, y=out, method=method, backend=backend, step=h, nsteps=nsteps,
                          wall_time=wall)
