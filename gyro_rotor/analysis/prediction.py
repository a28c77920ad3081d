"""What the linearization predicts for a scene: named modes, the spectral abscissa, E*_inf.

Mode names are labels from the mode shapes (:mod:`gyro_rotor.linear.stability`); no
verdict depends on them. Pure Python.
"""

from __future__ import annotations

import dataclasses
import math

from gyro_rotor.core.scene import Scene
from gyro_rotor.linear.stability import analyze_scene, ModeKind
import numpy as np

__all__ = ['PredictedMode', 'Prediction', 'predict']

_TWO_PI = 2.0 * math.pi


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

    From :func:`gyro_rotor.linear.stability.analyze_scene` (modes named there, by their
    modal energy at K_D = 0, followed by continuity).
    """
    model = scene.make_model()
    E_inf = float(model.energy(_steady_state(scene)))
    sm = scene.steady()
    p = scene.params
    common = {'scene': scene.name, 'E_inf': E_inf, 'theta0': sm.theta0,
              'psidot0': sm.psidot0, 'pole_pairs': int(p.pole_pairs), 'K_D': float(p.K_D)}
    rep = analyze_scene(scene)
    marginal = {str(m) for m in rep.marginal_modes}
    modes = tuple(PredictedMode(str(m.name), complex(m.eigenvalue), bool(m.reached_by_drive),
                                str(m.name) in marginal, structural=m.kind == ModeKind.ZERO)
                  for m in rep.modes if complex(m.eigenvalue).imag >= -1e-12)
    return Prediction(coords=rep.coords, modes=modes,
                      spectral_abscissa=float(rep.spectral_abscissa),
                      verdict=str(rep.verdict), source='stability.analyze_scene', **common)
