"""The verdict: a conjunction of named criteria, each PASS, FAIL or NOT YET with its numbers.

The same criteria are evaluated live (the analysis node) and offline (``gyro-rotor
analyze``, the demo), by :class:`gyro_rotor.analysis.analyzer.RotorAnalyzer`:

* **Lyapunov** -- E* never rises beyond the integrator's tolerance (eq. 13 may not
  increase, eq. 17);
* **energy balance** -- the residual |E* + D - E_ref| stays at tolerance level;
* **decay** -- E* approaches its limit E*_inf (fitted from the data) at least as fast as
  the slowest predicted decaying mode allows (:func:`decay_rate_bound`);
* **modes** -- each excited mode identified and matching its prediction; a mode the drive
  does not reach stays undamped;
* **data** -- no message lost, no sample unpaired;
* **synchronism** -- only where the drive law has poles: the rotor is locked in a well
  at the end (after counted pole slips, if any);
* **scene** -- the data are the scene's: E* recomputed from the recorded joints by the
  scene's model is the recorded E*, and a run starts at the scene's initial state
  (:mod:`gyro_rotor.analysis.fit`).

``asymptotically stable`` (or ``marginal``, where the prediction is marginal) is
confirmed only when every criterion that applies passes; otherwise the verdict is
``not confirmed`` (naming the failed criteria), ``insufficient data`` (naming the ones
not yet decided), ``unstable`` or ``diverged``.
"""

from __future__ import annotations

import dataclasses
import enum
import math

__all__ = ['Verdict', 'Status', 'CriterionName', 'ModeStatus', 'SyncState', 'Criterion',
           'Measured', 'decide', 'DECAY_RTOL', 'conjoin', 'over_run', 'combine',
           'decay_rate_bound', 'fmt_rate', 'fmt_tau', 'fmt_re', 'fmt_pm', 'fmt_interval',
           'fmt_against', 'needs_window', 'needs_phrase']


class _Coded(enum.StrEnum):
    """A closed choice sent on a topic as a number: its position in the class."""

    @property
    def code(self) -> int:
        """Numeric code on the topic (the member's position, from 0)."""
        return list(type(self)).index(self)


class Verdict(_Coded):
    """The analysis' verdict; the numeric code on the ``analysis`` topic is its position."""

    INSUFFICIENT_DATA = 'insufficient data'
    ASYMPTOTICALLY_STABLE = 'asymptotically stable'
    MARGINAL = 'marginal'
    UNSTABLE = 'unstable'
    DIVERGED = 'diverged'
    NOT_CONFIRMED = 'not confirmed'

    @property
    def confirmed(self) -> bool:
        """Every applicable criterion passed (stable or, as predicted, marginal)."""
        return self in (Verdict.ASYMPTOTICALLY_STABLE, Verdict.MARGINAL)


class Status(_Coded):
    """The outcome of one criterion; code on the ``analysis`` topic: 0 PASS, 1 FAIL, 2 NOT YET."""

    PASS = 'PASS'
    FAIL = 'FAIL'
    NOT_YET = 'NOT YET'


class CriterionName(enum.StrEnum):
    """The criteria of the verdict, in the order they are reported."""

    LYAPUNOV = 'Lyapunov'
    ENERGY_BALANCE = 'energy balance'
    DECAY = 'decay'
    MODES = 'modes'
    DATA = 'data'
    SYNCHRONISM = 'synchronism'
    SCENE = 'scene'


class ModeStatus(_Coded):
    """A predicted mode against the data; the code on ``analysis_modes`` is its position."""

    NOT_IDENTIFIED = 'not identified'
    DECAYING_AS_PREDICTED = 'decaying as predicted'
    EXPECTED_MARGINAL = 'expected marginal'
    WEAKLY_DAMPED = 'weakly damped'
    NOT_EXCITED = 'not excited'
    DISAGREES = 'disagrees'
    STRUCTURAL_ZERO_ROOT = 'structural zero root'
    #: identified, but the window cannot tell whether it agrees (its interval straddles
    #: the tolerance)
    NOT_RESOLVED = 'not resolved'
    #: faster than the sample grid can show (decays within a sample, or above Nyquist)
    UNOBSERVABLE = 'not observable at this sample rate'
    #: identified and predicted to grow (Re lambda > 0): the steady motion is unstable; never
    #: an agreement that passes
    GROWING = 'growing as predicted (unstable)'


class SyncState(_Coded):
    """Synchronism of a drive with poles; the numeric code is its position."""

    SYNCHRONOUS = 'synchronous'
    LOST = 'lost synchronism'
    RESYNCHRONIZED = 'resynchronized'


@dataclasses.dataclass(frozen=True)
class Criterion:
    """One criterion of the verdict: its status, why (text) and its numbers."""

    name: CriterionName
    status: Status
    detail: str
    numbers: dict = dataclasses.field(default_factory=dict)

    def line(self) -> str:
        """One line of text: ``[PASS] decay: ...``."""
        return f'[{self.status}] {self.name}: {self.detail}'

    def as_dict(self) -> dict:
        """JSON-friendly dict."""
        return {'name': str(self.name), 'status': str(self.status), 'detail': self.detail,
                'numbers': {k: (v if not isinstance(v, float) or math.isfinite(v) else None)
                            for k, v in self.numbers.items()}}


@dataclasses.dataclass(frozen=True)
class Measured:
    """A measured number and its uncertainty interval ``lo .. hi`` (never of zero width).

    ``lo``/``hi`` may be infinite (the data bound it on one side only); NaN ``value``:
    not measured.
    """

    value: float
    lo: float
    hi: float

    @classmethod
    def pm(cls, value: float, u: float) -> 'Measured':
        """Return the interval value +- u."""
        return cls(value, value - u, value + u)

    @property
    def measured(self) -> bool:
        """Return True if a value was measured; its interval may still be unbounded."""
        return math.isfinite(self.value) and not (math.isnan(self.lo) or math.isnan(self.hi))

    @property
    def bounded(self) -> bool:
        """Both ends of the interval are finite."""
        return self.measured and math.isfinite(self.lo) and math.isfinite(self.hi)

    @property
    def u(self) -> float:
        """Half width of the interval (inf if unbounded, NaN if not measured)."""
        if not self.measured:
            return math.nan
        return 0.5 * (self.hi - self.lo)

    def abs_deviation(self, reference: float) -> 'Measured':
        """|value - reference| with its interval (the distance of the interval from it)."""
        d = abs(self.value - reference)
        lo, hi = self.lo - reference, self.hi - reference
        near = 0.0 if lo <= 0.0 <= hi else min(abs(lo), abs(hi))
        return Measured(d, near, max(abs(lo), abs(hi)))

    def as_list(self) -> list:
        """``[value, lo, hi]`` with None for non-finite numbers (JSON)."""
        return [x if math.isfinite(x) else None for x in (self.value, self.lo, self.hi)]


def decide(m: Measured, bound: float, passing: str) -> Status:
    """Decide a criterion by the one rule of every criterion (README, "The verdict").

    PASS only when the whole interval of ``m`` is on the passing side of ``bound``
    (``passing`` 'above': lo >= bound; 'below': hi <= bound), FAIL only when the whole
    interval is on the failing side, NOT YET otherwise (the interval straddles the bound,
    or nothing was measured).
    """
    if passing not in ('above', 'below'):
        raise ValueError(f"passing must be 'above' or 'below', got {passing!r}")
    if not m.measured or math.isnan(bound):
        return Status.NOT_YET
    lo, hi = (m.lo, m.hi) if passing == 'above' else (-m.hi, -m.lo)
    b = bound if passing == 'above' else -bound
    if lo >= b:
        return Status.PASS
    if hi < b:
        return Status.FAIL
    return Status.NOT_YET


def conjoin(statuses) -> Status:
    """Status of a conjunction of tests: FAIL if one fails, PASS if all pass, else NOT YET."""
    statuses = list(statuses)
    if any(s is Status.FAIL for s in statuses):
        return Status.FAIL
    if statuses and all(s is Status.PASS for s in statuses):
        return Status.PASS
    return Status.NOT_YET


def over_run(history: list, current: Criterion | None = None,
             counts: tuple | None = None) -> Criterion | None:
    """Judge a criterion over every window of a run: what the whole run saw.

    ``history``: the criterion evaluated at the checkpoints of a segment, in time order,
    as (t, Criterion); ``current``: the evaluation of the newest window (if it is not the
    last checkpoint); ``counts``: (windows passed, windows judged) if the history is a
    summary. FAIL if one window failed (the first failure, with its time); PASS if a
    window passed and none failed (the last passing window's numbers, how many windows
    passed, and what the newest window says if it no longer decides: a term that decayed
    into the noise floor leaves nothing to measure, which contradicts no earlier
    measurement); NOT YET otherwise (the newest reason).
    """
    items = list(history) + ([(math.nan, current)] if current is not None else [])
    if not items:
        return None
    t_last, last = items[-1]
    fail = next(((t, c) for t, c in items if c.status is Status.FAIL), None)
    if fail is not None:
        t, c = fail
        when = f' (window ending t = {t:.2f} s)' if math.isfinite(t) else ''
        return dataclasses.replace(c, detail=c.detail + when)
    passed = [(t, c) for t, c in items if c.status is Status.PASS]
    if not passed:
        return last
    t, c = passed[-1]
    if c is last:
        return c
    t0 = passed[0][0]
    k, n = counts if counts is not None else (len(passed), len(items))
    if t0 < t:
        span = (f'passed in {k} of {n} windows, the first ending t = {t0:.2f} s, the last '
                f't = {t:.2f} s')
    else:
        span = f'passed in the window ending t = {t:.2f} s' + (f' (1 of {n})' if n > 1 else '')
    # the newest window's own reason: its last clause (the one that did not decide)
    why = last.detail.rsplit('; ', 1)[-1]
    return dataclasses.replace(c, detail=f'{c.detail} ({span}; newest window '
                                         f'{last.status}: {why})')


def needs_window(window_s: float, value: float, u: float) -> float:
    """Window [s] about long enough to resolve ``value`` (+- ``u`` now) at 2 sigma.

    The uncertainty of a rate or frequency fitted over a window falls like 1/window (at
    least): twice the window halves it.
    """
    if not (math.isfinite(u) and math.isfinite(value)) or value == 0:
        return math.inf
    return window_s * max(1.0, 2.0 * u / abs(value))


def needs_phrase(window_s: float, value: float, u: float) -> str:
    """Say how long a window would resolve ``value`` (+- ``u`` now): :func:`needs_window`.

    Never "needs about inf s" (an interval unbounded in this window) nor a window no
    longer than this one (the uncertainty is then not what is missing).
    """
    need = needs_window(window_s, value, u)
    if not math.isfinite(need):
        return 'its uncertainty unbounded in this window: a longer one may tell'
    if need <= window_s:
        return 'not for want of a longer window'
    return f'needs about {need:.3g} s'


def _digits(u: float) -> int:
    """Decimals that show an uncertainty ``u`` with two significant digits."""
    if not math.isfinite(u) or u <= 0:
        return 6
    return max(0, 1 - math.floor(math.log10(u)))


def fmt_pm(value: float, u: float, unit: str = '') -> str:
    """``value +- u unit`` with two significant digits of ``u`` (never a zero width)."""
    tail = f' {unit}' if unit else ''
    if not math.isfinite(value):
        return '-'
    if not math.isfinite(u):
        return f'{value:.4g}{tail} (uncertainty unbounded)'
    if abs(value) >= 1e6 or (value != 0 and abs(value) < 1e-4 and u < abs(value)):
        return f'{value:.{max(2, _sig(value, u))}e} +- {u:.2g}{tail}'
    d = min(_digits(u), 15)
    return f'{value:.{d}f} +- {u:.2g}{tail}'


def _sig(value: float, u: float) -> int:
    """Significant decimals of ``value`` in e-notation that show ``u``."""
    if u <= 0 or value == 0:
        return 6
    return max(1, min(15, int(math.floor(math.log10(abs(value))) - math.floor(math.log10(u)) + 1)))


def _interval_format(m: Measured, extra: int = 0):
    """Return the formatter of :func:`fmt_interval` (``extra`` digits beyond its own)."""
    width = m.hi - m.lo if math.isfinite(m.hi - m.lo) else abs(m.value)
    if abs(m.value) >= 1e6 or (0 < abs(m.value) < 1e-4):
        sig = min((_sig(m.value, 0.5 * width) if width > 0 else 6) + extra, 15)
        return lambda x: f'{x:.{sig}e}' if math.isfinite(x) else ('inf' if x > 0 else '-inf')
    d = min(_digits(0.5 * width if width > 0 else abs(m.value) * 1e-6) + extra, 15)
    return lambda x: f'{x:.{d}f}' if math.isfinite(x) else ('inf' if x > 0 else '-inf')


def fmt_interval(m: Measured, unit: str = '') -> str:
    """``value (interval lo .. hi) unit`` with enough digits that lo and hi differ."""
    if not m.measured:
        return '-'
    f = _interval_format(m)
    return f'{f(m.value)} (interval {f(m.lo)} .. {f(m.hi)}){f" {unit}" if unit else ""}'


def fmt_against(m: Measured, bound: float, unit: str = '') -> tuple[str, str]:
    """Return (:func:`fmt_interval` of m, the bound) printed as :func:`decide` reads them.

    The interval's ends are rounded to show their own width and the bound to 4 significant
    digits; where that rounding would make an end look equal to the bound or on its other
    side (0.412 against 0.4124 for 0.41246 > 0.41243), both get more digits until every
    end reads on its true side: a PASS never stands beside an interval that seems to cross
    its bound.
    """
    text, shown = fmt_interval(m, unit), f'{bound:.4g}'
    if not (m.measured and math.isfinite(bound)):
        return text, shown
    for extra in range(16):
        f = _interval_format(m, extra)
        b = shown if extra == 0 else f(bound)
        if all(not math.isfinite(x) or x == bound
               or (float(f(x)) > float(b)) == (x > bound) and float(f(x)) != float(b)
               for x in (m.lo, m.hi)):
            break
    else:       # ends a few ulp from the bound: the shortest repr tells any two floats apart
        f = (lambda x: repr(float(x)))
        b = f(bound)
    return f'{f(m.value)} (interval {f(m.lo)} .. {f(m.hi)}){f" {unit}" if unit else ""}', b


def combine(criteria: list[Criterion], predicted: str, *, diverged: bool = False,
            unstable: bool = False, marginal_modes: tuple = (),
            identity: str = '') -> tuple[Verdict, str]:
    """Return the verdict of the criteria and a sentence naming what decided it.

    ``predicted`` is the verdict of the linear theory (``'asymptotically stable'`` or
    ``'marginal'`` can be confirmed); ``diverged``/``unstable`` are what the data showed
    beyond any criterion: the integration diverged (a non-finite E*, or the energy identity
    broken: numbers the simulation cannot be trusted with), or the motion grows with the
    identity sound (growing modes: the steady motion is unstable); ``identity`` says the
    identity's numbers; ``marginal_modes`` names the modes the drive does not reach (for a
    marginal verdict).
    """
    failed = [c.name for c in criteria if c.status is Status.FAIL]
    missing = [c.name for c in criteria if c.status is Status.NOT_YET]
    why = f' ({identity})' if identity else ''
    if diverged:
        return Verdict.DIVERGED, f'the integration diverged: energy identity broken{why}'
    if unstable:
        return Verdict.UNSTABLE, (f'the motion grows, the energy identity sound{why}: an '
                                  'unstable steady motion, not a numerical divergence') + (
            f'; failed: {", ".join(failed)}' if failed else '')
    if failed:
        return Verdict.NOT_CONFIRMED, f'failed: {", ".join(failed)}' + (
            f'; not yet decided: {", ".join(missing)}' if missing else '')
    if missing:
        return Verdict.INSUFFICIENT_DATA, f'not yet decided: {", ".join(missing)}' + (
            '' if predicted in (Verdict.ASYMPTOTICALLY_STABLE, Verdict.MARGINAL) else
            f'; the linear theory predicts {predicted}')
    if predicted == Verdict.MARGINAL:
        return Verdict.MARGINAL, ('every criterion passed; marginal as predicted: '
                                  + (', '.join(marginal_modes) or 'modes')
                                  + ' not reached by the drive (undamped)')
    if predicted != Verdict.ASYMPTOTICALLY_STABLE:
        return Verdict.NOT_CONFIRMED, (f'every criterion passed, but the linear theory '
                                       f'predicts {predicted}')
    return Verdict.ASYMPTOTICALLY_STABLE, 'every criterion passed'


def decay_rate_bound(alpha: float) -> float:
    """Least decay rate of E* - E*_inf from the slowest predicted decaying mode.

    E* - E*_inf is quadratic in the deviations (eq. 13), so a mode exp(lambda t) adds
    terms exp(2 Re(lambda) t): E* - E*_inf decays at no less than 2 |alpha|, alpha < 0
    the largest real part among the decaying modes. The one definition of the bound, live
    and offline.
    """
    return -2.0 * alpha if math.isfinite(alpha) and alpha < 0 else math.nan


#: the decay bound 2 |alpha| is that of the linearization; the kicked motion is slightly
#: nonlinear, so the rate of E* - E*_inf is held against (1 - DECAY_RTOL) 2 |alpha| (the
#: bound printed, and published as ``decay_rate_bound``, is that number)
DECAY_RTOL = 0.1


#: relative resolution of a real part from an eigensolver (of |lambda|, in double precision)
RE_RESOLUTION = 1e-12


def fmt_re(re: float, scale: float = 1.0) -> str:
    """Format a real part, 0 where it is below the eigensolver's resolution (never 1e-102)."""
    if not math.isfinite(re):
        return '-'
    if abs(re) <= RE_RESOLUTION * max(abs(scale), 1.0):
        return '0'
    return f'{re:+.6e}'


def fmt_tau(tau: float, longest: float = math.inf) -> str:
    """Format a decay time; beyond ``longest`` (no window could measure it) 'not measurable'."""
    if not math.isfinite(tau) or tau <= 0:
        return 'inf' if not math.isfinite(tau) else '-'
    if tau > longest:
        return 'not measurable'
    return f'{tau:.4g} s'


def fmt_rate(rate: float) -> str:
    """Format a rate [1/s] (``-`` if unknown)."""
    return f'{rate:.4g} 1/s' if math.isfinite(rate) else '-'
