"""The energy-identity guard: one rule for the live simulation, ``simulate`` and the analysis.

Along a solution E* + D is constant (eq. 17), so the energy-balance residual
r = E* + D - E_ref measures the integration error. The integration counts as diverged
where E* is not finite or

    |r| > limit x max(1 J, |E*|, |E_ref|)

a bound in joules for energies up to 1 J and relative to the energy beyond: the rounding
of E* grows with it, and 1e-14 J of 1e14 J of a statically unstable system's growing
motion is no divergence of the integration but growth with a sound energy identity. The
live simulation stops there (``max_residual``), ``gyro-rotor simulate`` reports it, and
the analysis calls a run diverged by it (:class:`~gyro_rotor.analysis.analyzer.RotorAnalyzer`
``diverge_residual``). Pure numpy.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ['ENERGY_FLOOR_J', 'energy_scale', 'relative_residual', 'breaks_identity',
           'first_break', 'describe_break']

#: the guard's bound is in joules up to this energy, relative to |E*| or |E_ref| beyond
ENERGY_FLOOR_J = 1.0


def energy_scale(E_star, E_ref):
    """Return max(1 J, |E*|, |E_ref|) (elementwise for arrays; NaN if either is NaN)."""
    if isinstance(E_star, float) and isinstance(E_ref, float):
        # one sample (the analysis, per sample): plain floats, no numpy call
        if math.isnan(E_star) or math.isnan(E_ref):
            return math.nan
        return max(abs(E_star), abs(E_ref), ENERGY_FLOOR_J)
    with np.errstate(invalid='ignore'):
        return np.maximum(np.maximum(np.abs(E_star), np.abs(E_ref)), ENERGY_FLOOR_J)


def relative_residual(residual, E_star, E_ref):
    """Return |r| / max(1 J, |E*|, |E_ref|): the number the guard holds against its limit."""
    if isinstance(residual, float):
        return abs(residual) / energy_scale(E_star, E_ref)
    with np.errstate(invalid='ignore'):
        return np.abs(residual) / energy_scale(E_star, E_ref)


def breaks_identity(E_star, residual, E_ref, limit: float):
    """Return where the energy identity is broken: E* not finite or |r| beyond the bound."""
    E_star, residual = np.asarray(E_star, dtype=float), np.asarray(residual, dtype=float)
    with np.errstate(invalid='ignore'):
        return ~(np.isfinite(E_star) & (relative_residual(residual, E_star, E_ref) <= limit))


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
    return (f'energy-balance residual {residual:.6g} J {at} exceeds {name} {limit:g} x '
            f'max(1 J, |E*|, |E_ref|) = {limit * float(energy_scale(E_star, E_ref)):.6g} J')
