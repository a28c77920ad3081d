"""Small helpers of the command line (argument parsing only; no physics)."""

from __future__ import annotations

from typing import Any

from gyro_rotor.errors import SceneError


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
        out[name.strip()] = value
    return out
