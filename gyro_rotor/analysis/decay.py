"""Decay of E* toward its limit: E*_inf fitted from the data with the predicted rates.

The paper promises asymptotic stability in the velocities and rotor angles, not in every
coordinate: after a kick the motion may settle on a neighbouring steady motion of the
family (the cyclic psi), so E*_inf is not known in advance. E* - E*_inf is a quadratic
form of the deviations (eq. 13); with the deviations a sum of modes exp(lambda_i t) it is
a sum of terms exp((lambda_i + lambda_j) t) and exp((lambda_i + conj lambda_j) t). Their
exponents are known from the prediction, so E*(t) = E_inf + sum of those terms is linear
in E_inf and the term amplitudes: a least-squares fit gives E_inf and its standard error
(:func:`fit_energy`).

The measured rate is not taken from that fit: with the predicted exponents fixed, E_inf and
the amplitudes absorb a wrong rate (over an 8 s window exp(-0.311 t) is exp(-0.415 t) plus
a constant and a line to 0.3 % of E*'s spread), and the slope of log(E* - E_inf) was
pulled toward the prediction (precession simulated at 0.75 K_D measured 0.420 1/s against
the true 0.312). Instead the slowest predicted terms that show (eq. 13's terms
exp(2 Re(lambda) t) of the slowest mode above the noise floor) get a free rate r, fitted by
variable projection (a 1-D search over r, E_inf and every amplitude refitted at each r):
the rate is the r of least residual and its interval the r whose residual exceeds that
least one by at most :data:`SIGMAS` squared standard errors (the profile of the fit).
Where predicted terms too slow for the window are merged into E_inf and a line, the
interval also holds the rates measured with that slow part to second order, and to third
where the parabola leaves more than noise (:data:`SLOW_ORDER`): the profile assumes its
model exact, and a term the window barely resolves (r T ~ 0.1) trades its rate against the
slow part's curvature. A random system over 0 .. 8 s measured 0.0063 (0 .. 0.0072) with the
line and 0.0123 (0.0122 .. 0.0125) with the parabola for the true 0.01239 1/s: FAIL by the
line alone, NOT YET by both. The parabola's terms show or not above its own fit's floor:
judged against the line's (10 x its residual 1.4e-7 J), a random system's parabola
measurement over 4 .. 10 s was discarded, and the line's 0.539 (0.532 .. 0.545) stood for
the true 0.628818 (with its own: 0.532 .. 0.62880; with the cubic's as well: 0.532 ..
0.62886). The least residual at the search's lower end, the slowest rate the window
resolves (:data:`RESOLVABLE` / T), means the data prefer a decay the window cannot resolve:
no rate is measured there. A term barely resolved (r T = 0.089 over 8 s) has little but its
curvature to tell its rate from E_inf and the line, and the slow part merged into them has
curvature too: a random system measured 0.00625 (0 .. 0.0086) 1/s, the search's lower end,
for the true 0.01117 with E*'s residual 1e-13 of its spread (FAIL for a valid system);
another 0.033 (0 .. 0.48), the lower end over a 1.5-s window, for 4.19.

The profile interval counts the residual, not what the columns cannot fit; a fit short of
E* moves the rate outside it. So the fit goes to E*'s round-off: no singular value above
it is cut (:func:`_rcond`), and where the quadratic form of eq. 13 leaves more than
:data:`NOISE_K` times the noise, E*'s third-order terms as slow as the free ones join the
kept columns (:func:`_third_order`): a random system with a mode the drive barely
reaches measured 0.4448 (0.4414 .. 0.4481) 1/s for its 0.5237 over 2 .. 10 s, residual
1.8e-7 J, and with them the residual is round-off.

The faster terms that show get their predicted rates times one common factor, fitted
alternately with r (:func:`_faster_scale`): fixed as predicted, their error leaked into r
(elastic_frame at 0.8 K_D: 0.531 measured, 0.367 true). The rate is measured only while
the slowest shown terms show above the noise floor, by the part of them no other column
can take and over the window's last fifth; a term that fades into the floor is fitted by
the nonlinear remainder instead (elastic_frame at K_D: 0.33 1/s for its 0.458 by t = 23 s).

One common factor is a model of a wrong prediction, not the truth: a wrong drive damping
moves the modes' rates by different factors and their frequencies too, and what the
faster terms then miss still leaks into r, most where they are largest, at the window's
start. Where faster terms show, the rate is therefore measured again over the window's
last three quarters (:data:`TAIL_FROM`, ``EnergyFit.tail``), where they have decayed further:
elastic_frame simulated at 0.88 K_D (true rate 0.403 1/s, bound 0.412) measures 0.419
(0.416 .. 0.422) over the window ending at 6 s and 0.406 (0.4055 .. 0.4062) over its last
three quarters; at its own K_D the two agree (0.4582 and 0.4585). The decay criterion
holds both against its bound. Once the faster terms are below the noise floor there is
nothing of theirs to leak, and no second measurement: late in a run the slowest terms fade
toward the floor and the nonlinear remainder pulls a shorter fit's rate down (elastic_frame
at its own K_D, window 11 .. 19 s: 0.432 over it, 0.415 over its last three quarters).

Pure numpy (threadpoolctl keeps its BLAS on one thread, :func:`fit_energy`).
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple, Sequence

import numpy as np
from threadpoolctl import threadpool_limits


__all__ = ['EnergyFit', 'fit_energy', 'envelope_decay_rate', 'SIGMAS', 'NOISE_K', 'RESOLVABLE',
           'REMAINDER_SHARE', 'TAIL_FROM']

#: a rate r changes an amplitude by r T over a window T; below this (5 %) it is not
#: resolvable there: the nonlinear remainder and the leakage of neighbouring roots reach it.
#: A non-oscillating term of E* this slow is nearly collinear with a constant and merged
#: into E_inf (the nutation about solution II, 2 |Re| = 0.0035 1/s over 8 s: 0.028)
RESOLVABLE = 0.05
#: E_inf is varied by this many standard errors for the rate interval
SIGMAS = 2.0
#: a term decaying by more than exp(-MAX_EXPONENT) within one sample is no column (it is
#: gone by the second sample)
MAX_EXPONENT = 30.0
#: the slow part merged into E_inf is also fitted as a polynomial of up to this degree in
#: time, and the rate measured with each (:func:`_measure_hull`)
SLOW_ORDER = 3
#: the rate is measured again from this fraction of the window on (``EnergyFit.tail``,
#: module doc)
TAIL_FROM = 0.25


@dataclasses.dataclass(frozen=True)
class EnergyFit:
    """Result of :func:`fit_energy` (rates in 1/s, NaN where not determined).

    ``rate_lo``/``rate_hi`` bound the measured rate (module doc); ``noise`` is the noise
    level of E* [J] and ``floor`` the noise floor below which E* - E*_inf is not used;
    ``settled``: E* varies over the window by less than the floor (nothing left to fit);
    ``residual_rms`` the rms residual of the fit [J] and ``n_eff`` the number of
    independent residuals (sign changes + 1) behind the uncertainties.
    """

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
    noise: float = 0.0
    floor: float = 0.0
    remainder: float = 0.0
    settled: bool = False
    residual_rms: float = 0.0
    n_eff: float = 1.0
    rate_note: str = ''
    #: predicted terms too slow to resolve in the window were merged into E_inf and the
    #: trend: E_inf is then their value at the window's end, not the limit of E*
    slow: bool = False
    #: the predicted rate of the terms whose rate was fitted free (``rate``), NaN if none
    free_rate: float = math.nan
    #: the same fit over the window's last part (from :data:`TAIL_FROM` of it on), or None
    tail: 'EnergyFit | None' = None
    #: exponents of E*'s third-order terms kept as columns (:func:`_third_order`)
    third: tuple = ()

    def terms(self) -> list[tuple[complex, float]]:
        """Return (exponent, amplitude at the window's start [J]) of each fitted term."""
        return _amplitudes(self.exponents, self.coef)

    def shown_decay(self) -> float:
        """Return the slowest decay rate [1/s] of the terms that show in the measured rate.

        The rate is measured where E* - E*_inf is above the noise floor (``floor``): a term
        whose amplitude at the window's start is below the floor never shows there, nor
        does a term whose decay the window cannot resolve (rate x span below
        :data:`RESOLVABLE`: the slow terms merged into E_inf, an undamped one). NaN if no
        term shows.
        """
        shown = [-mu.real for mu, a in self.terms()
                 if a >= self.floor and -mu.real * self.span >= RESOLVABLE]
        return min(shown, default=math.nan)

    def curve(self, t: np.ndarray) -> np.ndarray:
        """Return the fitted E*(t) (E_inf plus the predicted terms)."""
        tau = np.asarray(t, dtype=float) - self.t0
        X = _basis(tau, self.exponents)
        return self.E_inf + self.trend * (tau - self.span) + X @ np.asarray(self.coef)


def _amplitudes(mus: Sequence[complex], coef: Sequence[float]) -> list[tuple[complex, float]]:
    """Return (exponent, amplitude [J]) of each term: a real column, or a cos/sin pair."""
    widths = _widths(mus)
    edges = np.cumsum([0, *widths])
    return [(mu, abs(coef[a]) if w == 1 else math.hypot(coef[a], coef[a + 1]))
            for mu, a, w in zip(mus, edges[:-1], widths)]


def _golden_log(f, a: float, b: float, steps: int) -> tuple[float, float]:
    """Return (x, f(exp x)): golden-section search for the minimum of f(exp x) on [a, b].

    ``steps`` narrowings after the first two evaluations; the better of the last pair
    (the later one on a tie).
    """
    g = 0.5 * (math.sqrt(5.0) - 1.0)
    c, d = b - g * (b - a), a + g * (b - a)
    fc, fd = f(math.exp(c)), f(math.exp(d))
    for _ in range(steps):
        if fc < fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            fc = f(math.exp(c))
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            fd = f(math.exp(d))
    return (c, fc) if fc < fd else (d, fd)


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


def _is_real(mu: complex) -> bool:
    """Return True if the term exp(mu t) is real: one column of :func:`_basis`, else two."""
    return abs(mu.imag) <= 1e-12


def _widths(exponents: Sequence[complex]) -> np.ndarray:
    """Return each term's number of columns in :func:`_basis` (1 real, 2 a cos/sin pair)."""
    return np.array([1 if _is_real(mu) else 2 for mu in exponents], dtype=int)


def _basis(tau: np.ndarray, exponents: Sequence[complex]) -> np.ndarray:
    """Return the columns exp(mu tau), or their cos/sin pair (:func:`_widths`), of each term."""
    cols = []
    for mu in exponents:
        env = np.exp(mu.real * tau)
        if _is_real(mu):
            cols.append(env)
        else:
            cols += [env * np.cos(mu.imag * tau), env * np.sin(mu.imag * tau)]
    return np.column_stack(cols) if cols else np.zeros((len(tau), 0))


#: the noise floor is this many times the noise level (of E*, or of the fit's residual)
NOISE_K = 10.0
#: E* beyond its quadratic form: the linearization leaves out terms of third order in the
#: deviations, so a fit with the predicted rates leaves a remainder that does not decay
#: with them (the unreached modes' nonlinear coupling to the drive). Measured, relative to
#: E*'s change over the segment: 1.0e-5 on elastic_frame, 6.6e-7 on upright (their rms
#: residuals once the reached modes have decayed); this share is the remainder allowed
REMAINDER_SHARE = 1e-4


def _n_eff(r: np.ndarray) -> float:
    """Independent pieces of a residual series: its sign changes + 1 (at least 2)."""
    if r.size < 2:
        return 1.0
    s = np.sign(r)
    return float(max(2, int(np.count_nonzero(s[1:] * s[:-1] < 0)) + 1))


#: points of the coarse search over the free rate (geometric, :data:`RESOLVABLE` / span to
#: :data:`FREE_SPAN` x the predicted rate), and bisection steps for each end of its interval
FREE_POINTS = 20
FREE_SPAN = 20.0
_BISECT = 12


#: the common factor of the other terms' rates is searched over 1 / KAPPA_SPAN .. KAPPA_SPAN,
#: alternating with the group's free rate at most ALTERNATE times (until the rate settles)
KAPPA_SPAN = 10.0
ALTERNATE = 3


def _rcond(X: np.ndarray) -> float:
    """Return the relative size below which a singular value of X is round-off: eps max(m, n).

    numpy's own rank tolerance (``matrix_rank``). E* is simulated to round-off, so a
    direction of the columns above it carries the data: cut at 1e-12 (4500 eps for 501
    samples), a random system's fit over the last 1.5 s of a 2-s window (condition 3.4e13)
    lost directions its terms need, left a residual of 8.9e-15 J against round-off
    1.4e-17 J, and the free rate took up the loss: 0.0708 (0.0697 .. 0.0718) 1/s for the
    true 0.0916 (FAIL for a valid system).
    """
    return float(np.finfo(float).eps * max(X.shape))


def _orth(X: np.ndarray) -> np.ndarray:
    """Return an orthonormal basis of the columns of X (rank-revealing SVD, :func:`_rcond`)."""
    scale = np.linalg.norm(X, axis=0)
    scale[scale == 0] = 1.0
    U, S, _ = np.linalg.svd(X / scale, full_matrices=False)
    return U[:, S > _rcond(X) * S[0]]


def _project_out(Q: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Return the columns F without their part in the span of the orthonormal Q.

    Formed explicitly: the group's columns can lie all but in that span (a short window,
    terms of nearby rates), and F^T F - (Q^T F)^T (Q^T F), their normal matrix by
    difference, then cancels to round-off of F's own size: over the last 1.5 s of a random
    system's 2-s window (design matrix condition 5.6e10) the free rate's profile had its
    least residual at 0.141 1/s, with a zero-width interval, for the true 0.3996 (the
    explicit form: least at 0.3996, 5.4e-29 against 2.1e-25 J^2 at 0.141).
    """
    return F - Q @ (Q.T @ F)


def _projected_fit(P: np.ndarray, y: np.ndarray) -> tuple:
    """Return (c, P c): least squares of y on the columns P (scaled; SVD, not normal equations).

    The normal equations square the columns' condition (1.4e8 for the faster terms of a
    random system's 2-s window: their kappa profile then had no minimum at the true 1, the
    residual 1.7e-17 there against 1.2e-32 by the SVD).
    """
    d = np.linalg.norm(P, axis=0)
    d[d == 0] = 1.0
    c = np.linalg.lstsq(P / d, y, rcond=_rcond(P))[0] / d
    return c, P @ c


def _faster_scale(tau: np.ndarray, y: np.ndarray, Q: np.ndarray, group: Sequence[complex],
                  faster: Sequence[complex], near: float = math.nan) -> float:
    """Return the common factor kappa of the other decaying terms' rates that fits E* best.

    The other terms that show and that the window resolves as decaying (``faster``: all
    but the slowest shown ones, ``group``) get the real parts kappa Re(mu), the group and
    the kept columns (E_inf, the trend, the terms below the noise floor or not resolved as
    decaying; ``Q``: their orthonormal basis, :func:`_orth`) as they are; least residual by
    variable projection over log kappa, from 1 / KAPPA_SPAN to
    KAPPA_SPAN, or within a factor 1.5 of ``near`` (a previous round's kappa). A wrong
    drive damping moves every rate the drive reaches (eq. 17): fixed as predicted, their
    error would leak into the group's free rate (elastic_frame at 0.8 K_D: 0.441 1/s
    measured against the true 0.367).
    """
    y_perp = y - Q @ (Q.T @ y)
    G = _basis(tau, group)
    trig = _basis(tau, [complex(0.0, mu.imag) for mu in faster])
    reals = np.repeat([mu.real for mu in faster], _widths(faster))

    def rss(kappa: float) -> float:
        F = np.column_stack([G, np.exp(np.outer(tau, kappa * reals)) * trig])
        res = y_perp - _projected_fit(_project_out(Q, F), y_perp)[1]
        return float(res @ res)

    if math.isfinite(near):
        a, b = math.log(near / 1.5), math.log(near * 1.5)
        best, best_v = near, rss(near)
    else:
        grid = np.geomspace(1.0 / KAPPA_SPAN, KAPPA_SPAN, 13)
        vals = [rss(k) for k in grid]
        i = int(np.argmin(vals))
        best, best_v = float(grid[i]), vals[i]
        a, b = math.log(grid[max(i - 1, 0)]), math.log(grid[min(i + 1, len(grid) - 1)])
    x, v = _golden_log(rss, a, b, 10)                      # golden section in log kappa
    return math.exp(x) if v < best_v else best


def _own_parts(F: np.ndarray, Q: np.ndarray, c: np.ndarray,
               group: Sequence[complex]) -> list[float]:
    """Return each term's own part (rms) of the group's fitted columns ``F`` (coefficients c).

    A term's own part is what of it neither the kept columns (``Q``) nor the group's other
    terms can take: a term that the window cannot tell from them has none to show its rate.
    """
    P = F - Q @ (Q.T @ F)
    edges = np.cumsum([0, *_widths(group)])
    out = []
    for a, b in zip(edges[:-1], edges[1:]):
        Pk = P[:, a:b]
        rest = np.delete(P, np.s_[a:b], axis=1)
        if rest.shape[1]:
            Qr = _orth(rest)
            Pk = Pk - Qr @ (Qr.T @ Pk)
        out.append(float(np.sqrt(np.mean((Pk @ c[a:b]) ** 2))))
    return out


def _least(f, grid: np.ndarray) -> tuple[float, int, np.ndarray]:
    """Return (r, k, f(grid)): the r of least f(r), near grid[k] (k = 0: the grid's start).

    The profile of a free rate can have more than one minimum: every minimum of the coarse
    grid is refined by golden section between its neighbours (in log r), and the least of
    them taken. Refining only the grid's least point, a random system's window (two free
    terms beating at the frequency of a third) measured 3.273 (3.193 .. 3.376) 1/s, a
    local minimum, for 4.3953: the least residual (under 1e-3 of that one's) lay within
    2 % of it, between two grid points 1.5 apart in ratio.
    """
    vals = np.array([f(r) for r in grid])
    k = int(np.argmin(vals))
    r, least = float(grid[k]), float(vals[k])
    for i in range(1, len(grid) - 1):
        if vals[i] <= min(vals[i - 1], vals[i + 1]):
            x, v = _golden_log(f, math.log(grid[i - 1]), math.log(grid[i + 1]), 12)
            if v < least:
                r, least, k = math.exp(x), v, i
    return r, k, vals


def _free_rate(tau: np.ndarray, y: np.ndarray, Xf: np.ndarray, group: Sequence[complex],
               rate0: float, dt: float, noise: float) -> tuple:
    """Fit the rate of the terms ``group`` free: (rate, interval, shown), rate in 1/s.

    ``interval()``: (lo, hi), computed when called; ``shown``: the group's own part (rms).

    ``Xf``: the columns kept as predicted; the terms of ``group`` (the slowest of them at the rate
    ``rate0``) get their rates shifted by r - rate0, frequencies kept; at each r the fit is
    linear (variable projection). The rate is the r of least residual (:func:`_least`, over a
    geometric grid with ``rate0`` among its points), none (NaN) where that is the slowest rate
    the window resolves (:data:`RESOLVABLE` / span, module doc); the interval every r whose
    residual sum of squares exceeds the least by at most SIGMAS^2 s^2 (s^2 counted over
    :func:`_n_eff` pieces, at least the noise level's), down to 0 at the slowest resolvable
    rate, open above at the fastest searched one.
    """
    n = len(tau)
    span = float(tau[-1]) if n else 0.0
    Q = _orth(Xf)
    y_perp = y - Q @ (Q.T @ y)

    trig = _basis(tau, [complex(0.0, mu.imag) for mu in group])    # the group's cos, sin
    # each column's rate above rate0 (terms the window cannot tell from rate0, _measure)
    above = np.repeat([-mu.real - rate0 for mu in group], _widths(group))

    def at(r: float) -> np.ndarray:
        return np.exp(-np.outer(tau, r + above)) * trig

    def fit(r: float, full: bool = False):
        F = at(r)
        c, own = _projected_fit(_project_out(Q, F), y_perp)
        res = y_perp - own
        return (float(res @ res), res, own, F @ c, c) if full else float(res @ res)

    r_min = RESOLVABLE / max(span, 1e-12)
    r_max = max(FREE_SPAN * rate0, 2.0 * r_min)
    if dt > 0:
        r_max = min(r_max, MAX_EXPONENT / dt)
    if not r_max > r_min:
        return math.nan, lambda: (math.nan, math.nan), (0.0, 0.0, [0.0] * len(group))
    grid = np.geomspace(r_min, r_max, FREE_POINTS)
    if r_min < rate0 < r_max:
        grid = np.sort(np.append(grid, rate0))
    rate, k, rss = _least(fit, grid)
    rss_min, res, own, term, c = fit(rate, full=True)
    # the group's part no other column can take, the terms over the window's last fifth
    # and each term's own part (rms): each must show above the noise floor (_measure)
    shown = (float(np.sqrt(np.mean(own ** 2))),
             float(np.sqrt(np.mean(term[tau >= 0.8 * span] ** 2))),
             _own_parts(at(rate), Q, c, group))
    if k == 0:
        # the least residual at the slowest rate the window resolves: the data prefer a
        # decay it cannot resolve, and measure none (module doc)
        return math.nan, lambda: (math.nan, math.nan), shown
    dof = max(n - Q.shape[1] - 2 * len(group) - 1, 1)
    s2 = max(rss_min / dof, noise * noise) * (n / _n_eff(res))
    level = rss_min + SIGMAS ** 2 * s2

    def edge(inside: float, outside: float) -> float:
        # the profile narrower than the bisection resolves (every probe outside: exact
        # data, 4.5596708 (interval 4.5596708 .. 4.5596708) 1/s): the nearest probe
        # outside bounds it, not the rate itself (an interval of zero width)
        start = inside
        for _ in range(_BISECT):
            mid = math.sqrt(inside * outside)
            if fit(mid) <= level:
                inside = mid
            else:
                outside = mid
        return outside if inside == start else inside

    def interval() -> tuple[float, float]:
        below = [i for i in range(len(grid)) if grid[i] < rate and rss[i] > level]
        above = [i for i in range(len(grid)) if grid[i] > rate and rss[i] > level]
        lo = edge(rate, grid[below[-1]]) if below else 0.0
        hi = edge(rate, grid[above[0]]) if above else math.inf
        return min(lo, rate), max(hi, rate)

    return rate, interval, shown


def _measure(tau: np.ndarray, y: np.ndarray, cols: list, mus: list, terms: list,
             free: float, floor: float, dt: float, noise: float,
             group: list | None = None) -> tuple:
    """Return (rate, lo, hi, note, scaled) of the slowest shown terms (rate ``free``).

    Fitted free; ``scaled``: faster terms showed and got their rates scaled by one factor.
    ``group``: the terms fitted free (default: every term whose rate the window cannot tell
    from ``free``, by less than RESOLVABLE / span: two random systems' terms 3.3e-4 and 3e-4
    1/s faster than their slowest shown ones, 100 and 3 times larger, fitted as faster terms
    while a tiny one or two carried the free rate, measured 2.79 (2.43 .. 3.18) for 10.94 1/s
    over 0 .. 6 s and 0.0484 (0.0446 .. 0.0513) for 0.0570 over 4 .. 10 s: false FAILs). A term
    of them that shows (amplitude above the floor) but whose own part (:func:`_own_parts`) is
    below it is one the window cannot tell from E_inf and the other terms: its leftover is the
    remainder's, and a rate shared with it follows the remainder (tri over 0 .. 4 s: its
    non-oscillating 2|alpha| term, 8.5e-4 J, kept 6e-7 J of its own against the floor 1.8e-6 J
    and pulled the rate to 0.0125 for the true 0.0933 1/s). It is kept as predicted, like every
    term below the floor, and the rate measured from the terms that show by their own part; if
    none does, it is not measurable in the window. Kept apart, it splits the group again: the
    interval also holds the rate measured with it (a random system's group of four terms at
    0.0133 and 0.01396 1/s, three of them weak, measured 0.00954 (0.00754 .. 0.01155) 1/s by
    the fourth alone for 0.0133: a false FAIL; 0.0130 with them).
    """
    amp = dict(terms)
    if group is None:
        group = [mu for mu in mus if abs(-mu.real - free) * tau[-1] < RESOLVABLE]
    fixed = [mu for mu in mus if mu not in group]
    # the other terms the window resolves as decaying: their rates scaled by one fitted
    # factor while any of them shows (a wrong K_D moves them all, eq. 17)
    other = [mu for mu, a in terms if mu in fixed and a >= floor
             and -mu.real > free * (1.0 + 1e-9)]
    rounds = ALTERNATE if other else 1
    still = [mu for mu in fixed if mu not in other]
    Q_still = _orth(np.column_stack(cols + [_basis(tau, still)])) if other else None
    kappa, r = math.nan, free
    for k in range(rounds):
        if rounds > 1:
            # alternately: the others' common factor with the group at its rate so far,
            # then the group's rate with the others at that factor
            at_r = [complex(mu.real + free - r, mu.imag) for mu in group]
            kappa = _faster_scale(tau, y, Q_still, at_r, other, kappa)
        if other:
            fixed = still + [complex(kappa * mu.real, mu.imag) for mu in other]
        Xf = np.column_stack(cols + [_basis(tau, fixed)])
        rate, interval, (own, end, parts) = _free_rate(tau, y, Xf, group, free, dt,
                                                       noise)
        measurable = math.isfinite(rate) and own >= floor and end >= floor
        if not measurable or abs(rate - r) <= 3e-3 * r:
            break                       # settled, or not measurable (below)
        r = rate
    shown = [(p, mu) for p, mu in zip(parts, group) if amp[mu] >= floor]
    weak = [(p, mu) for p, mu in shown if not p >= floor]
    if measurable and weak and len(weak) < len(shown):
        keep = [mu for mu in group if mu not in [mu for _, mu in weak]]
        got = _measure(tau, y, cols, mus, terms, free, floor, dt, noise, keep)
        if math.isfinite(got[0]):
            # the weak terms kept apart split the group again: the interval also holds the
            # rate measured with them in it
            lo, hi = interval()
            return got[0], min(got[1], lo), max(got[2], hi), got[3], got[4]
        return got
    if measurable and not weak:
        lo, hi = interval()
        return rate, lo, hi, '', bool(other)
    note = _why_not(own, end, weak, free, floor, amp, tau[-1], math.isfinite(rate))
    return math.nan, math.nan, math.nan, note, bool(other)


def _measure_hull(tau: np.ndarray, y: np.ndarray, cols: list, mus: list, terms: list,
                  free: float, floor: float, dt: float, noise: float, slow: bool) -> tuple:
    """Return :func:`_measure`'s (rate, lo, hi, note, scaled), the interval widened.

    ``slow``: predicted terms too slow for the window are merged into ``cols`` (E_inf and a
    line); the interval then also holds the rate measured with the slow part to second
    order, and to each next order (up to :data:`SLOW_ORDER`) while the last one's fit
    leaves more than :data:`NOISE_K` times the noise (module doc): the rate may not depend
    on the slow part's next term that shows. The parabola alone (residual 3e-10 J) left a
    random system's window (``curved``, the last 6 s of 2 .. 10 s, the slow term 0.00746
    1/s) at 0.62869 (0.62850 .. 0.62880) for the true 0.628818; with the cubic, 0.628818
    (0.628805 .. 0.628864). Where the parabola leaves the noise, a cubic only widens the
    interval of a term the window barely resolves (0.0143 1/s over 6 s: 0.0113 .. 0.0174
    against 0.0131 .. 0.0148 without it).
    """
    rate, lo, hi, note, scaled = _measure(tau, y, cols, mus, terms, free, floor, dt, noise)
    for order in range(2, SLOW_ORDER + 1) if slow and math.isfinite(rate) else ():
        cols = cols + [(tau - tau[-1]) ** order]
        fit = _quadratic_fit(tau, y, cols, mus, noise, tau[-1])
        again = _measure(tau, y, cols, mus, fit.terms, free, fit.floor, dt, noise)
        if math.isfinite(again[0]):
            lo, hi = min(lo, again[1]), max(hi, again[2])
        if fit.rms < NOISE_K * noise:
            break                   # this order leaves the noise: no next term shows
    return rate, lo, hi, note, scaled


def _why_not(own: float, end: float, weak: list, free: float, floor: float,
             amp: dict, span: float, resolved: bool) -> str:
    """Say why the slowest shown terms (rate ``free``) give no rate (:func:`_measure`).

    ``resolved``: the free rate's least residual lay above the search's lower end; where
    it did not, that is the reason, whatever the parts at that end show.
    """
    if not resolved:
        # their least residual at the search's lower end (_free_rate)
        return (f'its slowest shown terms ({free:.4g} 1/s) fit best at the slowest rate '
                f'this {span:.3g} s window resolves ({RESOLVABLE / span:.3g} 1/s): no decay '
                f'of theirs is resolved in it')
    if not own >= floor:
        # E_inf, the trend and the other terms mimic these terms but for less than the
        # noise floor: nothing of them is left to measure a rate from
        return (f'the part of its slowest shown terms ({free:.4g} 1/s) that E*_inf, the '
                f'trend and the other terms cannot take is {own:.2g} J rms, below the '
                f'noise floor {floor:.2g} J')
    if not end >= floor:
        # what is left at the window's end is the remainder's, which a free rate fits too
        return (f'its slowest shown terms ({free:.4g} 1/s) fall below the noise floor '
                f'{floor:.2g} J within the window ({end:.2g} J rms over its last fifth)')
    # every one of them the window cannot tell from the other columns
    p, mu = min(weak, key=lambda w: w[0])
    return (f'the part of its slowest shown term {_fmt_mu(mu)} that E*_inf, the trend '
            f'and the other terms cannot take is {p:.2g} J rms, below the noise floor '
            f'{floor:.2g} J (of its {amp[mu]:.2g} J)')


def _fmt_mu(mu: complex) -> str:
    """Name a term of E* by its exponent (rate, and frequency if it oscillates)."""
    if _is_real(mu):
        return f'exp({mu.real:.4g} t)'
    return f'exp({mu.real:.4g} t) cos({mu.imag:.4g} t)'


def fit_energy(t: np.ndarray, E: np.ndarray, eigs: Sequence[complex],
               noise: float = 0.0, remainder: float = 0.0,
               tail_from: float = TAIL_FROM) -> EnergyFit:
    """Fit E*(t) = E_inf + sum of terms with the exponents of the predicted ``eigs``.

    ``eigs`` are the predicted eigenvalues with Im >= 0 (one of each conjugate pair),
    without the structural zero roots; ``noise`` the noise level of E* [J] (at least
    its rounding); ``remainder`` [J] what the linearization leaves out of E*
    (:data:`REMAINDER_SHARE` of E*'s change over the segment): E* varying by less than
    :data:`NOISE_K` times the larger of the two has settled. Non-oscillating terms too slow
    to resolve in the window (:data:`RESOLVABLE`) are merged into E_inf plus a straight
    line (``trend``, J/s, E_inf being their value at the window's end); terms that die
    within the window (exponent times span below -:data:`MAX_EXPONENT`) are left out.

    Uncertainties: that of E_inf is the least-squares one with the residuals counted as
    :func:`_n_eff` independent pieces (they are smooth), at least the noise level. The rate
    is that of the slowest predicted terms that show above the noise floor (:data:`NOISE_K`
    times the larger of the noise level and the fit's rms residual) and whose decay the
    window resolves, fitted free (:func:`_measure`, the module doc: eq. 17, E* decays by
    the drive damping at twice the modes' Re lambda). Where faster terms were scaled by
    one factor, ``tail`` is the same fit from ``tail_from`` of the window on.

    Computed with numpy's BLAS on one thread: the hundreds of least-squares fits of a few
    columns (:func:`_projected_fit`) each woke the BLAS threads, 14 ms a fit on this 2-core
    machine under load against 0.3 ms on one thread.
    """
    with threadpool_limits(limits=1, user_api='blas'):
        return _fit_energy(t, E, eigs, noise, remainder, tail_from)


def _linear_fit(tau: np.ndarray, y: np.ndarray, cols: list, mus: list) -> tuple:
    """Return (coef, res, cov00) of y on the columns ``cols`` and the terms ``mus``.

    Scaled columns, least squares by SVD (:func:`_rcond`); cov00 the variance of the first
    coefficient (E_inf), from the residual variance counted over :func:`_n_eff` pieces.
    """
    X = np.column_stack(cols + [_basis(tau, mus)])
    scale = np.linalg.norm(X, axis=0)
    scale[scale == 0] = 1.0
    Xs = X / scale
    coef, _, rank, _ = np.linalg.lstsq(Xs, y, rcond=_rcond(Xs))
    res = y - Xs @ coef
    s2 = float(res @ res) / max(len(y) - rank, 1) * (len(y) / _n_eff(res))
    # covariance of the scaled coefficients via the pseudo-inverse (rank-revealing SVD)
    _, S, Vt = np.linalg.svd(Xs, full_matrices=False)
    keep = S > _rcond(Xs) * S[0]
    cov00 = float(np.sum((Vt[keep, 0] / S[keep]) ** 2)) * s2
    return coef / scale, res, cov00


def _third_order(eigs: Sequence[complex], known: list, free: float, dt: float,
                 span: float) -> list[complex]:
    """Exponents lambda_i + lambda_j + lambda_k of E*'s third-order terms no faster than ``free``.

    E* is quadratic in the deviations only to first order: its cubic part, and its
    quadratic form of the deviations' own second-order parts, are terms
    exp((lambda_i + lambda_j + lambda_k) t) (conjugates among them). With a mode the drive
    barely reaches (Re lambda_j ~ 0) they hold lambda_i + 2 Re lambda_j ~ lambda_i, half
    the rate of the terms of eq. 13: fitted by the free rate, they pulled a random
    system's 0.5237 1/s down to 0.4448 (0.4414 .. 0.4481) over 2 .. 10 s, residual 1.8e-7
    J; with them as columns the residual is round-off (1.3e-17 J) and the rate 0.52377
    (0.52357 .. 0.52381). Those the window resolves, told apart from ``known`` and each
    other (by RESOLVABLE / span in rate or frequency), alive for a sample (``dt``),
    decaying no faster than ``free`` (the faster ones die before it).
    """
    lam = [complex(z) for z in eigs]
    lam += [z.conjugate() for z in lam if abs(z.imag) > 1e-12]
    out: list[complex] = []
    n = len(lam)
    for i in range(n):
        for j in range(i, n):
            for k in range(j, n):
                mu = lam[i] + lam[j] + lam[k]
                mu = complex(mu.real, abs(mu.imag))
                if (-mu.real > free * (1.0 + 1e-9) or mu.real * dt <= -MAX_EXPONENT
                        or max(abs(mu.real), abs(mu.imag)) * span < RESOLVABLE):
                    continue          # faster than the free terms, dead, or merged
                # one the window cannot tell from a term it has (lambda_i + lambda_j +
                # 2 Re lambda_k with Re lambda_k ~ 0 is lambda_i + lambda_j) is that term
                if all(max(abs(mu.real - m.real), abs(mu.imag - m.imag)) * span >= RESOLVABLE
                       for m in out + known):
                    out.append(mu)
    return out


class _QuadraticFit(NamedTuple):
    """The linear least squares fit of eq. 13's terms (:func:`_quadratic_fit`)."""

    #: coefficients: the kept columns', then the terms' (cosine, sine for a complex one)
    coef: np.ndarray
    #: residual of every sample
    res: np.ndarray
    #: variance of the first coefficient (E_inf's)
    cov00: float
    #: rms residual
    rms: float
    #: noise floor: NOISE_K x the larger of the noise and the rms residual
    floor: float
    #: (exponent, amplitude) of each term
    terms: list
    #: the slowest rate of the terms that show above the floor and decay resolvably in the
    #: window (NaN if none): the rate fitted free
    free: float


def _quadratic_fit(tau: np.ndarray, y: np.ndarray, cols: list, mus: list, noise: float,
                   span: float) -> _QuadraticFit:
    """Return the fit of eq. 13's terms to ``y`` with the kept columns ``cols``."""
    coef, res, cov00 = _linear_fit(tau, y, cols, mus)
    rms = float(np.sqrt(np.mean(res * res)))
    floor = NOISE_K * max(noise, rms)
    terms = _amplitudes(mus, coef[len(cols):])
    shown = [-mu.real for mu, a in terms if a >= floor and -mu.real * span >= RESOLVABLE]
    return _QuadraticFit(coef, res, cov00, rms, floor, terms, min(shown, default=math.nan))


def _fit_energy(t: np.ndarray, E: np.ndarray, eigs: Sequence[complex], noise: float,
                remainder: float, tail_from: float) -> EnergyFit:
    """Return :func:`fit_energy`'s fit (its doc), BLAS threads as the caller left them."""
    t = np.asarray(t, dtype=float)
    E = np.asarray(E, dtype=float)
    t0 = float(t[0])
    tau = t - t0
    span = float(tau[-1]) if len(tau) else 0.0
    noise = max(float(noise), 16.0 * np.finfo(float).eps * float(np.max(np.abs(E))))
    dt = float(np.median(np.diff(tau))) if len(tau) > 1 else span
    # a term that dies within one sample is no column (the caller starts the window after
    # it, see RotorAnalyzer); one that dies within the window still explains its start
    alive = [mu for mu in _exponents(eigs) if mu.real * dt > -MAX_EXPONENT]
    # merged only where the term changes by less than RESOLVABLE in amplitude and in phase:
    # a slow beat of two modes (Im = the difference of their frequencies) merged while it
    # made less than a period in the window was a line for up to a period of a cosine (a
    # random system over 0 .. 4 s: rms residual 0.089 of E*'s spread, the fit FAILed)
    slow = [mu for mu in alive if abs(mu.imag) * span < RESOLVABLE
            and abs(mu.real) * span < RESOLVABLE]
    mus = [mu for mu in alive if mu not in slow]
    # the slow terms merged into E_inf: their first order, a straight line, stays a column
    # (measured from the window's end, so that E_inf is the slow part's value there)
    cols = [np.ones_like(tau)] + ([tau - span] if slow else [])
    y = E - E[-1]
    fit = _quadratic_fit(tau, y, cols, mus, noise, span)
    third: list[complex] = []
    if math.isfinite(fit.free) and fit.rms >= NOISE_K * noise:
        # more than noise left: E*'s third-order terms as slow as the free terms join the
        # kept columns (one refit)
        third = _third_order(eigs, mus, fit.free, dt, span)
        if third:
            cols = cols + list(_basis(tau, third).T)
            fit = _quadratic_fit(tau, y, cols, mus, noise, span)
    E_inf = float(fit.coef[0] + E[-1])
    trend = float(fit.coef[1]) if slow else 0.0
    sigma = max(math.sqrt(max(fit.cov00, 0.0)), noise)
    spread = float(np.std(E))
    rel = fit.rms / spread if spread > 0 else 0.0
    settled = float(np.ptp(E)) <= NOISE_K * max(noise, remainder)
    rate = lo = hi = math.nan
    note, tail = 'no predicted term of E* - E*_inf decays resolvably above its noise floor', None
    if math.isfinite(fit.free):
        rate, lo, hi, note, scaled = _measure_hull(tau, y, cols, mus, fit.terms, fit.free,
                                                   fit.floor, dt, noise, bool(slow))
        if scaled and math.isfinite(rate) and tail_from > 0:
            late = tau >= tail_from * span
            tail = _fit_energy(t[late], E[late], eigs, noise, remainder, 0.0)
    return EnergyFit(t0=t0, E_inf=E_inf, E_inf_sigma=sigma, rate=rate, rate_lo=lo,
                     rate_hi=hi, rel_residual=rel, spread=spread, trend=trend, span=span,
                     exponents=tuple(mus), coef=tuple(float(c) for c in fit.coef[len(cols):]),
                     noise=noise, floor=fit.floor, remainder=remainder, settled=settled,
                     residual_rms=fit.rms, n_eff=_n_eff(fit.res), rate_note=note,
                     slow=bool(slow), free_rate=fit.free, tail=tail, third=tuple(third))


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
