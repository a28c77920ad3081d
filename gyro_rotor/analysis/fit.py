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
#: below this sin(theta) the 3-1-3 angles of a recorded joint state are singular: the
#: state cannot be rebuilt from them (solution I passes through theta = 0)
SIN_THETA_MIN = 1e-3


def _general(scene) -> bool:
    return not scene.builtin


def joint_names(scene) -> tuple:
    """Return the ``joint_states`` names rotor_sim publishes for a scene."""
    if _general(scene):
        from gyro_rotor.numerics.live_general import general_joint_names
        return general_joint_names(scene.system.coordinates, scene.system.rotors)
    from gyro_rotor.bag.wire import JOINT_NAMES
    return JOINT_NAMES


def start_joints(scene) -> tuple[tuple, tuple, float]:
    """(positions, velocities, E*) that rotor_sim publishes for a scene at t = 0."""
    model = scene.make_model()
    y0 = np.asarray(scene.initial_state(model), dtype=float)
    E = float(np.asarray(model.energy(y0[None, :])).reshape(-1)[0])
    if _general(scene):
        sq, sqd, sz, szd = model.slices()
        return (tuple(np.concatenate([y0[sq], y0[sz]]).tolist()),
                tuple(np.concatenate([y0[sqd], y0[szd]]).tolist()), E)
    from gyro_rotor.core.rotations import euler_from_quaternion, euler_rates_from_body
    from gyro_rotor.numerics.live import wrap_angles
    Y = y0[None, :]
    q = model.quaternion(Y)
    psi, theta, phi_M = euler_from_quaternion(q)
    psidot, thetadot, phi_M_dot = euler_rates_from_body(theta, phi_M, model.body_rates(Y))
    z, zdot = Y[:, model.iz], Y[:, model.izd]
    Omega0 = scene.params.Omega0
    pos = wrap_angles(np.column_stack([theta, psi, z + phi_M, phi_M]))[0]
    vel = np.column_stack([thetadot, psidot, Omega0 + zdot + phi_M_dot, phi_M_dot])[0]
    return tuple(float(v) for v in pos), tuple(float(v) for v in vel), E


def energy_from_joints(scene, model, s: Sample) -> float:
    """E* of a recorded sample's state by the scene's model (NaN where not rebuildable)."""
    if not s.joints:
        return math.nan
    if _general(scene):
        sq, sqd, sz, szd = model.slices()
        n, m = sq.stop - sq.start, sz.stop - sz.start
        if len(s.positions) != n + m or len(s.velocities) != n + m:
            return math.nan
        y = np.zeros(model.size)
        y[sq], y[sz] = s.positions[:n], s.positions[n:]
        y[sqd], y[szd] = s.velocities[:n], s.velocities[n:]
        return float(np.asarray(model.energy(y[None, :])).reshape(-1)[0])
    if len(s.positions) != 4 or not (math.isfinite(s.z) and math.isfinite(s.zdot)):
        return math.nan
    theta, psi, _, phi_M = s.positions
    thetadot, psidot, _, phi_M_dot = s.velocities
    if scene.model == 'full' and abs(math.sin(theta)) < SIN_THETA_MIN:
        return math.nan
    # the twist chi = psi + phi_M of the housing is small (its spring); the wrapped angles
    # add multiples of 2 pi to it, which would flip the quaternion's sign and its chi
    phi_M = math.remainder(psi + phi_M, 2.0 * math.pi) - psi
    try:
        y = model.state_from_euler(theta=theta, thetadot=thetadot, psi=psi, psidot=psidot,
                                   phi_M=phi_M, phi_M_dot=phi_M_dot, z=s.z, zdot=s.zdot)
    except ValueError:
        return math.nan
    return float(np.asarray(model.energy(np.asarray(y)[None, :])).reshape(-1)[0])


def _differs(a: float, b: float, angle: bool = False) -> bool:
    d = abs(a - b)
    if angle:
        d = abs(math.remainder(a - b, 2.0 * math.pi))
    return not d <= TOL * max(1.0, abs(a), abs(b))


def check_energy(scene, model, s: Sample) -> str | None:
    """Why the sample's recorded E* is not the scene's E* of its state (None: it is)."""
    E = energy_from_joints(scene, model, s)
    if not math.isfinite(E) or not math.isfinite(s.E_star):
        return None
    if _differs(E, s.E_star):
        return (f'E* recorded at t = {s.t:.3f} s is {s.E_star:.9g} J, but scene '
                f"'{scene.name}' gives {E:.9g} J for the recorded state (other constants, or E* "
                'not that of the state)')
    return None


def check_start(scene, s: Sample, names: tuple) -> str | None:
    """Why a run's first sample (k = 0) is not the scene's initial state (None: it is).

    ``names``: the joint names (for the message).
    """
    if not s.joints:
        return None
    pos, vel, E = start_joints(scene)
    if len(pos) != len(s.positions) or len(vel) != len(s.velocities):
        return None
    diffs = []
    general = _general(scene)
    skip = set()
    if not general and abs(math.sin(pos[0])) < SIN_THETA_MIN:
        skip = {1, 3}           # psi, phi_M: singular at theta = 0
    for i, (a, b) in enumerate(zip(s.positions, pos)):
        if i not in skip and _differs(a, b, angle=not general):
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
        why = check_start(self.scene, s, self.names)
        if why and why not in self.problems:
            self.problems.append(why)

    def on_sample(self, s: Sample) -> None:
        """Check a sample's E* against the scene's E* of its state."""
        why = check_energy(self.scene, self.model, s)
        if why is None:
            self.energies += math.isfinite(energy_from_joints(self.scene, self.model, s))
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

    Each entry names a quantity with its value in ``given`` and in ``recorded``: the
    parameters, the model and the initial condition of a centrifuge scene; the system
    (coordinates, rotors, constants, drives, equations), the steady motion and the
    initial state of a general one. Names, descriptions, t_end and the kick do not count.
    """
    if _general(given) != _general(recorded):
        kinds = ('a general system', 'the centrifuge')
        return [f'{kinds[0] if _general(given) else kinds[1]} (recorded: '
                f'{kinds[0] if _general(recorded) else kinds[1]})']
    pairs = []
    if _general(given):
        a, b = given.system, recorded.system
        pairs += [('system', a.name, b.name), ('coordinates', a.coordinates, b.coordinates),
                  ('rotors', a.rotors, b.rotors)]
        for k in sorted(set(a.constants) | set(b.constants)):
            pairs.append((k, a.constants.get(k), b.constants.get(k)))
        for r, da, db in zip(a.rotors, a.drives, b.drives):
            for f in ('K_S', 'K_D', 'Omega0', 'pole_pairs'):
                pairs.append((f'drive.{r}.{f}', getattr(da, f), getattr(db, f)))
        pairs += [('the equations (mass matrix, guidance, potential, rotor inertia)',
                   (a.mass_matrix, a.guidance, a.potential, tuple(a.rotor_inertia)),
                   (b.mass_matrix, b.guidance, b.potential, tuple(b.rotor_inertia)))]
        for f in ('steady_q', 'steady_qdot', 'steady_z', 'q0', 'qdot0', 'z0', 'zdot0'):
            name = f.replace('_', '.', 1) if f.startswith('steady') else f'initial.{f[:-1]}'
            pairs.append((name, getattr(given, f), getattr(recorded, f)))
    else:
        from gyro_rotor.core.params import PARAM_FIELDS
        pairs += [(f, getattr(given.params, f), getattr(recorded.params, f))
                  for f in PARAM_FIELDS]
        pairs.append(('model', given.model, recorded.model))
        for f in ('mode', 'theta0', 'branch', 'dtheta', 'dthetadot', 'dpsidot', 'dchi', 'dz',
                  'dzdot', 'quaternion', 'omega_body', 'z', 'zdot', 'chi'):
            pairs.append((f'initial.{f}', getattr(given.initial, f),
                          getattr(recorded.initial, f)))
    return [f'{name} {_fmt(x)} (recorded {_fmt(y)})' for name, x, y in pairs
            if _num_diff(x, y)]
