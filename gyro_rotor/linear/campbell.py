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
round-off (:mod:`gyro_rotor.linear.roundoff`) is 0: the mode is undamped there.

General scenes (a ``system`` key) scale every drive's Omega0 with the first. An
equilibrium (steady.qdot = 0) keeps q; a steady motion that moves (the centrifuge in
Euler angles) keeps its non-moving coordinates and the pattern of its rates, whose size
and the drive lags are solved at each speed (Gauss-Newton, continued from the scene's
speed outwards). Centrifuge scenes recompute their steady motion (branch, theta0) at
each speed; speeds where it does not exist are left out and reported.
"""

from __future__ import annotations

import dataclasses
import math

from gyro_rotor.errors import ParameterError, SceneError
from gyro_rotor.linear.newton import damped_newton
import numpy as np

__all__ = ['Campbell', 'campbell', 'campbell_general', 'campbell_centrifuge']


@dataclasses.dataclass(frozen=True)
class Campbell:
    """A Campbell diagram: tracked roots over the field speed and the modes they form.

    ``roots`` (speeds, roots): column j follows one root; ``modes`` the columns of each
    mode (two for a pair, one for a real root); ``frequencies`` and ``decay`` (speeds,
    modes) in Hz and 1/s (0 within round-off: ``undamped``); ``critical``: one dict per
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

    def real_roots(self) -> np.ndarray:
        """Return the number of real roots at each speed (Im = 0 within round-off)."""
        return np.sum(np.abs(self.roots.imag) <= self.resolution, axis=1)

    def as_dict(self) -> dict:
        """Return the diagram as plain data (the command's --json)."""
        return {'Omega0': self.Omega0.tolist(), 'modes': list(self.labels),
                'frequencies_hz': self.frequencies.tolist(),
                'decay_rates': self.decay.tolist(),
                'undamped': self.undamped.tolist(),
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
    """Campbell diagram of a general or a centrifuge scene (module doc)."""
    if not scene.builtin:
        return campbell_general(scene, Omega0_values, orders=orders)
    return campbell_centrifuge(scene, Omega0_values, orders=orders)


# -- general scenes ---------------------------------------------------------------------------
class _GeneralPath:
    """The scene at any speed: drives scaled, steady motion solved, A and its eigenpairs."""

    def __init__(self, scene):
        from gyro_rotor.core.system.model import GeneralModel
        self.scene = scene
        self.ref = scene.system.drives[0].Omega0
        if self.ref == 0:
            raise ParameterError('campbell: the first drive has Omega0 = 0; nothing to scale')
        self.model = scene.make_model()
        self._Model = GeneralModel
        self.qdot = np.asarray(scene.steady_qdot, dtype=float)
        self.moving = bool(np.any(self.qdot != 0))
        # unknowns: the drive lags z and (moving) the size s of the rate pattern
        self.solved = {self.ref: (np.asarray(scene.steady_z, dtype=float), 1.0)}
        self.cache = {}

    def at(self, W: float):
        """(scene, model) at field speed W (every drive scaled by W / Omega0 of the first)."""
        f = W / self.ref
        drives = [d.replace(Omega0=d.Omega0 * f) for d in self.scene.system.drives]
        sc = dataclasses.replace(self.scene, system=self.scene.system.with_drives(drives))
        mdl = self._Model(sc.system, self.model.compiled)
        z, s = self._steady(sc, mdl, W)
        sc = dataclasses.replace(sc, steady_z=tuple(z.tolist()),
                                 steady_qdot=tuple((s * self.qdot).tolist()))
        return sc, mdl

    def _steady(self, sc, mdl, W):
        if W in self.solved:
            return self.solved[W]
        near = min(self.solved, key=lambda w: abs(w - W))
        z, s = self.solved[near]
        n, m = mdl.n, mdl.m
        q = np.asarray(sc.steady_q, dtype=float)

        def acc(u):
            zz, ss = u[:m], (u[m] if self.moving else 1.0)
            f = mdl.rhs(0.0, mdl.state(q, ss * self.qdot, zz, np.zeros(m)))
            return np.concatenate([f[n:2 * n], f[2 * n + m:2 * n + 2 * m]])
        u = np.concatenate([z, [s]]) if self.moving else z.copy()
        tol = 1e-11 * max(1.0, float(np.abs(self.qdot).max()) ** 2 * max(s, 1.0) ** 2,
                          mdl.rate())
        u, r = damped_newton(acc, u, tol)
        if not (np.all(np.isfinite(r)) and np.abs(r).max() <= 1e3 * tol):
            raise SceneError(
                f'scene {self.scene.name}: no steady motion of its family at Omega0 = {W:.6g} '
                f'rad/s (the rates keep the pattern of steady.qdot, the other coordinates '
                f'stay; largest acceleration {np.abs(r).max():.3g}); narrow the range with '
                '--omega-min/--omega-max')
        out = (u[:m], float(u[m]) if self.moving else 1.0)
        self.solved[W] = out
        return out

    def eig(self, W: float):
        """(eigenvalues, unit eigenvectors, resolutions) of A at speed W."""
        if W not in self.cache:
            from gyro_rotor.linear.system import linearize_scene
            from gyro_rotor.linear.roundoff import resolutions
            sc, mdl = self.at(W)
            lin = linearize_scene(sc, model=mdl)
            A = lin.A_scene()
            lam, V = np.linalg.eig(A)
            V = V / np.maximum(np.linalg.norm(V, axis=0), 1e-300)
            lam_r, res_r = resolutions(A, lin.A_cons)
            res = np.array([res_r[int(np.argmin(np.abs(lam_r - x)))] for x in lam])
            self.cache[W] = (lam, V, res, lin)
        return self.cache[W]


def campbell_general(scene, Omega0_values, *, orders=(1, 2)) -> Campbell:
    """Campbell diagram of a general scene (module doc)."""
    from gyro_rotor.linear.system import dominant
    from gyro_rotor.linear.spectrum import track
    values = _check_values(Omega0_values)
    path = _GeneralPath(scene)
    # continue the steady motion from the scene's speed outwards
    order = np.argsort(np.abs(values - path.ref))
    for W in values[order]:
        path.at(float(W))
    n_roots = len(path.eig(float(values[0]))[0])
    R = track(lambda W: path.eig(W)[:2], values, [''] * n_roots)
    res = np.empty(R.shape)
    for i, W in enumerate(values):
        lam, _, r, _ = path.eig(float(W))
        for j, x in enumerate(R[i]):
            res[i, j] = r[int(np.argmin(np.abs(lam - x)))]

    def name(i, j):
        lam, V, _, lin = path.eig(float(values[i]))
        k = int(np.argmin(np.abs(lam - R[i, j])))
        return dominant(lin, V[:, k])
    return _assemble(values, R, res, name, orders, nominal=path.ref)


# -- centrifuge scenes ------------------------------------------------------------------------
def campbell_centrifuge(scene, Omega0_values, *, orders=(1, 2)) -> Campbell:
    """Campbell diagram of a centrifuge scene: its steady motion recomputed at each speed."""
    from gyro_rotor.core.steady import NoSteadyMotionError, steady_motion
    from gyro_rotor.linear.linearize import linearize
    from gyro_rotor.linear.spectrum import _tol_re
    from gyro_rotor.linear.stability import sweep
    values = _check_values(Omega0_values)
    ic = scene.initial
    branch = ic.branch if ic.mode == 'steady' else 0
    theta0 = ic.theta0 if branch else 0.0
    p = scene.params
    keep, skipped = [], []
    for W in values:
        try:
            steady_motion(p.replace(Omega0=float(W)), theta0, branch)
            keep.append(float(W))
        except (NoSteadyMotionError, ParameterError, ValueError):
            skipped.append(float(W))
    if len(keep) < 2:
        raise SceneError(f'scene {scene.name}: its steady motion (branch {branch}, theta0 = '
                         f'{theta0:g} rad) exists at {len(keep)} of the {len(values)} speeds; '
                         'choose another range with --omega-min/--omega-max')
    values = np.array(keep)
    names, R = sweep(p, 'Omega0', values, theta0=theta0, branch=branch, model=scene.model)
    res = np.empty(R.shape)
    for i, W in enumerate(values):
        pp = p.replace(Omega0=float(W))
        res[i] = _tol_re(linearize(pp, steady_motion(pp, theta0, branch), scene.model))
    return _assemble(values, R, res, lambda i, j: names[j], orders, skipped=tuple(skipped),
                     nominal=p.Omega0)


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


def _assemble(values, R, res, name, orders, *, skipped=(), nominal=math.nan) -> Campbell:
    S = len(values)
    re = np.where(np.abs(R.real) <= res, 0.0, R.real)
    im = np.where(np.abs(R.imag) <= res, 0.0, np.abs(R.imag))

    def freq(m):
        return im[:, list(m)].max(axis=1) / (2 * math.pi)
    # the oscillating modes from the highest frequency down (the legend's order), then
    # the real roots from the slowest
    modes = sorted(_pairs(R, res), key=lambda m: (-freq(m).max(), -re[:, list(m)].mean()))
    F = np.column_stack([freq(m) for m in modes])
    D = np.column_stack([(-re[:, list(m)]).min(axis=1) for m in modes])
    # label each mode where it is most clearly a mode: its largest frequency (or the middle)
    i_ref = np.where(F.max(axis=0) > 0, np.argmax(F, axis=0), S // 2)
    labels = []
    for k, m in enumerate(modes):
        i = int(i_ref[k])
        j = max(m, key=lambda c: R[i, c].imag)
        dom = name(i, j)
        at = int(np.argmin(np.abs(values - nominal))) if math.isfinite(nominal) else i
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
            for j, word in zip(same, ('slow', 'fast')):     # sorted slowest first
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
                w = values[i] + (values[i + 1] - values[i]) * g[i] / (g[i] - g[i + 1])
                crit.append({'order': order_k, 'mode': k, 'label': labels[k],
                             'Omega0': float(w),
                             'frequency_hz': float(order_k * abs(w) / (2 * math.pi))})
    crit.sort(key=lambda c: (c['Omega0'], c['order']))
    return Campbell(Omega0=np.asarray(values, dtype=float), frequencies=F, decay=D,
                    critical=crit, roots=R, resolution=res, modes=tuple(modes),
                    labels=tuple(labels), skipped=tuple(skipped), nominal=float(nominal))
