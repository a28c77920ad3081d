"""Linear stability of the steady motions: modes, root locus over K_D, the paper's claims.

Built on :mod:`gyro_rotor.linear.linearize`, where ``A(K_D) = A0 - K_D b c^T``: the drive damping
is a rank-one feedback of the rotor's lag rate, so the root locus over K_D is a classic
one. At K_D = 0 the roots are those of A0; as K_D -> infinity, n - 1 roots tend to the
zeros of c^T (sI - A0)^-1 b (the motion with the rotor locked to the stator) and one
tends to -K_D c^T b -> -infinity (Magnus 1980, section 4 and figure 2).

Eigenvalues are computed from the pencil ``[[A0, -b], [c^T, -1/K_D]] - lambda diag(1,..,1,0)``
for large K_D (its entries stay of the size of A0, so the nearly undamped roots keep
their small real parts to ~1e-13 absolute even at K_D = 1e9) and from A itself for small
K_D; at K_D = infinity the same pencil gives the asymptotes.

Modes are named once, at K_D = 0, by the coordinate group that holds most of their modal
energy (tilt: nutation, and precession around solution I; twist: housing twist; drive:
rotor-field coupling; around solution II the root at 0 is the zero root of the cyclic
coordinate psi, a shift to a neighbouring steady motion of the family, not an
oscillation, and excluded from every verdict). From there the names follow the modes
along any parameter path by eigenvector continuity (:func:`track`), never by sorting.

Drive penetration (the paper's footnote, Hagedorn): the first-order sensitivity
d lambda/d K_D = -(w^H b)(c^T v)/(w^H v) at K_D = 0 (left and right eigenvectors w, v).
A mode is reached by the drive damping iff d Re(lambda)/d K_D < 0 beyond the numerical
noise (:data:`TOL_SENS_REL` times the largest sensitivity).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Sequence

from gyro_rotor.core.params import RotorParams
from gyro_rotor.core.steady import steady_motion, SteadyMotion
from gyro_rotor.errors import NoSteadyMotionError, ParameterError
from gyro_rotor.linear.claims import Claim
from gyro_rotor.linear.linearize import linearize, LinearSystem
from gyro_rotor.linear.spectrum import (_cyclic_z, _name_at_zero, _tol_re,  # noqa: F401
                                        spectrum, STRUCTURAL, TOL_RE_REL, TOL_SENS_REL, track,
                                        ZERO_ROOT, ZERO_ROOT_Z)
import numpy as np

# the spectra (eigen-decomposition at any K_D, mode names, continuity): linear/spectrum.py
__all__ = ['Mode', 'StabilityReport', 'RootLocus', 'Claim', 'ClaimsReport', 'TuneResult',
           'spectrum', 'modes', 'analyze', 'analyze_scene', 'root_locus', 'check_claims',
           'best_K_D', 'track', 'sweep', 'asymptotes', 'sensitivities', 'default_grid',
           'scene_operating_point', 'ZERO_ROOT', 'ZERO_ROOT_Z', 'STRUCTURAL', 'TOL_RE_REL']


# -- data -------------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Mode:
    """One mode: a conjugate pair (upper eigenvalue given) or a real root.

    ``freq_hz`` = |Im lambda|/(2 pi); ``zeta`` = -Re lambda/|lambda|; ``tau`` = -1/Re lambda
    [s] (inf if Re >= 0); ``dRe_dKD`` = d Re(lambda)/d K_D at K_D = 0 [1/(N m s^2/rad)];
    ``reached_by_drive``: that sensitivity is strictly negative; ``kind`` 'oscillatory',
    'real' or 'zero' (the structural zero root).
    """

    name: str
    eigenvalue: complex
    freq_hz: float
    zeta: float
    tau: float
    reached_by_drive: bool
    dRe_dKD: float
    kind: str
    eigenvalue_K_D0: complex

    def as_dict(self) -> dict:
        """JSON-friendly dict."""
        d = dataclasses.asdict(self)
        for k in ('eigenvalue', 'eigenvalue_K_D0'):
            d[k] = [d[k].real, d[k].imag]
        return d


@dataclasses.dataclass(frozen=True)
class StabilityReport:
    """Modes about a steady motion and the verdict (see :func:`analyze`)."""

    scene: str
    model: str
    motion: SteadyMotion
    coords: str
    state_names: tuple
    K_D: float
    modes: list
    spectral_abscissa: float
    slowest_mode: str
    verdict: str
    marginal_modes: list
    reason: str
    A: np.ndarray = dataclasses.field(repr=False)

    def mode(self, name: str) -> Mode:
        """Return the mode called ``name``."""
        for m in self.modes:
            if m.name == name:
                return m
        raise KeyError(f"no mode '{name}'; modes: {', '.join(m.name for m in self.modes)}")


@dataclasses.dataclass(frozen=True)
class ClaimsReport:
    """Claims (a) to (d), K_D* (coupling pair meets on the real axis) and the regimes."""

    claims: dict
    K_D_star: float | None
    breakaway: float | None
    regimes: list
    locus: RootLocus | None = dataclasses.field(default=None, repr=False)
    meetings: list = dataclasses.field(default_factory=list)

    @property
    def all_hold(self) -> bool:
        """Return True if (a) to (d) all hold."""
        return all(c.holds for c in self.claims.values())


@dataclasses.dataclass
class RootLocus:
    """Tracked roots over K_D: ``eigenvalues[i, j]`` at ``K_D[i]`` on branch ``labels[j]``.

    ``zeros`` are the finite K_D -> infinity asymptotes with ``zero_labels`` (the branch
    that ends there), ``fast_label`` the branch that goes to -infinity like
    ``-K_D * fast_gain``.
    """

    lin: LinearSystem
    K_D: np.ndarray
    eigenvalues: np.ndarray
    labels: list
    zeros: np.ndarray
    zero_labels: list
    fast_label: str
    fast_gain: float

    def to_rows(self) -> list:
        """Rows (K_D, branch, Re, Im) for CSV."""
        return [(float(k), self.labels[j], float(lam.real), float(lam.imag))
                for k, row in zip(self.K_D, self.eigenvalues) for j, lam in enumerate(row)]

    def as_dict(self) -> dict:
        """JSON-friendly dict."""
        return {
            'state_names': list(self.lin.state_names), 'coords': self.lin.coords,
            'K_D': self.K_D.tolist(), 'labels': self.labels,
            're': self.eigenvalues.real.tolist(), 'im': self.eigenvalues.imag.tolist(),
            'asymptotes': {'zeros_re': self.zeros.real.tolist(),
                           'zeros_im': self.zeros.imag.tolist(), 'zero_labels':
                           self.zero_labels, 'fast_label': self.fast_label,
                           'fast_root': f'-{self.fast_gain:.12g} K_D'},
        }


@dataclasses.dataclass(frozen=True)
class TuneResult:
    """Best K_D for the slowest decay (the paper's closing remark) and its sensitivity."""

    K_S: float
    K_D_best: float
    rate_best: float
    tau_best: float
    governing_modes: list
    excluded_modes: list
    rate_at: dict
    K_D_range_90: tuple
    dlnrate_dlnKD: tuple
    K_D_current: float
    rate_current: float


# -- spectra ----------------------------------------------------------------------------------
# -- modes at an operating point -------------------------------------------------------------
def sensitivities(lin: LinearSystem) -> tuple:
    """(eigenvalues of A0, d lambda/d K_D at K_D = 0, weighted right eigenvectors).

    Eigenvalue perturbation theory: d lambda/d K_D = -(w^H b)(c^T v)/(w^H v). Where
    w^H v is tiny (a defective or repeated root) a central finite difference of the
    tracked eigenvalue over K_D in [-h, h] replaces it. A semisimple cluster of zero roots
    (K_S = 0 about solution II: the roots of psi and of the drive's slip) has no unique
    eigenvectors: its basis is the one that the perturbation -K_D b c^T diagonalizes
    (first-order degenerate perturbation theory), and d lambda/d K_D are the eigenvalues
    of the perturbation restricted to it.
    """
    lam, Vw, W = spectrum(lin, 0.0, left=True)
    V = Vw / lin.weights[:, None]
    d = np.empty(len(lam), dtype=complex)
    done = _zero_cluster(lin, lam, V, W, Vw, d)
    for j in range(len(lam)):
        if j in done:
            continue
        w, v = W[:, j], V[:, j]
        den = np.vdot(w, v)
        cond = np.linalg.norm(w) * np.linalg.norm(v) / max(abs(den), 1e-300)
        if cond < 1e8:
            d[j] = -np.vdot(w, lin.b) * (lin.c @ v) / den
        else:                                      # pragma: no cover -- degenerate roots
            h = 1e-7 * np.linalg.norm(lin.A0) / max(np.linalg.norm(lin.b), 1e-300)
            lp = np.linalg.eigvals(lin.A0 - h * np.outer(lin.b, lin.c))
            lm = np.linalg.eigvals(lin.A0 + h * np.outer(lin.b, lin.c))
            d[j] = (lp[np.argmin(abs(lp - lam[j]))] - lm[np.argmin(abs(lm - lam[j]))]) / (2 * h)
    return lam, d, Vw


def _zero_cluster(lin, lam, V, W, Vw, d) -> set:
    """Resolve a semisimple cluster of zero roots in place (see :func:`sensitivities`).

    Returns the indices handled (their ``Vw`` columns rotated, ``d`` set).
    """
    n = len(lam)
    iz = _cyclic_z(lin)
    tol = 1e-8 * max(np.linalg.norm(lin.A0), 1.0)
    idx = [j for j in range(n) if abs(lam[j]) <= tol and not (iz is not None and j == n - 1)]
    if len(idx) < 2:
        return set()
    N, L = V[:, idx], W[:, idx]
    G = L.conj().T @ N
    if np.linalg.cond(G) > 1e8:        # pragma: no cover -- a defective cluster
        return set()
    M = -np.linalg.solve(G, np.outer(L.conj().T @ lin.b, lin.c @ N))
    mu, Y = np.linalg.eig(M)
    Vn = (N @ Y) * lin.weights[:, None]
    Vw[:, idx] = Vn / np.maximum(np.linalg.norm(Vn, axis=0), 1e-300)
    d[idx] = mu
    return set(idx)


def _modes_from(lin, lam_K, names, lam0, d0, tol_re, tol_sens) -> list:
    """Mode objects: one per name (upper eigenvalue), or per real root of a split pair."""
    by_name: dict = {}
    for j, nm in enumerate(names):
        by_name.setdefault(nm, []).append(j)
    # a pair is complex beyond the scale of A0, not of the escaping root -K_D c^T b
    tol_im = 1e-9 * max(np.linalg.norm(lin.A0), 1.0)
    out = []
    for nm, idx in by_name.items():
        lams = lam_K[idx]
        if nm in STRUCTURAL:
            groups = [(nm, idx[0], 'zero')]
        elif len(idx) == 2 and abs(lams[0].imag) > tol_im:
            j = idx[int(np.argmax(lams.imag))]
            groups = [(nm, j, 'oscillatory')]
        elif len(idx) == 2:
            slow, fast = sorted(idx, key=lambda i: -lam_K[i].real)
            groups = [(f'{nm} (slow real)', slow, 'real'), (f'{nm} (fast real)', fast, 'real')]
        else:
            groups = [(nm, j, 'real') for j in idx]
        for label, j, kind in groups:
            lamv = complex(lam_K[j])
            dre = float(d0[j].real)
            reached = kind != 'zero' and dre < -tol_sens
            re = lamv.real
            zeta = -re / abs(lamv) if abs(re) > tol_re and kind != 'zero' else 0.0
            out.append(Mode(
                name=label, eigenvalue=lamv, freq_hz=abs(lamv.imag) / (2 * math.pi),
                zeta=zeta,
                tau=(-1.0 / re) if re < -tol_re else math.inf, reached_by_drive=reached,
                dRe_dKD=dre, kind=kind, eigenvalue_K_D0=complex(lam0[j])))
    out.sort(key=lambda m: (m.kind == 'zero', -m.eigenvalue.real))
    return out


def _tracked_names(lin: LinearSystem, K_values: Sequence[float]):
    """Names at K_D = 0 and the eigenvalues tracked along ``K_values`` (starting at 0)."""
    lam0, d0, Vw = sensitivities(lin)
    names = _name_at_zero(lin, lam0, Vw, d0)
    lam_path = track(lambda k: (lam0, Vw) if k == 0 else spectrum(lin, k), K_values, names,
                     log=True)
    return names, lam0, d0, lam_path


def _path_to(K_D: float, params: RotorParams, per_decade: int = 8) -> list:
    """0, then a log path to K_D that starts well below the characteristic K_D."""
    if K_D <= 0:
        return [0.0]
    lo = min(K_D * 1e-6, 1e-4 * _K_ref(params))
    return [0.0] + list(np.geomspace(lo, K_D, 6 * per_decade + 1))


def analyze(params: RotorParams, motion: SteadyMotion, model: str = 'full', *,
            K_D: float | None = None, scene: str = '') -> StabilityReport:
    """Modes, spectral abscissa and verdict about ``motion`` at drive damping ``K_D``.

    Verdict: 'unstable' if a root (other than the cyclic zero root) has Re > 0;
    'marginal' if one is on the imaginary axis (the reason names the modes and whether
    the drive damping reaches them); 'asymptotically stable' otherwise. The structural
    zero root of solution II (a neighbouring steady motion of the family) is listed but
    not judged: the paper's stability is in the velocities and the rotor angles.
    """
    K_D = params.K_D if K_D is None else float(K_D)
    if not (K_D >= 0 and math.isfinite(K_D)):
        raise ParameterError(f'K_D must be finite and not negative, got {K_D!r} N m s/rad')
    lin = linearize(params.replace(K_D=K_D), motion, model)
    names, lam0, d0, lam_path = _tracked_names(lin, _path_to(K_D, lin.params))
    lam_K = lam_path[-1]
    tol_re = _tol_re(lin)
    tol_sens = TOL_SENS_REL * max(np.max(np.abs(d0)), 1e-300)
    ms = _modes_from(lin, lam_K, names, lam0, d0, tol_re, tol_sens)
    judged = [m for m in ms if m.kind != 'zero']
    absc = max((m.eigenvalue.real for m in judged), default=-math.inf)
    slowest = max(judged, key=lambda m: m.eigenvalue.real).name if judged else ''
    unstable = [m for m in judged if m.eigenvalue.real > tol_re]
    marginal = [m for m in judged if abs(m.eigenvalue.real) <= tol_re]
    if unstable:
        verdict = 'unstable'
        reason = 'growing: ' + ', '.join(f'{m.name} (Re = {m.eigenvalue.real:+.3e} 1/s)'
                                         for m in unstable)
    elif marginal:
        verdict = 'marginal'
        parts = []
        for m in marginal:
            why = ('no drive damping (K_D = 0)' if K_D == 0 and m.reached_by_drive
                   else 'not reached by the drive damping (dRe/dK_D = 0 at K_D = 0; '
                        "Hagedorn's exclusion)" if not m.reached_by_drive
                   else 'on the imaginary axis')
            parts.append(f'{m.name}: {why}')
        reason = '; '.join(parts)
    else:
        verdict = 'asymptotically stable'
        reason = (f'every root except the cyclic zero root has Re < 0; slowest: {slowest} '
                  f'(Re = {absc:.4g} 1/s)' if lin.coords == 'II' else
                  f'every root has Re < 0; slowest: {slowest} (Re = {absc:.4g} 1/s)')
    return StabilityReport(scene=scene, model=model, motion=motion, coords=lin.coords,
                           state_names=lin.state_names, K_D=K_D, modes=ms,
                           spectral_abscissa=float(absc), slowest_mode=slowest,
                           verdict=verdict, marginal_modes=[m.name for m in marginal],
                           reason=reason, A=lin.A)


def modes(params: RotorParams, motion: SteadyMotion, model: str = 'full',
          K_D: float | None = None) -> list:
    """Return the named modes about ``motion`` (shorthand for ``analyze(...).modes``)."""
    return analyze(params, motion, model, K_D=K_D).modes


def scene_operating_point(scene) -> tuple:
    """(params, steady motion, model) that a scene's linear analysis uses.

    A steady-mode scene: its steady motion (I or II on its branch); a body-mode scene:
    solution I.
    """
    return scene.params, scene.steady(), scene.model


def analyze_scene(scene) -> StabilityReport:
    """:func:`analyze` for a scene (name, path or loaded :class:`~gyro_rotor.core.scene.Scene`)."""
    from gyro_rotor.core.scene import load_scene, Scene
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    p, sm, model = scene_operating_point(scene)
    return analyze(p, sm, model, scene=scene.name)


# -- root locus -------------------------------------------------------------------------------
def _K_ref(p: RotorParams) -> float:
    """Characteristic drive damping 2 sqrt(K_S mu), mu = C_R C_M/(C_R + C_M)."""
    mu = p.C_R * p.C_M / (p.C_R + p.C_M)
    k = p.K_S if p.K_S > 0 else max(p.c_psi, 1e-12)
    return 2.0 * math.sqrt(k * mu)


def default_grid(params: RotorParams, per_decade: int = 40) -> np.ndarray:
    """[0] plus a log grid from 1e-4 to 1e3 times 2 sqrt(K_S C_R C_M/(C_R + C_M))."""
    K = _K_ref(params)
    return np.concatenate([[0.0], np.geomspace(1e-4 * K, 1e3 * K, 7 * per_decade + 1)])


def asymptotes(lin: LinearSystem) -> tuple:
    """K_D -> infinity: (finite zeros (n-1,), gain g of the fast root -g K_D)."""
    lam, _ = spectrum(lin, math.inf)
    return lam, float(lin.c @ lin.b)


def _check_grid(grid) -> np.ndarray:
    g = np.asarray(grid, dtype=float)
    if g.ndim != 1 or g.size < 2:
        raise ParameterError('the K_D grid needs at least two values')
    if not np.all(np.isfinite(g)):
        raise ParameterError('the K_D grid must be finite (K_D -> infinity is added as '
                             'the asymptotes)')
    if np.any(g < 0):
        raise ParameterError(f'K_D must not be negative, got {g[g < 0][0]!r} N m s/rad in '
                             f'the grid')
    if np.any(np.diff(g) <= 0):
        raise ParameterError('the K_D grid must increase strictly')
    return g


def _reach(lin, K, zeros, gain) -> float:
    """Return the distance of the roots at K from their asymptotes.

    Relative to the spectral scale max(|zeros|, |eig(A0)|).
    """
    lam, _ = spectrum(lin, K)
    if not np.all(np.isfinite(lam)):
        return math.inf
    fast = int(np.argmin(lam.real))
    rest = np.delete(lam, fast)
    from scipy.optimize import linear_sum_assignment
    D = np.abs(rest[:, None] - zeros[None, :])
    r, c = linear_sum_assignment(D)
    scale = max(np.max(np.abs(zeros), initial=0.0),
                np.max(np.abs(np.linalg.eigvals(lin.A0))), 1e-12)
    far = float(np.max(D[r, c]) / scale)
    # the escaping root must also be far beyond the zeros
    if -lam[fast].real < 10 * scale:
        far = max(far, 1.0)
    return far


#: the grid must end where every finite root is within this fraction of max |zero| of its
#: asymptote (and the fast root beyond 10 max |zero|)
REACH_TOL = 0.01


def root_locus(lin: LinearSystem, K_D_grid=None) -> RootLocus:
    """Tracked roots over K_D (default :func:`default_grid`) and the K_D -> inf asymptotes.

    Raises ParameterError for negative or unordered grids, and for a grid that does not
    reach large K_D (roots still further than REACH_TOL from their asymptotes).
    """
    grid = default_grid(lin.params) if K_D_grid is None else _check_grid(K_D_grid)
    zeros, gain = asymptotes(lin)
    far = _reach(lin, grid[-1], zeros, gain)
    if far > REACH_TOL:
        need = grid[-1]
        for _ in range(15):
            need *= 10
            if _reach(lin, need, zeros, gain) <= REACH_TOL:
                break
        raise ParameterError(
            f'the K_D grid ends at {grid[-1]:.4g} N m s/rad, which does not reach large K_D: '
            f'the roots there are still {100 * far:.3g}% (of the largest asymptote) away '
            f'from their K_D -> infinity asymptotes; extend it to at least {need:.3g}')
    path = list(grid) if grid[0] == 0 else [0.0] + list(grid)
    names, lam0, d0, lam_path = _tracked_names(lin, path)
    if grid[0] != 0:
        lam_path = lam_path[1:]
    # which branch ends at which zero
    from scipy.optimize import linear_sum_assignment
    last = lam_path[-1]
    fast = int(np.argmin(last.real))
    others = [j for j in range(len(last)) if j != fast]
    D = np.abs(last[others][:, None] - zeros[None, :])
    r, c = linear_sum_assignment(D)
    zlab = [''] * len(zeros)
    for ri, ci in zip(r, c):
        zlab[ci] = names[others[ri]]
    return RootLocus(lin=lin, K_D=grid, eigenvalues=lam_path, labels=names, zeros=zeros,
                     zero_labels=zlab, fast_label=names[fast], fast_gain=gain)


def check_claims(lin: LinearSystem, K_D_grid=None) -> ClaimsReport:
    """Check the paper's claims (a) to (d) for this linearization, by their meaning.

    See :mod:`gyro_rotor.linear.claims` (one function per claim, on a
    :class:`~gyro_rotor.linear.claims.DriveSystem`; no claim looks at mode names).
    ``K_D_star``/``breakaway`` are the last meeting of a pair on the real axis (the one
    that splits toward 0 and -infinity); ``meetings`` holds all of them.
    """
    from gyro_rotor.linear import claims as cl
    loc = root_locus(lin, K_D_grid)
    sys = cl.drive_system(lin)
    path = loc.eigenvalues if loc.K_D[0] == 0 else np.vstack(
        [spectrum(lin, 0.0)[0][None, :], loc.eigenvalues])
    K = loc.K_D if loc.K_D[0] == 0 else np.concatenate([[0.0], loc.K_D])
    claim_d, meets = cl.claim_d(sys, K, path)
    claims = {'a': cl.claim_a(sys), 'b': cl.claim_b(sys, K, path, loc.labels),
              'c': cl.claim_c(sys, float(K[-1])), 'd': claim_d}
    K_star = meets[-1].K_D if meets else None
    lam_star = meets[-1].lam if meets else None
    regimes = []
    if K_star is not None:
        regimes.append({'regime': 'the pair that meets last is complex (oscillatory)',
                        'K_D_from': 0.0, 'K_D_to': K_star})
        regimes.append({'regime': 'that pair real (overdamped)', 'K_D_from': K_star,
                        'K_D_to': math.inf})
    return ClaimsReport(claims=claims, K_D_star=K_star, breakaway=lam_star, regimes=regimes,
                        locus=loc, meetings=meets)


# -- the best K_D ----------------------------------------------------------------------------
def best_K_D(params: RotorParams, motion: SteadyMotion, model: str = 'full', *,
             K_S: float | None = None, K_D_grid=None) -> TuneResult:
    """Return the K_D that maximizes the slowest decay rate -max Re over the judged modes.

    Judged modes: all except the cyclic zero root and the modes the drive damping does not
    reach (their rate is 0 for every K_D; they are listed in ``excluded_modes``). A grid
    scan (default grid) is refined by a bounded scalar search in log K_D. Sensitivity:
    the rate at 0.5, 0.9, 1.1, 2 times the optimum, the K_D range where the rate stays
    within 90% of the best, and d ln(rate)/d ln(K_D) just below and above.
    """
    from scipy.optimize import minimize_scalar
    if K_S is not None:
        params = params.replace(K_S=float(K_S))
    lin = linearize(params, motion, model)
    names, lam0, d0, _ = _tracked_names(lin, [0.0])
    lam_z, _, Vw_z = sensitivities(lin)

    def fn0(k):          # the K_D = 0 basis that named the modes (zero clusters resolved)
        return (lam_z, Vw_z) if k == 0 else spectrum(lin, k)
    tol_sens = TOL_SENS_REL * max(np.max(np.abs(d0)), 1e-300)
    excluded = sorted({nm for j, nm in enumerate(names)
                       if nm in STRUCTURAL or not d0[j].real < -tol_sens})
    judged_names = {nm for nm in names if nm not in excluded}
    if not judged_names:
        raise ParameterError('no mode is reached by the drive damping: K_D cannot be tuned')
    grid = default_grid(params) if K_D_grid is None else _check_grid(K_D_grid)
    grid = grid[grid > 0]
    lam_path = track(fn0, [0.0] + list(grid), names, log=True)[1:]
    judged = [j for j, nm in enumerate(names) if nm in judged_names]

    def rate_of(lam):
        return float(-np.max(lam[judged].real))

    rates = np.array([rate_of(r) for r in lam_path])
    i = int(np.argmax(rates))

    def rate_at(K):
        return rate_of(_aligned(lin, lam_path[i], grid[i], K))

    lo = grid[max(i - 1, 0)]
    hi = grid[min(i + 1, len(grid) - 1)]
    res = minimize_scalar(lambda u: -rate_at(math.exp(u)), bounds=(math.log(lo), math.log(hi)),
                          method='bounded', options={'xatol': 1e-6})
    K_best = float(math.exp(res.x))
    r_best = -float(res.fun)
    if rates[i] > r_best:
        K_best, r_best = float(grid[i]), float(rates[i])
    lam_best = _aligned(lin, lam_path[i], grid[i], K_best)
    gov = sorted({names[j] for j in judged if -lam_best[j].real <= r_best * (1 + 1e-6)})
    at = {f'{f:g}': rate_at(K_best * f) for f in (0.5, 0.9, 1.1, 2.0)}
    ok = np.where(rates >= 0.9 * r_best)[0]
    rng = (float(grid[ok[0]]), float(grid[ok[-1]])) if ok.size else (K_best, K_best)
    h = 0.01
    r_m, r_p = rate_at(K_best * math.exp(-h)), rate_at(K_best * math.exp(h))
    slopes = ((math.log(r_best) - math.log(r_m)) / h if r_m > 0 else math.nan,
              (math.log(r_p) - math.log(r_best)) / h if r_p > 0 else math.nan)
    cur = params.K_D
    r_cur = (rate_of(track(fn0, _path_to(cur, params), names, log=True)[-1])
             if cur > 0 else 0.0)
    return TuneResult(K_S=params.K_S, K_D_best=K_best, rate_best=r_best,
                      tau_best=1.0 / r_best if r_best > 0 else math.inf,
                      governing_modes=gov, excluded_modes=excluded, rate_at=at,
                      K_D_range_90=rng, dlnrate_dlnKD=slopes, K_D_current=cur,
                      rate_current=r_cur)


def _aligned(lin, lam_ref, K_ref, K) -> np.ndarray:
    """Eigenvalues at K in the tracked order of ``lam_ref`` (known at K_ref)."""
    lam_s, V = spectrum(lin, K_ref)
    perm0 = [int(np.argmin(np.abs(lam_s - x))) for x in lam_ref]
    names = [str(k) for k in range(len(lam_ref))]
    path = track(lambda k: (lambda r: (r[0][perm0], r[1][:, perm0]))(spectrum(lin, k))
                 if k == K_ref else spectrum(lin, k), [K_ref, K], names, log=True)
    return path[-1]


# -- parameter sweeps -------------------------------------------------------------------------
def sweep(params: RotorParams, name: str, values: Sequence[float], *, theta0: float = 0.1,
          branch: int = 1, model: str = 'full') -> tuple:
    """Track the named modes while parameter ``name`` runs through ``values``.

    The steady motion (theta0, branch) is recomputed at each value; names are given at
    K_D = 0 for ``values[0]`` and followed by eigenvector continuity at the parameters'
    K_D. Returns (labels, eigenvalues (len(values), n)).
    """
    values = [float(v) for v in values]

    def lin_at(v):
        p = params.replace(**{name: v})
        try:
            sm = steady_motion(p, theta0 if branch else 0.0, branch)
        except NoSteadyMotionError as err:
            raise NoSteadyMotionError(f'{name} = {v:g}: {err}') from None
        return linearize(p, sm, model)

    lin0 = lin_at(values[0])
    names, _, _, path0 = _tracked_names(lin0, _path_to(lin0.params.K_D, lin0.params))
    # start the parameter path from the tracked state at K_D
    lam_start = path0[-1]
    lam_s, V_s = spectrum(lin0, lin0.params.K_D)
    perm = [int(np.argmin(np.abs(lam_s - x))) for x in lam_start]

    def fn(v):
        lin = lin_at(v)
        lam, V = spectrum(lin, lin.params.K_D)
        if v == values[0]:
            return lam[perm], V[:, perm]
        return lam, V

    return names, track(fn, values, names)
