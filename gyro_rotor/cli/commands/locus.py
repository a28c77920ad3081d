"""``gyro-rotor locus SCENE``: root locus over K_D, the asymptotes and claims (a) to (d)."""

from __future__ import annotations

import argparse
import csv

from gyro_rotor.cli.util import (check_number, check_output_file, load_scene_with_sets,
                                 write_json, write_output)
from gyro_rotor.errors import NotApplicableError, ParameterError

#: most points of the --points grid (each is an eigen-decomposition, plus tracking)
MAX_POINTS = 100000

HELP = ("root locus over K_D (the paper's figure 2), its asymptotes and claims (a) to (d); "
        'exit 0 if every claim holds, 2 if one fails')
#: exit status when a claim fails (1 is bad input)
CLAIM_FAILS = 2


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``locus``."""
    p.add_argument('scene', nargs='?', default='precession', help='scene name or path')
    p.add_argument('--set', action='append', default=[], metavar='NAME=VALUE')
    p.add_argument('--out', default=None, metavar='FILE.png', help='plot (needs matplotlib)')
    p.add_argument('--csv', default=None, metavar='FILE',
                   help='rows K_D, branch, mode, re, im')
    p.add_argument('--json', default=None, metavar='FILE', help='locus, asymptotes, claims')
    p.add_argument('--kd-min', type=float, default=None,
                   help='smallest K_D > 0 of the grid (default 1e-4 K_ref)')
    p.add_argument('--kd-max', type=float, default=None,
                   help='largest K_D of the grid (default 1e4 K_ref)')
    p.add_argument('--points', type=int, default=281,
                   help=f'points of the log grid (2 to {MAX_POINTS})')
    p.add_argument('--drive', default=None, metavar='ROTOR',
                   help="vary only this rotor's K_D (default: all drives)")


def _print_claims(cr) -> None:
    """Print claims (a) to (d) and every meeting K_D*."""
    for key, c in cr.claims.items():
        word = 'PASS' if c.holds else 'FAIL' if c.applicable else 'NOT APPLICABLE'
        print(f'  ({key}) {word}: {c.statement}\n      {c.detail}')
        if c.exception:
            print(f'      expected exception: {c.exception}')
    for mt in cr.meetings:
        pairs = '' if mt.multiplicity == 1 else f' of {mt.multiplicity} pairs at once'
        what = mt.kind if mt.verified else 'unresolved event'
        print(f'  K_D* = {mt.K_D:.10g} N m s/rad: {what}{pairs}, double root at '
              f'{mt.lam:.8g} 1/s' + ('' if mt.verified else ' (NOT verified: the same on '
                                     'both sides down to round-off, net 0)'))


def _grid(args, lin):
    """Return [0] and the log grid of --points from --kd-min to --kd-max (K_ref: 1e-4, 1e4)."""
    from gyro_rotor.linear.locus import K_ref
    import numpy as np

    K = K_ref(lin)
    lo = 1e-4 * K if args.kd_min is None else args.kd_min
    hi = 1e4 * K if args.kd_max is None else args.kd_max
    for name, v in (('--kd-min', lo), ('--kd-max', hi)):
        # the grid is logarithmic: K_D = 0 is always its first point, added below
        check_number(name, v, low=0.0, low_open=True,
                     what='N m s/rad (the log grid; K_D = 0 is always included)')
    if hi <= lo:
        raise ParameterError(f'--kd-max ({hi:g}) must exceed --kd-min ({lo:g})')
    return np.concatenate([[0.0], np.geomspace(lo, hi, args.points)])


def run(args: argparse.Namespace) -> int:
    """Compute, print the claims, write the requested files; 0 if all claims hold, else 2."""
    # imported here, not at the top: ``gyro-rotor --help`` loads every command's module
    from gyro_rotor.linear.locus import check_claims, regimes, root_locus
    from gyro_rotor.linear.roundoff import shown
    from gyro_rotor.linear.system import linearize_scene

    for path, suffixes in ((args.csv, ()), (args.json, ()), (args.out, ('.png',))):
        if path:
            check_output_file(path, suffixes)
    if not 2 <= args.points <= MAX_POINTS:
        raise ParameterError(f'--points must be from 2 to {MAX_POINTS}, got {args.points}')
    scene = load_scene_with_sets(args.scene, args.set)
    try:
        lin = linearize_scene(scene, drive=args.drive)
    except NotApplicableError as err:       # the option that gave it
        raise ParameterError(f'--{err}') from None
    grid = _grid(args, lin)
    loc = root_locus(lin, grid)
    cr = check_claims(lin)
    print(f'scene {scene.name} (system {scene.system_name}): root locus over K_D of '
          f'{args.drive or "all drives"}, from 0 to {grid[-1]:.4g} N m s/rad '
          f'({len(grid)} values)')
    _print_claims(cr)
    for r in regimes(cr):
        print(f"  regime: K_D in [{r['K_D_from']:.4g}, {r['K_D_to']:.4g}]: "
              f"{r['real_roots']} real roots (of those the drives move)")
    print('  asymptotes (K_D -> infinity): ' + ', '.join(
        f'{nm} {shown(z.real, e):.4g}{z.imag:+.6g}j'
        for z, e, nm in zip(loc.locked, loc.locked_res, loc.locked_labels) if z.imag >= 0)
        + f'; {len(lin.vary)} root(s) to 0 like 1/K_D, {len(lin.vary)} to -infinity like -K_D x '
        + ', '.join(f'{g:.6g}' for g in lin.fast_rates))
    if args.csv:
        def write_csv(path):
            with open(path, 'w', newline='') as f:
                w = csv.writer(f)
                w.writerow(['K_D', 'branch', 'mode', 're', 'im'])
                for row in loc.to_rows():
                    w.writerow([repr(row[0]), row[1], row[2], repr(row[3]), repr(row[4])])
        write_output(args.csv, write_csv)
        print(f'  wrote {args.csv}')
    if args.json:
        doc = {'scene': scene.name, 'system': scene.system_name, 'drive': args.drive,
               'claims': {k: {'statement': c.statement, 'holds': c.holds, 'detail': c.detail,
                              'exception': c.exception, 'data': c.data,
                              'applicable': c.applicable}
                          for k, c in cr.claims.items()},
               'K_D_star': cr.K_D_star, 'meetings': [mt.as_dict() for mt in cr.meetings],
               'meeting_points': [mt.lam for mt in cr.meetings],
               'structural_zero_roots': cr.structural_zero_roots, 'regimes': regimes(cr),
               **loc.as_dict()}
        write_json(args.json, doc)
        print(f'  wrote {args.json}')
    if args.out:
        from gyro_rotor.linear.locus_plot import plot_root_locus
        plot_root_locus(lin, cr, args.out, K_lo=float(grid[1]), K_hi=float(grid[-1]),
                        title=f'root locus over K_D: scene {scene.name}')
        print(f'  wrote {args.out}')
    return 0 if cr.all_hold else CLAIM_FAILS
