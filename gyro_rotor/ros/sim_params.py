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

import warnings

from gyro_rotor.core.scene import DEFAULT_SCENE, load_scene, SCENE_KEYS
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

    The parameters are the scene's system's (``parameter_specs`` of
    :class:`~gyro_rotor.core.param_spec.ParamSpec`), then the node's keys; the scene is the
    scene file's with the values given at start that differ from it
    (:meth:`~gyro_rotor.core.scene.Scene.with_changes`). The perturbation is the kick's
    keys without the ``perturbation.`` prefix.
    """
    name = _declare(node, 'scene', DEFAULT_SCENE, 'scene name (config/<name>.yaml), a general '
                    "scene's name (config/systems/scenes) or a path to a scene file; loaded "
                    'at start, the other parameters override it', True)
    base = load_scene(name)
    given, overrides, kick = {}, {}, {}
    for spec in base.system.parameter_specs(base, given):
        value = _declare(node, spec.key, spec.default, spec.doc, spec.read_only, spec.typ)
        given[spec.key] = list(value) if spec.typ is list else value  # (an array.array)
        if spec.fixed and given[spec.key] != spec.default:
            raise ParameterError(f"parameter {spec.key}: '{value}' is not the {spec.key} of "
                                 f"scene '{base.name}' ('{spec.default}'); give a scene of "
                                 f'that {spec.key}')
        if spec.kick:
            kick[spec.key.removeprefix('perturbation.')] = value
        if given[spec.key] != spec.default:
            overrides[spec.key] = given[spec.key]
    cfg = _node_keys(node, base.node)
    try:        # rebuilt only for values given at start that differ from the scene file's
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')
            scene = base.with_changes(overrides) if overrides else base
    except GyroRotorError as err:
        raise ParameterError(f"parameters of scene '{base.name}': "
                             f"{str(err).removeprefix(f'scene {base.name}: ')}") from None
    return scene, cfg, kick


def _node_keys(node: Node, base_node: dict) -> dict:
    """Declare the node keys (publish_rate, integrator, ...); return their values."""
    return {k: _declare(node, k, base_node.get(k, default),
                        doc + ('' if k in READ_ONLY else '; live'), k in READ_ONLY)
            for k, (typ, default, doc) in NODE_KEYS.items() if k != 'use_sim_time'}
