"""The criteria of the verdict (:mod:`gyro_rotor.analysis.verdict`), one function each.

Each takes what was measured, every number with its uncertainty interval
(:class:`~gyro_rotor.analysis.verdict.Measured`), and returns a
:class:`~gyro_rotor.analysis.verdict.Criterion` with PASS, FAIL or NOT YET by the one rule
of :func:`~gyro_rotor.analysis.verdict.decide` (PASS only when the whole interval is on the
passing side of the bound, FAIL only when it is wholly on the failing side), why, and its
numbers. :func:`decay` and :func:`modes` judge one window; the analyzer combines the
windows of a run with :func:`~gyro_rotor.analysis.verdict.over_run`. Pure Python.
"""

from __future__ import annotations

import math

from gyro_rotor.analysis.decay import NOISE_K, RESOLVABLE, TAIL_FROM
from gyro_rotor.analysis.modes import (FREQ_RTOL, mode_tolerances, RATE_RTOL as MODE_RATE_RTOL,
                                       tone_line)
from gyro_rotor.analysis.prediction import Prediction
from gyro_rotor.analysis.results import SegmentResult
from gyro_rotor.analysis.verdict import (conjoin, Criterion, CriterionName, decay_rate_bound,
                                         DECAY_RTOL, decide, fmt_against, fmt_interval, fmt_pm,
                                         Measured, ModeStatus, needs_phrase, Status, SyncState)
from gyro_rotor.numerics.guard import RELATIVE_LIMIT

__all__ = ['lyapunov', 'energy_balance', 'decay', 'modes', 'data', 'synchronism', 'scene',
           'FIT_RTOL', 'RATE_RTOL', 'rate_bound', 'mode_line', 'slow_phrase']

#: the fit of E*(t) with the predicted rates must leave at most this rms residual, relative
#: to the spread of E* over the window (or the noise floor, if that is larger). Measured on
#: a demo bag of the default scene: 4e-6 to 2.3e-5 over 8 s windows with the right
#: prediction (0.022 on pole_slip after its slips), 0.23 for K_D = 0.3 instead of 0.05
FIT_RTOL = 0.05
#: the decay bound's allowance for the nonlinearity (:data:`~.verdict.DECAY_RTOL`)
RATE_RTOL = DECAY_RTOL

_EPS = 2.220446049250313e-16
_AGREE = (ModeStatus.DECAYING_AS_PREDICTED, ModeStatus.EXPECTED_MARGINAL,
          ModeStatus.WEAKLY_DAMPED)


def _unfitted(seg: SegmentResult, min_fit_s: float, what: str) -> str:
    """Why the newest window was not fitted."""
    if seg.missing:
        return (f'{seg.missing} samples of the window are missing (lost messages): no '
                f'{what} across the gap')
    return f'window {seg.window_s:.3g} s too short to {what} (need {min_fit_s:g} s)'


def rate_bound(pred: Prediction) -> float:
    """Return the bound the rate of E* - E*_inf is held against: (1 - RATE_RTOL) 2|alpha|."""
    return (1.0 - RATE_RTOL) * decay_rate_bound(pred.decaying_abscissa)


def lyapunov(segs: list[SegmentResult], tol: float, rtol: float) -> Criterion:
    """E* never rises beyond the integrator's tolerance (eq. 13 non-increasing, eq. 17).

    The measured number is the largest rise of E* between two samples (its interval: the
    rounding of E*, 4 ulp); the bound tol + rtol |E*|.
    """
    n = sum(s.lyapunov_violations for s in segs)
    steps = [s.lyapunov_max_increase for s in segs if math.isfinite(s.lyapunov_max_increase)]
    worst = max(steps, default=math.nan)
    E = max((abs(s.E_last) for s in segs if math.isfinite(s.E_last)), default=0.0)
    bound = tol + rtol * E
    nums = {'violations': n, 'max_increase_J': worst, 'tol_J': tol, 'rtol': rtol}
    name = CriterionName.LYAPUNOV
    if not steps:
        return Criterion(name, Status.NOT_YET, 'fewer than two samples', nums)
    rise = Measured.pm(worst, 4 * _EPS * max(E, 1.0))
    status = decide(rise, bound, 'below')
    if n and status is not Status.FAIL:
        status = Status.FAIL        # a rise beyond a sample's own bound (rtol |E*| there)
    if status is Status.FAIL:
        return Criterion(name, status, f'E* rose {max(n, 1)} times beyond {tol:.1g} J + '
                         f'{rtol:.1g} |E*| (max rise {worst:.3g} J)', nums)
    text = (f'E* never rose beyond {tol:.1g} J + {rtol:.1g} |E*| (largest step '
            f'{worst:+.3g} J)')
    return Criterion(name, status, text + ('' if status is Status.PASS else
                                           ': the largest rise is at the bound'), nums)


def energy_balance(segs: list[SegmentResult], warn: float) -> Criterion:
    """Check |E* + D - E_ref| by the simulation guard's rule with the limit ``warn``.

    E* + D - E_ref is computed from the recorded E* and D (E_ref: E* + D - residual at a
    segment's first sample) and held together with the recorded residual: each of the
    two, and their difference, must stay below max(``warn``, RELATIVE_LIMIT x max(|E*|,
    |E_ref|)) (:func:`~gyro_rotor.numerics.guard.bound`: the one rule of the energy
    identity, whose divergence limit is the analyzer's ``diverge_residual``); the number
    judged is the sample nearest its bound (interval: its rounding, 4 ulp).
    """
    name = CriterionName.ENERGY_BALANCE
    recorded = max((s.residual_max for s in segs), default=math.nan)
    computed = max((s.balance_max for s in segs if s.balance_n), default=math.nan)
    mismatch = max((s.balance_mismatch for s in segs if s.balance_n), default=math.nan)
    worst = max(segs, key=lambda s: s.balance_excess) if segs else None
    nums = {'residual_max_J': recorded, 'balance_max_J': computed, 'mismatch_J': mismatch,
            'tol_J': warn, 'rel_tol': RELATIVE_LIMIT}
    if worst is None or not math.isfinite(worst.balance_bound):
        return Criterion(name, Status.NOT_YET, 'no residual yet', nums)
    r, b = worst.balance_r, worst.balance_bound
    nums.update(worst_J=r, worst_bound_J=b, worst_t=worst.balance_t)
    status = decide(Measured.pm(r, 4 * _EPS * max(b / RELATIVE_LIMIT, 1.0)), b, 'below')
    rel = {Status.PASS: '<=', Status.FAIL: '>', Status.NOT_YET: 'at'}[status]
    if b > warn:
        against = (f'{rel} max({warn:.1g} J, {RELATIVE_LIMIT:g} x max(|E*|, |E_ref|)); '
                   f'nearest it at t = {worst.balance_t:.6g} s: {r:.3g} J against {b:.3g} J')
    else:
        against = f'{rel} {warn:.1g} J'
    if math.isnan(computed):
        return Criterion(name, status, f'max |E* + D - E_ref| = {recorded:.3g} J as the '
                         f'recorded residual says (D not recorded: not computed) ({against})',
                         nums)
    return Criterion(name, status, f'max |E* + D - E_ref| = {computed:.3g} J from the '
                     f'recorded E* and D, recorded residual max {recorded:.3g} J, they differ '
                     f'by up to {mismatch:.3g} J ({against})', nums)


def _limit_text(seg: SegmentResult, pred: Prediction) -> str:
    """Return what the fitted constant of E*(t) is: E*_inf, or E* without its resolved terms.

    Predicted terms too slow for the window are part of the fitted constant: it is then
    E* at the window's end without the resolved terms, not the limit of E*.
    """
    fit = seg.energy_fit
    if fit.slow:
        return (f"E* without its resolved terms = {fmt_pm(fit.E_inf, fit.E_inf_sigma, 'J')} "
                f"at the window's end (not the limit E*_inf: predicted terms slower than "
                f'{RESOLVABLE / max(seg.window_s, 1e-9):.3g} 1/s, unresolved in this window, '
                f"are part of it, trend {fit.trend:+.3g} J/s; E* on the scene's steady "
                f'motion {pred.E_inf:.9g} J)')
    return (f'E*_inf = {fmt_pm(fit.E_inf, fit.E_inf_sigma, "J")} (fitted; E* on the '
            f"scene's steady motion {pred.E_inf:.9g} J, a kick moves the limit)")


def decay(seg: SegmentResult, pred: Prediction, min_fit_s: float) -> Criterion:
    """E* approaches its fitted limit at least as fast as the slowest predicted mode allows.

    Two tests, each by the rule: the fit of E*(t) with the predicted rates holds (its rms
    residual, with its interval from the number of independent residuals, below
    :data:`FIT_RTOL` of E*'s spread or the noise floor; a coarse test: a constant and a line
    absorb a wrong rate, 0.3 % of the spread for 0.75 K_D on precession), and the rate of
    E* - E*_inf (that of its slowest shown terms fitted free, with its interval, from
    :func:`~gyro_rotor.analysis.decay.fit_energy`) is above the bound of the
    predicted terms it shows (:func:`_rate`; :func:`rate_bound` where the slowest mode's term
    shows). E* settled within its noise floor decides nothing (NOT YET), unless
    no mode is predicted to decay (then it is as predicted).
    """
    full = decay_rate_bound(pred.decaying_abscissa)
    bound = rate_bound(pred)
    fit = seg.energy_fit
    nums = {'bound': full, 'rate_bound': bound, 'window_s': seg.window_s}
    name = CriterionName.DECAY
    if fit is None:
        return Criterion(name, Status.NOT_YET, _unfitted(seg, min_fit_s, 'fit'), nums)
    grow = pred.growing_modes
    if grow:
        # E* of an unstable steady motion need not approach any limit: nothing to confirm
        nums['growing'] = [m.name for m in grow]
        return Criterion(name, Status.NOT_YET, 'predicted to grow: ' + ', '.join(
            f'{m.name} (Re lambda = {m.eigenvalue.real:+.3g} 1/s)' for m in grow)
            + ': E* of an unstable steady motion need not approach a limit', nums)
    nums.update(rate=fit.rate, rate_lo=fit.rate_lo, rate_hi=fit.rate_hi, E_inf=fit.E_inf,
                spread=fit.spread, trend=fit.trend, E_inf_sigma=fit.E_inf_sigma,
                rel_residual=fit.rel_residual, noise=fit.noise)
    if fit.tail is not None:
        nums.update(tail_rate=fit.tail.rate, tail_rate_lo=fit.tail.rate_lo,
                    tail_rate_hi=fit.tail.rate_hi)
    if fit.settled:
        var = (f'E* varies by less than its noise floor ({NOISE_K:g} x '
               f'{max(fit.noise, fit.remainder):.2g} J)')
        if not math.isfinite(full):
            return Criterion(name, Status.PASS, f'{var} over the window: constant, as '
                             'predicted (no mode decays)', nums)
        return Criterion(name, Status.NOT_YET, f'{var} over the window: E* has settled, '
                         'nothing left to measure here', nums)
    # the predicted E*_inf is E* on the scene's own steady motion; a kick or a drift along a
    # cyclic coordinate moves the motion the rotor settles on, and so the limit
    parts = [_limit_text(seg, pred)]
    rms = Measured(fit.residual_rms, fit.residual_rms * (1 - 1 / math.sqrt(fit.n_eff)),
                   fit.residual_rms * (1 + 1 / math.sqrt(fit.n_eff)))
    fit_bound = max(FIT_RTOL * fit.spread, NOISE_K * fit.noise, fit.remainder)
    st_fit = decide(rms, fit_bound, 'below')
    how = {Status.PASS: 'follows', Status.FAIL: 'does not follow',
           Status.NOT_YET: 'may not follow'}[st_fit]
    parts.append(f'E*(t) {how} the predicted rates (rms residual '
                 f'{fit.rel_residual:.2g} of its spread, bound {fit_bound / fit.spread:.2g})')
    tests = [st_fit]
    if math.isfinite(full):
        st, text, nums['rate_bound'] = _rate(fit, full, seg.window_s)
        tests.append(st)
        parts.append(text)
    else:
        parts.append('no decaying mode predicted')
    return Criterion(name, conjoin(tests), '; '.join(parts), nums)


def _rate(fit, full: float, window_s: float) -> tuple[Status, str, float]:
    """Judge the rate of E* - E*_inf against the terms it shows; (status, text, bound).

    Like with like: the rate measured is that of the slowest predicted terms of E* that show
    above the noise floor, fitted free (not pulled toward the prediction, see
    :mod:`~gyro_rotor.analysis.decay`), so it is held against (1 - RATE_RTOL) x their
    predicted rate (:meth:`~gyro_rotor.analysis.decay.EnergyFit.shown_decay`), which is
    2|alpha| (eq. 13: terms exp(2 Re(lambda) t)) where the slowest mode's term shows. A
    slowest mode too slow for the window is merged into E*_inf
    (:func:`~gyro_rotor.analysis.decay.fit_energy`): the fast terms' rate is not held
    against its bound, which it would pass whatever the data. No term showing: NOT YET.
    Measured over the window and again over its last part (``fit.tail``, where a wrong
    prediction's faster terms leak less into it): each measured rate is held against its
    bound, and the rate passes only if every one does.
    """
    ref = f'2|alpha| = {full:.4g} 1/s'
    if full * window_s < RESOLVABLE:
        ref += f', {slow_phrase(full, window_s)}'
    parts = [(fit, '')]
    if fit.tail is not None and math.isfinite(fit.tail.rate):
        parts = [(fit, ' over the window'),
                 (fit.tail, f' over its last {100 * (1 - TAIL_FROM):.0f} %')]
    judged = [_one_rate(f, full, ref if i == 0 else '', window_s, where)
              for i, (f, where) in enumerate(parts)]
    measured = [j for j, (f, _) in zip(judged, parts) if math.isfinite(f.rate)
                and math.isfinite(f.shown_decay())]
    if not measured:
        return judged[0]
    return conjoin(j[0] for j in measured), '; '.join(j[1] for j in measured), measured[0][2]


def _one_rate(fit, full: float, ref: str, window_s: float,
              where: str) -> tuple[Status, str, float]:
    """Judge one measured rate of E* - E*_inf (:func:`_rate`): (status, text, bound)."""
    slowest = fit.shown_decay()
    bound = (1.0 - RATE_RTOL) * slowest
    factor = '2|alpha|' if slowest == full else (
        f'{slowest:.4g} 1/s (the slowest predicted term of E* above its noise floor)')
    rate = Measured(fit.rate, fit.rate_lo, fit.rate_hi)
    if not rate.measured:
        why = fit.rate_note or 'E* - E*_inf not resolved'
        head = (f'bound (1 - {RATE_RTOL:g}) x {factor} = {bound:.4g} 1/s ({ref})'
                if math.isfinite(bound) else ref)
        # the reason last: over_run quotes the newest window's last clause
        return Status.NOT_YET, (f'{head}: rate of E* - E*_inf not measurable in this window, '
                                f'{why}'), bound
    if not math.isfinite(slowest):
        return Status.NOT_YET, (f'rate of E* - E*_inf not decided: no predicted decaying term '
                                f'of E* above its noise floor ({fit.floor:.2g} J) decays '
                                f'resolvably in this window ({ref})'), math.nan
    st = decide(rate, bound, 'above')
    shown, b = fmt_against(rate, bound, '1/s')
    text = (f'E* - E*_inf decays at {shown}{where} (the rate of its slowest shown terms, '
            f'fitted free), bound (1 - {RATE_RTOL:g}) x {factor} = {b} 1/s'
            + (f' ({ref})' if ref else ''))
    if st is Status.FAIL:
        text += ': slower than predicted'
    elif st is Status.NOT_YET:
        text += (': the interval straddles the bound '
                 f'({needs_phrase(window_s, rate.value - bound, rate.u)})')
    return st, text, bound


def slow_phrase(rate: float, window_s: float) -> str:
    """Say what a decay rate too slow for the window means, in numbers.

    A term decaying at ``rate`` changes by rate x window over it; below :data:`RESOLVABLE`
    (5 %) :func:`~gyro_rotor.analysis.decay.fit_energy` merges it into E*_inf and the trend.
    RESOLVABLE / rate is only the window in which it would change by 5 % and be fitted as a
    term of its own, not one that measures its rate; its time constant is 1 / rate.
    """
    return (f'too slow to resolve in this {window_s:.3g} s window: it changes its terms by '
            f'{100.0 * rate * window_s:.2g} % over it, under the {100.0 * RESOLVABLE:g} % that '
            f'tells a term from E*_inf ({RESOLVABLE / rate:.3g} s would, without measuring its '
            f'rate), time constant {1.0 / rate:.3g} s')


def mode_line(c) -> str:
    """Return a mode with its numbers: frequency, decay time (intervals), status.

    Each measured number stands beside the prediction's band it is judged against
    (:func:`~gyro_rotor.analysis.modes.mode_tolerances` over the window): the frequency
    within FREQ_RTOL of |lambda|, the decay time from the rate within RATE_RTOL.
    """
    out = c.name
    tol_im, tol_re = mode_tolerances(c.predicted, c.window_s)
    two_pi = 2 * math.pi
    if c.freq is not None and c.freq.bounded:
        out += (f' {fmt_pm(abs(c.freq.value) / two_pi, c.freq.u / two_pi, "Hz")} against '
                f'{fmt_pm(abs(c.predicted.imag) / two_pi, tol_im / two_pi, "Hz")}')
    tau = c.tau
    if tau is not None and c.rate_status is not None:
        re = c.rate_target
        band = ' .. '.join(f'{-1.0 / r:.4g}' if r < 0 else 'inf'
                           for r in (re - tol_re, re + tol_re))
        pred = f'{-1.0 / re:.4g} s' if re < 0 else 'undamped'
        out += f', tau {fmt_interval(tau, "s")} against {pred} (band {band} s)'
    return f'{out}: {c.describe()}'


def modes(seg: SegmentResult, min_fit_s: float) -> Criterion:
    """Each excited mode identified and as predicted; unreached modes stay undamped.

    Per mode the frequency (within :data:`~gyro_rotor.analysis.modes.FREQ_RTOL`) and,
    where this window resolves it, the decay rate (within
    :data:`~gyro_rotor.analysis.modes.RATE_RTOL` or the window's resolution), each by the
    rule. FAIL if a mode disagrees or a resolved oscillation that lasts through the window
    matches no mode and is no combination tone; PASS if a mode agrees and no judged number
    straddles its tolerance; NOT YET otherwise.
    """
    name = CriterionName.MODES
    judged = [m for m in seg.modes if not m.structural]
    nums = {'identified': sum(m.measured is not None for m in judged),
            'disagree': [m.name for m in judged if m.status is ModeStatus.DISAGREES],
            'unexplained_hz': [abs(r.value.imag) / (2 * math.pi) for r, _ in seg.unexplained],
            'combination_hz': [abs(r.value.imag) / (2 * math.pi) for r, _ in
                               seg.combinations],
            'freq_rtol': FREQ_RTOL, 'rate_rtol': MODE_RATE_RTOL}
    if seg.energy_fit is None:
        return Criterion(name, Status.NOT_YET, _unfitted(seg, min_fit_s, 'identify'), nums)
    parts = [mode_line(m) for m in judged]
    if seg.combinations:
        parts.append('; '.join(tone_line(r, text) for r, text in seg.combinations))
    if seg.unexplained:
        parts.append('unexplained oscillations at ' + ', '.join(t for _, t in seg.unexplained))
    bad = [m for m in judged if m.status is ModeStatus.DISAGREES]
    straddle = [m for m in judged if Status.NOT_YET in (m.freq_status, m.rate_status)]
    agree = [m for m in judged if m.status in _AGREE]
    # a mode predicted to grow is an unstable steady motion: never a pass
    growing = [m for m in judged if m.predicted.real > 0 and m.status not in (
        ModeStatus.EXPECTED_MARGINAL, ModeStatus.STRUCTURAL_ZERO_ROOT)]
    nums['growing'] = [m.name for m in growing]
    if growing:
        parts.append('predicted to grow: ' + ', '.join(
            f'{m.name} (Re lambda = {m.predicted.real:+.3g} 1/s, '
            f'{"identified" if m.status is ModeStatus.GROWING else str(m.status)})'
            for m in growing))
    if bad or seg.unexplained or any(m.status is ModeStatus.GROWING for m in growing):
        return Criterion(name, Status.FAIL, '; '.join(parts), nums)
    if growing:
        return Criterion(name, Status.NOT_YET, '; '.join(parts), nums)
    if straddle:
        return Criterion(name, Status.NOT_YET, '; '.join(parts) + '; not decided: '
                         + ', '.join(m.name for m in straddle), nums)
    if not agree:
        return Criterion(name, Status.NOT_YET, 'no mode resolved in the window: '
                         + '; '.join(parts), nums)
    return Criterion(name, Status.PASS, '; '.join(parts), nums)


def data(samples: int, dropped: int, unpaired: int, non_finite: int, cut: int = 0,
         truncated: str = '', bag_lost: int = 0, bag_loss: str = '',
         non_finite_fields: tuple = (), lost_first: int = 0) -> Criterion:
    """No message lost (sequence gaps, or in a damaged bag), no sample unpaired, all finite.

    ``cut``: messages past the end of the other topic at a cut recording (the one sample
    whose partner the cut took: not a loss the data show); ``truncated`` says where the
    recording was cut, if it was. ``bag_lost`` and ``bag_loss`` are the recorded messages a
    damaged bag lost (counted by its reader) and the line that says which; any of it fails
    the criterion, so a damaged bag never gives a plain CONFIRMED. ``non_finite_fields``:
    the recorded fields that were NaN or infinite (named in the text). ``lost_first``: of
    the ``dropped``, those before the first sample of a simulation (its seq; the
    simulation numbers them from 0).
    """
    nums = {'samples': samples, 'dropped': dropped, 'unpaired': unpaired,
            'non_finite': non_finite, 'cut': cut, 'bag_lost': bag_lost}
    if samples == 0:
        return Criterion(CriterionName.DATA, Status.NOT_YET, 'no samples yet', nums)
    text = f'{samples} samples, {dropped} messages lost (sequence gaps'
    if lost_first:
        text += (f', {lost_first} of them before the first sample: the simulation numbers '
                 'its samples from 0')
    text += (f'), {unpaired} unpaired between energy and joint_states, {non_finite} with '
             'non-finite values')
    if non_finite_fields:
        text += f' ({", ".join(non_finite_fields)})'
    if cut:
        text += f' ({cut} at the cut of the recording without its partner: not counted)'
    if truncated:
        text += f'; {truncated}'
    if bag_loss:
        text += f'; damaged bag: {bag_loss}'
    lost = dropped + unpaired + non_finite + bag_lost + (1 if bag_loss else 0)
    return Criterion(CriterionName.DATA, decide(Measured(lost, lost, lost), 0, 'below'),
                     text, nums)


def synchronism(seg: SegmentResult, pred: Prediction) -> Criterion | None:
    """Locked in a well at the end (slips counted); None without drive poles."""
    if pred.pole_pairs <= 0:
        return None
    nums = {'pole_slips': seg.pole_slips, 'well': seg.well, 'state': str(seg.sync_state)}
    if seg.sync_state is SyncState.LOST:
        # a rotor started far off synchronism slips poles before it locks (pole_slip): not
        # a failure while it lasts; a run that ends slipping never decides
        return Criterion(CriterionName.SYNCHRONISM, Status.NOT_YET,
                         f'slipping: {seg.pole_slips} pole slips so far, not locked in a '
                         f'well yet', nums)
    text = (f'{seg.sync_state}: {seg.pole_slips} pole slips, locked in well {seg.well} '
            f'(z = {seg.well} * 2 pi / {pred.pole_pairs})')
    return Criterion(CriterionName.SYNCHRONISM, Status.PASS, text, nums)


def scene(name: str, problems: list, checks: int, starts: int = 0) -> Criterion | None:
    """Check that the data are the scene's (:mod:`~gyro_rotor.analysis.fit`); None: unchecked.

    ``checks``: how many comparisons were made (E* from the recorded joints, and
    ``starts`` of them the first sample of a run against the scene's initial state: none
    when the data begin after it); ``problems``: what differed. Each comparison is exact
    to rounding: the interval of a difference is its rounding
    (:data:`~gyro_rotor.analysis.fit.TOL`), so one difference beyond it fails.
    """
    nums = {'checks': checks, 'starts': starts, 'problems': list(problems)}
    if problems:
        return Criterion(CriterionName.SCENE, Status.FAIL, '; '.join(problems)
                         + ': a recording of another scene, or with other constants', nums)
    if not checks:
        return None
    what = (f'{_count(starts, "start")} of a run against its initial state' if starts
            else "the run's start not in the data")
    return Criterion(CriterionName.SCENE, Status.PASS,
                     f"the data fit scene '{name}' ({_count(checks, 'check')}: E* from the "
                     f'recorded joints, {what})', nums)


def _count(n: int, noun: str) -> str:
    """Return '1 check', '2 checks'."""
    return f'{n} {noun}' if n == 1 else f'{n} {noun}s'
