"""The rosbag2 ``metadata.yaml`` (version 9) and what writer, reader and recovery share.

``rosbag2_storage/include/rosbag2_storage/yaml.hpp``: top key
``rosbag2_bagfile_information``; written at open, rewritten (atomically) when a topic is
added and at close; after a crash :func:`gyro_rotor.bag.recovery.recover_bag` rewrites it.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
import dataclasses
import os
from pathlib import Path
from typing import Any

from gyro_rotor import __version__
from gyro_rotor.errors import BagError
import mcap
import yaml

__all__ = ['BagWarning', 'METADATA_VERSION', 'MAGIC', 'LIBRARY', 'METADATA_YAML',
           'ROSBAG2_RECORD']

#: rosbag2 metadata version written (Jazzy).
METADATA_VERSION = 9
MAGIC = b'\x89MCAP0\r\n'
LIBRARY = f'gyro_rotor.bagio {__version__}; mcap-python {mcap.__version__}'
METADATA_YAML = 'metadata.yaml'
#: the MCAP metadata record rosbag2's writer adds when it closes a file (the bag's
#: metadata.yaml, serialized); a file without it was not closed.
ROSBAG2_RECORD = 'rosbag2'


class BagWarning(UserWarning):
    """A bag was read only partly (truncated) or without its ``metadata.yaml``."""


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
    target = directory / METADATA_YAML
    tmp = directory / f'.{METADATA_YAML}.tmp'
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


def load_metadata_yaml(path: Path) -> tuple[dict[str, Any] | None, str]:
    """Return the inner node of ``metadata.yaml`` (or None) and a problem description."""
    from gyro_rotor.core.yamlio import load_yaml
    try:
        doc = load_yaml(path.read_text(encoding='utf-8'), str(path), BagError)
        info = doc['rosbag2_bagfile_information']
        if not isinstance(info, dict):
            raise TypeError('not a mapping')
        return info, ''
    except (OSError, UnicodeDecodeError, BagError, KeyError, TypeError) as err:
        return None, f'{path} is unreadable ({type(err).__name__}: {str(err)[:200]})'
