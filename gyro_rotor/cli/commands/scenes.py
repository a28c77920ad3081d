"""``gyro-rotor scenes``: list the shipped scenes (the centrifuge's and general systems')."""

from __future__ import annotations

import argparse

HELP = 'list the shipped scenes'


def add_arguments(p: argparse.ArgumentParser) -> None:
    """No arguments."""


def run(args: argparse.Namespace) -> int:
    """Print one line per scene: its system (and the centrifuge's model), t_end, what."""
    # imported here, not at the top: ``gyro-rotor --help`` loads every command's module
    from gyro_rotor.core.scene import list_scenes, load_scene

    for name in list_scenes():
        s = load_scene(name)
        what = f'centrifuge {s.system.model}' if s.builtin else f'system {s.system.name}'
        print(f'{name:16s} {what:28s} t_end {s.t_end:6g} s  {s.description}')
    return 0
