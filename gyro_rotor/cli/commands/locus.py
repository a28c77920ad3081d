"""``gyro-rotor locus SCENE``: root locus over K_D, the asymptotes and claims (a) to (d)."""

from __future__ import annotations

import argparse
import csv
import json

from gyro_rotor.cli.util import check_output_file, parse_sets
from gyro_rotor.core.scene import load_scene
from gyro_rotor.errors import ParameterError
from gyro_rotor.linear.linearize import linearize
from gyro_rotor.linear.locus import check_claims, default_grid, root_locus
from gyro_rotor.linear.spectrum import _tol_re
from gyro_rotor.linear.stability import scene_operating_point
import numpy as np

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
    p.add_argument('--csv', default=None, metavar='FILE', help='rows K_D, branch, re, im')
    p.add_argument('--json', default=None, metavar='FILE', help='locus, asymptotes, claims')
    p.add_argument('--kd-min', type=float, default=None, help='smallest K_D > 0 of the grid')
    p.add_argument('--kd-max', type=float, default=None, help='largest K_D of the grid')
    p.add_argument('--points', type=int, default=281,
                   help=f'points of the log grid (2 to {MAX_POINTS})')


def _grid(args, params) -> np.ndarray | None:
    d = default_grid(params)
    lo = d[1] if args.kd_min is None else args.kd_min
    hi = d[-1] if args.kd_max is None else args.kd_max
    for name, v in (('--kd-min', lo), ('--kd-max', hi)):
        if not np.isfinite(v) or v <= 0:
            raise ParameterError(f'{name} must be positive (K_D >= 0), got {v!r}')
    if hi <= lo:
        raise ParameterError(f'--kd-max ({hi:g}) must exceed --kd-min ({lo:g})')
    if not 2 <= args.points <= MAX_POINTS:
        raise ParameterError(f'--points must be from 2 to {MAX_POINTS}, got {args.points}')
    return np.concatenate([[0.0], np.geomspace(lo, hi, args.points)])


def run(args: argparse.Namespace) -> int:
    """Compute, print the claims, write the requested files; 0 if all claims hold, else 2."""
    for path in (args.csv, args.json, args.out):
        if path:
            check_output_file(path)
    scene = load_scene(args.scene, overrides=parse_sets(args.set))
    p, sm, model = scene_operating_point(scene)
    lin = linearize(p, sm, model)
    grid = _grid(args, p)
    cr = check_claims(lin, grid)
    loc = cr.locus
    if cr.K_D_star is not None:
        # the branch point K_D* is a square-root singularity: cluster points around it
        d = np.concatenate([[0.0], np.geomspace(1e-6, 0.3, 120)])
        near = cr.K_D_star * np.concatenate([1.0 - d[1:], 1.0 + d])
        grid = np.unique(np.concatenate([loc.K_D, near[near > 0]]))
        loc = root_locus(lin, grid)
    print(f'scene {scene.name} (model {model}) about {sm.name}; K_D from 0 to '
          f'{loc.K_D[-1]:.4g} N m s/rad ({len(loc.K_D)} values)')
    for key, c in cr.claims.items():
        print(f'  ({key}) {"PASS" if c.holds else "FAIL"}: {c.statement}\n      {c.detail}')
        if c.exception:
            print(f'      expected exception: {c.exception}')
    for mt in cr.meetings:
        print(f'  K_D* = {mt.K_D:.10g} N m s/rad: {mt.kind}, double root at {mt.lam:.8g} 1/s'
              + ('' if mt.verified else ' (NOT verified)'))
    for r in cr.regimes:
        print(f"  regime: {r['regime']}: K_D in [{r['K_D_from']:.4g}, {r['K_D_to']:.4g}]")
    tol = _tol_re(lin)
    print('  asymptotes (K_D -> infinity): ' + ', '.join(
        f'{nm} ' + (f'{z.real:+.4g}' if abs(z.real) > tol else '0') + f'{z.imag:+.6g}j'
        for z, nm in zip(loc.zeros, loc.zero_labels) if z.imag >= 0)
        + f'; {loc.fast_label} -> -{loc.fast_gain:.6g} K_D')
    if args.csv:
        with open(args.csv, 'w', newline='') as f:
            w = csv.writer(f)
            w.writerow(['K_D', 'branch', 're', 'im'])
            for row in loc.to_rows():
                w.writerow([repr(row[0]), row[1], repr(row[2]), repr(row[3])])
        print(f'  wrote {args.csv}')
    if args.json:
        doc = loc.as_dict()
        doc['claims'] = {k: {'statement': c.statement, 'holds': c.holds, 'detail': c.detail,
                             'exception': c.exception, 'data': c.data}
                         for k, c in cr.claims.items()}
        doc['meetings'] = [mt.as_dict() for mt in cr.meetings]
        doc['meeting_points'] = [mt.lam for mt in cr.meetings]
        doc['K_D_star'] = cr.K_D_star
        doc['breakaway'] = cr.breakaway
        doc['regimes'] = cr.regimes
        with open(args.json, 'w') as f:
            json.dump(doc, f, indent=1, default=str)
        print(f'  wrote {args.json}')
    if args.out:
        from gyro_rotor.linear.locus_plot import plot_root_locus
        plot_root_locus(loc, args.out, claims=cr, K_D_mark=p.K_D if p.K_D > 0 else None,
                        title=f'root locus over K_D: scene {scene.name}, {sm.name}')
        print(f'  wrote {args.out}')
    return 0 if cr.all_hold else CLAIM_FAILS
