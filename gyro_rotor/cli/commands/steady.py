"""``gyro-rotor steady SCENE``: steady motions I and II, exact and by the paper's eq. (22)."""

from __future__ import annotations

import argparse

from gyro_rotor.cli.util import parse_sets
from gyro_rotor.core.scene import load_scene
from gyro_rotor.core.steady import steady_motion
from gyro_rotor.errors import NoSteadyMotionError

HELP = 'print the steady motions (solution I; II on both branches, exact and eq. 22)'


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``steady``."""
    p.add_argument('scene', nargs='?', default='precession', help='scene name or path')
    p.add_argument('--theta0', type=float, default=None,
                   help="tilt of solution II [rad] (default: the scene's, else 0.1)")
    p.add_argument('--set', action='append', default=[], metavar='NAME=VALUE')


def run(args: argparse.Namespace) -> int:
    """Print both branches; exit 1 if solution II does not exist at theta0."""
    scene = load_scene(args.scene, overrides=parse_sets(args.set))
    p = scene.params
    theta0 = args.theta0
    if theta0 is None:
        theta0 = scene.initial.theta0 if scene.initial.theta0 > 0 else 0.1
    print(f'scene {scene.name}: Omega0 = {p.Omega0:g} rad/s, I = {p.I:g} kg m^2, '
          f'C_R = {p.C_R:g}, G s = {p.Gs:g} N m, c_theta = {p.c_theta:g} N m/rad')
    print('  I:  theta = 0, psidot = 0, rotor at Omega0 about the vertical, housing at rest')
    status = 0
    for branch in (1, 2):
        try:
            sm = steady_motion(p, theta0, branch)
        except NoSteadyMotionError as err:
            print(f'  II branch {branch}: {err}')
            status = 1
            continue
        print(f'  {sm.name}: theta0 = {sm.theta0:.6g} rad, psidot0 = {sm.psidot0:.12g} rad/s '
              f'(exact); eq. (22) corrected: {sm.psidot0_eq22:.12g} rad/s; relative '
              f'difference {sm.relative_difference:+.3e}')
    return status
