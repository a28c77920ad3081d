"""The best drive damping K_D for a given K_S (the paper's closing remark): ``gyro-rotor tune``.

The slowest decay rate -max Re(lambda) over the modes the drive damping reaches, maximized
over K_D on the tracked spectrum (:mod:`gyro_rotor.linear.stability` names the modes,
:mod:`gyro_rotor.linear.locus` gives the K_D grid).
"""

from __future__ import annotations

import dataclasses
import math

from gyro_rotor.core.params import RotorParams
from gyro_rotor.core.steady import SteadyMotion
from gyro_rotor.errors import ParameterError
from gyro_rotor.linear.linearize import linearize
from gyro_rotor.linear.locus import check_grid, default_grid
from gyro_rotor.linear.spectrum import spectrum, STRUCTURAL, TOL_SENS_REL, track
from gyro_rotor.linear.stability import _path_to, _tracked_names, sensitivities
import numpy as np

__all__ = ['TuneResult', 'best_K_D']


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
    grid = default_grid(params) if K_D_grid is None else check_grid(K_D_grid)
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
