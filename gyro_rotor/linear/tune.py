"""The best drive damping K_D for a given K_S (the paper's closing remark): ``gyro-rotor tune``.

One objective on any :class:`~gyro_rotor.linear.system.Linearization`: the slowest decay
rate -max Re(lambda) of A(K) = A_cons - K B C' (every drive at the same K) over the roots
the drive damping reaches (not the structural zero roots, not the roots the drives do not
reach: the fixed subspace, :func:`gyro_rotor.linear.claims.split`; their rate is 0 for
every K), maximized over K: a log grid scan, then the root
of the slowest root's d Re/d K = -(w^H B C' v)/(w^H v) (left and right eigenvectors).
"""

from __future__ import annotations

import collections
import dataclasses
import math

from gyro_rotor.errors import ParameterError
from gyro_rotor.linear.roundoff import resolution
from gyro_rotor.linear.spectrum import drive_sensitivity
from gyro_rotor.linear.stability import ModeKind
import numpy as np

__all__ = ['TuneResult', 'tune']


@dataclasses.dataclass(frozen=True)
class TuneResult:
    """Best K_D for the slowest decay (the paper's closing remark) and its sensitivity.

    ``rate_at``: the rate at 0.5, 0.9, 1.1, 2 x the best K_D [1/s]; ``relative_rate``: the
    rate at 0.5 and 2 x the best K_D over the best (how flat the optimum is: 1 flat, near
    0 sharp); ``K_D_current``: the drives' own K_D.
    """

    K_D_best: float
    rate_best: float
    tau_best: float
    governing_modes: list
    excluded_modes: list
    rate_at: dict
    K_D_range_90: tuple
    relative_rate: dict
    K_D_current: list
    rate_current: float


def tune(lin) -> TuneResult:
    """Return the common K_D that maximizes the slowest decay rate of the judged roots.

    Sensitivity: the rate at 0.5, 0.9, 1.1, 2 times the optimum, that at 0.5 and 2 times
    relative to the best, and the K_D range where the rate stays within 90% of the best
    (on the grid). The rate at the scene's own K_D is that of its modes (:func:`modes`).
    """
    from scipy.linalg import eig
    from scipy.optimize import brentq
    from gyro_rotor.linear.claims import split
    from gyro_rotor.linear.spectrum import K_ref
    from gyro_rotor.linear.system import modes
    here = [m for m in modes(lin) if m.eigenvalue.imag >= -m.resolution]
    if all(m.kind == ModeKind.ZERO or not m.reached_by_drive for m in here):
        raise ParameterError('no mode is reached by the drive damping: K_D cannot be tuned')
    # the judged roots: those of A(K) on the complement V of the fixed subspace, the one
    # rule of reach (:func:`gyro_rotor.linear.stability.classify`), for every K
    V = split(lin.A_cons, lin.c_all.T)[1]
    A0v, BCv = V.T @ lin.A_cons @ V, V.T @ lin.b_all @ (lin.c_all.T @ V)

    def rate(K: float) -> float:
        return float(-np.linalg.eigvals(A0v - K * BCv).real.max())

    def slope(u: float) -> float:
        """Return d rate/d ln K = -K d Re/d K of the slowest judged root."""
        A = A0v - math.exp(u) * BCv
        lam, W, Vr = eig(A, left=True, right=True)
        j = [int(np.argmax(lam.real))]
        return -math.exp(u) * float(drive_sensitivity(A, BCv, lam[j], W[:, j], Vr[:, j])[0].real)
    grid = np.geomspace(1e-6 * K_ref(lin), 1e4 * K_ref(lin), 401)
    rates = np.array([rate(K) for K in grid])
    i = int(np.argmax(rates))
    lo, hi = math.log(grid[max(i - 1, 0)]), math.log(grid[min(i + 1, len(grid) - 1)])
    # the maximum: where the slope of the slowest root changes sign (smooth, or a kink
    # where two roots meet), not a search on the flat rate itself (its round-off)
    K_best = (math.exp(brentq(slope, lo, hi, xtol=1e-12)) if slope(lo) > 0 > slope(hi)
              else float(grid[i]))
    r_best = rate(K_best)
    if not r_best > 0:
        _refuse(lin, K_best, modes)
    # a best rate within the round-off of its root is no rate (a stiff drive, K_S = 1e9:
    # "best" 3.9e-8 1/s beside -1.9e-7 at 0.9 x best, the round-off about 1e-4)
    lam_b, res_b = resolution(A0v - K_best * BCv, scale=max(np.linalg.norm(A0v), 1.0))
    noise = float(res_b[int(np.argmax(lam_b.real))])
    if r_best <= noise:
        raise ParameterError(
            f'the decay rates over K_D are within their round-off: the best found, '
            f'{r_best:.3g} 1/s at K_D = {K_best:.4g} N m s/rad, against {noise:.2g} 1/s '
            f'(||A0|| = {np.linalg.norm(A0v):.3g} 1/s: a drive this stiff against the '
            'structure leaves its modes almost undamped): K_D cannot be tuned in double '
            'precision')
    gov = sorted({m.name for m in modes(lin, K_best)
                  if m.kind != ModeKind.ZERO and m.reached_by_drive
                  and -m.eigenvalue.real <= r_best * (1 + 1e-6)})
    # the 90 % range: from the outermost grid points at 90 % of the best (K_best itself
    # where a peak is narrower than the grid: a kink where two roots meet) to the crossing
    # towards the next grid point out, which is below 90 %
    ok = grid[rates >= 0.9 * r_best]
    K_lo, K_hi = min(ok.min(initial=K_best), K_best), max(ok.max(initial=K_best), K_best)

    def edge(K_in: float, out: np.ndarray) -> float:
        """Return where the rate crosses 90% of the best between K_in and out's grid point."""
        if not out.size:
            return K_in
        return brentq(lambda K: rate(K) - 0.9 * r_best, *sorted((K_in, float(out[0]))),
                      xtol=1e-12 * K_in)
    rate_at = {f'{f:g}': rate(K_best * f) for f in (0.5, 0.9, 1.1, 2.0)}
    now = [m.eigenvalue.real for m in here if m.kind != ModeKind.ZERO and m.reached_by_drive]
    return TuneResult(K_D_best=K_best, rate_best=r_best,
                      tau_best=1.0 / r_best if r_best > 0 else math.inf,
                      governing_modes=gov, excluded_modes=_not_judged(here),
                      rate_at=rate_at,
                      relative_rate={f: rate_at[f] / r_best for f in ('0.5', '2')},
                      K_D_range_90=(edge(K_lo, grid[grid < K_lo][::-1]),
                                    edge(K_hi, grid[grid > K_hi])),
                      K_D_current=lin.K_all.tolist(),
                      rate_current=-max(now) if np.any(lin.K_all > 0) else 0.0)


def _not_judged(here) -> list:
    """Return the names of the modes ``tune`` does not judge (zero, or not reached).

    An oscillatory one with its frequency; a repeated root once, with its multiplicity (a
    cyclic coordinate's double zero root).
    """
    names = collections.Counter(
        m.name + (f' ({m.freq_hz:.4g} Hz)' if m.kind == ModeKind.OSCILLATORY else '')
        for m in here if m.kind == ModeKind.ZERO or not m.reached_by_drive)
    return [f'{name} ({n} roots)' if n > 1 else name for name, n in names.items()]


def _refuse(lin, K: float, modes) -> None:
    """Raise the one error of a system no common K_D makes decay (the theorem's premise fails).

    ``K`` is the best K_D found: the slowest judged root there is named, with its real part
    against its resolution (growing, or on the imaginary axis).
    """
    judged = [m for m in modes(lin, K) if m.kind != ModeKind.ZERO and m.reached_by_drive]
    m = max(judged, key=lambda x: x.eigenvalue.real)
    lam = m.eigenvalue
    root = (f'lambda = {lam.real:+.6g}{lam.imag:+.6g}j' if lam.imag else
            f'lambda = {lam.real:+.6g}') + f' 1/s ({m.name})'
    if lam.real > m.resolution:
        raise ParameterError(
            f'unstable for every K_D: even at the best K_D = {K:.4g} N m s/rad the root '
            f'{root} grows (doubling in {math.log(2) / lam.real:.4g} s): '
            "the theorem's premise fails (E*, eq. 13, is not positive definite about this "
            'motion), K_D cannot be tuned')
    raise ParameterError(
        f'no K_D makes every reached root decay: at the best K_D = {K:.4g} N m s/rad the root '
        f'{root} stays on the imaginary axis (|Re| within its resolution '
        f'{m.resolution:.2g} 1/s): K_D cannot be tuned')
