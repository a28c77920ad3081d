"""Live and offline evidence of asymptotic stability (Magnus 1980, eqs. 13, 17): pure Python.

:class:`RotorAnalyzer` is a streaming check fed with samples of the simulation node's
``joint_states`` and ``energy`` topics (paired by their common simulation time; see
:class:`SamplePairer`). The analysis node feeds it live, ``gyro-rotor analyze`` feeds it
from a bag: the same class, the same numbers. Its :meth:`RotorAnalyzer.result` holds

* **Lyapunov**: the largest increase of E* between samples (eq. 13 must not increase,
  eq. 17), against ``lyapunov_tol`` (integrator tolerance), and the largest
  energy-balance residual |E* + D - E_ref| (docs/model.md section 4);
* **Decay**: over a sliding window, the fitted decay rate of E* - E*_inf (E*_inf = E* of
  the steady motion) and of the envelope of the deviations from the steady motion, against
  the predicted spectral abscissa alpha: no excited mode decays slower than alpha, so the
  energy must fall at least at 2 |alpha| and the deviations at |alpha| (a check that
  fails if the prediction or the data is wrong);
* **Modes**: eigenvalues identified from the window (a matrix pencil fit of the
  deviations, :func:`identify_modes`) matched to the predicted ones *mode by mode*, each
  with predicted and measured frequency and decay time, and a status: ``'decaying as
  predicted'``, ``'expected marginal'`` (a mode the drive does not reach, e.g. the tilt
  modes about solution I, Hagedorn's exclusion), ``'weakly damped'`` (predicted decay time
  far beyond the window: the nutation about solution II decays over minutes to hours; its
  measured decay time is reported, it is not a failure), ``'not excited'`` or
  ``'disagrees'``;
* **Synchronism** (sine law with p pole pairs): pole slips counted as passages of z over
  the maxima of the drive potential, z = (2k+1) pi / p, and a ``'lost synchronism'``
  state while slips keep coming; the well the rotor locks into is reported;
* **Data integrity**: sequence gaps (dropped messages, from the node's never-reset
  ``seq``), resets (t_sim or the grid index going back), time jumps, kicks (E* rising with
  a continuous residual: the node's ``~/perturb``) and parameter changes. Each of these
  starts a new *segment*; fits never mix segments;
* **Verdict**: ``'asymptotically stable'``, ``'marginal'`` (naming the modes),
  ``'unstable'``, ``'diverged'`` or ``'insufficient data'``, with the evidence as text.

Nothing here imports rclpy or message types.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Iterable, Mapping, Sequence

from gyro_rotor.core.scene import Scene
from gyro_rotor.errors import AnalysisError, BagError, ParameterError
import numpy as np

__all__ = ['RotorAnalyzer', 'Sample', 'SamplePairer', 'Prediction', 'PredictedMode',
           'ModeCheck', 'SegmentResult', 'AnalysisResult', 'predict', 'identify_modes',
           'ANALYSIS_FIELDS', 'ANALYSIS_LABEL', 'MODE_FIELDS', 'MODE_LABEL', 'VERDICTS',
           'MODE_STATUS', 'SYNC_STATES', 'scene_to_flat', 'energy_sample_fields',
           'samples_from_trajectory', 'scene_from_sim_doc', 'AnalysisSession',
           'analyze_bag', 'BagAnalysis']

#: verdicts, in the order of their numeric code on the ``analysis`` topic
VERDICTS = ('insufficient data', 'asymptotically stable', 'marginal', 'unstable', 'diverged')
#: per-mode statuses, in the order of their numeric code on ``analysis_modes``
MODE_STATUS = ('not identified', 'decaying as predicted', 'expected marginal',
               'weakly damped', 'not excited', 'disagrees', 'structural zero root')
#: synchronism states, in the order of their numeric code
SYNC_STATES = ('synchronous', 'lost synchronism', 'resynchronized')

#: scalar fields of the ``analysis`` topic (std_msgs/Float64MultiArray, one dimension)
ANALYSIS_FIELDS = (
    't_sim', 'segment', 'samples', 'dropped', 'resets', 'kicks', 'time_jumps',
    'E_star', 'E_inf', 'lyapunov_max_increase', 'lyapunov_violations', 'residual_max',
    'energy_decay_rate', 'deviation_decay_rate', 'spectral_abscissa', 'decay_rate_bound',
    'pole_slips', 'sync_state', 'well', 'verdict', 'modes_matched', 'window_s')
ANALYSIS_LABEL = ','.join(ANALYSIS_FIELDS)
#: columns of one row of the ``analysis_modes`` topic (2-D Float64MultiArray, a row per mode)
MODE_FIELDS = ('pred_re', 'pred_im', 'meas_re', 'meas_im', 'pred_tau', 'meas_tau',
               'amplitude', 'status')
MODE_LABEL = ','.join(MODE_FIELDS)

_TWO_PI = 2.0 * math.pi
_BLAS_LIMITED = False


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


# ------------------------------------------------------------------------------------------
# samples


@dataclasses.dataclass(frozen=True)
class Sample:
    """One paired sample of ``energy`` and ``joint_states`` at simulation time ``t``.

    ``positions``/``velocities`` are (theta, psi, phi_R, phi_M) and their rates as
    published (angles wrapped); the rest are the ``energy`` fields of
    :mod:`gyro_rotor.ros_msgs` (t_sim, E_star, dE_dt, residual, z, zdot, seq, D, k).
    """

    t: float
    seq: int
    k: int
    E_star: float
    dE_dt: float
    residual: float
    z: float
    zdot: float
    D: float
    positions: tuple = (0.0, 0.0, 0.0, 0.0)
    velocities: tuple = (0.0, 0.0, 0.0, 0.0)


def energy_sample_fields(values: Sequence[float], fields: Sequence[str]) -> dict:
    """Map an ``energy`` array to a dict by the field names of its layout label."""
    if len(values) != len(fields):
        raise AnalysisError(f'energy message has {len(values)} values but its layout names '
                            f'{len(fields)} fields ({",".join(fields)})')
    return dict(zip(fields, (float(v) for v in values)))


class SamplePairer:
    """Pair ``energy`` and ``joint_states`` messages by their simulation time stamp.

    The node publishes both for every grid point with the same stamp; messages may arrive
    interleaved in any order. A joint state without energy is dropped after ``keep``
    newer stamps (it was lost, and sequence gaps count that). Energy without a joint state
    is paired with ``None`` joints after the same delay.
    """

    def __init__(self, keep: int = 64):
        self.keep = keep
        self._energy: dict[int, dict] = {}
        self._joints: dict[int, tuple] = {}
        self._order: list[int] = []

    def add_energy(self, stamp_ns: int, fields: Mapping[str, float]) -> list[Sample]:
        """Add an energy message; return the samples completed (in order)."""
        return self._add(stamp_ns, energy=dict(fields))

    def add_joints(self, stamp_ns: int, positions, velocities) -> list[Sample]:
        """Add a joint state; return the samples completed."""
        return self._add(stamp_ns, joints=(tuple(float(v) for v in positions),
                                           tuple(float(v) for v in velocities)))

    def _add(self, stamp_ns: int, energy=None, joints=None) -> list[Sample]:
        if energy is not None:
            self._energy[stamp_ns] = energy
        if joints is not None:
            self._joints[stamp_ns] = joints
        if stamp_ns not in self._order:
            self._order.append(stamp_ns)
        out = []
        while self._order:
            s = self._order[0]
            if s in self._energy and s in self._joints:
                out.append(self._make(s))
            elif len(self._order) > self.keep:
                if s in self._energy:
                    out.append(self._make(s))
                else:
                    self._order.pop(0)
                    self._joints.pop(s, None)
            else:
                break
        return out

    def flush(self) -> list[Sample]:
        """Return every pending energy sample (joints missing or not)."""
        out = []
        while self._order:
            s = self._order[0]
            if s in self._energy:
                out.append(self._make(s))
            else:
                self._order.pop(0)
                self._joints.pop(s, None)
        return out

    def _make(self, s: int) -> Sample:
        self._order.pop(0)
        e = self._energy.pop(s)
        pos, vel = self._joints.pop(s, (None, None))
        nan4 = (math.nan,) * 4
        return Sample(t=e['t_sim'], seq=int(e['seq']), k=int(e.get('k', -1)),
                      E_star=e['E_star'], dE_dt=e.get('dE_dt', math.nan),
                      residual=e.get('residual', math.nan), z=e['z'], zdot=e['zdot'],
                      D=e.get('D', math.nan), positions=pos or nan4, velocities=vel or nan4)


# ------------------------------------------------------------------------------------------
# predictions


@dataclasses.dataclass(frozen=True)
class PredictedMode:
    """One predicted mode (one eigenvalue of a conjugate pair, Im >= 0)."""

    name: str
    eigenvalue: complex
    reached_by_drive: bool = True
    marginal: bool = False
    structural: bool = False

    @property
    def freq_hz(self) -> float:
        """Damped frequency |Im| / 2 pi [Hz]."""
        return abs(self.eigenvalue.imag) / _TWO_PI

    @property
    def tau(self) -> float:
        """Decay time -1/Re [s] (inf for a marginal or growing mode)."""
        re = self.eigenvalue.real
        return -1.0 / re if re < 0 else math.inf


@dataclasses.dataclass(frozen=True)
class Prediction:
    """What the linearization predicts for a scene (see :func:`predict`)."""

    scene: str
    coords: str
    modes: tuple
    spectral_abscissa: float
    verdict: str
    E_inf: float
    theta0: float
    psidot0: float
    pole_pairs: int
    K_D: float
    source: str = ''

    @property
    def marginal_modes(self) -> tuple:
        """Modes on the imaginary axis (not reached by the drive)."""
        return tuple(m for m in self.modes if m.marginal)

    @property
    def decaying_abscissa(self) -> float:
        """Largest real part among the modes that decay (the rate bound for the fits)."""
        re = [m.eigenvalue.real for m in self.modes if not (m.marginal or m.structural)]
        return max(re) if re else math.nan


def _marginal(ev: complex) -> bool:
    return abs(ev.real) <= 1e-9 * max(1.0, abs(ev))


def _steady_state(scene: Scene) -> np.ndarray:
    """Model state on the unperturbed steady motion of the scene."""
    model = scene.make_model()
    ic = scene.initial
    if ic.mode != 'steady':
        return model.state_from_euler()
    sm = scene.steady()
    return model.state_from_euler(theta=sm.theta0, psidot=sm.psidot0,
                                  phi_M_dot=-sm.psidot0)


def predict(scene: Scene) -> Prediction:
    """Predicted eigenvalues, named modes and verdict of a scene's steady motion.

    Uses :func:`gyro_rotor.stability.analyze_scene` when present, else the eigenvalues of
    :func:`gyro_rotor.linearize.linearize` with modes named by their dominant coordinate
    group (tilt, twist, drive; weighted to energy units).
    """
    model = scene.make_model()
    E_inf = float(model.energy(_steady_state(scene)))
    sm = scene.steady()
    p = scene.params
    common = {'scene': scene.name, 'E_inf': E_inf, 'theta0': sm.theta0,
              'psidot0': sm.psidot0, 'pole_pairs': int(p.pole_pairs), 'K_D': float(p.K_D)}
    try:
        import gyro_rotor.linear.stability as stability
        analyze_scene = stability.analyze_scene
    except (ImportError, AttributeError):
        analyze_scene = None
    if analyze_scene is not None:
        rep = analyze_scene(scene)
        marginal = {str(getattr(m, 'name', m)) for m in rep.marginal_modes}
        modes = []
        for m in rep.modes:
            ev = complex(m.eigenvalue)
            if ev.imag < -1e-12:
                continue
            modes.append(PredictedMode(str(m.name), ev, bool(m.reached_by_drive),
                                       str(m.name) in marginal,
                                       structural=getattr(m, 'kind', '') == 'zero'))
        coords = getattr(rep, 'coords', '') or _coords(scene)
        return Prediction(coords=coords, modes=tuple(modes),
                          spectral_abscissa=float(rep.spectral_abscissa),
                          verdict=str(rep.verdict), source='stability.analyze_scene',
                          **common)
    from gyro_rotor.linear.linearize import linearize
    lin = linearize(p, sm, scene.model)
    ev, vec = np.linalg.eig(lin.A)
    ev0 = np.linalg.eigvals(lin.A0)
    modes = []
    for i in np.argsort(-ev.real):
        lam = complex(ev[i])
        if lam.imag < -1e-12:
            continue      # conjugate partner
        if abs(lam) < 1e-9:
            modes.append(PredictedMode('zero root', lam, False, False, structural=True))
            continue
        share = {}
        for g, w, v in zip(lin.groups, lin.weights, vec[:, i]):
            share[g] = share.get(g, 0.0) + (w * abs(v)) ** 2
        group = max(share, key=share.get)
        # reached by the drive: the root moved off the K_D = 0 root
        moved = np.min(np.abs(ev0 - lam)) > 1e-9 * max(1.0, abs(lam))
        name = f'{group} {abs(lam.imag) / _TWO_PI:.3g} Hz'
        modes.append(PredictedMode(name, lam, bool(moved), _marginal(lam)))
    alpha = max((m.eigenvalue.real for m in modes if not m.structural), default=0.0)
    if alpha > 1e-9:
        verdict = 'unstable'
    elif any(m.marginal for m in modes):
        verdict = 'marginal'
    else:
        verdict = 'asymptotically stable'
    return Prediction(coords=lin.coords, modes=tuple(modes), spectral_abscissa=alpha,
                      verdict=verdict, source='linearize', **common)


def _coords(scene: Scene) -> str:
    from gyro_rotor.linear.linearize import coordinates
    return coordinates(scene.model, scene.steady())


# ------------------------------------------------------------------------------------------
# identification


def identify_modes(Y: np.ndarray, dt: float, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Continuous-time eigenvalues and amplitudes of multichannel samples.

    A thin wrapper of :func:`gyro_rotor.sysid.matrix_pencil` (channels normalized to unit
    rms); the amplitude of an eigenvalue is the rms over channels of its residues, in
    units of each channel's rms.

    Parameters
    ----------
    Y : ndarray, shape (channels, N)
    dt : float
        Sample interval [s].
    order : int
        Number of exponentials (a conjugate pair counts two).
    """
    from gyro_rotor.linear.sysid import matrix_pencil
    Y = np.atleast_2d(np.asarray(Y, dtype=float))
    scale = np.sqrt(np.mean(Y * Y, axis=1))
    scale[scale == 0] = 1.0
    m = Y.shape[1]
    pencil = max(min(m // 3, 120), order + 1)      # cost: SVD of (k (m - L), L + 1)
    fit = matrix_pencil((Y / scale[:, None]).T, dt, order, pencil=pencil, normalize=False)
    amp = np.sqrt(np.mean(np.abs(fit.amplitudes) ** 2, axis=1))
    return fit.eigenvalues, amp


# ------------------------------------------------------------------------------------------
# results


@dataclasses.dataclass
class ModeCheck:
    """A predicted mode against the data."""

    name: str
    predicted: complex
    measured: complex | None
    amplitude: float
    status: str
    reached_by_drive: bool = True
    structural: bool = False

    @property
    def pred_tau(self) -> float:
        """Predicted decay time [s] (inf for a structural zero root: it does not decay)."""
        if self.structural or not self.predicted.real < 0:
            return math.inf
        return -1.0 / self.predicted.real

    @property
    def meas_tau(self) -> float:
        """Measured decay time [s] (inf if not decaying or not identified)."""
        if self.measured is None or self.measured.real >= 0:
            return math.inf
        return -1.0 / self.measured.real

    def as_dict(self) -> dict:
        """JSON-friendly dict."""
        def c(z):
            return None if z is None else [z.real, z.imag]
        return {'name': self.name, 'predicted': c(self.predicted),
                'measured': c(self.measured), 'pred_freq_hz': abs(self.predicted.imag) / _TWO_PI,
                'meas_freq_hz': (None if self.measured is None
                                 else abs(self.measured.imag) / _TWO_PI),
                'pred_tau_s': _num(self.pred_tau), 'meas_tau_s': _num(self.meas_tau),
                'amplitude': self.amplitude, 'status': self.status,
                'reached_by_drive': self.reached_by_drive}


def _num(x: float):
    return x if math.isfinite(x) else None


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
    sync_state: str
    well: int
    verdict: str
    evidence: list

    def as_dict(self) -> dict:
        """JSON-friendly dict."""
        d = dataclasses.asdict(self)
        d['modes'] = [m.as_dict() for m in self.modes]
        for k, v in d.items():
            if isinstance(v, float) and not math.isfinite(v):
                d[k] = None
        return d


@dataclasses.dataclass
class AnalysisResult:
    """The analysis so far: totals, the prediction and the segments (the last is current)."""

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
    verdict: str
    evidence: list
    level: str
    t_sim: float

    @property
    def current(self) -> SegmentResult | None:
        """Return the last segment (None before data)."""
        return self.segments[-1] if self.segments else None

    def as_dict(self) -> dict:
        """JSON-friendly dict."""
        pred = self.prediction
        return {
            'scene': self.scene, 'verdict': self.verdict, 'level': self.level,
            'evidence': list(self.evidence), 't_sim': self.t_sim, 'samples': self.samples,
            'dropped': self.dropped, 'resets': self.resets, 'kicks': self.kicks,
            'time_jumps': self.time_jumps, 'param_changes': self.param_changes,
            'pole_slips': self.pole_slips,
            'prediction': {
                'source': pred.source, 'coords': pred.coords, 'verdict': pred.verdict,
                'spectral_abscissa': pred.spectral_abscissa, 'E_inf': pred.E_inf,
                'modes': [{'name': m.name, 'eigenvalue': [m.eigenvalue.real,
                                                          m.eigenvalue.imag],
                           'freq_hz': m.freq_hz, 'tau_s': _num(m.tau),
                           'reached_by_drive': m.reached_by_drive, 'marginal': m.marginal}
                          for m in pred.modes]},
            'segments': [s.as_dict() for s in self.segments],
        }

    def analysis_vector(self) -> list[float]:
        """Values of :data:`ANALYSIS_FIELDS` (NaN where not available)."""
        s = self.current
        nan = math.nan
        alpha = self.prediction.decaying_abscissa
        vals = {
            't_sim': self.t_sim, 'segment': s.index if s else nan, 'samples': self.samples,
            'dropped': self.dropped, 'resets': self.resets, 'kicks': self.kicks,
            'time_jumps': self.time_jumps, 'E_star': s.E_last if s else nan,
            'E_inf': self.prediction.E_inf,
            'lyapunov_max_increase': s.lyapunov_max_increase if s else nan,
            'lyapunov_violations': s.lyapunov_violations if s else nan,
            'residual_max': s.residual_max if s else nan,
            'energy_decay_rate': s.energy_decay_rate if s else nan,
            'deviation_decay_rate': s.deviation_decay_rate if s else nan,
            'spectral_abscissa': self.prediction.spectral_abscissa,
            'decay_rate_bound': -alpha if math.isfinite(alpha) else nan,
            'pole_slips': self.pole_slips,
            'sync_state': SYNC_STATES.index(s.sync_state) if s else nan,
            'well': s.well if s else nan, 'verdict': VERDICTS.index(self.verdict),
            'modes_matched': (sum(m.measured is not None for m in s.modes) if s else nan),
            'window_s': s.window_s if s else nan,
        }
        return [float(vals[f]) for f in ANALYSIS_FIELDS]

    def mode_matrix(self) -> tuple[list[str], list[list[float]]]:
        """Mode names and rows of :data:`MODE_FIELDS` for the current segment."""
        s = self.current
        names, rows = [], []
        for m in (s.modes if s else []):
            meas = m.measured if m.measured is not None else complex(math.nan, math.nan)
            names.append(m.name)
            rows.append([m.predicted.real, m.predicted.imag, meas.real, meas.imag,
                         m.pred_tau, m.meas_tau, m.amplitude,
                         float(MODE_STATUS.index(m.status))])
        return names, rows


# ------------------------------------------------------------------------------------------
# the analyzer


class _Segment:
    """Raw data of one segment (ring-buffered to ``max_samples``)."""

    def __init__(self, index: int, reason: str, scene: Scene, pred: Prediction,
                 max_samples: int):
        self.index, self.reason, self.scene, self.pred = index, reason, scene, pred
        self.max_samples = max_samples
        self.rows: list[tuple] = []
        self.samples = 0
        self.t_start = math.nan
        self.E_first = math.nan
        self.lyap_max = -math.inf
        self.lyap_violations = 0
        self.residual_max = 0.0
        self.slips = 0
        self.last_slip_t = -math.inf
        self.well_index: int | None = None   # the well z last arrived in (hysteresis)
        self.last: Sample | None = None
        self.fit: dict = {}

    def add(self, s: Sample, row: tuple) -> None:
        if self.samples == 0:
            self.t_start, self.E_first = s.t, s.E_star
        self.samples += 1
        self.rows.append(row)
        if len(self.rows) > self.max_samples:
            del self.rows[:len(self.rows) - self.max_samples]
        self.last = s


def _check_window(window_s) -> float:
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
        |residual| or deviation beyond which the run counts as diverged [J].
    sync_hold_s : float
        A slip within this time keeps the state 'lost synchronism' [s].
    min_fit_s : float
        Shortest window for fits [s].
    max_window_samples : int
        Samples kept per segment (older ones are dropped from the fits).
    blas_threads : int
        Limit numpy's OpenBLAS to this many threads (0 = leave it), see
        :func:`limit_blas_threads`.
    """

    def __init__(self, scene: Scene, *, window_s: float = 8.0, lyapunov_tol: float = 1e-8,
                 lyapunov_rtol: float = 1e-9, residual_warn: float = 1e-6,
                 diverge_residual: float = 1e-2, sync_hold_s: float = 1.0,
                 min_fit_s: float = 2.0, max_window_samples: int = 20000,
                 blas_threads: int = 1):
        if not isinstance(scene, Scene):
            raise AnalysisError('RotorAnalyzer needs a gyro_rotor.scene.Scene')
        self.window_s = _check_window(window_s)
        self.lyapunov_tol = float(lyapunov_tol)
        self.lyapunov_rtol = float(lyapunov_rtol)
        self.residual_warn = float(residual_warn)
        self.diverge_residual = float(diverge_residual)
        self.sync_hold_s = float(sync_hold_s)
        self.min_fit_s = float(min_fit_s)
        self.max_window_samples = int(max_window_samples)
        global _BLAS_LIMITED
        if blas_threads and not _BLAS_LIMITED:
            _BLAS_LIMITED = limit_blas_threads(blas_threads)
        self.scene = scene
        self.prediction = predict(scene)
        self.samples = 0
        self.dropped = 0
        self.resets = 0
        self.kicks = 0
        self.time_jumps = 0
        self.param_changes = 0
        self.non_finite = 0
        self.segments: list[_Segment] = []
        self._done: list[SegmentResult] = []
        self._last: Sample | None = None
        self._dt: float | None = None

    # -- input --------------------------------------------------------------------------------
    def set_scene(self, scene: Scene) -> bool:
        """Switch to new scene parameters (a new segment); return whether they changed."""
        if scene == self.scene or (scene.params == self.scene.params
                                   and scene.model == self.scene.model
                                   and scene.initial == self.scene.initial):
            return False
        self.scene = scene
        self.prediction = predict(scene)
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
        else:
            if s.seq > last.seq + 1:
                self.dropped += s.seq - last.seq - 1
            elif s.seq <= last.seq:
                reason = 'simulation restarted (sequence went back)'
                self.resets += 1
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
                rise = s.E_star - last.E_star
                tol = self.lyapunov_tol + self.lyapunov_rtol * abs(s.E_star)
                dres = s.residual - last.residual
                if rise > tol and (not math.isfinite(dres) or abs(dres) < 0.5 * rise):
                    # E* rose, and the residual (E* + D - E_ref) did not rise with it: an
                    # external kick (~/perturb rebases E_ref), not a Lyapunov violation; an
                    # integration error moves E* and the residual together
                    reason = f'kick (E* rose by {rise:.6g} J)'
                    self.kicks += 1
        self.samples += 1
        if not all(math.isfinite(v) for v in (s.t, s.E_star, s.z, s.zdot)):
            self.non_finite += 1
        if reason is not None:
            self._new_segment(reason)
        self._add_to_segment(self.segments[-1], s, last if reason is None else None)
        self._last = s

    def add_many(self, samples: Iterable[Sample]) -> None:
        """Feed several samples."""
        for s in samples:
            self.add(s)

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
        # synchronism: passages of z over the potential maxima (2k+1) pi / p
        # with hysteresis: the well index changes only once z is within pi/(2p) of the
        # bottom of another well, so jitter on a maximum counts nothing
        p = pred.pole_pairs
        if p > 0 and math.isfinite(s.z):
            u = p * s.z / _TWO_PI                      # z in wells (bottoms at integers)
            k = round(u)
            if abs(u - k) <= 0.25:
                if seg.well_index is not None and k != seg.well_index:
                    seg.slips += abs(k - seg.well_index)
                    seg.last_slip_t = s.t
                seg.well_index = k
        seg.add(s, self._row(s, pred))

    def _row(self, s: Sample, pred: Prediction) -> tuple:
        """(t, E*, residual, z, zdot, deviation channels...) of one sample."""
        th, psi = s.positions[0], s.positions[1]
        thd, psid, _, phiMd = s.velocities
        p = pred.pole_pairs
        z = s.z
        if p > 0:
            z = z - _TWO_PI / p * round(p * z / _TWO_PI)       # deviation from the well
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
        """Evaluate the current segment and return the whole analysis so far."""
        segs = list(self._done)
        if self.segments:
            segs.append(self._evaluate(self.segments[-1]))
        verdict, evidence, level = self._verdict(segs)
        return AnalysisResult(
            scene=self.scene.name, prediction=self.prediction, samples=self.samples,
            dropped=self.dropped, resets=self.resets, kicks=self.kicks,
            time_jumps=self.time_jumps, param_changes=self.param_changes,
            pole_slips=sum(s.pole_slips for s in segs), segments=segs, verdict=verdict,
            evidence=evidence, level=level,
            t_sim=self._last.t if self._last is not None else math.nan)

    def _window(self, seg: _Segment) -> np.ndarray:
        R = np.asarray(seg.rows, dtype=float)
        if R.size == 0:
            return R.reshape(0, 5)
        if math.isfinite(self.window_s):
            R = R[R[:, 0] >= R[-1, 0] - self.window_s - 1e-9]
        return R

    def _evaluate(self, seg: _Segment) -> SegmentResult:
        pred = seg.pred
        R = self._window(seg)
        evidence: list[str] = []
        last = seg.last
        sync_state, well = 'synchronous', 0
        if pred.pole_pairs > 0 and last is not None:
            well = int(round(pred.pole_pairs * last.z / _TWO_PI))
            if last.t - seg.last_slip_t <= self.sync_hold_s:
                sync_state = 'lost synchronism'
            elif seg.slips:
                sync_state = 'resynchronized'
        # fit only data after the last slip (locked in one well)
        if R.size and math.isfinite(seg.last_slip_t):
            R = R[R[:, 0] > seg.last_slip_t + 0.5]
        span = float(R[-1, 0] - R[0, 0]) if len(R) > 1 else 0.0
        e_rate = dev_rate = math.nan
        modes: list[ModeCheck] = []
        if span >= self.min_fit_s and len(R) > 20:
            e_rate = _energy_decay_rate(R[:, 0], R[:, 1] - pred.E_inf)
            dev_rate = _envelope_decay_rate(R[:, 0], R[:, 5:], pred)
            modes = _check_modes(R[:, 0], R[:, 5:], pred, span)
        else:
            modes = [ModeCheck(m.name, m.eigenvalue, None, math.nan, 'not identified',
                               m.reached_by_drive, m.structural) for m in pred.modes]
        res = SegmentResult(
            index=seg.index, reason=seg.reason, scene=seg.scene.name,
            t_start=seg.t_start, t_end=last.t if last else math.nan, samples=seg.samples,
            E_first=seg.E_first, E_last=last.E_star if last else math.nan, E_inf=pred.E_inf,
            lyapunov_max_increase=seg.lyap_max if math.isfinite(seg.lyap_max) else math.nan,
            lyapunov_violations=seg.lyap_violations, residual_max=seg.residual_max,
            energy_decay_rate=e_rate, deviation_decay_rate=dev_rate, window_s=span,
            modes=modes, pole_slips=seg.slips, sync_state=sync_state, well=well,
            verdict='insufficient data', evidence=evidence)
        res.verdict, res.evidence = self._segment_verdict(res, pred)
        return res

    def _segment_verdict(self, r: SegmentResult, pred: Prediction) -> tuple[str, list]:
        ev: list[str] = []
        if not math.isfinite(r.E_last) or r.residual_max > self.diverge_residual:
            ev.append(f'energy-balance residual {r.residual_max:.3g} J exceeds '
                      f'{self.diverge_residual:g} J or E* is not finite')
            return 'diverged', ev
        if r.sync_state == 'lost synchronism':
            ev.append(f'lost synchronism: {r.pole_slips} pole slips, still slipping')
            return 'unstable', ev
        if r.pole_slips:
            ev.append(f'{r.pole_slips} pole slips, then locked in well {r.well} '
                      f'(z = {r.well} * 2 pi / {pred.pole_pairs})')
        if r.lyapunov_violations:
            ev.append(f'Lyapunov: E* rose {r.lyapunov_violations} times (max '
                      f'{r.lyapunov_max_increase:.3g} J)')
        else:
            ev.append(f'Lyapunov: E* non-increasing (max step {r.lyapunov_max_increase:.3g} '
                      f'J), |residual| <= {r.residual_max:.3g} J')
        if not math.isfinite(r.energy_decay_rate):
            ev.append(f'window {r.window_s:.3g} s too short to fit (need {self.min_fit_s:g} s)')
            return 'insufficient data', ev
        alpha = pred.decaying_abscissa
        bound = -2.0 * alpha if math.isfinite(alpha) else 0.0
        ev.append(f'E* - E*_inf decays at {r.energy_decay_rate:.4g} 1/s (bound from the '
                  f'slowest decaying predicted mode: >= {bound:.4g} 1/s); deviations at '
                  f'{r.deviation_decay_rate:.4g} 1/s')
        growing = [m for m in r.modes if m.measured is not None and m.status == 'disagrees'
                   and m.measured.real > 0]
        if pred.spectral_abscissa > 1e-9 or r.deviation_decay_rate < -0.05 or growing:
            ev.append(f'predicted spectral abscissa {pred.spectral_abscissa:.4g} 1/s'
                      + (f'; growing: {", ".join(m.name for m in growing)}' if growing else ''))
            return 'unstable', ev
        for m in r.modes:
            line = (f'{m.name}: predicted {_fmt_ev(m.predicted)} (tau {_fmt_tau(m.pred_tau)})'
                    f', measured {_fmt_ev(m.measured)} (tau {_fmt_tau(m.meas_tau)}): '
                    f'{m.status}')
            ev.append(line)
        bad = [m for m in r.modes if m.status == 'disagrees']
        if bad:
            ev.append('disagree with the prediction: ' + ', '.join(m.name for m in bad))
        if pred.marginal_modes:
            names = ', '.join(m.name for m in pred.marginal_modes)
            ev.append(f'marginal (not reached by the drive, as predicted): {names}')
            return 'marginal', ev
        return 'asymptotically stable', ev

    def _verdict(self, segs: list[SegmentResult]) -> tuple[str, list, str]:
        if not segs:
            return 'insufficient data', ['no samples yet'], 'STALE'
        cur = segs[-1]
        # the verdict is that of the last segment long enough to fit
        judged = next((s for s in reversed(segs) if s.verdict != 'insufficient data'), cur)
        verdict = judged.verdict
        evidence = [f'segment {judged.index} ({judged.reason}, t = {judged.t_start:.3f} .. '
                    f'{judged.t_end:.3f} s): {verdict}'] + list(judged.evidence)
        if self.dropped:
            evidence.append(f'{self.dropped} messages dropped (sequence gaps)')
        if any(s.verdict == 'diverged' for s in segs):
            verdict = 'diverged'
        level = {'asymptotically stable': 'OK', 'marginal': 'OK', 'insufficient data': 'OK',
                 'unstable': 'ERROR', 'diverged': 'ERROR'}[verdict]
        if cur.lyapunov_violations or cur.residual_max > self.residual_warn or self.dropped:
            level = 'WARN' if level == 'OK' else level
        if cur.sync_state == 'lost synchronism':
            level = 'WARN' if level == 'OK' else level
        return verdict, evidence, level


def _fmt_ev(z: complex | None) -> str:
    if z is None:
        return '-'
    return f'{z.real:.4g}{z.imag:+.4g}j'


def _fmt_tau(t: float) -> str:
    return f'{t:.4g} s' if math.isfinite(t) else 'inf'


def _energy_decay_rate(t: np.ndarray, dE: np.ndarray) -> float:
    """-slope of log(E* - E*_inf) fitted over the window (1/s)."""
    ok = dE > 0
    if ok.sum() < 10:
        return math.inf if np.all(np.abs(dE) < 1e-12) else math.nan
    slope = np.polyfit(t[ok], np.log(dE[ok]), 1)[0]
    return float(-slope)


def _envelope_decay_rate(t: np.ndarray, D: np.ndarray, pred: Prediction) -> float:
    """-slope of the log of the deviation envelope (chunk maxima of the normalized norm)."""
    scale = np.sqrt(np.mean(D * D, axis=0))
    scale[scale == 0] = 1.0
    n = np.sqrt(np.sum((D / scale) ** 2, axis=1))
    fmin = min((m.freq_hz for m in pred.modes if m.freq_hz > 0), default=1.0)
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
    if len(mc) < 3 or np.any(mc <= 0):
        return math.nan
    return float(-np.polyfit(tc, np.log(mc), 1)[0])


def _check_modes(t: np.ndarray, D: np.ndarray, pred: Prediction, span: float) -> list:
    """Identify eigenvalues from the deviation channels and judge each predicted mode."""
    dt_raw = float(np.median(np.diff(t)))
    fmax = max((m.freq_hz for m in pred.modes), default=1.0)
    dec = max(1, int((1.0 / dt_raw) // max(40.0, 5.0 * fmax)))
    Y = D[::dec].T
    dt = dt_raw * dec
    n_pred = sum(1 if abs(m.eigenvalue.imag) < 1e-9 else 2 for m in pred.modes)
    # + a constant offset unless the structural zero root (cyclic psi) stands for it
    order = n_pred + (0 if any(m.structural for m in pred.modes) else 1)
    try:
        lam, amp = identify_modes(Y, dt, order)
    except (AnalysisError, np.linalg.LinAlgError):
        return [ModeCheck(m.name, m.eigenvalue, None, math.nan, 'not identified',
                          m.reached_by_drive) for m in pred.modes]
    keep = lam.imag >= -1e-9
    lam, amp = lam[keep], amp[keep]
    amax = float(amp.max()) if amp.size else 0.0
    used: set = set()
    out = []
    for m in sorted(pred.modes, key=lambda m: -abs(m.eigenvalue)):
        ev = m.eigenvalue
        best, bd = None, math.inf
        for i, z in enumerate(lam):
            if i in used:
                continue
            d = abs(z.imag - ev.imag) + 0.3 * abs(z.real - ev.real)
            if d < bd:
                best, bd = i, d
        if best is None or bd > max(0.05 * abs(ev), 1.0):
            # nothing near the prediction among the dominant exponentials
            out.append(ModeCheck(m.name, ev, None, 0.0, 'not excited', m.reached_by_drive))
            continue
        used.add(best)
        z, a = complex(lam[best]), float(amp[best])
        out.append(ModeCheck(m.name, ev, z, a, _status(m, z, a, amax, span),
                             m.reached_by_drive, m.structural))
    order_names = [m.name for m in pred.modes]
    out.sort(key=lambda c: order_names.index(c.name))
    return out


#: relative frequency tolerance of a matched mode (see test/test_analysis.py for why)
FREQ_RTOL = 0.02


def _status(m: PredictedMode, z: complex, a: float, amax: float, span: float) -> str:
    ev = m.eigenvalue
    if m.structural:
        return 'structural zero root'
    if a < 1e-4 * amax:
        return 'not excited'
    if abs(z.imag - ev.imag) > FREQ_RTOL * max(abs(ev.imag), 1.0):
        return 'disagrees'
    # damping resolution of a window of length span: amplitude change of ~1% is visible
    sigma_res = 0.02 / span
    if m.marginal:
        return 'expected marginal' if abs(z.real) <= max(sigma_res, 0.1 * abs(ev)
                                                         * 1e-3) else 'disagrees'
    if m.tau > 10.0 * span:
        return 'weakly damped'
    if abs(z.real - ev.real) <= max(0.25 * abs(ev.real), sigma_res):
        return 'decaying as predicted'
    return 'disagrees'


# ------------------------------------------------------------------------------------------
# scenes as flat mappings (for the bag metadata)


def scene_to_flat(scene: Scene) -> dict[str, Any]:
    """Return the flat dotted keys of a scene, so that ``scene_from_mapping`` rebuilds it."""
    flat: dict[str, Any] = {'scene': scene.name, 'model': scene.model, 't_end': scene.t_end}
    if scene.description:
        flat['description'] = scene.description
    flat.update(scene.params.to_mapping())
    ic = scene.initial
    flat['initial.mode'] = ic.mode
    if ic.mode == 'steady':
        for k in ('theta0', 'branch', 'dtheta', 'dthetadot', 'dpsidot', 'dchi', 'dz',
                  'dzdot'):
            flat[f'initial.{k}'] = getattr(ic, k)
    else:
        flat['initial.quaternion'] = list(ic.quaternion)
        flat['initial.omega_body'] = list(ic.omega_body)
        flat['initial.z'], flat['initial.zdot'] = ic.z, ic.zdot
        if ic.chi is not None:
            flat['initial.chi'] = ic.chi
    for k, v in scene.perturbation.items():
        flat[f'perturbation.{k}'] = v
    return flat


def samples_from_trajectory(tr, seq0: int = 0) -> list[Sample]:
    """Return samples as the simulation node would publish them, from a simulate() Trajectory."""
    o = tr.out
    wrap = np.vectorize(lambda a: math.remainder(a, _TWO_PI))
    pos = np.column_stack([o['theta'], wrap(o['psi']), wrap(o['phi_R']), wrap(o['phi_M'])])
    vel = np.column_stack([o['thetadot'], o['psidot'], o['phi_R_dot'], o['phi_M_dot']])
    D = tr.y[:, tr.model.idiss]
    return [Sample(t=float(t), seq=seq0 + i, k=i, E_star=float(o['E_star'][i]),
                   dE_dt=float(o['dE_dt'][i]), residual=float(o['residual'][i]),
                   z=float(o['z'][i]), zdot=float(o['zdot'][i]), D=float(D[i]),
                   positions=tuple(pos[i]), velocities=tuple(vel[i]))
            for i, t in enumerate(tr.t)]


def scene_from_sim_doc(doc: Mapping[str, Any], base: Scene | Mapping[str, Any] | None = None
                       ) -> Scene:
    """Return the Scene described by the simulation node's ``~/scene`` YAML document.

    The document carries the scene name and path, the model, t_end, the (live) parameters,
    the perturbation and (since issue 8) the initial condition as ``initial``; ``base`` (a
    Scene or a flat mapping, e.g. from the bag's metadata) takes precedence, and older
    documents without ``initial`` fall back to the scene file named.

    Raises
    ------
    SceneError, ParameterError
        For an unknown scene without a base, or invalid values.
    """
    from gyro_rotor.core.scene import load_scene, scene_from_mapping
    if not isinstance(doc, Mapping) or 'params' not in doc:
        raise AnalysisError(f'not a scene document of rotor_sim: {str(doc)[:80]!r}')
    if isinstance(base, Scene):
        flat = scene_to_flat(base)
    elif base is not None:
        flat = dict(base)
    elif isinstance(doc.get('initial'), Mapping):     # documents since issue 8
        flat = {f'initial.{k}': v for k, v in doc['initial'].items()}
    else:
        path = doc.get('path')
        try:
            flat = scene_to_flat(load_scene(path if path else doc.get('scene', '')))
        except AnalysisError:
            raise
        except Exception:
            flat = scene_to_flat(load_scene(doc.get('scene', '')))
    flat['scene'] = str(doc.get('scene', flat.get('scene', 'custom')))
    for key in ('model', 't_end'):
        if key in doc:
            flat[key] = doc[key]
    flat.update(doc['params'])
    for k, v in (doc.get('perturbation') or {}).items():
        flat[f'perturbation.{k}'] = v
    return scene_from_mapping(flat, strict_float=False)


class AnalysisSession:
    """Messages in, analysis out: the glue the node and the offline analysis share.

    Messages are duck-typed: rclpy messages (live) and the ``mcap_ros2`` decoder's objects
    (offline) have the same fields. Samples that arrive before the scene is known are
    kept (up to ``max_pending``) and analysed when it is.

    Parameters
    ----------
    scene : Scene, optional
        A fixed scene (then the sim node's scene documents only switch parameters).
    base : Scene or flat mapping, optional
        Initial-condition source for :func:`scene_from_sim_doc`.
    **options
        Passed to :class:`RotorAnalyzer` (``window_s`` ...).
    """

    def __init__(self, scene: Scene | None = None, base=None, *, max_pending: int = 100000,
                 keep_series: bool = False, **options: Any):
        self.options = options
        self.series: list[Sample] | None = [] if keep_series else None
        self.base = base if base is not None else scene
        self.fixed = scene is not None
        self.analyzer: RotorAnalyzer | None = (RotorAnalyzer(scene, **options)
                                               if scene is not None else None)
        self.pairer = SamplePairer()
        self.pending: list[Sample] = []
        self.max_pending = max_pending
        self.scene_docs = 0
        self.energy_fields: tuple = ()

    @property
    def scene(self) -> Scene | None:
        """Return the scene being analysed (None until known)."""
        return self.analyzer.scene if self.analyzer is not None else None

    def on_scene_doc(self, text: str) -> Scene:
        """Feed a ``~/scene`` document (YAML text) of the simulation node."""
        import yaml
        try:
            doc = yaml.safe_load(text)
        except yaml.YAMLError as err:
            raise AnalysisError(f'scene document is not YAML: {err}') from err
        self.scene_docs += 1
        scene = scene_from_sim_doc(doc, self.base)
        if self.base is None:
            self.base = scene
        if self.analyzer is None:
            self.analyzer = RotorAnalyzer(scene, **self.options)
            self.analyzer.add_many(self.pending)
            self.pending.clear()
        else:
            self.analyzer.set_scene(scene)
        return scene

    def on_energy(self, msg: Any) -> None:
        """Feed an ``energy`` message (std_msgs/Float64MultiArray, layout of ros_msgs)."""
        from_label = ''
        if msg.layout.dim:
            from_label = msg.layout.dim[0].label
        if from_label and (not self.energy_fields or
                           ','.join(self.energy_fields) != from_label):
            self.energy_fields = tuple(from_label.split(','))
        if not self.energy_fields:
            raise AnalysisError('energy message without a labelled layout')
        fields = energy_sample_fields(msg.data, self.energy_fields)
        stamp = int(round(fields['t_sim'] * 1e9))
        self._take(self.pairer.add_energy(stamp, fields))

    def on_joints(self, msg: Any) -> None:
        """Feed a ``joint_states`` message (sensor_msgs/JointState)."""
        stamp = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
        self._take(self.pairer.add_joints(stamp, msg.position, msg.velocity))

    def _take(self, samples: list[Sample]) -> None:
        if not samples:
            return
        if self.series is not None:
            self.series.extend(samples)
        if self.analyzer is None:
            self.pending.extend(samples)
            del self.pending[:max(0, len(self.pending) - self.max_pending)]
        else:
            self.analyzer.add_many(samples)

    def finish(self) -> None:
        """Analyse samples still waiting for their pair."""
        self._take(self.pairer.flush())

    def result(self) -> AnalysisResult:
        """Return the analysis so far.

        Raises
        ------
        AnalysisError
            If the scene is still unknown.
        """
        if self.analyzer is None:
            raise AnalysisError(f'the scene is unknown ({len(self.pending)} samples waiting): '
                                'no scene document from rotor_sim and no scene given')
        return self.analyzer.result()


@dataclasses.dataclass
class BagAnalysis:
    """The offline analysis of a bag: the result, the live result recorded, the samples."""

    path: str
    result: AnalysisResult
    live: dict | None
    samples: list
    topics: dict
    truncated: bool
    scene_source: str
    options: dict


def _find_topic(topics: Mapping[str, Any], suffix: str, type_name: str) -> str | None:
    names = [t for t, info in topics.items()
             if t.rsplit('/', 1)[-1] == suffix and info.type == type_name]
    return sorted(names, key=len)[0] if names else None


def analyze_bag(path, *, scene: str | Scene | None = None, window_s: float | None = None,
                **options: Any) -> BagAnalysis:
    """Run the analysis of the live node over a recorded bag (nothing but the bag needed).

    The scene comes from ``scene`` if given, else from the bag's ``gyro_rotor.scene``
    metadata record, else from the simulation node's ``~/scene`` documents in the bag. The
    window is the one the live node used (metadata ``gyro_rotor.analysis``) unless
    ``window_s`` is given (0 = whole segments).

    Raises
    ------
    BagError
        Missing or unreadable bag.
    AnalysisError
        The bag lacks the ``energy`` / ``joint_states`` topics, or no scene is known.
    SceneError
        The scene named in the bag is unknown (and the bag carries no parameters).
    """
    import json
    import warnings

    from gyro_rotor.bag.bagio import BagWarning, open_bag
    if not str(path).strip():
        raise BagError('the bag path is empty (give a bag directory or an .mcap file)')
    if window_s is not None:
        _check_window(window_s)
    from gyro_rotor.core.scene import load_scene, scene_from_mapping
    import yaml
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always', BagWarning)
        reader = open_bag(path)
    problems = [str(w.message) for w in caught]
    energy = _find_topic(reader.topics, 'energy', 'std_msgs/msg/Float64MultiArray')
    joints = _find_topic(reader.topics, 'joint_states', 'sensor_msgs/msg/JointState')
    if energy is None or joints is None:
        found = ', '.join(f'{t} ({i.type})' for t, i in sorted(reader.topics.items()))
        raise AnalysisError(f'{path}: not a gyro_rotor recording: needs the topics energy '
                            f'(std_msgs/msg/Float64MultiArray) and joint_states '
                            f'(sensor_msgs/msg/JointState); found {found or "no topics"}')
    scene_topic = _find_topic(reader.topics, 'scene', 'std_msgs/msg/String')
    meta_opts = {}
    if 'gyro_rotor.analysis' in reader.metadata:
        try:
            meta_opts = json.loads(reader.metadata['gyro_rotor.analysis'].get('options', '{}'))
        except ValueError:
            meta_opts = {}
    opts = {**meta_opts, **options}
    if window_s is not None:
        opts['window_s'] = window_s
    fixed: Scene | None = None
    base = None
    source = ''
    if isinstance(scene, Scene):
        fixed, source = scene, 'given'
    elif scene:
        fixed, source = load_scene(scene), f'given ({scene})'
    elif 'gyro_rotor.scene' in reader.metadata:
        rec = reader.metadata['gyro_rotor.scene']
        try:
            flat = yaml.safe_load(rec.get('flat', ''))
        except yaml.YAMLError as err:
            raise AnalysisError(f'{path}: the scene record is not YAML: {err}') from err
        if not isinstance(flat, dict):
            raise AnalysisError(f'{path}: the gyro_rotor.scene record holds no parameters')
        base = scene_from_mapping(flat, strict_float=False)
        source = f"bag metadata (scene '{base.name}')"
    elif scene_topic is not None:
        source = f'scene documents on {scene_topic}'
    else:
        raise AnalysisError(f'{path}: the bag names no scene (no gyro_rotor.scene metadata, '
                            f'no ~/scene topic); pass one with --scene')
    session = AnalysisSession(fixed if fixed is not None else base, base=base,
                              keep_series=True, **opts)
    if fixed is None and base is not None:
        session.fixed = False
    wanted = [energy, joints] + ([scene_topic] if scene_topic and fixed is None else [])
    for topic, _, msg in reader.decoded(wanted):
        if topic == energy:
            session.on_energy(msg)
        elif topic == joints:
            session.on_joints(msg)
        else:
            session.on_scene_doc(msg.data)
    session.finish()
    if session.analyzer is None:
        raise AnalysisError(f'{path}: no scene document in the bag and no scene given')
    if session.analyzer.samples == 0:
        raise AnalysisError(f'{path}: the energy and joint_states topics hold no messages')
    live = None
    if 'gyro_rotor.live_result' in reader.metadata:
        rec = reader.metadata['gyro_rotor.live_result']
        live = {'verdict': rec.get('verdict'), 'error': rec.get('error')}
        if rec.get('json'):
            try:
                live = json.loads(rec['json'])
            except ValueError:
                pass
    result = session.result()
    if problems:
        result.evidence.extend(problems)
    return BagAnalysis(path=str(path), result=result, live=live, samples=session.series,
                       topics={t: i.count for t, i in reader.topics.items()},
                       truncated=reader.truncated, scene_source=source, options=opts)
