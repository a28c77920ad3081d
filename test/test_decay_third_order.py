"""The free rate is measured against everything of E* the window shows, to round-off.

Recorded E*(t) of two random valid systems (test_verdict_random_systems' generator), as
:func:`fit_energy` received it (``test/data/random_energy_windows.npz``); each simulated
with the parameters of its prediction, so the true rates are the predicted ones.

- ``short`` (seed 3431486997, n 1, m 2; t = 0 .. 2 s): 2|alpha| = 0.0916 1/s. Its last
  1.5 s have a design matrix of condition 3.4e13; with singular values cut at 1e-12 the
  fit lost directions its terms need and the free rate took up the loss: 0.0708
  (0.0697 .. 0.0718) 1/s over the last 75 %, a false FAIL.
- ``late`` (seed 1048793445, n 2, m 2; t = 1 .. 9 s): a mode the drive barely reaches
  (Re lambda = -8e-7 1/s) makes E*'s third-order terms lambda_i + 2 Re lambda_j ~ lambda_i,
  half the rate of the slowest shown terms of eq. 13 (0.5237 1/s); fitted without them
  the free rate follows them (0.4448 (0.4414 .. 0.4481) over 2 .. 10 s: FAIL).
"""

from __future__ import annotations

import math
from pathlib import Path

from gyro_rotor.analysis.decay import _exponents, fit_energy
import numpy as np
import pytest

DATA = Path(__file__).parent / 'data' / 'random_energy_windows.npz'


@pytest.fixture(scope='module')
def windows():
    with np.load(DATA) as d:
        return {k: d[k] for k in d.files}


def _fit(w, name):
    noise, rem = w[f'{name}_nr']
    return fit_energy(w[f'{name}_t'], w[f'{name}_E'], list(w[f'{name}_eigs']), noise=noise,
                      remainder=rem)


def _holds(fit, truth):
    """Return whether the measured rate's interval holds the truth (or none is measured)."""
    return math.isnan(fit.rate) or fit.rate_lo <= truth <= fit.rate_hi


@pytest.mark.parametrize('name', ['short', 'late'])
def test_every_rate_measured_holds_the_truth(windows, name):
    fit = _fit(windows, name)
    parts = [fit] + ([fit.tail] if fit.tail is not None else [])
    for f in parts:
        assert math.isfinite(f.free_rate)
        assert _holds(f, f.free_rate), (f.t0, f.rate, f.rate_lo, f.rate_hi, f.free_rate)
    assert any(math.isfinite(f.rate) for f in parts)       # and something is measured


def test_the_quadratic_form_fits_the_short_window_to_round_off(windows):
    """Without third-order columns: the quadratic form leaves round-off, none are added."""
    fit = _fit(windows, 'short')
    assert fit.third == ()
    assert fit.residual_rms < 1e-16
    assert fit.tail is not None and fit.tail.residual_rms < fit.tail.floor


def test_third_order_terms_take_the_late_window_to_round_off(windows):
    """The terms lambda_i + lambda_j + lambda_k as columns take the residual to round-off.

    Those no faster than the slowest term that shows above the quadratic fit's floor
    (0.5237 1/s); none of them is among eq. 13's exponents.
    """
    fit = _fit(windows, 'late')
    assert fit.third
    quadratic = _exponents(list(windows['late_eigs']))
    assert not set(fit.third) & set(quadratic)
    assert all(-mu.real <= 0.5237 * (1 + 1e-4) for mu in fit.third)
    assert fit.residual_rms < 100 * fit.noise
