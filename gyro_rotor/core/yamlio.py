"""The one YAML loader for outside data, with its limits stated once (issue 24).

Every YAML text that enters from outside -- scene files, system files, ``--params-file``,
``--set`` values, live parameters, the simulation node's ``~/scene`` documents, the bag's
metadata records -- goes through :func:`load_yaml`:

* **Size**: at most :data:`MAX_CHARS` characters.
* **Depth**: collections nested at most :data:`MAX_DEPTH` deep (no RecursionError).
* **Nodes and aliases**: the document, and the document with every alias expanded, may
  hold at most :data:`MAX_NODES` nodes (an alias bomb is refused before anything walks it;
  PyYAML shares the aliased node, so nothing is expanded in memory while counting).
* **Duplicate keys** in a mapping are refused (PyYAML keeps the last one silently).
* **Scalars** resolve by the YAML 1.2 core schema, the same everywhere: ``1.0e5`` and ``1e5``
  are floats, ``012`` is the integer 12, ``0o17`` and ``0x1F`` are integers, ``yes``/``no``/
  ``on``/``off`` and sexagesimal ``1:30`` are strings, ``.inf``/``.nan`` are floats, and no
  merge keys (``<<``) or timestamps. Digits are ASCII only.

Errors are raised as the caller's error class with one line naming what and where.
"""

from __future__ import annotations

import re
from typing import Any

from gyro_rotor.errors import GyroRotorError, ParameterError
import yaml

__all__ = ['load_yaml', 'MAX_CHARS', 'MAX_DEPTH', 'MAX_NODES', 'yaml12_scalar', 'IDENTIFIER',
           'SCENE_NAME', 'short']

#: longest YAML text accepted [characters]
MAX_CHARS = 4 * 1024 * 1024
#: deepest nesting of collections accepted
MAX_DEPTH = 64
#: most nodes of a document with every alias expanded (PyYAML composes about 30000 nodes a
#: second: this bounds the time of a hostile document to about 2 s)
MAX_NODES = 50_000

#: a name of the system file (coordinate, rotor, constant, system): ASCII, whole string
IDENTIFIER = re.compile(r'\A[A-Za-z_][A-Za-z0-9_]{0,99}\Z', re.ASCII)
#: a scene's name (it names output directories): ASCII letters, digits, _ . -
SCENE_NAME = re.compile(r'\A[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}\Z', re.ASCII)

_INT = re.compile(r'[-+]?[0-9]+\Z|0o[0-7]+\Z|0x[0-9a-fA-F]+\Z', re.ASCII)
_FLOAT = re.compile(r'[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?\Z'
                    r'|[-+]?\.(?:inf|Inf|INF)\Z|\.(?:nan|NaN|NAN)\Z', re.ASCII)
_BOOL = {'true': True, 'True': True, 'TRUE': True,
         'false': False, 'False': False, 'FALSE': False}
_NULL = frozenset({'', '~', 'null', 'Null', 'NULL'})


def short(value: Any, limit: int = 120) -> str:
    """Return ``repr(value)`` cut to about ``limit`` characters (for error messages).

    Nested containers are shown only a few levels deep and a few items long, so an error
    message never grows with the data it names.
    """
    import reprlib
    r = reprlib.Repr()
    r.maxlevel, r.maxlist, r.maxdict, r.maxtuple = 3, 6, 6, 6
    r.maxstring, r.maxother = limit, limit
    text = r.repr(value)
    return text if len(text) <= limit else text[:limit - 3] + '...'


def yaml12_scalar(text: str) -> Any:
    """Return the value of a plain scalar under the YAML 1.2 core schema (str if none)."""
    if text in _NULL:
        return None
    if text in _BOOL:
        return _BOOL[text]
    if _INT.match(text):
        if text.startswith('0o'):
            return int(text[2:], 8)
        if text.startswith('0x'):
            return int(text[2:], 16)
        return int(text, 10)
    if _FLOAT.match(text):
        low = text.lower()
        if low.endswith('.nan'):
            return float('nan')
        if low.endswith('.inf'):
            return float('-inf') if low.startswith('-') else float('inf')
        return float(text)
    return text


class _Resolver(yaml.resolver.BaseResolver):
    """Plain scalars get the tag ``tag:yaml.org,2002:yaml12`` (resolved by the constructor)."""


_Resolver.yaml_implicit_resolvers = {}
_Resolver.add_implicit_resolver('tag:gyro_rotor,2024:plain', re.compile(r'.*', re.S),
                                None)


class _Constructor(yaml.constructor.SafeConstructor):
    """SafeConstructor without YAML 1.1's implicit types; duplicate keys refused."""

    def construct_plain(self, node: yaml.ScalarNode) -> Any:
        return yaml12_scalar(node.value)

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        if not isinstance(node, yaml.MappingNode):
            raise yaml.constructor.ConstructorError(
                None, None, f'expected a mapping node, but found {node.id}', node.start_mark)
        mapping: dict = {}
        for key_node, value_node in node.value:
            key = self.construct_object(key_node, deep=deep)
            try:
                hash(key)
            except TypeError:
                raise yaml.constructor.ConstructorError(
                    'while constructing a mapping', node.start_mark,
                    'found an unhashable key', key_node.start_mark) from None
            if key in mapping:
                raise yaml.constructor.ConstructorError(
                    'while constructing a mapping', node.start_mark,
                    f'found the key {str(key)[:60]!r} a second time', key_node.start_mark)
            mapping[key] = self.construct_object(value_node, deep=deep)
        return mapping


_Constructor.add_constructor('tag:gyro_rotor,2024:plain', _Constructor.construct_plain)
_Constructor.add_constructor('tag:yaml.org,2002:map', _Constructor.construct_yaml_map)


class _Scanner(yaml.scanner.Scanner):
    """Scanner that refuses deep flow nesting as it reads it.

    PyYAML's scanner looks ahead over a whole flow collection for possible simple keys,
    quadratically in its depth: 5000 '[' took 0.28 s before the composer saw depth 65.
    """

    def fetch_flow_collection_start(self, TokenClass):
        if self.flow_level >= MAX_DEPTH:
            raise yaml.scanner.ScannerError(
                None, None, f'nested more than {MAX_DEPTH} levels deep', self.get_mark())
        super().fetch_flow_collection_start(TokenClass)


class _Composer(yaml.composer.Composer):
    """Composer that refuses deep nesting (before Python's recursion limit is near)."""

    _depth = 0
    _nodes = 0

    def compose_node(self, parent, index):
        self._depth += 1
        self._nodes += 1
        try:
            if self._nodes > MAX_NODES:
                raise yaml.composer.ComposerError(
                    None, None, f'more than {MAX_NODES} nodes', self.peek_event().start_mark)
            if self._depth > MAX_DEPTH:
                event = self.peek_event()
                raise yaml.composer.ComposerError(
                    None, None, f'nested more than {MAX_DEPTH} levels deep',
                    event.start_mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


class _Loader(yaml.reader.Reader, _Scanner, yaml.parser.Parser, _Composer,
              _Constructor, _Resolver):
    def __init__(self, stream):
        yaml.reader.Reader.__init__(self, stream)
        _Scanner.__init__(self)
        yaml.parser.Parser.__init__(self)
        _Composer.__init__(self)
        _Constructor.__init__(self)
        _Resolver.__init__(self)


def _expanded_size(node: yaml.Node) -> int:
    """Nodes of ``node`` with every alias expanded (memoized per shared node; capped)."""
    memo: dict[int, int] = {}
    stack = [(node, False)]
    while stack:
        n, done = stack.pop()
        if id(n) in memo:
            continue
        if isinstance(n, yaml.ScalarNode):
            memo[id(n)] = 1
            continue
        children = ([c for pair in n.value for c in pair] if isinstance(n, yaml.MappingNode)
                    else list(n.value))
        if done:
            memo[id(n)] = min(MAX_NODES + 1, 1 + sum(memo.get(id(c), 0) for c in children))
        else:
            stack.append((n, True))
            stack.extend((c, False) for c in children if id(c) not in memo)
    return memo[id(node)]


def load_yaml(text: str | bytes, what: str, error: type[GyroRotorError] = ParameterError
              ) -> Any:
    """Parse one YAML document from outside data within the limits (module doc).

    Parameters
    ----------
    text : str or bytes
        The document (bytes are decoded as UTF-8).
    what : str
        What it is, for the error message (a file name, ``'--set K_D'``).
    error : exception class
        Raised for anything refused, with one line.
    """
    if isinstance(text, (bytes, bytearray)):
        try:
            text = bytes(text).decode('utf-8')
        except UnicodeDecodeError as err:
            raise error(f'{what}: not UTF-8 text ({err.reason} at byte {err.start})') from None
    if not isinstance(text, str):
        raise error(f'{what}: expected YAML text, got {type(text).__name__}')
    if len(text) > MAX_CHARS:
        raise error(f'{what}: {len(text)} characters, more than the {MAX_CHARS} a YAML '
                    'document may have')
    loader = None
    try:
        loader = _Loader(text)          # the reader refuses control characters already here
        node = loader.get_single_node()
        if node is None:
            return None
        size = _expanded_size(node)
        if size > MAX_NODES:
            raise error(f'{what}: more than {MAX_NODES} nodes with its aliases expanded '
                        '(an alias bomb?), refused')
        return loader.construct_document(node)
    except yaml.MarkedYAMLError as err:
        mark = err.problem_mark
        where = f' (line {mark.line + 1}, column {mark.column + 1})' if mark else ''
        raise error(f'{what} is not valid YAML{where}: {err.problem}') from None
    except yaml.YAMLError as err:
        raise error(f'{what} is not valid YAML: {" ".join(str(err).split())[:200]}'
                    ) from None
    except RecursionError:
        raise error(f'{what}: nested too deeply') from None
    finally:
        if loader is not None:
            loader.dispose()
