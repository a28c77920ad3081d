"""Recovery of a damaged bag (a killed writer, a cut copy, damaged chunks or records).

Every file with damage is rewritten from what :func:`gyro_rotor.bag.mcapfile.read_mcap` could
read (the messages of every intact chunk, every intact metadata record) into a complete MCAP
file, which also carries the metadata record :data:`~gyro_rotor.bag.reader.RECOVERY_RECORD`:
what the original lost, per topic, and the losses of unknown size. A reader of the recovered
bag therefore still says that it is not the whole recording.
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path
from typing import Any

from gyro_rotor.bag.mcapfile import iter_messages, McapContents, read_mcap
from gyro_rotor.bag.metadata import (_bag_metadata, _Topic, _write_metadata_yaml, LIBRARY,
                                     METADATA_YAML, ROSBAG2_RECORD)
from gyro_rotor.bag.qos import normalize_qos
from gyro_rotor.bag.reader import _bag_files, BagReader, RECOVERY_RECORD
from gyro_rotor.errors import BagError
from mcap.writer import CompressionType, Writer
import yaml

__all__ = ['RecoveryReport', 'recover_bag']


@dataclasses.dataclass(frozen=True)
class RecoveryReport:
    """The outcome of :func:`recover_bag`."""

    path: Path
    messages_per_topic: dict[str, int]
    rewritten: tuple[Path, ...]
    originals: tuple[Path, ...]
    metadata_rewritten: bool
    problems: tuple[str, ...]
    #: messages the damaged original lost, per topic (recorded minus readable)
    lost: dict[str, int] = dataclasses.field(default_factory=dict)
    #: losses whose size nothing in the bag tells
    unknown_loss: tuple[str, ...] = ()
    #: metadata records lost with the end of a cut file (e.g. the live verdict)
    lost_records: tuple[str, ...] = ()

    @property
    def message_count(self) -> int:
        """Messages in the recovered bag."""
        return sum(self.messages_per_topic.values())

    @property
    def was_damaged(self) -> bool:
        """Whether some MCAP file had to be rewritten."""
        return bool(self.rewritten)


def _rewrite(data: McapContents, target: Path, loss: dict[str, Any]) -> None:
    """Write the readable content of a damaged file into a complete MCAP file."""
    with open(target, 'xb') as stream:
        writer = Writer(stream, compression=CompressionType.NONE)
        library = f'{data.library}; recovered by {LIBRARY}' if data.library else LIBRARY
        writer.start(profile=data.profile or 'ros2', library=library)
        schema_ids = {sid: writer.register_schema(s.name, s.encoding, s.data)
                      for sid, s in sorted(data.schemas.items())}
        channel_ids = {cid: writer.register_channel(c.topic, c.message_encoding,
                                                    schema_ids.get(c.schema_id, 0),
                                                    metadata=dict(c.metadata))
                       for cid, c in sorted(data.channels.items())}
        for name, meta in data.metadata.items():
            if name not in (ROSBAG2_RECORD, RECOVERY_RECORD):
                writer.add_metadata(name, meta)
        writer.add_metadata(RECOVERY_RECORD, {'json': json.dumps(loss),
                                              'summary': loss['summary']})
        for msg in iter_messages(data):
            writer.add_message(channel_ids[msg.channel_id], msg.log_time, msg.data,
                               msg.publish_time, sequence=msg.sequence)
        info = _bag_metadata(_topics_of(data), target.name, data.start, data.end)
        writer.add_metadata(ROSBAG2_RECORD,
                            {'serialized_metadata': yaml.safe_dump(info, sort_keys=False)})
        writer.finish()
        stream.flush()
        os.fsync(stream.fileno())


def _replace_file(data: McapContents, file: Path, loss: dict[str, Any]) -> Path:
    """Rewrite a damaged file in place, keeping the original as ``.orig``; return that."""
    orig = file.with_name(file.name + '.orig')
    tmp = file.with_name(file.name + '.recovering')
    for existing in (orig, tmp):
        if existing.exists():
            raise BagError(f'cannot recover {file}: {existing} exists already, '
                           'not overwriting')
    try:
        _rewrite(data, tmp, loss)
        os.replace(file, orig)
        os.replace(tmp, file)
    except OSError as err:
        raise BagError(f'cannot recover {file}: {err.strerror or err}') from err
    return orig


def _topics_of(data: McapContents) -> list[_Topic]:
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
    """Make a damaged bag readable by every reader again, its losses kept on record.

    Each damaged MCAP file (no valid footer or summary, a damaged chunk or record) is read
    as far as it is intact, every readable message and metadata record is copied into a new,
    complete file of the same name (with summary, statistics, a ``rosbag2`` metadata record
    and the losses in :data:`~gyro_rotor.bag.reader.RECOVERY_RECORD`), and the damaged
    original is kept as ``<name>.mcap.orig``.
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
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        before = BagReader(path)
    lost, unknown = dict(before.lost), list(before.unknown_loss)
    for index, file in enumerate(files):
        data = before._data[index]
        if data.damaged:
            problems.extend(f'{file}: {p}' for p in data.problems)
            loss = {'lost': lost, 'unknown_loss': unknown,
                    'lost_records': list(before.lost_records),
                    'problems': [p[:300] for p in data.problems][:50],
                    'summary': before.loss_text()}
            originals.append(_replace_file(data, file, loss))
            rewritten.append(file)
            data = read_mcap(file)
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
            meta_path = path / METADATA_YAML
            backup = path / f'{METADATA_YAML}.orig'
            if meta_path.exists() and not backup.exists():
                try:
                    os.replace(meta_path, backup)
                except OSError as err:
                    raise BagError(f'cannot back up {meta_path}: {err.strerror}') from err
            _write_metadata_yaml(path, new_info)
            metadata_rewritten = True
    return RecoveryReport(path, counts, tuple(rewritten), tuple(originals),
                          metadata_rewritten, tuple(problems), lost, tuple(unknown),
                          tuple(before.lost_records))
