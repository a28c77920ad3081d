"""Small helpers of the command line (argument parsing only; no physics)."""

from __future__ import annotations

import contextlib
from typing import Any

from gyro_rotor.errors import NotSteadyError, ParameterError, SceneError


_NON_FINITE = {'nan': float('nan'), 'inf': float('inf'), '+inf': float('inf'),
               '-inf': float('-inf'), 'infinity': float('inf'), '-infinity': float('-inf')}


def parse_sets(items: list[str]) -> dict[str, Any]:
    """``['K_D=0.1', 'initial.branch=2']`` -> ``{'K_D': 0.1, 'initial.branch': 2}``.

    Values are read as YAML scalars or lists (``0.1``, ``2``, ``true``, ``[1, 0, 0, 0]``).
    """
    from gyro_rotor.core.yamlio import load_yaml, short
    out: dict[str, Any] = {}
    for item in items or []:
        name, sep, text = item.partition('=')
        if not sep or not name.strip():
            raise SceneError(f'--set needs NAME=VALUE, got {short(item)}')
        # the one YAML loader (YAML 1.2 numbers, limits): the same values as a scene file
        value = load_yaml(text, f'--set {short(name.strip(), 60)}', SceneError)
        if isinstance(value, str) and value.strip().lower() in _NON_FINITE:
            value = _NON_FINITE[value.strip().lower()]      # nan, inf written plainly
        out[name.strip()] = value
    return out


def error_hint(err: BaseException) -> str:
    """Return what the command line adds to the message of ``err`` ('' if nothing).

    A system file's steady motion that is not one (:class:`~gyro_rotor.errors.NotSteadyError`,
    ``err`` or the error it was raised from, whose message ends ``err``'s): the command
    ``steady`` solves for one from the scene's guess.
    """
    found = None
    while err is not None:
        if isinstance(err, NotSteadyError):
            found = err
        err = err.__cause__
    if found is None:
        return ''
    return f'; `gyro-rotor steady {found.scene}` solves for one from this guess'


def load_scene_with_sets(scene: str, sets: list[str], *, check: bool = True):
    """Load a scene, then apply ``--set`` overrides; an error names its real source.

    The file is loaded alone first, so that a fault of the file names the file; a value
    refused only with the overrides names ``--set`` (not the scene file it was applied to).
    ``check=False``: a system file's steady motion is not checked (``steady`` solves for
    one).
    """
    from gyro_rotor.core.scene import load_scene
    overrides = parse_sets(sets)
    base = load_scene(scene, check=check)
    if not overrides:
        return base
    try:
        return load_scene(scene, overrides=overrides, check=check)
    except (SceneError, ParameterError) as err:
        text = str(err)
        prefix = f'scene file {base.path}: '
        if text.startswith(prefix):
            text = text[len(prefix):]
        given = ' '.join(f'--set {item}' for item in sets)
        raise type(err)(f'{given} (scene {base.name}): {text}') from err


def check_output_file(path: str, suffixes: tuple[str, ...] = (), *,
                      overwrite: bool | None = None) -> None:
    """Refuse, before any work is done, an output file that could not be written.

    ``overwrite=False`` also refuses an existing file (``--force`` lets it be replaced);
    None leaves that to the command.
    """
    import os
    from pathlib import Path
    p = Path(path)
    if suffixes and not str(path).endswith(suffixes):
        raise ParameterError(f'{path}: the output file must end in {" or ".join(suffixes)}')
    if overwrite is False and p.is_file():
        raise ParameterError(f'{path} exists already; pass --force to overwrite it')
    if p.is_dir():
        raise ParameterError(f'{path} is a directory, not a file')
    parent = p.parent if str(p.parent) else Path('.')
    if not parent.is_dir():
        raise ParameterError(f'cannot write {path}: directory {parent} does not exist')
    if not os.access(parent, os.W_OK):
        raise ParameterError(f'cannot write {path}: directory {parent} is not writable')
    # the permission bits do not tell everything (root, /proc, a read-only mount): create
    # and remove a probe file where the output will be written (as write_output does)
    probe = parent / f'.{p.name}.probe{os.getpid()}'
    try:
        os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
    except OSError as err:
        raise ParameterError(f'cannot write {path}: no file can be created in directory '
                             f'{parent} ({err.strerror or err})') from None
    with contextlib.suppress(OSError):
        os.unlink(probe)


def check_output_dir(path: str) -> None:
    """Refuse, before any work is done, an output directory that could not be made.

    It may exist (as a directory) or not; its nearest existing parent must be a writable
    directory (it is made with its parents when the output is written).
    """
    import os
    from pathlib import Path
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise ParameterError(f'{path} exists and is not a directory')
    parent = p
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise ParameterError(f'cannot make directory {path}: {parent} is not a directory')
    if not os.access(parent, os.W_OK):
        raise ParameterError(f'cannot make directory {path}: {parent} is not writable')


def write_output(path: str, write) -> None:
    """Call ``write(tmp)`` on a temporary file beside ``path``, then rename it to ``path``.

    A failed write (a full disk) leaves no partial file, and the error names ``path``.
    """
    import os
    from pathlib import Path
    p = Path(path)
    tmp = p.with_name(f'.{p.stem}.tmp{os.getpid()}{p.suffix}')
    try:
        write(str(tmp))
        os.replace(tmp, p)
    except OSError as err:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise ParameterError(f'cannot write {path}: {err.strerror or err} (nothing written)'
                             ) from None


def check_number(name: str, value: float, *, low: float | None = None,
                 high: float | None = None, low_open: bool = False, what: str = '') -> float:
    """Return ``value`` if it is finite and in range, else raise one ParameterError line."""
    import math
    ok = math.isfinite(value) and (low is None or (value > low if low_open else value >= low)) \
        and (high is None or value <= high)
    if not ok:
        rng = []
        if low is not None:
            rng.append(f'{">" if low_open else ">="} {low:g}')
        if high is not None:
            rng.append(f'<= {high:g}')
        raise ParameterError(f'{name} must be finite{" and " + " and ".join(rng) if rng else ""}'
                             f'{" " + what if what else ""}, got {value!r}')
    return value


#: where run outputs go by default (benchmarks, demos): never the tracked tree, ignored by
#: the repository's .gitignore
RUNS_DIR = 'bench_out'


def make_unique_dir(base, *, tries: int = 1000):
    """Create and return a new directory ``base``, or ``base-2``, ``base-3``, ...

    ``mkdir`` without ``exist_ok`` is atomic: two runs started in the same second (the
    same time stamp in ``base``) get two folders, never one shared.
    """
    from pathlib import Path
    base = Path(base)
    base.parent.mkdir(parents=True, exist_ok=True)
    for k in range(1, tries + 1):
        out = base if k == 1 else base.with_name(f'{base.name}-{k}')
        try:
            out.mkdir()
        except FileExistsError:
            continue
        except OSError as err:
            raise ParameterError(f'cannot create output directory {out}: {err}') from err
        return out
    raise ParameterError(f'no free output directory like {base} after {tries} tries')


def write_json(path: str, doc: Any) -> None:
    """Write ``doc`` to ``path`` as strict JSON (via :func:`write_output`).

    The one rule of every JSON file the command line writes, ``analyze``'s report's
    (:func:`gyro_rotor.analysis.report.strict_json`): ``null`` where a number is not finite.

    ``allow_nan=False``: a non-finite number that reached the writer is an error, never the
    bare ``Infinity`` that strict parsers (``jq``, ``JSON.parse``) refuse.
    """
    import json

    from gyro_rotor.analysis.report import strict_json
    text = json.dumps(strict_json(doc), indent=1, allow_nan=False)

    def write(tmp):
        with open(tmp, 'w', encoding='utf-8') as f:
            f.write(text + '\n')
    write_output(path, write)
