"""The parameters of ``rotor_sim``: descriptors (documentation, ranges) and their checks.

Every scene key is a parameter of the node (:data:`~gyro_rotor.core.scene.SCENE_KEYS` gives
its type). They are declared with ``dynamic_typing`` so that a value of the wrong type
reaches the node's own check, which names the parameter, the value and the expected type
(rclpy's own refusal says only "Wrong parameter type"): at start-up a bad
``--ros-args -p`` value is a :class:`~gyro_rotor.errors.ParameterError` (one ``ERROR:``
line from the runner, exit status 1), live it is the refusal's reason. The ranges stay in
the descriptors (``ros2 param describe`` shows them; rclpy enforces them for values of
the right type).
"""

from __future__ import annotations

import dataclasses
import warnings

from gyro_rotor.core.params import PARAM_DESCRIPTIONS, PARAM_FIELDS, PARAM_UNITS
from gyro_rotor.core.scene import (CENTRIFUGE, DEFAULT_SCENE, INITIAL_UNITS, load_scene,
                                   PERTURBATION_KEYS, scene_from_mapping, SCENE_KEYS)
from gyro_rotor.errors import GyroRotorError, ParameterError
from gyro_rotor.node_settings import NODE_KEYS, NODE_RANGES
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.parameter import Parameter

__all__ = ['declare_parameters', 'declare_node_parameter', 'type_error', 'PARAM_RANGES',
           'NODE_RANGES', 'READ_ONLY']

_BIG = 1e9
#: ranges of the RotorParams fields (RotorParams validates the rest)
PARAM_RANGES = {
    'A_R': (0.0, 1e6), 'A_M': (0.0, 1e6), 'C_R': (0.0, 1e6), 'C_M': (0.0, 1e6),
    'G': (0.0, 1e7), 's': (-100.0, 100.0), 'c_theta': (0.0, _BIG), 'c_psi': (0.0, _BIG),
    'K_S': (0.0, _BIG), 'K_D': (0.0, _BIG), 'Omega0': (-1e5, 1e5), 'pole_pairs': (0, 64),
}
#: node keys that only take effect at start
READ_ONLY = {'scene', 'model', 'publish_rate', 'description', 'wait_for_subscribers',
             'wait_for_node', 'realtime_priority'}
_TYPES = {float: Parameter.Type.DOUBLE, int: Parameter.Type.INTEGER, bool: Parameter.Type.BOOL,
          str: Parameter.Type.STRING, list: Parameter.Type.DOUBLE_ARRAY}
_TYPE_NAMES = {Parameter.Type.DOUBLE: 'a double',
               Parameter.Type.INTEGER: 'an integer', Parameter.Type.BOOL: 'true or false',
               Parameter.Type.STRING: 'a string',
               Parameter.Type.DOUBLE_ARRAY: 'a list of doubles such as [1.0, 0.0]'}
_INITIAL_DOC = {
    'mode': 'initial condition: steady (on a steady motion) or body (quaternion, rates)',
    'theta0': 'tilt of the steady motion [rad]', 'branch': 'steady motion: 0 = solution I, '
    '1 = precession, 2 = nutation branch', 'dtheta': 'offset of theta [rad]',
    'dthetadot': 'offset of thetadot [rad/s]', 'dpsidot': 'offset of psidot [rad/s]',
    'dchi': 'offset of the twist chi [rad]', 'dz': 'offset of z [rad]',
    'dzdot': 'offset of zdot [rad/s]', 'quaternion': 'stator quaternion [w, x, y, z]',
    'omega_body': 'stator body rates [rad/s]', 'z': 'rotor lag z [rad]',
    'zdot': 'rate of z [rad/s]', 'chi': 'twist chi [rad]',
}


def _range(name: str) -> tuple | None:
    return PARAM_RANGES.get(name) or NODE_RANGES.get(name)


def _expected(name: str, typ: type) -> str:
    """Describe the expected value of a parameter: its type and range."""
    rng = _range(name)
    return _TYPE_NAMES[_TYPES[typ]] + (f' in [{rng[0]:g}, {rng[1]:g}]' if rng else '')


def type_error(param: Parameter, types: dict | None = None) -> str | None:
    """Return why a parameter of the node has the wrong type (None if its type is right).

    ``types``: the Python type of each parameter as declared (default: the centrifuge
    scene's keys, SCENE_KEYS).
    """
    typ = (SCENE_KEYS if types is None else types).get(param.name)
    expected = _TYPES[typ] if typ is not None else None
    if expected is None or param.type_ == expected:
        return None
    hint = (f' (write {float(param.value)!r})' if expected == Parameter.Type.DOUBLE
            and param.type_ == Parameter.Type.INTEGER else '')
    return (f'parameter {param.name}: {param.value!r} ({param.type_.name.lower()}) is not '
            f'{_expected(param.name, typ)}{hint}')


def _declare(node: Node, name: str, value, doc: str, read_only: bool = False,
             typ: type | None = None):
    """Declare one parameter (dynamic typing, see the module doc); return its value.

    ``typ``: its Python type (default: SCENE_KEYS'); recorded in ``node.parameter_types``.
    """
    typ = typ or SCENE_KEYS[name]
    if not hasattr(node, 'parameter_types'):
        node.parameter_types = {}
    node.parameter_types[name] = typ
    d = ParameterDescriptor(name=name, description=doc, read_only=read_only,
                            dynamic_typing=True)
    rng = _range(name)
    if rng and typ is float:
        d.floating_point_range = [FloatingPointRange(from_value=float(rng[0]),
                                                     to_value=float(rng[1]), step=0.0)]
    elif rng:
        d.integer_range = [IntegerRange(from_value=int(rng[0]), to_value=int(rng[1]), step=1)]
    try:
        param = node.declare_parameter(name, value, d)
    except ParameterException as err:
        given = getattr(node, '_parameter_overrides', {}).get(name)
        shown = repr(given.value) if given is not None else '(the given value)'
        raise ParameterError(f'parameter {name}: {shown} is out of range: expected '
                             f'{_expected(name, typ)}') from err
    reason = type_error(param, node.parameter_types)
    if reason:
        raise ParameterError(reason)
    return param.value


def declare_node_parameter(node: Node, name: str, default, doc: str,
                           read_only: bool = False):
    """Declare a parameter of the node alone (not a scene key); return its value.

    Its range, if any, is in :data:`NODE_RANGES`; its type is that of ``default``.
    """
    return _declare(node, name, default, doc, read_only, type(default))


def declare_parameters(node: Node) -> tuple:
    """Declare every parameter; return (scene, node keys, perturbation) as given at start.

    The parameters of the built-in centrifuge are its RotorParams and initial condition;
    a system file's scene has its own (:func:`_declare_system`).
    """
    name = _declare(node, 'scene', DEFAULT_SCENE, 'scene name (config/<name>.yaml), a general '
                    "scene's name (config/systems/scenes) or a path to a scene file; loaded "
                    'at start, the other parameters override it', True)
    base = load_scene(name)
    if not base.builtin:
        return _declare_system(node, base)
    flat: dict = {'scene': base.name}
    flat['system'] = _declare(node, 'system', CENTRIFUGE, 'the rotor system: the built-in '
                              'centrifuge (that of the scene file)', True)
    if flat['system'] != CENTRIFUGE:
        raise ParameterError(f"parameter system: '{flat['system']}' is not the system of "
                             f"scene '{base.name}' ('{CENTRIFUGE}'); give a scene of that system")
    flat['description'] = _declare(node, 'description', base.description,
                                   'what the scene shows', True)
    flat['model'] = _declare(node, 'model', base.system.model,
                             'full | locked_housing | upright_axis',
                             True)
    flat['t_end'] = _declare(node, 't_end', base.t_end, 'scene duration [s] (the node stops '
                             'there if stop_at_t_end)')
    for f in PARAM_FIELDS:
        flat[f] = _declare(node, f, getattr(base.system.params, f),
                           f'{PARAM_DESCRIPTIONS[f]} [{PARAM_UNITS[f]}]; live')
    ic = base.system.initial
    mode = _declare(node, 'initial.mode', ic.mode, _INITIAL_DOC['mode'], True)
    keys = (('theta0', 'branch', *PERTURBATION_KEYS) if mode == 'steady'
            else ('quaternion', 'omega_body', 'z', 'zdot'))
    flat['initial.mode'] = mode
    if mode == 'body' and ic.chi is not None:
        keys = (*keys, 'chi')
    for k in keys:
        v = getattr(ic, k)
        v = [float(x) for x in v] if isinstance(v, tuple) else v
        flat[f'initial.{k}'] = _declare(node, f'initial.{k}', v, _INITIAL_DOC[k] + (
            '' if k == 'chi' else '; read at start and by ~/reset'), True)
    for k in PERTURBATION_KEYS:
        flat[f'perturbation.{k}'] = _declare(
            node, f'perturbation.{k}', float(base.perturbation.get(k, 0.0)),
            f'kick of ~/perturb [{INITIAL_UNITS[k]}]; live')
    flat.update(_node_keys(node, base.node))
    try:           # the scene file loaded: what fails now comes from the parameters
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')
            scene = scene_from_mapping(flat, strict_float=False)
    except GyroRotorError as err:
        raise ParameterError(f"parameters of scene '{base.name}': "
                             f"{str(err).removeprefix('scene: ')}") from None
    scene = dataclasses.replace(scene, path=base.path)
    cfg = {k: flat[k] for k in NODE_KEYS if k != 'use_sim_time'}
    perturbation = {k: flat[f'perturbation.{k}'] for k in PERTURBATION_KEYS}
    return scene, cfg, perturbation


def _node_keys(node: Node, base_node: dict) -> dict:
    """Declare the node keys (publish_rate, integrator, ...); return their values."""
    return {k: _declare(node, k, base_node.get(k, default),
                        doc + ('' if k in READ_ONLY else '; live'), k in READ_ONLY)
            for k, (typ, default, doc) in NODE_KEYS.items() if k != 'use_sim_time'}


def _declare_system(node: Node, base) -> tuple:
    """Declare the parameters of a system file's scene; return (scene, keys, perturbation).

    ``system`` (read only), ``t_end``, ``constants.NAME`` and ``drive.ROTOR.KEY`` (live),
    ``initial.q``/``qdot``/``z``/``zdot`` and ``steady.*`` (read at start),
    ``perturbation.q``/``qdot``/``z``/``zdot`` (the kick of ~/perturb, live) and the node
    keys.
    """
    from gyro_rotor.core.system.system_file import DRIVE_KEYS
    system, flat = base.system.full, dict(base.flat)
    decl, overrides = {}, {}

    def scene_key(key, default, doc, read_only=False, typ=float):
        """Declare a key of the scene; a value other than the scene's is an override."""
        value = _declare(node, key, default, doc, read_only, typ)
        decl[key] = list(value) if typ is list else value    # (an array.array for lists)
        if decl[key] != default:
            overrides[key] = decl[key]

    scene_key('description', base.description, 'what the scene shows', True, str)
    system_name = _declare(node, 'system', flat['system'], 'the rotor system (a name or a '
                           'system file; that of the scene file)', True, str)
    if system_name != flat['system']:
        raise ParameterError(f"parameter system: '{system_name}' is not the system of scene "
                             f"'{base.name}' ('{flat['system']}'); give a scene of that system")
    scene_key('t_end', base.t_end, 'scene duration [s]')
    for c, v in system.constants.items():
        scene_key(f'constants.{c}', float(v), f'constant {c} of system {system.name}; live')
    for r, d in zip(system.rotors, system.drives):
        for k in DRIVE_KEYS:
            typ = int if k == 'pole_pairs' else float
            scene_key(f'drive.{r}.{k}', typ(getattr(d, k)),
                      f'drive of rotor {r}: {_DRIVE_DOC[k]}; live', typ=typ)
    sizes = {'q': system.n, 'qdot': system.n, 'z': system.m, 'zdot': system.m}
    for part in ('initial', 'steady'):
        for k, size in sizes.items():
            key = f'{part}.{k}'
            default = [float(x) for x in flat.get(key, [0.0] * size)]
            if (part, k) == ('steady', 'zdot') or not default:
                continue        # no such key; an empty list has no ROS type: nothing to set
            scene_key(key, default, f'{part} {k} ({size} numbers); read at start'
                      + (' and by ~/reset' if part == 'initial' else ''), True, list)
    kick = {}
    for k, size in sizes.items():
        if size:
            kick[k] = _declare(node, f'perturbation.{k}',
                               [float(x) for x in flat.get(f'perturbation.{k}', [0.0] * size)],
                               f'kick of ~/perturb added to {k} ({size} numbers); live',
                               typ=list)
    cfg = _node_keys(node, base.node)
    try:        # rebuilt only for values given at start that differ from the scene file's
        scene = base.with_changes(overrides) if overrides else base
    except GyroRotorError as err:
        raise ParameterError(f"parameters of scene '{base.name}': {err}") from None
    return scene, cfg, kick


_DRIVE_DOC = {'K_S': 'synchronizing stiffness K_S [N m/rad] (eq. 8)',
              'K_D': 'damping K_D [N m s/rad] (eq. 8)',
              'Omega0': 'field speed Omega0 [rad/s] (eq. 7)',
              'pole_pairs': 'pole pairs p (0: linear law, > 0: sine law)'}
