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

__all__ = ['PredictedMode', 'Prediction', 'predict', 'predict_general',
           'GENERAL_COORDS']

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
    #: general systems: the steady motion (q, qdot, z) the deviations are taken from
    steady: tuple = ()
    #: general systems: the pole pairs of each rotor's drive
    rotor_pole_pairs: tuple = ()
    #: general systems: rows that map the coordinates' deviation q - q_s to the deviation
    #: channels: a basis of the complement of the zero roots' directions (a cyclic
    #: combination of coordinates drifts after a kick and is left out)
    active_q: tuple = ()

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


def predict(scene) -> Prediction:
    """Predicted eigenvalues, named modes and verdict of a scene's steady motion.

    A general scene goes to :func:`predict_general`. Otherwise from
    :func:`gyro_rotor.linear.stability.analyze_scene` (modes named there, by their
    modal energy at K_D = 0, followed by continuity).
    """
    if not scene.builtin:
        return predict_general(scene)
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


#: :attr:`Prediction.coords` of a general system (deviations of q, qdot, z, zdot)
GENERAL_COORDS = 'general'


def predict_general(scene) -> Prediction:
    """Predict the modes and verdict of a general scene (:mod:`gyro_rotor.linear.system`).

    Modes: the roots of A(K) at the scene's drives, one of each conjugate pair, named by
    their largest state; a zero root is structural (a cyclic coordinate), a root the
    drives do not reach (PBH) is marginal. Verdict: unstable if a root has Re > 0,
    marginal if a mode is not reached, else asymptotically stable.
    """
    from gyro_rotor.linear.system import linearize_scene, modes, REL_AXIS
    from gyro_rotor.linear.stability import Stability
    model = scene.make_model()
    lin = linearize_scene(scene, model=model)
    roots = modes(lin)
    scale = max([1.0] + [abs(r.eigenvalue) for r in roots])
    out = _unique_names(tuple(PredictedMode(r.name, r.eigenvalue, r.reached_by_drive,
                                            marginal=not (r.reached_by_drive or _zero(r)),
                                            structural=_zero(r))
                              for r in roots if r.eigenvalue.imag >= -1e-12 * scale))
    live = [m.eigenvalue.real for m in out if not m.structural]
    abscissa = max(live) if live else -math.inf
    if abscissa > REL_AXIS * scale:
        verdict = Stability.UNSTABLE
    elif any(m.marginal for m in out):
        verdict = Stability.MARGINAL
    else:
        verdict = Stability.ASYMPTOTICALLY_STABLE
    n = lin.n
    active = _position_channels(lin.A_scene(), n, scale)
    drives = scene.system.drives
    poles = scene.pole_pairs
    return Prediction(
        scene=scene.name, coords=GENERAL_COORDS, modes=out, spectral_abscissa=abscissa,
        verdict=str(verdict), E_inf=float(model.energy(scene.steady_state(model))),
        theta0=math.nan, psidot0=math.nan,
        pole_pairs=max(poles), K_D=max(d.K_D for d in drives),
        source='linear.system.modes',
        steady=(tuple(scene.steady_q), tuple(scene.steady_qdot), tuple(scene.steady_z)),
        rotor_pole_pairs=poles, active_q=active)


def _zero(mode) -> bool:
    return mode.kind == ModeKind.ZERO


def _unique_names(modes: tuple) -> tuple:
    """Give modes that share a name (the dominant coordinate of two modes) their frequency.

    The name labels a mode in the report, the ``analysis_modes`` topic and the live
    table; two modes called 'mode (beta1)' could not be told apart there.
    """
    count: dict = {}
    for m in modes:
        count[m.name] = count.get(m.name, 0) + 1
    out = []
    for m in modes:
        if count[m.name] > 1:
            label = f'{m.freq_hz:.3g} Hz' if m.freq_hz > 0 else f'{m.eigenvalue.real:.3g} 1/s'
            m = dataclasses.replace(m, name=f'{m.name} {label}')
        out.append(m)
    return tuple(out)


def _position_channels(A: np.ndarray, n: int, scale: float) -> tuple:
    """Rows spanning the coordinate directions orthogonal to the null space of A.

    A null vector of A (A x = 0) has no rate part; its coordinate part is a direction along
    which the steady motion can shift without a restoring force (a cyclic combination).
    The null space, not the eigenvectors of the zero roots: a zero root of multiplicity 2
    is a Jordan pair here (a kick drifts along its one eigenvector), and the eigensolver's
    two nearly equal vectors (apart by 1e-7) would remove a second, wrong direction.
    """
    if n == 0:
        return ()
    _, sv, Vt = np.linalg.svd(A)
    null = Vt[sv <= 1e-9 * max(float(sv[0]), scale)]
    if null.size == 0:
        return tuple(tuple(float(v) for v in row) for row in np.eye(n))
    U, s2, _ = np.linalg.svd(null[:, :n].T)
    rank = int(np.count_nonzero(s2 > 1e-6 * max(1.0, float(s2.max()))))
    return tuple(tuple(float(v) for v in row) for row in U[:, rank:].T)
