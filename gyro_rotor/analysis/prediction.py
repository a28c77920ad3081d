"""What the linearization predicts for a scene: named modes, the spectral abscissa, E*_inf.

Mode names are labels from the mode shapes (:mod:`gyro_rotor.linear.stability`); no
verdict depends on them. Pure Python.
"""

from __future__ import annotations

import dataclasses
import math

from gyro_rotor.core.linearize import Coords
from gyro_rotor.core.scene import Scene
from gyro_rotor.linear.stability import ModeKind
import numpy as np

__all__ = ['PredictedMode', 'Prediction', 'predict', 'GENERAL_COORDS']

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
    #: a system file's steady motion (q, qdot, z) the deviations are taken from
    steady: tuple = ()
    #: the pole pairs of each rotor's drive
    rotor_pole_pairs: tuple = ()
    #: rows that map the deviation q - q_s of a system file's coordinates to the deviation
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
        re = [m.eigenvalue.real for m in self.modes
              if not (m.marginal or m.structural) and m.eigenvalue.real < 0]
        return max(re) if re else math.nan

    @property
    def growing_modes(self) -> tuple:
        """Modes predicted to grow (Re lambda > 0, not marginal): an unstable steady motion."""
        return tuple(m for m in self.modes if not (m.marginal or m.structural)
                     and m.eigenvalue.real > 0)


#: :attr:`Prediction.coords` of a system file's linearization (deviations of q, qdot, z, zdot)
GENERAL_COORDS = Coords.GENERAL


def predict(scene: Scene) -> Prediction:
    """Predict the modes and verdict of a scene's steady motion, any system's.

    Modes and verdict: :func:`~gyro_rotor.linear.system.assess` of the scene's one
    linearization (the centrifuge's modes named by modal energy at K_D = 0 and followed
    by continuity, a system file's by the dominant coordinate), one of each conjugate
    pair. A mode is marginal as the verdict judges it (:attr:`~gyro_rotor.linear.
    stability.Mode.is_marginal`, the one rule of reach and damping shared with claim (b)
    of ``locus``): a root not damped (the drives do not reach it, or there is no drive
    damping), or the zero root of a rotor angle without drive stiffness. Any other zero
    root is structural (a cyclic coordinate) and not judged
    (:func:`~gyro_rotor.linear.stability.judge`).
    """
    from gyro_rotor.linear.system import assess, linearize_scene
    model = scene.make_model()
    lin = linearize_scene(scene, model=model)
    roots, verdict = assess(lin)
    scale = max([1.0] + [abs(r.eigenvalue) for r in roots])
    out = tuple(PredictedMode(r.name, complex(r.eigenvalue), bool(r.reached_by_drive),
                              marginal=bool(r.is_marginal),
                              structural=_zero(r))
                for r in roots if r.eigenvalue.imag >= -1e-12 * scale)
    # the centrifuge's steady motion by theta0, psidot0; a system file's in its coordinates
    terms = scene.system.steady_terms()
    q_s = terms['steady'][0] if terms['steady'] else ()
    return Prediction(
        scene=scene.name, coords=lin.coords, modes=out,
        spectral_abscissa=float(verdict.spectral_abscissa), verdict=str(verdict.verdict),
        E_inf=float(model.energy(scene.steady_state(model))), pole_pairs=max(scene.pole_pairs),
        K_D=float(lin.K_all.max()), source='linear.system.assess',
        rotor_pole_pairs=scene.pole_pairs,
        active_q=_position_channels(lin.A_scene(), len(q_s), scale), **terms)


def _zero(mode) -> bool:
    return mode.kind == ModeKind.ZERO


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
