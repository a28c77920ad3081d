"""``gyro-rotor steady SCENE``: the steady motions of the scene's system."""

from __future__ import annotations

import argparse

from gyro_rotor.cli.util import load_scene_with_sets
from gyro_rotor.linear.newton import steady_motions

HELP = ('print the steady motions (the centrifuge: solution I; II on both branches, exact and '
        'eq. 22; a system file: Newton from the guess)')


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``steady``."""
    p.add_argument('scene', nargs='?', default='precession', help='scene name or path')
    p.add_argument('--theta0', type=float, default=None,
                   help="tilt of the centrifuge's solution II [rad] (default: the scene's, "
                        'else 0.1; the centrifuge only)')
    p.add_argument('--set', action='append', default=[], metavar='NAME=VALUE')


def run(args: argparse.Namespace) -> int:
    """Print the steady motions the scene's system offers; exit 1 if one is not found."""
    scene = load_scene_with_sets(args.scene, args.set, check=False)
    st = steady_motions(scene, args.theta0)
    print(f'scene {scene.name}: system {scene.system_name}; {st.head}')
    for line in st.lines:
        print(f'  {line}')
    return 0 if st.found else 1
