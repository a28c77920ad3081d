"""The paper's claims (a) to (d) about the root locus over K_D: one checker for every system.

Magnus 1980, sections 2-4 (MODEL.md section 8). About a steady motion the state x of any
rotor system of the paper's form (n carrier coordinates, m rotors with self-stable
synchronous drives) obeys

    x' = A(K) x,   A(K) = A0 - B diag(K) C,

with A0 the conservative system (every drive's damping K_D = 0), B (N x m) the response to
a unit drive torque on each rotor and C (m x N) picking the rotors' lag rates zdot. The
root locus varies a common K over the drives in ``vary`` (all, or one), the others keep
their own K_D.

The claims, each decided by its meaning (no eigenvalue is called real, zero or reached by
comparing its size with a threshold tuned to some spectrum):

(a) at K = 0 every root on the imaginary axis;
(b) at the scene's K_D every root the drives reach in the open left half plane, the
    unreached ones on the axis at their K = 0 values (Hautus/PBH: a mode is unreached when
    its eigenvector has no zdot part);
(c) as K -> infinity m roots go to -infinity (like -K eig(C B)), m to 0 (like 1/K), the
    rest to the spectrum of the locked system (zdot = 0 held, computed separately) at a
    distance that shrinks like 1/K;
(d) every K where a pair meets on the real axis (break-in: a complex pair lands and splits)
    or leaves it (breakaway: two real roots merge and go complex), with its meeting point,
    and the net count (break-ins minus breakaways) equal to m.

How. The unreached roots do not move with K: they are the eigenvalues of A0 on the
unobservable subspace U of (C, A0) (the largest A0-invariant subspace in ker C, found by
an orthogonal staircase; :func:`fixed_subspace`), which is invariant under A(K) for every
K. Structural zero roots (cyclic coordinates) lie in U and are identified by their
eigenvectors: the generalized kernel of A0 on U. On the complement the moving roots are the
eigenvalues of A_V(K) = A0_V - K B_V C_V, a system with no root that stays put, so a root
near 0 is just a root: slow roots -K_S/K still count as real. The locus of A_V is
followed by eigenvalue continuation over K (:func:`track`) whose step is bounded by the
change of the distances between roots: two roots that approach force the step down, so a
meeting cannot be stepped over however narrow its bubble, while two that move together
(nearly identical parts) do not, and a double root of identical parts is followed as one.
Each meeting is then solved exactly:
for real lambda the gains putting a root at lambda are K = -1/mu for the real eigenvalues
mu of the m x m transfer matrix C (lambda I - A0)^-1 B, and a meeting is a stationary
point of such a branch K(lambda); its zero of dK/dlambda (analytic) is bracketed and
solved by Brent's method to round-off, then verified by the roots just before and after,
in a window of K small enough to leave out any other meeting near it (:func:`_verify`).
"""

from __future__ import annotations

import dataclasses
import enum
import math

from gyro_rotor.linear.roundoff import floor, resolution
import numpy as np
from scipy.linalg import lapack
from scipy.optimize import brentq, linear_sum_assignment

__all__ = ['DriveSystem', 'Claim', 'Meeting', 'MeetingKind', 'ClaimsResult', 'Locus',
           'fixed_subspace', 'split', 'locked_spectrum', 'track', 'check', 'Damping',
           'damped', 'cyclic_drives']

_EPS = np.finfo(float).eps
#: rank decisions of the structural-zero count: singular values below this times the norm
RANK_RTOL = 1e-10
#: digits of the fixed subspace's staircase (:func:`fixed_subspace`)
FINE_DPS = 40
#: a singular value of that staircase at most this times ||A0|| is an exact zero: the
#: geometric mean of the unit round-offs in FINE_DPS digits (1e-40) and in double (1e-16)
ZERO_RTOL = 1e-28
#: a pair of roots closer than this (relative to their size) is solved as a double root
MEET_RTOL = 1e-6
#: the meeting is verified by the roots at K* (1 -/+ w), its window w at most this
#: (:func:`_verify`)
VERIFY_RTOL = 1e-7
#: the real roots within this of |lambda*| (relative) are the meeting's cluster: a pair
#: splits like sqrt(K - K*), 3e-4 of the scale at VERIFY_RTOL; twins bracket and duplicates
#: are told apart within it
CLUSTER_RTOL = 1e-2


class MeetingKind(enum.StrEnum):
    """How a pair meets the real axis as K grows."""

    BREAK_IN = 'break-in'       # a complex pair lands on the axis and splits into two reals
    BREAKAWAY = 'breakaway'     # two real roots merge and leave the axis as a complex pair


@dataclasses.dataclass(frozen=True)
class DriveSystem:
    """x' = (A0 - B diag(K) C) x: the conservative system and its m drives (module doc).

    ``K_scene`` holds each drive's own K_D; the locus varies the drives in ``vary`` with a
    common K (the others stay at their K_D).
    """

    A0: np.ndarray
    B: np.ndarray
    C: np.ndarray
    K_scene: np.ndarray
    vary: tuple = ()

    def __post_init__(self):
        """Check the shapes; ``vary`` defaults to every drive."""
        N, m = self.B.shape
        if self.A0.shape != (N, N) or self.C.shape != (m, N) or len(self.K_scene) != m:
            raise ValueError('DriveSystem: A0 (N x N), B (N x m), C (m x N), K_scene (m)')
        if not self.vary:
            object.__setattr__(self, 'vary', tuple(range(m)))

    @property
    def drives(self) -> int:
        """Return the number of drives varied on the locus."""
        return len(self.vary)

    def A(self, K) -> np.ndarray:
        """Return A with the varied drives at the common K, the others at their own K_D."""
        k = np.array(self.K_scene, dtype=float)
        k[list(self.vary)] = K
        return self.A0 - (self.B * k) @ self.C

    def locus_pieces(self) -> tuple:
        """Return (A0', B_v, C_v): A(K) = A0' - K B_v C_v on the locus."""
        v = list(self.vary)
        return self.A(0.0), self.B[:, v], self.C[v, :]


@dataclasses.dataclass(frozen=True)
class Meeting:
    """A pair of roots meeting on the real axis at K = K_D, at lambda = lam (a double root).

    ``multiplicity``: how many pairs meet there at once (2 for two identical uncoupled
    parts, whose pairs land together), from the real roots near lam just before and after;
    ``window``: the w of K_D (1 -/+ w), before and after, that it was verified at
    (:func:`_verify`): no other meeting near lam lies inside.
    """

    K_D: float
    lam: float
    kind: MeetingKind
    verified: bool
    multiplicity: int = 1
    window: float = VERIFY_RTOL

    def as_dict(self) -> dict:
        """Return the meeting as plain data."""
        return {'K_D_star': self.K_D, 'lambda_star': self.lam, 'kind': str(self.kind),
                'verified': self.verified, 'multiplicity': self.multiplicity}


@dataclasses.dataclass(frozen=True)
class Claim:
    """One of the paper's claims: whether it holds, why, its numbers, expected exceptions."""

    key: str
    statement: str
    holds: bool
    detail: str
    data: dict
    exception: str = ''
    applicable: bool = True


@dataclasses.dataclass(frozen=True)
class Locus:
    """The moving roots followed over K: ``roots[i]`` at ``K[i]`` (continuation order)."""

    K: np.ndarray
    roots: np.ndarray
    meetings: tuple
    real_counts: tuple


@dataclasses.dataclass(frozen=True)
class ClaimsResult:
    """Claims (a) to (d) and every meeting, sorted by K."""

    claims: dict
    meetings: tuple
    locus: Locus
    structural_zero_roots: int
    unreached: np.ndarray

    @property
    def all_hold(self) -> bool:
        """Return True if (a) to (d) all hold."""
        return all(c.holds for c in self.claims.values())

    @property
    def K_D_star(self) -> list:
        """Return every K where a pair meets on the real axis, increasing."""
        return [mt.K_D for mt in self.meetings]


# -- double-precision kernels of the continuation (thousands of small calls) -----------------
_GEEV = lapack.get_lapack_funcs(('geev', 'geev_lwork'), (np.zeros((1, 1)),))
_LWORK: dict = {}
_I = np.array(1j, dtype='F')


def _complex_pairs(v: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Complex eigenvectors from LAPACK's real pairs: column i +- i column i+1 (i in idx)."""
    out = v.astype(complex)
    nxt = idx + 1
    out.imag[:, idx] = v[:, nxt]
    out[:, nxt] = out[:, idx].conj()
    return out


def _eig_lr(A: np.ndarray) -> tuple:
    """Return ``scipy.linalg.eig(A, left=True, right=True)`` of a real A, bit for bit.

    The same LAPACK call (dgeev, the same workspace) and the same arithmetic on its output
    (scipy's ``_make_complex_eigvecs``), without scipy's per-call checks and its Python
    loop over the conjugate pairs: the continuation (:func:`track`) calls it for every
    trial step.
    """
    A = np.asarray(A, dtype=float)
    if not np.isfinite(A).all():
        raise ValueError('array must not contain infs or NaNs')
    n = A.shape[0]
    geev, geev_lwork = _GEEV
    lwork = _LWORK.get(n)
    if lwork is None:
        lwork = _LWORK[n] = lapack._compute_lwork(geev_lwork, n, compute_vl=1, compute_vr=1)
    wr, wi, vl, vr, info = geev(A, lwork=lwork, compute_vl=1, compute_vr=1)
    if info != 0:
        raise np.linalg.LinAlgError(f'eig algorithm (geev) failed: info = {info}')
    w = wr + _I * wi
    if wi.any():                        # Im w is wi: complex vectors, as scipy makes them
        m = wi > 0
        m[:-1] |= wi[1:] < 0
        # dgeev returns each pair as Im > 0 then its conjugate: the marked columns are
        # never adjacent, and scipy's loop over them is this one array operation
        idx = m.nonzero()[0]
        vl, vr = _complex_pairs(vl, idx), _complex_pairs(vr, idx)
    return w, vl, vr


def _norm2(A: np.ndarray) -> float:
    """Return ``np.linalg.norm(A, 2)`` (the largest singular value) without its wrapper."""
    return np.linalg.svd(A, compute_uv=False).max()


# -- the subspace that does not move with K -------------------------------------------------
def _null(M: np.ndarray, scale: float) -> np.ndarray:
    """Orthonormal basis of the null space of M (singular values <= RANK_RTOL * scale)."""
    if M.shape[0] == 0:
        return np.eye(M.shape[1])
    _, s, vt = np.linalg.svd(M)
    rank = int(np.sum(s > RANK_RTOL * scale))
    return vt[rank:].T


def _null_fine(M, scale: float):
    """Basis (mpmath, orthonormal columns) of the null space of the mpmath matrix M.

    Singular values at most ZERO_RTOL * ``scale`` are zeros (:func:`fixed_subspace`).
    """
    import mpmath
    if M.rows == 0 or M.cols == 0:
        return mpmath.eye(M.cols)
    # a tall M: the thin SVD, whose S and V are those of the full one bit for bit (mpmath
    # pads M with zero columns for the full one; their Householder steps and rotations are
    # exact no-ops), without its M.rows x M.rows U and V
    _, s, vt = mpmath.svd_r(M, full_matrices=M.rows <= M.cols)
    rank = sum(1 for x in s if x > ZERO_RTOL * scale)
    return vt[rank:, :].T if rank < M.cols else mpmath.matrix(M.cols, 0)


def fixed_subspace(A0: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the unobservable subspace of (C, A0) (may have 0 columns).

    The largest A0-invariant subspace in ker C: W_0 = ker C, W_k+1 = {x in W_k: A0 x in W_k},
    each step a null space (orthogonal staircase), every step in FINE_DPS digits of the
    given double-precision A0 and C. A mode is unreached when it is exactly unreached by
    the data (Hagedorn: the drive damping vanishes identically on it), not when it is
    reached weakly: a stiff drive (large K_S) reaches the slow modes with a zdot part of
    order 1/K_S, small against ||A0|| ~ K_S but never zero. In FINE_DPS digits an exact
    zero comes out at the working precision, about 1e-40 ||A0||; ZERO_RTOL (module
    constant) lies 12 decades above that and 12 below the double-precision round-off
    (1e-16) that every later computation on the data carries anyway: a reach that the
    double data cannot resolve at all is not mistaken for none, and none for a reach.
    """
    import mpmath
    N = len(A0)
    if N == 0 or not C.size:
        return np.zeros((N, 0)) if C.size else np.eye(N)
    scale = max(np.linalg.norm(A0, 2), np.linalg.norm(C, 2), 1e-300)
    with mpmath.workdps(FINE_DPS):
        A, Cm = mpmath.matrix(A0.tolist()), mpmath.matrix(C.tolist())
        W = _null_fine(Cm, np.linalg.norm(C, 2))
        while W.cols:
            R = A * W
            R -= W * (W.T * R)
            Y = _null_fine(R, scale)
            if Y.cols == W.cols:
                break
            if Y.cols == 0:
                W = Y
                break
            W, _ = mpmath.qr(W * Y)
            W = W[:, :Y.cols]
        out = np.array(W.tolist(), dtype=float).reshape(N, W.cols)
    if out.shape[1]:
        out, _ = np.linalg.qr(out)
    return out


def split(A0: np.ndarray, C: np.ndarray) -> tuple:
    """Return (U, V): orthonormal bases of the fixed subspace and its orthogonal complement.

    U spans :func:`fixed_subspace` (the roots the drives do not reach), V the rest: the
    roots of V' A(K) V are the reached ones for every K (U is invariant under A(K)).
    """
    U = fixed_subspace(A0, C)
    Q, _ = np.linalg.qr(np.hstack([U, np.eye(len(A0))]))
    V = Q[:, U.shape[1]:len(A0)]
    # Q's first columns span U; make them exactly U's span (QR keeps it)
    return Q[:, :U.shape[1]], V


def _structural_zeros(A_U: np.ndarray, scale: float) -> int:
    """Dimension of the generalized kernel of A0 on U (cyclic coordinates' zero roots).

    Identified by the eigenvectors' space, not by the size of eigenvalues: the kernel of
    A_U, then of A_U on the quotient, until it stops growing; ``scale`` is the norm of
    the whole A0 (the rank decisions are relative to it).
    """
    n = len(A_U)
    if n == 0:
        return 0
    count, M = 0, A_U.copy()
    for _ in range(n):
        Z = _null(M, scale)
        if Z.shape[1] == 0:
            break
        count += Z.shape[1]
        if count >= n:
            break
        # restrict to the complement of the kernel found (quotient map)
        Q, _ = np.linalg.qr(np.hstack([Z, np.eye(len(M))]))
        Qc = Q[:, Z.shape[1]:len(M)]
        M = Qc.T @ M @ Qc
    return count


# -- the continuation ---------------------------------------------------------------------------
class _Roots:
    """The roots of A(K) = A0 - K B C, each from the better conditioned of A(K) and A(K)^-1.

    For a large K, ||A(K)|| grows like K and so does the absolute round-off of every root
    computed from A(K): the slow roots (like 1/K) lose their relative accuracy like K^2.
    A(K)^-1 = A0^-1 + A0^-1 B (I/K - C A0^-1 B)^-1 C A0^-1 (Woodbury) has the same
    eigenvectors and the reciprocal roots, the slow ones now its largest, computed to
    relative round-off. Above K_inv, each root is taken from the form whose error bound
    relative to it is smaller (eps ||A|| / |lambda| against eps ||A^-1|| |lambda|); at or
    below K_inv, or where A0 is not invertible, every root from A(K). Which forms there are
    at K is :meth:`forms`, which one each root is from :func:`_from_inverse`: the roots
    (:meth:`__call__`) and their round-off (:func:`_floor`) both ask them, and the forms of
    the last K asked are kept, so that the two at one K build them once.
    """

    def __init__(self, A0: np.ndarray, B: np.ndarray, C: np.ndarray):
        """Keep the pieces; the inverse form only where A0 is invertible."""
        self.A0, self.B, self.C, self.BC = A0, B, C, B @ C
        self.inv = None
        self._last = (None, None)       # (K, its forms): :meth:`forms`
        # below K_inv (the fast root still within the spectrum's scale) no root is slow
        scale = float(np.max(np.abs(np.linalg.eigvals(A0)), initial=0.0))
        gain = float(np.max(np.abs(np.linalg.eigvals(C @ B)), initial=0.0))
        self.K_inv = scale / gain if gain > 0 else math.inf
        if len(A0) and np.linalg.cond(A0) < 1e12:
            self.inv = (np.linalg.inv(A0), np.linalg.solve(A0, B), C @ np.linalg.inv(A0))

    def A(self, K: float) -> np.ndarray:
        """Return A0 - K B C."""
        return self.A0 - K * self.BC

    def _inverse(self, K: float) -> np.ndarray:
        """Return A(K)^-1 (class doc)."""
        A0i, A0iB, CA0i = self.inv
        m = self.B.shape[1]
        return A0i + A0iB @ np.linalg.solve(np.eye(m) / K - self.C @ A0iB, CA0i)

    def forms(self, K: float) -> tuple:
        """Return (A(K), A(K)^-1): the forms the roots at K are taken from.

        A(K)^-1 is None at or below K_inv and where A0 is not invertible: there every
        root is from A(K) (class doc). Built once for the last K asked (the roots at K,
        then their round-off, :func:`_floor`), read-only.
        """
        if self._last[0] != K:
            A = self.A(K)
            Ai = None if self.inv is None or K <= self.K_inv else self._inverse(K)
            A.flags.writeable = False       # the same arrays go to every caller at K
            if Ai is not None:
                Ai.flags.writeable = False
            self._last = (K, (A, Ai))
        return self._last[1]

    def __call__(self, K: float, vectors: bool = True) -> tuple:
        """Return (roots, left, right eigenvectors) at K (vectors None if not asked)."""
        A, Ai = self.forms(K)
        if vectors:
            lam, yl, xr = _eig_lr(A)
        else:
            lam, yl, xr = np.linalg.eigvals(A), None, None
        if Ai is None:
            return lam, yl, xr
        if vectors:
            mu, yl_i, xr_i = _eig_lr(Ai)
        else:
            mu, yl_i, xr_i = np.linalg.eigvals(Ai), None, None
        with np.errstate(divide='ignore'):
            lam_i = 1.0 / mu
        r, c = linear_sum_assignment(np.abs(lam[:, None] - lam_i[None, :]))
        take = _from_inverse(A, Ai, np.abs(lam[r]) ** 2)
        lam = lam.astype(complex)
        lam[r[take]] = lam_i[c[take]]
        if vectors:
            yl, xr = yl.astype(complex), xr.astype(complex)
            yl[:, r[take]] = yl_i[:, c[take]]
            xr[:, r[take]] = xr_i[:, c[take]]
        return lam, yl, xr


def _from_inverse(A: np.ndarray, Ai: np.ndarray | None, x: np.ndarray) -> np.ndarray:
    """Return ||A^-1||_2 x < ||A||_2 (x = |lambda|^2: the root is taken from A^-1).

    All False where there is no A^-1 (``Ai`` None, :meth:`_Roots.forms`). Decided by the
    Frobenius norms where they suffice (||M||_2 <= ||M||_F <= sqrt(N) ||M||_2, a margin of
    1e-9 for their round-off), the 2-norms (an SVD each) computed only for a root in
    between: the same answer as the 2-norms give, at every step of the continuation.
    """
    if Ai is None:
        return np.zeros(np.shape(x), bool)
    fA, fAi = np.linalg.norm(A), np.linalg.norm(Ai)
    k = math.sqrt(len(A)) * (1 + 1e-9)
    lhs = fAi * x
    yes, no = lhs * k < fA, lhs >= fA * k
    if np.all(yes | no):
        return yes
    return _norm2(Ai) * x < _norm2(A)


def _velocity(lam, yl, xr, BC) -> np.ndarray:
    """Return d lambda / d K = -(y^H B C x) / (y^H x) for every simple root."""
    num = np.sum(yl.conj() * (BC @ xr), axis=0)
    den = np.sum(yl.conj() * xr, axis=0)
    with np.errstate(divide='ignore', invalid='ignore'):
        v = -num / den
    return np.where(np.isfinite(v), v, 0.0)


def _distances(lam: np.ndarray) -> np.ndarray:
    """Return |lambda_i - lambda_j|, infinite on the diagonal (a root is not its own neighbour)."""
    D = np.abs(lam[:, None] - lam[None, :])
    np.fill_diagonal(D, np.inf)
    return D


def _gaps(lam: np.ndarray, twins: np.ndarray | None = None) -> np.ndarray:
    """Return each root's distance to the nearest other root that is not its twin."""
    D = _distances(lam)
    if twins is not None:
        D[twins] = np.inf
    return D.min(axis=1) if len(lam) > 1 else np.full(len(lam), np.inf)


def _twins(R: '_Roots', K: float, lam: np.ndarray, yl: np.ndarray, xr: np.ndarray) -> tuple:
    """Return (twins, tol): the pairs of roots that are one double root within round-off.

    ``twins`` (None: none): the pairs within the sum of their round-off (:func:`_floor`);
    ``tol``: that round-off times each root's condition number (a cluster's roots are
    ill-conditioned one by one), the jitter a step allows (:func:`_step`). Identical
    uncoupled parts (two equal rotors on equal carriers) keep every
    root double for every K: the two are one root to the continuation (no step can
    separate them), and their pairs meet the axis together (:attr:`Meeting.multiplicity`).
    Only where two roots are within MEET_RTOL of each other is any of it computed (tol 0).
    """
    D = _distances(lam)
    if not np.any(D <= MEET_RTOL * np.maximum(np.abs(lam)[:, None], 1e-300)):
        return None, np.zeros(len(lam))
    with np.errstate(divide='ignore'):
        kappa = (np.linalg.norm(yl, axis=0) * np.linalg.norm(xr, axis=0)
                 / np.abs(np.sum(yl.conj() * xr, axis=0)))
    fl = _floor(R, K, lam)
    twins = D <= fl[:, None] + fl[None, :]
    return (twins if twins.any() else None), fl * np.minimum(kappa, 1e8)


def _is_real(lam: np.ndarray) -> np.ndarray:
    """Real as LAPACK returns it: a 1 x 1 block of the real Schur form has Im exactly 0."""
    return lam.imag == 0.0


def _branch_K(A0, B, C, lam: float, K_near: float) -> tuple:
    """Return (K, dK/dlambda) of the branch K(lambda) = -1/mu(lambda) nearest to K_near.

    mu: the real negative eigenvalues of G(lambda) = C (lambda I - A0)^-1 B; dmu/dlambda =
    w^T G' u / (w^T u), G' = -C (lambda I - A0)^-2 B. (nan, nan) where no branch.
    """
    N = len(A0)
    L = lam * np.eye(N) - A0
    X = np.linalg.solve(L, B)
    G = C @ X
    Gp = -C @ np.linalg.solve(L, X)
    mu, wl, ur = _eig_lr(G)
    best = None
    for i, z in enumerate(mu):
        if abs(z.imag) > 1e-9 * abs(z) or z.real >= 0:
            continue
        K = -1.0 / z.real
        if best is None or abs(math.log(K / K_near)) < abs(math.log(best[0] / K_near)):
            w, u = wl[:, i], ur[:, i]
            dmu = (w.conj() @ Gp @ u) / (w.conj() @ u)
            best = (K, float(dmu.real) / z.real ** 2)
    return best if best is not None else (math.nan, math.nan)


def _solve_meeting(A0, B, C, lo: float, hi: float, K_near: float) -> tuple | None:
    """Return the stationary point of the branch K(lambda) in [lo, hi] (dK/dlambda = 0)."""
    def dK(x):
        return _branch_K(A0, B, C, x, K_near)[1]
    f_lo, f_hi = dK(lo), dK(hi)
    if not (np.isfinite(f_lo) and np.isfinite(f_hi)) or f_lo * f_hi > 0:
        return None
    if f_lo == 0.0:
        x = lo
    elif f_hi == 0.0:
        x = hi
    else:
        x = brentq(dK, lo, hi, xtol=4 * _EPS * max(abs(lo), abs(hi)), rtol=4 * _EPS,
                   maxiter=200)
    return _branch_K(A0, B, C, x, K_near)[0], x


def _copies(lam: np.ndarray, x: float) -> int | None:
    """Return how many copies of the root nearest x there are, if that root is complex.

    A pair of a meeting is split by 2 |Im| on its complex side; a root within a hundredth
    of that of the nearest root is that root again: identical uncoupled parts give every
    root once per part, and their pairs meet together (:attr:`Meeting.multiplicity`).
    None where the nearest root is real.
    """
    r0 = lam[np.argmin(np.abs(lam - x))]
    if abs(r0.imag) <= 1e-9 * max(abs(x), 1e-300):
        return None
    return int(np.sum(np.abs(lam - r0) <= 1e-2 * abs(r0.imag)))


def _verify(R: _Roots, K: float, x: float) -> tuple:
    """Return (kind, verified, multiplicity q, window w) of the meeting at (K, x).

    q: the copies of the root nearest x where it is complex (:func:`_copies`; 1 in a system
    of distinct parts). From the 2 q roots nearest x at K (1 - w) and K (1 + w): real after
    and not before is a break-in, before and not after a breakaway (two copies of one real
    root are not its pair: with 2 roots, a break-in beside a breakaway in two identical
    parts read as real on both sides of the wrong window). w starts at VERIFY_RTOL and is
    halved while they are real on both sides or on neither: another meeting near x within
    the window (a real root passing a complex pair where it lands, near a triple root: a
    break-in and a breakaway 3e-8 K apart) undoes this one there, and a smaller window
    leaves it out. Not below the meeting's round-off as a change of K
    (:func:`_least_window`), where the sides prove nothing: not verified.
    """
    def real(lam, q):
        near = lam[np.argsort(np.abs(lam - x))[:2 * q]]
        return bool(np.all(np.abs(near.imag) <= 1e-9 * max(abs(x), 1e-300)))
    least, w = None, VERIFY_RTOL
    while True:
        lam_b, lam_a = (R(K * (1 + s * w), vectors=False)[0] for s in (-1, 1))
        q = max(_copies(lam_b, x) or 1, _copies(lam_a, x) or 1)
        below, above = real(lam_b, q), real(lam_a, q)
        if below != above:
            break
        least = _least_window(R, K, x) if least is None else least   # only when halving
        if w / 2 < least:
            break
        w /= 2
    kind = MeetingKind.BREAKAWAY if below and not above else MeetingKind.BREAK_IN
    return kind, below != above, q, w


def _least_window(R: _Roots, K: float, x: float) -> float:
    """Return the least window w of :func:`_verify` at (K, x): the round-off as a change of K.

    A(K) moves by ||B C|| per unit of K: the round-off of the roots near x (:func:`_floor`)
    is a change of K by it / ||B C||, and a window within that cannot tell the sides apart.
    At least eps: K (1 -/+ w) is K itself below it.
    """
    return max(float(_floor(R, K, np.array([x]))[0]) / (K * _norm2(R.BC)), _EPS)


def _meeting_near(R: _Roots, K: float, lam: np.ndarray, i: int, j: int) -> Meeting | None:
    """Solve the meeting of roots i and j, found close together at K (module doc)."""
    a, b = lam[i], lam[j]
    if a.imag == 0.0 and b.imag == 0.0:
        lo, hi = sorted((a.real, b.real))
        if hi - lo <= 1e-2 * MEET_RTOL * abs(a):
            # twins (identical parts: two pairs meet together, and these two are copies of
            # one root, their distance the round-off of a nearly double root; a pair that
            # approaches is found as it comes within MEET_RTOL, closing by at most a quarter
            # a step): the bracket is the real roots of their cluster
            near = lam[_is_real(lam) & (np.abs(lam - a) <= CLUSTER_RTOL * abs(a))].real
            lo, hi = float(near.min()), float(near.max())
        width = hi - lo
    elif abs(a - b.conjugate()) <= 1e-12 * abs(a):
        width = 2 * abs(a.imag)
        lo, hi = a.real - 4 * width, a.real + 4 * width
    else:
        return None
    pad = max(width, 1e-12 * abs(a.real))
    for grow in (0.0, 1.0, 10.0, 100.0):
        res = _solve_meeting(R.A0, R.B, R.C, lo - grow * pad, hi + grow * pad, K)
        if res is not None:
            break
    if res is None or not math.isfinite(res[0]) or res[1] >= 0:
        return None
    K_star, x = res
    kind, ok, n_pairs, w = _verify(R, K_star, x)
    return Meeting(K_D=float(K_star), lam=float(x), kind=kind, verified=ok,
                   multiplicity=n_pairs, window=w)


def _floor(R: _Roots, K: float, lam: np.ndarray) -> np.ndarray:
    """Round-off of each root at K: 1e4 eps times the bound of the form it is taken from.

    eps ||A(K)|| for a root from A(K), eps ||A(K)^-1|| |lambda|^2 for one from A(K)^-1,
    the form decided as :meth:`_Roots.__call__` decides it (:func:`_from_inverse`): at or
    below K_inv every root is from A(K), and so is its bound (a root at 0 too). Decided
    by the root given, not by A(K)'s root as there: they differ by round-off, and where
    the choice flips the two bounds are equal. The smaller of the two bounds at every K
    underestimated a slow root below K_inv: measured against 50 digits in six random
    systems at 1e-3 to 1 K_inv, the slowest root's error was 0.015 to 0.15 eps ||A(K)||
    but up to 3.6e3 eps ||A(K)^-1|| |lambda|^2; in 400 random systems (200, and each
    doubled) at 1e-3 to 1 K_inv this floor is up to 6.4e4 (median 225) times the smaller
    one. Above K_inv it is the smaller one, as before.
    """
    A, Ai = R.forms(K)
    x = np.abs(lam) ** 2
    take = _from_inverse(A, Ai, x)
    bound = np.full(np.shape(x), _norm2(A))
    if np.any(take):
        bound[take] = _norm2(Ai) * x[take]
    return 1e4 * _EPS * bound


def _settled(a1, a2, f1, f2, ratio: float, rtol: float) -> bool:
    """Return True if the gaps between sorted |roots| a1 (at K) and a2 (at 10 K) scale so.

    A gap within the round-off f1, f2 of its roots at both K values is a persistent double
    root (identical uncoupled parts: a pair that is landing is double at one K only): it
    carries no scaling to test and is skipped.
    """
    g1, g2 = np.diff(a1), np.diff(a2)
    double = (g1 <= f1[1:] + f1[:-1]) & (g2 <= f2[1:] + f2[:-1])
    with np.errstate(divide='ignore', invalid='ignore'):
        r = g2[~double] / g1[~double]
    return bool(np.all(np.abs(r - ratio) < rtol))


def _asymptotic(R: _Roots, K: float, m: int) -> bool:
    """Return True if at K the m fast and m slow roots are in claim (c)'s regime.

    Each real, and scaling like K (fast) or 1/K (slow) from K to 10 K (and so do the gaps
    between them, :func:`_settled`); fast roots beyond ten times, slow roots below a tenth
    of, every other root. Past such a K no pair meets again.
    """
    parts = []
    for k in (K, 10 * K):
        lam = R(k, vectors=False)[0]
        order = np.argsort(lam.real)
        fast, rest = lam[order[:m]], lam[order[m:]]
        slow = rest[np.argsort(np.abs(rest))[:m]]
        others = rest[np.argsort(np.abs(rest))[m:]]
        if not (np.all(_is_real(fast)) and np.all(_is_real(slow))
                and np.min(np.abs(fast)) > 10 * np.max(np.abs(rest), initial=0.0)
                and np.max(np.abs(slow), initial=0.0) * 10 < np.min(np.abs(others),
                                                                    initial=np.inf)):
            return False
        f, s_ = np.sort(np.abs(fast)), np.sort(np.abs(slow))
        parts.append((f, s_, _floor(R, k, -f), _floor(R, k, -s_)))
    (f1, s1, ff1, fs1), (f2, s2, ff2, fs2) = parts
    with np.errstate(divide='ignore', invalid='ignore'):    # a root at 0 (K_S = 0): nan
        scaled = np.all(np.abs(f2 / f1 - 10) < 0.1) and np.all(np.abs(s2 / s1 - 0.1) < 1e-3)
    return bool(scaled and _settled(f1, f2, ff1, ff2, 10.0, 1.0)
                and _settled(s1, s2, fs1, fs2, 0.1, 0.01))


def _ends(R: _Roots, K_ref, regime: bool = True) -> tuple:
    """K range of the continuation: every meeting lies inside it (module doc of :func:`track`).

    ``regime`` False: the end is not searched for (:func:`track`): 1e6 K_ref.
    """
    lo = 1e-6 * K_ref
    for _ in range(20):
        if not len(R.A0) or not np.any(_is_real(R(lo, vectors=False)[0])):
            break
        lo *= 1e-2
    if not regime:
        return lo, 1e6 * K_ref
    hi = 1e4 * K_ref
    for _ in range(30):
        if _asymptotic(R, hi, R.B.shape[1]):
            break
        hi *= 10.0
    return lo, hi


def _step(R: _Roots, K, lam, vel, h, twins=None, tol=None):
    """One accepted continuation step from K (module doc of :func:`track`).

    Accepted when, for any two roots (not twins, :func:`_twins`), their distance changed
    by at most a quarter of itself and their errors against the first-order prediction
    differ by at most a twentieth of it: a pair that approaches or turns forces the step
    down, two that move together (the nearly equal roots of nearly identical parts) do
    not. Changes within the two roots' round-off (``tol``, :func:`_twins`) are allowed. The
    roots are matched to the prediction by least squares, which keeps each pair's order
    whenever their errors differ by less than their distance. Returns (K_new, h, roots,
    left and right eigenvectors) with the roots in the order of ``lam``.
    """
    u = math.log(K)
    d0 = lam[:, None] - lam[None, :]
    apart = np.ones(d0.shape, bool) if twins is None else ~twins
    np.fill_diagonal(apart, False)
    limit = np.abs(d0[apart])
    noise = 0.0 if tol is None else (tol[:, None] + tol[None, :])[apart]
    while True:
        K_new = math.exp(u + h)
        lam_n, yl_n, xr_n = R(K_new)
        pred = lam + (K_new - K) * vel
        r, c = linear_sum_assignment(np.abs(pred[:, None] - lam_n[None, :]) ** 2)
        new = np.empty_like(lam_n)
        new[r] = lam_n[c]
        err = new - pred
        moved = np.abs((new[:, None] - new[None, :]) - d0)[apart]
        differ = np.abs(err[:, None] - err[None, :])[apart]
        if (np.all(moved <= 0.25 * limit + noise) and np.all(differ <= 0.05 * limit + noise)
                or h < 1e-14):
            break
        h *= 0.5
    order = np.empty(len(lam), int)
    order[r] = c
    return K_new, h, lam_n[order], yl_n[:, order], xr_n[:, order]


def _close_pairs(lam: np.ndarray, gaps: np.ndarray, twins=None) -> list:
    """Pairs (i, j) of roots closer than MEET_RTOL of their size (never twins)."""
    close = np.flatnonzero(gaps <= MEET_RTOL * np.maximum(np.abs(lam), 1e-300))
    pairs = []
    for i in close:
        d = np.abs(lam - lam[i])
        d[i] = np.inf
        if twins is not None:
            d[twins[i]] = np.inf
        j = int(np.argmin(d))
        if (min(i, j), max(i, j)) not in pairs:
            pairs.append((min(int(i), j), max(int(i), j)))
    return pairs


def _crossed_pairs(lam_a: np.ndarray, lam_b: np.ndarray) -> list:
    """Roots that changed between real and complex in one step: (side, i, j) per pair.

    ``side`` is 0 if the pair is real at the start of the step (a breakaway inside it),
    1 if real at its end (a break-in); i, j index that side's two real roots.
    """
    out = []
    for side, (real, cplx) in enumerate(((lam_a, lam_b), (lam_b, lam_a))):
        idx = np.flatnonzero(_is_real(real) & ~_is_real(cplx))
        # pair them by the conjugate pairs they are on the complex side
        used = set()
        for i in idx:
            if i in used:
                continue
            d = np.abs(cplx[idx] - cplx[i].conjugate())
            d[list(idx).index(i)] = np.inf
            j = int(idx[int(np.argmin(d))]) if len(idx) > 1 else None
            if j is None or j in used:
                continue
            used |= {int(i), j}
            out.append((side, int(i), j))
    return out


def _add(meetings: list, mt: Meeting | None) -> bool:
    """Append a meeting not found before; True if appended.

    Found before: lambda within CLUSTER_RTOL of the other's, K within either meeting's
    window (:attr:`Meeting.window`).
    """
    if mt is None or any(abs(mt.K_D - o.K_D) <= max(mt.window, o.window) * o.K_D
                         and abs(mt.lam - o.lam) <= CLUSTER_RTOL * abs(o.lam)
                         for o in meetings):
        return False
    meetings.append(mt)
    return True


def track(A0: np.ndarray, B: np.ndarray, C: np.ndarray, K_lo: float | None = None,
          K_hi: float | None = None, max_steps: int = 200000, regime: bool = True) -> Locus:
    """Follow the roots of A0 - K B C over K in [K_lo, K_hi] and find every meeting.

    A0, B, C must have no fixed root (use the complement of :func:`fixed_subspace`). The
    step in log K is accepted when no distance between two roots changed by more than a
    quarter of itself and their errors against the first-order prediction differ by at
    most a twentieth of it; otherwise it is halved (:func:`_step`). A double root within
    round-off (identical uncoupled parts: :func:`_twins`) is one root to the step, and its
    pairs meet the axis together (:attr:`Meeting.multiplicity`). Two roots closer than
    MEET_RTOL of their
    size are a meeting, solved exactly (module doc), and the continuation resumes just past
    it; a pair that changes between real and complex within a step is solved from the side
    where it is real. The default ends: from where no root is real yet to where the m fast
    and m slow roots are real and far from the rest (the asymptotic regime of claim (c)).
    ``regime`` False (a varied drive without stiffness, K_S = 0: there is no such regime,
    claim (c) is not applicable): the end is not searched for, the default is 1e6 K_ref,
    K_ref = (spectral radius of A0) / max |eig(C B)|, two decades past where the search
    starts (and past the end of the ``locus`` command's default grid). Searched for
    without a regime, the end went to 1e34 K_ref; with A0 singular the root that stays at
    0 is computed from A(K) alone, its round-off eps ||A(K)|| grows like K, and the step
    stalled below 1e-14 for all ``max_steps`` (at K = 3e13 for twin_gimbal with drive
    R2's K_S = 0: 200 s). ``K_hi`` given: no search either.
    """
    R = _Roots(A0, B, C)
    scale = max(float(np.max(np.abs(np.linalg.eigvals(A0)), initial=0.0)), 1e-300)
    gain = float(np.max(np.abs(np.linalg.eigvals(C @ B)))) if len(B.T) else 1.0
    lo_d, hi_d = _ends(R, scale / max(gain, 1e-300), regime and K_hi is None)
    K = lo_d if K_lo is None else K_lo
    K_end = hi_d if K_hi is None else K_hi
    h = h_max = math.log(10.0) / 8
    lam, yl, xr = R(K)
    Ks, roots, counts = [K], [lam], [int(np.sum(_is_real(lam)))]
    meetings: list[Meeting] = []
    for _ in range(max_steps):
        if K >= K_end * (1 - 1e-12):
            break
        vel = _velocity(lam, yl, xr, R.BC)
        twins, tol = _twins(R, K, lam, yl, xr)
        gaps = _gaps(lam, twins)
        ahead = [mt for i, j in _close_pairs(lam, gaps, twins)
                 if _add(meetings, mt := _meeting_near(R, K, lam, i, j))
                 and mt.K_D >= K]
        if ahead:
            # resume just past the meeting(s) ahead, where each was verified: within its
            # window no other meeting near it lies (:func:`_verify`)
            K = max(mt.K_D * (1 + mt.window) for mt in ahead)
            lam, yl, xr = R(K)
            h = min(h, 1e-6)
        else:
            h = min(h, math.log(K_end) - math.log(K))
            K_new, h, lam_n, yl, xr = _step(R, K, lam, vel, h, twins, tol)
            for side, i, j in _crossed_pairs(lam, lam_n):
                _add(meetings, _meeting_near(R, (K, K_new)[side], (lam, lam_n)[side], i, j))
            K, lam = K_new, lam_n
            h = min(1.5 * h, h_max)
        Ks.append(K)
        roots.append(lam)
        counts.append(int(np.sum(_is_real(lam))))
    meetings.sort(key=lambda mt: mt.K_D)
    return Locus(K=np.array(Ks), roots=np.array(roots), meetings=tuple(meetings),
                 real_counts=tuple(counts))


# -- the locked system ----------------------------------------------------------------------
def locked_spectrum(A0: np.ndarray, B: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Eigenvalues of the locked system: A0 restricted to ker C, projected along B.

    With C x = 0 held by an unbounded drive torque B u, x' = P A0 x with the projector
    P = I - B (C B)^-1 C (C P = 0 keeps x in ker C); in an orthonormal basis N of ker C
    the locked matrix is N^T P A0 N ((N - m) x (N - m)).
    """
    P = np.eye(len(A0)) - B @ np.linalg.solve(C @ B, C)
    Nk = np.linalg.svd(C)[2][C.shape[0]:].T
    return np.linalg.eigvals(Nk.T @ P @ A0 @ Nk)


# -- the claims --------------------------------------------------------------------------------
def _fmt(z: complex) -> str:
    return f'{z.real:+.6g}{z.imag:+.6g}j'


def _claim_a(A0: np.ndarray, U: np.ndarray, V: np.ndarray, n_zero: int,
             others: bool = False) -> Claim:
    """Check (a) on A0, every drive undamped; ``others``: the locus varies only some drives.

    The locus then starts (its K = 0) with the others at their own K_D, off the axis: the
    statement says that (a) is about every drive at K_D = 0.
    """
    lam, res = resolution(V.T @ A0 @ V)
    lam_u, res_u = resolution(U.T @ A0 @ U) if U.shape[1] else (lam[:0], res[:0])
    # the structural zero roots (a Jordan block each pair) are on the axis by construction;
    # the other fixed roots are simple and judged by their resolution like the moving ones
    nz_u = np.argsort(np.abs(lam_u))[n_zero:] if lam_u.size else np.zeros(0, int)
    excess = np.concatenate([np.abs(lam.real) - res, np.abs(lam_u[nz_u].real) - res_u[nz_u]])
    holds = bool(np.all(excess <= 0))
    worst = float(np.max(np.abs(np.concatenate([lam.real, lam_u[nz_u].real])), initial=0.0))
    osc = int(np.sum(lam.imag > 0) + np.sum(lam_u[nz_u].imag > 0))
    freqs = sorted(float(x) for x in np.concatenate([lam.imag, lam_u[nz_u].imag])
                   / (2 * math.pi) if x > 0)
    detail = (f'{osc} undamped oscillations and {n_zero} structural zero root(s) (cyclic '
              f'coordinates, by their eigenvectors); max |Re| = {worst:.3e} 1/s, '
              + ('every one within its resolution' if holds else
                 f'{int(np.sum(excess > 0))} beyond their resolution'))
    where = ('at K_D = 0 of every drive (also those the locus does not vary)' if others
             else 'at K_D = 0')
    return Claim('a', f'{where} every root on the imaginary axis (undamped oscillations '
                 'and zero roots)', holds, detail,
                 {'oscillations': osc, 'zero_roots': n_zero, 'max_abs_re': worst,
                  'freq_hz': freqs})


def _eig_fine(A0: np.ndarray, B: np.ndarray, C: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Eigenvalues of A0 - B diag(K) C in 40-digit arithmetic (mpmath), the product exact.

    For a large K the double-precision A(K) carries round-off eps K ||B C|| into every root;
    formed and solved in 40 digits the roots keep only the resolution of A0 itself.
    """
    import mpmath
    with mpmath.workdps(40):
        A = mpmath.matrix(A0.tolist()) - mpmath.matrix((B * K).tolist()) * mpmath.matrix(
            C.tolist())
        ev = mpmath.eig(A, left=False, right=False)
        return np.array([complex(z) for z in ev])


@dataclasses.dataclass(frozen=True)
class Damping:
    """The roots of A(K) the drives reach and whether each is damped (:func:`damped`).

    ``lam`` the reached roots (A(K) on the complement V of the fixed subspace), those
    below the double-precision resolution replaced by their 40-digit values (``fine``);
    ``res`` each one's resolution (for a fine one ten times its share of A0's round-off);
    ``damped`` the one rule: the root lies in the open left half plane; ``noise`` the
    largest share of A0's round-off among the fine roots (0 if no root needed 40 digits).
    """

    lam: np.ndarray
    res: np.ndarray
    damped: np.ndarray
    fine: np.ndarray
    noise: float


def damped(sys: DriveSystem, K=None, V: np.ndarray | None = None) -> Damping:
    """Decide, once for every command, which reached root of A(K) is damped.

    ``K``: each drive's damping (default: the scene's ``K_scene``); ``V``: a basis of the
    complement of the fixed subspace (:func:`fixed_subspace`; computed if not given). A
    reached root is damped when Re < -resolution of A(K) on V (:func:`resolution`, at least
    the eigen-solver's floor :func:`gyro_rotor.linear.roundoff.floor` of A0). A root
    within that resolution (a mode the drives reach only weakly, or a slow root -K_S/K at a
    large K) is recomputed in 40 digits (:func:`_eig_fine`) and judged against the
    round-off the data A0 carries itself: at K = 0 every root of the conservative A0 lies
    on the axis (claim a), so the real parts of A0's own roots in 40 digits measure that
    round-off. A root's own share of it is the larger of its own |Re| at K = 0 and the
    data's relative round-off (the largest |Re lambda0| / |lambda0|) times its size: the
    round-off of a root at 3873 rad/s (6e-12 1/s on precession at K_S = 1e5) is not that
    of one at 61 rad/s (1e-13 1/s). The root is damped when it lies left of the axis and
    has moved left of its K = 0 value by more than ten times its share (``res``);
    ``noise`` is the largest share.
    """
    K = np.asarray(sys.K_scene if K is None else K, dtype=float)
    if V is None:
        V = split(sys.A0, sys.C)[1]
    A0v, Bv, Cv = V.T @ sys.A0 @ V, V.T @ sys.B, sys.C @ V
    lam, res = resolution(V.T @ (sys.A0 - (sys.B * K) @ sys.C) @ V)
    res = np.maximum(res, floor(sys.A0))
    fine = (np.abs(lam.real) <= res) & bool(np.any(K > 0))
    ok = lam.real < -res
    noise = 0.0
    if fine.any():
        ev, ev0 = _eig_fine(A0v, Bv, Cv, K), _eig_fine(A0v, Bv, Cv, np.zeros_like(K))
        size = np.abs(ev0)
        rel = float(np.max(np.abs(ev0.real[size > 0]) / size[size > 0], initial=0.0))
        r, c = linear_sum_assignment(np.abs(lam[:, None] - ev[None, :]))
        lam = lam.astype(complex)
        lam[r[fine[r]]] = ev[c[fine[r]]]
        r0, c0 = linear_sum_assignment(np.abs(lam[:, None] - ev0[None, :]))
        base, share = np.empty(len(lam)), np.empty(len(lam))
        base[r0] = ev0[c0].real
        share[r0] = np.maximum(np.abs(ev0[c0].real), rel * size[c0])
        noise = float(np.max(share[fine]))
        res = res.copy()
        res[fine] = 10 * share[fine]
        ok[fine] = (lam.real[fine] < 0) & (lam.real[fine] - base[fine] < -res[fine])
    return Damping(lam=lam, res=res, damped=ok, fine=fine, noise=noise)


def _claim_b(sys: DriveSystem, U, V, lam_fixed, n_zero: int) -> Claim:
    K = np.asarray(sys.K_scene, dtype=float).copy()
    A0v, Bv, Cv = V.T @ sys.A0 @ V, V.T @ sys.B, sys.C @ V
    zero = K <= 0
    note = ''
    if zero.any():
        # the theorem is about K_D > 0: a conservative scene is judged at a small K_D
        gain = float(np.max(np.abs(np.linalg.eigvals(Cv @ Bv)), initial=1.0))
        scale = float(np.max(np.abs(np.linalg.eigvals(A0v)), initial=1.0))
        K[zero] = 1e-3 * scale / gain
        note = (f' (the scene has K_D = 0, conservative: judged at K_D = {K[zero][0]:.3g}, '
                'the theorem being about K_D > 0)')
    A = sys.A0 - (sys.B * K) @ sys.C
    dm = damped(sys, K, V)
    lam, res, fine, noise, ok_reached = dm.lam, dm.res, dm.fine, dm.noise, dm.damped
    bad = np.flatnonzero(~ok_reached)
    lam_u, res_u = resolution(U.T @ A @ U) if U.shape[1] else (lam[:0], res[:0])
    # the unreached roots: on the axis, at their K = 0 values (U is invariant, so A = A0 on
    # U; checked, not assumed)
    r, c = linear_sum_assignment(np.abs(lam_u[:, None] - lam_fixed[None, :]))
    stays = bool(np.all(np.abs(lam_u[r] - lam_fixed[c]) <= res_u[r] + 1e3 * _EPS * max(
        1.0, float(np.max(np.abs(lam_fixed), initial=0.0)))))
    nonzero = np.argsort(np.abs(lam_u))[n_zero:]
    stays &= bool(np.all(np.abs(lam_u[nonzero].real) <= res_u[nonzero]))
    holds = bool(ok_reached.all() and stays)
    worst = float(np.max(lam.real, initial=-math.inf))
    K_text = ', '.join(f'{k:.6g}' for k in sys.K_scene) + note
    if holds:
        detail = (f'at K_D = {K_text}: every one of the {len(lam)} reached roots in the open '
                  f'left half plane, largest Re {worst:.6g} 1/s ' + (
                      f'({int(fine.sum())} damped below the double-precision resolution, '
                      'resolved in 40 digits against the round-off of A0 itself: each moved '
                      'left by more than ten times its share, at most '
                      f'{noise:.1e} 1/s)' if fine.any()
                      else '(beyond its resolution)'))
    else:
        detail = (f'fails at K_D = {K_text}: ' + (
            ', '.join(f'{_fmt(lam[i])} (resolution {res[i]:.1e})' for i in bad[:4])
            if bad.size else 'an unreached root moved'))
    exc = ''
    n_un = len(lam_u) - n_zero
    if n_un:
        exc = (f'{n_un} roots not reached by the drive (their eigenvectors have no zdot '
               "part: Hagedorn's exclusion, PBH) stay on the imaginary axis at their K_D = 0 "
               'values, as the theory expects')
    where = ("at the scene's K_D" if not zero.any() else
             f"at K_D = {K[zero][0]:.3g} (the scene's K_D = 0 substituted)")
    return Claim('b', f'{where} every root the drives reach in the open left half '
                 'plane, the unreached ones on the axis at their K_D = 0 values', holds,
                 detail, {'max_re_reached': worst, 'unreached': n_un,
                          'reached': len(lam), 'failing': [_fmt(lam[i]) for i in bad]}, exc)


#: the statements of claims (c) and (d) (also when they are not applicable)
_STATEMENT = {
    'c': 'K_D -> infinity: m roots to -infinity, m to 0, the rest to the spectrum of the locked '
         'system',
    'd': 'every pair meeting on the negative real axis found, with its kind; net, m pairs meet '
         '(one per drive)'}


def _claim_c(A0v, Bv, Cv, K1: float, scale: float, fixed: np.ndarray) -> Claim:
    """Check (c) on the moving part at K1 and 10 K1 (the asymptotic regime).

    ``fixed``: the roots that do not move (they belong to the locked spectrum as well).
    """
    m = Bv.shape[1]
    gains = np.sort(np.linalg.eigvals(Cv @ Bv).real)
    locked = locked_spectrum(A0v, Bv, Cv) if m < len(A0v) else np.zeros(0, complex)
    R = _Roots(A0v, Bv, Cv)
    out, floor = [], []
    for K in (K1, 10 * K1):
        lam = R(K, vectors=False)[0]
        order = np.argsort(lam.real)
        out.append((lam[order[:m]], lam[order[m:]]))
        floor.append(_floor(R, K, lam[order[m:]]))
    fast_ok = all(np.all(_is_real(f)) and np.all(
        np.abs(np.sort(-f.real) / (K * gains) - 1.0) < 0.01)
        for (f, _), K in zip(out, (K1, 10 * K1)))
    # the m slow roots: the m smallest of the rest, real, shrinking like 1/K (ratio 0.1 per
    # decade); the locked system's m zero roots (each locked z is free) are their limit
    (_, r1), (_, r2) = out
    s1, s2 = np.argsort(np.abs(r1))[:m], np.argsort(np.abs(r2))[:m]
    ratio = np.sort(np.abs(r2[s2])) / np.sort(np.abs(r1[s1]))
    slow_ok = (np.all(r1[s1].imag == 0) and np.all(r2[s2].imag == 0)
               and np.all(np.abs(ratio - 0.1) < 0.01))
    to_zero = m if slow_ok else int(np.sum(np.abs(ratio - 0.1) < 0.01))
    zl = np.argsort(np.abs(locked))[:m]
    nz = np.delete(locked, zl)
    r1, r2 = np.delete(r1, s1), np.delete(r2, s2)
    f2 = np.delete(floor[1], s2)
    i1, j1 = linear_sum_assignment(np.abs(r1[:, None] - nz[None, :]))
    i2, j2 = linear_sum_assignment(np.abs(r2[:, None] - nz[None, :]))
    d1, d2, fl = np.empty(len(nz)), np.empty(len(nz)), np.empty(len(nz))
    d1[j1] = np.abs(r1[i1] - nz[j1])
    d2[j2] = np.abs(r2[i2] - nz[j2])
    # the round-off floor of each root at 10 K1: ||A|| grows like K, and so does the
    # absolute error of the small roots
    fl[j2] = f2[i2]
    # every other root approaches its locked value like 1/K (distance ratio ~ 0.1)
    conv = (d2 <= 0.2 * d1) | (d2 <= 10 * fl)
    holds = bool(fast_ok and np.all(conv) and to_zero == m)
    full = np.concatenate([locked, fixed])
    detail = ('locked spectrum (zdot = 0 held, ' + f'{len(full)} roots): '
              + ', '.join(_fmt(z) for z in nz if z.imag >= 0)
              + '; largest distance of a root to it / scale: '
              f'{float(d1.max(initial=0)) / scale:.2e}'
              f' at K_D = {K1:.3g}, {float(d2.max(initial=0)) / scale:.2e} at {10 * K1:.3g} '
              f'(like 1/K_D: {"yes" if np.all(conv) else "NO"}); fast root(s) -K_D '
              + ', '.join(f'{g:.6g}' for g in gains) + f' ({"ok" if fast_ok else "NOT"}); '
              f'roots to 0 like 1/K_D: {to_zero} (drives: {m})')
    return Claim('c', _STATEMENT['c'], holds, detail,
                 {'locked_re': full.real.tolist(), 'locked_im': full.imag.tolist(),
                  'distance': [float(d1.max(initial=0)) / scale,
                               float(d2.max(initial=0)) / scale],
                  'fast_gain': gains.tolist(), 'to_zero': to_zero, 'K_large': [K1, 10 * K1]})


def _claim_d(loc: Locus, m: int) -> Claim:
    # the net of the verified meetings. An unverified one (:func:`_verify`: its pair real,
    # or complex, on both sides down to the round-off window) adds 0 whatever it is: no
    # meeting (two real roots of nearly identical parts passing each other), or a break-in
    # and a breakaway within round-off. Its guessed kind is not counted, and the real roots
    # counted at both ends (an independent count) must still agree with the net: a
    # meeting whose sides were misread fails the claim there.
    net = sum((1 if mt.kind is MeetingKind.BREAK_IN else -1) * mt.multiplicity
              for mt in loc.meetings if mt.verified)
    unknown = sum(mt.multiplicity for mt in loc.meetings if not mt.verified)
    counted = (loc.real_counts[-1] - loc.real_counts[0]) // 2
    negative = all(mt.lam < 0 for mt in loc.meetings)
    holds = bool(net == m and counted == net and negative)
    text = '; '.join(('' if mt.multiplicity == 1 else f'{mt.multiplicity} pairs: ')
                     + (f'{mt.kind} at' if mt.verified else 'unresolved event at')
                     + f' K_D* = {mt.K_D:.10g}, lambda* = {mt.lam:.8g} 1/s'
                     + ('' if mt.verified else ' (NOT verified: net 0)')
                     for mt in loc.meetings)
    detail = ((text or 'no pair meets on the real axis')
              + f'; net {net} (break-ins minus breakaways'
              + (f'; {unknown} pair(s) at events NOT verified, the same on both sides down '
                 'to round-off: net 0 either way' if unknown else '')
              + f'), real roots {loc.real_counts[0]} at '
              f'K_D = {loc.K[0]:.3g} and {loc.real_counts[-1]} at {loc.K[-1]:.3g} '
              f'(net {counted}); drives: {m}')
    return Claim('d', _STATEMENT['d'], holds, detail,
                 {'K_D_star': [mt.K_D for mt in loc.meetings],
                  'lambda_star': [mt.lam for mt in loc.meetings],
                  'kinds': [str(mt.kind) for mt in loc.meetings], 'net_meetings': net,
                  'net_from_counts': counted, 'unverified_pairs': unknown})


def cyclic_drives(A0: np.ndarray, C: np.ndarray) -> list:
    """Return the drives k whose angle z_k is cyclic (K_S = 0), decided by the structure.

    z_k is the state whose equation is z_k' = zdot_k (its row of A0 equals row k of C); no
    equation depends on it (its column of A0 is zero) exactly when its restoring torque
    K_S z_k is absent: the potential V(q) does not depend on z.
    """
    out = []
    for k, c in enumerate(C):
        rows = np.flatnonzero(np.all(A0 == c, axis=1))
        if any(not np.any(A0[:, j]) for j in rows):
            out.append(k)
    return out


def _not_applicable(key: str, statement: str, cyclic: list) -> Claim:
    """Return claim ``key`` marked not applicable: K_S = 0 on the ``cyclic`` drives."""
    names = ', '.join(f'#{k + 1}' for k in cyclic)
    return Claim(key, statement, False,
                 f'not applicable: K_S = 0 on drive(s) {names} (the rotor angle is cyclic, '
                 'no self-stable drive): the theorem and its K_D -> infinity claims need '
                 'K_S > 0 on every varied drive (a root stays at 0 for every K_D, none goes to '
                 '0 like K_S / K_D)', {'cyclic_drives': cyclic}, applicable=False)


def check(sys: DriveSystem) -> ClaimsResult:
    """Check claims (a) to (d) on a :class:`DriveSystem` (module doc)."""
    A0, C = sys.A0, sys.C
    # (a), (b): the fixed roots of all drives together
    U, V = split(A0, C)
    A_U = U.T @ A0 @ U
    n_zero = _structural_zeros(A_U, max(np.linalg.norm(A0, 2), 1e-300))
    lam_fixed = np.linalg.eigvals(A_U) if U.shape[1] else np.zeros(0, complex)
    a = _claim_a(A0, U, V, n_zero, sys.drives < len(sys.K_scene))
    b = _claim_b(sys, U, V, lam_fixed, n_zero)
    # (c), (d): the locus of the varied drives, on its moving part
    A0l, Bl, Cl = sys.locus_pieces()
    # varying every drive, A0' and C_v are A0 and C: the same fixed subspace (40 digits)
    same = np.array_equal(A0l, A0) and np.array_equal(Cl, C)
    Ul, Vl = (U, V) if same else split(A0l, Cl)
    A0v, Bv, Cv = Vl.T @ A0l @ Vl, Vl.T @ Bl, Cl @ Vl
    cyclic = [k for k in cyclic_drives(A0, C) if k in sys.vary]
    loc = track(A0v, Bv, Cv, regime=not cyclic)
    if cyclic:
        # outside the theorem: (c) and (d) are not computed, only said so
        c = _not_applicable('c', _STATEMENT['c'], cyclic)
        d = _not_applicable('d', _STATEMENT['d'], cyclic)
        loc = dataclasses.replace(loc, meetings=())
    else:
        scale = max(float(np.max(np.abs(np.linalg.eigvals(A0v)), initial=0.0)), 1e-300)
        fixed_l = (np.linalg.eigvals(Ul.T @ A0l @ Ul) if Ul.shape[1]
                   else np.zeros(0, complex))
        c = _claim_c(A0v, Bv, Cv, float(loc.K[-1]), scale, fixed_l)
        d = _claim_d(loc, sys.drives)
    un = lam_fixed[np.argsort(np.abs(lam_fixed))[n_zero:]] if lam_fixed.size else lam_fixed
    return ClaimsResult(claims={'a': a, 'b': b, 'c': c, 'd': d}, meetings=loc.meetings,
                        locus=loc, structural_zero_roots=n_zero, unreached=un)
