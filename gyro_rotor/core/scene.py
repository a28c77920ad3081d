"""Scenes: a YAML file that is at once a ROS 2 parameter file for ``rotor_sim``.

A scene names the parameters (:mod:`gyro_rotor.core.params`), the model it needs, the
duration and the initial condition. The shipped scenes are keyed ``/**`` (any node name,
so that a renamed or namespaced rotor_sim reads them too); ``rotor_sim`` and
``/rotor_sim`` are read as well::

    /**:
      ros__parameters:
        scene: precession
        model: full                 # full | locked_housing | upright_axis
        t_end: 10.0                 # s
        A_R: 0.05                   # ... every RotorParams field (floats written as floats)
        initial:
          mode: steady              # steady | body
          theta0: 0.1
          branch: 1                 # 0 = solution I, 1 = precession, 2 = nutation branch
          dtheta: 0.005             # dthetadot dpsidot dchi dz dzdot as well
        perturbation:               # the kick of the node's ~/perturb service
          dthetadot: 0.05

With ``initial.mode: steady`` the state at t = 0 is theta = theta0 + dtheta,
thetadot = dthetadot, psi = 0, psidot = psidot0 + dpsidot, phi_M = dchi,
phi_M_dot = -psidot0, z = dz, zdot = dzdot (field angle Omega0 t). With ``body``:
``initial.quaternion`` [w, x, y, z] (stator, body to space), ``initial.omega_body`` [3],
``initial.z``, ``initial.zdot`` and ``initial.chi`` (the twist for the upright_axis model;
for the full model it must agree with the quaternion's).

ROS 2 parameter files are typed: a float parameter written as ``98`` is an integer there
and the node could not take it, so the loader refuses it with a hint to write ``98.0``.
Unknown keys are refused with the nearest valid name.
"""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path
import re
import sys
from typing import Any, Mapping

from gyro_rotor.core.model import make_model, Model, MODELS
from gyro_rotor.core.params import PARAM_FIELDS, RotorParams
from gyro_rotor.core.steady import steady_motion, SteadyMotion
from gyro_rotor.errors import did_you_mean, ParameterError, SceneError
import numpy as np

__all__ = ['Scene', 'InitialCondition', 'load_scene', 'scene_from_mapping', 'find_scene',
           'list_scenes', 'scene_path', 'perturb_state', 'PERTURBATION_KEYS', 'NODE_KEYS',
           'SCENE_KEYS', 'DEFAULT_SCENE']

DEFAULT_SCENE = 'precession'
NODE_NAMES = ('rotor_sim', '/rotor_sim', '/**')

#: ranges of the simulation node's numeric keys, the same in a scene file, --set, a
#: --params-file and a live parameter (rotor_sim declares them with these ranges)
NODE_RANGES = {
    'publish_rate': (1.0, 10000.0), 'real_time_factor': (0.0, 1000.0), 'rtol': (0.0, 1.0),
    'atol': (0.0, 1.0), 'step_size': (0.0, 1.0), 'diagnostics_period': (0.05, 3600.0),
    'max_catch_up': (0.001, 10.0), 'max_residual': (0.0, 1e9), 't_end': (1e-6, 1e9),
    'visualization_rate': (0.0, 10000.0), 'realtime_priority': (0, 99),
}

PERTURBATION_KEYS = ('dtheta', 'dthetadot', 'dpsidot', 'dchi', 'dz', 'dzdot')

#: keys of the simulation node that a scene file may carry as well (type, default, doc)
NODE_KEYS: dict[str, tuple[type, Any, str]] = {
    'publish_rate': (float, 250.0, 'publish rate of the state topics [Hz]'),
    'real_time_factor': (float, 1.0, 'simulated seconds per wall second; 0 = as fast as '
                                     'possible'),
    'publish_clock': (bool, True, 'publish /clock (rosgraph_msgs/Clock) with the '
                                  'simulation time (as Gazebo does; other nodes follow it '
                                  'with use_sim_time)'),
    'integrator': (str, 'auto', 'integration method (auto picks one per scene)'),
    'rtol': (float, 0.0, 'relative tolerance of adaptive methods (0 = the method default)'),
    'atol': (float, 0.0, 'absolute tolerance of adaptive methods (0 = the method default)'),
    'step_size': (float, 0.0, 'step of fixed-step methods [s] (0 = the method default)'),
    'frame_id': (str, 'world', 'frame of the published poses and markers'),
    'diagnostics_period': (float, 1.0, 'period of /diagnostics [s]'),
    'max_catch_up': (float, 0.25, 'most wall seconds of simulation one tick may catch up'),
    'stop_at_t_end': (bool, False, 'stop integrating (and idle) when t reaches t_end'),
    'max_residual': (float, 1.0, 'divergence guard: |energy-balance residual| [J] above '
                                 'which the node stops integrating'),
    'wait_for_subscribers': (int, 0, 'hold simulation time at 0 until joint_states and '
                                     'energy each have this many subscribers (a recorder '
                                     'then gets every sample from t = 0; 0 = start at once)'),
    'wait_for_node': (str, '', "and until a subscriber of this node (its recorder's hidden "
                               'node _<name>_recorder counts as it) is among them: another '
                               'subscriber, such as Foxglove, cannot stand in for the '
                               "recorder ('' = any subscribers)"),
    'use_sim_time': (bool, False, 'ROS: must stay false for the simulator itself'),
}

_FLOAT_INITIAL = ('theta0', 'dtheta', 'dthetadot', 'dpsidot', 'dchi', 'dz', 'dzdot', 'z',
                  'zdot', 'chi')
SCENE_KEYS: dict[str, type] = {
    'scene': str, 'description': str, 'model': str, 't_end': float,
    **{name: (int if name == 'pole_pairs' else float) for name in PARAM_FIELDS},
    'initial.mode': str, 'initial.branch': int, 'initial.quaternion': list,
    'initial.omega_body': list,
    **{f'initial.{k}': float for k in _FLOAT_INITIAL},
    **{f'perturbation.{k}': float for k in PERTURBATION_KEYS},
    **{name: spec[0] for name, spec in NODE_KEYS.items()},
}


@dataclasses.dataclass(frozen=True)
class InitialCondition:
    """Initial condition of a scene (see module doc)."""

    mode: str = 'steady'
    theta0: float = 0.0
    branch: int = 0
    dtheta: float = 0.0
    dthetadot: float = 0.0
    dpsidot: float = 0.0
    dchi: float = 0.0
    dz: float = 0.0
    dzdot: float = 0.0
    quaternion: tuple = (1.0, 0.0, 0.0, 0.0)
    omega_body: tuple = (0.0, 0.0, 0.0)
    z: float = 0.0
    zdot: float = 0.0
    chi: float | None = None


@dataclasses.dataclass(frozen=True)
class Scene:
    """A loaded, validated scene."""

    name: str
    params: RotorParams
    model: str = 'full'
    t_end: float = 10.0
    initial: InitialCondition = InitialCondition()
    perturbation: Mapping[str, float] = dataclasses.field(default_factory=dict)
    node: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    description: str = ''
    path: str | None = None

    def make_model(self) -> Model:
        """Return the model this scene needs."""
        return make_model(self.model, self.params)

    def steady(self) -> SteadyMotion:
        """Return the steady motion the initial condition refers to (solution I for body mode)."""
        ic = self.initial
        if ic.mode != 'steady':
            return steady_motion(self.params, 0.0, 0)
        return steady_motion(self.params, ic.theta0, ic.branch)

    def initial_state(self, model: Model | None = None) -> np.ndarray:
        """State vector at t = 0 for this scene's model."""
        model = model or self.make_model()
        ic = self.initial
        if ic.mode == 'steady':
            sm = self.steady()
            if model.name != 'full' and (ic.dtheta or ic.dthetadot or sm.theta0):
                raise SceneError(f"scene '{self.name}': model {model.name} holds the axis "
                                 'vertical; theta0, dtheta and dthetadot must be 0')
            return model.state_from_euler(
                theta=sm.theta0 + ic.dtheta, thetadot=ic.dthetadot, psi=0.0,
                psidot=sm.psidot0 + ic.dpsidot, phi_M=ic.dchi, phi_M_dot=-sm.psidot0,
                z=ic.dz, zdot=ic.dzdot)
        # body mode
        q = np.asarray(ic.quaternion, dtype=float)
        W = np.asarray(ic.omega_body, dtype=float)
        if model.name == 'full':
            # q and -q are one orientation, but the sign carries the twist chi (|chi| < 2 pi):
            # without initial.chi take the smaller twist (q_w >= 0); with it, the sign that
            # gives that twist
            if q[0] < 0 or (q[0] == 0 and q[3] < 0):
                q = -q
            if ic.chi is not None and abs(2.0 * math.atan2(-q[3], -q[0]) - ic.chi) < abs(
                    2.0 * math.atan2(q[3], q[0]) - ic.chi):
                q = -q
            y = model.state_from_body(q, W, ic.z, ic.zdot)
            if ic.chi is not None:
                chi_q = 2.0 * math.atan2(y[3], y[0])
                if abs(chi_q - ic.chi) > 1e-9:
                    raise SceneError(
                        f"scene '{self.name}': initial.chi = {ic.chi} disagrees with the "
                        f"quaternion's twist 2 atan2(q_z, q_w) = {chi_q:.12g}")
            return y
        if model.name == 'upright_axis':
            if abs(W[0]) > 0 or abs(W[1]) > 0 or abs(q[1]) > 0 or abs(q[2]) > 0:
                raise SceneError(f"scene '{self.name}': model upright_axis needs the axis "
                                 'vertical: quaternion x, y and omega_body 1, 2 must be 0')
            chi = ic.chi if ic.chi is not None else 2.0 * math.atan2(q[3], q[0])
            return np.array([chi, W[2], ic.z, ic.zdot, 0.0])
        return np.array([ic.z, ic.zdot, 0.0])

    def with_params(self, **changes: Any) -> 'Scene':
        """Copy with some parameters changed (validated)."""
        return dataclasses.replace(self, params=self.params.replace(**changes))


def perturb_state(model: Model, y: np.ndarray, perturbation: Mapping[str, float]) -> np.ndarray:
    """Apply a kick (dtheta, dthetadot, dpsidot, dchi, dz, dzdot) to a state.

    Full model: the orientation is turned by dtheta and dchi in the current 3-1-3 angles
    (psi, theta + dtheta, phi_M + dchi), and the rate kick is added to the body rates,
    W += J(psi, theta, phi_M) (dpsidot, dthetadot, 0) with J the map of
    :func:`~gyro_rotor.core.rotations.body_rates_from_euler` at the (new) angles. This is
    linear in the kick and regular at theta = 0, where the Euler rates themselves are not
    defined: every other component of W is kept. The quaternion keeps its hemisphere, so
    chi moves by exactly dchi. Reduced models: the same in their coordinates. z and zdot
    are kicked directly; the dissipated work D is kept.
    """
    from gyro_rotor.core.rotations import (body_rates_from_euler, euler_from_quaternion,
                                           euler_rates_from_body, quaternion_from_euler)
    for key in perturbation:
        if key not in PERTURBATION_KEYS:
            raise SceneError(_unknown(f'perturbation.{key}', [f'perturbation.{k}'
                                                              for k in PERTURBATION_KEYS]))
    d = {k: float(perturbation.get(k, 0.0)) for k in PERTURBATION_KEYS}
    for k, v in d.items():
        if not math.isfinite(v):
            raise SceneError(f'perturbation.{k} must be finite, got {v!r}')
    y = np.asarray(y, dtype=float)
    if model.name != 'full' and (d['dtheta'] or d['dthetadot']):
        raise SceneError(f'model {model.name} holds the axis vertical: dtheta and dthetadot '
                         f'cannot be applied')
    q = model.quaternion(y)
    W = model.body_rates(y)
    psi, theta, phi = (float(v) for v in euler_from_quaternion(q))
    if model.name == 'full':
        new = np.array(y, dtype=float)
        if d['dtheta'] or d['dchi']:
            theta, phi = theta + d['dtheta'], phi + d['dchi']
            new[0:4] = quaternion_from_euler(psi, theta, phi) * np.linalg.norm(q)
        new[4:7] = W + body_rates_from_euler(psi, theta, phi, d['dpsidot'], d['dthetadot'],
                                             0.0)
        new[model.iz] += d['dz']
        new[model.izd] += d['dzdot']
        return new
    psidot, thetadot, phidot = euler_rates_from_body(theta, phi, W)
    new = model.state_from_euler(theta=theta, thetadot=float(thetadot), psi=psi,
                                 psidot=float(psidot) + d['dpsidot'], phi_M=phi + d['dchi'],
                                 phi_M_dot=float(phidot), z=float(y[model.iz]) + d['dz'],
                                 zdot=float(y[model.izd]) + d['dzdot'])
    new[model.idiss] = y[model.idiss]
    return new


# -- loading ---------------------------------------------------------------------------------
def config_dirs() -> list[Path]:
    """Where scene files are searched: the source tree, then installed share directories."""
    dirs = [Path(__file__).resolve().parents[2] / 'config']
    prefixes = [sys.prefix] + [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)
                               if p]
    dirs += [Path(p) / 'share' / 'gyro_rotor' / 'config' for p in prefixes]
    return [d for d in dirs if d.is_dir()]


def list_scenes() -> list[str]:
    """Names of the shipped scenes."""
    names = set()
    for d in config_dirs():
        for f in d.glob('*.yaml'):
            if f.stem not in ('analysis',):
                names.add(f.stem)
    return sorted(names)


def scene_path(name_or_path: str | os.PathLike) -> Path:
    """Resolve a scene name ('precession') or a path to a scene file."""
    s = str(name_or_path)
    p = Path(s)
    if s.endswith(('.yaml', '.yml')) or os.sep in s or p.is_file():
        if not p.is_file():
            raise SceneError(f'scene file {s} does not exist')
        return p
    for d in config_dirs():
        f = d / f'{s}.yaml'
        if f.is_file():
            return f
    raise SceneError(unknown_scene_message(s))


def unknown_scene_message(name: str) -> str:
    """``unknown scene 'X'; did you mean 'Y'? (scenes: ...)``: every shipped scene listed.

    The centrifuge's scenes and the general systems' (config/systems/scenes) both, so that
    every command that takes a scene name says the same thing.
    """
    from gyro_rotor.core.system.scene import list_general_scenes
    from gyro_rotor.errors import did_you_mean
    names = list_scenes()
    general = [g for g in list_general_scenes() if g not in names]
    hint = did_you_mean(name, names + general)
    listed = ', '.join(names) + (f'; general systems: {", ".join(general)}' if general else '')
    return f"unknown scene '{name}'{hint} (scenes: {listed})"


find_scene = scene_path


def load_scene(name_or_path: str | os.PathLike = DEFAULT_SCENE,
               overrides: Mapping[str, Any] | None = None) -> Scene:
    """Load and validate a scene by name or path; ``overrides`` use the flat dotted keys."""
    from gyro_rotor.core.yamlio import load_yaml
    path = scene_path(name_or_path)
    try:
        text = path.read_text(encoding='utf-8')
    except (OSError, UnicodeDecodeError) as err:
        raise SceneError(f'cannot read scene file {path}: {err}') from err
    doc = load_yaml(text, f'scene file {path}', SceneError)
    if not isinstance(doc, dict):
        raise SceneError(f'scene file {path}: expected a mapping with a /** (or rotor_sim): '
                         f'ros__parameters: section')
    section = None
    for key in NODE_NAMES:
        if key in doc:
            section = doc[key]
            break
    if section is None:
        raise SceneError(f'scene file {path}: no rotor_sim (or /**) section; found '
                         f'{", ".join(map(str, doc)) or "nothing"}')
    if not isinstance(section, dict) or not isinstance(section.get('ros__parameters'), dict):
        raise SceneError(f'scene file {path}: its /** (rotor_sim) section needs a '
                         'ros__parameters mapping')
    flat = flatten(section['ros__parameters'])
    for key in section:
        if key != 'ros__parameters':
            raise SceneError(f"scene file {path}: unexpected key '{key}' beside "
                             'ros__parameters')
    if overrides:
        for key, value in overrides.items():
            if key not in SCENE_KEYS:
                raise SceneError(_unknown(key, SCENE_KEYS))
            if (SCENE_KEYS[key] is float and isinstance(value, int)
                    and not isinstance(value, bool)):
                value = float(value)   # overrides are not typed ROS files
            flat[key] = value
    flat.setdefault('scene', re.sub(r'[^A-Za-z0-9_.-]', '_', path.stem, flags=re.ASCII))
    return scene_from_mapping(flat, path=str(path))


def flatten(d: Mapping[str, Any], prefix: str = '') -> dict[str, Any]:
    """Nested dict to ROS 2 dotted parameter names."""
    out: dict[str, Any] = {}
    for k, v in d.items():
        name = f'{prefix}{k}'
        if isinstance(v, dict):
            out.update(flatten(v, name + '.'))
        else:
            out[name] = v
    return out


def _unknown(key: str, valid) -> str:
    return f"unknown key '{key}'{did_you_mean(key, valid)}"


def _typed(key: str, value: Any, where: str, *, strict_float: bool) -> Any:
    from gyro_rotor.core.yamlio import SCENE_NAME, short
    want = SCENE_KEYS[key]
    if key == 'scene' and not (isinstance(value, str) and SCENE_NAME.match(value)):
        raise SceneError(f'{where}: scene must be a name of ASCII letters, digits, _ . - '
                         f'(at most 100), got {short(value)}')
    if want is str and isinstance(value, str) and len(value) > 10000:
        raise SceneError(f'{where}: {key} is longer than 10000 characters')
    if want is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SceneError(f'{where}: {key} must be a number, got {short(value)}')
        if strict_float and isinstance(value, int):
            raise SceneError(f'{where}: {key} must be written as a float ({value}.0): ROS 2 '
                             f'parameter files are typed')
        return float(value)
    if want is int:
        if strict_float and isinstance(value, float):
            raise SceneError(f'{where}: {key} must be written as an integer, got '
                             f'{short(value)}: ROS 2 parameter files are typed')
        if isinstance(value, bool) or not isinstance(value, (int, float)) or (
                isinstance(value, float) and not value.is_integer()):
            raise SceneError(f'{where}: {key} must be an integer, got {short(value)}')
        return int(value)
    if want is bool:
        if not isinstance(value, bool):
            raise SceneError(f'{where}: {key} must be true or false, got {short(value)}')
        return value
    if want is str:
        if not isinstance(value, str):
            raise SceneError(f'{where}: {key} must be a string, got {short(value)}')
        return value
    if want is list:
        if not isinstance(value, (list, tuple)) or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            raise SceneError(f'{where}: {key} must be a list of numbers, got {short(value)}')
        return tuple(float(v) for v in value)
    raise AssertionError(want)  # pragma: no cover


def check_node_ranges(vals: Mapping[str, Any], where: str) -> None:
    """Refuse a node key outside :data:`NODE_RANGES` (as rotor_sim would, but before a run)."""
    for key, (low, high) in NODE_RANGES.items():
        v = vals.get(key)
        if v is not None and not (isinstance(v, (int, float)) and low <= v <= high):
            raise SceneError(f'{where}: {key} must be in [{low:g}, {high:g}], got {v!r}')


def scene_from_mapping(flat: Mapping[str, Any], path: str | None = None,
                       strict_float: bool | None = None) -> Scene:
    """Build a Scene from flat dotted keys (as in a parameter file or ROS parameters)."""
    where = f'scene file {path}' if path else 'scene'
    strict = path is not None if strict_float is None else strict_float
    vals: dict[str, Any] = {}
    for key, value in flat.items():
        if key not in SCENE_KEYS:
            raise SceneError(f'{where}: ' + _unknown(key, SCENE_KEYS))
        vals[key] = _typed(key, value, where, strict_float=strict)
    name = vals.get('scene', Path(path).stem if path else 'custom')
    model = vals.get('model', 'full')
    if model not in MODELS:
        raise SceneError(f"{where}: unknown model '{model}'; valid: {', '.join(MODELS)}")
    t_end = vals.get('t_end', 10.0)
    if not (math.isfinite(t_end) and t_end > 0):
        raise SceneError(f'{where}: t_end must be positive and finite, got {t_end!r}')
    try:
        params = RotorParams(**{k: vals[k] for k in PARAM_FIELDS if k in vals})
    except ParameterError as err:
        raise ParameterError(f'{where}: {err}') from None
    ini = {k.split('.', 1)[1]: v for k, v in vals.items() if k.startswith('initial.')}
    mode = ini.get('mode', 'steady')
    if mode not in ('steady', 'body'):
        raise SceneError(f"{where}: initial.mode must be 'steady' or 'body', got {mode!r}")
    if mode == 'body':
        bad = [k for k in ini if k in ('theta0', 'branch') or k in PERTURBATION_KEYS]
        if bad:
            raise SceneError(f'{where}: initial.{bad[0]} belongs to initial.mode steady')
        if len(ini.get('quaternion', (1, 0, 0, 0))) != 4:
            raise SceneError(f'{where}: initial.quaternion needs 4 numbers [w, x, y, z]')
        if len(ini.get('omega_body', (0, 0, 0))) != 3:
            raise SceneError(f'{where}: initial.omega_body needs 3 numbers')
        qn = math.hypot(*ini.get('quaternion', (1, 0, 0, 0)))
        if not (math.isfinite(qn) and qn > 0):
            raise SceneError(f'{where}: initial.quaternion must be finite and non-zero')
    else:
        bad = [k for k in ini if k in ('quaternion', 'omega_body', 'z', 'zdot', 'chi')]
        if bad:
            raise SceneError(f'{where}: initial.{bad[0]} belongs to initial.mode body')
    for k, v in ini.items():
        if isinstance(v, float) and not math.isfinite(v):
            raise SceneError(f'{where}: initial.{k} must be finite, got {v!r}')
        if isinstance(v, tuple) and not all(math.isfinite(x) for x in v):
            raise SceneError(f'{where}: initial.{k} must be finite, got {list(v)!r}')
    initial = InitialCondition(**ini)
    pert = {k.split('.', 1)[1]: v for k, v in vals.items() if k.startswith('perturbation.')}
    for k, v in pert.items():
        if not math.isfinite(v):
            raise SceneError(f'{where}: perturbation.{k} must be finite, got {v!r}')
    node = {k: v for k, v in vals.items() if k in NODE_KEYS}
    check_node_ranges(vals, where)
    scene = Scene(name=name, params=params, model=model, t_end=t_end, initial=initial,
                  perturbation=pert, node=node, description=vals.get('description', ''),
                  path=path)
    # validate the initial condition now (steady motion exists, model fits)
    scene.initial_state()
    return scene
