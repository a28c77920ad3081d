"""Decay of E* toward its limit: E*_inf fitted from the data with the predicted rates.

The paper promises asymptotic stability in the velocities and rotor angles, not in every
coordinate: after a kick the motion may settle on a neighbouring steady motion of the
family (the cyclic psi), so E*_inf is not known in advance. E* - E*_inf is a quadratic
form of the deviations (eq. 13); with the deviations a sum of modes exp(lambda_i t) it is
a sum of terms exp((lambda_i + lambda_j) t) and exp((lambda_i + conj lambda_j) t). Their
exponents are known from the prediction, so E*(t) = E_inf + sum of those terms is linear
in E_inf and the term amplitudes: a least-squares fit gives E_inf and its standard error
(:func:`fit_energy`). The measured rate is the slope of log(E* - E_inf) over the window,
its interval that of E_inf +- 2 standard errors.

Pure numpy.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Sequence

import numpy as np

_TWO_PI = 2.0 * math.pi

__all__ = ['EnergyFit', 'fit_energy', 'envelope_decay_rate', 'SIGMAS']

#: a non-oscillating term whose exponent times the window is below this changes by less than
#: 5 % over the window, nearly collinear with a constant: it is merged into E_inf (the
#: nutation about solution II, 2 |Re| = 0.0035 1/s over 8 s: 0.028)
RESOLVABLE = 0.05
#: E_inf is varied by this many standard errors for the rate interval
SIGMAS = 2.0
#: a term decaying by more than exp(-MAX_DECADES_E) over the window is no column (it is an
#: impulse at the window's start, indistinguishable from noise)
MAX_EXPONENT = 60.0


@dataclasses.dataclass(frozen=True)
class EnergyFit:
    """Result of :func:`fit_energy` (rates in 1/s, NaN where not determined)."""

    t0: float
    E_inf: float
    E_inf_sigma: float
    rate: float
    rate_lo: float
    rate_hi: float
    rel_residual: float
    spread: float
    trend: float
    span: float
    exponents: tuple
    coef: tuple

    def curve(self, t: np.ndarray) -> np.ndarray:
        """Return the fitted E*(t) (E_inf plus the predicted terms)."""
        tau = np.asarray(t, dtype=float) - self.t0
        X = _basis(tau, self.exponents)
        return self.E_inf + self.trend * (tau - self.span) + X @ np.asarray(self.coef)


def _exponents(eigs: Sequence[complex]) -> list[complex]:
    """Distinct exponents lambda_i + lambda_j, lambda_i + conj lambda_j (Im >= 0 kept)."""
    lam = [complex(z) for z in eigs]
    out: list[complex] = []
    for i, a in enumerate(lam):
        for b in lam[i:]:
            for mu in (a + b, a + b.conjugate(), a.conjugate() + b):
                mu = complex(mu.real, abs(mu.imag))
                if abs(mu) <= 1e-12 * max(1.0, abs(a) + abs(b)):
                    continue          # a constant: that is E_inf itself
                if all(abs(mu - m) > 1e-9 * max(1.0, abs(mu)) for m in out):
                    out.append(mu)
    return out


def _basis(tau: np.ndarray, exponents: Sequence[complex]) -> np.ndarray:
    cols = []
    for mu in exponents:
        env = np.exp(mu.real * tau)
        if abs(mu.imag) <= 1e-12:
            cols.append(env)
        else:
            cols += [env * np.cos(mu.imag * tau), env * np.sin(mu.imag * tau)]
    return np.column_stack(cols) if cols else np.zeros((len(tau), 0))


def _log_slope_rate(t: np.ndarray, dE: np.ndarray) -> float:
    """-slope of log(dE) over t (NaN unless dE > 0 at 90 % of the points)."""
    ok = dE > 0
    if ok.sum() < max(10, 0.9 * len(dE)):
        return math.nan
    return float(-np.polyfit(t[ok], np.log(dE[ok]), 1)[0])


def fit_energy(t: np.ndarray, E: np.ndarray, eigs: Sequence[complex]) -> EnergyFit:
    """Fit E*(t) = E_inf + sum of terms with the exponents of the predicted ``eigs``.

    ``eigs`` are the predicted eigenvalues with Im >= 0 (one of each conjugate pair),
    without the structural zero roots. Non-oscillating terms too slow to resolve in the
    window (:data:`RESOLVABLE`) are merged into E_inf plus a straight line (``trend``, J/s,
    E_inf being their value at the window's end); terms that die within the window
    (exponent times span below -:data:`MAX_EXPONENT`) are left out. The standard error of
    E_inf is that of ordinary least squares (residuals taken as independent: an
    underestimate for correlated noise, so the rate interval is not wider than it should be).
    """
    t = np.asarray(t, dtype=float)
    E = np.asarray(E, dtype=float)
    t0 = float(t[0])
    tau = t - t0
    span = float(tau[-1]) if len(tau) else 0.0
    alive = [mu for mu in _exponents(eigs) if mu.real * span > -MAX_EXPONENT]
    slow = [mu for mu in alive if abs(mu.imag) * span < _TWO_PI
            and abs(mu.real) * span < RESOLVABLE]
    mus = [mu for mu in alive if mu not in slow]
    # the slow terms merged into E_inf: their first order, a straight line, stays a column
    # (measured from the window's end, so that E_inf is the slow part's value there)
    cols = [np.ones_like(tau)] + ([tau - span] if slow else [])
    X = np.column_stack(cols + [_basis(tau, mus)])
    scale = np.linalg.norm(X, axis=0)
    scale[scale == 0] = 1.0
    Xs = X / scale
    coef, _, rank, _ = np.linalg.lstsq(Xs, E - E[-1], rcond=1e-12)
    res = (E - E[-1]) - Xs @ coef
    dof = max(len(E) - rank, 1)
    s2 = float(res @ res) / dof
    # covariance of the scaled coefficients via the pseudo-inverse (rank-revealing SVD)
    _, S, Vt = np.linalg.svd(Xs, full_matrices=False)
    keep = S > 1e-12 * S[0]
    cov00 = float(np.sum((Vt[keep, 0] / S[keep]) ** 2)) * s2
    coef = coef / scale
    E_inf = float(coef[0] + E[-1])
    trend = float(coef[1]) if slow else 0.0
    sigma = math.sqrt(max(cov00, 0.0))
    spread = float(np.std(E))
    rel = float(np.sqrt(np.mean(res * res)) / spread) if spread > 0 else 0.0
    dE = E - E_inf - trend * (tau - span)
    rate = _log_slope_rate(t, dE)
    lo = _log_slope_rate(t, dE + SIGMAS * sigma)    # a lower limit: slower decay
    hi = _log_slope_rate(t, dE - SIGMAS * sigma)
    if not math.isfinite(hi) and math.isfinite(rate):
        hi = math.inf           # E_inf + 2 sigma reaches the data: any faster rate fits
    return EnergyFit(t0=t0, E_inf=E_inf, E_inf_sigma=sigma, rate=rate, rate_lo=lo,
                     rate_hi=hi, rel_residual=rel, spread=spread, trend=trend, span=span,
                     exponents=tuple(mus), coef=tuple(float(c) for c in coef[len(cols):]))


def envelope_decay_rate(t: np.ndarray, D: np.ndarray, freqs_hz: Sequence[float]) -> float:
    """-slope of the log of the deviation envelope (chunk maxima of the normalized norm)."""
    scale = np.sqrt(np.mean(D * D, axis=0))
    scale[scale == 0] = 1.0
    n = np.sqrt(np.sum((D / scale) ** 2, axis=1))
    fmin = min((f for f in freqs_hz if f > 0), default=1.0)
    chunk = max(1.0 / fmin, 0.2)
    edges = np.arange(t[0], t[-1] + 1e-12, chunk)
    tc, mc = [], []
    for a in edges:
        sel = (t >= a) & (t < a + chunk)
        if sel.sum() >= 3:
            i = np.argmax(n[sel])
            tc.append(t[sel][i])
            mc.append(n[sel][i])
    mc = np.asarray(mc)
    if len(mc) < 3 or np.any(mc <= 0) or not np.all(np.isfinite(mc)):
        return math.nan
    return float(-np.polyfit(tc, np.log(mc), 1)[0])
