"""The bag reader: rosbag2 MCAP bags (directory or bare ``.mcap``), damaged ones too.

A file without a valid footer and summary (a killed writer, a cut copy) is read record by
record from the start; every complete record is used, the first incomplete or malformed one
ends the scan. The reader then sets ``truncated`` and warns with :class:`BagWarning`.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
import dataclasses
import heapq
import io
import os
from pathlib import Path
import struct
from typing import Any, NamedTuple
import warnings

from gyro_rotor.bag.metadata import BagWarning, load_metadata_yaml, MAGIC, METADATA_YAML
from gyro_rotor.errors import BagError
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.reader import SeekingReader
from mcap.records import Channel, Chunk, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import breakup_chunk

__all__ = ['BagReader', 'TopicInfo', 'open_bag']

_MAGIC = MAGIC


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


def _bag_files(path: Path) -> tuple[list[Path], dict[str, Any] | None, list[str]]:
    """Return the MCAP files of a bag path, its metadata.yaml node and problems."""
    if not path.exists():
        raise BagError(f'{path}: no such bag (neither a directory nor a file)')
    if not path.is_dir():
        return [path], None, []
    problems: list[str] = []
    info: dict[str, Any] | None = None
    files: list[Path] = []
    meta_path = path / METADATA_YAML
    if meta_path.is_file():
        info, problem = load_metadata_yaml(meta_path)
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
