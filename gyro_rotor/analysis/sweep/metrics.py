"""Metrics of one sampled trajectory of a sweep (the columns of the sweep's Parquet output).

Notation: z is the rotor's lag behind the rotating field, p the number of pole pairs of the
sine law Q = -(K_S/p) sin(p z) - K_D zdot (p = 0: the linear law, eq. 23). The wells of the
drive potential have their bottoms at z = 2 pi k / p and their maxima at (2k + 1) pi / p.

=====================  ===============================================================  =====
column                 definition                                                       unit
=====================  ===============================================================  =====
``final_well``         k of the well the rotor ends in: round(p z(T) / 2 pi) (0 if p = 0)   -
``pole_slips``         passages of z over the maxima of the drive potential, counted as     -
                       :class:`~gyro_rotor.analysis.checks.RotorAnalyzer` counts them
                       (the well index changes only once z is within a quarter well of
                       a bottom, so jitter on a maximum counts nothing)
``settling_time``      first sample time after which the drive's phase-plane amplitude      s
                       a = sqrt(dz^2 + (zdot / omega_d)^2) stays <= ``tol`` (dz = z minus
                       the bottom of the final well, omega_d = sqrt(K_S (1/C_R + 1/C_M)),
                       the drive's frequency); NaN if a(T) > tol
``peak_deviation``     max |z(t) - z_0| with z_0 the bottom of the initial well             rad
``decay_rate``         -slope of a least-squares line through the log of the envelope of    1/s
                       a(t) (maxima of 40 chunks) over the locked part (after the last
                       change of the nearest well), where resolved: its interval (2
                       standard errors, at least 0.025 / the part's length) on one side
                       of 0; NaN ("not resolved within t_end") otherwise
``final_E_star``       E* (eq. 13) at t = T                                                 J
``spectral_abscissa``  max Re of the linearization's roots at the point (judged modes,      1/s
                       :func:`gyro_rotor.linear.system.modes`)
=====================  ===============================================================  =====

Every system offers every metric; :func:`point_metrics` measures a point of any scene in
its model's terms. A scene with a ``system`` key (eqs. 1-17 of any rotor
system) has no single drive lag: its ``peak``, ``settling`` and ``decay``
(:func:`system_metrics`) are taken of the deviation amplitude a = max_i |q_i - steady.q_i|
over the coordinates that move (peak: max a; settling: the first time after which a stays
<= tol; decay: the decay rate of a over the run, :func:`fit_decay`). ``well`` of any
system: the well of the first rotor with a sine law and the passages of all its rotors
(:func:`wells`); ``energy``: E* at t_end (eq. 13); ``abscissa``: of the one linearization
of every scene (:mod:`gyro_rotor.linear.system`).
"""

from __future__ import annotations

import enum
import math

import numpy as np

__all__ = ['Metric', 'METRIC_COLUMNS', 'COLUMN_UNITS', 'INT_COLUMNS', 'PointStatus',
           'trajectory_metrics', 'well_passages', 'DEFAULT_TOL', 'settle_time', 'fit_decay',
           'decay_interval', 'system_metrics', 'wells', 'point_metrics']

#: default settling tolerance of the drive amplitude a [rad]
DEFAULT_TOL = 1e-3
_TWO_PI = 2.0 * math.pi


class Metric(enum.StrEnum):
    """The metric groups of ``--metrics``."""

    WELL = 'well'
    SETTLING = 'settling'
    PEAK = 'peak'
    DECAY = 'decay'
    ENERGY = 'energy'
    ABSCISSA = 'abscissa'


class PointStatus(enum.IntEnum):
    """What became of a point: every point gets a row, failed ones too."""

    OK = 0
    DIVERGED = 1      # a non-finite state during the integration
    FAILED = 2        # the point could not be set up (no steady motion, ...) or integrated


#: metric group -> its columns
METRIC_COLUMNS = {
    Metric.WELL: ('final_well', 'pole_slips'),
    Metric.SETTLING: ('settling_time',),
    Metric.PEAK: ('peak_deviation',),
    Metric.DECAY: ('decay_rate',),
    Metric.ENERGY: ('final_E_star',),
    Metric.ABSCISSA: ('spectral_abscissa',),
}
#: columns stored as (nullable) integers
INT_COLUMNS = ('final_well', 'pole_slips')
COLUMN_UNITS = {'final_well': '-', 'pole_slips': '-', 'settling_time': 's',
                'peak_deviation': 'rad', 'decay_rate': '1/s', 'final_E_star': 'J',
                'spectral_abscissa': '1/s'}


def well_passages(u: np.ndarray) -> int:
    """Passages over potential maxima from z in wells, u = p z / 2 pi (bottoms at integers).

    The rule of :class:`~gyro_rotor.analysis.checks.RotorAnalyzer`: a sample within a
    quarter well of a bottom (|u - round(u)| <= 1/4) sets the well index k; each change of
    k adds |k - k_previous| passages.
    """
    k = np.round(u)
    k = k[np.abs(u - k) <= 0.25]
    return int(np.sum(np.abs(np.diff(k)))) if k.size > 1 else 0


def wells(Z: np.ndarray, poles) -> dict:
    """Return ``final_well`` and ``pole_slips`` of the lags ``Z`` (samples, rotors).

    final_well: round(p z(T) / 2 pi) of the first rotor with a sine law (p > 0), else 0;
    pole_slips: the passages (:func:`well_passages`) of every rotor, summed.
    """
    sine = [(r, p) for r, p in enumerate(poles) if p > 0]
    return {'final_well': int(round(Z[-1, sine[0][0]] / (_TWO_PI / sine[0][1])))
            if sine else 0,
            'pole_slips': sum(well_passages(Z[:, r] / (_TWO_PI / p)) for r, p in sine)}


#: chunks of the run over which the amplitude's envelope is taken (their maxima)
ENVELOPE_CHUNKS = 40
#: below this share of its largest value the amplitude is rounding noise (not fitted)
AMPLITUDE_FLOOR = 1e-12


def decay_interval(t: np.ndarray, a: np.ndarray):
    """Return the decay rate of an amplitude a(t) >= 0 with its interval (a ``Measured``).

    The envelope of a: the maxima of :data:`ENVELOPE_CHUNKS` equal chunks of the run (an
    oscillating deviation is zero twice a period; a drive's phase-plane amplitude ripples),
    those above :data:`AMPLITUDE_FLOOR` of the largest. The rate is -slope of a
    least-squares line through their logarithm; its uncertainty twice the slope's standard
    error, with the residuals counted as independent pieces (their sign changes + 1: a
    beat of two modes is one slow wave, not many samples), and at least half the run's
    resolution (RESOLVABLE = 0.05 over t_end: a slower rate changes a by less than 5 %).
    Not measured (NaN) with fewer than 5 chunks above the floor.
    """
    from gyro_rotor.analysis.decay import _n_eff, RESOLVABLE
    from gyro_rotor.analysis.verdict import Measured
    nan = Measured(math.nan, math.nan, math.nan)
    t, a = np.asarray(t, dtype=float), np.asarray(a, dtype=float)
    if t.size < 10 or not np.all(np.isfinite(a)) or t[-1] - t[0] < 0.1:
        return nan
    edges = np.linspace(0, t.size, min(ENVELOPE_CHUNKS, t.size // 2) + 1).astype(int)
    tc, mc = [], []
    for i0, i1 in zip(edges[:-1], edges[1:]):
        k = i0 + int(np.argmax(a[i0:i1]))
        tc.append(t[k])
        mc.append(a[k])
    tc, mc = np.asarray(tc), np.asarray(mc)
    ok = mc > AMPLITUDE_FLOOR * max(float(np.max(a)), 1e-300)
    if ok.sum() < 5:
        return nan
    tc, y = tc[ok], np.log(mc[ok])
    p = np.polyfit(tc, y, 1)
    r = y - np.polyval(p, tc)
    sd = float(np.sqrt(np.sum(r * r) / max(r.size - 2, 1)))
    se = sd / (math.sqrt(_n_eff(r)) * float(np.std(tc)))
    u = max(2.0 * se, 0.5 * RESOLVABLE / float(t[-1] - t[0]))
    return Measured.pm(float(-p[0]), u)


def fit_decay(t: np.ndarray, a: np.ndarray) -> float:
    """Return the decay rate of an amplitude a(t) where the run resolves it, else NaN.

    :func:`decay_interval`, by the rule of the verdict: the rate is given when its whole
    interval is on one side of zero (positive: a decay; negative: a resolved growth), NaN
    ("not resolved within t_end") when the interval holds zero or nothing was measured.
    """
    m = decay_interval(t, a)
    if not m.bounded or m.lo <= 0.0 <= m.hi:
        return math.nan
    return m.value


def settle_time(t: np.ndarray, a: np.ndarray, tol: float) -> float:
    """First sample time after which the amplitude ``a`` stays <= ``tol``; NaN if a(T) > tol."""
    above = np.nonzero(a > tol)[0]
    if above.size == 0:
        return float(t[0])
    if above[-1] == a.size - 1:
        return math.nan
    return float(t[above[-1] + 1])


def trajectory_metrics(model, t: np.ndarray, y: np.ndarray, metrics, *,
                       tol: float = DEFAULT_TOL) -> dict:
    """Column -> value for one trajectory (samples ``y`` (m, n) at ``t`` (m,), all finite).

    ``model`` (a :class:`~gyro_rotor.core.model.Model`) carries the point's parameters;
    ``metrics`` is a set of :class:`Metric` (the linear spectral abscissa is computed by
    the caller, once per parameter set).
    """
    p = model.params
    pp = p.pole_pairs
    z = y[:, model.iz]
    zd = y[:, model.izd]
    out: dict = {}
    well_w = _TWO_PI / pp if pp > 0 else 0.0
    k_end = int(round(z[-1] / well_w)) if pp > 0 else 0
    if Metric.WELL in metrics:
        out.update(wells(z[:, None], (pp,)))
    if Metric.PEAK in metrics:
        z0 = well_w * round(z[0] / well_w) if pp > 0 else 0.0
        out['peak_deviation'] = float(np.max(np.abs(z - z0)))
    if Metric.SETTLING in metrics or Metric.DECAY in metrics:
        omega_d = math.sqrt(p.K_S * (1.0 / p.C_R + 1.0 / p.C_M)) if p.K_S > 0 else 1.0
        a = np.hypot(z - k_end * well_w, zd / omega_d)
        if Metric.SETTLING in metrics:
            out['settling_time'] = settle_time(t, a, tol)
        if Metric.DECAY in metrics:
            start = 0
            if pp > 0:
                other = np.nonzero(np.round(z / well_w) != k_end)[0]
                start = other[-1] + 1 if other.size else 0
            out['decay_rate'] = fit_decay(t[start:], a[start:])
    if Metric.ENERGY in metrics:
        out['final_E_star'] = float(model.energy(y[-1]))
    return out


def system_metrics(model, steady_q: np.ndarray, t: np.ndarray, y: np.ndarray, metrics, *,
                   tol: float = DEFAULT_TOL) -> dict:
    """Column -> value for one trajectory of a rotor system (samples ``y`` (m, n), finite).

    ``model`` is the point's :class:`~gyro_rotor.core.system.model.GeneralModel`,
    ``steady_q`` its steady coordinates; ``metrics`` a set of :class:`Metric` (the
    spectral abscissa is computed by the caller).
    """
    q = y[:, model.slices()[0]]
    a = np.max(np.abs(q - steady_q), axis=1) if q.shape[1] else np.zeros(t.size)
    out: dict = {}
    if Metric.WELL in metrics:
        out.update(wells(y[:, model.slices()[2]],
                         tuple(d.pole_pairs for d in model.system.drives)))
    if Metric.PEAK in metrics:
        out['peak_deviation'] = float(np.max(a))
    if Metric.SETTLING in metrics:
        out['settling_time'] = settle_time(t, a, tol)
    if Metric.DECAY in metrics:
        out['decay_rate'] = fit_decay(t, a)
    if Metric.ENERGY in metrics:
        out['final_E_star'] = float(model.energy(y[-1:])[0])
    return out


def point_metrics(scene, model, t: np.ndarray, y: np.ndarray, metrics, *,
                  tol: float = DEFAULT_TOL) -> dict:
    """Column -> value for one trajectory of any scene (samples ``y`` (m, n) at ``t``, finite).

    ``scene`` and ``model`` are the point's, with its numbers. The metrics are taken in the
    terms of the model (module doc): the centrifuge's hand-written :class:`Model` by its
    drive lag (:func:`trajectory_metrics`), a system file's model by the deviation from the
    scene's steady motion (:func:`system_metrics`). The spectral abscissa is computed by
    the caller.
    """
    # imported here: the metric names (``gyro-rotor sweep --help``) need not load the model
    from gyro_rotor.core.model import Model
    if isinstance(model, Model):
        return trajectory_metrics(model, t, y, metrics, tol=tol)
    steady_q = scene.steady_state(model)[model.slices()[0]]
    return system_metrics(model, steady_q, t, y, metrics, tol=tol)
