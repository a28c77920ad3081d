"""QoS profiles in the rosbag2 version 9 form (the text of ``offered_qos_profiles``).

ros2/rosbag2 ``jazzy:rosbag2_storage/src/rosbag2_storage/qos.cpp``: version 9 writes the
policies as strings (``keep_last``, ``reliable``, ``volatile``, ``automatic``) and durations
as ``{sec, nsec}``; ``metadata.yaml`` holds the list itself, the channel metadata the same
list dumped to a YAML string (:func:`qos_yaml`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from gyro_rotor.errors import BagError
import yaml

__all__ = ['qos_profile_dict', 'normalize_qos', 'qos_yaml', 'INFINITE_DURATION']

#: ``{sec, nsec}`` of ``RMW_DURATION_INFINITE`` as rosbag2 records it from the graph.
INFINITE_DURATION = {'sec': 9223372036, 'nsec': 854775807}
_POLICIES: dict[str, tuple[str, ...]] = {
    'history': ('system_default', 'keep_last', 'keep_all', 'unknown'),
    'reliability': ('system_default', 'reliable', 'best_effort', 'unknown', 'best_available'),
    'durability': ('system_default', 'transient_local', 'volatile', 'unknown',
                   'best_available'),
    'liveliness': ('system_default', 'automatic', 'manual_by_node', 'manual_by_topic',
                   'unknown', 'best_available'),
}
_DURATIONS = ('deadline', 'lifespan', 'liveliness_lease_duration')
_QOS_KEYS = ('history', 'depth', 'reliability', 'durability', 'deadline', 'lifespan',
             'liveliness', 'liveliness_lease_duration', 'avoid_ros_namespace_conventions')


def qos_profile_dict(reliability: str = 'reliable', durability: str = 'volatile',
                     history: str = 'keep_last', depth: int = 10, *,
                     deadline: Any = None, lifespan: Any = None,
                     liveliness: str = 'automatic', liveliness_lease_duration: Any = None,
                     avoid_ros_namespace_conventions: bool = False) -> dict[str, Any]:
    """Return one offered QoS profile in the rosbag2 version 9 form.

    Durations left at ``None`` are infinite (``{sec: 9223372036, nsec: 854775807}``), which is
    what rosbag2 records for publishers with default QoS. Durations may also be integer
    nanoseconds, ``{sec, nsec}`` dicts or objects with a ``nanoseconds`` attribute.

    Raises
    ------
    BagError
        If a policy name or value is invalid.
    """
    return normalize_qos({
        'history': history, 'depth': depth, 'reliability': reliability,
        'durability': durability,
        'deadline': INFINITE_DURATION if deadline is None else deadline,
        'lifespan': INFINITE_DURATION if lifespan is None else lifespan,
        'liveliness': liveliness,
        'liveliness_lease_duration': (INFINITE_DURATION if liveliness_lease_duration is None
                                      else liveliness_lease_duration),
        'avoid_ros_namespace_conventions': avoid_ros_namespace_conventions,
    })[0]


def _policy(key: str, value: Any) -> str:
    names = _POLICIES[key]
    if hasattr(value, 'value') and not isinstance(value, (str, int)):
        value = value.value  # an enum, e.g. rclpy.qos.ReliabilityPolicy.RELIABLE
    if isinstance(value, bool):
        raise BagError(f'QoS {key}: invalid value {value!r}')
    if isinstance(value, int):
        if 0 <= value < len(names):
            return names[value]
    elif isinstance(value, str) and value.lower() in names:
        return value.lower()
    raise BagError(f'QoS {key}: invalid value {value!r}; expected one of {", ".join(names)}')


def _duration(key: str, value: Any) -> dict[str, int]:
    if isinstance(value, Mapping) and set(value) == {'sec', 'nsec'}:
        sec, nsec = value['sec'], value['nsec']
    elif hasattr(value, 'nanoseconds'):
        sec, nsec = divmod(int(value.nanoseconds), 10**9)
    elif isinstance(value, int) and not isinstance(value, bool):
        sec, nsec = divmod(value, 10**9)
    else:
        raise BagError(f'QoS {key}: invalid duration {value!r}; expected {{sec, nsec}} '
                       'or integer nanoseconds')
    if (not all(isinstance(x, int) and not isinstance(x, bool) for x in (sec, nsec))
            or sec < 0 or not 0 <= nsec < 10**9):
        raise BagError(f'QoS {key}: invalid duration {value!r}')
    return {'sec': sec, 'nsec': nsec}


def normalize_qos(qos: Any) -> list[dict[str, Any]]:
    """Return offered QoS profiles as the rosbag2 version 9 list of dicts.

    Parameters
    ----------
    qos : None, mapping, QoS object, or a sequence of these
        ``None`` gives ``[qos_profile_dict()]``. A mapping may leave keys out (they take the
        :func:`qos_profile_dict` defaults); policies may be names (``'best_effort'``), rmw enum
        integers or enums. An object with the attributes of ``rclpy.qos.QoSProfile`` is read
        attribute by attribute.

    Raises
    ------
    BagError
        For unknown keys and invalid values.
    """
    if qos is None:
        return [qos_profile_dict()]
    if isinstance(qos, Sequence) and not isinstance(qos, (str, bytes)):
        return [p for item in qos for p in normalize_qos(item)]
    if not isinstance(qos, Mapping):
        if not all(hasattr(qos, key) for key in _QOS_KEYS):
            raise BagError(f'QoS: cannot use {qos!r}; expected a dict or a QoS profile')
        qos = {key: getattr(qos, key) for key in _QOS_KEYS}
    unknown = set(qos) - set(_QOS_KEYS)
    if unknown:
        raise BagError(f'QoS: unknown keys {sorted(unknown)}; expected {list(_QOS_KEYS)}')
    out: dict[str, Any] = {}
    for key in _QOS_KEYS:
        value = qos.get(key)
        if value is None:
            default = {'history': 'keep_last', 'depth': 10, 'reliability': 'reliable',
                       'durability': 'volatile', 'liveliness': 'automatic',
                       'avoid_ros_namespace_conventions': False}
            value = default.get(key, INFINITE_DURATION)
        if key in _POLICIES:
            out[key] = _policy(key, value)
        elif key in _DURATIONS:
            out[key] = _duration(key, value)
        elif key == 'depth':
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise BagError(f'QoS depth: invalid value {value!r}')
            out[key] = value
        else:
            if not isinstance(value, bool):
                raise BagError(f'QoS {key}: invalid value {value!r}; expected a bool')
            out[key] = value
    return [out]


def qos_yaml(profiles: list[dict[str, Any]]) -> str:
    """Dump QoS profiles to the YAML string of the MCAP channel metadata."""
    return yaml.safe_dump(profiles, default_flow_style=False, sort_keys=False)
