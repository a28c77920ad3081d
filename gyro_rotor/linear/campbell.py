"""Campbell diagrams of any scene: every root over the field speed, tracked by continuity.

The roots of A(Omega0) are followed from speed to speed by eigenvector continuity
(:func:`gyro_rotor.linear.spectrum.track`: an assignment between neighbouring speeds, the
interval bisected where the match is ambiguous), never by sorting. So "mode j" is one
mode over the whole range, also where its frequency crosses another mode's or where a
complex pair lands on the real axis and splits into two real roots (the number of roots
with Im >= 0 changes there; the table of frequencies keeps its shape).

A *mode* is a pair of tracks that are complex conjugates somewhere in the range, or a
root that stays real over the whole range. Its frequency is |Im| / 2 pi (0 while the pair
is real), its decay rate the slower -Re of the pair; a real part within its eigenvalue's
round-off (:mod:`gyro_rotor.linear.roundoff`) is 0: the mode is undamped there. Whether a
root is damped is decided as ``eig`` decides it, by the one rule
(:func:`gyro_rotor.linear.claims.damped`, 40 digits below round-off), wherever double
precision cannot settle it (:func:`_settled`): a root of |Re| above :data:`SETTLED`
resolutions is settled by its sign, one within them only if it is certified unreached.

Every drive's Omega0 is scaled with the first; at each speed the scene's steady motion is
re-solved (``speed_family``: what its system offers, the centrifuge in closed form),
linearized (:func:`gyro_rotor.linear.system.linearize_scene`);
each mode is named as the linearization names its modes at one speed, the one nearest the
scene's (:attr:`Campbell.named_at`: the name, the reach by the drives and the frequency of
the label are those there). The centrifuge's steady motion
(branch, theta0) follows from its parameters in closed form; a system file's equilibrium
(steady.qdot = 0) keeps q, and a steady motion that moves (the centrifuge in Euler angles)
keeps its non-moving coordinates and the pattern of its rates, whose size and the drive
lags are solved at each speed (Gauss-Newton, continued from the scene's speed outwards).
Speeds where the steady motion does not exist are left out and reported.

A critical speed (a mode's frequency = 1 or 2 x the rotor speed) is bracketed by the grid,
then solved there (:func:`_crossing`: the mode followed into the bracket, ``brentq``) to
:data:`CROSSING_RTOL` of the speed: the same speed whatever the number of grid points.
"""

from __future__ import annotations

import dataclasses
import math

from gyro_rotor.errors import NoSteadyMotionError, ParameterError, SceneError
import numpy as np

__all__ = ['Campbell', 'campbell']


@dataclasses.dataclass(frozen=True)
class Campbell:
    """A Campbell diagram: tracked roots over the field speed and the modes they form.

    ``roots`` (speeds, roots): column j follows one root; ``modes`` the columns of each
    mode (two for a pair, one for a real root); ``frequencies`` and ``decay`` (speeds,
    modes) in Hz and 1/s (0 within round-off: ``undamped``; negative where a root grows:
    ``unstable``); ``critical``: one dict per
    crossing of a mode frequency with ``order`` x the rotor speed Omega0 / 2 pi.
    """

    Omega0: np.ndarray
    frequencies: np.ndarray
    decay: np.ndarray
    critical: list
    roots: np.ndarray = None
    resolution: np.ndarray = None
    modes: tuple = ()
    labels: tuple = ()
    skipped: tuple = ()
    nominal: float = math.nan

    @property
    def undamped(self) -> np.ndarray:
        """Return (speeds, modes): True where the mode's real part is 0 within round-off."""
        return self.decay == 0.0

    @property
    def unstable(self) -> np.ndarray:
        """Return (speeds, modes): True where a root of the mode grows (Re > its resolution)."""
        return self.decay < 0.0

    @property
    def named_at(self) -> int:
        """Return the index of the speed the modes are named at: the nearest the scene's."""
        if not math.isfinite(self.nominal):
            return len(self.Omega0) // 2
        return int(np.argmin(np.abs(self.Omega0 - self.nominal)))

    def real_roots(self) -> np.ndarray:
        """Return the number of real roots at each speed (Im = 0 within round-off)."""
        return np.sum(np.abs(self.roots.imag) <= self.resolution, axis=1)

    def as_dict(self) -> dict:
        """Return the diagram as plain data (the command's --json)."""
        return {'Omega0': self.Omega0.tolist(), 'modes': list(self.labels),
                'modes_named_at_Omega0': float(self.Omega0[self.named_at]),
                'frequencies_hz': self.frequencies.tolist(),
                'decay_rates': self.decay.tolist(),
                'undamped': self.undamped.tolist(),
                'unstable': self.unstable.tolist(),
                'unstable_modes': [int(k) for k in np.flatnonzero(self.unstable.any(axis=0))],
                'critical_speeds': self.critical,
                'roots': [[[z.real, z.imag] for z in row] for row in self.roots],
                'mode_roots': [list(m) for m in self.modes],
                'skipped_Omega0': list(self.skipped)}


def _check_values(values) -> np.ndarray:
    v = np.asarray(values, dtype=float).ravel()
    if v.size < 2 or not np.all(np.isfinite(v)):
        raise ParameterError('campbell needs at least two finite speeds')
    d = np.diff(v)
    if not (np.all(d > 0) or np.all(d < 0)):
        raise ParameterError('campbell: the speeds must be strictly monotonic')
    return v


def campbell(scene, Omega0_values, *, orders=(1, 2)) -> Campbell:
    """Campbell diagram of any scene over the field speeds ``Omega0_values`` (module doc)."""
    from gyro_rotor.linear.locus import name_roots
    from gyro_rotor.linear.spectrum import track
    values = _check_values(Omega0_values)
    path = _Speeds(scene)
    # continue the steady motion from the scene's speed outwards; leave out where none
    failed = {}
    for W in sorted(values, key=lambda w: abs(w - path.ref)):
        try:
            path.eig(float(W))
        except (NoSteadyMotionError, ParameterError) as err:
            failed[float(W)] = err
    if len(values) - len(failed) < 2:
        raise SceneError(f'scene {scene.name}: its steady motion exists at '
                         f'{len(values) - len(failed)} of the {len(values)} speeds '
                         f'({next(iter(failed.values()))}); choose another range with '
                         '--omega-min/--omega-max')
    values = np.array([w for w in values if float(w) not in failed])
    n_roots = len(path.eig(float(values[0]))[0])
    R = track(lambda W: path.eig(W)[:2], values, [''] * n_roots)
    res = np.empty(R.shape)
    for i, W in enumerate(values):
        lam, _, r, _ = path.eig(float(W))
        for j, x in enumerate(R[i]):
            res[i, j] = r[int(np.argmin(np.abs(lam - x)))]

    def name(i, cols):
        return name_roots(path.eig(float(values[i]))[3], R[i, cols])

    def refine(i, cols, order):
        try:
            return _crossing(path, values[i], values[i + 1], R[i, cols], order)
        except (NoSteadyMotionError, ParameterError):      # none inside the bracket
            return None
    return _assemble(values, R, res, name, orders, skipped=tuple(sorted(failed)),
                     nominal=path.ref, refine=refine)


#: critical speeds are refined to this relative tolerance (of the larger bracket end)
CROSSING_RTOL = 1e-10


def _crossing(path, a: float, b: float, z0: np.ndarray, order: int) -> float | None:
    """Return the speed in (a, b) where the mode of roots ``z0`` (at ``a``) crosses order x.

    The mode is followed from ``a`` to ``b`` by eigenvector continuity on a sub-grid
    (:func:`~gyro_rotor.linear.spectrum.track`, bisecting where ambiguous); the first sign
    change of its frequency minus ``order`` x the rotor speed is solved by ``brentq`` to
    :data:`CROSSING_RTOL` (the mode there: the roots nearest those tracked at the ends of
    that interval). None: the tracked mode does not cross (the grid's tracks jumped);
    the caller interpolates then, as it does where the steady motion fails in the bracket.
    """
    from scipy.optimize import brentq

    from gyro_rotor.linear.spectrum import track
    sub = np.linspace(a, b, 17)
    T = track(lambda W: path.eig(W)[:2], sub, [''] * len(path.eig(float(a))[0]))
    cols = [int(np.argmin(np.abs(T[0] - z))) for z in z0]

    def h(W, za, zb, wa, wb):
        lam, _, r, _ = path.eig(float(W))
        t = (W - wa) / (wb - wa)
        near = [int(np.argmin(np.abs(lam - (za[j] + t * (zb[j] - za[j])))))
                for j in range(len(za))]
        im = max(abs(lam[n].imag) if abs(lam[n].imag) > r[n] else 0.0 for n in near)
        return (im - order * abs(W)) / (2 * math.pi)
    for j in range(len(sub) - 1):
        za, zb = T[j, cols], T[j + 1, cols]
        ha, hb = (h(sub[j + k], za, zb, sub[j], sub[j + 1]) for k in (0, 1))
        if ha == 0 or hb == 0 or np.sign(ha) == np.sign(hb):
            continue
        return float(brentq(h, sub[j], sub[j + 1], args=(za, zb, sub[j], sub[j + 1]),
                            xtol=CROSSING_RTOL * max(abs(a), abs(b)), rtol=1e-14))
    return None


class _Speeds:
    """The scene at any field speed W: its steady motion re-solved there, linearized."""

    def __init__(self, scene):
        """Keep the scene and its family of steady motions (its system's ``speed_family``)."""
        self.ref = scene.Omega0
        if self.ref == 0:
            raise ParameterError('campbell: the first drive has Omega0 = 0; nothing to scale')
        self.at = scene.system.speed_family(scene)
        self.cache = {}

    def eig(self, W: float):
        """Return (eigenvalues, unit eigenvectors, resolutions, linearization) of A at W."""
        if W not in self.cache:
            from gyro_rotor.linear.roundoff import nearest, resolutions
            from gyro_rotor.linear.spectrum import unit_eig
            from gyro_rotor.linear.system import linearize_scene
            lin = linearize_scene(self.at(W))
            A = lin.A_scene()
            lam, V = unit_eig(A)
            lam_r, res_r = resolutions(A, lin.A_cons)
            res = res_r[nearest(lam_r, lam)]
            if not _settled(lin, lam, res):
                lam, res = _one_rule(lin, lam, res)
            self.cache[W] = (lam, V, res, lin)
        return self.cache[W]


#: a root whose |Re| exceeds this many times its resolution has its sign settled in double
SETTLED = 2.0


def _settled(lin, lam: np.ndarray, res: np.ndarray) -> bool:
    """Return True if the double-precision resolutions decide as the one rule would here.

    The one rule is :func:`~gyro_rotor.linear.claims.damped`; here it is not called (its
    40-digit fixed subspace and, where a drive damps, its 40-digit roots at K and at K = 0
    cost more than the rest of the diagram at each speed: on stiff_drive the roots about
    twice the subspace, on conservative (K_D = 0) the subspace alone).
    A reached root's resolution there is at most its resolution in A (its condition number
    on the complement of the fixed subspace is at most that in A), so a root with |Re| above
    :data:`SETTLED` resolutions is damped or grows by its sign under either rule. Each other
    root must be certified unreached: a root of the block A[S, S] of the states S that no
    drive and no other state sees (C[:, S] = 0, A0[~S, S] = 0: an exactly invariant
    subspace in ker C), or one of the zero roots of the exact nilpotent invariant subspace
    in ker C (:func:`_zeros_exact`); if it is not,
    the caller decides by the one rule.
    """
    from scipy.optimize import linear_sum_assignment
    open_ = np.abs(lam.real) <= SETTLED * res
    if not open_.any():
        return True
    A0, C = lin.A_cons, lin.c_all.T
    S = np.all(C == 0, axis=0)
    while S.any():
        seen = np.any(A0[np.ix_(~S, S)] != 0, axis=0)
        if not seen.any():
            break
        S[np.flatnonzero(S)[seen]] = False
    if S.any():
        lam_s = np.linalg.eigvals(A0[np.ix_(S, S)])
        r, _ = linear_sum_assignment(np.abs(lam[:, None] - lam_s[None, :]))
        open_[r] = False
    if not open_.any():
        return True
    # the zero roots of the exact nilpotent part beyond those of the block A[S, S]: the
    # roots nearest 0 (a cluster 1e3 times nearer than the others: a defective zero root
    # splits like sqrt(eps) in double)
    known = _zeros_exact(A0[np.ix_(S, S)], C[:, S]) if S.any() else 0
    extra = _zeros_exact(A0, C, known + int(open_.sum())) - known
    free = np.setdiff1d(np.arange(len(lam)), r) if S.any() else np.arange(len(lam))
    size = np.sort(np.abs(lam[free]))
    if extra <= 0 or extra < len(size) and size[extra - 1] > 1e-3 * size[extra]:
        return False
    return bool(np.all(np.abs(lam[open_]) <= size[extra - 1]))


def _zeros_exact(A0: np.ndarray, C: np.ndarray, enough: int | None = None) -> int:
    """Return the dimension of the largest nilpotent A0-invariant subspace in ker C, exactly.

    W_k = {u: A0^k u = 0, C A0^i u = 0 (i < k)} in exact arithmetic of the double data,
    k growing until W_k stops growing (or has ``enough`` dimensions): an invariant
    subspace in ker C whose roots are all 0, so within the fixed subspace (its 40-digit
    staircase sees each such u at its working precision, far below its zero threshold).
    The data are exact integers (each matrix times a power of 2, :func:`_integers`) and each
    row of C A0^i and A0^k is divided by its gcd: a row's scale leaves the kernel as it is.
    """
    n = len(A0)
    A = np.array(_integers(A0), dtype=object).reshape(n, n)
    new = np.array(_integers(C), dtype=object).reshape(len(C), n)
    obs, P, last = [list(r) for r in new], [list(r) for r in A], -1
    for _ in range(n):
        dim = _nullity(obs + P)
        if dim in (last, 0) or enough is not None and dim >= enough:
            return dim
        last = dim
        new = _reduced(new.dot(A))
        obs = obs + [list(r) for r in new]
        P = [list(r) for r in _reduced(np.array(P, dtype=object).dot(A))]
    return last


def _integers(M: np.ndarray) -> list:
    """Return the rows of the double matrix M times the power of 2 that makes all integers."""
    ratios = [[float(x).as_integer_ratio() for x in row] for row in M]
    k = max((d.bit_length() for row in ratios for _, d in row), default=1)
    return [[m << (k - d.bit_length()) for m, d in row] for row in ratios]


def _reduced(M: np.ndarray) -> np.ndarray:
    """Return the integer rows of M (object array), each divided by the gcd of its entries."""
    out = M.copy()
    for i, row in enumerate(M):
        g = math.gcd(*row)
        if g > 1:
            out[i] = [x // g for x in row]
    return out


def _nullity(rows: list) -> int:
    """Return the dimension of the kernel of the matrix of integer ``rows``, exactly.

    Fraction-free Gaussian elimination: each row below the pivot row p becomes
    p[col] row - row[col] p (divided by its gcd), integers throughout.
    """
    rows = [list(x) for x in rows]
    rank, n = 0, len(rows[0]) if rows else 0
    for col in range(n):
        piv = next((i for i in range(rank, len(rows)) if rows[i][col]), None)
        if piv is None:
            continue
        rows[rank], rows[piv] = rows[piv], rows[rank]
        p = rows[rank]
        for i in range(rank + 1, len(rows)):
            b = rows[i][col]
            if b:
                r = [p[col] * x - b * y for x, y in zip(rows[i], p)]
                g = math.gcd(*r)
                rows[i] = [x // g for x in r] if g > 1 else r
        rank += 1
    return n - rank


def _one_rule(lin, lam: np.ndarray, res: np.ndarray) -> tuple:
    """Return (roots, resolutions): the reached ones' by :func:`claims.damped`.

    Each reached root takes the one rule's value and resolution (a root damped there reads
    damped, one not damped reads undamped or growing); the unreached keep theirs.
    """
    from scipy.optimize import linear_sum_assignment
    from gyro_rotor.linear import claims as cl
    sys = lin.drive_system()
    dm = cl.damped(sys, sys.K_scene, cl.split(sys.A0, sys.C)[1])
    lam, res = lam.astype(complex), res.copy()
    i, j = linear_sum_assignment(np.abs(lam[:, None] - dm.lam[None, :]))
    for a, b in zip(i, j):
        z, r = complex(dm.lam[b]), float(dm.res[b])
        if dm.damped[b] and z.real >= -r:
            r = -z.real / 2
        elif not dm.damped[b] and z.real < -r:
            r = -z.real
        lam[a], res[a] = z, r
    return lam, res


# -- modes from tracked roots -----------------------------------------------------------------
def _pairs(R: np.ndarray, res: np.ndarray) -> list:
    """Group the tracks into modes: conjugate pairs (by vote over speeds), then singles."""
    S, n = R.shape
    votes = np.zeros((n, n))
    for i in range(S):
        z = R[i]
        cplx = np.abs(z.imag) > res[i]
        for j in np.flatnonzero(cplx & (z.imag > 0)):
            d = np.abs(z - np.conj(z[j]))
            d[j] = np.inf
            d[~cplx] = np.inf
            k = int(np.argmin(d))
            if math.isfinite(d[k]):
                votes[j, k] += 1
                votes[k, j] += 1
    modes, used = [], set()
    for flat in np.argsort(-votes, axis=None):
        a, b = divmod(int(flat), n)
        if votes[a, b] <= 0:
            break
        if a < b and a not in used and b not in used:
            used.update((a, b))
            modes.append((a, b))
    modes += [(j,) for j in range(n) if j not in used]
    return modes


def _assemble(values, R, res, name, orders, *, skipped=(), nominal=math.nan,
              refine=None) -> Campbell:
    re = np.where(np.abs(R.real) <= res, 0.0, R.real)
    im = np.where(np.abs(R.imag) <= res, 0.0, np.abs(R.imag))

    def freq(m):
        return im[:, list(m)].max(axis=1) / (2 * math.pi)
    # the oscillating modes from the highest frequency down (the legend's order), then
    # the real roots from the slowest
    modes = sorted(_pairs(R, res), key=lambda m: (-freq(m).max(), -re[:, list(m)].mean()))
    F = np.column_stack([freq(m) for m in modes])
    D = np.column_stack([(-re[:, list(m)]).min(axis=1) for m in modes])
    # name every mode at one speed, the one nearest the scene's (its name, its reach by the
    # drives, its frequency are those there: the reach of a mode can change with the speed,
    # the gimbals of a rotor at rest are out of the drives' reach)
    at = Campbell(Omega0=np.asarray(values, dtype=float), frequencies=None, decay=None,
                  critical=[], nominal=float(nominal)).named_at
    labels = []
    # every mode named in one call: the linearization's modes classified once
    doms = name(at, [max(m, key=lambda c: R[at, c].imag) for m in modes])
    for k, (m, dom) in enumerate(zip(modes, doms)):
        if F[:, k].max() == 0:
            if np.all(np.abs(R[:, list(m)]) <= res[:, list(m)]):
                text = dom if dom.startswith('zero root') else f'zero root ({dom})'
            else:
                text = f'{dom}, real'
        elif F[at, k] == 0:
            text = f'{dom}, real at the scene speed'
        else:
            text = f'{dom}, {F[at, k]:.3g} Hz'
        labels.append(text)
    for k, t in enumerate(labels):      # two modes with one label: tell them apart
        same = [j for j, u in enumerate(labels) if u == t]
        if len(same) == 2 and t.endswith(', real'):
            grows = [bool(np.any(D[:, j] < 0)) for j in same]
            words = (('growing', 'decaying') if grows == [True, False] else
                     ('slow', 'fast'))      # sorted slowest first: a growing root first
            for j, word in zip(same, words):
                labels[j] = f'{t} ({word})'
        elif len(same) > 1:
            for c, j in enumerate(same, 1):
                labels[j] = f'{t} #{c}'
    crit = []
    rot = np.abs(values) / (2 * math.pi)
    for order_k in orders:
        for k in range(F.shape[1]):
            g = F[:, k] - order_k * rot
            for i in np.flatnonzero(np.sign(g[:-1]) * np.sign(g[1:]) < 0):
                if F[i, k] == 0 or F[i + 1, k] == 0:
                    continue
                w = None if refine is None else refine(i, list(modes[k]), order_k)
                if w is None:       # not refined: between the grid points, linearly
                    w = values[i] + (values[i + 1] - values[i]) * g[i] / (g[i] - g[i + 1])
                crit.append({'order': order_k, 'mode': k, 'label': labels[k],
                             'Omega0': float(w),
                             'frequency_hz': float(order_k * abs(w) / (2 * math.pi))})
    crit.sort(key=lambda c: (c['Omega0'], c['order']))
    return Campbell(Omega0=np.asarray(values, dtype=float), frequencies=F, decay=D,
                    critical=crit, roots=R, resolution=res, modes=tuple(modes),
                    labels=tuple(labels), skipped=tuple(skipped), nominal=float(nominal))
