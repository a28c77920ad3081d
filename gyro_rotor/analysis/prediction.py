"""What the linearization predicts for a scene: named modes, the spectral abscissa, E*_inf.

Mode names are labels from the mode shapes (:mod:`gyro_rotor.linear.stability`); no
verdict depends on them. Pure Python.
"""

from __future__ import annotations

import dataclasses
import math

from gyro_rotor.core.scene import Scene
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

    Uses :func:`gyro_rotor.linear.stability.analyze_scene` when present, else the eigenvalues of
    :func:`gyro_rotor.linear.linearize.linearize` with modes named by their dominant coordinate
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
