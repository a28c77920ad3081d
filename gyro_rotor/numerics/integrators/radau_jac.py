"""Radau IIA with the exact Jacobian: the stiff method of the generated rotor systems.

For a generated system (:mod:`gyro_rotor.core.system.codegen`) the stiffness of a stiff
drive is the drive damping -K_D zdot (eq. 8) seen through Mbar(q)^-1: m directions that
turn with q, not the one fixed direction that :mod:`~.radau` (radau9 of the centrifuge)
inverts in closed form. This kernel therefore solves the stage equations of the s-stage
Radau IIA method (order 2 s - 1, L-stable, stiffly accurate; ``s`` = the rows of the
tableau passed in, 5 for :data:`STAGES`) by simplified Newton iterations with the exact
Jacobian J = d(rhs)/dy that sympy generated (``jac`` of the generated module):

    Z = h (A x I) F(y + Z),   (h^-1 Lambda x I - I x J) dW = (T^-1 x I) F - h^-1 (Lambda x I) W,

with Z = (T x I) W and T^-1 A^-1 T = Lambda block diagonal: one real eigenvalue mu_r of
A^-1 and (s - 1) / 2 complex ones mu_c (:func:`transformation`), so an iteration needs one
real and (s - 1) / 2 complex n x n LU factorizations (Hairer and Wanner II, sec. IV.8;
scipy's ``Radau`` for s = 3).

Cost does not grow with K_D: J is evaluated only when the Newton iteration converged
slowly (rate above :data:`JAC_RATE`) or failed, the LU factors are kept while the step size
changes by less than :data:`KEEP_STEP` (and the step is then kept), and the step size is set
by accuracy alone: the error estimate is Hairer's embedded formula of order s filtered by
(I - h gamma0 J)^-1 with gamma0 = 1 / mu_r (the real LU again), which stays bounded in the
stiff limit; after a rejection it is refined once with one more evaluation. Step size
control: Gustafsson's predictive controller with Hairer's Newton-dependent safety factor.
Steps land on the sample times (a clipped step keeps the LU factors when it is at least
1 / KEEP_STEP of the step they were made for).
"""

from __future__ import annotations

import math

from gyro_rotor.errors import ParameterError
from gyro_rotor.numerics.integrators import tableaux as tb
from gyro_rotor.numerics.integrators.base import LoopStepped
from gyro_rotor.numerics.integrators.primitives import (all_finite, BUDGET, clip_to_sample,
                                                        finish_run, lu_factor, lu_solve,
                                                        MIN_FACTOR, njit, NONFINITE, OK, rhs,
                                                        start_run, store_samples, too_small,
                                                        UNDERFLOW)
from gyro_rotor.numerics.integrators.radau import extrapolate, lagrange_weights
import numpy as np

__all__ = ['Radau9Jac', 'transformation', 'radau_jac_run', 'STAGES', 'tableau']

#: stages of the method of the generated systems (order 2 s - 1 = 9)
STAGES = 5
#: most Newton iterations of one step (Hairer's RADAU: 7 for 5 stages)
NEWTON_MAXITER = 7
#: largest growth of the step in one go
MAX_GROWTH = 10.0
#: the Jacobian is re-evaluated after a step whose Newton iteration contracted slower
JAC_RATE = 1e-3
#: LU factors are kept (and the step with them) while the proposed step changes by a
#: factor in [1, KEEP_STEP)
KEEP_STEP = 1.2


def transformation(A: np.ndarray) -> tuple:
    """Return (T, TI, mu_r, mu_c) with TI A^-1 T = diag(mu_r, [[a, -b], [b, a]], ...).

    mu_r is the real eigenvalue of A^-1, mu_c (array) the a + i b of the complex blocks:
    on rows (1 + 2 p, 2 + 2 p) of W, (Lambda W) reads mu_c[p] (W_1 + i W_2).
    """
    lam, V = np.linalg.eig(np.linalg.inv(A))
    real = int(np.argmin(np.abs(lam.imag)))
    cols = [V[:, real].real / np.linalg.norm(V[:, real].real)]
    mu_c = []
    for j in np.argsort(-lam.imag):
        if lam[j].imag > 1e-12:
            # A^-1 (vr + i vi) = lam (vr + i vi): on the columns (vr, vi) A^-1 acts as
            # [[Re, Im], [-Im, Re]], i.e. as multiplication by conj(lam)
            cols += [V[:, j].real, V[:, j].imag]
            mu_c.append(np.conj(lam[j]))
    T = np.array(cols).T
    TI = np.linalg.inv(T)
    return T, TI, float(lam[real].real), np.array(mu_c)


def tableau(s: int = STAGES) -> tuple:
    """Return the arrays of the kernel for s stages: (A, C, T, TI, mu_r, mu_c, E).

    E: the error weights, err = (mu_r / h - J)^-1 (f(y_n) + sum_j E_j Z_j / h), i.e.
    Hairer's embedded estimate gamma0 h f + sum (BH_i - B_i) h k_i (:func:`tb.radau_estimator`,
    h k = A^-1 Z) filtered by (I - h gamma0 J)^-1, gamma0 = 1 / mu_r.
    """
    A, B, C = tb.radau_iia(s)
    T, TI, mu_r, mu_c = transformation(A)
    BH = tb.radau_estimator(C, 1.0 / mu_r)
    E = mu_r * np.linalg.solve(A.T, BH - B)
    return A, C, T, TI, mu_r, mu_c, E


@njit(cache=True, error_model='numpy')
def _factor(J, h, mu_r, mu_c, LR, LC, pr, pc):
    """LU of mu_r / h - J (LR) and of mu_c[p] / h - J (LC[p]); False if one is singular."""
    n = J.shape[0]
    for i in range(n):
        for j in range(n):
            LR[i, j] = -J[i, j]
        LR[i, i] += mu_r / h
    if not lu_factor(LR, pr):
        return False
    for p in range(mu_c.shape[0]):
        for i in range(n):
            for j in range(n):
                LC[p, i, j] = -J[i, j]
            LC[p, i, i] += mu_c[p] / h
        if not lu_factor(LC[p], pc[p]):
            return False
    return True


@njit(cache=True, error_model='numpy')
def _apply(M, X, out):
    """Set ``out`` = M X for the s x s matrix M and the stages X (s, n): Z = T W, W = T^-1 Z."""
    s = M.shape[0]
    for i in range(s):
        for m in range(X.shape[1]):
            acc = 0.0
            for j in range(s):
                acc += M[i, j] * X[j, m]
            out[i, m] = acc


@njit(cache=True, error_model='numpy')
def _newton(f, P, y, h, C, T, TI, mu_r, mu_c, LR, LC, pr, pc, sc, tol, Z, W, F, ytmp, br,
            bc):
    """Simplified Newton iterations on the stages (start values in Z).

    Returns (iterations, rate); -iterations (the evaluations made: -iterations * s) when
    the iteration diverged, was predicted not to converge within NEWTON_MAXITER, or met a
    non-finite value.
    """
    s = C.shape[0]
    n = y.shape[0]
    npair = mu_c.shape[0]
    _apply(TI, Z, W)
    norm_old = -1.0
    rate = 1.0
    for it in range(NEWTON_MAXITER):
        for i in range(s):
            for m in range(n):
                ytmp[m] = y[m] + Z[i, m]
            rhs(f, ytmp, P, F[i])
        if not all_finite(F[s - 1]):
            return -(it + 1), rate
        # right-hand sides of the transformed equations, then their solutions dW
        for m in range(n):
            acc = 0.0
            for j in range(s):
                acc += TI[0, j] * F[j, m]
            br[m] = acc - mu_r / h * W[0, m]
        lu_solve(LR, pr, br)
        for p in range(npair):
            for m in range(n):
                a = 0.0
                b = 0.0
                for j in range(s):
                    a += TI[1 + 2 * p, j] * F[j, m]
                    b += TI[2 + 2 * p, j] * F[j, m]
                w = complex(W[1 + 2 * p, m], W[2 + 2 * p, m])
                bc[p, m] = complex(a, b) - mu_c[p] / h * w
            lu_solve(LC[p], pc[p], bc[p])
        norm = 0.0
        for m in range(n):
            e = br[m] * sc[m]
            norm += e * e
            for p in range(npair):
                e = bc[p, m].real * sc[m]
                norm += e * e
                e = bc[p, m].imag * sc[m]
                norm += e * e
        norm = math.sqrt(norm / (s * n))
        if not math.isfinite(norm):
            return -(it + 1), rate
        if norm_old >= 0.0:
            rate = norm / norm_old
            if rate >= 1.0 or rate ** (NEWTON_MAXITER - it) / (1.0 - rate) * norm > tol:
                return -(it + 1), rate
        for m in range(n):
            W[0, m] += br[m]
            for p in range(npair):
                W[1 + 2 * p, m] += bc[p, m].real
                W[2 + 2 * p, m] += bc[p, m].imag
        _apply(T, W, Z)
        if norm == 0.0 or (norm_old >= 0.0 and rate / (1.0 - rate) * norm < tol):
            return it + 1, rate
        norm_old = norm
    return -NEWTON_MAXITER, rate


@njit(cache=True, error_model='numpy')
def _error_norm(fy, E, Z, h, LR, pr, y, rtol, atol, err):
    """Return the RMS norm of the error estimate (module doc) from ``fy``; estimate in ``err``.

    ``fy`` is f at the step's start (or, to refine a rejected step, f at y + err).
    """
    s = Z.shape[0]
    n = y.shape[0]
    for m in range(n):
        acc = 0.0
        for j in range(s):
            acc += E[j] * Z[j, m]
        err[m] = fy[m] + acc / h
    lu_solve(LR, pr, err)
    e = 0.0
    for m in range(n):
        scm = atol + rtol * max(abs(y[m]), abs(y[m] + Z[s - 1, m]))
        e += (err[m] / scm) ** 2
    return math.sqrt(e / n)


@njit(cache=True, error_model='numpy')
def radau_jac_run(f, jac, P, y0, t0, t_eval, rtol, atol, h_max, h_init, max_steps, A, C, T,
                  TI, mu_r, mu_c, E, Y_out, counts, y_last):
    """Adaptive Radau IIA with the exact Jacobian through the sample times (module doc).

    ``f`` and ``jac`` are the generated system's ``rhs`` and ``jac`` (first-class functions).
    Returns the status; ``counts`` = (nfev, nsteps, rejected, next step size, njev, t at
    the end) and ``y_last`` the state there (after ``max_steps`` steps, or the end).
    """
    n = y0.shape[0]
    s = C.shape[0]
    npair = mu_c.shape[0]
    y, fy, ytmp, ftmp, kk, h, nfev, status = start_run(f, P, y0, t0, t_eval, rtol, atol, s,
                                                       h_max, h_init, Y_out)
    sc = np.empty(n)
    err = np.empty(n)
    br = np.empty(n)
    Z = np.zeros((s, n))
    Zp = np.zeros((s, n))
    W = np.empty((s, n))
    F = np.empty((s, n))
    J = np.empty((n, n))
    LR = np.empty((n, n))
    LC = np.empty((npair, n, n), dtype=np.complex128)
    bc = np.empty((npair, n), dtype=np.complex128)
    pr = np.zeros(n, dtype=np.int64)
    pc = np.zeros((npair, n), dtype=np.int64)
    w = lagrange_weights(C)
    t = t0
    t_end = t_eval[t_eval.shape[0] - 1]
    njev = 0
    nsteps = 0
    nrej = 0
    tol = max(10.0 * 2.220446049250313e-16 / rtol, min(0.03, math.sqrt(rtol)))
    jac(y, P, J)
    njev += 1
    jac_current = True
    h_lu = 0.0                  # the step of the LU factors (0: none)
    h_old = 0.0                 # the last accepted step (0: none, no extrapolation)
    err_old = -1.0
    rejected = False
    while status == OK and t < t_end:
        if too_small(t, h):
            status = UNDERFLOW
            break
        h, h_free, clipped, t_next = clip_to_sample(t_eval, kk, t, h, h_max, t_end)
        # simplified Newton: the factors of h_lu serve steps h in [h_lu / KEEP_STEP, h_lu]
        if not (h_lu > 0.0 and h_lu / KEEP_STEP <= h <= h_lu):
            if not _factor(J, h, mu_r, mu_c, LR, LC, pr, pc):
                nrej += 1
                h *= 0.5
                h_lu = 0.0
                continue
            h_lu = h
        if h_old > 0.0:
            extrapolate(C, w, Zp, h / h_old, Z)
        else:
            for i in range(s):
                for m in range(n):
                    Z[i, m] = 0.0
        for m in range(n):
            sc[m] = 1.0 / (atol + rtol * abs(y[m]))
        it, rate = _newton(f, P, y, h, C, T, TI, mu_r, mu_c, LR, LC, pr, pc, sc, tol, Z,
                           W, F, ytmp, br, bc)
        nfev += abs(it) * s
        if it < 0:
            nrej += 1
            if not jac_current:
                jac(y, P, J)
                njev += 1
                jac_current = True
            else:
                h *= 0.5
            h_lu = 0.0
            rejected = True
            continue
        # error estimate (module doc)
        e = _error_norm(fy, E, Z, h, LR, pr, y, rtol, atol, err)
        if rejected and e > 1.0:            # refined once (Hairer): f at y + err
            for m in range(n):
                ytmp[m] = y[m] + err[m]
            rhs(f, ytmp, P, ftmp)
            nfev += 1
            e = _error_norm(ftmp, E, Z, h, LR, pr, y, rtol, atol, err)
        safety = 0.9 * (2 * NEWTON_MAXITER + 1) / (2 * NEWTON_MAXITER + it)
        if not math.isfinite(e) or e > 1.0:
            nrej += 1
            rejected = True
            h *= max(MIN_FACTOR, safety * e ** (-1.0 / (s + 1))) if math.isfinite(e) \
                else MIN_FACTOR
            continue
        # accepted
        t = t_next if clipped else t + h
        for m in range(n):
            y[m] += Z[s - 1, m]
        rhs(f, y, P, fy)
        nfev += 1
        for i in range(s):
            for m in range(n):
                Zp[i, m] = Z[i, m]
        nsteps += 1
        if not (all_finite(y) and all_finite(fy)):
            status = NONFINITE
            break
        kk = store_samples(t_eval, kk, t, y, Y_out)
        # Gustafsson's predictive controller (as scipy's Radau)
        if err_old < 0.0 or e == 0.0 or h_old == 0.0:
            mult = 1.0
        else:
            mult = h / h_old * (err_old / e) ** (1.0 / (s + 1))
        fac = MAX_GROWTH if e == 0.0 else min(1.0, mult) * e ** (-1.0 / (s + 1))
        fac = min(MAX_GROWTH, safety * fac)
        h_old = h
        err_old = e
        rejected = False
        recompute = it > 2 and rate > JAC_RATE
        if not recompute and 1.0 <= fac < KEEP_STEP:
            h_new = h
        else:
            h_new = h * fac
        if clipped and h_free > h_new:
            h_new = h_free
        if recompute:
            jac(y, P, J)
            njev += 1
            jac_current = True
            h_lu = 0.0
        else:
            jac_current = False
        h = h_new
        if nsteps >= max_steps:
            status = BUDGET
            break
    finish_run(counts, status, nfev, nsteps, nrej, h)
    counts[4] = njev
    counts[5] = t
    for m in range(n):
        y_last[m] = y[m]
    return status


_A, _C, _T, _TI, _MU_R, _MU_C, _E = tableau(STAGES)


class Radau9Jac(LoopStepped):
    """Radau IIA, 5 stages, order 9, with the exact generated Jacobian (module doc).

    For generated systems only (:class:`gyro_rotor.numerics.kernel_system.KernelSystem`: its
    ``kernel_rhs`` and ``kernel_jac``). Steps land on the sample times.
    References: Hairer and Wanner II, sec. IV.8; scipy's ``Radau`` (3 stages).
    """

    name = 'radau9'
    order = 2 * STAGES - 1
    adaptive = True
    implicit = True
    renormalize = False
    default_rtol = 1e-9
    default_atol = 1e-11

    def __init__(self, model, *args, **kwargs):
        if not hasattr(type(model), 'kernel_jac'):
            raise ParameterError(f'{self.name} with the generated Jacobian needs a generated '
                                 f'system, not {getattr(model, "name", model)!r}')
        super().__init__(model, *args, **kwargs)
        self.jac = model.kernel_jac

    def _loop(self, t_eval, Y, counts, max_steps):
        return radau_jac_run(self.kind, self.jac, self.P, self.y, self.t, t_eval, self.rtol,
                             self.atol, self.h_max, self._h_next, max_steps, _A, _C, _T, _TI,
                             _MU_R, _MU_C, _E, Y, counts, self._ylast)
