"""What the windows of a segment saw, kept in constant memory: :class:`RunRecord`.

The analyzer judges the window at every checkpoint (:mod:`~gyro_rotor.analysis.analyzer`);
the decay and modes criteria and the modes' statuses say what all those windows saw
(:func:`~gyro_rotor.analysis.verdict.over_run`: a failure in any window fails, a pass
stands once no window failed). A node may run for hours, so the windows are not kept:
per criterion the first failure, the first and the last pass and the newest window; per
mode the first disagreement, the first and last window that showed it as predicted and
when it was gone after that. Pure Python.
"""

from __future__ import annotations

import dataclasses
import math

from gyro_rotor.analysis.verdict import CriterionName, ModeStatus, over_run, Status

__all__ = ['RunRecord', 'AGREE']

#: a mode identified as the prediction says
AGREE = (ModeStatus.DECAYING_AS_PREDICTED, ModeStatus.EXPECTED_MARGINAL,
         ModeStatus.WEAKLY_DAMPED, ModeStatus.STRUCTURAL_ZERO_ROOT)
_JUDGED = (CriterionName.DECAY, CriterionName.MODES)
#: resolved growing roots kept (a growth shown once is enough to say 'unstable')
_MAX_GROWING = 8


@dataclasses.dataclass
class _Mode:
    bad: tuple | None = None         # (t, check) of the first window that disagreed
    first: float = math.nan          # end of the first window that showed it as predicted
    good: tuple | None = None        # (t, check) of the newest such window
    gone: float = math.nan           # end of the first window after that which did not


class RunRecord:
    """The judged windows of one segment, summarized (module doc)."""

    def __init__(self):
        self.n = 0
        self.first_t = math.nan
        self.last_t = math.nan
        #: the newest window's result (the analyzer reuses it while no sample came since)
        self.last = None
        self.rate_fit = None
        self.growing: list = []
        self._crit: dict = {name: {} for name in _JUDGED}
        self._modes: dict = {}

    def copy(self) -> RunRecord:
        """Return a copy to add a window to without changing this record."""
        out = RunRecord()
        out.n, out.first_t, out.last_t, out.last = self.n, self.first_t, self.last_t, self.last
        out.rate_fit, out.growing = self.rate_fit, list(self.growing)
        out._crit = {k: dict(v) for k, v in self._crit.items()}
        out._modes = {k: dataclasses.replace(v) for k, v in self._modes.items()}
        return out

    def add(self, w) -> None:
        """Add a judged window (a SegmentResult whose criteria are the window's own)."""
        t = w.t_end
        self.n += 1
        self.first_t = t if self.n == 1 else self.first_t
        self.last_t, self.last = t, w
        if w.energy_fit is not None and math.isfinite(w.energy_fit.rate):
            self.rate_fit = w.energy_fit
        self.growing = (self.growing + list(w.growing))[:_MAX_GROWING]
        for c in w.criteria:
            if c.name not in self._crit:
                continue
            rec = self._crit[c.name]
            if c.status is Status.FAIL and 'fail' not in rec:
                rec['fail'] = (t, c)
            if c.status is Status.PASS:
                rec.setdefault('first_pass', (t, c))
                rec['last_pass'] = (t, c)
            rec['last'] = (t, c)
            rec['n'] = rec.get('n', 0) + 1
            rec['n_pass'] = rec.get('n_pass', 0) + (c.status is Status.PASS)
        for c in w.modes:
            m = self._modes.setdefault(c.name, _Mode())
            if c.status is ModeStatus.DISAGREES and m.bad is None:
                m.bad = (t, c)
            if c.status in AGREE:
                m.first = t if m.good is None else m.first
                m.good, m.gone = (t, c), math.nan
            elif m.good is not None and math.isnan(m.gone):
                m.gone = t

    def criterion(self, name: CriterionName):
        """Return the criterion ``name`` over the windows (:func:`verdict.over_run`)."""
        rec = self._crit[name]
        items = [rec[k] for k in ('first_pass', 'last_pass', 'fail') if k in rec]
        if 'last' not in rec:
            return None
        return over_run(items + [rec['last']], counts=(rec['n_pass'], rec['n']))

    def modes(self, newest: list) -> list:
        """Each mode as the windows saw it, given the newest window's checks.

        A mode that disagreed in a window keeps that window's check (and says when); one
        that agreed keeps its newest agreeing check, with the windows it was seen in and,
        if the newest window no longer shows it, when it decayed below the noise floor.
        """
        out = []
        for cur in newest:
            m = self._modes.get(cur.name, _Mode())
            if m.bad is not None:
                t, c = m.bad
                out.append(dataclasses.replace(c, run_status=f'disagrees (window ending '
                                                             f't = {t:.2f} s)'))
                continue
            if m.good is None:
                out.append(cur)
                continue
            t1, c = m.good
            when = (f'windows ending t = {m.first:.2f} .. {t1:.2f} s' if t1 > m.first else
                    f'window ending t = {t1:.2f} s')
            text = f'{c.status} in the {when}'
            if cur.status in (ModeStatus.NOT_EXCITED, ModeStatus.NOT_IDENTIFIED) and \
                    math.isfinite(m.gone):
                text += f'; decayed below the noise floor by t = {m.gone:.2f} s'
            elif cur.status not in AGREE and cur.status is not c.status:
                note = f' ({cur.note})' if cur.note else ''
                text += f'; newest window: {cur.status}{note}'
            if c.note and cur.status in AGREE:
                text += f' ({c.note})'
            out.append(dataclasses.replace(c, seen=(m.first, t1), run_status=text))
        return out
