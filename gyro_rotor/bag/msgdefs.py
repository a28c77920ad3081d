"""Full ROS 2 message definitions and type hashes from the installed share files.

rosbag2 stores, for every topic type, the complete ``ros2msg`` definition text in the MCAP
schema record, and the RIHS01 type hash in the channel metadata. This module reproduces both
without rclpy, ament_index or rosbag2:

* :func:`message_definition` mirrors ``LocalMessageDefinitionSource::get_full_text`` of
  ros2/rosbag2 ``jazzy:rosbag2_cpp/src/rosbag2_cpp/message_definitions/
  local_message_definition_source.cpp``: the top-level ``.msg`` text first, then for each
  dependency (the non-primitive field types of each definition, in sorted order, depth first,
  each type once) a newline, a line of exactly 80 ``=``, a line ``MSG: <pkg>/<Type>`` spelled as
  in the field declaration, and the dependency's text. A bare ``Type`` resolves to the package
  of the definition that uses it. The format is documented in ros2/rosbag2
  ``jazzy:docs/message_definition_encoding.md``.
* :func:`type_hash` reads the ``RIHS01_...`` string from the rosidl type description
  ``share/<pkg>/msg/<Type>.json`` (key ``type_hashes``), as rosbag2 writes it into the channel
  metadata ``topic_type_hash`` and the ``metadata.yaml`` field ``type_description_hash``.

The share directories are ``<prefix>/share`` for every entry of ``AMENT_PREFIX_PATH`` and then
``sys.prefix``: in the PyPI-wheel environment the variable is not set and the wheels install
their share files under the virtual environment prefix.
"""

from __future__ import annotations

import functools
import json
import os
from pathlib import Path
import re
import sys

from gyro_rotor.errors import BagError

__all__ = ['message_definition', 'type_hash', 'normalize_type_name', 'share_dirs',
           'PRIMITIVE_TYPES', 'DELIMITER']

#: Field types that are not messages (rosidl primitive types; ``wstring`` included).
PRIMITIVE_TYPES = frozenset({
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
    'int32', 'uint32', 'int64', 'uint64', 'string', 'wstring',
})

#: The line that separates two definitions in a ``ros2msg`` full text.
DELIMITER = '=' * 80

_NAME = r'[A-Za-z][A-Za-z0-9_]*'
_TYPE_RE = re.compile(rf'^({_NAME})/(?:({_NAME})/)?({_NAME})$')
# The type token of a field or constant line: name, optional array suffix, optional bound.
_FIELD_RE = re.compile(r'^\s*([A-Za-z0-9_/]+)(?:<=\d+)?(?:\[[^\]]*\])?\s+\S')


def share_dirs() -> list[Path]:
    """Return the ``share`` directories searched for interface files, in search order."""
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    prefixes.append(sys.prefix)
    dirs: list[Path] = []
    for prefix in prefixes:
        share = Path(prefix) / 'share'
        if share not in dirs:
            dirs.append(share)
    return dirs


def normalize_type_name(type_name: str) -> str:
    """Return the ``pkg/msg/Type`` spelling of ``pkg/Type`` or ``pkg/msg/Type``.

    Raises
    ------
    BagError
        If the name is not a ROS 2 message type name.
    """
    match = _TYPE_RE.match(type_name) if isinstance(type_name, str) else None
    if match is None or match.group(2) not in (None, 'msg'):
        raise BagError(f'{type_name!r} is not a ROS 2 message type name (pkg/msg/Type)')
    return f'{match.group(1)}/msg/{match.group(3)}'


def _split(type_name: str) -> tuple[str, str]:
    pkg, _, name = normalize_type_name(type_name).split('/')
    return pkg, name


def _find_file(type_name: str, suffix: str) -> Path | None:
    pkg, name = _split(type_name)
    for share in share_dirs():
        candidate = share / pkg / 'msg' / f'{name}{suffix}'
        if candidate.is_file():
            return candidate
    return None


@functools.lru_cache(maxsize=None)
def _msg_text(type_name: str) -> str:
    path = _find_file(type_name, '.msg')
    if path is None:
        pkg, name = _split(type_name)
        searched = ', '.join(str(d) for d in share_dirs())
        raise BagError(f'message type {type_name!r} not found: no {pkg}/msg/{name}.msg '
                       f'under {searched} (set AMENT_PREFIX_PATH to add prefixes)')
    try:
        return path.read_text(encoding='utf-8')
    except (OSError, UnicodeDecodeError) as err:
        raise BagError(f'message type {type_name!r}: cannot read {path}: {err}') from err


def _dependencies(text: str, package: str) -> list[str]:
    """Return the non-primitive field types of a ``.msg`` text, sorted, as spelled."""
    deps: set[str] = set()
    for line in text.splitlines():
        line = line.split('#', 1)[0]
        match = _FIELD_RE.match(line)
        if match is None:
            continue
        token = match.group(1)
        if token in PRIMITIVE_TYPES:
            continue
        deps.add(token if '/' in token else f'{package}/{token}')
    return sorted(deps)


@functools.lru_cache(maxsize=None)
def message_definition(type_name: str) -> str:
    r"""Return the complete ``ros2msg`` definition text of a message type, as rosbag2 writes it.

    Parameters
    ----------
    type_name : str
        ``'sensor_msgs/msg/JointState'`` (or ``'sensor_msgs/JointState'``).

    Returns
    -------
    str
        The ``.msg`` text, followed by one ``'\n' + '=' * 80 + '\nMSG: pkg/Type\n' + text``
        block for every (recursive) dependency.

    Raises
    ------
    BagError
        If the type or one of its dependencies has no ``.msg`` file in the share directories.
    """
    root = normalize_type_name(type_name)
    seen: set[str] = set()

    def append(name: str, depth: int) -> str:
        if depth <= 0:
            raise BagError(f'message type {root!r}: dependency recursion too deep at {name!r}')
        try:
            text = _msg_text(normalize_type_name(name))
        except BagError as err:
            if name == root:
                raise
            raise BagError(f'message type {root!r} needs {name!r}: {err}') from err
        result = text
        for dep in _dependencies(text, name.split('/', 1)[0]):
            if dep not in seen:
                seen.add(dep)
                result += f'\n{DELIMITER}\nMSG: {dep}\n' + append(dep, depth - 1)
        return result

    return append(root, 50)


@functools.lru_cache(maxsize=None)
def type_hash(type_name: str) -> str:
    """Return the RIHS01 type hash of a message type, or ``''`` if none is installed.

    The hash comes from ``share/<pkg>/msg/<Type>.json`` (rosidl type description), entry of
    ``type_hashes`` whose ``type_name`` is the requested type.
    """
    name = normalize_type_name(type_name)
    path = _find_file(name, '.json')
    if path is None:
        return ''
    try:
        data = json.loads(path.read_text(encoding='utf-8'))
    except (OSError, ValueError):
        return ''
    for entry in data.get('type_hashes', []) if isinstance(data, dict) else []:
        if isinstance(entry, dict) and entry.get('type_name') == name:
            return str(entry.get('hash_string', ''))
    return ''
