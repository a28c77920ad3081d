"""The house of layers (gyro_rotor/__init__.py): who may import whom, checked on the source.

Every module of the package is parsed (not imported); each ``import``/``from`` of a
gyro_rotor module is checked against the layer order, and rclpy only in the ROS layers.
"""

import ast
from pathlib import Path

import gyro_rotor
import pytest

PKG = Path(gyro_rotor.__file__).resolve().parent
ORDER = {name: i for i, name in enumerate(gyro_rotor.LAYERS)}


def _layer(module: str) -> str | None:
    """Return the layer of a dotted gyro_rotor module name (None: below every layer)."""
    parts = module.split('.')
    return parts[1] if len(parts) > 1 and parts[1] in ORDER else None


def _imports(path: Path) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text(), str(path))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.append((node.lineno, node.module))
            if node.module == 'gyro_rotor':
                out += [(node.lineno, f'gyro_rotor.{a.name}') for a in node.names]
    return out


MODULES = sorted(p for p in PKG.rglob('*.py') if '__pycache__' not in p.parts)


def test_every_module_is_in_a_layer():
    """Only the entry files, errors.py, signals.py and node_settings.py are outside the layers.

    The last three are below every layer (their imports are checked by test_layer_rule: none
    of a layer): the exception types, the stop request that every process of the package
    (a node's main() in ros, the soak in tools, the commands in cli) takes its signals as,
    and the simulation node's settings that a scene file carries (the scene reader in core
    accepts them, the node declares them).
    """
    loose = {p.name for p in MODULES if p.parent == PKG}
    assert loose <= {'__init__.py', '__main__.py', 'errors.py', 'signals.py', 'node_settings.py'}


@pytest.mark.parametrize('path', MODULES, ids=[str(p.relative_to(PKG)) for p in MODULES])
def test_layer_rule(path):
    """No pure layer imports rclpy; no module imports from a layer above its own."""
    rel = path.relative_to(PKG).with_suffix('')
    own = rel.parts[0] if len(rel.parts) > 1 else None
    if rel.name == '__main__':          # ``python -m gyro_rotor``: the top, like the cli
        own = 'cli'
    own_rank = ORDER.get(own, -1)
    for line, name in _imports(path):
        if name.split('.')[0] in ('rclpy', 'launch', 'launch_ros'):
            assert own in gyro_rotor.ROS_LAYERS, f'{rel}:{line} imports {name} in a pure layer'
        if name.startswith('gyro_rotor.'):
            layer = _layer(name)
            if layer is not None:
                assert ORDER[layer] <= own_rank, \
                    f'{rel}:{line} ({own or "top"}) imports {name} from the higher layer {layer}'


#: the longest function the house allows (issue 13); compiled numba kernels are exempt,
#: since splitting their loops would cost a call per step
MAX_FUNCTION_LINES = 80


def _is_compiled(fn: ast.FunctionDef) -> bool:
    """Return True if ``fn`` is decorated with numba's ``njit``/``jit`` (any form)."""
    for dec in fn.decorator_list:
        target = dec.func if isinstance(dec, ast.Call) else dec
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, 'id', '')
        if name in ('njit', 'jit'):
            return True
    return False


@pytest.mark.parametrize('path', MODULES, ids=lambda p: str(p.relative_to(PKG)))
def test_no_function_over_80_lines(path):
    tree = ast.parse(path.read_text(), str(path))
    long = [f'{fn.name} (line {fn.lineno}): {fn.end_lineno - fn.lineno + 1} lines'
            for fn in ast.walk(tree)
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef))
            and not _is_compiled(fn) and fn.end_lineno - fn.lineno + 1 > MAX_FUNCTION_LINES]
    assert not long, f'{path.relative_to(PKG)}: split ' + '; '.join(long)


def test_the_function_length_check_can_fail(tmp_path):
    """A 90-line function is caught, a 90-line njit kernel is not."""
    body = '\n'.join(f'    x{i} = {i}' for i in range(88))
    src = f'def long():\n{body}\n    return 0\n\n\n@njit(cache=True)\ndef kernel():\n{body}\n'
    tree = ast.parse(src)
    fns = [f for f in ast.walk(tree) if isinstance(f, ast.FunctionDef)]
    assert [f.end_lineno - f.lineno + 1 > MAX_FUNCTION_LINES and not _is_compiled(f)
            for f in fns] == [True, False]
