"""The paper's claims (a) to (d) about the root locus over K_D, checked by what they mean.

Magnus 1980, section 4: for x' = A(K_D) x with A(K_D) = A0 - K_D B C (m drives: B the
response to a unit drive torque, n x m; C picks the drive lag rates, m x n; the
centrifuge has m = 1, ``B = b``, ``C = c^T``):

(a) at K_D = 0 every root lies on the imaginary axis (the conservative system);
(b) for every K_D > 0 no root in the right half plane, and every root the drive reaches
    in the open left half plane (within the eigensolver's resolution), except roots the drive
    does not reach (d lambda/d K_D = 0 at K_D = 0, e.g. the tilt modes about solution I:
    Hagedorn's exclusion), which theory expects to stay on the axis;
(c) as K_D -> infinity the roots tend to the spectrum of the *locked* system (C x = 0:
    each rotor locked to its field; computed here separately as A0 projected on ker C,
    :func:`locked_spectrum`) plus, per drive, one real root to -infinity (like -K_D times
    an eigenvalue of C B) and one to 0 (the lag frozen by the lock);
(d) a complex pair meets the negative real axis at K_D* and splits, one root toward 0,
    one toward -infinity: every K_D* where a pair meets the real axis is bracketed on the
    grid and located by polishing the double root (:func:`meeting_points`).

No claim looks at mode names: they are labels from the mode shapes only. The functions
take a :class:`DriveSystem`, built from the centrifuge's
:class:`~gyro_rotor.linear.linearize.LinearSystem` by :func:`drive_system`, so they serve
any system of this form.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Callable

import numpy as np

__all__ = ['DriveSystem', 'Claim', 'Meeting', 'drive_system', 'locked_spectrum',
           'claim_a', 'claim_b', 'claim_c', 'claim_d', 'meeting_points', 'POLISH_RTOL']

#: relative accuracy of K_D* (the double root is polished to it and verified)
POLISH_RTOL = 1e-8


@dataclasses.dataclass(frozen=True)
class DriveSystem:
    """x' = (A0 - K_D B C) x and how to compute its spectrum at any K_D (inf included).

    ``eigvals(K)`` returns the n eigenvalues (n - m finite ones at K = inf); ``tol_re`` is
    the eigensolver's resolution of a real part; ``reached`` marks, per eigenvalue of A0
    (in the order of ``eigvals(0)``), whether the drive damping moves it (d Re/d K_D < 0).
    """

    A0: np.ndarray
    B: np.ndarray
    C: np.ndarray
    eigvals: Callable[[float], np.ndarray]
    tol_re: float
    reached: np.ndarray

    @property
    def drives(self) -> int:
        """Return the number of drives m."""
        return self.B.shape[1]


@dataclasses.dataclass(frozen=True)
class Claim:
    """One of the paper's claims: whether it holds, why, its numbers, expected exceptions."""

    key: str
    statement: str
    holds: bool
    detail: str
    data: dict
    exception: str = ''


@dataclasses.dataclass(frozen=True)
class Meeting:
    """A complex pair meeting the real axis at K_D* in a double root lambda*."""

    K_D: float
    lam: float
    verified_rtol: float


def drive_system(lin) -> DriveSystem:
    """Return the :class:`DriveSystem` of a centrifuge linearization (one drive)."""
    from gyro_rotor.linear.stability import _tol_re, sensitivities, spectrum
    lam_s, d0, _ = sensitivities(lin)
    lam0 = spectrum(lin, 0.0)[0]
    # sensitivities are in the order of their own basis: align them with eigvals(0)
    from scipy.optimize import linear_sum_assignment
    r, c = linear_sum_assignment(np.abs(lam0[:, None] - lam_s[None, :]))
    tol_sens = 1e-9 * max(float(np.max(np.abs(d0))), 1e-300)
    reached = np.zeros(len(lam0), dtype=bool)
    reached[r] = np.asarray(d0)[c].real < -tol_sens
    return DriveSystem(A0=lin.A0, B=lin.b[:, None], C=lin.c[None, :],
                       eigvals=lambda K: spectrum(lin, K)[0], tol_re=_tol_re(lin),
                       reached=reached)


def locked_spectrum(sys: DriveSystem) -> np.ndarray:
    """Eigenvalues of the locked system: A0 restricted to ker C, projected along B.

    With C x = 0 held by an unbounded drive torque B u, x' = P A0 x with the projector
    P = I - B (C B)^-1 C (C P = 0 keeps x in ker C); in an orthonormal basis N of ker C
    the locked matrix is N^T P A0 N ((n - m) x (n - m)).
    """
    B, C = sys.B, sys.C
    P = np.eye(len(sys.A0)) - B @ np.linalg.solve(C @ B, C)
    N = np.linalg.svd(C)[2][C.shape[0]:].T
    return np.linalg.eigvals(N.T @ P @ sys.A0 @ N)


def _scale(sys: DriveSystem) -> float:
    return max(float(np.max(np.abs(np.linalg.eigvals(sys.A0)))), 1.0)


def claim_a(sys: DriveSystem) -> Claim:
    """Check (a): at K_D = 0 every root on the imaginary axis."""
    lam0 = sys.eigvals(0.0)
    worst = float(np.max(np.abs(lam0.real)))
    tol = sys.tol_re
    zero = int(np.sum(np.abs(lam0) <= tol))
    osc = int(np.sum((lam0.imag > tol) & (np.abs(lam0.real) <= tol)))
    return Claim('a', 'at K_D = 0 every root on the imaginary axis (undamped oscillations '
                 'and zero roots)', worst <= tol,
                 f'{osc} undamped oscillations and {zero} zero root(s); max |Re| = '
                 f'{_res(worst, tol)} 1/s',
                 {'oscillations': osc, 'zero_roots': zero, 'max_abs_re': worst,
                  'freq_hz': sorted((lam0[lam0.imag > tol].imag / (2 * math.pi)).tolist())})


def _res(x: float, tol: float) -> str:
    """Format a real part; below the resolution 'below the resolution tol' (never 1e-102)."""
    return f'below the resolution {tol:.1e}' if abs(x) <= tol else f'{x:+.3e}'


def claim_b(sys: DriveSystem, K: np.ndarray, eig_path: np.ndarray,
            labels: list | None = None) -> Claim:
    """Check (b): for every K_D > 0 of the path, every root reached by the drive in the open LHP.

    ``eig_path[i, j]`` is branch j at ``K[i]``, tracked by continuity from ``eigvals(0)``
    (matched to the eigenvalues of A0 at its start). A root at zero for every K_D (a
    cyclic coordinate) is structural and not judged. ``labels`` (mode names per branch)
    only name the exceptions in the text.
    """
    from scipy.optimize import linear_sum_assignment
    tol = sys.tol_re
    pos = K > 0
    re = eig_path[pos].real
    structural = np.all(np.abs(eig_path) <= tol, axis=0)
    # branch j starts at eigenvalue col[j] of A0
    _, col = linear_sum_assignment(np.abs(eig_path[0][:, None] - sys.eigvals(0.0)[None, :]))
    reached = sys.reached[col] & ~structural
    unreached = ~sys.reached[col] & ~structural
    # a reached root within the resolution of the axis is not a failure: Re ~ K_D dRe/dK_D
    # at tiny K_D (fast_spin's nutation: -7e-7 per N m s/rad), or a branch returning to an
    # asymptote on the axis like 1/K_D; such roots are counted in the detail
    bad = re > tol
    unresolved = int(np.sum((np.abs(re) <= tol) & reached[None, :]))
    exc = ''
    if unreached.any():
        on_axis = bool(np.all(np.abs(re[:, unreached]) <= tol))
        names = sorted({labels[j] for j in np.where(unreached)[0]}) if labels else []
        exc = (f'{int(unreached.sum())} roots not reached by the drive'
               + (f' ({", ".join(names)})' if names else '')
               + " (d Re/d K_D = 0 at K_D = 0: Hagedorn's exclusion) stay on the imaginary "
               'axis, as the theory expects' + ('' if on_axis else ' (BUT some left it)'))
    worst_reached = float(re[:, reached].max()) if reached.any() else -math.inf
    if bad.any():
        i, j = np.argwhere(bad)[0]
        detail = (f'fails: at K_D = {K[pos][i]:.6g} root {eig_path[pos][i, j]:.6g} has Re = '
                  f'{_res(re[i, j], tol)} 1/s')
    else:
        detail = (f'holds on {int(pos.sum())} K_D values from {K[pos][0]:.3g} to '
                  f'{K[-1]:.3g}: largest Re of a reached root {_res(worst_reached, tol)} 1/s'
                  + (f' ({unresolved} roots of reached modes within the resolution of the '
                     f'axis)' if unresolved else ''))
    return Claim('b', 'for every K_D > 0 every root the drive reaches in the open left half '
                 'plane', not bool(bad.any()), detail,
                 {'max_re_reached': worst_reached, 'tol_re': tol, 'unresolved': unresolved,
                  'unreached': int(unreached.sum())}, exc)


def claim_c(sys: DriveSystem, K_check: float) -> Claim:
    """Check (c): K_D -> inf, roots -> locked spectrum, plus per drive one to -inf and one to 0.

    Checked at ``K_check`` (large) and 10 ``K_check``: the m fastest roots go like
    -K_D eig(C B) (within 1 %), the other n - m approach the locked spectrum (computed
    separately) with a distance that falls like 1/K_D; the locked spectrum holds m more
    zero roots than A(K_D) has at finite K_D (the roots that go to 0).
    """
    m = sys.drives
    locked = locked_spectrum(sys)
    gains = np.sort(np.linalg.eigvals(sys.C @ sys.B).real)
    scale = _scale(sys)
    from scipy.optimize import linear_sum_assignment
    dist, fast_ok = [], True
    for K in (K_check, 10.0 * K_check):
        lam = sys.eigvals(K)
        order = np.argsort(lam.real)
        fast, rest = lam[order[:m]], lam[order[m:]]
        fast_ok &= bool(np.all(np.abs(np.sort(-fast.real) / (K * gains) - 1.0) < 0.01)
                        and np.all(np.abs(fast.imag) <= 1e-6 * np.abs(fast)))
        D = np.abs(rest[:, None] - locked[None, :])
        r, c = linear_sum_assignment(D)
        dist.append(float(D[r, c].max()) / scale)
    tol = sys.tol_re
    zeros_locked = int(np.sum(np.abs(locked) <= tol * 10))
    zeros_finite = int(np.sum(np.abs(sys.eigvals(K_check)) <= tol * 10))
    to_zero = zeros_locked - zeros_finite
    converging = dist[1] <= max(0.2 * dist[0], 1e-9)
    holds = fast_ok and converging and dist[1] < 1e-2 and to_zero == m
    on_axis = locked[np.abs(locked.real) <= tol * 10]
    detail = (f'locked spectrum (A0 on ker C, {len(locked)} roots): '
              + ', '.join(f'{z.real:+.4g}{z.imag:+.6g}j' if abs(z.real) > tol * 10
                          else f'{z.imag:+.6g}j' for z in locked if z.imag >= -tol)
              + f'; distance of the roots to it / max|lambda(A0)|: {dist[0]:.2e} at K_D = '
              f'{K_check:.3g}, {dist[1]:.2e} at {10 * K_check:.3g}; fast root(s) '
              f'-K_D {", ".join(f"{g:.6g}" for g in gains)} '
              f'({"ok" if fast_ok else "NOT"}); roots to 0: {to_zero} (drives: {m}); '
              f'{len(on_axis)} locked roots on the imaginary axis')
    return Claim('c', 'K_D -> infinity: the roots tend to the spectrum of the locked system, '
                 'plus per drive one real root to -infinity and one to 0', bool(holds), detail,
                 {'locked_re': locked.real.tolist(), 'locked_im': locked.imag.tolist(),
                  'distance': dist, 'fast_gain': gains.tolist(), 'to_zero': to_zero,
                  'locked_on_axis': len(on_axis)})


def _n_real(lam: np.ndarray, tol_im: float) -> int:
    return int(np.sum(np.abs(lam.imag) <= tol_im))


def _K_of_lambda(sys: DriveSystem, lam: float) -> float:
    """Gain K >= 0 putting a root at the real ``lam``: det(I + K C (lam - A0)^-1 B) = 0."""
    n = len(sys.A0)
    G = sys.C @ np.linalg.solve(lam * np.eye(n) - sys.A0, sys.B)
    mu = np.linalg.eigvals(G)
    ks = [-1.0 / z.real for z in mu if abs(z.imag) <= 1e-12 * abs(z) and z.real < 0]
    return min(ks) if ks else math.inf


def _polish(sys: DriveSystem, lo: float, hi: float, tol_im: float) -> Meeting | None:
    """Locate the meeting between grid values lo < hi (real-root count up by 2)."""
    from scipy.optimize import minimize_scalar
    lam_hi = sys.eigvals(hi)
    lam_lo = sys.eigvals(lo)
    real_hi = lam_hi[np.abs(lam_hi.imag) <= tol_im].real
    real_lo = lam_lo[np.abs(lam_lo.imag) <= tol_im].real
    if len(real_hi) < 2:
        return None
    # the two real roots at hi that were complex at lo: farthest from the real roots at lo
    far = [np.min(np.abs(real_lo - x)) if len(real_lo) else math.inf for x in real_hi]
    cand = real_hi[np.argsort(far)[-2:]]
    a, b = float(min(cand)), float(max(cand))
    if b >= 0:
        return None
    # on the real axis K(lambda) has a local minimum K_D* at the double root lambda*
    res = minimize_scalar(lambda x: _K_of_lambda(sys, x), bounds=(a, b), method='bounded',
                          options={'xatol': 1e-13 * max(abs(a), 1.0)})
    K_star, lam_star = float(res.fun), float(res.x)
    if not (lo <= K_star <= hi * (1 + 1e-12)):
        return None
    # verify: complex just below K_D* (1 - r), two real roots just above (1 + r)
    r = POLISH_RTOL / 10
    below = _n_real(sys.eigvals(K_star * (1 - r)), tol_im * 1e-3)
    above = _n_real(sys.eigvals(K_star * (1 + r)), tol_im * 1e-3)
    return Meeting(K_star, lam_star, r if above == below + 2 else math.nan)


def meeting_points(sys: DriveSystem, K: np.ndarray) -> list[Meeting]:
    """Every K_D* of the grid's range where a complex pair meets the real axis."""
    tol_im = 1e-7 * _scale(sys)
    counts = [_n_real(sys.eigvals(k), tol_im) for k in K]
    out = []
    for i in range(1, len(K)):
        if counts[i] >= counts[i - 1] + 2 and K[i - 1] > 0:
            mt = _polish(sys, float(K[i - 1]), float(K[i]), tol_im)
            if mt is not None:
                out.append(mt)
    return out


def claim_d(sys: DriveSystem, K: np.ndarray, eig_path: np.ndarray) -> tuple:
    """Check (d): a pair meets the negative real axis at K_D* and splits toward 0 and -infinity.

    Returns (claim, meetings). The pair that meets last is followed along the tracked
    path (``eig_path`` columns, continuity): at the largest K_D one of its roots must be
    the fastest (toward -infinity), the other the one nearest to 0 among the non-structural
    roots (toward 0).
    """
    meets = meeting_points(sys, K)
    tol = sys.tol_re
    text = '; '.join(f'K_D* = {mt.K_D:.8g} N m s/rad, double root {mt.lam:.6g} 1/s'
                     + ('' if mt.verified_rtol == mt.verified_rtol else ' (NOT verified)')
                     for mt in meets)
    if not meets:
        return Claim('d', 'a complex pair meets the negative real axis at K_D* and splits: '
                     'one root toward 0, one toward -infinity', False,
                     f'no complex pair meets the real axis for K_D in {K[1]:.3g} .. '
                     f'{K[-1]:.3g}', {'K_D_star': [], 'lambda_star': []}), meets
    last = meets[-1]
    i = int(np.searchsorted(K, last.K_D))
    row = eig_path[min(i, len(K) - 1)]
    pair = np.argsort(np.abs(row - last.lam))[:2]
    end = eig_path[-1]
    structural = np.all(np.abs(eig_path) <= tol, axis=0)
    judged = np.where(~structural)[0]
    fastest = judged[np.argmin(end[judged].real)]
    nearest0 = judged[np.argmin(np.abs(end[judged]))]
    splits = {int(fastest), int(nearest0)} == {int(j) for j in pair}
    verified = all(mt.verified_rtol == mt.verified_rtol for mt in meets)
    holds = bool(verified and all(mt.lam < 0 for mt in meets) and splits)
    text += (f'; after the last one the pair splits toward 0 and -infinity (the nearest '
             f'root to 0 and the fastest at K_D = {K[-1]:.3g}: {end[pair[0]].real:.4g} and '
             f'{end[pair[1]].real:.4g} 1/s): {"yes" if splits else "NO"}')
    return Claim('d', 'a complex pair meets the negative real axis at K_D* and splits: one '
                 'root toward 0, one toward -infinity', holds, text,
                 {'K_D_star': [mt.K_D for mt in meets],
                  'lambda_star': [mt.lam for mt in meets], 'splits': splits}), meets
