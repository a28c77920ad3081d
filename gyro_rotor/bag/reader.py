"""The bag reader: rosbag2 MCAP bags (directory or bare ``.mcap``), damaged ones too.

Each file is read by :func:`gyro_rotor.bag.mcapfile.read_mcap`: the messages of every intact
chunk are kept, also after a damaged one (the chunk index when the summary holds,
resynchronisation on record boundaries otherwise), and what was lost is counted per topic
against the counts the bag recorded (the MCAP statistics, else the ``rosbag2`` metadata
record, else ``metadata.yaml``). A bag recovered by :func:`gyro_rotor.bag.recovery.recover_bag`
carries its losses in the metadata record ``gyro_rotor.recovery``, so they stay known. Any
damage sets :attr:`BagReader.damaged` and warns with :class:`BagWarning`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
import heapq
import json
import os
from pathlib import Path
from typing import Any, NamedTuple
import warnings

from gyro_rotor.bag.mcapfile import iter_messages, McapContents, read_mcap
from gyro_rotor.bag.metadata import (BagWarning, load_metadata_yaml, METADATA_YAML,
                                     ROSBAG2_RECORD)
from gyro_rotor.errors import BagError
from mcap.records import Channel, Message, Schema

__all__ = ['BagReader', 'TopicInfo', 'open_bag', 'RECOVERY_RECORD']

#: the metadata record in which recover_bag keeps what the damaged original lost
RECOVERY_RECORD = 'gyro_rotor.recovery'


class TopicInfo(NamedTuple):
    """Type and message count of one topic in a bag."""

    type: str  # noqa: A003 (public field name, as in rosbag2's metadata)
    count: int


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
        # as rosbag2, only the listed files are read; one that is not is named, not ignored
        # in silence (a copy of a file beside it would double every message if it were read)
        unlisted = sorted(p.name for p in path.glob('*.mcap') if p.is_file() and p not in files)
        if files and unlisted:
            problems.append(f'{path}: {", ".join(unlisted)} not listed in metadata.yaml: '
                            'not read (as rosbag2 reads a bag)')
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
        ``topic -> (type, count)`` of the readable messages (not from ``metadata.yaml``).
    metadata : dict of str to dict
        The MCAP metadata records, ``name -> {key: value}``.
    channel_metadata : dict of str to dict
        The channel metadata per topic (``offered_qos_profiles``, ``topic_type_hash``).
    bag_metadata : dict or None
        The ``rosbag2_bagfile_information`` node of ``metadata.yaml``, if readable.
    truncated : bool
        True if some file has no valid footer (cut short, or its end damaged).
    damaged : bool
        True if anything recorded could not be read (or was lost before a recovery).
    lost : dict of str to int
        Messages known lost per topic: recorded minus readable, where the bag recorded its
        counts; the damaged chunks' message indexes otherwise.
    unknown_loss : list of str
        Losses whose size nothing in the bag tells (a cut file without recorded counts).
    lost_records : list of str
        Metadata records lost with the end of a file that was cut short (not messages: the
        samples may all be there, but e.g. the live verdict is not).
    problems : list of str
        What was wrong (also emitted as :class:`BagWarning`).
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.files, self.bag_metadata, self.problems = _bag_files(self.path)
        self._data: list[McapContents] = [read_mcap(f) for f in self.files]
        self.lost: dict[str, int] = {}
        self.unknown_loss: list[str] = []
        self.lost_records: list[str] = []
        recorded_yaml = _yaml_counts(self.bag_metadata) if len(self._data) == 1 else None
        for data in self._data:
            for problem in data.problems:
                self.problems.append(f'{data.path}: {problem}')
            if data.profile != 'ros2' and data.profile:
                self.problems.append(f'{data.path}: MCAP profile is {data.profile!r}, '
                                     "not 'ros2'")
            self._file_losses(data, recorded_yaml)
        self.truncated = any(not d.complete for d in self._data)
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
        self._recovered_losses()
        self.lost = {t: n for t, n in sorted(self.lost.items()) if n}
        self.damaged = bool(self.truncated or self.lost or self.unknown_loss
                            or self.lost_records or any(d.damaged for d in self._data))
        if self.lost or self.unknown_loss or self.lost_records:
            self.problems.append(f'{self.path}: {self.loss_text()}')
        for problem in self.problems:
            warnings.warn(problem, BagWarning, stacklevel=3)

    def _file_losses(self, data: McapContents, recorded_yaml: dict[str, int] | None) -> None:
        """Add one file's losses by topic; use the bag's recorded counts where it has none."""
        def topic(cid: int) -> str:
            ch = data.channels.get(cid)
            return ch.topic if ch is not None else f'<channel {cid}>'

        if not data.complete and ROSBAG2_RECORD not in data.metadata:
            # the records a writer adds when it closes the file are not there: counts from
            # metadata.yaml may account for every message, but not for these
            self.lost_records.append(
                f'{data.path.name}: the metadata records written at its end (the '
                f'{ROSBAG2_RECORD!r} record, and the live verdict where one was recorded)')
        self.lost_records.extend(f'{data.path.name}: {r}' for r in data.lost_records)

        if data.recorded is None and (data.unknown_loss or data.lost):
            readable: dict[str, int] = {}
            for cid, n in data.counts.items():
                readable[topic(cid)] = readable.get(topic(cid), 0) + n
            rosbag2 = _yaml_counts(_rosbag2_record(data.metadata.get(ROSBAG2_RECORD)))
            for source, counts in (('the rosbag2 metadata record', rosbag2),
                                   ('metadata.yaml', recorded_yaml)):
                if counts and sum(counts.values()) and all(
                        counts.get(t, 0) >= n for t, n in readable.items()):
                    for t, n in counts.items():
                        if n > readable.get(t, 0):
                            self.lost[t] = self.lost.get(t, 0) + n - readable.get(t, 0)
                    self.problems.append(f'{data.path}: losses counted against {source}')
                    return
        for cid, n in data.lost.items():
            self.lost[topic(cid)] = self.lost.get(topic(cid), 0) + n
        for cid, n in data.orphans.items():
            self.lost[topic(cid)] = self.lost.get(topic(cid), 0) + n
        self.unknown_loss.extend(f'{data.path.name}: {u}' for u in data.unknown_loss)

    def _recovered_losses(self) -> None:
        """Add the losses a recovery recorded in the bag (``gyro_rotor.recovery``)."""
        record = self.metadata.get(RECOVERY_RECORD)
        if not record:
            return
        try:
            info = json.loads(record.get('json', '{}'))
            lost = {str(t): int(n) for t, n in dict(info.get('lost', {})).items()}
            unknown = [str(u) for u in info.get('unknown_loss', [])]
            records = [str(r) for r in info.get('lost_records', [])]
        except (ValueError, TypeError, AttributeError) as err:
            self.problems.append(f'{self.path}: the {RECOVERY_RECORD} record is unreadable '
                                 f'({err}): the bag was recovered, its losses are unknown')
            self.unknown_loss.append('before the recovery (record unreadable)')
            return
        for t, n in lost.items():
            self.lost[t] = self.lost.get(t, 0) + n
        self.unknown_loss.extend(f'before the recovery: {u}' for u in unknown)
        self.lost_records.extend(f'before the recovery: {r}' for r in records)
        self.problems.append(f'{self.path}: recovered from a damaged bag '
                             f'({record.get("summary", "")})')

    def loss_text(self) -> str:
        """One line: the messages lost per topic, the losses of unknown size, the records."""
        parts = []
        if self.lost:
            parts.append(f'{sum(self.lost.values())} recorded messages lost ('
                         + ', '.join(f'{t} {n}' for t, n in self.lost.items()) + ')')
        if self.unknown_loss:
            parts.append('loss of unknown size: ' + '; '.join(self.unknown_loss[:3])
                         + (f' and {len(self.unknown_loss) - 3} more'
                            if len(self.unknown_loss) > 3 else ''))
        if self.lost_records:
            parts.append('records lost: ' + '; '.join(self.lost_records))
        return '; '.join(parts) if parts else 'nothing lost'

    def __enter__(self) -> BagReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Release the messages held in memory (files are opened per iteration)."""
        for data in self._data:
            data.loose = []

    def __repr__(self) -> str:
        flag = ', truncated' if self.truncated else (', damaged' if self.damaged else '')
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
        if not wanted:
            return
        for i, msg in enumerate(iter_messages(data, wanted)):
            channel = data.channels[msg.channel_id]
            yield msg.log_time, index, i, channel, data.schemas.get(channel.schema_id), msg

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

    def decoded(self, topics: str | Iterable[str] | None = None,
                on_error: Callable[[str, BaseException], Any] | None = None
                ) -> Iterator[tuple[str, int, Any]]:
        """Yield ``(topic, log_time_ns, message)`` decoded with the ``mcap_ros2`` decoder.

        The message objects are the decoder's dynamic classes with the fields of the
        definition stored in the bag; no rclpy is needed.

        Parameters
        ----------
        topics : str or iterable of str, optional
            Only these topics; all if None.
        on_error : callable, optional
            ``on_error(topic, error)`` for a message that cannot be decoded, which is then
            skipped (the rest is read on); without it the error is raised.

        Raises
        ------
        BagError
            If a topic has no ``ros2msg`` schema or a message cannot be decoded (and no
            ``on_error`` was given).
        """
        from mcap_ros2.decoder import DecoderFactory

        factories = [DecoderFactory() for _ in self._data]
        for log_time, index, _, channel, schema, msg in self._iter(topics):
            try:
                try:
                    decoder = factories[index].decoder_for(channel.message_encoding, schema)
                except Exception as err:  # the decoder raises various types
                    raise BagError(f'{self.files[index]}: cannot build a decoder for '
                                   f'{channel.topic!r}: {err}') from err
                if decoder is None:
                    raise BagError(f'{self.files[index]}: topic {channel.topic!r} has no '
                                   'ros2msg schema with cdr encoding, cannot decode')
                try:
                    value = decoder(msg.data)
                except Exception as err:  # the decoder raises various types
                    raise BagError(f'{self.files[index]}: cannot decode message on '
                                   f'{channel.topic!r} at {log_time}: '
                                   f'{type(err).__name__}: {str(err)[:200]}') from err
            except BagError as err:
                if on_error is None:
                    raise
                on_error(channel.topic, err)
                continue
            yield channel.topic, log_time, value


def open_bag(path: str | os.PathLike[str]) -> BagReader:
    """Open a bag directory or a bare ``.mcap`` file for reading.

    Raises
    ------
    BagError
        For a missing path, an empty directory, a non-MCAP file, a file cut inside its magic,
        or unsupported storage. Damaged and truncated files are read as far as they are
        intact and flagged with ``damaged`` / ``truncated``, ``lost`` and a
        :class:`BagWarning` instead.
    """
    return BagReader(path)


def _rosbag2_record(record: dict[str, str] | None) -> dict[str, Any] | None:
    """Return the bag information of a ``rosbag2`` metadata record, or None."""
    if not record or 'serialized_metadata' not in record:
        return None
    from gyro_rotor.core.yamlio import load_yaml
    try:
        doc = load_yaml(record['serialized_metadata'], 'the rosbag2 metadata record')
    except Exception:   # noqa: B902 -- damaged: the counts are unknown
        return None
    return doc if isinstance(doc, dict) else None


def _yaml_counts(info: dict[str, Any] | None) -> dict[str, int] | None:
    """Return ``topic -> message_count`` of a rosbag2 bag information node, or None."""
    if not isinstance(info, dict):
        return None
    counts: dict[str, int] = {}
    try:
        for entry in info.get('topics_with_message_count') or []:
            name = str(entry['topic_metadata']['name'])
            counts[name] = counts.get(name, 0) + int(entry['message_count'])
    except (KeyError, TypeError, ValueError):
        return None
    return counts
