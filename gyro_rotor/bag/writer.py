"""The bag writer: a rosbag2 directory with one MCAP file, as ``ros2 bag record`` on Jazzy.

See :mod:`gyro_rotor.bag.bagio` for the format decisions (records, flushing).
"""

from __future__ import annotations

from collections.abc import Mapping
import contextlib
import os
from pathlib import Path
import time
from typing import Any

from gyro_rotor.bag.metadata import (_bag_metadata, _Topic, _write_metadata_yaml, LIBRARY,
                                     ROSBAG2_RECORD)
from gyro_rotor.bag.msgdefs import message_definition, normalize_type_name, type_hash
from gyro_rotor.bag.qos import normalize_qos, qos_yaml
from gyro_rotor.errors import BagError
from mcap.writer import CompressionType, Writer
import yaml

__all__ = ['BagWriter']

_U64 = 2**64
_COMPRESSION = {'none': CompressionType.NONE, 'zstd': CompressionType.ZSTD,
                'lz4': CompressionType.LZ4}


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
            self._writer.start(profile='ros2', library=LIBRARY)
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
        with contextlib.suppress(OSError):
            self.path.rmdir()

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
            metadata={'offered_qos_profiles': qos_yaml(profiles), 'topic_type_hash': digest})
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
                    ROSBAG2_RECORD,
                    {'serialized_metadata': yaml.safe_dump(info, sort_keys=False)})
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
