"""The free rate is measured against everything of E* the window shows, to round-off.

Recorded E*(t) of random valid systems (test_verdict_random_systems' generator), as
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
- ``cubic`` (seed 3435928384, n 2, m 2; t = 0 .. 4 s): the quadratic form fits E* to its
  noise, yet a free rate for the slowest shown terms (3.792 1/s, frequency 1.406 rad/s)
  fits best at 0.035 (0 .. 2.25) 1/s: E*'s third-order term 2 lambda_b + conj lambda_b of
  the all but undamped mode lambda_b = -6e-5 + 1.406 i at the same frequency, below the
  fit's floor but not below the profile's level (FAIL). Measured again with the
  third-order terms as columns it had no rate, but with that check (and the parabola's
  below) 7 of 60 replayed soak draws went from confirmed to insufficient data, most by
  losing right rates to those columns. The slowest shown term has a partner 3e-3 1/s
  faster, exp(-3.795 t) cos(3.378 t), that the window cannot tell from it: with it in the
  free group (``tail``) that partner's own part, 4.7e-16 J, is below the floor 1.6e-15 J,
  and no rate is measured (NOT YET: no FAIL).
- ``near`` (seed 4130726406, n 2, m 2; t = 2 .. 10 s): the third-order terms
  lambda_d + 2 Re lambda_j with Re lambda_j ~ -1e-3 decay at 2.9141 1/s, faster than the
  free terms' 2.9133 by less than the window resolves; left out as 'faster', the free
  rate measured 1.116 (1.004 .. 1.219) 1/s (FAIL). With the terms the window cannot tell
  from the free ones in their group (``tail``) 2.8715 (2.8458 .. 2.8977), above the bound
  0.9 x 2.9133 (no FAIL) but not holding the truth: not yet mended (xfail); the
  third-order terms kept as columns cost measurable rates elsewhere (the ``late`` window
  measured none).
- ``near7`` (seed 286651472, n 2, m 1; t = 0 .. 7 s, the stop-47 soak's one false FAIL in
  167 draws): the free terms lambda_d + lambda_b (lambda_d = -2.93758, lambda_b = -1.5e-5 +
  1.36 i) measured 1.744 (1.675 .. 1.824) for 2.9376 (FAIL). Taken for the ``near``
  family at first (the third-order term lambda_d + lambda_b + conj lambda_b, faster by
  1.5e-5 1/s, left out), it was the search: the free rate's profile has more than one
  minimum, and only the coarse grid's least point was refined; refining every coarse
  minimum, the predicted rate among the grid's points, measures 2.9403 (2.9358 .. 2.9407);
  with the terms it cannot tell from the free ones in their group (``tail``), 2.93761
  (2.93736 .. 2.93771).
- ``beat`` (seed 615112150, n 1, m 1; t = 0 .. 2 s, a 10-s run): the free terms at
  14.11 and 12.55 rad/s (4.3953 1/s) beat at 1.56 rad/s, the frequency of the all but
  undamped term; over the last 75 % the profile has a local minimum at 3.27 1/s and its
  least (under 1e-3 of that one's residual) within 2 % of 4.3953, between two coarse grid
  points 1.5 apart in ratio: 3.273 (3.193 .. 3.376) 1/s against the bound 3.956 (a false
  FAIL); refined at every coarse minimum, 4.39528 (4.39493 .. 4.39538).
- ``curved`` (seed 721218819, n 1, m 2; t = 2 .. 10 s): over the last 6 s the 2|alpha|
  term (0.00746 1/s) is merged into E_inf and a line, whose curvature the fit leaves
  (rms residual 1.4e-7 J): the free rate 0.539 (0.532 .. 0.545) for 0.6288, a false FAIL.
  The rate measured with the slow part to second order (a parabola) was discarded: its
  terms were judged against the line's floor (10 x 1.4e-7 J), not its own fit's. With its
  own floor it measures 0.6285, and the interval 0.532 .. 0.6288 held the truth, by
  2e-5; once the search found the parabola's least residual (``beat``), 0.62869
  (0.62850 .. 0.62880) no longer did. With the cubic as well, 0.628818
  (0.628805 .. 0.628864): the interval holds the rates of the slow part to second and
  third order.
- ``line`` (seed 4208142203, n 1, m 2; t = 0 .. 2 s): the same, its 2|alpha| term
  (0.0128 1/s) merged: 1.58 (1.00 .. 2.34) 1/s for 7.881 (FAIL); with the parabola's
  measurement 1.00 .. 7.886.

The two false FAILs of a soak (seed 5001: 351 draws, 287 confirmed, 62 insufficient data,
2 not confirmed by decay: these two), one cause: terms whose rates the window cannot tell
from the free ones' were fitted as faster terms, not in the free group.

- ``tail`` (seed 4010597016, n 3, m 2; t = 2 .. 10 s, a 20-s run): over the window the
  free rate is the truth, 0.0570115 (0.0570112 .. 0.0570150) 1/s; over its last 75 %
  0.0484 (0.0446 .. 0.0513), wholly below the bound 0.05131. The slowest shown terms
  (0.05701 1/s, 2.4e-5 and 6.6e-5 J) have partners 3e-4 1/s faster, the larger 2.0e-4 J.
  In the group, each term's rate shifted by one free amount: 0.0570115 (0.0541 .. 0.0599)
  over the last 75 %. (One rate shared by all of them measured 0.05721 (0.05720 ..
  0.05722) over the window: between the two predicted rates, holding neither.)
- ``fast`` (seed 1285713523, n 2, m 1; t = 0 .. 6 s, a 10-s run): 2.79 (2.43 .. 3.18)
  1/s for 10.94: the free term (1.2e-5 J) has a partner 3.3e-4 1/s faster and 100 times
  larger; its own part showed 1.2 times the floor and its rate followed the remainder.
  In the group, the terms fall below the floor within the window: no rate (NOT YET).
- ``lone`` (seed 2259047846, n 3, m 2; t = 2 .. 10 s, a 20-s run; the one false FAIL of
  a fresh soak (seed 5002) of 351 draws on this code): the free group, four terms at
  0.0133 and 0.01396 1/s (r T ~ 0.11), measures 0.0130; three of them (0.86, 1.37 and
  5.15 rad/s; 8.3e-4, 5.1e-5, 5.8e-6 J) show no own part above the floor and are kept as
  predicted, and the one left (5.9e-5 J at 5.65 rad/s) measures 0.00954 (0.00754 ..
  0.01155) for 0.0133, below the bound 0.01197. The weak terms kept apart split the group
  again; before the group held the terms the window cannot tell apart, this window had no
  rate (the least residual at the search's lower end). The interval now also holds the
  rate measured with them: 0.00954 (0 .. 0.0238), NOT YET.
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


@pytest.mark.parametrize('name', ['short', 'late', 'near7', 'beat', 'tail', 'lone'])
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


@pytest.mark.parametrize('name', ['curved', 'line'])
def test_the_merged_slow_parts_curvature_widens_the_interval(windows, name):
    """The rates measured with the slow part to second (and third) order join the line's."""
    fit = _fit(windows, name)
    parts = [fit] + ([fit.tail] if fit.tail is not None else [])
    assert any(math.isfinite(f.rate) for f in parts)
    for f in parts:
        assert _holds(f, f.free_rate), (f.t0, f.rate, f.rate_lo, f.rate_hi, f.free_rate)


@pytest.mark.parametrize('name', ['cubic', 'fast'])
def test_terms_the_window_cannot_tell_apart_are_measured_together(windows, name):
    """No rate where the free group's terms fade or hide: NOT YET, not a FAIL (module doc)."""
    fit = _fit(windows, name)
    assert math.isnan(fit.rate), (fit.rate, fit.rate_lo, fit.rate_hi, fit.free_rate)
    assert 'below the noise floor' in fit.rate_note, fit.rate_note


@pytest.mark.xfail(strict=True, reason="E*'s third-order terms faster than the free ones by "
                   'less than the window resolves, left out: near 2.8715 (2.8458 .. 2.8977) '
                   'for 2.9133')
def test_third_order_terms_beside_the_free_ones(windows):
    fit = _fit(windows, 'near')
    assert _holds(fit, fit.free_rate), (fit.rate, fit.rate_lo, fit.rate_hi, fit.free_rate)
