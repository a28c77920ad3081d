"""Write and read rosbag2 bags (MCAP storage) the way ``ros2 bag`` on Jazzy does, in pure Python.

The module imports neither rclpy nor message types: messages go in and out as serialized CDR
bytes (``rclpy.serialization.serialize_message`` or ``raw=True`` subscriptions), and
:meth:`BagReader.decoded` decodes them with the ``mcap_ros2`` decoder from the definitions
stored in the bag.

Format decisions (each checked against the rosbag2 Jazzy sources and the readers in tests):

* **Layout.** A bag is a directory ``<name>/`` holding ``<name>_0.mcap`` and
  ``metadata.yaml`` (rosbag2 ``SequentialWriter``). A bare ``.mcap`` file can be read too.
* **MCAP records** (ros2/rosbag2 ``jazzy:rosbag2_storage_mcap/src/mcap_storage.cpp``,
  ``create_topic`` and ``update_metadata``): header profile ``ros2``; one schema per type,
  named by the type (``sensor_msgs/msg/JointState``), encoding ``ros2msg``, data the full
  definition text of :func:`gyro_rotor.msgdefs.message_definition`; one channel per topic,
  message encoding ``cdr``, metadata ``offered_qos_profiles`` (a YAML string) and
  ``topic_type_hash`` (RIHS01 or ``''``); a metadata record ``rosbag2`` with key
  ``serialized_metadata`` (the YAML of the bag metadata, version 9) written at close. The
  summary holds a Statistics record, which ``ros2 bag info`` on a bare ``.mcap`` requires.
  Chunks are uncompressed by default, like rosbag2 (``compression = None``).
* **QoS** (ros2/rosbag2 ``jazzy:rosbag2_storage/src/rosbag2_storage/qos.cpp``): version 9
  writes the policies as strings (``keep_last``, ``reliable``, ``volatile``, ``automatic``)
  and durations as ``{sec, nsec}``; ``metadata.yaml`` holds the list itself, the channel
  metadata the same list dumped to a YAML string. rosbags 0.11.9 (``rosbag2/metadata.py``
  ``parse_qos``) accepts both and pairs the ``metadata.yaml`` topics with the MCAP channels
  only if both parse to equal values, so both are produced from one normalized list.
* **metadata.yaml** (``rosbag2_storage/include/rosbag2_storage/yaml.hpp``, version 9): top key
  ``rosbag2_bagfile_information``; written at open, rewritten (atomically) when a topic is
  added (zero counts) and at close (final counts). After a crash :func:`recover_bag` rewrites
  it from the data.
* **Flushing.** ``mcap.writer.Writer`` keeps the current chunk in memory until it exceeds
  ``chunk_size``. :class:`BagWriter` also ends the chunk as soon as a write arrives more than
  ``flush_interval_s`` after the first message of the chunk, with the public
  ``mcap.writer.Writer.flush()`` (ends the chunk, writes it, flushes the Python buffer). A
  SIGKILL therefore loses at most about ``flush_interval_s`` of messages; the kernel keeps
  written data across a killed process, ``fsync=True`` adds an ``os.fsync`` per flush for power
  loss. A writer that may go idle should call :meth:`BagWriter.flush` from a timer.
* **Reading damaged files.** A file without a valid footer and summary (a killed writer, a
  cut copy) is read record by record from the start; every complete record is used, the first
  incomplete or malformed one ends the scan. The reader then sets ``truncated`` and warns with
  :class:`BagWarning`; it raises :class:`~gyro_rotor.errors.BagError` only when nothing at all
  can be read (missing path, empty directory, not an MCAP file).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping, Sequence
import dataclasses
import heapq
import io
import os
from pathlib import Path
import struct
import time
from typing import Any, NamedTuple
import warnings

from gyro_rotor import __version__
from gyro_rotor.bag.msgdefs import message_definition, normalize_type_name, type_hash
from gyro_rotor.errors import BagError
import mcap
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.reader import SeekingReader
from mcap.records import Channel, Chunk, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import breakup_chunk
from mcap.writer import CompressionType, Writer
import yaml

__all__ = [
    'BagError', 'BagWarning', 'BagWriter', 'BagReader', 'TopicInfo', 'RecoveryReport',
    'open_bag', 'recover_bag', 'qos_profile_dict', 'normalize_qos', 'message_definition',
    'type_hash', 'METADATA_VERSION',
]

#: rosbag2 metadata version written (Jazzy).
METADATA_VERSION = 9
#: ``{sec, nsec}`` of ``RMW_DURATION_INFINITE`` as rosbag2 records it from the graph.
INFINITE_DURATION = {'sec': 9223372036, 'nsec': 854775807}
_MAGIC = b'\x89MCAP0\r\n'
_U64 = 2**64
_LIBRARY = f'gyro_rotor.bagio {__version__}; mcap-python {mcap.__version__}'
_METADATA_YAML = 'metadata.yaml'
# Policy names indexed by their rmw enum value (rmw/types.h; names of rmw_qos_*_to_str).
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
_COMPRESSION = {'none': CompressionType.NONE, 'zstd': CompressionType.ZSTD,
                'lz4': CompressionType.LZ4}


class BagWarning(UserWarning):
    """A bag was read only partly (truncated) or without its ``metadata.yaml``."""


# --------------------------------------------------------------------------------------------
# QoS


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


def _qos_yaml(profiles: list[dict[str, Any]]) -> str:
    """Dump QoS profiles to the YAML string of the MCAP channel metadata."""
    return yaml.safe_dump(profiles, default_flow_style=False, sort_keys=False)


# --------------------------------------------------------------------------------------------
# metadata.yaml


@dataclasses.dataclass
class _Topic:
    name: str
    type: str  # noqa: A003 (rosbag2 metadata.yaml key)
    qos: list[dict[str, Any]]
    hash: str  # noqa: A003 (rosbag2 metadata.yaml key)
    count: int = 0


def _bag_metadata(topics: Iterable[_Topic], file_name: str, start: int | None,
                  end: int | None, custom_data: Mapping[str, str] | None = None
                  ) -> dict[str, Any]:
    """Return the inner ``rosbag2_bagfile_information`` node (version 9)."""
    topics = list(topics)
    total = sum(t.count for t in topics)
    start_ns = start if (total and start is not None) else 0
    duration = (end - start) if (total and start is not None and end is not None) else 0
    return {
        'version': METADATA_VERSION,
        'storage_identifier': 'mcap',
        'duration': {'nanoseconds': duration},
        'starting_time': {'nanoseconds_since_epoch': start_ns},
        'message_count': total,
        'topics_with_message_count': [
            {'topic_metadata': {'name': t.name, 'type': t.type, 'serialization_format': 'cdr',
                                'offered_qos_profiles': t.qos,
                                'type_description_hash': t.hash},
             'message_count': t.count}
            for t in topics
        ],
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [file_name],
        'files': [{'path': file_name,
                   'starting_time': {'nanoseconds_since_epoch': start_ns},
                   'duration': {'nanoseconds': duration},
                   'message_count': total}],
        'custom_data': dict(custom_data or {}),
        'ros_distro': 'jazzy',
    }


def _write_metadata_yaml(directory: Path, info: dict[str, Any]) -> None:
    """Write ``metadata.yaml`` atomically (temporary file, then ``os.replace``)."""
    target = directory / _METADATA_YAML
    tmp = directory / f'.{_METADATA_YAML}.tmp'
    text = yaml.safe_dump({'rosbag2_bagfile_information': info}, sort_keys=False,
                          default_flow_style=False)
    try:
        with open(tmp, 'w', encoding='utf-8') as stream:
            stream.write(text)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(tmp, target)
    except OSError as err:
        raise BagError(f'cannot write {target}: {err.strerror or err}') from err


# --------------------------------------------------------------------------------------------
# Writer


class BagWriter:
    """Write a rosbag2 directory with one MCAP file, as ``ros2 bag record`` on Jazzy.

    Parameters
    ----------
    path : str or Path
        The bag directory. It must not exist; its parent is created if needed.
    chunk_size : int
        Uncompressed chunk size in bytes at which the MCAP writer ends a chunk.
    flush_interval_s : float
        A write that arrives this long after the first message of the current chunk ends the
        chunk and flushes it to the file, so a killed process loses at most about this much.
    fsync : bool
        Also ``os.fsync`` the file at each flush (power-loss safety; not needed for SIGKILL).
    compression : {'none', 'zstd', 'lz4'}
        Chunk compression (rosbag2's default is none).
    metadata : dict of str to dict of str to str, optional
        MCAP metadata records to write at open (``name -> {key: value}``).

    Raises
    ------
    BagError
        If the path exists already, or the directory or the files cannot be created or
        written (permissions, a regular file as parent, a full disk).

    Examples
    --------
    >>> with BagWriter('/tmp/run1') as bag:                         # doctest: +SKIP
    ...     bag.add_topic('/joint_states', 'sensor_msgs/msg/JointState', qos_profile_dict())
    ...     bag.write('/joint_states', serialize_message(msg), time.time_ns())
    """

    def __init__(self, path: str | os.PathLike[str], *, chunk_size: int = 1024 * 1024,
                 flush_interval_s: float = 1.0, fsync: bool = False,
                 compression: str = 'none',
                 metadata: Mapping[str, Mapping[str, str]] | None = None) -> None:
        if compression not in _COMPRESSION:
            raise BagError(f'unknown compression {compression!r}; expected one of '
                           f'{sorted(_COMPRESSION)}')
        if not flush_interval_s > 0:
            raise BagError(f'flush_interval_s must be > 0, got {flush_interval_s!r}')
        self.path = Path(path)
        self.mcap_path = self.path / f'{self.path.name}_0.mcap'
        self.flush_interval_s = float(flush_interval_s)
        self.fsync = bool(fsync)
        self._topics: dict[str, _Topic] = {}
        self._channels: dict[str, int] = {}
        self._schemas: dict[str, int] = {}
        self._sequence: dict[str, int] = {}
        self._start: int | None = None
        self._end: int | None = None
        self._chunk_t0: float | None = None
        self._closed = False

        if self.path.exists() or self.path.is_symlink():
            raise BagError(f'{self.path} exists already, not overwriting')
        try:
            self.path.mkdir(parents=True)
        except FileExistsError as err:
            raise BagError(f'{self.path} exists already, not overwriting') from err
        except OSError as err:
            raise BagError(f'cannot create bag directory {self.path}: '
                           f'{err.strerror or err}') from err
        try:
            self._stream = open(self.mcap_path, 'xb')
        except OSError as err:
            self._remove_empty_dir()
            raise BagError(f'cannot create {self.mcap_path}: {err.strerror or err}') from err
        try:
            self._writer = Writer(self._stream, chunk_size=chunk_size,
                                  compression=_COMPRESSION[compression])
            self._writer.start(profile='ros2', library=_LIBRARY)
            for name, data in (metadata or {}).items():
                self._writer.add_metadata(name, dict(data))
            self._writer.flush()
            os.fsync(self._stream.fileno())
            self._write_metadata_yaml()
        except (OSError, BagError) as err:
            self._closed = True
            self._stream.close()
            raise BagError(f'cannot write bag {self.path}: '
                           f'{getattr(err, "strerror", None) or err}') from err

    def _remove_empty_dir(self) -> None:
        try:
            self.path.rmdir()
        except OSError:
            pass

    # -- context manager ------------------------------------------------------------------

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        state = 'closed' if self._closed else 'open'
        return f'<BagWriter {str(self.path)!r} {state}, {self.message_count} messages>'

    # -- state ----------------------------------------------------------------------------

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` has run."""
        return self._closed

    @property
    def message_counts(self) -> dict[str, int]:
        """Messages written so far, per topic."""
        return {name: t.count for name, t in self._topics.items()}

    @property
    def message_count(self) -> int:
        """Messages written so far, all topics."""
        return sum(t.count for t in self._topics.values())

    def _check_open(self, what: str) -> None:
        if self._closed:
            raise BagError(f'cannot {what}: bag {self.path} is closed')

    # -- writing --------------------------------------------------------------------------

    def add_topic(self, topic: str, type_name: str, qos: Any = None, *,
                  definition: str | None = None, topic_type_hash: str | None = None) -> int:
        """Register a topic (schema and channel) and return its channel id.

        Parameters
        ----------
        topic : str
            Topic name, e.g. ``'/joint_states'``.
        type_name : str
            ``'sensor_msgs/msg/JointState'`` (``'sensor_msgs/JointState'`` is accepted).
        qos : dict, QoS profile, list of these, or None
            The offered QoS profiles (see :func:`normalize_qos`); ``None`` is the default
            profile (keep_last 10, reliable, volatile).
        definition, topic_type_hash : str, optional
            Override the definition text and hash read from the installed share files.

        Returns
        -------
        int
            The MCAP channel id. Adding the same topic with the same type again returns it.

        Raises
        ------
        BagError
            If the bag is closed, the topic exists with another type, the type is unknown or
            the QoS is invalid.
        """
        self._check_open(f'add topic {topic!r}')
        if not isinstance(topic, str) or not topic:
            raise BagError(f'invalid topic name {topic!r}')
        type_name = normalize_type_name(type_name)
        if topic in self._topics:
            if self._topics[topic].type != type_name:
                raise BagError(f'topic {topic!r} is already in {self.path} with type '
                               f'{self._topics[topic].type}, not {type_name}')
            return self._channels[topic]
        profiles = normalize_qos(qos)
        text = message_definition(type_name) if definition is None else definition
        digest = type_hash(type_name) if topic_type_hash is None else topic_type_hash
        schema_id = self._schemas.get(type_name)
        if schema_id is None:
            schema_id = self._writer.register_schema(type_name, 'ros2msg', text.encode())
            self._schemas[type_name] = schema_id
        channel_id = self._writer.register_channel(
            topic, 'cdr', schema_id,
            metadata={'offered_qos_profiles': _qos_yaml(profiles), 'topic_type_hash': digest})
        self._topics[topic] = _Topic(topic, type_name, profiles, digest)
        self._channels[topic] = channel_id
        self._sequence[topic] = 0
        self._write_metadata_yaml()
        return channel_id

    def write(self, topic: str, data: bytes | bytearray | memoryview, log_time_ns: int,
              publish_time_ns: int | None = None) -> None:
        """Store one serialized (CDR) message unchanged.

        Parameters
        ----------
        topic : str
            A topic registered with :meth:`add_topic`.
        data : bytes-like
            The serialized message, including the 4-byte CDR encapsulation header.
        log_time_ns : int
            Receive time in ns since the epoch (MCAP ``log_time``).
        publish_time_ns : int, optional
            Send time in ns (MCAP ``publish_time``); defaults to ``log_time_ns``.

        Raises
        ------
        BagError
            If the bag is closed, the topic unknown, a time invalid or the file unwritable.
        """
        # the recorder's hot path (1000s of messages per second): plain ints and bytes pass
        # with two comparisons; anything else is checked by _time_ns and converted
        if self._closed:
            self._check_open(f'write to {topic!r}')
        channel_id = self._channels.get(topic)
        if channel_id is None:
            raise BagError(f'unknown topic {topic!r} in {self.path}; call add_topic() first')
        log_time = (log_time_ns if type(log_time_ns) is int and 0 <= log_time_ns < _U64
                    else _time_ns('log_time_ns', log_time_ns))
        if publish_time_ns is None:
            publish_time = log_time
        elif type(publish_time_ns) is int and 0 <= publish_time_ns < _U64:
            publish_time = publish_time_ns
        else:
            publish_time = _time_ns('publish_time_ns', publish_time_ns)
        if type(data) is not bytes:
            if not isinstance(data, (bytearray, memoryview)):
                raise BagError(f'data for {topic!r} must be bytes, not {type(data).__name__}')
            data = bytes(data)
        seq = self._sequence[topic] + 1
        self._sequence[topic] = seq
        try:
            self._writer.add_message(channel_id, log_time, data, publish_time, sequence=seq)
        except OSError as err:
            raise BagError(f'cannot write to {self.mcap_path}: {err.strerror or err}') from err
        self._topics[topic].count += 1
        if self._start is None or log_time < self._start:
            self._start = log_time
        if self._end is None or log_time > self._end:
            self._end = log_time
        now = time.monotonic()
        if self._chunk_t0 is None:
            self._chunk_t0 = now
        elif now - self._chunk_t0 >= self.flush_interval_s:
            self.flush()

    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Write an MCAP metadata record ``name`` with string keys and values."""
        self._check_open(f'add metadata {name!r}')
        if not all(isinstance(k, str) and isinstance(v, str) for k, v in data.items()):
            raise BagError(f'metadata {name!r}: keys and values must be str')
        try:
            self._writer.add_metadata(name, dict(data))
        except OSError as err:
            raise BagError(f'cannot write to {self.mcap_path}: {err.strerror or err}') from err

    def flush(self) -> None:
        """End the current chunk and write everything buffered to the file (and fsync)."""
        self._check_open('flush')
        try:
            self._writer.flush()
            if self.fsync:
                os.fsync(self._stream.fileno())
        except OSError as err:
            raise BagError(f'cannot write to {self.mcap_path}: {err.strerror or err}') from err
        self._chunk_t0 = None

    def _write_metadata_yaml(self) -> None:
        _write_metadata_yaml(self.path, self._info())

    def _info(self) -> dict[str, Any]:
        return _bag_metadata(self._topics.values(), self.mcap_path.name, self._start,
                             self._end)

    def close(self) -> None:
        """Write the summary and footer, close the file and write the final metadata.yaml.

        Idempotent: later calls do nothing.
        """
        if self._closed:
            return
        self._closed = True
        try:
            try:
                info = self._info()
                self._writer.add_metadata(
                    'rosbag2', {'serialized_metadata': yaml.safe_dump(info, sort_keys=False)})
                self._writer.finish()
                self._stream.flush()
                os.fsync(self._stream.fileno())
            finally:
                self._stream.close()
        except OSError as err:
            raise BagError(f'cannot finish {self.mcap_path}: {err.strerror or err}') from err
        self._write_metadata_yaml()

    finish = close


def _time_ns(name: str, value: Any) -> int:
    if isinstance(value, bool) or not hasattr(value, '__index__'):
        raise BagError(f'{name} must be integer nanoseconds, got {value!r}')
    value = int(value)
    if not 0 <= value < 2**64:
        raise BagError(f'{name} out of range: {value}')
    return value


# --------------------------------------------------------------------------------------------
# Reading


class TopicInfo(NamedTuple):
    """Type and message count of one topic in a bag."""

    type: str  # noqa: A003 (public field name, as in rosbag2's metadata)
    count: int


@dataclasses.dataclass
class _FileData:
    """What could be read from one MCAP file."""

    path: Path
    profile: str = ''
    library: str = ''
    schemas: dict[int, Schema] = dataclasses.field(default_factory=dict)
    channels: dict[int, Channel] = dataclasses.field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = dataclasses.field(default_factory=dict)
    counts: dict[int, int] = dataclasses.field(default_factory=dict)
    start: int | None = None
    end: int | None = None
    indexed: bool = False
    truncated: bool = False
    problem: str = ''
    messages: list[Message] | None = None   # set when the file was scanned, not indexed


_RECORDS = {0x01: Header, 0x03: Schema, 0x04: Channel, 0x06: Chunk, 0x0C: Metadata,
            0x02: Footer}


def _read_file(path: Path) -> _FileData:
    """Read the summary of an MCAP file, or scan it from the start if it has none."""
    data = _FileData(path)
    try:
        size = path.stat().st_size
        with open(path, 'rb') as stream:
            head = stream.read(len(_MAGIC))
            if not head:
                raise BagError(f'{path}: empty file, not an MCAP file')
            if head != _MAGIC[:len(head)]:
                raise BagError(f'{path}: not an MCAP file (magic {head[:8]!r})')
            if len(head) < len(_MAGIC):
                raise BagError(f'{path}: truncated inside the MCAP magic, nothing to read')
            if _read_indexed(stream, size, data):
                return data
            _scan(stream, size, data)
    except OSError as err:
        raise BagError(f'cannot read {path}: {err.strerror or err}') from err
    return data


def _read_indexed(stream: io.BufferedReader, size: int, data: _FileData) -> bool:
    """Fill ``data`` from the summary section; return False if the file has none."""
    if size < 2 * len(_MAGIC) + 29:
        return False
    stream.seek(-len(_MAGIC), io.SEEK_END)
    if stream.read(len(_MAGIC)) != _MAGIC:
        return False
    try:
        reader = SeekingReader(stream, record_size_limit=size)
        summary = reader.get_summary()
        if summary is None or summary.statistics is None:
            return False
        header = reader.get_header()
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
    except Exception:  # any damage: fall back to the sequential scan
        return False
    data.profile, data.library = header.profile, header.library
    data.schemas = dict(summary.schemas)
    data.channels = dict(summary.channels)
    data.metadata = metadata
    data.counts = dict(summary.statistics.channel_message_counts)
    if summary.statistics.message_count:
        data.start = summary.statistics.message_start_time
        data.end = summary.statistics.message_end_time
    data.indexed = True
    return True


def _scan(stream: io.BufferedReader, size: int, data: _FileData) -> None:
    """Read records one by one from the start; stop at the first incomplete or bad one."""
    data.messages = []
    offset = len(_MAGIC)
    stream.seek(offset)
    complete = False
    while True:
        head = stream.read(9)
        if len(head) < 9:
            data.problem = (f'no footer: the file ends at byte {size}'
                            + (' inside a record header' if head else ''))
            break
        opcode, length = struct.unpack('<BQ', head)
        if length > size - offset - 9:
            data.problem = (f'no footer: record at byte {offset} (opcode 0x{opcode:02x}, '
                            f'{length} bytes) is cut off at byte {size}')
            break
        body = stream.read(length)
        try:
            if opcode == 0x05:
                records: list[Any] = [Message.read(ReadDataStream(io.BytesIO(body)), length)]
            elif opcode in _RECORDS:
                record = _RECORDS[opcode].read(ReadDataStream(io.BytesIO(body)))
                records = (breakup_chunk(record, validate_crc=True)
                           if isinstance(record, Chunk) else [record])
            else:
                records = []
        except Exception as err:  # malformed record: keep what was read
            data.problem = (f'malformed record at byte {offset} (opcode 0x{opcode:02x}): '
                            f'{type(err).__name__}: {err}')
            break
        offset += 9 + length
        if any(isinstance(r, Footer) for r in records):
            complete = stream.read(len(_MAGIC)) == _MAGIC
            if not complete:
                data.problem = 'footer is not followed by the MCAP magic'
            break
        _take(records, data)
    data.truncated = not complete


def _take(records: list[Any], data: _FileData) -> None:
    for record in records:
        if isinstance(record, Message):
            if record.channel_id in data.channels:
                data.messages.append(record)
                data.counts[record.channel_id] = data.counts.get(record.channel_id, 0) + 1
                t = record.log_time
                data.start = t if data.start is None else min(data.start, t)
                data.end = t if data.end is None else max(data.end, t)
        elif isinstance(record, Channel):
            data.channels.setdefault(record.id, record)
        elif isinstance(record, Schema):
            data.schemas.setdefault(record.id, record)
        elif isinstance(record, Metadata):
            data.metadata[record.name] = dict(record.metadata)
        elif isinstance(record, Header):
            data.profile, data.library = record.profile, record.library


def _load_metadata_yaml(path: Path) -> tuple[dict[str, Any] | None, str]:
    """Return the inner node of ``metadata.yaml`` (or None) and a problem description."""
    try:
        doc = yaml.safe_load(path.read_text(encoding='utf-8'))
        info = doc['rosbag2_bagfile_information']
        if not isinstance(info, dict):
            raise TypeError('not a mapping')
        return info, ''
    except (OSError, UnicodeDecodeError, yaml.YAMLError, KeyError, TypeError) as err:
        return None, f'{path} is unreadable ({type(err).__name__}: {err})'


def _bag_files(path: Path) -> tuple[list[Path], dict[str, Any] | None, list[str]]:
    """Return the MCAP files of a bag path, its metadata.yaml node and problems."""
    if not path.exists():
        raise BagError(f'{path}: no such bag (neither a directory nor a file)')
    if not path.is_dir():
        return [path], None, []
    problems: list[str] = []
    info: dict[str, Any] | None = None
    files: list[Path] = []
    meta_path = path / _METADATA_YAML
    if meta_path.is_file():
        info, problem = _load_metadata_yaml(meta_path)
        if problem:
            problems.append(problem + '; reading the .mcap files directly')
    else:
        problems.append(f'{meta_path} is missing; reading the .mcap files directly')
    if info is not None:
        storage = info.get('storage_identifier', 'mcap')
        if storage != 'mcap':
            raise BagError(f'{path}: storage {storage!r} is not supported, only mcap')
        listed = info.get('relative_file_paths') or []
        files = [path / Path(str(name)).name for name in listed]
        missing = [str(f) for f in files if not f.is_file()]
        if missing:
            raise BagError(f'{path}: files listed in metadata.yaml are missing: {missing}')
    if not files:
        files = sorted(p for p in path.glob('*.mcap') if p.is_file())
    if not files:
        raise BagError(f'{path}: no .mcap file in the bag directory')
    return files, info, problems


class BagReader:
    """Read a rosbag2 MCAP bag (directory or bare ``.mcap`` file); see :func:`open_bag`.

    Attributes
    ----------
    path : Path
        The path given.
    files : list of Path
        The MCAP files read.
    topics : dict of str to TopicInfo
        ``topic -> (type, count)`` from the MCAP data (not from ``metadata.yaml``).
    metadata : dict of str to dict
        The MCAP metadata records, ``name -> {key: value}``.
    channel_metadata : dict of str to dict
        The channel metadata per topic (``offered_qos_profiles``, ``topic_type_hash``).
    bag_metadata : dict or None
        The ``rosbag2_bagfile_information`` node of ``metadata.yaml``, if readable.
    truncated : bool
        True if some file had no valid footer and only its readable prefix is used.
    problems : list of str
        What was wrong (also emitted as :class:`BagWarning`).
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.files, self.bag_metadata, self.problems = _bag_files(self.path)
        self._data = [_read_file(f) for f in self.files]
        for data in self._data:
            if data.truncated:
                n = len(data.messages or [])
                self.problems.append(f'{data.path} is truncated ({data.problem}); '
                                     f'{n} messages are readable')
            elif data.profile != 'ros2':
                self.problems.append(f'{data.path}: MCAP profile is {data.profile!r}, '
                                     "not 'ros2'")
        self.truncated = any(d.truncated for d in self._data)
        topics: dict[str, TopicInfo] = {}
        self.channel_metadata: dict[str, dict[str, str]] = {}
        self.metadata: dict[str, dict[str, str]] = {}
        for data in self._data:
            self.metadata.update(data.metadata)
            for cid, channel in data.channels.items():
                schema = data.schemas.get(channel.schema_id)
                type_name = schema.name if schema is not None else ''
                old = topics.get(channel.topic, TopicInfo(type_name, 0))
                topics[channel.topic] = TopicInfo(old.type or type_name,
                                                  old.count + data.counts.get(cid, 0))
                self.channel_metadata.setdefault(channel.topic, dict(channel.metadata))
        self.topics = topics
        for problem in self.problems:
            warnings.warn(problem, BagWarning, stacklevel=3)

    def __enter__(self) -> BagReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Release the messages read from damaged files (files are opened per iteration)."""
        for data in self._data:
            if data.messages is not None:
                data.messages = []

    def __repr__(self) -> str:
        flag = ', truncated' if self.truncated else ''
        return f'<BagReader {str(self.path)!r}: {self.message_count} messages{flag}>'

    @property
    def message_count(self) -> int:
        """Return the number of readable messages."""
        return sum(t.count for t in self.topics.values())

    def _iter_file(self, index: int, topics: set[str] | None
                   ) -> Iterator[tuple[int, int, int, Channel, Schema | None, Message]]:
        data = self._data[index]
        wanted = {cid for cid, ch in data.channels.items()
                  if topics is None or ch.topic in topics}
        if not data.indexed:
            order = sorted(range(len(data.messages or [])),
                           key=lambda i: data.messages[i].log_time)
            for i in order:
                msg = data.messages[i]
                if msg.channel_id in wanted:
                    channel = data.channels[msg.channel_id]
                    yield (msg.log_time, index, i, channel,
                           data.schemas.get(channel.schema_id), msg)
            return
        if not wanted:
            return
        try:
            with open(data.path, 'rb') as stream:
                reader = SeekingReader(stream, record_size_limit=stream.seek(0, io.SEEK_END))
                names = sorted({data.channels[c].topic for c in wanted})
                for i, (schema, channel, msg) in enumerate(
                        reader.iter_messages(topics=names, log_time_order=True)):
                    yield msg.log_time, index, i, channel, schema, msg
        except (OSError, McapError, ValueError, KeyError, struct.error, EOFError) as err:
            raise BagError(f'cannot read messages from {data.path}: '
                           f'{type(err).__name__}: {err}') from err

    def _iter(self, topics: str | Iterable[str] | None
              ) -> Iterator[tuple[int, int, int, Channel, Schema | None, Message]]:
        wanted = None if topics is None else ({topics} if isinstance(topics, str)
                                              else set(topics))
        streams = [self._iter_file(i, wanted) for i in range(len(self._data))]
        if len(streams) == 1:
            return streams[0]
        return heapq.merge(*streams, key=lambda item: (item[0], item[1], item[2]))

    def messages(self, topics: str | Iterable[str] | None = None
                 ) -> Iterator[tuple[str, int, bytes]]:
        """Yield ``(topic, log_time_ns, data)`` in log-time order, data as serialized CDR.

        Parameters
        ----------
        topics : str or iterable of str, optional
            Only these topics (names not in the bag yield nothing); all if None.
        """
        for log_time, _, _, channel, _, msg in self._iter(topics):
            yield channel.topic, log_time, msg.data

    def decoded(self, topics: str | Iterable[str] | None = None
                ) -> Iterator[tuple[str, int, Any]]:
        """Yield ``(topic, log_time_ns, message)`` decoded with the ``mcap_ros2`` decoder.

        The message objects are the decoder's dynamic classes with the fields of the
        definition stored in the bag; no rclpy is needed.

        Raises
        ------
        BagError
            If a topic has no ``ros2msg`` schema or a message cannot be decoded.
        """
        from mcap_ros2.decoder import DecoderFactory

        factories = [DecoderFactory() for _ in self._data]
        for log_time, index, _, channel, schema, msg in self._iter(topics):
            try:
                decoder = factories[index].decoder_for(channel.message_encoding, schema)
            except Exception as err:  # the decoder raises various types
                raise BagError(f'{self.files[index]}: cannot build a decoder for '
                               f'{channel.topic!r}: {err}') from err
            if decoder is None:
                raise BagError(f'{self.files[index]}: topic {channel.topic!r} has no ros2msg '
                               'schema with cdr encoding, cannot decode')
            try:
                yield channel.topic, log_time, decoder(msg.data)
            except Exception as err:  # the decoder raises various types
                raise BagError(f'{self.files[index]}: cannot decode message on '
                               f'{channel.topic!r} at {log_time}: {err}') from err


def open_bag(path: str | os.PathLike[str]) -> BagReader:
    """Open a bag directory or a bare ``.mcap`` file for reading.

    Raises
    ------
    BagError
        For a missing path, an empty directory, a non-MCAP file, a file cut inside its magic,
        or unsupported storage. Truncated files are read up to the damage and flagged with
        ``truncated`` and a :class:`BagWarning` instead.
    """
    return BagReader(path)


# --------------------------------------------------------------------------------------------
# Recovery


@dataclasses.dataclass(frozen=True)
class RecoveryReport:
    """The outcome of :func:`recover_bag`."""

    path: Path
    messages_per_topic: dict[str, int]
    rewritten: tuple[Path, ...]
    originals: tuple[Path, ...]
    metadata_rewritten: bool
    problems: tuple[str, ...]

    @property
    def message_count(self) -> int:
        """Messages in the recovered bag."""
        return sum(self.messages_per_topic.values())

    @property
    def was_damaged(self) -> bool:
        """Whether some MCAP file had to be rewritten."""
        return bool(self.rewritten)


def _rewrite(data: _FileData, target: Path) -> None:
    """Write the readable content of a scanned file into a complete MCAP file."""
    with open(target, 'xb') as stream:
        writer = Writer(stream, compression=CompressionType.NONE)
        library = f'{data.library}; recovered by {_LIBRARY}' if data.library else _LIBRARY
        writer.start(profile=data.profile or 'ros2', library=library)
        schema_ids = {sid: writer.register_schema(s.name, s.encoding, s.data)
                      for sid, s in sorted(data.schemas.items())}
        channel_ids = {cid: writer.register_channel(c.topic, c.message_encoding,
                                                    schema_ids.get(c.schema_id, 0),
                                                    metadata=dict(c.metadata))
                       for cid, c in sorted(data.channels.items())}
        for name, meta in data.metadata.items():
            if name != 'rosbag2':
                writer.add_metadata(name, meta)
        for msg in data.messages or []:
            writer.add_message(channel_ids[msg.channel_id], msg.log_time, msg.data,
                               msg.publish_time, sequence=msg.sequence)
        info = _bag_metadata(_topics_of(data), target.name, data.start, data.end)
        writer.add_metadata('rosbag2',
                            {'serialized_metadata': yaml.safe_dump(info, sort_keys=False)})
        writer.finish()
        stream.flush()
        os.fsync(stream.fileno())


def _topics_of(data: _FileData) -> list[_Topic]:
    """Return the topics of a file with QoS, hash and message counts from its channels."""
    topics: dict[str, _Topic] = {}
    for cid, channel in sorted(data.channels.items()):
        schema = data.schemas.get(channel.schema_id)
        try:
            profiles = normalize_qos(yaml.safe_load(channel.metadata.get(
                'offered_qos_profiles', '[]')) or [])
        except (BagError, yaml.YAMLError, TypeError):
            profiles = []
        topic = topics.setdefault(channel.topic, _Topic(
            channel.topic, schema.name if schema else '', profiles,
            channel.metadata.get('topic_type_hash', '')))
        topic.count += data.counts.get(cid, 0)
    return list(topics.values())


def recover_bag(path: str | os.PathLike[str]) -> RecoveryReport:
    """Make a bag whose writer was killed readable by every reader again.

    Each MCAP file without a valid summary and footer is scanned, every readable message is
    copied into a new, complete file of the same name (with summary, statistics and a
    ``rosbag2`` metadata record), and the damaged original is kept as ``<name>.mcap.orig``.
    For a bag directory, ``metadata.yaml`` is then rewritten with the real counts (the old one
    is kept as ``metadata.yaml.orig``). Complete files are left alone, so recovering twice is
    harmless. Nothing is ever deleted.

    Raises
    ------
    BagError
        If the bag cannot be read at all, or a ``.orig`` file exists already.
    """
    path = Path(path)
    files, info, problems = _bag_files(path)
    rewritten: list[Path] = []
    originals: list[Path] = []
    all_topics: dict[str, _Topic] = {}
    entries: list[dict[str, Any]] = []
    for file in files:
        data = _read_file(file)
        if data.truncated:
            problems.append(f'{file}: {data.problem}')
            orig = file.with_name(file.name + '.orig')
            tmp = file.with_name(file.name + '.recovering')
            for existing in (orig, tmp):
                if existing.exists():
                    raise BagError(f'cannot recover {file}: {existing} exists already, '
                                   'not overwriting')
            try:
                _rewrite(data, tmp)
                os.replace(file, orig)
                os.replace(tmp, file)
            except OSError as err:
                raise BagError(f'cannot recover {file}: {err.strerror or err}') from err
            rewritten.append(file)
            originals.append(orig)
            data = _read_file(file)
        topics = _topics_of(data)
        for topic in topics:
            known = all_topics.setdefault(topic.name, dataclasses.replace(topic, count=0))
            known.count += topic.count
        entries.append(_bag_metadata(topics, file.name, data.start, data.end)['files'][0])
    counts = {name: t.count for name, t in all_topics.items()}
    metadata_rewritten = False
    if path.is_dir():
        starts = [e['starting_time']['nanoseconds_since_epoch'] for e in entries
                  if e['message_count']]
        ends = [e['starting_time']['nanoseconds_since_epoch'] + e['duration']['nanoseconds']
                for e in entries if e['message_count']]
        custom = (info or {}).get('custom_data') or {}
        new_info = _bag_metadata(all_topics.values(), files[0].name,
                                 min(starts) if starts else None,
                                 max(ends) if ends else None,
                                 custom if isinstance(custom, dict) else {})
        new_info['relative_file_paths'] = [f.name for f in files]
        new_info['files'] = entries
        if new_info != info:
            meta_path = path / _METADATA_YAML
            backup = path / f'{_METADATA_YAML}.orig'
            if meta_path.exists() and not backup.exists():
                try:
                    os.replace(meta_path, backup)
                except OSError as err:
                    raise BagError(f'cannot back up {meta_path}: {err.strerror}') from err
            _write_metadata_yaml(path, new_info)
            metadata_rewritten = True
    return RecoveryReport(path, counts, tuple(rewritten), tuple(originals),
                          metadata_rewritten, tuple(problems))
