"""Linearization of any rotor system and the paper's claims (a) to (d), checked by meaning.

About a steady motion (q0, qdot0, z0, zdot = 0) the state x = (q, z, qdot, zdot) obeys

    x' = A(K) x,   A(K) = [[0, I], [Mbar^-1 G_x, Mbar^-1 G_v]] = A_0 - K b c',

with Mbar, G_x = [dF/dq | dQ/dz], G_v = dF/dv + [0; dQ/dzdot] from the generated
equations (:mod:`gyro_rotor.core.system.codegen`), exact (symbolic) derivatives. K is the
common drive damping of the drives varied (all, or one); c' picks their zdot, b =
[0; Mbar^-1 e_z]. The coordinates that move on the steady motion must enter the
equations only through combinations that stay constant, so that A does not change along
the motion; :func:`linearize` checks this.

The claims (Magnus 1980, eqs. 13-17 and the footnote; docs MODEL.md section 8):

(a) K = 0: every root on the imaginary axis; zero roots are structural (a cyclic
    coordinate) and named by their eigenvector.
(b) K > 0: the roots of every mode the drives reach (PBH: its eigenvector at K = 0 has
    a non-zero zdot part) lie in the open left half plane, and exactly the unreached ones
    stay on the axis, at their K = 0 values (Hagedorn's exclusion).
(c) K -> infinity: the roots tend to the spectrum of the locked system (z = 0 held,
    computed separately), plus m real roots to -infinity and m to 0.
(d) every K* where a complex pair meets on the negative real axis, located by bisection
    of the double root to 1e-8 relative, with the meeting point; net, m pairs meet.
"""

from __future__ import annotations

import dataclasses
import math

from gyro_rotor.core.system.model import GeneralModel
from gyro_rotor.core.system.scene import check_steady, GeneralScene
from gyro_rotor.errors import ParameterError, SceneError
import numpy as np

__all__ = ['GeneralLinear', 'linearize_scene', 'modes', 'Mode', 'check_claims',
           'GeneralClaims', 'meetings', 'Meeting', 'campbell', 'Campbell', 'solve_steady',
           'K_D_REL_TOL']

#: relative precision of K* in claim (d)
K_D_REL_TOL = 1e-8
#: roots with |Re| <= REL_AXIS * spectral radius count as on the imaginary axis
REL_AXIS = 1e-9
#: a mode is reached when the zdot part of its unit eigenvector exceeds this
REACH_TOL = 1e-7


@dataclasses.dataclass(frozen=True)
class GeneralLinear:
    """A(K) = A0 - K b c' about a steady motion (module doc), with names of the states."""

    A0: np.ndarray
    b: np.ndarray
    c: np.ndarray
    K_D: float
    A_locked: np.ndarray
    names: tuple
    n: int
    m: int
    fast_rates: np.ndarray
    K_each: np.ndarray
    A_cons: np.ndarray
    b_all: np.ndarray
    c_all: np.ndarray
    K_all: np.ndarray

    def A_scene(self) -> np.ndarray:
        """Return A with every drive at its own K_D (the scene's spectrum)."""
        return self.A_cons - self.b_all @ np.diag(self.K_all) @ self.c_all.T

    def A_common(self, K: float) -> np.ndarray:
        """Return A with every drive at the same K_D = K."""
        return self.A_cons - K * (self.b_all @ self.c_all.T)

    def A(self, K: float) -> np.ndarray:
        """Return the matrix for drive damping K of the drives varied."""
        return self.A0 - K * (self.b @ self.c.T)

    def eig(self, K: float) -> np.ndarray:
        """Return the eigenvalues of A(K)."""
        return np.linalg.eigvals(self.A(K))


def _parts(model: GeneralModel, y: np.ndarray):
    return model.lin(y)


def _A0(model: GeneralModel, y: np.ndarray, drives, which) -> tuple:
    """A0 (varied drives undamped), b, c of the varied drives, A_locked, fast rates, A_cons."""
    n, m, N = model.n, model.m, model.N
    Mbar, Fq, Fv = _parts(model, y)
    Gx = np.zeros((N, N))
    Gx[:, :n] = Fq
    Gv = Fv.copy()
    z = y[2 * n:2 * n + m]
    for k, d in enumerate(drives):
        p = d.pole_pairs
        Gx[n + k, n + k] = -d.K_S * (math.cos(p * z[k]) if p else 1.0)
    Minv = np.linalg.inv(Mbar)
    A_cons = np.block([[np.zeros((N, N)), np.eye(N)], [Minv @ Gx, Minv @ Gv]])
    for k, d in enumerate(drives):
        if k not in which:
            Gv[n + k, n + k] -= d.K_D
    A0 = np.block([[np.zeros((N, N)), np.eye(N)], [Minv @ Gx, Minv @ Gv]])
    E = np.zeros((N, len(which)))
    for j, k in enumerate(which):
        E[n + k, j] = 1.0
    b = np.vstack([np.zeros((N, len(which))), Minv @ E])
    c = np.vstack([np.zeros((N, len(which))), E])
    # the locked system: z of the varied drives held at 0 (their rows and columns removed)
    keep = [i for i in range(N) if i - n not in which]
    Mi = np.linalg.inv(Mbar[np.ix_(keep, keep)]) if keep else np.zeros((0, 0))
    r = len(keep)
    A_locked = np.block([[np.zeros((r, r)), np.eye(r)],
                         [Mi @ Gx[np.ix_(keep, keep)], Mi @ Gv[np.ix_(keep, keep)]]])
    fast = np.linalg.eigvalsh(Minv[np.ix_([n + k for k in which], [n + k for k in which])])
    return A0, b, c, A_locked, fast, A_cons


def linearize_scene(scene: GeneralScene, *, drive: str | None = None,
                    model: GeneralModel | None = None) -> GeneralLinear:
    """Linearize a general scene about its steady motion (checked steady and stationary).

    ``drive``: vary only that rotor's K_D (default: all drives together).
    """
    model = model or scene.make_model()
    check_steady(scene, model)
    system = scene.system
    if drive is None:
        which = list(range(system.m))
    elif drive in system.rotors:
        which = [system.rotors.index(drive)]
    else:
        raise ParameterError(f"unknown rotor '{drive}'; rotors of {system.name}: "
                             f"{', '.join(system.rotors)}")
    y0 = scene.steady_state(model)
    A0, b, c, A_locked, fast, A_cons = _A0(model, y0, system.drives, which)
    everyone = list(range(system.m))
    _, b_all, c_all, *_ = _A0(model, y0, system.drives, everyone)
    if np.any(np.asarray(scene.steady_qdot) != 0):
        y1 = y0.copy()
        y1[:model.n] += 0.37 * np.asarray(scene.steady_qdot)
        A1 = _A0(model, y1, system.drives, which)[0]
        if not np.allclose(A0, A1, rtol=1e-8, atol=1e-10 * np.abs(A0).max()):
            raise SceneError(f'scene {scene.name}: the linearization changes along the steady '
                             'motion (the moving coordinates are not cyclic): no constant '
                             'A matrix to analyse')
    if not np.all(np.isfinite(A0)):
        raise SceneError(f'scene {scene.name}: the linearization is not finite')
    Ks = np.array([system.drives[k].K_D for k in which])
    coords = system.coordinates
    names = tuple(coords) + tuple(f'z_{r}' for r in system.rotors) + tuple(
        f'{q}_dot' for q in coords) + tuple(f'zdot_{r}' for r in system.rotors)
    return GeneralLinear(A0=A0, b=b, c=c, K_D=float(Ks.max()), A_locked=A_locked, names=names,
                         n=model.n, m=model.m, fast_rates=fast, K_each=Ks, A_cons=A_cons,
                         b_all=b_all, c_all=c_all,
                         K_all=np.array([d.K_D for d in system.drives]))


@dataclasses.dataclass(frozen=True)
class Mode:
    """One root: value, whether the drives reach its mode (PBH at K = 0) and its name."""

    value: complex
    reached: bool
    name: str
    structural_zero: bool = False


def _scale(lam: np.ndarray) -> float:
    return max(1.0, float(np.abs(lam).max())) if lam.size else 1.0


def _dominant(lin: GeneralLinear, v: np.ndarray) -> str:
    N = lin.n + lin.m
    w = np.abs(v[:N]) + np.abs(v[N:])
    return lin.names[int(np.argmax(w))]


def modes(lin: GeneralLinear, K: float | None = None) -> list[Mode]:
    """Roots of A(K) (default: the scene's own K_D), each with its PBH reach and a name.

    A root is unreached when it is one of the K = 0 roots whose eigenvector has no zdot
    part (the PBH test); those stay where they are for every K.
    """
    A = lin.A_scene() if K is None else lin.A_common(K)
    un, zeros, scale = _unreached(lin)
    lam, V = np.linalg.eig(A)
    out = []
    for i, value in enumerate(lam):
        v = V[:, i] / np.linalg.norm(V[:, i])
        zero = abs(value) <= 1e-7 * scale
        unreached = bool(un.size) and float(np.min(np.abs(un - value))) <= 1e-7 * scale and \
            float(np.abs(lin.c_all.T @ v).max()) <= REACH_TOL
        if zero:
            label = f'zero root (cyclic {_dominant(lin, v)})'
        else:
            label = f'{"unreached mode" if unreached else "mode"} ({_dominant(lin, v)})'
        out.append(Mode(complex(value), not (zero or unreached), label, bool(zero)))
    return out


def _unreached(lin: GeneralLinear) -> tuple[np.ndarray, np.ndarray, float]:
    """Non-zero roots at K = 0 whose eigenvectors have no zdot part, zero roots, scale."""
    lam0, V0 = np.linalg.eig(lin.A_cons)
    scale = _scale(lam0)
    zero = np.abs(lam0) <= 1e-7 * scale
    un = []
    for i in np.flatnonzero(~zero):
        v = V0[:, i] / np.linalg.norm(V0[:, i])
        if float(np.abs(lin.c_all.T @ v).max()) <= REACH_TOL:
            un.append(lam0[i])
    return np.array(un, dtype=complex), lam0[zero], scale


@dataclasses.dataclass(frozen=True)
class Meeting:
    """A complex pair meets on the negative real axis at K = K_star, at lambda = point."""

    K_star: float
    point: float
    bracket: float


@dataclasses.dataclass(frozen=True)
class GeneralClaims:
    """Claims (a) to (d) with their numbers."""

    a: bool
    b: bool
    c: bool
    d: bool
    details: dict
    meetings: list

    def as_dict(self) -> dict:
        """Return the claims and their numbers as plain data (for --json)."""
        return {'a': self.a, 'b': self.b, 'c': self.c, 'd': self.d, 'details': self.details}


def _n_real(lin: GeneralLinear, K: float, scale: float) -> int:
    lam = lin.eig(K)
    real = (np.abs(lam.imag) <= 1e-6 * np.maximum(np.abs(lam), 1e-300)) & \
        (lam.real < -1e-7 * scale)
    return int(np.count_nonzero(real))


def meetings(lin: GeneralLinear, K_grid=None) -> tuple[list, int]:
    """Return (the K* where a pair meets on the negative real axis, net count of meetings).

    The number of real negative roots is scanned over ``K_grid``; each rise is bisected
    (the pair just before is complex, just after real) to 1e-8 relative.
    """
    scale = _scale(np.linalg.eigvals(lin.A0))
    K_ref = scale / float(lin.fast_rates.min())
    grid = np.geomspace(1e-6 * K_ref, 1e6 * K_ref, 481) if K_grid is None else np.asarray(
        K_grid, dtype=float)
    counts = [_n_real(lin, K, scale) for K in grid]
    found, net = [], (counts[-1] - counts[0]) // 2
    for i in range(len(grid) - 1):
        if counts[i + 1] <= counts[i]:
            continue
        lo, hi, target = grid[i], grid[i + 1], counts[i + 1]
        while hi - lo > 0.25 * K_D_REL_TOL * hi:
            mid = 0.5 * (lo + hi)
            if _n_real(lin, mid, scale) >= target:
                hi = mid
            else:
                lo = mid
        lam_lo = lin.eig(lo)
        # the pair about to meet: the complex root with the smallest imaginary part
        cand = [x for x in lam_lo if x.imag > 0 and x.real < 0]
        best = min(cand, key=lambda x: x.imag) if cand else complex(np.nan)
        found.append(Meeting(K_star=float(0.5 * (lo + hi)), point=float(best.real),
                             bracket=float((hi - lo) / hi)))
    return found, int(net)


def _claim_c(lin: GeneralLinear, scale: float) -> tuple[bool, dict]:
    m = lin.b.shape[1]
    mu = float(lin.fast_rates.min())
    K1 = 1e4 * scale / mu
    locked = np.linalg.eigvals(lin.A_locked) if lin.A_locked.size else np.zeros(0)
    dists = []
    ok = True
    for K in (K1, 10 * K1):
        lam = lin.eig(K)
        order = np.argsort(lam.real)
        fast = lam[order[:m]]
        rest = lam[order[m:]]
        slow_idx = np.argsort(np.abs(rest))[:m] if m else []
        slow = rest[slow_idx]
        others = np.delete(rest, slow_idx)
        ok &= bool(np.all(fast.real < -0.5 * K * mu))
        ok &= bool(np.all(np.abs(fast.imag) <= 1e-6 * np.abs(fast)))
        ok &= bool(np.all(np.abs(slow) <= 1e-3 * scale))
        d = max((float(np.min(np.abs(locked - x))) for x in others), default=0.0)
        d = max(d, max((float(np.min(np.abs(others - x))) for x in locked), default=0.0))
        dists.append(d / scale)
    ok &= dists[0] <= 1e-3 and dists[1] <= max(0.5 * dists[0], 1e-9)
    return bool(ok), {'K_large': [K1, 10 * K1], 'distance_to_locked_rel': dists,
                      'locked_spectrum': [[float(x.real), float(x.imag)] for x in locked]}


def check_claims(lin: GeneralLinear, K: float | None = None) -> GeneralClaims:
    """Check claims (a) to (d) (module doc); K defaults to the scene's K_D (> 0 needed)."""
    lam0 = np.linalg.eigvals(lin.A_cons)
    scale = _scale(lam0)
    tol = REL_AXIS * scale
    a = bool(np.all(np.abs(lam0.real) <= tol))
    un, zeros, _ = _unreached(lin)
    if K is None and np.all(lin.K_all > 0):
        A, K = lin.A_scene(), lin.K_D
    else:
        K = K if K is not None and K > 0 else 1e-3 * scale / float(lin.fast_rates.min())
        A = lin.A_common(K)
    lam = np.linalg.eigvals(A)
    on_axis = np.abs(lam.real) <= tol
    zero_K = np.abs(lam) <= 1e-7 * scale
    stays = all(np.min(np.abs(lam - u)) <= 1e-7 * scale for u in un)
    b = bool(stays and np.count_nonzero(on_axis & ~zero_K) == un.size
             and np.count_nonzero(zero_K) == zeros.size
             and np.all(lam[~on_axis & ~zero_K].real < -tol))
    c, cdet = _claim_c(lin, scale)
    found, net = meetings(lin)
    d = bool(net == lin.b.shape[1] and all(x.bracket <= K_D_REL_TOL for x in found))
    details = {
        'max_abs_re_at_K0': float(np.abs(lam0.real).max()) if lam0.size else 0.0,
        'axis_tol': tol, 'K': K, 'unreached': [[float(u.real), float(u.imag)] for u in un],
        'structural_zero_roots': int(zeros.size),
        'max_re_reached_at_K': (float(lam[~on_axis & ~zero_K].real.max())
                                if np.any(~on_axis & ~zero_K) else None),
        'net_meetings': net, **cdet,
    }
    return GeneralClaims(a=a, b=b, c=c, d=d, details=details, meetings=found)


@dataclasses.dataclass(frozen=True)
class Campbell:
    """Frequencies [Hz] and decay rates [1/s] of every mode over the field speed scale."""

    Omega0: np.ndarray
    frequencies: np.ndarray
    decay: np.ndarray
    critical: list


def campbell(scene: GeneralScene, Omega0_values, *, orders=(1, 2)) -> Campbell:
    """Campbell diagram over Omega0 (every drive's Omega0 scaled by the same factor).

    The steady motion must be an equilibrium (steady.qdot = 0) that stays steady at every
    speed. Critical speeds: a mode frequency crosses k times the rotor speed Omega0/2 pi.
    """
    if np.any(np.asarray(scene.steady_qdot) != 0):
        raise SceneError(f'scene {scene.name}: campbell needs a steady motion that is an '
                         'equilibrium (steady.qdot = 0); this one moves and changes with '
                         'Omega0')
    values = np.asarray(Omega0_values, dtype=float)
    ref = scene.system.drives[0].Omega0
    if ref == 0:
        raise ParameterError('campbell: the first drive has Omega0 = 0; nothing to scale')
    model = scene.make_model()
    freqs, decay = [], []
    for W in values:
        f = W / ref
        drives = [d.replace(Omega0=d.Omega0 * f) for d in scene.system.drives]
        sc = dataclasses.replace(scene, system=scene.system.with_drives(drives))
        mdl = GeneralModel(sc.system, model.compiled)
        lam = np.linalg.eigvals(linearize_scene(sc, model=mdl).A_scene())
        lam = lam[lam.imag >= 0]
        order = np.argsort(lam.imag)
        freqs.append(lam.imag[order] / (2 * math.pi))
        decay.append(-lam.real[order])
    F = np.array(freqs)
    crit = []
    rot = values / (2 * math.pi)
    for k in orders:
        for j in range(F.shape[1]):
            g = F[:, j] - k * np.abs(rot)
            for i in np.flatnonzero(np.sign(g[:-1]) * np.sign(g[1:]) < 0):
                w = values[i] + (values[i + 1] - values[i]) * g[i] / (g[i] - g[i + 1])
                crit.append({'order': k, 'mode': j, 'Omega0': float(w)})
    return Campbell(Omega0=values, frequencies=F, decay=np.array(decay), critical=crit)


def solve_steady(scene: GeneralScene, *, max_iter: int = 50) -> tuple:
    """Newton for (q, z) with qdot = steady.qdot held: the accelerations vanish.

    Returns (q, z, largest |acceleration|) from the scene's steady guess.
    """
    model = scene.make_model()
    n, m, N = model.n, model.m, model.N
    x = np.concatenate([scene.steady_q, scene.steady_z]).astype(float)

    def acc(x):
        y = model.state(x[:n], scene.steady_qdot, x[n:], np.zeros(m))
        f = model.rhs(0.0, y)
        return np.concatenate([f[n:2 * n], f[2 * n + m:2 * n + 2 * m]])
    r = acc(x)
    for _ in range(max_iter):
        if not np.all(np.isfinite(r)):
            break
        J = np.empty((N, N))
        for j in range(N):
            h = 1e-7 * max(1.0, abs(x[j]))
            e = np.zeros(N)
            e[j] = h
            J[:, j] = (acc(x + e) - acc(x - e)) / (2 * h)
        dx = np.linalg.lstsq(J, -r, rcond=None)[0]
        step = 1.0
        while step > 1e-4:
            r_new = acc(x + step * dx)
            if np.all(np.isfinite(r_new)) and np.abs(r_new).max() < np.abs(r).max():
                break
            step *= 0.5
        x, r = x + step * dx, acc(x + step * dx)
        if np.abs(r).max() <= 1e-13 * max(1.0, model.rate()):
            break
    return x[:n], x[n:], float(np.abs(r).max())
