"""Modes from data: eigenvalues identified in a window, matched to the predicted ones.

:func:`identify_modes` fits the deviation channels with a matrix pencil
(:func:`gyro_rotor.linear.sysid.matrix_pencil`); :func:`check_modes` matches each
predicted mode to an identified eigenvalue by frequency and damping and gives it a
:class:`~gyro_rotor.analysis.verdict.ModeStatus`. Pure Python.
"""

from __future__ import annotations

import dataclasses
import math

from gyro_rotor.analysis.prediction import PredictedMode, Prediction
from gyro_rotor.analysis.verdict import ModeStatus
from gyro_rotor.errors import AnalysisError
import numpy as np

__all__ = ['identify_modes', 'check_modes', 'ModeCheck', 'ModesFound', 'FREQ_RTOL']

_TWO_PI = 2.0 * math.pi


def identify_modes(Y: np.ndarray, dt: float, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Continuous-time eigenvalues and amplitudes of multichannel samples.

    A thin wrapper of :func:`gyro_rotor.linear.sysid.matrix_pencil` (channels normalized to unit
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


@dataclasses.dataclass
class ModeCheck:
    """A predicted mode against the data."""

    name: str
    predicted: complex
    measured: complex | None
    amplitude: float
    status: ModeStatus
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
                'amplitude': self.amplitude, 'status': str(self.status),
                'reached_by_drive': self.reached_by_drive}


def _num(x: float):
    return x if math.isfinite(x) else None


#: an identified oscillation with at least this share of the largest amplitude that matches
#: no predicted mode and lasts through the window (decays by less than
#: exp(-UNEXPLAINED_DECAY)) is unexplained: the modes criterion fails. (The pencil's spare
#: exponentials fit transients: measured on pole_slip after the slips, -1.0 1/s over 8 s.)
UNEXPLAINED_SHARE = 0.05
UNEXPLAINED_DECAY = 3.0


@dataclasses.dataclass(frozen=True)
class ModesFound:
    """The predicted modes judged (:class:`ModeCheck`) and identified ones left unexplained."""

    checks: list
    unexplained: list      # (eigenvalue, amplitude) of oscillations no prediction explains


def _identify(t: np.ndarray, D: np.ndarray, pred: Prediction):
    dt_raw = float(np.median(np.diff(t)))
    fmax = max((m.freq_hz for m in pred.modes), default=1.0)
    dec = max(1, int((1.0 / dt_raw) // max(40.0, 5.0 * fmax)))
    n_pred = sum(1 if abs(m.eigenvalue.imag) < 1e-9 else 2 for m in pred.modes)
    # + a constant offset unless the structural zero root (cyclic psi) stands for it
    order = n_pred + (0 if any(m.structural for m in pred.modes) else 1)
    lam, amp = identify_modes(D[::dec].T, dt_raw * dec, order)
    keep = lam.imag >= -1e-9
    return lam[keep], amp[keep]


def check_modes(t: np.ndarray, D: np.ndarray, pred: Prediction, span: float) -> ModesFound:
    """Identify eigenvalues from the deviation channels and judge each predicted mode."""
    try:
        lam, amp = _identify(t, D, pred)
    except (AnalysisError, np.linalg.LinAlgError):
        return ModesFound([ModeCheck(m.name, m.eigenvalue, None, math.nan,
                                     ModeStatus.NOT_IDENTIFIED, m.reached_by_drive,
                                     m.structural) for m in pred.modes], [])
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
            out.append(ModeCheck(m.name, ev, None, 0.0, ModeStatus.NOT_EXCITED,
                                 m.reached_by_drive, m.structural))
            continue
        used.add(best)
        z, a = complex(lam[best]), float(amp[best])
        out.append(ModeCheck(m.name, ev, z, a, _status(m, z, a, amax, span),
                             m.reached_by_drive, m.structural))
    order_names = [m.name for m in pred.modes]
    out.sort(key=lambda c: order_names.index(c.name))
    fmin = 1.0 / max(span, 1e-9)          # slower than a cycle per window: an offset
    extra = [(complex(lam[i]), float(amp[i])) for i in range(len(lam)) if i not in used
             and abs(lam[i].imag) > _TWO_PI * fmin and amp[i] >= UNEXPLAINED_SHARE * amax
             and -lam[i].real * span < UNEXPLAINED_DECAY]
    return ModesFound(out, extra)


#: relative frequency tolerance of a matched mode (see test/test_analysis.py for why)
FREQ_RTOL = 0.02


def _status(m: PredictedMode, z: complex, a: float, amax: float, span: float) -> ModeStatus:
    ev = m.eigenvalue
    if m.structural:
        return ModeStatus.STRUCTURAL_ZERO_ROOT
    if a < 1e-4 * amax:
        return ModeStatus.NOT_EXCITED
    if abs(z.imag - ev.imag) > FREQ_RTOL * max(abs(ev.imag), 1.0):
        return ModeStatus.DISAGREES
    # damping resolution of a window of length span: amplitude change of ~1% is visible
    sigma_res = 0.02 / span
    if m.marginal:
        undamped = abs(z.real) <= max(sigma_res, 1e-4 * abs(ev))
        return ModeStatus.EXPECTED_MARGINAL if undamped else ModeStatus.DISAGREES
    if m.tau > 10.0 * span:
        return ModeStatus.WEAKLY_DAMPED
    if abs(z.real - ev.real) <= max(0.25 * abs(ev.real), sigma_res):
        return ModeStatus.DECAYING_AS_PREDICTED
    return ModeStatus.DISAGREES
