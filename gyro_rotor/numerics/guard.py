"""The energy-identity guard: one rule for the live simulation, ``simulate`` and the analysis.

Along a solution E* + D is constant (eq. 17), so the energy-balance residual
r = E* + D - E_ref measures the integration error. The integration counts as diverged
where E* is not finite or

    |r| > max(limit, RELATIVE_LIMIT x max(|E*|, |E_ref|))

``limit`` is a bound in joules (``max_residual`` of the live simulation and of
``gyro-rotor simulate``, ``diverge_residual`` of the analysis); the relative term takes
over only where the energy has grown far beyond it: the error of E* grows with E*, and
1e-5 J of 1e14 J of a statically unstable system's growing motion is no divergence of the
integration but growth with a sound energy identity. A blow-up of the integration makes
|r| of the order of |E*| itself and breaks the identity at every energy. Pure numpy.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ['RELATIVE_LIMIT', 'bound', 'excess', 'breaks_identity', 'first_break',
           'describe_break']

#: the identity holds to this fraction of max(|E*|, |E_ref|) in every integration at the
#: package's tolerances (rtol <= 1e-6; a statically unstable system grown to 1e14 J keeps it
#: to 1e-11): beyond both it and the limit in joules, the integration has diverged
RELATIVE_LIMIT = 1e-6


def bound(E_star, E_ref, limit: float):
    """Return the bound on |r|: max(limit, RELATIVE_LIMIT x max(|E*|, |E_ref|)) [J].

    Elementwise for arrays; NaN where E* is NaN.
    """
    if isinstance(E_star, float) and isinstance(E_ref, float):
        # one sample (the analysis, per sample): plain floats, no numpy call
        if math.isnan(E_star) or math.isnan(E_ref):
            return math.nan
        return max(limit, RELATIVE_LIMIT * max(abs(E_star), abs(E_ref)))
    with np.errstate(invalid='ignore'):
        return np.maximum(limit, RELATIVE_LIMIT * np.maximum(np.abs(E_star), np.abs(E_ref)))


def excess(residual, E_star, E_ref, limit: float):
    """Return |r| / :func:`bound`: the identity is broken where it exceeds 1."""
    if isinstance(residual, float):
        return abs(residual) / bound(E_star, E_ref, limit)
    with np.errstate(invalid='ignore', divide='ignore'):
        return np.abs(residual) / bound(E_star, E_ref, limit)


def breaks_identity(E_star, residual, E_ref, limit: float):
    """Return where the energy identity is broken: E* not finite or |r| beyond the bound."""
    E_star, residual = np.asarray(E_star, dtype=float), np.asarray(residual, dtype=float)
    with np.errstate(invalid='ignore'):
        return ~(np.isfinite(E_star) & (excess(residual, E_star, E_ref, limit) <= 1.0))


def first_break(E_star, residual, E_ref, limit: float) -> int | None:
    """Return the index of the first sample that breaks the identity (None: none does)."""
    bad = np.atleast_1d(breaks_identity(E_star, residual, E_ref, limit))
    return int(np.argmax(bad)) if bad.any() else None


def describe_break(t: float, E_star: float, residual: float, E_ref: float, limit: float,
                   name: str = 'max_residual') -> str:
    """Return why a sample breaks the identity, with its numbers (``name``: the limit's)."""
    at = f'at t = {t:.6f} s'
    if not np.isfinite(E_star):
        return f'E* = {E_star:g} J {at} is not finite'
    return (f'energy-balance residual {residual:.6g} J {at} exceeds max({name} {limit:g} J, '
            f'{RELATIVE_LIMIT:g} x max(|E*|, |E_ref|)) = '
            f'{float(bound(float(E_star), float(E_ref), limit)):.6g} J')
