"""Streaming stability analysis of one simulation: :class:`RotorAnalyzer` (pure Python).

Fed with paired samples (:mod:`gyro_rotor.analysis.samples`) of the simulation node's
``energy`` and ``joint_states`` topics, live by the analysis node and offline from a bag
(:mod:`gyro_rotor.analysis.offline`): the same class, the same numbers. Data events start
a new *segment* (fits never mix segments): resets (t_sim or the grid index going back),
time jumps, kicks (E* + D jumping either way, the residual continuous: the node's
``~/perturb``, :func:`_kick_jump`) and
parameter changes; sequence gaps are counted. Over a sliding window of the last segment
long enough to fit it measures E*_inf and the decay of E* (:mod:`~.decay`), the modes
(:mod:`~.modes`), the deviation envelope and pole slips (sine law with p pole pairs:
passages of z over the maxima of the drive potential, z = (2k+1) pi / p). The verdict is
the conjunction of the named criteria of :mod:`~.verdict` (:mod:`~.criteria`).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Iterable

from gyro_rotor.analysis import criteria as crit
from gyro_rotor.analysis.decay import (envelope_decay_rate, fit_energy, MAX_EXPONENT,
                                       REMAINDER_SHARE)
from gyro_rotor.analysis.fit import joint_names, SceneFit
from gyro_rotor.analysis.modes import check_modes, ModeCheck, ModesFound, tone_line
from gyro_rotor.analysis.prediction import GENERAL_COORDS, predict, Prediction
from gyro_rotor.analysis.results import AnalysisResult, SegmentResult
from gyro_rotor.analysis.ring import RowRing
from gyro_rotor.analysis.run import RunRecord
from gyro_rotor.analysis.samples import Sample
from gyro_rotor.analysis.verdict import (combine, CriterionName, ModeStatus, Status, SyncState,
                                         Verdict)
from gyro_rotor.core.scene import Scene
from gyro_rotor.errors import AnalysisError, ParameterError
from gyro_rotor.numerics.guard import bound, excess, RELATIVE_LIMIT
import numpy as np

__all__ = ['RotorAnalyzer', 'limit_blas_threads']

_TWO_PI = 2.0 * math.pi
_BLAS_LIMITED = False
#: a sine-law drive is in its linear range while |p (z - well bottom)| stays below this
#: [rad]: the potential's nonlinearity then shifts the drive's frequency by less than
#: (0.5)^2 / 16 = 1.6 %, within the modes' frequency tolerance (2 %)
LINEAR_DRIVE = 0.5


def limit_blas_threads(n: int = 1) -> bool:
    """Limit numpy's bundled OpenBLAS to ``n`` threads; return whether it worked.

    The analysis runs beside the simulator on a small machine; a multithreaded OpenBLAS
    spin-waits when the cores are busy: the SVD of one window (2280 x 121) took 3 to 5 s
    with 2 threads under load and 0.05 s with one (measured here on 2 cores), long enough
    for the node to miss messages. Environment variables would have to be set before numpy
    is loaded, so the library's own ``*_set_num_threads`` is called instead.
    """
    import ctypes
    import glob
    import os
    libdir = os.path.join(os.path.dirname(np.__file__), os.pardir, 'numpy.libs')
    for lib in glob.glob(os.path.join(libdir, '*openblas*')):
        try:
            dll = ctypes.CDLL(lib)
        except OSError:
            continue
        for name in ('scipy_openblas_set_num_threads64_', 'scipy_openblas_set_num_threads',
                     'openblas_set_num_threads64_', 'openblas_set_num_threads'):
            fn = getattr(dll, name, None)
            if fn is not None:
                fn(int(n))
                return True
    return False


class _Segment:
    """Raw data of one segment (ring-buffered to ``max_samples``, decimated to keep a span).

    The ring keeps every :attr:`stride`-th sample of the segment. When it is full and its
    rows span less than the time the fits need (``keep_s`` of :meth:`add`: the window, at
    least the shortest fitted one), every other row is dropped and the stride doubled: a
    cap on samples thins the window, never shortens it below what a fit needs.
    """

    def __init__(self, index: int, reason: str, scene: Scene, pred: Prediction,
                 max_samples: int):
        self.index, self.reason, self.scene, self.pred = index, reason, scene, pred
        self.max_samples = max_samples
        self.rows = RowRing(max_samples)
        self.stride = 1
        self.gaps: list = []          # (t, messages lost just before it) by sequence gaps
        self.samples = 0
        self.t_start = math.nan
        self.E_first = math.nan
        self.lyap_max = -math.inf
        self.lyap_violations = 0
        self.residual_max = 0.0
        #: E_ref of the segment (E* + D - residual at its first finite sample), max |E* + D -
        #: E_ref| from the recorded E* and D, and its largest difference from the residual
        self.E_ref = math.nan
        self.balance_max = 0.0
        self.balance_mismatch = 0.0
        self.balance_n = 0
        #: the sample with the largest |r| / bound (:func:`~gyro_rotor.numerics.guard.excess`):
        #: that ratio, its time, |r| and the bound there
        self.identity_excess = 0.0
        self.identity_t = math.nan
        self.identity_r = 0.0
        self.identity_bound = math.nan
        #: the same for the energy balance criterion's limit (``residual_warn``), its
        #: recorded residual, balance and their mismatch: ratio, time, |r|, bound
        self.balance_excess = 0.0
        self.balance_t = math.nan
        self.balance_r = 0.0
        self.balance_bound = math.nan
        self.slips = 0
        self.last_slip_t = -math.inf
        self.wells: dict = {}     # rotor -> the well its z last arrived in (hysteresis)
        self.lags: tuple = ()     # the rotor lags of the last sample that had them
        self.last: Sample | None = None
        self.fit: dict = {}
        #: what the windows judged at the checkpoints saw
        self.record = RunRecord()
        self.checkpoint = -1          # index k of the last checkpoint t = k * period
        self.last_nonlinear_t = -math.inf   # last sample with a drive beyond LINEAR_DRIVE

    def add(self, s: Sample, row: tuple, keep_s: float = math.inf) -> None:
        if self.samples == 0:
            self.t_start, self.E_first = s.t, s.E_star
        i = self.samples
        self.samples += 1
        self.last = s
        if i % self.stride:
            return
        self.rows.append(row)
        if len(self.rows) == self.rows.capacity and self.rows.capacity > 1:
            R = self.rows.array()
            if R[-1, 0] - R[0, 0] < keep_s:
                # the rows' sample indices i - stride (n-1-j); keep those on the new grid
                idx = i - self.stride * np.arange(len(R) - 1, -1, -1)
                self.rows = RowRing(self.rows.capacity, R.shape[1])
                for r in R[idx % (2 * self.stride) == 0]:
                    self.rows.append(r)
                self.stride *= 2


def check_window(window_s) -> float:
    """Return the fit window [s] (inf for 0, inf or None: whole segments); refuse < 0, NaN."""
    if window_s is None:
        return math.inf
    try:
        w = float(window_s)
    except (TypeError, ValueError):
        raise ParameterError(f'window_s must be a number of seconds, got {window_s!r}') from None
    if math.isnan(w) or w < 0:
        raise ParameterError(f'window_s must be >= 0 s (0 = whole segments), got {w!r}')
    return w if w > 0 and math.isfinite(w) else math.inf


class RotorAnalyzer:
    """Streaming stability analysis of one simulation (see module doc).

    Parameters
    ----------
    scene : Scene
        The scene the data come from (parameters, steady motion).
    window_s : float
        Length of the sliding window of the decay and mode fits [s]; 0 or inf = the whole
        segment (offline).
    lyapunov_tol : float
        Largest increase of E* between two samples counted as integration noise [J]
        (plus ``lyapunov_rtol`` |E*|).
    residual_warn : float
        |energy-balance residual| above which the result is WARN [J].
    diverge_residual : float
        The run counts as diverged where |residual| (recorded, or computed from E* and D)
        exceeds max(this, 1e-6 x max(|E*|, |E_ref|)) [J]: the rule of the simulation's
        guard (:mod:`gyro_rotor.numerics.guard`), stricter than its default limit. Growth
        with the identity sound is no divergence: the verdict is then ``unstable``.
    sync_hold_s : float
        A slip within this time keeps the state 'lost synchronism' [s].
    min_fit_s : float
        Shortest window for fits [s].
    max_window_samples : int
        Samples kept per segment: beyond it the window is thinned (every other sample
        dropped), never shortened below the window or ``min_fit_s`` (:class:`_Segment`).
    blas_threads : int
        Limit numpy's OpenBLAS to this many threads (0 = leave it), see
        :func:`limit_blas_threads`.
    checkpoint_s : float
        The window is judged whenever simulation time passes a multiple of this [s] (the
        same times live and offline, however often results are asked for); the decay
        and modes criteria say what these windows saw over the run (0 = only the newest).
    combination_tones : bool
        Name identified roots at the sum or difference of two modes' frequencies as
        combination tones (False: they count as unexplained; for the tests' mutations).
    """

    def __init__(self, scene: Scene, *, window_s: float = 8.0, lyapunov_tol: float = 1e-8,
                 lyapunov_rtol: float = 1e-9, residual_warn: float = 1e-6,
                 diverge_residual: float = 1e-2, sync_hold_s: float = 1.0,
                 min_fit_s: float = 2.0, max_window_samples: int = 20000,
                 blas_threads: int = 1, checkpoint_s: float = 1.0,
                 combination_tones: bool = True):
        if not isinstance(scene, Scene):
            raise AnalysisError('RotorAnalyzer needs a Scene')
        self.window_s = check_window(window_s)
        self.lyapunov_tol = float(lyapunov_tol)
        self.lyapunov_rtol = float(lyapunov_rtol)
        self.residual_warn = float(residual_warn)
        self.diverge_residual = float(diverge_residual)
        self.sync_hold_s = float(sync_hold_s)
        self.min_fit_s = float(min_fit_s)
        self.max_window_samples = int(max_window_samples)
        self.checkpoint_s = float(checkpoint_s)
        self.combination_tones = bool(combination_tones)
        global _BLAS_LIMITED
        if blas_threads and not _BLAS_LIMITED:
            _BLAS_LIMITED = limit_blas_threads(blas_threads)
        self.scene = scene
        self.prediction = predict(scene)
        self._fit = SceneFit(scene, joint_names(scene))
        #: what differed between the data and the scene (the ``scene`` criterion)
        self.fit_problems: list[str] = []
        self.fit_checks = 0
        #: of those, the samples that began a run (checked against the scene's initial state)
        self.fit_starts = 0
        self.samples = 0
        self.dropped = 0
        #: of the dropped, those before the first sample of a simulation (:meth:`_lost_before`)
        self.lost_first = 0
        self.resets = 0
        self.kicks = 0
        self.time_jumps = 0
        self.param_changes = 0
        self.non_finite = 0
        #: the recorded fields that were non-finite in some sample
        self.non_finite_fields: set = set()
        #: samples left unpaired by the caller's SamplePairer (data loss; set by the session)
        self.unpaired = 0
        #: recorded messages a damaged bag lost, and the reader's line on it (set offline)
        self.bag_lost = 0
        self.bag_loss = ''
        #: messages at the cut of a recording without their partner (not counted as
        #: unpaired), and where the recording was cut ('' if it was not); set by the caller
        self.cut = 0
        self.truncated = ''
        self.segments: list[_Segment] = []
        self._done: list[SegmentResult] = []
        self._last: Sample | None = None
        self._dt: float | None = None

    # -- input --------------------------------------------------------------------------------
    def set_scene(self, scene: Scene) -> bool:
        """Switch to new scene parameters (a new segment); return whether they changed."""
        if scene == self.scene or _same_physics(scene, self.scene):
            return False
        self.scene = scene
        self.prediction = predict(scene)
        self._fit = SceneFit(scene, joint_names(scene))
        self.param_changes += 1
        if self.segments:
            self._new_segment('parameters changed')
        return True

    def add(self, s: Sample) -> None:
        """Feed one sample (in publication order)."""
        last = self._last
        reason = None
        if last is None:
            reason = 'start'
            self._lost_before(s)
        else:
            if s.seq > last.seq + 1:
                self.dropped += s.seq - last.seq - 1
            elif s.seq <= last.seq:
                reason = 'simulation restarted (sequence went back)'
                self.resets += 1
                self._lost_before(s)
            if reason is None:
                dt = s.t - last.t
                if s.t < last.t or (s.k >= 0 and 0 <= s.k < last.k):
                    reason = 'reset (simulation time went back)'
                    self.resets += 1
                else:
                    step = self._dt or dt
                    nseq = max(1, s.seq - last.seq)
                    if step > 0 and dt > (nseq + 0.5) * step:
                        reason = f'time jump of {dt:.6g} s'
                        self.time_jumps += 1
                    elif dt > 0 and s.seq == last.seq + 1:
                        self._dt = dt if self._dt is None else self._dt
            if reason is None:
                tol = self.lyapunov_tol + self.lyapunov_rtol * max(abs(s.E_star),
                                                                   abs(last.E_star))
                # a kick's sample that this one undoes was one corrupt message
                jump = 0.0 if self._undo_kick(s, tol) else _kick_jump(last, s, tol)
                if jump:
                    # E* + D jumped, in either direction, and the residual E* + D - E_ref
                    # did not: an external kick (~/perturb rebases E_ref), not a Lyapunov
                    # violation nor an integration error (which moves the residual with it)
                    reason = f'kick (E* + D changed by {jump:+.6g} J)'
                    self.kicks += 1
        self.samples += 1
        bad = [k for k, v in self._recorded(s).items() if not math.isfinite(v)]
        if bad:
            self.non_finite += 1
            self.non_finite_fields.update(bad)
        elif s.dissipation is not None and s.dissipation != -s.dE_dt:
            # the simulation writes dissipation = -dE_dt exactly: one of them is corrupt
            self.non_finite += 1
            self.non_finite_fields.add('dissipation != -dE_dt')
        if reason is not None:
            self._new_segment(reason)
        seg = self.segments[-1]
        if reason is None and s.seq > last.seq + 1:
            seg.gaps.append((s.t, s.seq - last.seq - 1))
        self._add_to_segment(seg, s, last if reason is None else None)
        self._last = s
        if reason is not None:
            self._check_fit(s, start=s.k == 0 and not reason.startswith(('kick', 'time',
                                                                         'param')))
        if self.checkpoint_s > 0 and math.isfinite(s.t):
            k = math.floor(s.t / self.checkpoint_s + 1e-6)
            if k > seg.checkpoint:
                seg.checkpoint = k
                self._check_fit(s, start=False)
                res = self._evaluate(seg, judge=False)
                if res.energy_fit is not None:
                    seg.record.add(res)

    def _lost_before(self, s: Sample) -> None:
        """Count the messages lost before the first sample of a simulation (seq from 0).

        The simulation numbers its samples from 0 over its life (a reset goes on counting,
        a restarted node starts at 0 again): a first sample with seq n > 0 comes after n
        that were published and never received (a recording or an analysis begun late).
        """
        if s.seq > 0:
            self.dropped += s.seq
            self.lost_first += s.seq

    def _check_fit(self, s: Sample, start: bool) -> None:
        """Hold a sample against the scene (:mod:`~gyro_rotor.analysis.fit`)."""
        fit = self._fit
        starts, energies = fit.starts, fit.energies
        if start:
            fit.on_start(s)
        fit.on_sample(s)
        self.fit_starts += fit.starts - starts
        self.fit_checks += fit.starts + fit.energies - starts - energies
        for p in fit.problems:
            if p not in self.fit_problems:
                self.fit_problems.append(p)

    def add_many(self, samples: Iterable[Sample]) -> None:
        """Feed several samples."""
        for s in samples:
            self.add(s)

    def _undo_kick(self, s: Sample, tol: float) -> bool:
        """Take back a kick that ``s``, the next sample, undoes; return whether it did.

        A kick rebases E_ref = E* + D - residual for good; a single corrupt message (E* or
        D) moves it there and back. If the newest segment is a kick's with one sample and
        ``s`` is back on the previous segment's E_ref, that sample joins the previous
        segment again (where the energy balance judges it) and the kick is not counted.
        """
        seg = self.segments[-1]
        if len(self.segments) < 2 or seg.samples != 1 or not seg.reason.startswith('kick'):
            return False
        old = self.segments[-2]
        if not abs(s.E_star + s.D - s.residual - old.E_ref) <= tol:
            return False
        self.segments.pop()
        self._done.pop()
        self.kicks -= 1
        old.gaps += seg.gaps
        self._add_to_segment(old, seg.last, old.last)
        return True

    def _new_segment(self, reason: str) -> None:
        if self.segments:
            self._done.append(self._evaluate(self.segments[-1]))
        self.segments.append(_Segment(len(self.segments), reason, self.scene,
                                      self.prediction, self.max_window_samples))

    def _add_to_segment(self, seg: _Segment, s: Sample, prev: Sample | None) -> None:
        pred = seg.pred
        if prev is not None:
            rise = s.E_star - prev.E_star
            seg.lyap_max = max(seg.lyap_max, rise)
            if rise > self.lyapunov_tol + self.lyapunov_rtol * abs(s.E_star):
                seg.lyap_violations += 1
        if math.isfinite(s.residual):
            seg.residual_max = max(seg.residual_max, abs(s.residual))
        # the energy balance from the recorded E* and D themselves, not only the residual
        if not math.isfinite(seg.E_ref):
            seg.E_ref = s.E_star + s.D - s.residual
        bal = s.E_star + s.D - seg.E_ref
        if math.isfinite(bal):
            seg.balance_n += 1
            seg.balance_max = max(seg.balance_max, abs(bal))
            if math.isfinite(s.residual):
                seg.balance_mismatch = max(seg.balance_mismatch, abs(bal - s.residual))
        # E_ref needs a recorded D; without it the bound's energy scale is E* alone
        ref = float(seg.E_ref) if math.isfinite(seg.E_ref) else float(s.E_star)
        for r in (s.residual, bal):
            if math.isfinite(r):
                x = excess(float(r), float(s.E_star), ref, self.diverge_residual)
                if x > seg.identity_excess:
                    seg.identity_excess, seg.identity_t, seg.identity_r = x, s.t, abs(r)
                    seg.identity_bound = bound(float(s.E_star), ref, self.diverge_residual)
        # the energy balance criterion: the same rule with its own limit (residual_warn)
        for r in (s.residual, bal, bal - s.residual):
            if math.isfinite(r):
                x = excess(float(r), float(s.E_star), ref, self.residual_warn)
                if x > seg.balance_excess:
                    seg.balance_excess, seg.balance_t, seg.balance_r = x, s.t, abs(r)
                    seg.balance_bound = bound(float(s.E_star), ref, self.residual_warn)
        # synchronism: passages of each z over the potential maxima (2k+1) pi / p
        # with hysteresis: the well index changes only once z is within pi/(2p) of the
        # bottom of another well, so jitter on a maximum counts nothing
        lags = self._lags(s)
        if lags:
            seg.lags = lags
        for r, (p, z) in enumerate(zip(pred.rotor_pole_pairs, lags)):
            if p > 0 and math.isfinite(z):
                u = p * z / _TWO_PI                    # z in wells (bottoms at integers)
                k = round(u)
                if abs(u - k) * _TWO_PI > LINEAR_DRIVE:
                    seg.last_nonlinear_t = s.t
                if abs(u - k) <= 0.25:
                    if r in seg.wells and k != seg.wells[r]:
                        seg.slips += abs(k - seg.wells[r])
                        seg.last_slip_t = s.t
                    seg.wells[r] = k
        seg.add(s, self._row(s, pred), max(self.window_s, self.min_fit_s))

    def _recorded(self, s: Sample) -> dict:
        """Return the recorded numbers of a sample that must be finite, by field name.

        A general system's ``energy`` has no z, zdot (its lags are joints): those are left
        out; so are the joints of a sample whose joint state never came (unpaired).
        """
        out = {'t_sim': s.t, 'E_star': s.E_star, 'dE_dt': s.dE_dt, 'residual': s.residual,
               'D': s.D}
        if s.dissipation is not None:
            out['dissipation'] = s.dissipation
        if self.prediction.coords != GENERAL_COORDS:
            out['z'], out['zdot'] = s.z, s.zdot
        for f in s.absent:               # not carried by the message: not recorded as NaN
            out.pop(f, None)
        if s.joints:
            out.update({f'position[{i}]': v for i, v in enumerate(s.positions)})
            out.update({f'velocity[{i}]': v for i, v in enumerate(s.velocities)})
        return out

    def _lags(self, s: Sample) -> tuple:
        """Return the rotor lags z of a sample (a general system's are joints after q)."""
        if self.prediction.coords == GENERAL_COORDS:
            n, m = len(self.prediction.steady[0]), len(self.prediction.steady[2])
            # a sample without its joint state has no lags (counted as unpaired, not here)
            ok = s.joints and len(s.positions) == n + m
            return tuple(s.positions[n:]) if ok else ()
        return (s.z,)

    def _row(self, s: Sample, pred: Prediction) -> tuple:
        """(t, E*, residual, z, zdot, deviation channels...) of one sample."""
        if pred.coords == GENERAL_COORDS:
            return _general_row(s, pred)
        th, psi = s.positions[0], s.positions[1]
        thd, psid, _, phiMd = s.velocities
        z = _from_well(s.z, pred.pole_pairs)
        if pred.coords == 'II':
            dev = (th - pred.theta0, thd, psid - pred.psidot0, psid + phiMd, z, s.zdot)
        elif pred.coords == 'I':
            st = math.sin(th)
            dev = (st * math.sin(psi), -st * math.cos(psi), z, s.zdot)
        else:
            dev = (z, s.zdot)
        return (s.t, s.E_star, s.residual, s.z, s.zdot) + tuple(dev)

    # -- evaluation ---------------------------------------------------------------------------
    def result(self) -> AnalysisResult:
        """Evaluate the segments and return the whole analysis so far (module doc)."""
        segs = list(self._done)
        if self.segments:
            segs.append(self._evaluate(self.segments[-1]))
        judged = next((s for s in reversed(segs) if s.windows or s.energy_fit is not None),
                      segs[-1] if segs else None)
        criteria = self._criteria(segs, judged)
        verdict, reason = self._combine(judged, criteria)
        evidence = [f'{verdict}: {reason}'] + [c.line() for c in criteria]
        if judged is not None:
            evidence.insert(1, f'judged on segment {judged.index} ({judged.reason}, t = '
                               f'{judged.t_start:.3f} .. {judged.t_end:.3f} s, '
                               f'{windows_text(judged)})')
        level = {Verdict.ASYMPTOTICALLY_STABLE: 'OK', Verdict.MARGINAL: 'OK',
                 Verdict.INSUFFICIENT_DATA: 'OK', Verdict.NOT_CONFIRMED: 'WARN',
                 Verdict.UNSTABLE: 'ERROR', Verdict.DIVERGED: 'ERROR'}[verdict]
        if not segs:
            level = 'STALE'
        return AnalysisResult(
            scene=self.scene.name, prediction=self.prediction, samples=self.samples,
            dropped=self.dropped, resets=self.resets, kicks=self.kicks,
            time_jumps=self.time_jumps, param_changes=self.param_changes,
            pole_slips=sum(s.pole_slips for s in segs), segments=segs, verdict=verdict,
            evidence=evidence, level=level, criteria=criteria, reason=reason,
            unpaired=self.unpaired, judged=judged, cut=self.cut, truncated=self.truncated,
            t_sim=self._last.t if self._last is not None else math.nan)

    def _criteria(self, segs: list, judged: SegmentResult | None) -> list:
        out = [crit.lyapunov(segs, self.lyapunov_tol, self.lyapunov_rtol),
               crit.energy_balance(segs, self.residual_warn)]
        if judged is not None:
            out += [c for c in judged.criteria
                    if c.name in (CriterionName.DECAY, CriterionName.MODES)]
        out.append(crit.data(self.samples, self.dropped, self.unpaired, self.non_finite,
                             self.cut, self.truncated, self.bag_lost, self.bag_loss,
                             non_finite_fields=sorted(self.non_finite_fields),
                             lost_first=self.lost_first))
        if judged is not None:
            sync = crit.synchronism(segs[-1], self.segments[-1].pred)
            if sync is not None:
                out.append(sync)
        fit = crit.scene(self.scene.name, self.fit_problems, self.fit_checks, self.fit_starts)
        if fit is not None:
            out.append(fit)
        return out

    def _combine(self, judged: SegmentResult | None, criteria: list) -> tuple:
        if judged is None:
            return Verdict.INSUFFICIENT_DATA, 'no samples yet'
        pred = judged_pred(self, judged)
        diverged, identity = self._identity(self._done + [judged])
        return combine(criteria, pred.verdict, diverged=diverged,
                       unstable=bool(judged.growing), identity=identity,
                       marginal_modes=tuple(m.name for m in pred.marginal_modes))

    def _identity(self, segs: list) -> tuple[bool, str]:
        """Return whether the integration diverged, and the energy identity's numbers.

        Diverged: E* not finite at a segment's end, or the identity broken by the
        simulation guard's rule (:func:`~gyro_rotor.numerics.guard.excess` above 1 with
        ``diverge_residual`` as its limit).
        """
        worst = max(segs, key=lambda s: s.identity_excess)
        nan = next((s for s in segs if s.non_finite), None)
        if nan is not None:
            return True, f'E* is not finite at t = {nan.t_end:.6g} s'
        broken = worst.identity_excess > 1.0
        # the sample nearest its bound (the largest |r| / bound), not the largest |r|: that
        # is the energy balance criterion's number, and the bound grows with |E*|
        text = (f'|E* + D - E_ref| = {worst.identity_r:.3g} J at t = {worst.identity_t:.6g} s, '
                f'the sample nearest its bound, {">" if broken else "<="} '
                f'max({self.diverge_residual:g} J, {RELATIVE_LIMIT:g} x max(|E*|, |E_ref|)) '
                f'= {worst.identity_bound:.3g} J there')
        return broken, text

    def _window(self, seg: _Segment) -> np.ndarray:
        R = seg.rows.array()
        if R.size == 0:
            return R
        if math.isfinite(self.window_s):
            R = R[R[:, 0] >= R[-1, 0] - self.window_s - 1e-9]
        return R

    def _sync(self, seg: _Segment) -> tuple:
        pred, last = seg.pred, seg.last
        if pred.pole_pairs <= 0 or last is None:
            return SyncState.SYNCHRONOUS, 0
        r, p = next((r, p) for r, p in enumerate(pred.rotor_pole_pairs) if p > 0)
        z = seg.lags[r] if len(seg.lags) > r else math.nan
        well = int(round(p * z / _TWO_PI)) if math.isfinite(z) else 0
        if last.t - seg.last_slip_t <= self.sync_hold_s:
            return SyncState.LOST, well
        return (SyncState.RESYNCHRONIZED if seg.slips else SyncState.SYNCHRONOUS), well

    def _missing(self, R: np.ndarray, seg: _Segment) -> int:
        """Return how many samples a window misses (lost messages) on the sample grid.

        The fits need equally spaced samples; a window with a gap is not fitted (the data
        criterion counts the loss; interpolating across it would put invented samples into
        the fits).
        """
        if len(R) < 3:
            return 0
        lost = sum(n for t, n in seg.gaps if R[0, 0] < t <= R[-1, 0])   # by sequence gaps
        dt = self._dt * seg.stride if self._dt else None     # a thinned window's grid
        if not dt:
            return lost
        steps = np.round(np.diff(R[:, 0]) / dt).astype(int)
        return max(lost, int(np.sum(np.maximum(steps - 1, 0))))

    def _noise(self, R: np.ndarray) -> float:
        """Noise level of E* in a window [J]: the jitter of the energy-balance residual.

        The residual r = E* + D - E_ref carries the integration error and the rounding of
        E*; its deviation from a straight line over the window is their noise.
        """
        r = R[:, 2]
        if len(r) < 3 or not np.all(np.isfinite(r)):
            return 0.0
        tt = R[:, 0] - R[0, 0]
        p = np.polyfit(tt, r, 1)
        return float(np.std(r - np.polyval(p, tt)))

    def _evaluate(self, seg: _Segment, judge: bool = True) -> SegmentResult:
        """Judge the newest window of a segment; with ``judge``, over its checkpoints too.

        ``judge=False`` (a checkpoint): the window alone. Otherwise the decay and modes
        criteria say what the windows of the segment's checkpoints and the newest one saw
        (:func:`~gyro_rotor.analysis.verdict.over_run`), and so do the modes' statuses.
        """
        pred = seg.pred
        last = seg.last
        judged = seg.record.last
        if judge and judged is not None and judged.samples == seg.samples:
            # the newest checkpoint judged this very window: its result, judged over the run
            res = dataclasses.replace(judged)
            res.criteria = list(res.criteria)
            return self._judge_over_run(seg, res)
        R = self._window(seg)
        sync_state, well = self._sync(seg)
        # fit only data after the last slip, once the drive is back in its linear range,
        # and after the modes that die within a sample (a stiff drive's real root) are gone
        fit_from = max(seg.last_slip_t + 0.5, seg.last_nonlinear_t,
                       seg.t_start + _gone_after(pred, self._dt and self._dt * seg.stride))
        if R.size and math.isfinite(fit_from):
            R = R[R[:, 0] > fit_from]
        R = R[np.all(np.isfinite(R), axis=1)] if R.size else R
        missing = self._missing(R, seg)
        span = float(R[-1, 0] - R[0, 0]) if len(R) > 1 else 0.0
        e_fit, dev_rate = None, math.nan
        found = ModesFound([], [])
        if span >= self.min_fit_s and len(R) > 20 and not missing:
            eigs = [m.eigenvalue for m in pred.modes if not m.structural]
            change = abs(seg.E_first - last.E_star) if last is not None else 0.0
            e_fit = fit_energy(R[:, 0], R[:, 1], eigs, noise=self._noise(R),
                               remainder=REMAINDER_SHARE * change)
            dev_rate = envelope_decay_rate(R[:, 0], R[:, 5:], [m.freq_hz for m in pred.modes])
            found = check_modes(R[:, 0], R[:, 5:], pred, span,
                                combination_tones=self.combination_tones)
            modes = found.checks
        else:
            modes = [ModeCheck(m.name, m.eigenvalue, None, math.nan,
                               ModeStatus.NOT_IDENTIFIED, m.reached_by_drive, m.structural)
                     for m in pred.modes]
        res = SegmentResult(
            index=seg.index, reason=seg.reason, scene=seg.scene.name,
            t_start=seg.t_start, t_end=last.t if last else math.nan, samples=seg.samples,
            E_first=seg.E_first, E_last=last.E_star if last else math.nan,
            E_inf=e_fit.E_inf if e_fit else math.nan,
            lyapunov_max_increase=seg.lyap_max if math.isfinite(seg.lyap_max) else math.nan,
            lyapunov_violations=seg.lyap_violations, residual_max=seg.residual_max,
            balance_max=seg.balance_max, balance_mismatch=seg.balance_mismatch,
            balance_n=seg.balance_n, identity_excess=seg.identity_excess,
            identity_t=seg.identity_t, identity_r=seg.identity_r,
            identity_bound=seg.identity_bound, balance_excess=seg.balance_excess,
            balance_t=seg.balance_t, balance_r=seg.balance_r,
            balance_bound=seg.balance_bound,
            energy_decay_rate=e_fit.rate if e_fit else math.nan,
            deviation_decay_rate=dev_rate, window_s=span, modes=modes,
            pole_slips=seg.slips, sync_state=sync_state, well=well,
            verdict=Verdict.INSUFFICIENT_DATA, evidence=[], energy_fit=e_fit,
            unexplained=found.unexplained, combinations=found.combinations,
            growing=found.growing, fit_from=fit_from if math.isfinite(fit_from) else math.nan,
            missing=missing,
            non_finite=not (last and math.isfinite(last.E_star)))
        res.criteria = [crit.decay(res, pred, self.min_fit_s), crit.modes(res, self.min_fit_s)]
        if not judge:
            return res
        return self._judge_over_run(seg, res)

    def _judge_over_run(self, seg: _Segment, res: SegmentResult) -> SegmentResult:
        """Judge the newest window's result over the segment's checkpoints (verdict too)."""
        pred = seg.pred
        self._over_run(seg, res)
        sync = crit.synchronism(res, pred)
        if sync is not None:
            res.criteria.append(sync)
        diverged, identity = self._identity([res])
        res.verdict, reason = combine(res.criteria, pred.verdict, diverged=diverged,
                                      unstable=bool(res.growing), identity=identity,
                                      marginal_modes=tuple(m.name for m in pred.marginal_modes))
        res.evidence = [reason] + [c.line() for c in res.criteria]
        return res

    def _over_run(self, seg: _Segment, res: SegmentResult) -> None:
        """Turn the newest window's criteria and modes into what the whole segment saw."""
        rec = seg.record
        if res.energy_fit is not None and not (rec.last is not None
                                               and rec.last.samples == res.samples):
            rec = rec.copy()          # the newest window between two checkpoints
            rec.add(res)
        if not rec.n:
            return
        res.windows = (rec.n, rec.first_t, rec.last_t)
        out = [rec.criterion(CriterionName.DECAY), rec.criterion(CriterionName.MODES)]
        res.growing = list(rec.growing)
        res.modes = rec.modes(res.modes)
        if out[1].status is not Status.FAIL:
            # the modes as the whole run saw them (the newest window's combination tones)
            lines = [crit.mode_line(m) for m in res.modes if not m.structural]
            lines += [tone_line(r, text) for r, text in res.combinations]
            out[1] = dataclasses.replace(out[1], detail='; '.join(lines))
        res.criteria = out
        # the numbers of the decay: the newest window that measured a rate
        if res.energy_fit is not None and not math.isfinite(res.energy_fit.rate):
            res.rate_fit = rec.rate_fit


def _kick_jump(a: Sample, b: Sample, tol: float) -> float:
    """Return the jump of E* + D between two samples if it is a kick, else 0.

    Along a solution E* + D is constant (eq. 17) up to the integration error, which the
    residual E* + D - E_ref carries. A kick changes the state, and
    :mod:`~gyro_rotor.numerics.live` rebases E_ref by E*'s jump: E* + D jumps by more
    than ``tol`` (either way) and the residual does not carry the jump (it moves by less
    than half of it). Where the kicked energy goes afterwards does not matter: a stiff
    drive dissipates a kick of its lag rate within one sample, so D jumps with E* + D
    (D is the integral of K_D zdot^2 >= 0: it never decreases, not at a kick either).
    A jump the residual carries is no kick (the energy balance judges it); a single
    corrupt message is taken back by the next sample (:meth:`RotorAnalyzer._undo_kick`).
    """
    jump = (b.E_star + b.D) - (a.E_star + a.D)
    if not abs(jump) > tol:
        return 0.0
    if not (abs(b.residual - a.residual) < 0.5 * abs(jump) and b.D - a.D >= -tol):
        return 0.0
    return jump


def _gone_after(pred: Prediction, dt: float | None) -> float:
    """Time [s] after which the modes too fast for the sample grid have died (e^-30).

    -inf if there are none: no sample of a segment's start is left out.
    """
    fast = [-m.eigenvalue.real for m in pred.modes
            if dt and m.eigenvalue.real * dt < -MAX_EXPONENT]
    return 0.5 * MAX_EXPONENT / min(fast) if fast else -math.inf


def windows_text(seg: SegmentResult) -> str:
    """Return which windows a segment was judged on."""
    if not seg.windows:
        return f'window {seg.window_s:.3g} s'
    n, first, last = seg.windows
    if n == 1:
        return f'window {seg.window_s:.3g} s ending t = {last:.2f} s'
    return (f'{n} windows of up to {seg.window_s:.3g} s ending t = {first:.2f} .. '
            f'{last:.2f} s')


def judged_pred(analyzer: RotorAnalyzer, seg: SegmentResult) -> Prediction:
    """Return the prediction a segment was recorded under."""
    return analyzer.segments[seg.index].pred


def _same_physics(a, b) -> bool:
    """Return True if two scenes differ in nothing the analysis depends on (their physics).

    A system rebuilt from a bag's document has no file path and may list its constants in
    another order: :meth:`~gyro_rotor.core.scene.Scene.physics` holds neither.
    """
    return a.physics() == b.physics()


def _general_row(s: Sample, pred: Prediction) -> tuple:
    """(t, E*, residual, z_1, zdot_1, deviation channels) of a general system's sample.

    Channels: the coordinates' deviation from the steady motion q_s + qdot_s t projected
    on :attr:`Prediction.active_q`, then qdot - qdot_s, z - z_s (about the nearest well
    bottom for a sine law) and zdot.
    """
    q_s, qd_s, z_s = pred.steady
    n, m = len(q_s), len(z_s)
    if len(s.positions) != n + m or len(s.velocities) != n + m:
        nan = (math.nan,) * (len(pred.active_q) + n + 2 * m)
        return (s.t, s.E_star, s.residual, math.nan, math.nan) + nan
    q = np.asarray(s.positions[:n]) - np.asarray(q_s) - np.asarray(qd_s) * s.t
    dq = tuple(float(np.dot(row, q)) for row in pred.active_q)
    dqd = tuple(v - w for v, w in zip(s.velocities[:n], qd_s))
    dz = tuple(_from_well(z - z0, p)
               for p, z, z0 in zip(pred.rotor_pole_pairs, s.positions[n:], z_s))
    zd = tuple(s.velocities[n:])
    return (s.t, s.E_star, s.residual, s.positions[n], s.velocities[n]) + dq + dqd + dz + zd


def _from_well(z: float, p: int) -> float:
    """Return a lag's deviation from the bottom of its nearest well (p > 0: a sine law)."""
    return z - _TWO_PI / p * round(p * z / _TWO_PI) if p > 0 else z
