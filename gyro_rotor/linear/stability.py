"""Linear stability of the steady motions: named modes, drive penetration, verdict.

Built on :mod:`gyro_rotor.core.linearize` (``A(K_D) = A0 - K_D b c^T``) and the
eigen-decompositions of :mod:`gyro_rotor.linear.spectrum`. The root locus over K_D and the
paper's claims (a) to (d) live in :mod:`gyro_rotor.linear.locus`, the best K_D
(``gyro-rotor tune``) in :mod:`gyro_rotor.linear.tune`.

Modes are named once, at K_D = 0, by the coordinate group that holds most of their modal
energy (tilt: nutation, and precession around solution I; twist: housing twist; drive:
rotor-field coupling; around solution II the root at 0 is the zero root of the cyclic
coordinate psi, a shift to a neighbouring steady motion of the family, not an
oscillation, and excluded from every verdict). From there the names follow the modes
along any parameter path by eigenvector continuity (:func:`track`), never by sorting.

Drive penetration (the paper's footnote, Hagedorn) and damping are decided by one rule for
every system (:func:`classify`): a mode is reached iff its root at K_D = 0 is not on the
fixed (unobservable) subspace of :func:`gyro_rotor.linear.claims.fixed_subspace`, and a
reached root is damped by :func:`gyro_rotor.linear.claims.damped` (the rule of claim (b)),
so that ``eig``, the prediction and ``locus`` cannot disagree. The first-order sensitivity
d lambda/d K_D = -(w^H b)(c^T v)/(w^H v) at K_D = 0 (left and right eigenvectors w, v) is
printed beside it.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from typing import Sequence

from gyro_rotor.core.linearize import LinearSystem
from gyro_rotor.errors import ParameterError
from gyro_rotor.linear.roundoff import floor, nearest, resolution
from gyro_rotor.linear.spectrum import (_cyclic_z, _name_at_zero,  # noqa: F401
                                        by_pencil, K_ref, spectrum, STRUCTURAL, TOL_RE_REL,
                                        track, unit, zero_K_sensitivities, ZERO_ROOT,
                                        ZERO_ROOT_Z)
import numpy as np

# the spectra (eigen-decomposition at any K_D, mode names, continuity): linear/spectrum.py
__all__ = ['Stability', 'ModeKind', 'Mode', 'Verdict', 'judge', 'spectrum', 'named_modes',
           'classify', 'track', 'sensitivities', 'ZERO_ROOT', 'ZERO_ROOT_Z',
           'STRUCTURAL', 'TOL_RE_REL']


# -- data -------------------------------------------------------------------------------------
class Stability(enum.StrEnum):
    """The linear theory's verdict about a steady motion (:func:`judge`)."""

    ASYMPTOTICALLY_STABLE = 'asymptotically stable'
    MARGINAL = 'marginal'
    UNSTABLE = 'unstable'


class ModeKind(enum.StrEnum):
    """What a mode is: a conjugate pair, a real root, or the structural zero root."""

    OSCILLATORY = 'oscillatory'
    REAL = 'real'
    ZERO = 'zero'


@dataclasses.dataclass(frozen=True)
class Mode:
    """One mode: a conjugate pair (upper eigenvalue given) or a real root.

    ``freq_hz`` = |Im lambda|/(2 pi); ``zeta`` = -Re lambda/|lambda|; ``tau`` = -1/Re lambda
    [s] (inf if Re >= 0); ``dRe_dKD`` = d Re(lambda)/d K_D at K_D = 0 [1/(N m s^2/rad)]
    (nan: not defined, a root of a cluster still defective once the resting space is out);
    ``reached_by_drive``: its root at K_D = 0 is not on the fixed subspace; ``damped``: the rule of
    :func:`gyro_rotor.linear.claims.damped` (None: not classified, then Re < -resolution);
    ``kind`` a :class:`ModeKind` (ZERO: a zero root); ``rotor_angle``: a zero root whose
    eigenvector is a rotor angle z (no drive stiffness, K_S = 0: judged marginal);
    ``resolution`` the eigenvalue's.
    """

    name: str
    eigenvalue: complex
    freq_hz: float
    zeta: float
    tau: float
    reached_by_drive: bool
    dRe_dKD: float
    kind: ModeKind
    eigenvalue_K_D0: complex
    #: a |Re| within this is 0 (round-off; :mod:`gyro_rotor.linear.roundoff`)
    resolution: float = 0.0
    damped: bool | None = None
    rotor_angle: bool = False

    def as_dict(self) -> dict:
        """JSON-friendly dict: plain bools, floats (nan as None), complex as [re, im]."""
        d = dataclasses.asdict(self)
        for k, x in d.items():
            if isinstance(x, (complex, np.complexfloating)):
                d[k] = [float(x.real), float(x.imag)]
            elif isinstance(x, (bool, np.bool_)):
                d[k] = bool(x)
            elif isinstance(x, enum.Enum):
                d[k] = str(x)
            elif isinstance(x, (float, np.floating)):
                d[k] = float(x) if math.isfinite(x) or math.isinf(x) else None
        return d

    @property
    def is_damped(self) -> bool:
        """Return True if the root is damped (:attr:`damped`; unclassified: Re < -res)."""
        if self.damped is not None:
            return bool(self.damped)
        return self.eigenvalue.real < -self.resolution

    @property
    def is_marginal(self) -> bool:
        """Return True if :func:`judge` calls the mode marginal.

        A root (not a zero root) within its resolution of the axis or beyond it to the
        left that is not damped (:attr:`is_damped`), or a zero root of a rotor angle.
        """
        if self.kind == ModeKind.ZERO:
            return self.rotor_angle
        return self.eigenvalue.real <= self.resolution and not self.is_damped


@dataclasses.dataclass(frozen=True)
class Verdict:
    """The verdict of :func:`judge` about a list of modes."""

    verdict: Stability
    reason: str
    spectral_abscissa: float
    slowest_mode: str
    marginal_modes: list
    #: the resolution of the slowest mode's root (its |Re| within it prints as 0)
    slowest_resolution: float


# -- modes at an operating point -------------------------------------------------------------
def sensitivities(lin: LinearSystem) -> tuple:
    """(eigenvalues of A0, d lambda/d K_D at K_D = 0, weighted right eigenvectors).

    d lambda/d K_D by the one rule of every system (:func:`_one_rule`). A semisimple
    cluster of zero roots (K_S = 0 about solution II: the roots of psi and of the drive's
    slip) has no unique eigenvectors: its basis is the one that the perturbation
    -K_D b c^T diagonalizes (first-order degenerate perturbation theory), the one rule's.
    """
    lam, Vw = spectrum(lin, 0.0)
    return lam, _one_rule(lin, lam, Vw), Vw


def _one_rule(lin: LinearSystem, lam: np.ndarray, Vw: np.ndarray) -> np.ndarray:
    """Return d lambda/d K_D of the roots ``lam`` (vectors ``Vw``) by the one rule.

    :func:`~gyro_rotor.linear.spectrum.zero_K_sensitivities` (the resting space out, the
    rest by perturbation theory on the reduced matrix), its roots assigned to ``lam`` by
    eigenvalue and eigenvector (energy-weighted; a state without energy, z at K_S = 0,
    counted unweighted). The vectors of a cluster of zero roots (but the cyclic z's,
    appended last by :func:`spectrum`) are replaced in place by the rule's, the basis
    the perturbation diagonalizes, which the mode names follow.
    """
    from scipy.optimize import linear_sum_assignment
    lam1, d1, V1, _, _ = zero_K_sensitivities(lin.A0, np.outer(lin.b, lin.c))
    w = np.where(lin.weights > 0, lin.weights, 1.0)
    U1 = unit(V1 * w[:, None])
    scale = max(float(np.abs(lam).max(initial=0.0)), 1.0)
    cost = (np.abs(lam[:, None] - lam1[None, :]) / scale
            + 1.0 - np.abs(Vw.conj().T @ U1))
    rows, cols = linear_sum_assignment(cost)
    d = np.empty(len(lam), dtype=complex)
    d[rows] = d1[cols]
    last = len(lam) - 1 if _cyclic_z(lin) is not None else None
    at_zero = zero_within_roundoff(lin, lam)
    zero = [k for k, j in enumerate(rows) if at_zero[j] and j != last]
    if len(zero) > 1:
        Vw[:, rows[zero]] = unit(V1[:, cols[zero]] * lin.weights[:, None])
    return d


def zero_within_roundoff(lin: LinearSystem, lam: np.ndarray) -> np.ndarray:
    """Return which roots ``lam`` of A0 are 0 within their own round-off.

    A root is 0 when its modulus is within its resolution (condition number x the scale
    of balanced A0, the matrix LAPACK's eig factors: :func:`~gyro_rotor.linear.roundoff.
    resolution`), not within a fraction of ||A0||: a stiff drive (K_S = 1e12) makes ||A0||
    1.8e14 while the twist is 25.8 rad/s and its round-off 1.7e-5 rad/s.
    """
    lam_r, res_r = resolution(lin.A0, balanced=True)
    return np.abs(lam) <= res_r[nearest(lam_r, lam)]


def _modes_from(lin, lam_K, names, lam0, d0, tol_re) -> list:
    """Mode objects: one per name (upper eigenvalue), or per real root of a split pair."""
    by_name: dict = {}
    for j, nm in enumerate(names):
        by_name.setdefault(nm, []).append(j)
    # a pair is complex beyond its own round-off (condition number x the scale of the
    # matrix the roots come from: balanced A, or A0 for the pencil), not beyond a scale of
    # the whole matrix: a stiff drive (K_S = 1e12) makes ||A0|| 1.8e14 while the twist is
    # 25.8 rad/s
    if by_pencil(lin, lin.params.K_D):
        lam_r, res_r = resolution(lin.A, scale=max(np.linalg.norm(lin.A0), 1.0))
    else:
        lam_r, res_r = resolution(lin.A, balanced=True)

    def complex_pair(z: complex) -> bool:
        return abs(z.imag) > res_r[nearest(lam_r, z)[0]]
    out = []
    for nm, idx in by_name.items():
        lams = lam_K[idx]
        if nm in STRUCTURAL:
            groups = [(nm, idx[0], ModeKind.ZERO)]
        elif len(idx) == 2 and complex_pair(complex(lams[0])):
            j = idx[int(np.argmax(lams.imag))]
            groups = [(nm, j, ModeKind.OSCILLATORY)]
        elif len(idx) == 2:
            slow, fast = sorted(idx, key=lambda i: -lam_K[i].real)
            groups = [(f'{nm} (slow real)', slow, ModeKind.REAL),
                      (f'{nm} (fast real)', fast, ModeKind.REAL)]
        else:
            groups = [(nm, j, ModeKind.REAL) for j in idx]
        for label, j, kind in groups:
            lamv = complex(lam_K[j])
            dre = float(d0[j].real)
            # provisional: :func:`classify` decides reach and damping (one rule)
            reached = kind != ModeKind.ZERO
            re = lamv.real
            zeta = -re / abs(lamv) if abs(re) > tol_re and kind != ModeKind.ZERO else 0.0
            out.append(Mode(
                name=label, eigenvalue=lamv, freq_hz=abs(lamv.imag) / (2 * math.pi),
                zeta=zeta,
                tau=(-1.0 / re) if re < -tol_re else math.inf, reached_by_drive=reached,
                dRe_dKD=dre, kind=kind, eigenvalue_K_D0=complex(lam0[j]), resolution=tol_re,
                rotor_angle=nm == ZERO_ROOT_Z))
    out.sort(key=lambda m: (m.kind == ModeKind.ZERO, -m.eigenvalue.real))
    return out


def _tracked_names(lin: LinearSystem, K_values: Sequence[float]):
    """Names at K_D = 0 and the eigenvalues tracked along ``K_values`` (starting at 0)."""
    lam0, d0, Vw = sensitivities(lin)
    names = _name_at_zero(lin, lam0, Vw, d0, zero_within_roundoff(lin, lam0))
    lam_path = track(lambda k: (lam0, Vw) if k == 0 else spectrum(lin, k), K_values, names,
                     log=True)
    return names, lam0, d0, lam_path


def _path_to(K_D: float, lin: LinearSystem, per_decade: int = 8) -> list:
    """0, then a log path to K_D that starts well below the characteristic K_D (K_ref)."""
    if K_D <= 0:
        return [0.0]
    lo = min(K_D * 1e-6, 1e-4 * K_ref(lin))
    return [0.0] + list(np.geomspace(lo, K_D, 6 * per_decade + 1))


def classify(ms: Sequence[Mode], sys, K=None) -> list:
    """Return the modes with reach and damping decided by the one rule of every system.

    ``sys``: the :class:`~gyro_rotor.linear.claims.DriveSystem` of every drive (A0 with
    every drive undamped), ``K`` each drive's damping (default its ``K_scene``). Reached
    (judged at K = 0, the exact rule): the root is not one of A(K) on the fixed subspace
    (:func:`~gyro_rotor.linear.claims.fixed_subspace`; it holds the structural zero
    roots and the modes of Hagedorn's exclusion). Damped: :func:`gyro_rotor.linear.claims.
    damped` (the rule of claim (b)); a reached root resolved only in 40 digits takes that
    value and its resolution. Each mode is matched to the nearest root (one-to-one); a
    reached root is never a zero root (kind REAL however small it is).
    """
    from scipy.optimize import linear_sum_assignment
    from gyro_rotor.linear import claims as cl
    K = np.asarray(sys.K_scene if K is None else K, dtype=float)
    U, V = cl.split(sys.A0, sys.C)
    dm = cl.damped(sys, K, V)
    A = sys.A0 - (sys.B * K) @ sys.C
    lam_u = np.linalg.eigvals(U.T @ A @ U) if U.shape[1] else np.zeros(0, complex)
    roots = np.concatenate([dm.lam, lam_u])
    n_v = len(dm.lam)
    lam_m = np.array([m.eigenvalue for m in ms], dtype=complex)
    cost = np.abs(lam_m[:, None] - roots[None, :])
    # a repeated root (two zero roots at K_S = K_D = 0) is told apart by d lambda/d K: a
    # root on the fixed subspace stays for every K (d = 0), so a mode that moves is never
    # matched to one there while a root of V with its eigenvalue is free
    d = np.array([m.dRe_dKD for m in ms], dtype=float)
    d_scale = max(1.0, float(np.nanmax(np.abs(d), initial=0.0)))
    moves = np.isfinite(d) & (np.abs(d) > 1e-9 * d_scale)
    scale = max(1.0, float(np.abs(roots).max(initial=0.0)))
    cost[np.ix_(moves, np.arange(len(roots)) >= n_v)] += 1e-6 * scale
    r, c = linear_sum_assignment(cost)
    out = list(ms)
    for i, j in zip(r, c):
        m = ms[i]
        if j >= n_v:
            out[i] = dataclasses.replace(m, reached_by_drive=False, damped=False)
            continue
        # a root that moves with K is never a structural zero root, however small (a slow
        # root -K_S/K at a large K)
        kind = ModeKind.REAL if m.kind == ModeKind.ZERO else m.kind
        m = dataclasses.replace(m, kind=kind, rotor_angle=False)
        lam, res = complex(m.eigenvalue), float(dm.res[j])
        if dm.fine[j]:
            z = complex(roots[j])
            im = 0.0 if m.kind == ModeKind.REAL else abs(z.imag)
            lam = complex(z.real, im if lam.imag >= 0 else -im)
        ok = bool(dm.damped[j])
        re = lam.real
        out[i] = dataclasses.replace(
            m, eigenvalue=lam, reached_by_drive=True, damped=ok, resolution=res,
            zeta=-re / abs(lam) if abs(re) > res else 0.0,
            tau=-1.0 / re if re < -res else math.inf)
    return out


def judge(ms: Sequence[Mode], undamped_drives: bool) -> Verdict:
    """Judge modes: unstable, marginal or asymptotically stable, with the reason.

    'unstable' if a root (other than a zero root) has Re beyond its resolution;
    'marginal' if one is not damped (:attr:`Mode.is_damped`, the one rule of
    :func:`classify`; the reason names the modes and whether the drive damping reaches
    them; ``undamped_drives``: every K_D is 0), or if a zero root's eigenvector is a rotor
    angle (no drive stiffness, K_S = 0: the theorem needs self-stable drives and promises
    stability in the rotor angles); 'asymptotically stable' otherwise. Any other zero root
    (a cyclic coordinate: a neighbouring steady motion of the family) is listed but not
    judged: the paper's stability is in the velocities and the rotor angles. A complex
    pair counts once (its root with Im >= 0).
    """
    ms = [m for m in ms if m.eigenvalue.imag >= -m.resolution]
    judged = [m for m in ms if m.kind != ModeKind.ZERO]
    neutral = [m for m in ms if m.kind == ModeKind.ZERO and m.is_marginal]
    top = max(judged, key=lambda m: m.eigenvalue.real, default=None)
    absc, slowest, res = ((top.eigenvalue.real, top.name, top.resolution) if top
                          else (-math.inf, '', 0.0))
    unstable = [m for m in judged if m.eigenvalue.real > m.resolution]
    marginal = [m for m in judged if m.is_marginal]
    if unstable:
        verdict, reason = Stability.UNSTABLE, 'growing: ' + ', '.join(
            f'{m.name} (Re = {m.eigenvalue.real:+.3e} 1/s)' for m in unstable)
    elif marginal or neutral:
        verdict, reason = Stability.MARGINAL, '; '.join(
            [f'{m.name}: ' + ('no drive damping (K_D = 0)' if m.reached_by_drive
                              and undamped_drives else 'on the imaginary axis'
                              if m.reached_by_drive else 'not reached by the drive damping '
                              "(on the fixed subspace; Hagedorn's exclusion)")
             for m in marginal]
            + [f'{m.name}: rotor angle neutral (K_S = 0: no drive stiffness)'
               for m in neutral])
    else:
        but = ' except the cyclic zero roots' if len(judged) < len(ms) else ''
        verdict, reason = (Stability.ASYMPTOTICALLY_STABLE, f'every root{but} has Re < 0; '
                           f'slowest: {slowest} (Re = {absc:.4g} 1/s)')
    return Verdict(verdict, reason, float(absc), slowest,
                   [m.name for m in marginal + neutral], res)


def named_modes(lin: LinearSystem, K_D: float | None, sys) -> list:
    """Return the named, classified modes of the analytic linearization ``lin`` at ``K_D``.

    Named at K_D = 0 by modal energy and tracked to ``K_D`` (None: ``lin``'s own) by
    eigenvector continuity; reach and damping by :func:`classify` (the one rule) on ``sys``,
    its :class:`~gyro_rotor.linear.claims.DriveSystem`.
    """
    K_D = lin.params.K_D if K_D is None else float(K_D)
    if not (K_D >= 0 and math.isfinite(K_D)):
        raise ParameterError(f'K_D must be finite and not negative, got {K_D!r} N m s/rad')
    if K_D != lin.params.K_D:
        lin = dataclasses.replace(lin, params=lin.params.replace(K_D=K_D), A=lin.with_K_D(K_D))
    names, lam0, d0, lam_path = _tracked_names(lin, _path_to(K_D, lin))
    ms = _modes_from(lin, lam_path[-1], names, lam0, d0, floor(lin.A0))
    return classify(ms, sys, [K_D])
