"""Compiled kernels: the inner loops of the integrators (explicit RK, DOP853, Gauss, RODAS4).

The building blocks they share (``njit``, the model kinds and :func:`rhs`, the status
codes, the step size control, :func:`initial_step`, :func:`land_step`, the LU solver) are
in :mod:`~.primitives`, which the generated kernels (:mod:`~.rk_codegen`, loaded here as
``kernels.rk_generated``), :mod:`~.radau`, :mod:`~.radau_jac` and :mod:`~.splitting` import
as well; they are re-exported here (``kernels.rhs``, ``kernels.KIND``, ...).

Everything here is written in plain scalar arithmetic on float64 arrays, with no
allocation inside the loops, so that numba compiles it to machine code (``cache=True``:
compiled once per machine, then loaded from ``__pycache__``). Without numba the same
functions run as ordinary Python (slower, same results): real ROS installs without numba
still work.

Models are selected by ``kind``: a member of the hand-written model's own IntEnum class
(:data:`KIND`: FullKind.FULL = 0, UprightKind.UPRIGHT_AXIS = 1,
LockedKind.LOCKED_HOUSING = 2; each class is its own numba type, so each kernel is compiled
once per model with that model's right-hand side inlined) or a compiled general rotor
system's right-hand side as a numba first-class function (:func:`rhs`); the parameters
travel as one float array ``P`` (see :func:`pack_params`), so a single compiled kernel
serves every scene of a model.

Status codes returned by the run loops: :class:`Status` (0 finished, -1 step size
underflow, -2 non-finite state, -3 step budget exhausted, -4 Newton/fixed-point iteration
did not converge), as the plain int constants OK, UNDERFLOW, ... that numba reads.
Every kernel is compiled with numpy's error model (a division by zero gives inf or NaN,
never an exception); a loop whose right-hand side is non-finite at its start ends at once
with -2, and a non-finite error norm shrinks the step until it ends with -1 (a NaN step
fails the ``h >= min_step`` test), so no loop can reject steps forever.
"""

from __future__ import annotations

import math

from gyro_rotor.numerics.integrators import rk_codegen
from gyro_rotor.numerics.integrators.primitives import (
    all_finite, BUDGET, clip_to_sample, finish_run, fixed_segment, FullKind, HAVE_NUMBA,
    initial_step, KIND, LAND_SHRINK, land_step, LAND_STRETCH, LockedKind, lu_factor, lu_solve,
    MAX_FACTOR, MIN_FACTOR, njit, NOCONV, NONFINITE, normalize_quaternion, OK, pack_params, rhs,
    SAFETY, start_run, state_size, Status, store_samples, too_small, UNDERFLOW, UprightKind)
import numpy as np

#: the straight-line explicit Runge-Kutta kernels (DOP853, Verner), generated on first use
rk_generated = rk_codegen.load()

__all__ = ['HAVE_NUMBA', 'KIND', 'FullKind', 'UprightKind', 'LockedKind', 'Status',
           'pack_params', 'rhs', 'state_size', 'fixed_run', 'dop853_run', 'rodas_run',
           'rk_step', 'dop853_step', 'dop853_dense', 'gauss_step', 'rodas_step',
           'fd_jacobian', 'normalize_quaternion', 'land_step', 'all_finite', 'njit', 'OK',
           'UNDERFLOW', 'NONFINITE', 'BUDGET', 'NOCONV', 'SAFETY', 'MIN_FACTOR', 'MAX_FACTOR',
           'LAND_SHRINK', 'LAND_STRETCH', 'initial_step', 'lu_factor', 'lu_solve',
           'rk_generated']


@njit(cache=True, error_model='numpy')
def _rms_error(err, y, y_new, rtol, atol):
    n = y.shape[0]
    acc = 0.0
    for i in range(n):
        sc = atol + rtol * max(abs(y[i]), abs(y_new[i]))
        e = err[i] / sc
        acc += e * e
    return math.sqrt(acc / n)


# -- explicit Runge-Kutta, fixed step ----------------------------------------------------------
@njit(cache=True, error_model='numpy')
def rk_stage(kind, P, y, h, A, K, i, ytmp):
    """Evaluate stage ``i`` of the explicit tableau A into K[i]: f(y + h sum_j<i A[i, j] K[j])."""
    for m in range(y.shape[0]):
        acc = 0.0
        for j in range(i):
            acc += A[i, j] * K[j, m]
        ytmp[m] = y[m] + h * acc
    rhs(kind, ytmp, P, K[i])


@njit(cache=True, error_model='numpy')
def rk_step(kind, P, y, f0, h, A, B, K, ytmp, y_new):
    """One explicit RK step of tableau (A, B) from (y, f0 = f(y)); result in ``y_new``.

    ``K`` (s, n) receives the stages. Costs s - 1 evaluations (the first is ``f0``).
    """
    s = B.shape[0]
    n = y.shape[0]
    for m in range(n):
        K[0, m] = f0[m]
    for i in range(1, s):
        rk_stage(kind, P, y, h, A, K, i, ytmp)
    for m in range(n):
        acc = 0.0
        for j in range(s):
            acc += B[j] * K[j, m]
        y_new[m] = y[m] + h * acc


@njit(cache=True, error_model='numpy')
def fixed_run(kind, P, y0, t0, t_eval, h_max, A, B, implicit, renorm, max_steps, max_iter,
              Y_out, counts):
    """Fixed-step Runge-Kutta of tableau (A, B) from t0 through the sample times ``t_eval``.

    Explicit (:func:`rk_step`), or with ``implicit`` the Gauss method (:func:`gauss_step`,
    at most ``max_iter`` sweeps of its fixed-point iteration). Between consecutive samples
    (increasing) the interval is cut into the fewest equal steps no longer than ``h_max``,
    so every sample is hit exactly (no dense output needed). Returns the status; ``counts``
    receives (nfev, nsteps) and ``Y_out`` the samples.
    """
    n = y0.shape[0]
    s = B.shape[0]
    y = y0.copy()
    y_new = np.empty(n)
    f = np.empty(n)
    ytmp = np.empty(n)
    K = np.empty((s, n))
    nfev = 0
    nsteps = 0
    k, m, h = fixed_segment(t_eval, 0, t0, h_max, y, Y_out)
    while m > 0:
        for i in range(m):
            rhs(kind, y, P, f)
            if not all_finite(f):
                return finish_run(counts, NONFINITE, nfev + 1, nsteps, 0, 0.0)
            if implicit:
                ne = gauss_step(kind, P, y, f, h, A, B, K, ytmp, y_new, max_iter)
                if ne < 0:
                    return finish_run(counts, NOCONV, nfev, nsteps, 0, 0.0)
                nfev += ne + 1
            else:
                rk_step(kind, P, y, f, h, A, B, K, ytmp, y_new)
                nfev += s
            nsteps += 1
            if renorm:
                normalize_quaternion(kind, y_new, f)
            for j in range(n):
                y[j] = y_new[j]
            if not all_finite(y):
                return finish_run(counts, NONFINITE, nfev, nsteps, 0, 0.0)
            if nsteps >= max_steps:
                return finish_run(counts, BUDGET, nfev, nsteps, 0, 0.0)
        k, m, h = fixed_segment(t_eval, k, t_eval[k], h_max, y, Y_out)
    return finish_run(counts, OK, nfev, nsteps, 0, 0.0)


# -- DOP853, adaptive with dense output --------------------------------------------------------
@njit(cache=True, error_model='numpy')
def dop853_step(kind, P, y, f, h, rtol, atol, A, B, E3, E5, K, ytmp, y_new, f_new):
    """One trial step of DOP853 (12 stages, FSAL). Returns the scaled error norm.

    ``K`` (16, n): rows 0-11 the stages, row 12 f(y_new) (also copied to ``f_new``).
    """
    n = y.shape[0]
    rk_step(kind, P, y, f, h, A, B, K, ytmp, y_new)
    rhs(kind, y_new, P, f_new)
    for m in range(n):
        K[12, m] = f_new[m]
    # error estimate of Hairer's DOP853 (scipy's DOP853._estimate_error_norm)
    e5 = 0.0
    e3 = 0.0
    for m in range(n):
        sc = atol + rtol * max(abs(y[m]), abs(y_new[m]))
        a5 = 0.0
        a3 = 0.0
        for j in range(13):
            a5 += E5[j] * K[j, m]
            a3 += E3[j] * K[j, m]
        e5 += (a5 / sc) ** 2
        e3 += (a3 / sc) ** 2
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    denom = e5 + 0.01 * e3
    return abs(h) * e5 / math.sqrt(denom * n)


@njit(cache=True, error_model='numpy')
def dop853_dense(kind, P, y_old, y_new, f_old, f_new, h, A, C, D, K, ytmp, F):
    """Coefficients ``F`` (7, n) of the 7th-order dense output over the last step.

    Computes the three extra stages (rows 13-15 of ``K``, 3 evaluations).
    """
    n = y_old.shape[0]
    for s in range(13, 16):
        rk_stage(kind, P, y_old, h, A, K, s, ytmp)
    for m in range(n):
        dy = y_new[m] - y_old[m]
        F[0, m] = dy
        F[1, m] = h * f_old[m] - dy
        F[2, m] = 2.0 * dy - h * (f_new[m] + f_old[m])
        for r in range(4):
            acc = 0.0
            for j in range(16):
                acc += D[r, j] * K[j, m]
            F[3 + r, m] = h * acc


@njit(cache=True, error_model='numpy')
def dense_eval(F, y_old, x, out):
    """Evaluate the DOP853 interpolant at fraction ``x`` of the step into ``out``."""
    n = y_old.shape[0]
    for m in range(n):
        v = 0.0
        for i in range(7):
            v += F[6 - i, m]
            if i % 2 == 0:
                v *= x
            else:
                v *= 1.0 - x
        out[m] = v + y_old[m]


#: the adaptive DOP853 loop is the generated one (:mod:`~.rk_codegen`: straight-line steps and
#: dense output, about half the cost of :func:`dop853_step` and :func:`dop853_dense`)
dop853_run = rk_generated.dop853_run


# -- Gauss-Legendre collocation (implicit, fixed step) -----------------------------------------
@njit(cache=True, error_model='numpy')
def gauss_step(kind, P, y, f0, h, A, B, K, ytmp, y_new, max_iter):
    """One step of the s-stage Gauss method; stages by fixed-point iteration to round-off.

    Returns the number of evaluations, or -1 if the iteration did not converge.
    """
    s = B.shape[0]
    n = y.shape[0]
    for i in range(s):
        for m in range(n):
            K[i, m] = f0[m]
    Knew = np.empty(n)
    nfev = 0
    prev = math.inf
    for it in range(max_iter):
        delta = 0.0
        for i in range(s):
            for m in range(n):
                acc = 0.0
                for j in range(s):
                    acc += A[i, j] * K[j, m]
                ytmp[m] = y[m] + h * acc
            rhs(kind, ytmp, P, Knew)
            nfev += 1
            for m in range(n):
                if not math.isfinite(Knew[m]):
                    return -1
                d = abs(Knew[m] - K[i, m]) * h / (1e-12 + abs(y[m]) + abs(h * K[i, m]))
                if d > delta:
                    delta = d
                K[i, m] = Knew[m]
        # converged to round-off: tiny, or no longer decreasing once small
        if delta <= 1e-16 or (delta < 1e-13 and delta >= prev):
            break
        prev = delta
    else:
        return -1
    for m in range(n):
        acc = 0.0
        for j in range(s):
            acc += B[j] * K[j, m]
        y_new[m] = y[m] + h * acc
    return nfev


# -- RODAS4 (Rosenbrock, L-stable) -------------------------------------------------------------
@njit(cache=True, error_model='numpy')
def fd_jacobian(kind, P, y, J, ytmp, fa, fb):
    """Jacobian df/dy by forward differences from ``fa`` = f(y) (one evaluation per column).

    The last state (the dissipated work D) enters no right-hand side: its column is zero
    and costs nothing. The stiff entries (linear in zdot, docs/model.md section 7) are
    exact up to round-off; the others carry a relative error near sqrt(eps), which the
    Rosenbrock method tolerates (its error terms in J - df/dy are of order h^2).
    The difference for y_j is 1.5e-8 max(1e-5, |y_j|), relative to y_j itself: near the
    axis-down singularity q_w and q_z are about delta / 2 (delta = pi - theta) and the
    twist's rate varies on that scale; a step of 1.5e-8 crossed it from delta = 3e-8 on
    (a start 1e-9 rad from pi failed at once, 1e-7 ran out of 2e6 steps, 1e-5 took 45,699
    steps in 0.1 s; now 2,933, 1,689 and 1,494). It costs 3 to 4 % more steps at rtol
    1e-9 on precession, nutation and stiff_drive, none at 1e-4.
    """
    n = y.shape[0]
    for m in range(n):
        ytmp[m] = y[m]
    for j in range(n - 1):
        d = 1.5e-8 * max(1e-5, abs(y[j]))
        ytmp[j] = y[j] + d
        rhs(kind, ytmp, P, fb)
        ytmp[j] = y[j]
        for m in range(n):
            J[m, j] = (fb[m] - fa[m]) / d
    for m in range(n):
        J[m, n - 1] = 0.0
    return n - 1


@njit(cache=True, error_model='numpy')
def rodas_step(kind, P, y, f, J, h, rtol, atol, A, C, Mw, gamma, K, ytmp, y_new, W, piv,
               rhs_buf):
    """Take one trial step of RODAS4 with Jacobian ``J`` at y.

    Returns the error norm (inf if the matrix W = I/(h gamma) - J is singular).
    """
    n = y.shape[0]
    s = Mw.shape[0]
    g = 1.0 / (h * gamma)
    for i in range(n):
        for j in range(n):
            W[i, j] = -J[i, j]
        W[i, i] += g
    if not lu_factor(W, piv):
        return math.inf
    for i in range(s):
        if i == 0:
            for m in range(n):
                rhs_buf[m] = f[m]
        else:
            for m in range(n):
                acc = 0.0
                for j in range(i):
                    acc += A[i, j] * K[j, m]
                ytmp[m] = y[m] + acc
            rhs(kind, ytmp, P, rhs_buf)
            for m in range(n):
                acc = 0.0
                for j in range(i):
                    acc += C[i, j] * K[j, m]
                rhs_buf[m] += acc / h
        lu_solve(W, piv, rhs_buf)
        for m in range(n):
            K[i, m] = rhs_buf[m]
    for m in range(n):
        acc = 0.0
        for j in range(s):
            acc += Mw[j] * K[j, m]
        y_new[m] = y[m] + acc
    return _rms_error(K[s - 1], y, y_new, rtol, atol)


@njit(cache=True, error_model='numpy')
def rodas_run(kind, P, y0, t0, t_eval, rtol, atol, h_max, h_init, renorm, max_steps,
              A, C, Mw, gamma, Y_out, counts):
    """Adaptive RODAS4 through the sample times: steps are clipped to land on each sample.

    Returns the status; ``counts`` = (nfev, nsteps, rejected, last step size, njev).
    """
    n = y0.shape[0]
    s = Mw.shape[0]
    y, f, ytmp, fb, k, h, nfev, status = start_run(kind, P, y0, t0, t_eval, rtol, atol, 3,
                                                   h_max, h_init, Y_out)
    y_new = np.empty(n)
    rbuf = np.empty(n)
    K = np.empty((s, n))
    J = np.empty((n, n))
    W = np.empty((n, n))
    piv = np.zeros(n, dtype=np.int64)
    t = t0
    t_end = t_eval[t_eval.shape[0] - 1]
    njev = 0
    nsteps = 0
    nrej = 0
    jac_fresh = False
    while status == OK and t < t_end:
        if too_small(t, h):
            status = UNDERFLOW
            break
        h, h_free, clipped, t_next = clip_to_sample(t_eval, k, t, h, h_max, t_end)
        if not jac_fresh:
            nfev += fd_jacobian(kind, P, y, J, ytmp, f, fb)
            njev += 1
            jac_fresh = True
        err = rodas_step(kind, P, y, f, J, h, rtol, atol, A, C, Mw, gamma, K, ytmp, y_new,
                         W, piv, rbuf)
        nfev += s - 1
        if not math.isfinite(err) or err > 1.0:
            nrej += 1
            if math.isfinite(err):
                h *= max(MIN_FACTOR, SAFETY * err ** (-0.25))
            else:
                h *= MIN_FACTOR
            continue
        t = t_next if clipped else t + h
        rhs(kind, y_new, P, f)
        nfev += 1
        if renorm:
            normalize_quaternion(kind, y_new, f)
        for j in range(n):
            y[j] = y_new[j]
        jac_fresh = False
        nsteps += 1
        if not all_finite(y):
            status = NONFINITE
            break
        k = store_samples(t_eval, k, t, y, Y_out)
        if nsteps >= max_steps:
            status = BUDGET
            break
        fac = 6.0 if err == 0.0 else min(6.0, SAFETY * err ** (-0.25))
        fac = max(MIN_FACTOR, fac)
        h = max(h * fac, h_free) if clipped else h * fac
    counts[4] = njev
    return finish_run(counts, status, nfev, nsteps, nrej, h)
