"""Conversions from model outputs (numpy) to ROS 2 messages for the simulation node.

The only module besides the nodes that imports message types. Every function is a pure
conversion: the caller passes simulation time in seconds (or integer nanoseconds) and SI
values; nothing here integrates or decides.

``energy`` layout (std_msgs/Float64MultiArray, one dimension, see :data:`ENERGY_FIELDS`)::

    data = [t_sim, E_star, dE_dt, dissipation, residual, z, zdot, seq, D, k]
    layout.dim[0] = {label: 't_sim,E_star,...,k', size: 10, stride: 10}

t_sim [s] is the sample's simulation time (the same as the paired ``joint_states``
header stamp), E_star [J] (eq. 13), dE_dt = -K_D zdot^2 [W] (eq. 17), dissipation =
K_D zdot^2 [W], residual = E* + D - E_ref [J] (docs/model.md section 4), z [rad], zdot [rad/s],
seq = the node's sample counter (0, 1, 2, ... over the node's life, never reset, so a gap
proves a lost message), D [J] = dissipated work since the last reset, and k = the grid
index of the sample (t_sim = k / publish_rate, restarts at 0 on reset).
"""

from __future__ import annotations

import math
from typing import Mapping

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, Pose, PoseStamped, Quaternion, Vector3, Vector3Stamped
# the wire layouts are written once, in gyro_rotor.bag.wire
from gyro_rotor.bag.wire import ENERGY_FIELDS, ENERGY_LABEL, JOINT_NAMES
import numpy as np
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import ColorRGBA, Float64MultiArray, Header, MultiArrayDimension, String
from visualization_msgs.msg import Marker

__all__ = ['JOINT_NAMES', 'ENERGY_FIELDS', 'LEVELS', 'stamp', 'joint_state', 'float_array',
           'axis_vector', 'stator_pose', 'axis_marker', 'diagnostic_array', 'clock',
           'text', 'ENERGY_LABEL']

#: diagnostic levels as the byte constants the message needs (never plain ints)
LEVELS = {'OK': DiagnosticStatus.OK, 'WARN': DiagnosticStatus.WARN,
          'ERROR': DiagnosticStatus.ERROR, 'STALE': DiagnosticStatus.STALE}


def stamp(t: float | int) -> Time:
    """builtin_interfaces/Time from seconds (float) or nanoseconds (int)."""
    ns = t if isinstance(t, int) else int(round(float(t) * 1e9))
    if ns < 0:
        raise ValueError(f'stamp must not be negative, got {t!r}')
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def _wrap(a: float) -> float:
    """Angle in (-pi, pi]."""
    w = math.remainder(a, 2 * math.pi)
    return math.pi if w == -math.pi else w


def joint_state(t: Time, positions, velocities, efforts, names=JOINT_NAMES,
                wrap: bool = True) -> JointState:
    """Build a JointState (default: JOINT_NAMES, angles wrapped to (-pi, pi], theta in [0, pi]).

    ``names`` and ``wrap=False``: a general system's coordinates and rotor lags, as
    integrated.
    """
    return JointState(header=Header(stamp=t), name=list(names),
                      position=[_wrap(float(a)) if wrap else float(a) for a in positions],
                      velocity=[float(v) for v in velocities],
                      effort=[float(e) for e in efforts])


def float_array(data, *labels) -> Float64MultiArray:
    """Build a Float64MultiArray of ``data`` (row major), a dimension per list of labels.

    ``energy``: one dimension of ENERGY_FIELDS (see module doc); ``analysis_modes``: a row
    per mode, a column per field.
    """
    msg = Float64MultiArray()
    sizes = [len(names) for names in labels]
    msg.layout.dim = [MultiArrayDimension(label=','.join(names), size=n,
                                          stride=math.prod(sizes[i:]))
                      for i, (names, n) in enumerate(zip(labels, sizes))]
    msg.data = [float(v) for v in data]
    return msg


def axis_vector(t: Time, frame_id: str, axis) -> Vector3Stamped:
    """Return the stator's symmetry axis e_3 in space axes (unit vector)."""
    x, y, z = (float(v) for v in axis)
    return Vector3Stamped(header=Header(stamp=t, frame_id=frame_id), vector=Vector3(x=x, y=y, z=z))


def stator_pose(t: Time, frame_id: str, q) -> PoseStamped:
    """Stator orientation (body to space) from (w, x, y, z), normalized; position F = 0."""
    q = np.asarray(q, dtype=float)
    w, x, y, z = (float(v) for v in q / np.linalg.norm(q))
    return PoseStamped(header=Header(stamp=t, frame_id=frame_id),
                       pose=Pose(orientation=Quaternion(w=w, x=x, y=y, z=z)))


def axis_marker(t: Time, frame_id: str, axis, length: float = 0.3,
                ns: str = 'rotor_axis') -> Marker:
    """Build an ARROW from the fixed point F along the symmetry axis (RViz, Foxglove)."""
    a = np.asarray(axis, dtype=float) * length
    return Marker(header=Header(stamp=t, frame_id=frame_id), ns=ns, id=0, type=Marker.ARROW,
                  action=Marker.ADD, frame_locked=False,
                  points=[Point(), Point(x=float(a[0]), y=float(a[1]), z=float(a[2]))],
                  # shaft diameter, head diameter, head length
                  scale=Vector3(x=0.01 * length / 0.3, y=0.02 * length / 0.3,
                                z=0.04 * length / 0.3),
                  color=ColorRGBA(r=0.9, g=0.3, b=0.1, a=1.0))


def diagnostic_array(t: Time, name: str, level: str, message: str,
                     values: Mapping[str, object], hardware_id: str = '') -> DiagnosticArray:
    """Build a DiagnosticArray with one status; ``level`` is 'OK', 'WARN', 'ERROR' or 'STALE'."""
    st = DiagnosticStatus(level=LEVELS[level], name=name, message=message,
                          hardware_id=hardware_id,
                          values=[KeyValue(key=str(k), value=_fmt(v)) for k, v in values.items()])
    return DiagnosticArray(header=Header(stamp=t), status=[st])


def _fmt(v: object) -> str:
    if isinstance(v, float):
        return f'{v:.9g}'
    return str(v)


def clock(t: Time) -> Clock:
    """rosgraph_msgs/Clock at simulation time t."""
    return Clock(clock=t)


def text(s: str) -> String:
    """std_msgs/String."""
    return String(data=s)
