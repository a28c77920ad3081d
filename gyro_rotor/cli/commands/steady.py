"""``gyro-rotor steady SCENE``: the steady motions of the scene's system."""

from __future__ import annotations

import argparse

from gyro_rotor.cli.util import load_scene_with_sets
from gyro_rotor.errors import NotApplicableError, ParameterError

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
    """Print the steady motions the scene's system offers; an ERROR if one is not found."""
    scene = load_scene_with_sets(args.scene, args.set, check=False)
    try:
        st = scene.system.steady_motions(args.theta0, scene.name)
    except NotApplicableError as err:       # the option that gave it
        raise ParameterError(f'--{err}: set that with --set steady.q=[...]') from None
    print(f'scene {scene.name}: system {scene.system_name}; {st.head}')
    for line in st.lines:
        print(f'  {line}')
    if not st.found:        # bad input (the tilt asked for, the scene's guess): one ERROR line
        raise ParameterError(_not_found(st.lines, scene.name, args.theta0))
    return 0


def _not_found(lines: list[str], scene: str, theta0: float | None) -> str:
    """Return the one-line reason no steady motion was found (each distinct reason once)."""
    why = []
    for line in lines:
        if 'no steady motion' in line:
            text = line.split(': ', 1)[1] if line.startswith('II branch') else line
            if text not in why:
                why.append(text)
    given = '' if theta0 is None else f' (--theta0 {theta0:g})'
    return f'scene {scene}{given}: ' + ('; '.join(why) or 'no steady motion found')
