"""``gyro-rotor scenes``: list the shipped scenes."""

from __future__ import annotations

import argparse

from gyro_rotor.core.scene import list_scenes, load_scene

HELP = 'list the shipped scenes'


def add_arguments(p: argparse.ArgumentParser) -> None:
    """No arguments."""


def run(args: argparse.Namespace) -> int:
    """Print one line per scene."""
    for name in list_scenes():
        s = load_scene(name)
        print(f'{name:16s} {s.model:15s} t_end {s.t_end:6g} s  {s.description}')
    return 0
