"""The cache of code generated on first use: ``$GYRO_ROTOR_CACHE`` or ~/.cache/gyro_rotor.

Two kinds of Python source are generated at run time and kept here, one folder each: a
system file's equations (``systems/``, :mod:`gyro_rotor.core.system.codegen`) and the
straight-line explicit Runge-Kutta kernels (``kernels/``,
:mod:`gyro_rotor.numerics.integrators.rk_codegen`). numba caches their machine code beside
them (``cache=True``), so only the first use of a machine compiles. A generated file is
written whole to a temporary file and renamed (:func:`write_atomic`): processes that start
together (nodes, the command line) see the whole file or none. What a first use generates
is said on stderr in lines that begin with ``gyro_rotor: `` (:func:`note`).
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path
import sys
import tempfile

__all__ = ['cache_root', 'note', 'write_atomic', 'import_file']


def cache_root() -> Path:
    """Return the cache directory (``$GYRO_ROTOR_CACHE`` or ~/.cache/gyro_rotor)."""
    env = os.environ.get('GYRO_ROTOR_CACHE')
    return Path(env) if env else Path.home() / '.cache' / 'gyro_rotor'


def note(text: str) -> None:
    """Say on stderr what a first use generates (a line that begins with ``gyro_rotor: ``)."""
    print(f'gyro_rotor: {text}', file=sys.stderr, flush=True)


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` (its folder made if missing) by a temporary file's rename.

    Raises OSError when the folder cannot be made or written (a read-only cache).
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix='.tmp')
    try:
        with os.fdopen(fd, 'w', encoding='utf-8') as f:
            f.write(text)
        os.replace(tmp, path)   # atomic: a concurrent reader sees the whole file or none
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def import_file(path: Path, name: str):
    """Import the generated module at ``path`` under the module name ``name``."""
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module
