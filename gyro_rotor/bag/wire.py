"""Wire layouts of gyro_rotor's topics, written once: names, types, column orders, QoS.

Pure (no rclpy, no message types): the simulation node, the analysis node, the recorder,
the bag reader and the tools all take the layouts from here.

* **Topics** (:data:`SIM_TOPICS`, :data:`ANALYSIS_TOPICS`): relative names as the nodes
  publish them (resolved in the node's namespace), with their ROS types.
* **Column orders**: ``joint_states`` names :data:`JOINT_NAMES`; the ``energy`` array holds
  :data:`ENERGY_FIELDS` (its one dimension is labelled :data:`ENERGY_LABEL`). The analysis'
  own arrays depend on its criteria, so their columns are defined beside them
  (``gyro_rotor.analysis.results``: ``ANALYSIS_FIELDS``, ``MODE_FIELDS``); ``analysis_modes``
  is a matrix, a row per mode (dim[0] labelled with the mode names, comma separated). A
  reader takes the labels from the message itself (:func:`array_labels`), so that a change
  of layout cannot be misread.
* **QoS** (:data:`QOS`): the offered profiles in rosbag2's version 9 form (the form the bag
  metadata stores); ``gyro_rotor.ros.qos`` turns them into rclpy profiles.
* **Fast decoders** of the two high-rate topics from their CDR bytes
  (:func:`energy_from_cdr`, :func:`joints_from_cdr`): the recorder hands the analysis the
  very bytes it recorded, and decoding them here costs a tenth of a generic deserializer.
"""

from __future__ import annotations

from enum import StrEnum
import functools
import struct
from typing import NamedTuple

from gyro_rotor.core.model import Model

__all__ = ['JOINT_NAMES', 'ENERGY_FIELDS', 'ENERGY_LABEL', 'SIM_TOPICS', 'ANALYSIS_TOPICS',
           'Topic', 'QOS', 'sim_topics', 'scene_ref', 'scene_doc_for_bag',
           'array_labels', 'energy_from_cdr', 'joints_from_cdr', 'EnergyRow',
           'JointRow', 'CdrError']

#: joint order of the centrifuge's ``joint_states`` (3-1-3 angles of the paper; the rotor's
#: phi_R) and the fields of its ``energy`` array, in order (units: gyro_rotor.ros.messages):
#: the layout is the model's (written once, in core; a system file's model gives its own)
JOINT_NAMES = Model.joint_names
ENERGY_FIELDS = Model.energy_fields
ENERGY_LABEL = ','.join(ENERGY_FIELDS)


class Topic(StrEnum):
    """Relative names of the topics (the scene document is ``<sim node>/scene``)."""

    JOINT_STATES = 'joint_states'
    ENERGY = 'energy'
    AXIS = 'axis'
    STATOR_POSE = 'stator_pose'
    AXIS_MARKER = 'axis_marker'
    DIAGNOSTICS = '/diagnostics'
    CLOCK = '/clock'
    ANALYSIS = 'analysis'
    ANALYSIS_MODES = 'analysis_modes'
    ANALYSIS_VERDICT = 'analysis_verdict'


#: topics of the simulation node and their types (plus its ``~/scene``: :func:`sim_topics`)
SIM_TOPICS = {
    Topic.JOINT_STATES: 'sensor_msgs/msg/JointState',
    Topic.ENERGY: 'std_msgs/msg/Float64MultiArray',
    Topic.AXIS: 'geometry_msgs/msg/Vector3Stamped',
    Topic.STATOR_POSE: 'geometry_msgs/msg/PoseStamped',
    Topic.AXIS_MARKER: 'visualization_msgs/msg/Marker',
    Topic.DIAGNOSTICS: 'diagnostic_msgs/msg/DiagnosticArray',
    Topic.CLOCK: 'rosgraph_msgs/msg/Clock',
}
#: the analysis node's own output topics
ANALYSIS_TOPICS = {
    Topic.ANALYSIS: 'std_msgs/msg/Float64MultiArray',
    Topic.ANALYSIS_MODES: 'std_msgs/msg/Float64MultiArray',
    Topic.ANALYSIS_VERDICT: 'std_msgs/msg/String',
}


def sim_topics(sim_node: str = 'rotor_sim') -> dict[str, str]:
    """Topics of the simulation node (relative names), its latched scene document included."""
    return {**{str(k): v for k, v in SIM_TOPICS.items()},
            f'{sim_node}/scene': 'std_msgs/msg/String'}


#: QoS profiles (rosbag2 version 9 keys; unset keys are the defaults of normalize_qos):
#: ``state`` for the sampled topics (reliable, 10000 deep: 10 s at 1000 Hz for a
#: subscriber that falls behind), ``latched`` for documents (scene, verdict), ``results``
#: for the analysis' periodic output, ``monitor`` for a passive viewer (best effort).
QOS = {
    'state': {'history': 'keep_last', 'depth': 10000, 'reliability': 'reliable',
              'durability': 'volatile'},
    'latched': {'history': 'keep_last', 'depth': 1, 'reliability': 'reliable',
                'durability': 'transient_local'},
    'results': {'history': 'keep_last', 'depth': 10, 'reliability': 'reliable',
                'durability': 'volatile'},
    'monitor': {'history': 'keep_last', 'depth': 200, 'reliability': 'best_effort',
                'durability': 'volatile'},
}


def scene_ref(path) -> str:
    """Name a scene file without the recording machine's directories.

    A shipped scene is named relative to the package's share directory
    (``config/precession.yaml``), any other file by its file name alone; ``''`` for none.
    """
    from pathlib import Path

    from gyro_rotor.core.scene import config_dirs
    if not path:
        return ''
    p = Path(path).resolve()
    for d in config_dirs():
        if p.parent == d.resolve():
            return f'config/{p.name}'
    return p.name


def scene_doc_for_bag(text: str) -> str:
    """Return a ``~/scene`` document with its ``path`` as :func:`scene_ref` names it."""
    from gyro_rotor.core.yamlio import load_yaml
    from gyro_rotor.errors import GyroRotorError
    import yaml
    try:
        doc = load_yaml(text, 'scene document')
    except GyroRotorError:
        return text
    if not isinstance(doc, dict) or not doc.get('path'):
        return text
    doc['path'] = scene_ref(doc['path'])
    return yaml.safe_dump(doc, sort_keys=False)


def array_labels(dims) -> list[list[str]]:
    """Return the comma-separated labels of each dimension of a MultiArray layout."""
    return [d.label.split(',') if d.label else [] for d in dims]


# --------------------------------------------------------------------------------------------
# CDR decoding of energy and joint_states (XCDR1, as rmw_fastrtps writes them)


class CdrError(ValueError):
    """Bytes that are not the CDR of the expected message type."""


class _Dim(NamedTuple):
    label: str
    size: int
    stride: int


class _Layout(NamedTuple):
    dim: list
    data_offset: int


class EnergyRow(NamedTuple):
    """An ``energy`` message as its decoder gives it (the fields the analysis reads)."""

    layout: _Layout
    data: tuple


class _Stamp(NamedTuple):
    sec: int
    nanosec: int


class _Header(NamedTuple):
    stamp: _Stamp
    frame_id: str


class JointRow(NamedTuple):
    """A ``joint_states`` message as its decoder gives it."""

    header: _Header
    name: list
    position: tuple
    velocity: tuple
    effort: tuple


class _Cdr:
    """Sequential reader of a little-endian CDR buffer (alignment from the payload start)."""

    __slots__ = ('buf', 'pos')

    def __init__(self, buf: bytes):
        if len(buf) < 4 or buf[1] != 1:
            raise CdrError(f'not little-endian CDR (header {bytes(buf[:4])!r})')
        self.buf = buf
        self.pos = 4

    def _align(self, n: int) -> None:
        self.pos += (-(self.pos - 4)) % n

    def u32(self) -> int:
        self._align(4)
        v, = struct.unpack_from('<I', self.buf, self.pos)
        self.pos += 4
        return v

    def i32(self) -> int:
        self._align(4)
        v, = struct.unpack_from('<i', self.buf, self.pos)
        self.pos += 4
        return v

    def string(self) -> str:
        n = self.u32()
        end = self.pos + n
        if n == 0 or end > len(self.buf):
            raise CdrError(f'string of {n} bytes at {self.pos} outside the message')
        s = self.buf[self.pos:end - 1].decode()
        self.pos = end
        return s

    def f64s(self) -> tuple:
        n = self.u32()
        if n:
            self._align(8)
        end = self.pos + 8 * n
        if end > len(self.buf):
            raise CdrError(f'float64[{n}] at {self.pos} outside the message')
        fmt = _F64.get(n)
        if fmt is None:
            fmt = _F64.setdefault(n, struct.Struct(f'<{n}d'))
        a = fmt.unpack_from(self.buf, self.pos)
        self.pos = end
        return a


_F64: dict[int, struct.Struct] = {}


#: the Raises section of every decoder's docstring (:func:`_decoder` appends it)
_RAISES = """

    Raises
    ------
    CdrError
        If the bytes are too short for what they announce.
    """


def _decoder(what: str):
    """Make ``fn(reader)`` a decoder of bytes: a truncation raises one CdrError naming ``what``."""
    def wrap(fn):
        @functools.wraps(fn)
        def decode(data: bytes):
            try:
                return fn(_Cdr(data))
            except struct.error as err:
                raise CdrError(f'{what} of {len(data)} bytes: {err}') from err
        decode.__doc__ = (fn.__doc__ or '') + _RAISES    # None under python -OO
        return decode
    return wrap


@_decoder('Float64MultiArray')
def energy_from_cdr(r: _Cdr) -> EnergyRow:
    """Decode a serialized std_msgs/Float64MultiArray (layout and data) from its bytes."""
    dims = []
    for _ in range(r.u32()):
        label = r.string()
        dims.append(_Dim(label, r.u32(), r.u32()))
    offset = r.u32()
    return EnergyRow(_Layout(dims, offset), r.f64s())


@_decoder('JointState')
def joints_from_cdr(r: _Cdr) -> JointRow:
    """Decode a serialized sensor_msgs/JointState from its bytes."""
    stamp = _Stamp(r.i32(), r.u32())
    header = _Header(stamp, r.string())
    names = [r.string() for _ in range(r.u32())]
    return JointRow(header, names, r.f64s(), r.f64s(), r.f64s())
