"""Compiled kernels of radau9: Radau IIA (5 stages, order 9) with the drive's exact Jacobian.

The stiffness of a stiff drive sits in one linear term, the drive damping -K_D zdot of
eq. (23): its root near -lambda = -K_D (1/C_R + 1/C_M) (docs/model.md section 7). That term
is f_I(y) = -K_D b y_k with k the index of zdot and b the response of the state's rates to a
unit rotor torque (b_zdot = 1/C_R + 1/C_M, b_W3 = -1/C_M for the full model), so its
Jacobian L = -K_D b e_k^T = -lambda P is of rank one (P = b e_k^T / b_k a projector).

Radau IIA collocation is L-stable and stiffly accurate (y_new is the last stage, on the slow
manifold) with stage order 5, so its high order survives the stiff limit. Its stage
equations Z = h (A x I) F(y + Z) are solved by simplified Newton iterations whose matrix
keeps only the stiff part, M = I - h A x L: then

    M^-1 = I x (I - P) + (I + h lambda A)^-1 x P,

a 5 x 5 inverse per step (from A's eigen-decomposition: :func:`resolvent`) and O(n) work
per stage, whatever K_D: no Jacobian evaluation, no n x n factorization. The non-stiff rest
converges as a fixed-point iteration (rate about h rho(A) |df/dy|), from a start
extrapolated along the last step's collocation polynomial. The error estimate is
Hairer's: an embedded formula of order 5 with the weight gamma0 on f(y_n), filtered by
(I - h gamma0 L)^-1 for the stiff direction (Hairer and Wanner II, sec. IV.8).
"""

from __future__ import annotations

import math

from gyro_rotor.numerics.integrators.primitives import (all_finite, BUDGET, clip_to_sample,
                                                        FAST_MATH, finish_run, MAX_FACTOR,
                                                        MIN_FACTOR, njit,
                                                        NONFINITE, normalize_quaternion, OK, rhs,
                                                        SAFETY, start_run, state_size,
                                                        store_samples, too_small, UNDERFLOW)
import numpy as np

__all__ = ['stiff_direction', 'radau_run', 'lagrange_weights', 'extrapolate', 'resolvent',
           'MAX_ITER']

#: the number of stages of the kernels (the tableau RADAU5_*: a compile-time constant, so
#: that LLVM unrolls the loops over the stages)
STAGES = 5
#: most simplified-Newton iterations per step before the step is retried at half size
MAX_ITER = 20
#: the stage iteration stops when its update is this small, in tolerance units
ITER_TOL = 0.01
#: ... in units of a relative tolerance of at most this (loose tolerances do not leave the
#: stages unsolved: the step's error is then the method's, not the iteration's); the
#: kernels take it as the argument ``itol_max``
ITER_RTOL_MAX = 1e-4


@njit(cache=True, error_model='numpy')
def stiff_direction(kind, P, b):
    """Fill ``b`` and return (k, lambda) of the stiff part f_I = -K_D b y_k (module doc)."""
    for m in range(b.shape[0]):
        b[m] = 0.0
    inv_cr = 1.0 / P[1]
    if kind == 2:
        k = 1
        b[k] = inv_cr
    else:
        inv_cm = 1.0 / P[2]
        k = 8 if kind == 0 else 3
        b[k] = inv_cr + inv_cm
        b[6 if kind == 0 else 1] = -inv_cm
    return k, P[7] * b[k]


@njit(cache=True, error_model='numpy', fastmath=set(FAST_MATH))
def resolvent(mu, LAM, PROJ, out):
    """(I + mu A)^-1 into ``out`` from A's spectral parts (tableaux.resolvent_parts).

    sum_i Re(P_i / (1 + mu lambda_i)): three complex reciprocals and 150 multiply-adds, no
    pivoting (a 5 x 5 Gauss-Jordan inverse took 190 ns of a 1.2 us step).
    """
    s = out.shape[0]
    for i in range(s):
        for j in range(s):
            out[i, j] = 0.0
    for r in range(LAM.shape[0]):
        a = 1.0 + mu * LAM[r, 0]
        b = mu * LAM[r, 1]
        d = 1.0 / (a * a + b * b)
        cr = a * d
        ci = -b * d
        for i in range(s):
            for j in range(s):
                out[i, j] += cr * PROJ[r, 0, i, j] - ci * PROJ[r, 1, i, j]


@njit(cache=True, error_model='numpy', fastmath=set(FAST_MATH))
def lagrange_weights(C):
    """1 / the denominators of the Lagrange basis on the nodes 0, C[0], ..., C[s - 1].

    The basis polynomial of node C[j] vanishes at 0 and the other nodes; its denominator is
    C[j] prod_(q != j) (C[j] - C[q]). Once a run, for :func:`extrapolate` at every step.
    """
    s = C.shape[0]
    w = np.empty(s)
    for j in range(s):
        den = C[j]                    # the node 0 of the basis (value 0 there)
        for q in range(s):
            if q != j:
                den *= C[j] - C[q]
        w[j] = 1.0 / den
    return w


@njit(cache=True, error_model='numpy', fastmath=set(FAST_MATH))
def extrapolate(C, w, Zp, ratio, Z):
    """Start values: the last step's collocation polynomial at t_n + c_i h (h / h_old = ratio).

    For any number of stages s = C.shape[0] (radau9's and :mod:`~.radau_jac`'s kernels);
    ``w`` = :func:`lagrange_weights` (C).
    """
    s = C.shape[0]
    n = Z.shape[1]
    for i in range(s):
        th = 1.0 + C[i] * ratio
        for m in range(n):
            Z[i, m] = -Zp[s - 1, m]
        for j in range(s):
            lj = th * w[j]
            for q in range(s):
                if q != j:
                    lj *= th - C[q]
            for m in range(n):
                Z[i, m] += lj * Zp[j, m]


@njit(cache=True, error_model='numpy', fastmath=set(FAST_MATH))
def radau_solve(kind, P, y, f, h, rtol, atol, A, LAM, PROJ, b, k, lam, Z, F, V, T, ytmp, sc,
                itol_max):
    """Solve the stage equations for Z (start values in Z); return the iterations or -1."""
    s = STAGES
    n = state_size(kind, y)
    bk = b[k]
    resolvent(h * lam, LAM, PROJ, T)
    ra = min(rtol, itol_max)
    aa = min(atol, itol_max * 1e-2)
    for m in range(n):
        sc[m] = 1.0 / (aa + ra * abs(y[m]))     # the inverse scale
    prev = math.inf
    for it in range(MAX_ITER):
        for i in range(s):
            for m in range(n):
                ytmp[m] = y[m] + Z[i, m]
            rhs(kind, ytmp, P, F[i])
        for i in range(s):
            for m in range(n):
                acc = 0.0
                for j in range(s):
                    acc += A[i, j] * F[j, m]
                V[i, m] = h * acc - Z[i, m]
        norm = 0.0
        for i in range(s):
            acc = 0.0
            for j in range(s):
                acc += T[i, j] * V[j, k]
            corr = (acc - V[i, k]) / bk
            for m in range(n):
                d = V[i, m] + corr * b[m]
                Z[i, m] += d
                e = d * sc[m]
                norm += e * e
        norm = math.sqrt(norm / (s * n))
        if not math.isfinite(norm) or (it > 2 and norm > prev):
            return -1               # the non-normal start may grow; later growth diverges
        if norm <= ITER_TOL:
            return it + 1
        prev = norm
    return -1


@njit(cache=True, error_model='numpy', fastmath=set(FAST_MATH))
def radau_run(kind, P, y0, t0, t_eval, rtol, atol, h_max, h_init, renorm, max_steps,
              A, Ainv, C, BH, gamma0, LAM, PROJ, itol_max, Y_out, counts, y_last):
    """Adaptive Radau IIA through the sample times: steps are clipped to land on each sample.

    Returns the status; ``counts`` = (nfev, nsteps, rejected, next step size, -, t at the
    end) and ``y_last`` the state there (after ``max_steps`` steps, or the end).
    """
    n = state_size(kind, y0)
    s = STAGES
    b = np.empty(n)
    k, lam = stiff_direction(kind, P, b)
    y, f, ytmp, ftmp, kk, h, nfev, status = start_run(kind, P, y0, t0, t_eval, rtol, atol, 5,
                                                      h_max, h_init, Y_out)
    sc = np.empty(n)
    err = np.empty(n)
    Z = np.empty((s, n))
    Zp = np.empty((s, n))
    F = np.empty((s, n))
    V = np.empty((s, n))
    T = np.empty((s, s))
    w = lagrange_weights(C)
    t = t0
    t_end = t_eval[t_eval.shape[0] - 1]
    nsteps = 0
    nrej = 0
    h_old = 0.0
    while status == OK and t < t_end:
        if too_small(t, h):
            status = UNDERFLOW
            break
        h, h_free, clipped, t_next = clip_to_sample(t_eval, kk, t, h, h_max, t_end)
        if h_old > 0.0:
            extrapolate(C, w, Zp, h / h_old, Z)
        else:
            for i in range(s):
                for m in range(n):
                    Z[i, m] = C[i] * h * f[m]
        it = radau_solve(kind, P, y, f, h, rtol, atol, A, LAM, PROJ, b, k, lam, Z, F, V, T,
                         ytmp, sc, itol_max)
        if it < 0:
            nfev += MAX_ITER * s
            nrej += 1
            h *= 0.5
            continue
        nfev += it * s
        # error estimate (module doc): h gamma0 f_n + sum (BH_i - B_i) h k_i, h k = A^-1 Z
        for m in range(n):
            acc = 0.0
            for i in range(s):
                hk = 0.0
                for j in range(s):
                    hk += Ainv[i, j] * Z[j, m]
                acc += (BH[i] - A[s - 1, i]) * hk
            err[m] = gamma0 * h * f[m] + acc
        ek = err[k] / (1.0 + h * gamma0 * lam)
        corr = (ek - err[k]) / b[k]
        e = 0.0
        for m in range(n):
            em = err[m] + corr * b[m]
            sc_m = atol + rtol * max(abs(y[m]), abs(y[m] + Z[s - 1, m]))
            e += (em / sc_m) ** 2
        e = math.sqrt(e / n)
        if not math.isfinite(e) or e > 1.0:
            nrej += 1
            h *= max(MIN_FACTOR, SAFETY * e ** (-1.0 / (s + 1))) if math.isfinite(e) \
                else MIN_FACTOR
            continue
        t = t_next if clipped else t + h
        for j in range(n):
            y[j] += Z[s - 1, j]
        rhs(kind, y, P, f)
        nfev += 1
        if renorm:
            normalize_quaternion(kind, y, f)
        for i in range(s):
            for j in range(n):
                Zp[i, j] = Z[i, j]
        h_old = h
        nsteps += 1
        if not all_finite(y):
            status = NONFINITE
            break
        kk = store_samples(t_eval, kk, t, y, Y_out)
        # the next step before the budget check: a caller that steps one at a time
        # (max_steps = 1, the live stepper) resumes with it, not with this step's size
        fac = MAX_FACTOR if e == 0.0 else min(MAX_FACTOR, SAFETY * e ** (-1.0 / (s + 1)))
        h = max(h * fac, h_free) if clipped else h * fac
        if nsteps >= max_steps:
            status = BUDGET
            break
    finish_run(counts, status, nfev, nsteps, nrej, h)
    counts[5] = t
    for j in range(n):
        y_last[j] = y[j]
    return status
