"""Does the scene fit the recording? The data checked against the scene they are judged by.

Two checks, both exact (the simulation node computes what is recorded with the same
model code, to rounding):

* **E* from the joints**: E* (eq. 13) evaluated by the scene's model on a recorded joint
  state (and, for the centrifuge, the rotor's z, zdot from ``energy``) must equal the
  recorded E*. Other constants (inertias, G s, springs, K_S, Omega0, pole pairs) change
  E*; K_D does not (the modes show it: the drive's damping rates).
* **the start**: a run's first sample (grid index k = 0, at a start or a reset) must be
  the scene's initial state. Another scene with the same constants (``nutation`` on a
  ``precession`` recording: another steady motion) starts elsewhere.

Pure Python (core and numerics).
"""

from __future__ import annotations

import math

from gyro_rotor.analysis.samples import Sample
import numpy as np

__all__ = ['SceneFit', 'TOL', 'joint_names', 'start_joints', 'energy_from_joints', 'check_start',
           'check_energy', 'scene_differences']

#: relative (and absolute, in the units of each number) tolerance of the comparisons:
#: rounding of the same computation, and of a quaternion rebuilt from wrapped angles
TOL = 1e-7


def joint_names(scene) -> tuple:
    """Return the ``joint_states`` names rotor_sim publishes for a scene."""
    return scene.joint_names


def start_joints(scene, model) -> tuple[tuple, tuple, float]:
    """(positions, velocities, E*) that rotor_sim publishes for a scene (its model) at t = 0."""
    Y = np.asarray(scene.initial_state(model), dtype=float)[None, :]
    E = float(np.asarray(model.energy(Y)).reshape(-1)[0])
    pos, vel, _, _ = model.joints(Y, np.zeros((1, len(model.field_speeds()))))
    return tuple(float(v) for v in pos[0]), tuple(float(v) for v in vel[0]), E


def energy_from_joints(model, s: Sample) -> float:
    """E* of a recorded sample's state by the scene's model (NaN where not rebuildable)."""
    if not s.joints:
        return math.nan
    y = model.state_from_joints(s.positions, s.velocities, s.z, s.zdot)
    if y is None:
        return math.nan
    return float(np.asarray(model.energy(y[None, :])).reshape(-1)[0])


def _differs(a: float, b: float, angle: bool = False) -> bool:
    d = abs(a - b)
    if angle:
        d = abs(math.remainder(a - b, 2.0 * math.pi))
    return not d <= TOL * max(1.0, abs(a), abs(b))


def check_energy(scene, s: Sample, E: float) -> str | None:
    """Why the sample's recorded E* is not E, the scene's E* of its state (None: it is).

    ``E``: :func:`energy_from_joints` of the sample (NaN: nothing to check).
    """
    if not math.isfinite(E) or not math.isfinite(s.E_star):
        return None
    if _differs(E, s.E_star):
        return (f'E* recorded at t = {s.t:.3f} s is {s.E_star:.9g} J, but scene '
                f"'{scene.name}' gives {E:.9g} J for the recorded state (other constants, or E* "
                'not that of the state)')
    return None


def check_start(scene, model, s: Sample, names: tuple) -> str | None:
    """Why a run's first sample (k = 0) is not the scene's initial state (None: it is).

    ``model``: the scene's model; ``names``: the joint names (for the message).
    """
    if not s.joints:
        return None
    pos, vel, E = start_joints(scene, model)
    if len(pos) != len(s.positions) or len(vel) != len(s.velocities):
        return None
    diffs = []
    skip = model.singular_joints(pos)
    for i, (a, b) in enumerate(zip(s.positions, pos)):
        if i not in skip and _differs(a, b, angle=model.joint_angles):
            diffs.append(f'{names[i] if i < len(names) else i} {a:.6g} (scene {b:.6g})')
    for i, (a, b) in enumerate(zip(s.velocities, vel)):
        if i not in skip and _differs(a, b):
            diffs.append(f'{names[i] + "_dot" if i < len(names) else i} {a:.6g} '
                         f'(scene {b:.6g})')
    if _differs(s.E_star, E):
        diffs.append(f'E* {s.E_star:.9g} J (scene {E:.9g} J)')
    if not diffs:
        return None
    return (f"the run starts at {', '.join(diffs[:4])}"
            + (f' and {len(diffs) - 4} more' if len(diffs) > 4 else '')
            + f": not the initial state of scene '{scene.name}'")


class SceneFit:
    """The scene checks over a stream of samples (the analyzer's ``scene`` criterion)."""

    def __init__(self, scene, names: tuple):
        self.scene = scene
        self.names = names
        self.model = scene.make_model()
        self.problems: list[str] = []
        self.starts = 0
        self.energies = 0

    def on_start(self, s: Sample) -> None:
        """Check a sample that begins a run (k = 0 after a start or a reset)."""
        self.starts += 1
        why = check_start(self.scene, self.model, s, self.names)
        if why and why not in self.problems:
            self.problems.append(why)

    def on_sample(self, s: Sample) -> None:
        """Check a sample's E* against the scene's E* of its state."""
        E = energy_from_joints(self.model, s)
        why = check_energy(self.scene, s, E)
        if why is None:
            self.energies += math.isfinite(E)
        elif why not in self.problems:
            self.problems.append(why)


def _num_diff(a, b) -> bool:
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return _differs(float(a), float(b))
    if isinstance(a, (tuple, list)) and isinstance(b, (tuple, list)):
        return len(a) != len(b) or any(_num_diff(x, y) for x, y in zip(a, b))
    return a != b


def _fmt(v) -> str:
    if isinstance(v, (tuple, list)):
        return '[' + ', '.join(_fmt(x) for x in v) + ']'
    return f'{v:.6g}' if isinstance(v, float) else str(v)


def scene_differences(given, recorded) -> list[str]:
    """Return what differs between two scenes in what the analysis depends on (empty: nothing).

    Each entry names a quantity of :meth:`~gyro_rotor.core.scene.Scene.physics` with its
    value in ``given`` and in ``recorded`` (equal within :data:`TOL`); scenes of two
    systems differ in their system alone.
    """
    a, b = dict(given.physics()), dict(recorded.physics())
    if a['system'] != b['system']:
        return [f"system {a['system']} (recorded {b['system']})"]
    return [f'{name} {_fmt(x)} (recorded {_fmt(b.get(name))})' for name, x in a.items()
            if _num_diff(x, b.get(name))] + [
        f'{name} {_fmt(None)} (recorded {_fmt(y)})' for name, y in b.items() if name not in a]
