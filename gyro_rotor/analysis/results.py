"""Results of the analysis: per segment and in total, and their wire layouts.

The ``analysis`` topic (std_msgs/Float64MultiArray, one dimension labelled with
:data:`ANALYSIS_LABEL`) carries :meth:`AnalysisResult.analysis_vector`, the
``analysis_modes`` topic (two dimensions) :meth:`AnalysisResult.mode_matrix`. Pure Python.
"""

from __future__ import annotations

import dataclasses
import math

from gyro_rotor.analysis.decay import EnergyFit
from gyro_rotor.analysis.prediction import Prediction
from gyro_rotor.analysis.verdict import (Criterion, CriterionName, decay_rate_bound, DECAY_RTOL,
                                         ModeStatus, SyncState, Verdict)

__all__ = ['SegmentResult', 'AnalysisResult', 'ANALYSIS_FIELDS', 'ANALYSIS_LABEL',
           'MODE_FIELDS', 'MODE_LABEL', 'VERDICTS', 'MODE_STATUS', 'SYNC_STATES']

#: verdicts, in the order of their numeric code on the ``analysis`` topic
VERDICTS = tuple(str(v) for v in Verdict)
#: per-mode statuses, in the order of their numeric code on ``analysis_modes``
MODE_STATUS = tuple(str(s) for s in ModeStatus)
#: synchronism states, in the order of their numeric code
SYNC_STATES = tuple(str(s) for s in SyncState)
#: the status code of each criterion on the ``analysis`` topic (0 PASS, 1 FAIL, 2 NOT YET,
#: NaN: not applicable)
_STATUS_FIELDS = {CriterionName.LYAPUNOV: 'lyapunov_status',
                  CriterionName.ENERGY_BALANCE: 'energy_balance_status',
                  CriterionName.DECAY: 'decay_status', CriterionName.MODES: 'modes_status',
                  CriterionName.DATA: 'data_status', CriterionName.SYNCHRONISM: 'sync_status',
                  CriterionName.SCENE: 'scene_status'}

#: scalar fields of the ``analysis`` topic (std_msgs/Float64MultiArray, one dimension)
ANALYSIS_FIELDS = (
    't_sim', 'segment', 'samples', 'dropped', 'resets', 'kicks', 'time_jumps',
    'E_star', 'E_inf', 'lyapunov_max_increase', 'lyapunov_violations', 'residual_max',
    'energy_decay_rate', 'deviation_decay_rate', 'spectral_abscissa', 'decay_rate_bound',
    'pole_slips', 'sync_state', 'well', 'verdict', 'modes_matched', 'window_s',
    'E_inf_sigma', 'E_inf_predicted', 'decay_rate_lo', 'decay_rate_hi', 'fit_rel_residual',
    'unpaired') + tuple(_STATUS_FIELDS.values())
ANALYSIS_LABEL = ','.join(ANALYSIS_FIELDS)
#: columns of one row of the ``analysis_modes`` topic (2-D Float64MultiArray, a row per mode)
MODE_FIELDS = ('pred_re', 'pred_im', 'meas_re', 'meas_im', 'pred_tau', 'meas_tau',
               'amplitude', 'status', 'meas_re_u', 'meas_im_u', 't_seen')
MODE_LABEL = ','.join(MODE_FIELDS)


def _finite_or_none(d: dict) -> dict:
    for k, v in d.items():
        if isinstance(v, float) and not math.isfinite(v):
            d[k] = None
    return d


@dataclasses.dataclass
class SegmentResult:
    """Everything measured over one segment (one run without reset, kick or change)."""

    index: int
    reason: str
    scene: str
    t_start: float
    t_end: float
    samples: int
    E_first: float
    E_last: float
    E_inf: float
    lyapunov_max_increase: float
    lyapunov_violations: int
    residual_max: float
    energy_decay_rate: float
    deviation_decay_rate: float
    window_s: float
    modes: list
    pole_slips: int
    sync_state: SyncState
    well: int
    verdict: Verdict
    evidence: list
    energy_fit: EnergyFit | None = None
    #: (root, text) of resolved lasting oscillations no mode explains (the newest window)
    unexplained: list = dataclasses.field(default_factory=list)
    criteria: list = dataclasses.field(default_factory=list)
    non_finite: bool = False
    #: (root, text) of combination tones in the newest window
    combinations: list = dataclasses.field(default_factory=list)
    #: identified roots whose growth is resolved (the newest window, or any before)
    growing: list = dataclasses.field(default_factory=list)
    #: the windows judged in this segment: (how many, end of the first, end of the last)
    windows: tuple = ()
    #: where the fits start: after the last pole slip, once the drive is back in its linear
    #: range (NaN: the window's own start)
    fit_from: float = math.nan
    #: the newest window's fit that measured a rate (if the newest window did not)
    rate_fit: EnergyFit | None = None
    #: samples missing from the newest window (lost messages): it is not fitted
    missing: int = 0
    #: max |E* + D - E_ref| computed from the recorded E* and D (E_ref = E* + D - residual
    #: at the segment's first sample), and the largest difference from the recorded residual
    balance_max: float = 0.0
    balance_mismatch: float = 0.0
    #: samples whose recorded E* and D gave the balance (0: D not recorded)
    balance_n: int = 0
    #: the energy identity: the largest |r| / bound of the recorded residual and of the
    #: balance (:func:`~gyro_rotor.numerics.guard.excess`; above 1: diverged), the time of
    #: that sample, its |r| and the bound there [J]
    identity_excess: float = 0.0
    identity_t: float = math.nan
    identity_r: float = 0.0
    identity_bound: float = math.nan
    #: the same for the energy balance criterion's limit (residual_warn; recorded residual,
    #: balance and their mismatch): above 1 the criterion fails
    balance_excess: float = 0.0
    balance_t: float = math.nan
    balance_r: float = 0.0
    balance_bound: float = math.nan

    def as_dict(self) -> dict:
        """JSON-friendly dict."""
        skip = ('modes', 'energy_fit', 'unexplained', 'criteria', 'combinations', 'growing',
                'rate_fit')
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
             if f.name not in skip}
        d['sync_state'], d['verdict'] = str(self.sync_state), str(self.verdict)
        d['modes'] = [m.as_dict() for m in self.modes]
        d['criteria'] = [c.as_dict() for c in self.criteria]
        d['unexplained'] = [_root(r, text) for r, text in self.unexplained]
        d['combinations'] = [_root(r, text) for r, text in self.combinations]
        d['growing'] = [_root(r, '') for r in self.growing]
        f = self.energy_fit
        if f is not None:
            d['energy_fit'] = _finite_or_none({
                't0': f.t0, 'E_inf': f.E_inf, 'E_inf_sigma': f.E_inf_sigma, 'rate': f.rate,
                'rate_lo': f.rate_lo, 'rate_hi': f.rate_hi, 'rel_residual': f.rel_residual,
                'noise': f.noise, 'settled': f.settled, 'n_eff': f.n_eff})
        return _finite_or_none(d)


def _root(r, text: str) -> dict:
    """Return a root of :mod:`~gyro_rotor.analysis.modes` as JSON."""
    return {'eigenvalue': [r.value.real, r.value.imag], 're': r.re.as_list(),
            'im': r.im.as_list(), 'share': r.share, 'text': text}


@dataclasses.dataclass
class AnalysisResult:
    """The analysis so far: totals, criteria, the prediction and the segments (last: current).

    ``judged`` is the segment the decay and mode criteria were evaluated on (the last one
    long enough to fit, else the current one).
    """

    scene: str
    prediction: Prediction
    samples: int
    dropped: int
    resets: int
    kicks: int
    time_jumps: int
    param_changes: int
    pole_slips: int
    segments: list
    verdict: Verdict
    evidence: list
    level: str
    t_sim: float
    criteria: list = dataclasses.field(default_factory=list)
    reason: str = ''
    unpaired: int = 0
    judged: SegmentResult | None = None
    #: messages at the cut of a recording without their partner (not counted as unpaired)
    cut: int = 0
    #: where the recording was cut ('' if it was not)
    truncated: str = ''

    @property
    def current(self) -> SegmentResult | None:
        """Return the last segment (None before data)."""
        return self.segments[-1] if self.segments else None

    @property
    def confirmed(self) -> bool:
        """Every applicable criterion passed (see :class:`~.verdict.Verdict`)."""
        return self.verdict.confirmed

    def criterion(self, name: CriterionName) -> Criterion | None:
        """Return the criterion ``name`` (None if it does not apply)."""
        return next((c for c in self.criteria if c.name == name), None)

    def as_dict(self) -> dict:
        """JSON-friendly dict."""
        pred = self.prediction
        return {
            'scene': self.scene, 'verdict': str(self.verdict), 'confirmed': self.confirmed,
            'reason': self.reason, 'level': self.level,
            'criteria': [c.as_dict() for c in self.criteria],
            'evidence': list(self.evidence), 't_sim': self.t_sim, 'samples': self.samples,
            'dropped': self.dropped, 'unpaired': self.unpaired, 'cut': self.cut,
            'truncated': self.truncated, 'resets': self.resets,
            'kicks': self.kicks, 'time_jumps': self.time_jumps,
            'param_changes': self.param_changes, 'pole_slips': self.pole_slips,
            'judged_segment': self.judged.index if self.judged is not None else None,
            'prediction': {
                'source': pred.source, 'coords': pred.coords, 'verdict': pred.verdict,
                'spectral_abscissa': pred.spectral_abscissa, 'E_inf': pred.E_inf,
                'decay_rate_bound': _none(decay_rate_bound(pred.decaying_abscissa)),
                'modes': [{'name': m.name, 'eigenvalue': [m.eigenvalue.real,
                                                          m.eigenvalue.imag],
                           'freq_hz': m.freq_hz, 'tau_s': _none(m.tau),
                           'reached_by_drive': m.reached_by_drive, 'marginal': m.marginal}
                          for m in pred.modes]},
            'segments': [s.as_dict() for s in self.segments],
        }

    def _rate_bound(self) -> float:
        """Return the bound the decay criterion held the rate against.

        (1 - DECAY_RTOL) x the slowest predicted term of E* the fit shows; where the
        criterion has none, (1 - DECAY_RTOL) 2|alpha| of the prediction.
        """
        decay = self.criterion(CriterionName.DECAY)
        bound = decay.numbers.get('rate_bound', math.nan) if decay is not None else math.nan
        if bound is not None and math.isfinite(bound):
            return bound
        return (1.0 - DECAY_RTOL) * decay_rate_bound(self.prediction.decaying_abscissa)

    def analysis_vector(self) -> list[float]:
        """Values of :data:`ANALYSIS_FIELDS` (NaN where not available)."""
        s = self.judged if self.judged is not None else self.current
        nan = math.nan
        fit = s.energy_fit if s is not None else None
        rate_fit = (s.rate_fit or fit) if s is not None else None
        vals = {
            't_sim': self.t_sim, 'segment': s.index if s else nan, 'samples': self.samples,
            'dropped': self.dropped, 'resets': self.resets, 'kicks': self.kicks,
            'time_jumps': self.time_jumps,
            'E_star': self.current.E_last if self.current else nan,
            'E_inf': fit.E_inf if fit else nan, 'E_inf_sigma': fit.E_inf_sigma if fit else nan,
            'E_inf_predicted': self.prediction.E_inf,
            'lyapunov_max_increase': max((x.lyapunov_max_increase for x in self.segments
                                          if math.isfinite(x.lyapunov_max_increase)),
                                         default=nan),
            'lyapunov_violations': sum(x.lyapunov_violations for x in self.segments),
            'residual_max': max((x.residual_max for x in self.segments), default=nan),
            'energy_decay_rate': rate_fit.rate if rate_fit else nan,
            'decay_rate_lo': rate_fit.rate_lo if rate_fit else nan,
            'decay_rate_hi': rate_fit.rate_hi if rate_fit else nan,
            'fit_rel_residual': fit.rel_residual if fit else nan,
            'deviation_decay_rate': s.deviation_decay_rate if s else nan,
            'spectral_abscissa': self.prediction.spectral_abscissa,
            'decay_rate_bound': self._rate_bound(),
            'pole_slips': self.pole_slips,
            'sync_state': s.sync_state.code if s else nan,
            'well': s.well if s else nan, 'verdict': self.verdict.code,
            'modes_matched': (sum(m.measured is not None for m in s.modes) if s else nan),
            'window_s': s.window_s if s else nan, 'unpaired': self.unpaired,
        }
        for name, field in _STATUS_FIELDS.items():
            c = self.criterion(name)
            vals[field] = c.status.code if c is not None else nan
        return [float(vals[f]) for f in ANALYSIS_FIELDS]

    def mode_matrix(self) -> tuple[list[str], list[list[float]]]:
        """Mode names and rows of :data:`MODE_FIELDS` for the judged segment."""
        s = self.judged if self.judged is not None else self.current
        names, rows = [], []
        nan = math.nan
        for m in (s.modes if s else []):
            meas = m.measured if m.measured is not None else complex(nan, nan)
            names.append(m.name)
            rows.append([m.predicted.real, m.predicted.imag, meas.real, meas.imag,
                         m.pred_tau, m.meas_tau, m.amplitude, float(m.status.code),
                         m.rate.u if m.rate is not None else nan,
                         m.freq.u if m.freq is not None else nan,
                         m.seen[1] if m.seen else nan])
        return names, rows


def _none(x: float):
    return x if math.isfinite(x) else None
