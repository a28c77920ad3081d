"""Spectra of x' = A(K_D) x: eigen-decomposition at any K_D, mode names, continuity.

A(K_D) = A0 - K_D b c^T (:mod:`gyro_rotor.core.linearize`). :func:`spectrum` uses A itself
for small K_D and the pencil ``[[A0, -b], [c^T, -1/K_D]] - lambda diag(1,..,1,0)`` for large
K_D (its entries stay of the size of A0, so nearly undamped roots keep their small real parts
to ~1e-13 absolute even at K_D = 1e9; K_D = inf gives the asymptotes). Modes are named once,
at K_D = 0, by the coordinate group that holds most of their modal energy
(:func:`_name_at_zero`), then followed along any path by eigenvector continuity
(:func:`track`), never by sorting. Split from :mod:`gyro_rotor.linear.stability` (issue 13).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Callable, Sequence

from gyro_rotor.core.linearize import Coords, LinearSystem
from gyro_rotor.errors import ParameterError
import numpy as np

__all__ = ['spectrum', 'K_ref', 'track', 'drive_sensitivity', 'zero_K_sensitivities',
           'resting_space', 'unit', 'unit_eig', 'ZERO_ROOT',
           'ZERO_ROOT_Z', 'STRUCTURAL', 'TOL_RE_REL', 'SLOTS', 'MAX_BISECTIONS_PER_POINT']

ZERO_ROOT = 'zero root (cyclic psi)'
#: without drive stiffness (K_S = 0) the lag z is cyclic too: a second structural zero root
ZERO_ROOT_Z = 'zero root (cyclic z: no drive stiffness)'
#: the structural zero roots: listed, never judged
STRUCTURAL = (ZERO_ROOT, ZERO_ROOT_Z)
#: at most this many bisections per path point in :func:`track` (plus a fixed reserve)
MAX_BISECTIONS_PER_POINT = 16
#: a real part with |Re| <= TOL_RE_REL ||A0||_F is on the imaginary axis (eig noise is
#: ~1e-14 ||A0||; the pencil keeps it there for every K_D)
TOL_RE_REL = 1e-12
#: names per coordinate system at K_D = 0: (name, coordinate group)
SLOTS = {
    'II': (('nutation', 'tilt'), ('housing twist', 'twist'), ('rotor-field coupling', 'drive')),
    'I': (('nutation', 'tilt'), ('precession', 'tilt'), ('housing twist', 'twist'),
          ('rotor-field coupling', 'drive')),
    'upright': (('housing twist', 'twist'), ('rotor-field coupling', 'drive')),
    'locked': (('rotor-field coupling', 'drive'),),
}


def _cyclic_z(lin: LinearSystem) -> int | None:
    """Index of z if it is cyclic (K_S = 0: its column of A0 is zero), else None."""
    if lin.params.K_S != 0.0 or 'z' not in lin.state_names:
        return None
    iz = lin.state_names.index('z')
    return iz if not np.any(lin.A0[:, iz]) else None


def unit(V: np.ndarray) -> np.ndarray:
    """Return the columns of ``V`` scaled to unit norm (a zero column stays zero)."""
    return V / np.maximum(np.linalg.norm(V, axis=0), 1e-300)


def unit_eig(A: np.ndarray) -> tuple:
    """Return the eigenvalues of ``A`` and its right eigenvectors of unit norm."""
    lam, V = np.linalg.eig(A)
    return lam, unit(V)


def spectrum(lin: LinearSystem, K_D: float, *, left: bool = False):
    """Return the eigenvalues and eigenvectors of A(K_D); K_D may be inf.

    Eigenvalues (n,), right eigenvectors (n, n) (columns, energy-weighted, unit norm)
    and, if ``left``, left eigenvectors (unweighted).

    Without drive stiffness (K_S = 0) z is cyclic: its zero root is deflated (the
    spectrum of A without z, then the root 0 with eigenvector e_z appended last) so that
    it cannot make a defective cluster with the drive's slip root at K_D = 0; z carries
    no energy then (weight sqrt(K_S) = 0), so the other weighted vectors have no z part.
    Raises ParameterError if K_D is negative or the eigenvalues are not finite (K_D
    beyond what double precision resolves).
    """
    if K_D < 0 or math.isnan(K_D):
        raise ParameterError(f'K_D must not be negative, got {K_D!r} N m s/rad')
    iz = _cyclic_z(lin)
    if iz is None:
        out = _spectrum(lin, K_D, left)
    else:
        keep = [k for k in range(len(lin.c)) if k != iz]
        red = dataclasses.replace(
            lin, A=lin.A[np.ix_(keep, keep)], A0=lin.A0[np.ix_(keep, keep)], b=lin.b[keep],
            c=lin.c[keep], weights=lin.weights[keep],
            groups=tuple(lin.groups[k] for k in keep),
            state_names=tuple(lin.state_names[k] for k in keep))
        r = _spectrum(red, K_D, left)
        n = len(lin.c)
        ez = np.zeros((n, 1), dtype=complex)
        ez[iz] = 1.0

        def pad(M):
            full = np.zeros((n, M.shape[1]), dtype=complex)
            full[keep] = M
            return np.hstack([full, ez])
        out = (np.append(r[0], 0.0),) + tuple(pad(M) for M in r[1:])
    if not np.all(np.isfinite(out[0])):
        raise ParameterError(f'K_D = {float(K_D)!r} N m s/rad is too large for the linear '
                             'analysis: the eigenvalues are not finite in double precision')
    return out


def K_ref(lin) -> float:
    """Return the characteristic drive damping: the spectral radius of A0 over min eig(c'b).

    ``lin``: any linearization with A0, b, c (the centrifuge's analytic
    :class:`~gyro_rotor.core.linearize.LinearSystem`, b and c vectors, or a
    :class:`~gyro_rotor.linear.system.Linearization`, one column a drive).
    """
    cb = np.atleast_2d(lin.c.T @ lin.b)
    return (max(1.0, float(np.abs(np.linalg.eigvals(lin.A0)).max()))
            / float(np.linalg.eigvalsh(cb).min()))


def drive_sensitivity(A0: np.ndarray, BC: np.ndarray, lam: np.ndarray, W: np.ndarray,
                      V: np.ndarray) -> np.ndarray:
    """Return d lambda_j/d K of A0 - K BC at its eigenpairs (lam, left W, right V).

    Eigenvalue perturbation theory: d lambda/d K = -(w^H BC v)/(w^H v). Where w^H v is
    tiny (a defective or repeated root: a Jordan block, the cyclic zero roots) a central
    finite difference of the nearest eigenvalue over K in [-h, h] replaces it.
    """
    d = np.empty(len(lam), dtype=complex)
    h = 1e-7 * max(np.linalg.norm(A0), 1.0) / max(np.linalg.norm(BC), 1e-300)
    near = None
    for j in range(len(lam)):
        w, v = W[:, j], V[:, j]
        den = np.vdot(w, v)
        if np.linalg.norm(w) * np.linalg.norm(v) < 1e8 * abs(den):
            d[j] = -np.vdot(w, BC @ v) / den
            continue
        if near is None:
            near = [np.linalg.eigvals(A0 - h * BC), np.linalg.eigvals(A0 + h * BC)]
        lp, lm = (x[np.argmin(abs(x - lam[j]))] for x in near)
        d[j] = (lp - lm) / (2 * h)
    return d


def resting_space(A0: np.ndarray, BC: np.ndarray) -> np.ndarray:
    """Return an orthonormal basis of the states at rest for every K: A0 v = 0 = BC v.

    On this space A(K) = A0 - K BC is zero for every K: its roots stay at 0 with the same
    eigenvectors (d lambda/d K = 0 exactly). The coordinate axes whose column of A0 and of
    BC is zero (a rotor angle z without drive stiffness, K_S = 0) come last, as themselves;
    the rest of the space (e.g. a cyclic angle's direction) before them, orthogonal to them.
    """
    n = A0.shape[0]
    axes = [i for i in range(n) if not np.any(A0[:, i]) and not np.any(BC[:, i])]
    others = [i for i in range(n) if i not in axes]
    S = np.vstack([A0, BC])[:, others]
    if not others:
        return np.eye(n)[:, axes]
    _, sv, Vh = np.linalg.svd(S)
    # the numerical rank: singular values within round-off of the largest are zero
    # (numpy's matrix_rank rule; K_S = 1e-8 N m/rad is a stiffness, not a rest)
    tol = max(S.shape) * np.finfo(float).eps * max(float(sv[0]) if sv.size else 0.0, 1e-300)
    rank = int(np.sum(sv > tol))
    N = np.zeros((n, len(others) - rank))
    N[others] = Vh[rank:].conj().T
    return np.hstack([N, np.eye(n)[:, axes]])


#: roots closer than this many times their round-off radii are one (repeated) root
ROUND_OFF_MARGIN = 100.0


def _round_off_radius(A: np.ndarray, W: np.ndarray, V: np.ndarray) -> np.ndarray:
    """Return how far round-off can move each computed root of A: n eps ||A|| kappa_j.

    The computed roots are exact for a matrix within n eps ||A|| of A (backward
    stability of the QR algorithm); to first order a root moves by at most its condition
    number kappa_j = ||w|| ||v|| / |w^H v| times that (Bauer-Fike, per root). A defective
    root's computed pieces lie within it of each other (kappa grows as they approach); a
    semisimple repeated root's lie within n eps ||A||.
    """
    n = max(A.shape[0], 1)
    den = np.abs(np.einsum('ij,ij->j', W.conj(), V))
    norms = np.linalg.norm(W, axis=0) * np.linalg.norm(V, axis=0)
    with np.errstate(divide='ignore'):
        kappa = np.where(den > 0, norms / np.maximum(den, 1e-300), np.inf)
    return n * np.finfo(float).eps * max(np.linalg.norm(A), 1e-300) * kappa


def zero_K_sensitivities(A0: np.ndarray, BC: np.ndarray) -> tuple:
    """Return the roots of A0, their d lambda/d K of A0 - K BC at K = 0, right eigenvectors.

    The one rule of every system (the centrifuge's and a system file's): the resting space
    (:func:`resting_space`, dimension k) is taken out first; its k roots stay at 0 for every
    K (d = 0, returned last, eigenvectors its basis). The other roots are those of the
    reduced matrix Q^H A(K) Q (Q an orthonormal basis of the complement; the resting space
    is invariant, so A(K) is block triangular in (Q, N)): a simple root by perturbation
    theory, d = -(w^H BCr v)/(w^H v); a repeated root by first-order degenerate
    perturbation theory if it is semisimple there (d the eigenvalues of the perturbation
    restricted to it, its vectors the ones the perturbation diagonalizes), nan (not
    defined: the roots split like sqrt(K)) if it is still defective. Roots are one repeated
    root where they lie within the reach of round-off (:func:`_round_off_radius`: n eps
    ||A|| times their condition numbers), distinct where double precision resolves them:
    the rotor-field pair +-i sqrt(K_S/C) of a tiny K_S > 0 is two simple roots, each with
    its own d (a threshold on the spectral scale merged them by size, K_S = 1e-8 on the
    centrifuge, 1e-7 on its system file). Eigenvectors of the reduced roots are returned
    as Q y (unit norm).
    """
    import scipy.linalg as sl
    n = A0.shape[0]
    N = resting_space(A0, BC)
    k = N.shape[1]
    if k:
        Qf, _ = np.linalg.qr(np.hstack([N, np.eye(n)]))
        Q = Qf[:, k:n]
    else:
        Q = np.eye(n)
    Ar, Br = Q.conj().T @ A0 @ Q, Q.conj().T @ BC @ Q
    lam, W, V = sl.eig(Ar, left=True, right=True)
    V, W = unit(V).astype(complex), unit(W).astype(complex)
    r = len(lam)
    d = np.full(r, np.nan, dtype=complex)
    rho = _round_off_radius(Ar, W, V)
    done = np.zeros(r, dtype=bool)
    for j in range(r):
        if done[j]:
            continue
        idx = [i for i in range(r)
               if not done[i] and abs(lam[i] - lam[j]) <= ROUND_OFF_MARGIN * (rho[i] + rho[j])]
        done[idx] = True
        if len(idx) == 1:
            den = np.vdot(W[:, j], V[:, j])
            if abs(den) > 1e-8:
                d[j] = -np.vdot(W[:, j], Br @ V[:, j]) / den
            continue
        Nc, L = V[:, idx], W[:, idx]
        G = L.conj().T @ Nc
        sv = [np.linalg.svd(X, compute_uv=False) for X in (Nc, L)]
        # still defective (the vectors of the cluster do not span it): not defined
        if min(x[-1] / x[0] for x in sv) < 1e-6 or np.linalg.cond(G) > 1e8:
            continue
        M = -np.linalg.solve(G, L.conj().T @ Br @ Nc)
        mu, Y = np.linalg.eig(M)
        d[idx] = mu
        V[:, idx] = unit(Nc @ Y)
        lam[idx] = np.mean(lam[idx])
    return (np.concatenate([lam, np.zeros(k)]), np.concatenate([d, np.zeros(k)]),
            np.hstack([unit(Q @ V), N.astype(complex)]), Q, r)


def by_pencil(lin: LinearSystem, K_D: float) -> bool:
    """Return True if :func:`spectrum` computes the roots at ``K_D`` from the pencil.

    K_D ||b|| ||c|| beyond ||A0||: the roots of the pencil of A0 and the drive (QZ, no
    scaling: their round-off is that of A0), else of A(K_D) itself (LAPACK's eig, balanced).
    """
    c_norm = max(np.linalg.norm(lin.c), 1e-300)
    return bool(K_D * np.linalg.norm(lin.b) > np.linalg.norm(lin.A0) / c_norm)


def _spectrum(lin: LinearSystem, K_D: float, left: bool):
    import scipy.linalg as sl
    n = len(lin.c)
    if not by_pencil(lin, K_D):
        if left:
            lam, W, V = sl.eig(lin.with_K_D(K_D), left=True, right=True)
        else:
            lam, V = sl.eig(lin.with_K_D(K_D))
            W = None
    else:
        if left:
            raise ParameterError('left eigenvectors are only computed for small K_D')
        P = np.zeros((n + 1, n + 1))
        P[:n, :n] = lin.A0
        P[:n, n] = -lin.b
        P[n, :n] = lin.c
        P[n, n] = -1.0 / K_D if math.isfinite(K_D) else 0.0
        B = np.eye(n + 1)
        B[n, n] = 0.0
        lam, V = sl.eig(P, B)
        # QZ returns the infinite eigenvalues with beta = 0 or of rounding size
        big_lam = 1e300 if math.isfinite(K_D) else 1e12 * max(np.linalg.norm(lin.A0), 1.0)
        keep = np.isfinite(lam) & (np.abs(lam) < big_lam)
        order = np.argsort(~keep, kind='stable')
        lam, V = lam[order], V[:n, order]
        nfin = n if math.isfinite(K_D) else int(np.sum(keep))
        lam, V = lam[:nfin], V[:, :nfin]
        W = None
    Vw = V * lin.weights[:, None]
    Vw = unit(Vw)
    return (lam, Vw, W) if left else (lam, Vw)


def _shares(lin: LinearSystem, Vw: np.ndarray) -> dict:
    groups = np.array(lin.groups)
    e = np.abs(Vw) ** 2
    tot = np.maximum(e.sum(axis=0), 1e-300)
    return {g: e[groups == g].sum(axis=0) / tot for g in ('tilt', 'twist', 'drive')}


def _name_at_zero(lin: LinearSystem, lam: np.ndarray, Vw: np.ndarray, d=None,
                  at_zero=None) -> list:
    """Names of the eigenvalues of A0 (K_D = 0) by modal energy shares (module doc).

    ``d`` (the sensitivities d lambda/d K_D) decides which of several zero roots (``at_zero``:
    which roots are 0 within their round-off) is the structural one of psi: the one the
    drive damping does not move.
    """
    from scipy.optimize import linear_sum_assignment
    n = len(lam)
    tol_im = 1e-9 * max(np.max(np.abs(lam)), 1.0)
    names: list = [None] * n
    free = list(range(n))
    if _cyclic_z(lin) is not None:          # spectrum() appends the root of z last
        names[n - 1] = ZERO_ROOT_Z
        free.remove(n - 1)
    if lin.coords == Coords.II:
        mag = np.abs(lam[free])
        if d is not None and at_zero is not None:
            near = np.asarray(at_zero)[free]
            if np.sum(near) > 1:
                mag = np.where(near, np.abs(np.asarray(d)[free]), np.inf)
        j0 = free[int(np.argmin(mag))]
        names[j0] = ZERO_ROOT
        free.remove(j0)
    units = []               # lists of eigenvalue indices: a conjugate pair or a real root
    rest = sorted(free, key=lambda j: -lam[j].imag)
    while rest:
        j = rest.pop(0)
        if lam[j].imag > tol_im and rest:
            k = min(rest, key=lambda i: abs(lam[i] - np.conj(lam[j])))
            rest.remove(k)
            units.append([j, k])
        else:
            units.append([j])
    sh = _shares(lin, Vw)
    slots = list(SLOTS[lin.coords])
    cost = np.array([[-sh[g][u[0]] for _, g in slots] for u in units])
    rows, cols = linear_sum_assignment(cost)
    extra = 0
    assigned = dict(zip(rows, cols))
    for ui, u in enumerate(units):
        if ui in assigned:
            nm = slots[assigned[ui]][0]
        else:
            extra += 1
            nm = f'mode {extra}'
        for j in u:
            names[j] = nm
    # the two tilt modes about solution I: the faster one is the nutation
    if lin.coords == Coords.I:
        tilt = [ui for ui, u in enumerate(units)
                if names[u[0]] in ('nutation', 'precession')]
        if len(tilt) == 2:
            fast, slow = sorted(tilt, key=lambda ui: -abs(lam[units[ui][0]].imag))
            for j in units[fast]:
                names[j] = 'nutation'
            for j in units[slow]:
                names[j] = 'precession'
    return names


def _match(lam0, V0, lam1, V1):
    """Assign new eigenpairs to old ones: eigenvector overlap, eigenvalue distance."""
    from scipy.optimize import linear_sum_assignment
    if not (np.all(np.isfinite(lam1)) and np.all(np.isfinite(V1))):
        raise ParameterError('the eigenvalues along the path are not finite (a parameter '
                             'beyond what double precision resolves)')
    overlap = np.abs(V0.conj().T @ V1)
    # the spectral scale without the one root that escapes like -K_D c^T b (which would
    # make every other root's step look negligible); that root is measured against itself
    a0, a1 = np.abs(lam0), np.abs(lam1)
    scale = max(np.sort(a0)[-2] if a0.size > 1 else a0[0],
                np.sort(a1)[-2] if a1.size > 1 else a1[0], 1e-12)
    D = (np.abs(lam0[:, None] - lam1[None, :])
         / np.maximum(scale, np.minimum(a0[:, None], a1[None, :])))
    cost = (1.0 - overlap) + D
    rows, cols = linear_sum_assignment(cost)
    perm = np.empty(len(lam0), dtype=int)
    perm[rows] = cols
    quality = float(np.min(overlap[rows, cols])), float(np.max(D[rows, cols]))
    return perm, quality


def track(fn: Callable[[float], tuple], s_values: Sequence[float], labels0: list, *,
          log: bool = False, max_depth: int = 12, min_overlap: float = 0.9,
          max_jump: float = 0.05):
    """Follow eigenpairs along a parameter path by eigenvector continuity.

    Parameters
    ----------
    fn : callable
        ``fn(s) -> (eigenvalues (n,), eigenvectors (n, n))`` (vectors unit-norm columns).
    s_values : sequence of float
        The path (monotonic); intervals where the match is ambiguous (overlap below
        ``min_overlap`` or a jump above ``max_jump`` of the spectral scale) are bisected
        (geometrically if ``log`` and both ends are positive) up to ``max_depth`` times,
        and at most :data:`MAX_BISECTIONS_PER_POINT` times per path point in all.
    labels0 : list of str
        Names of the eigenpairs of ``fn(s_values[0])``, in its order.

    Returns
    -------
    eigenvalues : ndarray, shape (len(s_values), n)
        Column j follows the mode ``labels0[j]``.
    """
    s_values = [float(s) for s in s_values]
    lam, V = fn(s_values[0])
    out = [lam.copy()]
    # a cap on the bisections of the whole path: a degenerate cluster (repeated roots
    # whose vectors eig picks arbitrarily) must not bisect every interval to max_depth
    budget = MAX_BISECTIONS_PER_POINT * len(s_values) + 4 * max_depth
    for s1 in s_values[1:]:
        stack = [(s1, 0)]
        cur_s = s_values[len(out) - 1]
        while stack:
            target, depth = stack[-1]
            lam1, V1 = fn(target)
            perm, (ov, jump) = _match(lam, V, lam1, V1)
            if (ov < min_overlap or jump > max_jump) and depth < max_depth and budget > 0:
                if log and cur_s > 0 and target > 0:
                    mid = math.sqrt(cur_s * target)
                else:
                    mid = 0.5 * (cur_s + target)
                if mid != cur_s and mid != target:
                    budget -= 1
                    stack.append((mid, depth + 1))
                    continue
            lam, V = lam1[perm], V1[:, perm]
            cur_s = target
            stack.pop()
        out.append(lam.copy())
    return np.array(out)
