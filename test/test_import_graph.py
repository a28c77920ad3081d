"""The import graph between gyro_rotor's modules has no circle (issue 25).

Every import counts, at module level or inside a function: a function-level import that
closes a circle is a circle all the same (the two modules cannot be understood, tested
or moved one without the other). The graph is read from the source (ast), not by
importing, so a circle is found whether or not Python would trip over it.
"""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / 'gyro_rotor'


def _modules() -> dict:
    mods = {}
    for f in PACKAGE.rglob('*.py'):
        parts = f.relative_to(PACKAGE.parent).with_suffix('').parts
        name = '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)
        mods[name] = f
    return mods


def import_graph() -> dict:
    """Return {module: set of gyro_rotor modules it imports anywhere in its source}."""
    mods = _modules()
    graph = {}
    for name, f in mods.items():
        pkg = name if f.name == '__init__.py' else name.rpartition('.')[0]
        out = set()
        for node in ast.walk(ast.parse(f.read_text(encoding='utf-8'))):
            if isinstance(node, ast.Import):
                out.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ''
                if node.level:
                    up = pkg.split('.')[:len(pkg.split('.')) - node.level + 1]
                    base = '.'.join(up + ([node.module] if node.module else []))
                for a in node.names:
                    sub = f'{base}.{a.name}'
                    out.add(sub if sub in mods else base)
        graph[name] = {d for d in out if d in mods and d != name}
    return graph


def circles(graph: dict) -> list:
    """Return the strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_finder_finds_a_circle():
    """The check can fail: a two-module and a three-module circle are found."""
    g = {'a': {'b'}, 'b': {'a'}, 'c': {'d'}, 'd': {'e'}, 'e': {'c'}, 'f': {'a'}}
    assert sorted(circles(g)) == [['a', 'b'], ['c', 'd', 'e']]
    assert circles({'a': {'b'}, 'b': set()}) == []


def test_function_level_imports_count():
    """The graph holds the imports inside functions (sweep.task imports lazily)."""
    g = import_graph()
    assert 'gyro_rotor.core.scene' in g['gyro_rotor.analysis.sweep.task']
    assert len(g) > 100


def test_no_import_circle():
    """No module imports, directly or through others, a module that imports it."""
    assert circles(import_graph()) == []
