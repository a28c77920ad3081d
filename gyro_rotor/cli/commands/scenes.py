"""``gyro-rotor scenes``: list the shipped scenes (the centrifuge's and general systems')."""

from __future__ import annotations

import argparse

from gyro_rotor.core.scene import list_scenes, load_scene

HELP = 'list the shipped scenes'


def add_arguments(p: argparse.ArgumentParser) -> None:
    """No arguments."""


def run(args: argparse.Namespace) -> int:
    """Print one line per scene: the centrifuge's, then those of general rotor systems."""
    from gyro_rotor.core.system.scene import list_general_scenes, load_general_scene
    for name in list_scenes():
        s = load_scene(name)
        print(f'{name:16s} {s.model:23s} t_end {s.t_end:6g} s  {s.description}')
    for name in list_general_scenes():
        s = load_general_scene(name)
        what = f'system {s.system.name}'
        print(f'{name:16s} {what:23s} t_end {s.t_end:6g} s  {s.description}')
    return 0
