"""``gyro-rotor eig SCENE``: the named modes about the scene's steady motion and the verdict."""

from __future__ import annotations

import argparse
import math

from gyro_rotor.cli.util import check_output_file, load_scene_with_sets, write_json

HELP = 'eigenvalues, named modes, drive penetration and the stability verdict of a scene'


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``eig``."""
    p.add_argument('scene', nargs='?', default='precession', help='scene name or path')
    p.add_argument('--set', action='append', default=[], metavar='NAME=VALUE',
                   help='override a scene key, e.g. --set K_D=0.1')
    p.add_argument('--json', default=None, metavar='FILE', help='also write the modes as JSON')


def run(args: argparse.Namespace) -> int:
    """Print the modes about the scene's steady motion (one line per complex pair), the verdict.

    Every scene alike: the modes its linearization offers (:func:`assess`), a real part
    within the root's resolution (:mod:`gyro_rotor.linear.roundoff`) printed as 0 and
    the mode as undamped (no decay time from round-off), the verdict of
    :func:`gyro_rotor.linear.stability.judge`.
    """
    # imported here, not at the top: ``gyro-rotor --help`` loads every command's module
    from gyro_rotor.linear.roundoff import decay_text, fmt_re, shown
    from gyro_rotor.linear.stability import ModeKind
    from gyro_rotor.linear.system import assess, linearize_scene
    import numpy as np

    if args.json:
        check_output_file(args.json)
    scene = load_scene_with_sets(args.scene, args.set)
    lin = linearize_scene(scene)
    ms, v = assess(lin)
    ms = sorted(ms, key=lambda m: (m.kind == ModeKind.ZERO, -shown(m.eigenvalue.real,
                                                                   m.resolution),
                                   m.eigenvalue.imag))
    print(f'scene {scene.name}: system {scene.system_name} about {lin.about}; K_D = '
          f'{", ".join(f"{k:g}" for k in lin.K_all)}')
    print(f'  state: ({", ".join(lin.names)})')
    print(f'  {"mode":40s} {"Re [1/s]":>13s} {"Im [rad/s]":>12s} {"f [Hz]":>9s} '
          f'{"zeta":>10s} {"decay time":>13s} {"dRe/dK_D":>11s}  reached')
    for m in ms:
        lam, r = m.eigenvalue, m.resolution
        if lam.imag < -r:
            continue                     # a complex pair once, Im >= 0
        im = shown(abs(lam.imag), r)
        decay = '-' if m.kind == ModeKind.ZERO else decay_text(lam.real, r)
        # a root of a zero cluster that stays defective once the resting states are out
        # (spectrum.zero_K_sensitivities) splits like sqrt(K_D): no first-order sensitivity
        dre = f'{m.dRe_dKD:+11.4e}' if math.isfinite(m.dRe_dKD) else f'{"not defined":>11s}'
        print(f'  {m.name:40s} {fmt_re(lam.real, r)} {im:12.6f} {im / (2 * np.pi):9.4f} '
              f'{m.zeta:10.3e} {decay:>13s} {dre}  '
              f'{"yes" if m.reached_by_drive else "no"}')
    sa = shown(v.spectral_abscissa, v.slowest_resolution) if v.slowest_mode else 0.0
    if v.slowest_mode:
        print(f'  spectral abscissa {fmt_re(sa, 0.0, 0).strip() if sa else "0"} 1/s (slowest: '
              f'{v.slowest_mode}; a |Re| within the resolution of its root, about '
              f'{v.slowest_resolution:.1e} 1/s here, prints as 0)')
    print(f'  verdict: {v.verdict}: {v.reason}')
    if args.json:
        doc = {'scene': scene.name, 'system': scene.system_name, 'about': lin.about,
               'K_D': lin.K_all.tolist(), 'state_names': list(lin.names),
               'eigenvalues': [[float(x.real), float(x.imag)]
                               for x in np.linalg.eigvals(lin.A_scene())],
               'modes': [{**m.as_dict(), 're': float(m.eigenvalue.real),
                          'im': float(m.eigenvalue.imag),
                          'reached': bool(m.reached_by_drive), 'damped': bool(m.is_damped),
                          'structural_zero': m.kind == ModeKind.ZERO,
                          'undamped': bool(abs(m.eigenvalue.real) <= m.resolution)}
                         for m in ms],
               # the number itself, with the resolution of its root beside it
               'spectral_abscissa': float(v.spectral_abscissa),
               'spectral_abscissa_resolution': float(v.slowest_resolution),
               'slowest_mode': v.slowest_mode, 'verdict': str(v.verdict),
               'marginal_modes': list(v.marginal_modes), 'reason': v.reason}
        # no default=: a value json cannot write is an error, never silently a string
        write_json(args.json, doc)
        print(f'  wrote {args.json}')
    return 0
