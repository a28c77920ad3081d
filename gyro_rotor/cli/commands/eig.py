"""``gyro-rotor eig SCENE``: the named modes about the scene's steady motion and the verdict."""

from __future__ import annotations

import argparse
import json
import math

from gyro_rotor.cli.util import check_output_file, parse_sets
from gyro_rotor.core.scene import load_scene
from gyro_rotor.errors import ParameterError
from gyro_rotor.linear.linearize import linearize
from gyro_rotor.linear.roundoff import floor, fmt_re
from gyro_rotor.linear.stability import analyze, scene_operating_point

HELP = 'eigenvalues, named modes, drive penetration and the stability verdict of a scene'


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``eig``."""
    p.add_argument('scene', nargs='?', default='precession', help='scene name or path')
    p.add_argument('--set', action='append', default=[], metavar='NAME=VALUE',
                   help='override a scene key, e.g. --set K_D=0.1')
    p.add_argument('--json', default=None, metavar='FILE', help='also write the modes as JSON')


def run(args: argparse.Namespace) -> int:
    """Print the mode table and the verdict."""
    if args.json:
        check_output_file(args.json)
    scene = load_scene(args.scene, overrides=parse_sets(args.set))
    p, sm, model = scene_operating_point(scene)
    if p.K_D < 0:   # pragma: no cover -- RotorParams refuses it already
        raise ParameterError(f'K_D must not be negative, got {p.K_D}')
    r = analyze(p, sm, model, scene=scene.name)
    print(f'scene {scene.name} (model {model}), about {sm.name}: theta0 = {sm.theta0:g} rad, '
          f'psidot0 = {sm.psidot0:.9g} rad/s; K_S = {p.K_S:g}, K_D = {p.K_D:g}')
    print(f'  state: ({", ".join(r.state_names)})')
    print(f'  {"mode":40s} {"Re [1/s]":>13s} {"Im [rad/s]":>12s} {"f [Hz]":>9s} '
          f'{"zeta":>10s} {"tau [s]":>10s} {"dRe/dK_D":>11s}  reached')
    # a real part below the eigensolver's resolution is 0, not a result (never 1e-102): the
    # rule of every system (linear/roundoff.py), the floor TOL_RE_REL ||A0|| to which the
    # spectrum's pencil keeps its roots at any K_D
    res = floor(linearize(p, sm, model).A0)

    def re(x: float, width: int = 13) -> str:
        return fmt_re(x, res, width)
    for m in r.modes:
        if abs(m.eigenvalue.real) <= res:
            tau = f'{"undamped" if m.eigenvalue.imag else "inf":>10s}'
        else:
            tau = f'{m.tau:10.4g}' if math.isfinite(m.tau) else f'{"inf":>10s}'
        print(f'  {m.name:40s} {re(m.eigenvalue.real)} {m.eigenvalue.imag:12.6f} '
              f'{m.freq_hz:9.4f} {m.zeta:10.3e} {tau} {m.dRe_dKD:+11.4e}  '
              f'{"yes" if m.reached_by_drive else "no"}')
    print(f'  spectral abscissa {re(r.spectral_abscissa, 0).strip()} 1/s (slowest: '
          f'{r.slowest_mode}; |Re| below {res:.1e} 1/s prints as 0)')
    print(f'  verdict: {r.verdict}: {r.reason}')
    if args.json:
        with open(args.json, 'w') as f:
            json.dump({'scene': scene.name, 'model': model, 'branch': sm.branch,
                       'theta0': sm.theta0, 'psidot0': sm.psidot0, 'K_D': r.K_D,
                       'state_names': list(r.state_names),
                       'modes': [m.as_dict() for m in r.modes],
                       'spectral_abscissa': r.spectral_abscissa, 'verdict': r.verdict,
                       'marginal_modes': r.marginal_modes, 'reason': r.reason}, f, indent=1,
                      default=str)
        print(f'  wrote {args.json}')
    return 0
