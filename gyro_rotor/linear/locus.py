"""Root locus over the drive damping K_D and the paper's claims (a) to (d) on it.

``A(K_D) = A0 - K_D b c^T`` (:mod:`gyro_rotor.linear.linearize`): the drive damping is a
rank-one feedback of the rotor's lag rate, so the root locus over K_D is a classic one. At
K_D = 0 the roots are those of A0; as K_D -> infinity, n - 1 roots tend to the zeros of
c^T (sI - A0)^-1 b (the motion with the rotor locked to the stator) and one tends to
-K_D c^T b -> -infinity (Magnus 1980, section 4 and figure 2). Branch names come from
:mod:`gyro_rotor.linear.stability` (named at K_D = 0, followed by continuity); the claims
are judged by their meaning in :mod:`gyro_rotor.linear.claims`.
"""

from __future__ import annotations

import dataclasses
import math

from gyro_rotor.core.params import RotorParams
from gyro_rotor.errors import ParameterError
from gyro_rotor.linear.linearize import LinearSystem
from gyro_rotor.linear.spectrum import spectrum
from gyro_rotor.linear.stability import _K_ref, _tracked_names
import numpy as np

__all__ = ['RootLocus', 'ClaimsReport', 'root_locus', 'check_claims', 'asymptotes',
           'default_grid', 'check_grid', 'REACH_TOL']


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


# -- root locus -------------------------------------------------------------------------------
def default_grid(params: RotorParams, per_decade: int = 40) -> np.ndarray:
    """[0] plus a log grid from 1e-4 to 1e3 times 2 sqrt(K_S C_R C_M/(C_R + C_M))."""
    K = _K_ref(params)
    return np.concatenate([[0.0], np.geomspace(1e-4 * K, 1e3 * K, 7 * per_decade + 1)])


def asymptotes(lin: LinearSystem) -> tuple:
    """K_D -> infinity: (finite zeros (n-1,), gain g of the fast root -g K_D)."""
    lam, _ = spectrum(lin, math.inf)
    return lam, float(lin.c @ lin.b)


def check_grid(grid) -> np.ndarray:
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
    grid = default_grid(lin.params) if K_D_grid is None else check_grid(K_D_grid)
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


def drive_system(lin: LinearSystem):
    """Return the centrifuge linearization as a :class:`~gyro_rotor.linear.claims.DriveSystem`.

    One drive: ``B = b``, ``C = c^T``, the scene's K_D
    (:meth:`gyro_rotor.linear.system.Linearization.drive_system`).
    """
    from gyro_rotor.linear.system import from_analytic
    return from_analytic(lin).drive_system()


def check_claims(lin: LinearSystem, K_D_grid=None) -> ClaimsReport:
    """Check the paper's claims (a) to (d) for this linearization, by their meaning.

    The one checker of every system, :func:`gyro_rotor.linear.claims.check`, on
    :func:`drive_system`; the root locus on ``K_D_grid`` (named branches) is for the plot
    and the table. ``K_D_star``/``breakaway`` are the last break-in (the pair that splits
    toward 0 and -infinity); ``meetings`` holds all of them, each with its kind.
    """
    from gyro_rotor.linear import claims as cl
    loc = root_locus(lin, K_D_grid)
    res = cl.check(drive_system(lin))
    claims = dict(res.claims)
    if res.unreached.size:
        lam0 = loc.eigenvalues[0] if loc.K_D[0] == 0 else spectrum(lin, 0.0)[0]
        names = sorted({loc.labels[int(np.argmin(np.abs(lam0 - u)))] for u in res.unreached})
        b = claims['b']
        claims['b'] = dataclasses.replace(
            b, exception=b.exception.replace('roots not reached by the drive',
                                             f'roots not reached by the drive '
                                             f'({", ".join(names)})'))
    ins = [mt for mt in res.meetings if mt.kind is cl.MeetingKind.BREAK_IN]
    K_star = ins[-1].K_D if ins else None
    lam_star = ins[-1].lam if ins else None
    regimes = []
    if K_star is not None:
        regimes.append({'regime': 'the pair that meets last is complex (oscillatory)',
                        'K_D_from': 0.0, 'K_D_to': K_star})
        regimes.append({'regime': 'that pair real (overdamped)', 'K_D_from': K_star,
                        'K_D_to': math.inf})
    return ClaimsReport(claims=claims, K_D_star=K_star, breakaway=lam_star, regimes=regimes,
                        locus=loc, meetings=list(res.meetings))
