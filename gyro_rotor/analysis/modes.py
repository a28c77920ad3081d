"""Modes from data: eigenvalues identified in a window, with uncertainties, vs the prediction.

:func:`identify_roots` fits the deviation channels with a matrix pencil (Hua & Sarkar
1990, as :func:`gyro_rotor.linear.sysid.matrix_pencil`) of more exponentials than the
prediction has (the spare ones take combination tones, offsets and the nonlinear
remainder), once over the whole window and once over each half. The uncertainty of each
root is the largest difference between the whole window's value and the halves' (a
jackknife: it holds the nonlinear remainder, the leakage of neighbouring roots and the
window's length; a root that is not found again in either half has no bounded
uncertainty and is not resolved). :func:`check_modes` assigns the identified roots to the
predicted ones (:func:`scipy.optimize.linear_sum_assignment`, each root to at most one
mode, by a cost that uses the prediction's tolerance and the root's uncertainty), judges
each matched mode's frequency and decay rate with the one rule of
:func:`~gyro_rotor.analysis.verdict.decide`, names identified roots at the sum or
difference of two modes' frequencies as combination tones (a nonlinear system's products
of modes), and lists the oscillations nothing explains. Pure Python.
"""

from __future__ import annotations

from collections.abc import Iterator
import dataclasses
import math

from gyro_rotor.analysis.decay import RESOLVABLE
from gyro_rotor.analysis.prediction import PredictedMode, Prediction
from gyro_rotor.analysis.verdict import (_digits, decide, fmt_interval, fmt_pm, Measured,
                                         ModeStatus, needs_phrase, Status)
from gyro_rotor.errors import AnalysisError
import numpy as np

__all__ = ['identify_modes', 'identify_roots', 'check_modes', 'ModeCheck', 'ModesFound',
           'Root', 'FREQ_RTOL', 'RATE_RTOL', 'RESOLVABLE', 'mode_tolerances', 'alias_hz',
           'tone_line', 'TONE_SIGMAS']

_TWO_PI = 2.0 * math.pi

#: relative frequency tolerance of the prediction (the kicked motion is nonlinear: its
#: frequencies shift with the squared amplitude; see test/test_analysis.py)
FREQ_RTOL = 0.02
#: relative tolerance of a predicted decay rate
RATE_RTOL = 0.25
#: spare exponentials of the pencil beyond the predicted ones and an offset
SPARE = 12
#: an identified root whose rms contribution over the window is below this share of the
#: largest one is below the noise floor (not excited, or decayed)
NOISE_SHARE = 1e-4
#: an identified oscillation, resolved (found again in a half of the window, its frequency
#: within FREQ_RTOL), with at least this share of the largest contribution, that matches no
#: predicted mode and is no combination tone is unexplained: the modes criterion fails
#: (however fast it decays: a mode at a wrong frequency that dies within the window, such
#: as a rotor-field coupling predicted with the wrong C_M, is still a wrong mode)
UNEXPLAINED_SHARE = 0.05
#: a root farther than this many tolerances from a predicted mode is not matched to it
GATE = 3.0
#: most rows of the stacked Hankel matrix (rows are subsampled beyond: the shift invariance
#: the pencil uses is along the columns)
MAX_ROWS = 1000


@dataclasses.dataclass(frozen=True)
class Root:
    """An identified continuous-time eigenvalue with its uncertainty (module doc)."""

    value: complex
    re: Measured
    im: Measured
    #: rms contribution over the window, relative to the largest root's
    share: float
    #: its rms contribution over the second half of the window over that over the first
    #: (nan: not found again in both halves)
    growth: float = math.nan

    @property
    def resolved(self) -> bool:
        """Found again in a half of the window: its frequency has a bounded uncertainty."""
        return self.im.bounded

    def grows(self, span: float) -> bool:
        """Return whether it grows in a window of ``span`` seconds: Re > 0 resolved, larger later.

        Resolved: its frequency found again in a half of the window, and Re above the least
        the window resolves (its interval above RESOLVABLE / span). A pole of positive real
        part is growth only where the motion shows it: the root's amplitude larger in the
        second half of the window than in the first. A mode whose frequency drifts with its
        amplitude as it decays is fitted in a short window by a pole of the wrong sign whose
        halves agree (both see the drift), while its amplitude falls (``gyro-rotor demo``
        on a gyroscopically stabilised system, window 0 .. 2 s: Re 0.23 (interval
        0.043 .. 0.41) at 16.1 Hz).
        """
        return (self.resolved and self.re.lo > RESOLVABLE / max(span, 1e-9)
                and self.growth > 1.0)

    @property
    def freq_hz(self) -> float:
        """|Im| / 2 pi [Hz]."""
        return abs(self.value.imag) / _TWO_PI


def _pencil(Y: np.ndarray, dt: float, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Roots (Im >= 0) and their rms contributions of samples Y (N, k) (module doc)."""
    N, k = Y.shape
    L = max(min(N // 3, 120), order + 1)
    rows = N - L
    if rows < order + 1:
        raise AnalysisError(f'{N} samples are too few for order {order}')
    step = max(1, math.ceil(k * rows / MAX_ROWS))
    idx = np.arange(0, rows, step)[:, None] + np.arange(L + 1)[None, :]
    H = np.concatenate([Y[:, c][idx] for c in range(k)], axis=0)
    _, sv, Vh = np.linalg.svd(H, full_matrices=False)
    order = min(order, int(np.count_nonzero(sv > 1e-13 * sv[0])))
    if order < 1:
        return np.zeros(0, complex), np.zeros(0)
    Vr = Vh[:order].conj().T
    z = np.linalg.eigvals(np.linalg.lstsq(Vr[:-1], Vr[1:], rcond=None)[0])
    z = z[np.abs(z) > 0]
    n = np.arange(N)
    with np.errstate(over='ignore', under='ignore', invalid='ignore'):
        Phi = np.exp(np.outer(n, np.log(z.astype(complex))))
        amp = np.linalg.lstsq(Phi, Y.astype(complex), rcond=None)[0]      # (order, k)
        gain = np.sqrt(np.mean(np.abs(Phi) ** 2, axis=0))                # rms of z^n
    contrib = np.sqrt(np.mean(np.abs(amp) ** 2, axis=1)) * gain
    lam = np.log(z.astype(complex)) / dt
    keep = (lam.imag >= -1e-9) & np.isfinite(lam) & np.isfinite(contrib)
    return lam[keep], contrib[keep]


def _match(a: np.ndarray, b: np.ndarray) -> dict:
    """Map indices of ``a`` to indices of ``b`` one to one, nearest pairs first.

    Within 5 % of |a| (or 0.05 1/s): the same root seen again, not a neighbour.
    """
    if not len(a) or not len(b):
        return {}
    C = np.abs(a[:, None] - b[None, :]) / np.maximum(np.abs(a), 1.0)[:, None]
    out: dict = {}
    taken: set = set()
    for flat in np.argsort(C, axis=None):
        i, j = divmod(int(flat), C.shape[1])
        if C[i, j] > 0.05:
            break
        if i not in out and j not in taken:
            out[i] = j
            taken.add(j)
    return out


def identify_roots(Y: np.ndarray, dt: float, order: int) -> list[Root]:
    """Identify ``order`` exponentials in Y (N, k), each with its jackknife uncertainty.

    Channels are normalized to unit rms. Raises :class:`AnalysisError` for too few samples.
    """
    Y = np.asarray(Y, dtype=float)
    scale = np.sqrt(np.mean(Y * Y, axis=0))
    Y = Y[:, scale > 0] / scale[scale > 0]
    if Y.shape[1] == 0:
        return []
    lam, contrib = _pencil(Y, dt, order)
    halves = []
    N = Y.shape[0]
    for part in (Y[:N // 2], Y[N // 2:]):
        try:
            halves.append(_pencil(part, dt, order))
        except (AnalysisError, np.linalg.LinAlgError):
            halves.append((np.zeros(0, complex), np.zeros(0)))
    top = float(contrib.max()) if contrib.size else 0.0
    dev_re = [[] for _ in lam]
    dev_im = [[] for _ in lam]
    amps = [[] for _ in lam]
    for h, c in halves:
        for i, j in _match(lam, h).items():
            dev_re[i].append(abs(h[j].real - lam[i].real))
            dev_im[i].append(abs(h[j].imag - lam[i].imag))
            amps[i].append(c[j])
    out = []
    # the window's own resolution: a rate r changes an amplitude by r T over it, which
    # the nonlinear remainder reaches at RESOLVABLE (the halves share that remainder, so
    # their spread does not show it); the same for the frequency (the pole moves as a
    # point of the complex plane)
    window = 0.5 * RESOLVABLE / (N * dt)
    for i, z in enumerate(lam):
        floor = max(1e-9 * abs(z), window)
        ure = max(dev_re[i], default=math.inf)
        uim = max(dev_im[i], default=math.inf)
        ure, uim = max(ure, floor), max(uim, floor)
        growth = amps[i][1] / amps[i][0] if len(amps[i]) == 2 and amps[i][0] > 0 else math.nan
        out.append(Root(complex(z), Measured.pm(z.real, ure), Measured.pm(z.imag, uim),
                        float(contrib[i] / top) if top > 0 else 0.0, float(growth)))
    return out


def identify_modes(Y: np.ndarray, dt: float, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Continuous-time eigenvalues and relative contributions of samples Y (channels, N)."""
    roots = identify_roots(np.atleast_2d(np.asarray(Y, dtype=float)).T, dt, order)
    return (np.array([r.value for r in roots], dtype=complex),
            np.array([r.share for r in roots], dtype=float))


@dataclasses.dataclass
class ModeCheck:
    """A predicted mode against the data of one window (and, in a result, the whole run).

    ``measured`` is the matched root (None if none); ``freq``/``rate`` its frequency
    [rad/s] and real part [1/s] with their intervals; ``freq_status``/``rate_status`` the
    rule's decision on each (None: not judged); ``note`` says why a number is not
    measurable. ``seen`` is what the whole run saw (set by the analyzer).
    """

    name: str
    predicted: complex
    measured: complex | None
    amplitude: float
    status: ModeStatus
    reached_by_drive: bool = True
    structural: bool = False
    freq: Measured | None = None
    rate: Measured | None = None
    freq_status: Status | None = None
    rate_status: Status | None = None
    note: str = ''
    window_s: float = math.nan
    #: over the run: (first, last) window end [s] where the mode was identified as predicted
    seen: tuple = ()
    #: over the run: the text of the status (e.g. 'decaying as predicted in the windows
    #: ending t = 3 .. 11 s; decayed below the noise floor since')
    run_status: str = ''

    @property
    def marginal_like(self) -> bool:
        """Judged as undamped: a mode the drive does not reach."""
        return self.status is ModeStatus.EXPECTED_MARGINAL or (
            not self.reached_by_drive and not self.structural)

    @property
    def rate_target(self) -> float:
        """Return the real part the rate is judged against (0: a structural, unreached mode)."""
        return 0.0 if (self.structural or not self.reached_by_drive) else self.predicted.real

    @property
    def pred_tau(self) -> float:
        """Predicted decay time [s] (inf for a structural zero root: it does not decay)."""
        if self.structural or not self.predicted.real < 0:
            return math.inf
        return -1.0 / self.predicted.real

    @property
    def tau(self) -> Measured | None:
        """Measured decay time [s] with its interval, where the rate is resolved as a decay.

        Resolved: the rate's interval lies below zero and is at most its own size (2 sigma
        from zero); otherwise the window cannot measure the decay time.
        """
        r = self.rate
        if r is None or self.structural or not r.bounded:
            return None
        if not (r.hi < 0 and 2 * r.u <= -r.value):
            return None
        return Measured(-1.0 / r.value, -1.0 / r.lo, -1.0 / r.hi)

    @property
    def meas_tau(self) -> float:
        """Measured decay time [s] (NaN where not resolved)."""
        tau = self.tau
        return tau.value if tau is not None else math.nan

    def describe(self) -> str:
        """One phrase: the status, with the run's history where it adds to it."""
        text = self.run_status or str(self.status)
        return text + (f' ({self.note})' if self.note and not self.run_status else '')

    def as_dict(self) -> dict:
        """JSON-friendly dict."""
        def c(z):
            return None if z is None else [z.real, z.imag]
        tau = self.tau
        return {'name': self.name, 'predicted': c(self.predicted),
                'measured': c(self.measured), 'pred_freq_hz': abs(self.predicted.imag) / _TWO_PI,
                'meas_freq_hz': (None if self.freq is None else
                                 [x / _TWO_PI if x is not None else None
                                  for x in self.freq.as_list()]),
                'meas_rate': None if self.rate is None else self.rate.as_list(),
                'pred_tau_s': _num(self.pred_tau),
                'meas_tau_s': None if tau is None else tau.as_list(),
                'amplitude': self.amplitude, 'status': str(self.status),
                'freq_status': _st(self.freq_status), 'rate_status': _st(self.rate_status),
                'note': self.note, 'seen': list(self.seen), 'run_status': self.run_status,
                'reached_by_drive': self.reached_by_drive}


def _num(x: float):
    return x if math.isfinite(x) else None


def _st(s):
    return None if s is None else str(s)


@dataclasses.dataclass(frozen=True)
class ModesFound:
    """The predicted modes judged, and the identified roots no mode explains."""

    checks: list
    #: (root, text) of resolved lasting oscillations nothing explains: the criterion fails
    unexplained: list
    #: (root, text) of combination tones (sum or difference of two modes' frequencies)
    combinations: list = dataclasses.field(default_factory=list)
    #: roots whose growth is resolved (Re above the window's resolution)
    growing: list = dataclasses.field(default_factory=list)
    #: every identified root above the noise floor
    roots: list = dataclasses.field(default_factory=list)


def mode_tolerances(ev: complex, span: float) -> tuple[float, float]:
    """(frequency, rate) tolerance of a predicted eigenvalue over a window of ``span`` s.

    Frequency: :data:`FREQ_RTOL` of |lambda|; rate: :data:`RATE_RTOL` of |Re lambda|; both
    not below the window's resolution :data:`RESOLVABLE` / span (a real or zero root has
    no frequency to scale with).
    """
    res = RESOLVABLE / max(span, 1e-9)
    tol_im = max(FREQ_RTOL * abs(ev), res)
    tol_re = max(RATE_RTOL * abs(ev.real), res)
    return tol_im, tol_re


def _observable(m: PredictedMode, dt: float) -> bool:
    """Return whether the sample grid can show a mode (it lasts, it is below Nyquist)."""
    ev = m.eigenvalue
    return ev.real * dt > -5.0 and abs(ev.imag) * dt < math.pi * 0.999


def _identify(t: np.ndarray, D: np.ndarray, pred: Prediction) -> tuple:
    dt_raw = float(np.median(np.diff(t)))
    seen = [m for m in pred.modes if _observable(m, dt_raw)]
    fmax = max((m.freq_hz for m in seen), default=1.0)
    dec = max(1, int((1.0 / dt_raw) // max(40.0, 5.0 * fmax)))
    n_pred = sum(1 if abs(m.eigenvalue.imag) < 1e-9 else 2 for m in seen)
    order = n_pred + 1 + SPARE
    return identify_roots(D[::dec], dt_raw * dec, order), dt_raw * dec


def _not_identified(pred: Prediction, status=ModeStatus.NOT_IDENTIFIED) -> list:
    return [ModeCheck(m.name, m.eigenvalue, None, math.nan, status, m.reached_by_drive,
                      m.structural) for m in pred.modes]


def check_modes(t: np.ndarray, D: np.ndarray, pred: Prediction, span: float, *,
                combination_tones: bool = True) -> ModesFound:
    """Identify roots in the deviation channels D (N, channels) and judge each mode.

    The assignment runs twice: the modes matched within their tolerance (normalized
    distance <= 1) in the first pass are the parents of combination tones; a root that
    is a combination tone of parents and lies beyond the tolerance of every mode is then
    taken out before the second pass, so that a product of two modes is not judged as a
    mode that disagrees. ``combination_tones``: False counts those roots as unexplained
    (a mutation of the tests).
    """
    try:
        roots, dt = _identify(t, D, pred)
    except (AnalysisError, np.linalg.LinAlgError, ValueError):
        return ModesFound(_not_identified(pred), [])
    roots = [r for r in roots if r.share >= NOISE_SHARE]
    cand = [r for r in roots if r.resolved]
    modes = list(pred.modes)
    obs = [i for i, m in enumerate(modes) if _observable(m, dt)]
    pairs, C = _assign(modes, obs, cand, span)
    combos: dict = {}
    if combination_tones:
        combos = _products(modes, cand, pairs, C, dt, span)
        if combos:
            keep = [r for r in cand if id(r) not in combos]
            pairs, C = _assign(modes, obs, keep, span)
            cand = keep
    checks = []
    for i, m in enumerate(modes):
        if i not in obs:
            checks.append(ModeCheck(m.name, m.eigenvalue, None, 0.0, ModeStatus.UNOBSERVABLE,
                                    m.reached_by_drive, m.structural, window_s=span,
                                    note=_unobservable_note(m, dt)))
        elif i not in pairs:
            checks.append(ModeCheck(m.name, m.eigenvalue, None, 0.0, ModeStatus.NOT_EXCITED,
                                    m.reached_by_drive, m.structural, window_s=span))
        else:
            checks.append(_judge(m, cand[pairs[i]], span))
    ident = _identified(modes, cand, pairs)
    # a disagreement is what a root that absorbed an unseparated neighbour shows (a blend:
    # a frequency between the two, a beat read as decay): not the mode's own number, so
    # undecided here; an agreement (frequency and rate within tolerance) stands, a blend
    # with a neighbour of another rate does not mimic it
    for i in (i for i in pairs if checks[i].status is ModeStatus.DISAGREES):
        near = _unresolved_neighbour(modes[i], [modes[j] for j in obs if j != i],
                                     [p for p in ident if p[0] is not modes[i]], span,
                                     combination_tones)
        if near:
            checks[i] = dataclasses.replace(
                checks[i], status=ModeStatus.NOT_RESOLVED, freq_status=None,
                rate_status=None, note=near)
    used = {id(cand[b]) for b in pairs.values()}
    unexplained = []
    fmin = _TWO_PI / max(span, 1e-9)        # slower than a cycle per window: an offset
    free = [r for r in roots if id(r) not in used and id(r) not in combos and r.resolved
            and abs(r.value.imag) > fmin]
    combos.update(_aliases(free, modes, dt, span, _identified(modes, cand, pairs, C),
                           combination_tones))
    for r in free:
        if id(r) in combos:
            continue
        if r.share >= UNEXPLAINED_SHARE and r.im.u <= FREQ_RTOL * abs(r.value.imag):
            unexplained.append((r, f'{fmt_interval(_hz(r.im), "Hz")}, share '
                                   f'{r.share:.2g} of the largest'))
    combinations = [(r, combos[id(r)]) for r in roots if id(r) in combos]
    # growth: a root that grows, not one explained as a product of the modes or the second
    # root of a mode whose frequency drifts (a drifting oscillation fitted by two poles
    # may get one of positive real part while its amplitude falls)
    growing = [r for r in roots if r.grows(span) and r.share >= UNEXPLAINED_SHARE
               and id(r) not in combos]
    return ModesFound(checks, unexplained, combinations, growing, roots)


def _products(modes: list, cand: list, pairs: dict, C: dict, dt: float, span: float) -> dict:
    """Name the roots that are products of the modes matched within tolerance: {id: text}.

    Second roots of a drifting mode (:func:`_doublet`) and combination tones
    (:func:`_combination`); not the roots matched within tolerance, nor a root at the
    alias of a mode above the Nyquist frequency (that mode's: :func:`_aliases` names it).
    """
    parents = _identified(modes, cand, pairs, C)
    taken = {id(cand[b]) for i, b in pairs.items() if C[i] <= 1.0}
    taken |= {id(r) for _, r, _ in
              _mode_aliases([r for r in cand if id(r) not in taken], modes, dt,
                            span)[1].values()}
    out = {}
    for r in cand:
        if id(r) not in taken:
            text = _doublet(r, parents, span) or _combination(r, parents, span)
            if text is not None:
                out[id(r)] = text
    return out


def _identified(modes: list, cand: list, pairs: dict, C: dict | None = None) -> list:
    """Return (mode, root) of the oscillating modes matched (with ``C``: within tolerance)."""
    return [(modes[i], cand[b]) for i, b in pairs.items()
            if (C is None or C[i] <= 1.0) and not modes[i].structural
            and abs(cand[b].value.imag) > 1e-9]


def _assign(modes: list, obs: list, cand: list, span: float) -> tuple[dict, dict]:
    """Each observable mode to at most one root: {mode index: root index}, {index: d^2}.

    The cost of a pair is the squared distance in units of the combined uncertainty:
    (dIm)^2 / (tol_Im^2 + u_Im^2) + (dRe)^2 / (tol_Re^2 + u_Re^2), the prediction's
    tolerance (:func:`mode_tolerances`) and the root's uncertainty; pairs beyond
    :data:`GATE` tolerances are not matched. Solved as an assignment
    (:func:`scipy.optimize.linear_sum_assignment`), so that of two near modes each gets
    its own root.
    """
    from scipy.optimize import linear_sum_assignment
    big = 1e12
    C = np.full((len(obs), len(cand)), big)
    for a, i in enumerate(obs):
        m = modes[i]
        tol_im, tol_re = mode_tolerances(m.eigenvalue, span)
        for b, r in enumerate(cand):
            dim = (r.value.imag - m.eigenvalue.imag) ** 2 / (tol_im ** 2 + r.im.u ** 2)
            if math.isfinite(r.re.u):
                dre = (r.value.real - m.eigenvalue.real) ** 2 / (tol_re ** 2 + r.re.u ** 2)
            else:
                dre = 0.0           # the rate is not measured: match by the frequency
            if dim + dre <= GATE ** 2:
                C[a, b] = dim + dre
    if not C.size:
        return {}, {}
    rr, cc = linear_sum_assignment(C)
    pairs = {obs[a]: int(b) for a, b in zip(rr, cc) if C[a, b] < big}
    cost = {obs[a]: float(C[a, b]) for a, b in zip(rr, cc) if C[a, b] < big}
    return pairs, cost


def _hz(m: Measured) -> Measured:
    return Measured(m.value / _TWO_PI, m.lo / _TWO_PI, m.hi / _TWO_PI)


def _unobservable_note(m: PredictedMode, dt: float) -> str:
    ev = m.eigenvalue
    if abs(ev.imag) * dt >= math.pi * 0.999:
        return (f'{m.freq_hz:.4g} Hz is above the Nyquist frequency {0.5 / dt:.4g} Hz of '
                'the samples')
    return f'it decays within a sample ({-1.0 / ev.real:.3g} s < {dt:.3g} s)'


def alias_hz(f: float, fs: float) -> float:
    """Return the frequency at which a sine of ``f`` Hz sampled at ``fs`` Hz appears.

    The samples of f and of |f - k fs| are the same for every integer k: the apparent
    frequency is f folded into [0, fs/2].
    """
    r = math.fmod(abs(f), fs)
    return min(r, fs - r)


def _fold_u(r: Root, fs: float, span: float) -> float:
    """Return the uncertainty [Hz] of a root's frequency as the folding sees it.

    Sampled at ``fs``, a tone at f and its mirror fs - f, 2 |fs/2 - f| apart, are one
    pair of roots; a window of T s separates them only when they are more than 1/T
    apart. A root at the Nyquist frequency (within its uncertainty) is therefore any
    tone within 1/(2T) of fs/2, however narrow its own interval (the pencil pins the
    unresolved pair to z = -1, and each half of the window does the same).
    """
    u = r.im.u / _TWO_PI
    if abs(r.freq_hz - 0.5 * fs) <= u:
        u = max(u, 0.5 / max(span, 1e-9))
    return u


def _folded(what: str, f: float, fs: float) -> str:
    """Say where a tone of ``f`` Hz shows sampled at ``fs``: at f below fs/2, else its alias."""
    k = round(f / fs)
    if k == 0:
        return f'{what.removeprefix("the ")}: {f:.4g} Hz'
    return f'sampled alias of {what}: |{f:.4g} - {k} x {fs:.4g}| = {alias_hz(f, fs):.4g} Hz'


def _nyquist_note(r: Root, fs: float, span: float) -> str:
    """Say that a root at the Nyquist frequency stands for the tones near it ('' if not)."""
    if _fold_u(r, fs, span) <= r.im.u / _TWO_PI:
        return ''
    return (f'; a root at the Nyquist frequency {0.5 * fs:.4g} Hz is any tone within 1/(2T) '
            f'= {0.5 / span:.2g} Hz of it')


def _mode_aliases(roots: list, modes: list, dt: float, span: float) -> tuple[list, dict]:
    """Return the lasting modes above the Nyquist frequency and the roots at their aliases.

    A root within the mode's frequency tolerance (:func:`mode_tolerances`, unchanged by
    the folding) of its alias is that alias (the nearest root, one per mode): {mode name:
    (distance, root, text)}.
    """
    fs = 1.0 / dt
    # lasting (not gone within a sample) but not observable: above the Nyquist frequency
    nyq = [m for m in modes if not m.structural and m.eigenvalue.real * dt > -5.0
           and not _observable(m, dt)]
    single: dict = {}
    for m in nyq:
        f = abs(m.eigenvalue.imag) / _TWO_PI
        fa = alias_hz(f, fs)
        tol_im, _ = mode_tolerances(m.eigenvalue, span)
        for r in roots:
            d = abs(r.freq_hz - fa) / (tol_im / _TWO_PI + 2.0 * _fold_u(r, fs, span))
            if d <= 1.0 and (m.name not in single or d < single[m.name][0]):
                text = (_folded(m.name, f, fs) + f' ({f:.4g} Hz is above the Nyquist '
                        f'frequency {0.5 * fs:.4g} Hz)' + _nyquist_note(r, fs, span))
                single[m.name] = (d, r, text)
    return nyq, single


def _aliases(roots: list, modes: list, dt: float, span: float, inband: list,
             combination_tones: bool = True) -> dict:
    """Name roots as aliases of lasting predicted modes above the Nyquist frequency.

    Such a mode is not observable at its own frequency, but its samples are those of
    its alias (:func:`alias_hz`). A root within the mode's frequency tolerance
    (:func:`mode_tolerances`, unchanged by the folding) of its alias is that alias (the
    nearest root, one per mode); a root that is the alias of a combination tone of those
    (its parents' frequencies as measured, unfolded, combined as :func:`_combination`
    does, and folded again; within twice their combined uncertainty) is named so, before
    the looser match to a mode's predicted alias. A root at the Nyquist frequency is the
    fold of any tone within the window's resolution of it (:func:`_fold_u`). ``inband``:
    (mode, root) of the modes identified at their own frequency, parents too;
    ``combination_tones`` False: no combination tones (:func:`check_modes`). Return
    {id(root): text}.
    """
    fs = 1.0 / dt
    nyq, single = _mode_aliases(roots, modes, dt, span)
    # the parents: each aliased mode's true frequency from its measured alias
    parents = [(m.name, r.freq_hz, r.im.u / _TWO_PI, r) for m, r in inband]
    unfolded = {id(r) for _, r in inband}
    for m in nyq:
        if m.name in single:
            r = single[m.name][1]
            f = abs(m.eigenvalue.imag) / _TWO_PI
            k = round(f / fs)
            true = min((k * fs + r.freq_hz, k * fs - r.freq_hz), key=lambda x: abs(x - f))
            parents.append((m.name, true, r.im.u / _TWO_PI, r))
    out = {id(r): text for _, r, text in single.values()}
    for r in roots if combination_tones else ():
        best = None
        own = [p for p in parents if p[3] is not r]
        for order, combo, signs, f in _tones([p[1] for p in own]):
            if best is not None and order > best[2]:
                break                   # the lowest order that explains it
            if (round(f / fs) == 0 and all(id(own[k][3]) in unfolded for k in combo)
                    and not _nyquist_note(r, fs, span)):
                continue        # in-band modes' tone, not folded: :func:`_combination` names it
            fa = alias_hz(f, fs)
            # a repeated parent's error repeats: the uncertainties add
            u = 2.0 * (_fold_u(r, fs, span) + sum(own[k][2] for k in combo))
            d = abs(r.freq_hz - fa)
            if d <= u and (best is None or d / u < best[0]):
                label = _combo_label([own[k][0] for k in combo], signs)
                best = (d / u, _folded(f'the combination tone {label}', f, fs)
                        + f' ({d:.2g} Hz apart, within {u:.2g} Hz: 2 x the sum of the '
                        'uncertainties of the frequencies)' + _nyquist_note(r, fs, span), order)
        if best is not None:
            out[id(r)] = best[1]
    return out


def _unresolved_neighbour(m: PredictedMode, others: list, parents: list, span: float,
                          combination_tones: bool = True) -> str:
    """Say why a window cannot separate a mode from its nearest neighbour ('' if it can).

    Used on a mode that disagrees (:func:`check_modes`): it is then not decided.

    A window of T s resolves two frequencies about 1/T apart; closer, the root matched
    to the mode absorbs its neighbour (an amplitude modulation the fit reads as a wrong
    frequency or decay, with a narrow interval that excludes the truth). Neighbours: the
    other observable predicted modes and the combination tones (up to
    :data:`COMBINATION_ORDER`) of the other modes identified in the window (measured
    frequencies).
    """
    f = abs(m.eigenvalue.imag) / _TWO_PI
    if m.structural or f <= 0:
        return ''
    res = 1.0 / max(span, 1e-9)
    near = [(abs(f - abs(o.eigenvalue.imag) / _TWO_PI), o.name, abs(o.eigenvalue.imag) / _TWO_PI)
            for o in others if not o.structural and abs(o.eigenvalue.imag) > 0]
    if combination_tones:
        names = [o.name for o, _ in parents]
        for _, combo, signs, fc in _tones([r.freq_hz for _, r in parents]):
            label = _combo_label([names[k] for k in combo], signs)
            near.append((abs(f - fc), f'combination tone {label}', fc))
    close = min((n for n in near if n[0] < res), default=None)
    if close is None:
        return ''
    return (f'not separable from {close[1]} at {close[2]:.4g} Hz in this window: '
            f'{close[0]:.3g} Hz apart, the window resolves 1/T = {res:.3g} Hz')


def _doublet(r: Root, parents: list, span: float) -> str | None:
    """Name ``r`` as the second root of an identified mode whose frequency drifts.

    A nonlinear mode's frequency changes with its amplitude; over a window in which the
    amplitude decays a lot (a drive that has just locked after pole slips), the pencil
    fits the drifting oscillation with two roots of nearly the same frequency. A root
    within the frequency tolerance of a mode identified within its tolerance is that.
    """
    for m, root in parents:
        tol_im, _ = mode_tolerances(m.eigenvalue, span)
        if abs(r.value.imag - root.value.imag) <= tol_im + 2.0 * math.hypot(r.im.u, root.im.u):
            return (f'second root of {m.name} (its frequency drifts with the amplitude: '
                    f'{root.freq_hz:.4g} Hz)')
    return None


#: a combination tone matches within this many combined uncertainties of the frequencies
#: (the tolerance printed with it)
TONE_SIGMAS = 2.0
#: combination tones up to this order (products of two modes: sums and differences of two
#: frequencies, harmonics; of three: a cubic nonlinearity, such as a sine-law drive's)
COMBINATION_ORDER = 3


def _combination(r: Root, parents: list, span: float) -> str | None:
    """Name ``r`` as a sum or difference of identified modes' frequencies, if it is one.

    ``parents``: (mode, root) of the modes identified within their tolerance in this
    window (a product of modes needs the modes in the motion). A combination
    sum_k s_k omega_k (s_k = +-1, two or up to :data:`COMBINATION_ORDER` terms, repeats
    allowed: 2 omega_i is a harmonic) matches when it is within twice the combined
    uncertainty of the measured frequencies, and its rate sum_k Re lambda_k (a product
    of modes decays at the sum of their rates) within twice theirs plus the window's
    resolution. The lowest order that matches explains the root; where more than one tone
    of that order matches, the data cannot tell which it is (their distance is within the
    tolerance, and below the window's resolution 1/T if the tolerance is): the root is a
    combination tone of that order, not named after one of them. The text says the
    tolerance and the window's 1/T.
    """
    res_re = RESOLVABLE / max(span, 1e-9)
    items = [(m.name, root.value.imag, root.im.u, root.value.real,
              root.re.u if root.re.bounded else res_re) for m, root in parents]
    found = []
    for order, combo, signs, w in _tones([it[1] for it in items]):
        if found and order > found[0][0]:
            break               # the lowest order that explains it
        uw = TONE_SIGMAS * math.sqrt(r.im.u ** 2 + sum(items[k][2] ** 2 for k in combo))
        d = abs(r.value.imag - w)
        if d > uw:
            continue
        rate = sum(items[k][3] for k in combo)
        ur = 2.0 * math.sqrt((r.re.u if r.re.bounded else 0.0) ** 2
                             + sum(items[k][4] ** 2 for k in combo)) + res_re
        if abs(r.value.real - rate) > ur:
            continue
        found.append((order, d / uw, _combo_label([items[k][0] for k in combo], signs), w,
                      d, uw))
    if not found:
        return None
    found.sort(key=lambda x: x[1])
    dec = _digits(r.im.u / _TWO_PI)      # the digits of the measured frequency
    res = f'the window resolves 1/T = {1.0 / max(span, 1e-9):.2g} Hz'
    why = f'{TONE_SIGMAS:g} x the combined uncertainty of the frequencies; {res}'
    if len(found) == 1:
        _, _, label, w, d, uw = found[0]
        return (f'combination tone {label}: {w / _TWO_PI:.{dec}f} Hz ({d / _TWO_PI:.2g} Hz '
                f'apart, within the tolerance {uw / _TWO_PI:.2g} Hz: {why})')
    tones = ' or '.join(f'{label}: {w / _TWO_PI:.{dec}f} Hz ({d / _TWO_PI:.2g} Hz apart, '
                        f'tolerance {uw / _TWO_PI:.2g} Hz)' for _, _, label, w, d, uw in found)
    return (f'combination tone of order {found[0][0]}, not told apart in this window: '
            f'{tones} ({why})')


def tone_line(r: Root, text: str) -> str:
    """Return an identified root named by ``text``: its frequency +- uncertainty, the name."""
    return f'{fmt_pm(abs(r.value.imag) / _TWO_PI, r.im.u / _TWO_PI, "Hz")} is a {text}'


def _tones(values: list) -> Iterator[tuple[int, tuple, tuple, float]]:
    """Yield the positive combinations sum_k s_k v_k of ``values``, order by order.

    Orders 2 .. :data:`COMBINATION_ORDER` (repeats allowed: 2 v_i is a harmonic), the
    first sign +1, no term cancelling another (v_i + v_j - v_j is v_i, no tone of order
    3): (order, indices, signs, value). The one enumeration of combination
    tones (:func:`_combination`, their aliases, the neighbours a window cannot resolve).
    """
    import itertools
    for order in range(2, COMBINATION_ORDER + 1):
        for combo in itertools.combinations_with_replacement(range(len(values)), order):
            for tail in itertools.product((1, -1), repeat=order - 1):
                signs = (1,) + tail
                if any(a == b and sa != sb for a, sa, b, sb in
                       zip(combo, signs, combo[1:], signs[1:])):
                    continue        # v_i - v_i cancels: a lower order (or the mode itself)
                value = sum(sg * values[k] for sg, k in zip(signs, combo))
                if value > 0:
                    yield order, combo, signs, value


def _combo_label(names: list, signs: tuple) -> str:
    """Return 'a + b', '2 x a', '2 x a - b' ... for a combination of mode names."""
    terms: dict = {}
    for n, sg in zip(names, signs):
        terms[n] = terms.get(n, 0) + sg
    out = ''
    for n, k in terms.items():
        if k == 0:
            continue
        mag = f'{abs(k)} x {n}' if abs(k) > 1 else n
        out += (mag if not out and k > 0 else f' {"+" if k > 0 else "-"} {mag}' if out
                else f'-{mag}')
    return out


def _judge(m: PredictedMode, r: Root, span: float) -> ModeCheck:
    """Judge a predicted mode against its matched root with the one rule."""
    ev = m.eigenvalue
    tol_im, tol_re = mode_tolerances(m.eigenvalue, span)
    notes = []
    freq_status = decide(r.im.abs_deviation(ev.imag), tol_im, 'below')
    if r.im.u >= tol_im:
        freq_status = None
        notes.append('frequency not resolved in this window '
                     f'({needs_phrase(span, tol_im, r.im.u)})')
    target = 0.0 if (m.marginal or m.structural) else ev.real
    rate_status = decide(r.re.abs_deviation(target), tol_re, 'below')
    if not r.re.bounded or r.re.u >= tol_re:
        rate_status = None
        notes.append('decay not measurable in this window '
                     f'({needs_phrase(span, tol_re, r.re.u)})')
    judged = [s for s in (freq_status, rate_status) if s is not None]
    if Status.FAIL in judged:
        status = ModeStatus.DISAGREES
    elif freq_status is None or Status.NOT_YET in judged:
        status = ModeStatus.NOT_RESOLVED
    elif m.structural:
        status = ModeStatus.STRUCTURAL_ZERO_ROOT
    elif m.marginal:
        status = ModeStatus.EXPECTED_MARGINAL
    elif ev.real > 0 and ev.real * span < RESOLVABLE:
        status = ModeStatus.NOT_RESOLVED        # its growth is below this window's resolution
        notes.append(f'growth not resolvable in this window (Re lambda x {span:g} s = '
                     f'{ev.real * span:.2g} < {RESOLVABLE:g}; needs about '
                     f'{RESOLVABLE / ev.real:.3g} s)')
    elif ev.real > 0:
        status = ModeStatus.GROWING             # never "damped", however slow its growth
    elif -ev.real * span < RESOLVABLE:
        status = ModeStatus.WEAKLY_DAMPED       # its decay is below this window's resolution
    elif rate_status is None:
        status = ModeStatus.NOT_RESOLVED
    else:
        status = ModeStatus.DECAYING_AS_PREDICTED
    return ModeCheck(m.name, ev, r.value, r.share, status, m.reached_by_drive, m.structural,
                     freq=r.im, rate=r.re, freq_status=freq_status, rate_status=rate_status,
                     note='; '.join(notes), window_s=span)
