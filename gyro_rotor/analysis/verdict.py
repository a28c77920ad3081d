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
  at the end (after counted pole slips, if any).

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
           'combine', 'decay_rate_bound', 'fmt_rate', 'fmt_tau', 'fmt_re']


class Verdict(enum.StrEnum):
    """The analysis' verdict; the numeric code on the ``analysis`` topic is its position."""

    INSUFFICIENT_DATA = 'insufficient data'
    ASYMPTOTICALLY_STABLE = 'asymptotically stable'
    MARGINAL = 'marginal'
    UNSTABLE = 'unstable'
    DIVERGED = 'diverged'
    NOT_CONFIRMED = 'not confirmed'

    @property
    def code(self) -> int:
        """Numeric code on the ``analysis`` topic."""
        return list(Verdict).index(self)

    @property
    def confirmed(self) -> bool:
        """Every applicable criterion passed (stable or, as predicted, marginal)."""
        return self in (Verdict.ASYMPTOTICALLY_STABLE, Verdict.MARGINAL)


class Status(enum.StrEnum):
    """The outcome of one criterion."""

    PASS = 'PASS'
    FAIL = 'FAIL'
    NOT_YET = 'NOT YET'

    @property
    def code(self) -> int:
        """Numeric code on the ``analysis`` topic (0 PASS, 1 FAIL, 2 NOT YET)."""
        return list(Status).index(self)


class CriterionName(enum.StrEnum):
    """The criteria of the verdict, in the order they are reported."""

    LYAPUNOV = 'Lyapunov'
    ENERGY_BALANCE = 'energy balance'
    DECAY = 'decay'
    MODES = 'modes'
    DATA = 'data'
    SYNCHRONISM = 'synchronism'


class ModeStatus(enum.StrEnum):
    """A predicted mode against the data; the code on ``analysis_modes`` is its position."""

    NOT_IDENTIFIED = 'not identified'
    DECAYING_AS_PREDICTED = 'decaying as predicted'
    EXPECTED_MARGINAL = 'expected marginal'
    WEAKLY_DAMPED = 'weakly damped'
    NOT_EXCITED = 'not excited'
    DISAGREES = 'disagrees'
    STRUCTURAL_ZERO_ROOT = 'structural zero root'

    @property
    def code(self) -> int:
        """Numeric code on ``analysis_modes``."""
        return list(ModeStatus).index(self)


class SyncState(enum.StrEnum):
    """Synchronism of a drive with poles; the numeric code is its position."""

    SYNCHRONOUS = 'synchronous'
    LOST = 'lost synchronism'
    RESYNCHRONIZED = 'resynchronized'

    @property
    def code(self) -> int:
        """Numeric code on the ``analysis`` topic."""
        return list(SyncState).index(self)


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


def combine(criteria: list[Criterion], predicted: str, *, diverged: bool = False,
            unstable: bool = False, marginal_modes: tuple = ()) -> tuple[Verdict, str]:
    """Return the verdict of the criteria and a sentence naming what decided it.

    ``predicted`` is the verdict of the linear theory (``'asymptotically stable'`` or
    ``'marginal'`` can be confirmed); ``diverged``/``unstable`` are what the data showed
    beyond any criterion (a non-finite E*, slips that keep coming, growing modes);
    ``marginal_modes`` names the modes the drive does not reach (for a marginal verdict).
    """
    failed = [c.name for c in criteria if c.status is Status.FAIL]
    missing = [c.name for c in criteria if c.status is Status.NOT_YET]
    if diverged:
        return Verdict.DIVERGED, 'the run diverged'
    if unstable:
        return Verdict.UNSTABLE, 'the data show growth' + (
            f'; failed: {", ".join(failed)}' if failed else '')
    if failed:
        return Verdict.NOT_CONFIRMED, f'failed: {", ".join(failed)}' + (
            f'; not yet decided: {", ".join(missing)}' if missing else '')
    if missing:
        return Verdict.INSUFFICIENT_DATA, f'not yet decided: {", ".join(missing)}'
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
