"""Small helpers of the command line (argument parsing only; no physics)."""

from __future__ import annotations

from typing import Any

from gyro_rotor.errors import ParameterError, SceneError


def parse_sets(items: list[str]) -> dict[str, Any]:
    """``['K_D=0.1', 'initial.branch=2']`` -> ``{'K_D': 0.1, 'initial.branch': 2}``.

    Values are read as YAML scalars or lists (``0.1``, ``2``, ``true``, ``[1, 0, 0, 0]``).
    """
    import yaml
    out: dict[str, Any] = {}
    for item in items or []:
        name, sep, text = item.partition('=')
        if not sep or not name.strip():
            raise SceneError(f"--set needs NAME=VALUE, got '{item}'")
        try:
            value = yaml.safe_load(text)
        except yaml.YAMLError as err:
            raise SceneError(f"--set {name}: cannot read value '{text}': {err}") from err
        if isinstance(value, str):
            # YAML 1.1 reads 1e-3, 1e300, nan and inf as strings: numbers are meant here
            try:
                value = float(value)
            except ValueError:
                pass
        out[name.strip()] = value
    return out


def check_output_file(path: str, suffixes: tuple[str, ...] = ()) -> None:
    """Refuse, before any work is done, an output file that could not be written."""
    import os
    from pathlib import Path
    p = Path(path)
    if suffixes and not str(path).endswith(suffixes):
        raise ParameterError(f'{path}: the output file must end in {" or ".join(suffixes)}')
    if p.is_dir():
        raise ParameterError(f'{path} is a directory, not a file')
    parent = p.parent if str(p.parent) else Path('.')
    if not parent.is_dir():
        raise ParameterError(f'cannot write {path}: directory {parent} does not exist')
    if not os.access(parent, os.W_OK):
        raise ParameterError(f'cannot write {path}: directory {parent} is not writable')
