"""``gyro-rotor steady SCENE``: steady motions I and II, exact and by the paper's eq. (22)."""

from __future__ import annotations

import argparse
import json

from gyro_rotor.cli.util import on_system
from gyro_rotor.core.steady import steady_motion
from gyro_rotor.errors import NoSteadyMotionError

HELP = 'print the steady motions (solution I; II on both branches, exact and eq. 22)'


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``steady``."""
    p.add_argument('scene', nargs='?', default='precession', help='scene name or path')
    p.add_argument('--theta0', type=float, default=None,
                   help="tilt of solution II [rad] (default: the scene's, else 0.1)")
    p.add_argument('--set', action='append', default=[], metavar='NAME=VALUE')


def _run_centrifuge(args: argparse.Namespace, scene) -> int:
    """Print both branches; exit 1 if solution II does not exist at theta0."""
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


def _run_system(args, scene) -> int:
    """Check the scene's steady motion and solve for one from that guess (Newton)."""
    from gyro_rotor.core.scene import steady_residual
    from gyro_rotor.linear.newton import solve_steady
    acc = steady_residual(scene)
    names = [f'{c}_ddot' for c in scene.system.coordinates] + [
        f'zddot_{r}' for r in scene.system.rotors]
    print(f'scene {scene.name}: steady guess q = {list(scene.steady_q)}, qdot = '
          f'{list(scene.steady_qdot)}, z = {list(scene.steady_z)}')
    print('  accelerations there: ' + ', '.join(f'{a} = {v:.3g}' for a, v in zip(names, acc)))
    q, z, res = solve_steady(scene)
    ok = res <= 1e-9 * max(1.0, scene.make_model().rate())
    print(f'  {"steady motion" if ok else "no steady motion found"} (Newton, qdot held): '
          f'q = {q.tolist()}, z = {z.tolist()}, largest acceleration {res:.3g}')
    if ok:
        print('  for the scene: steady: {q: ' + json.dumps(q.tolist()) + ', z: '
              + json.dumps(z.tolist()) + '}')
    return 0 if ok else 1


def run(args: argparse.Namespace) -> int:
    """Run ``steady`` on the scene's system: the centrifuge's or a system file's."""
    return on_system(args, _run_centrifuge, _run_system, check=False)
