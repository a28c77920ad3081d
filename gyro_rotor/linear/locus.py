"""Root locus over the drive damping K_D of any scene, and the paper's claims (a) to (d) on it.

``A(K) = A0 - K b c'`` (:mod:`gyro_rotor.linear.system`): the drive damping is a feedback of
the rotors' lag rates, so the root locus over K is a classic one. At K = 0 the roots are
those of A0; as K -> infinity m roots go to -infinity like -K c'b, m to 0 like 1/K and the
rest to the spectrum of the locked system (Magnus 1980, section 4 and figure 2). The
branches are followed over the K grid by eigenvector continuity and named as the
linearization names its modes (:func:`gyro_rotor.linear.system.modes`: the centrifuge's
nutation, housing twist, ...; a system file's by their dominant coordinate). The claims are
judged by their meaning in :mod:`gyro_rotor.linear.claims`.
"""

from __future__ import annotations

import dataclasses
import math

from gyro_rotor.errors import ParameterError
from gyro_rotor.linear.spectrum import K_ref, track, unit_eig
from gyro_rotor.linear.system import check_claims, Linearization, name_roots
import numpy as np

__all__ = ['RootLocus', 'root_locus', 'check_claims', 'regimes', 'name_roots', 'K_ref',
           'check_grid', 'REACH_TOL']


@dataclasses.dataclass(frozen=True)
class RootLocus:
    """Tracked roots over K: ``eigenvalues[i, j]`` at ``K_D[i]`` on branch ``labels[j]``.

    ``locked`` are the finite K -> infinity limits (the locked system's spectrum) with
    ``locked_res`` their resolutions and ``locked_labels`` the branch that ends at each.
    """

    lin: Linearization
    K_D: np.ndarray
    eigenvalues: np.ndarray
    labels: list
    locked: np.ndarray
    locked_res: np.ndarray
    locked_labels: list

    def to_rows(self) -> list:
        """Rows (K_D, branch, mode, Re, Im) for CSV."""
        return [(float(k), j, self.labels[j], float(lam.real), float(lam.imag))
                for k, row in zip(self.K_D, self.eigenvalues) for j, lam in enumerate(row)]

    def as_dict(self) -> dict:
        """JSON-friendly dict."""
        return {'state_names': list(self.lin.names), 'K_D': self.K_D.tolist(),
                'labels': self.labels, 're': self.eigenvalues.real.tolist(),
                'im': self.eigenvalues.imag.tolist(),
                'asymptotes': {'locked_re': self.locked.real.tolist(),
                               'locked_im': self.locked.imag.tolist(),
                               'locked_labels': self.locked_labels,
                               'fast_gains': self.lin.fast_rates.tolist()}}


def check_grid(grid) -> np.ndarray:
    """Return the K_D grid as an array; ParameterError unless finite, >= 0, increasing."""
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


#: the grid must end where every finite root is within this fraction of the spectral scale
#: of its limit (and the m fast roots beyond 10 times that scale)
REACH_TOL = 0.01


def _reach(lin: Linearization, K: float, limits: np.ndarray) -> float:
    """Return the distance of the roots at K from their K -> infinity limits.

    Relative to the spectral scale max(|limits|, |eig A(0)|); at least 1 while the m fast
    roots are not yet beyond 10 times that scale.
    """
    from scipy.optimize import linear_sum_assignment
    lam = lin.eig(K)
    fast = np.argsort(lam.real)[:len(lin.vary)]
    D = np.abs(np.delete(lam, fast)[:, None] - limits[None, :])
    r, c = linear_sum_assignment(D)
    scale = max(float(np.abs(limits).max(initial=0.0)), float(np.abs(lin.eig(0.0)).max()), 1e-12)
    return max(float(D[r, c].max(initial=0.0)) / scale,
               1.0 if -lam[fast].real.max() < 10 * scale else 0.0)


def root_locus(lin: Linearization, K_D_grid) -> RootLocus:
    """Follow the roots of A(K) over the grid by eigenvector continuity, named, and their limits.

    Raises ParameterError for a grid that is negative, unordered, beyond double precision
    or that does not reach large K_D (roots further than REACH_TOL from their limits).
    """
    from scipy.optimize import linear_sum_assignment
    from gyro_rotor.linear.roundoff import resolution
    grid = check_grid(K_D_grid)
    if np.finfo(float).eps * grid[-1] * np.linalg.norm(lin.b @ lin.c.T) > np.linalg.norm(lin.A0):
        raise ParameterError(f'K_D = {float(grid[-1])!r} N m s/rad is too large for the linear '
                             "analysis: the round-off of K_D b c' exceeds A0 in double precision")
    locked, res = resolution(lin.A_locked)
    limits = np.concatenate([locked, np.zeros(len(lin.vary))])
    far = _reach(lin, grid[-1], limits)
    if far > REACH_TOL:
        need = next((k for k in grid[-1] * 10.0 ** np.arange(1, 16)
                     if _reach(lin, k, limits) <= REACH_TOL), math.inf)
        raise ParameterError(
            f'the K_D grid ends at {grid[-1]:.4g} N m s/rad, which does not reach large K_D: '
            f'the roots there are still {100 * far:.3g}% (of the spectral scale) away from '
            f'their K_D -> infinity limits; extend it to at least {need:.3g}')

    def eig(K):
        return unit_eig(lin.A(K))
    names = name_roots(lin, eig(grid[0])[0], grid[0])
    path = track(eig, grid, names, log=True)
    rows, cols = linear_sum_assignment(np.abs(path[-1][:, None] - locked[None, :]))
    ends = [''] * len(locked)
    for r, c in zip(rows, cols):
        ends[c] = names[r]
    return RootLocus(lin=lin, K_D=grid, eigenvalues=path, labels=names, locked=locked,
                     locked_res=res, locked_labels=ends)


def regimes(res) -> list:
    """Return the K_D intervals between meetings, each with its number of real moving roots.

    ``res``: a :class:`~gyro_rotor.linear.claims.ClaimsResult` (its continuation's counts).
    """
    K, counts = res.locus.K, res.locus.real_counts
    edges = [0.0] + [mt.K_D for mt in res.meetings] + [math.inf]
    return [{'K_D_from': a, 'K_D_to': b, 'real_roots':
             int(counts[min(int(np.searchsorted(K, a, side='right')), len(K) - 1)])}
            for a, b in zip(edges[:-1], edges[1:])]
