"""rclpy QoS profiles from the wire layouts' QoS dicts (:data:`gyro_rotor.bag.wire.QOS`).

The profiles are written once, in the rosbag2 form that the bag metadata stores; this module
only translates them for rclpy.
"""

from __future__ import annotations

from gyro_rotor.bag.wire import QOS
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = ['profile']

_HISTORY = {'keep_last': HistoryPolicy.KEEP_LAST, 'keep_all': HistoryPolicy.KEEP_ALL}
_RELIABILITY = {'reliable': ReliabilityPolicy.RELIABLE,
                'best_effort': ReliabilityPolicy.BEST_EFFORT}
_DURABILITY = {'volatile': DurabilityPolicy.VOLATILE,
               'transient_local': DurabilityPolicy.TRANSIENT_LOCAL}


def profile(name: str) -> QoSProfile:
    """Return the rclpy QoSProfile of ``QOS[name]`` (``state``, ``latched``, ...)."""
    spec = QOS[name]
    return QoSProfile(history=_HISTORY[spec['history']], depth=spec['depth'],
                      reliability=_RELIABILITY[spec['reliability']],
                      durability=_DURABILITY[spec['durability']])
