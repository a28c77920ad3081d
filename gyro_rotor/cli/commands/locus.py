"""``gyro-rotor locus SCENE``: root locus over K_D, the asymptotes and claims (a) to (d)."""

from __future__ import annotations

import argparse
import csv
import json
import math

from gyro_rotor.cli.util import check_output_file, on_system
from gyro_rotor.errors import ParameterError
from gyro_rotor.linear.locus import check_claims, default_grid, root_locus
from gyro_rotor.linear.spectrum import _tol_re
from gyro_rotor.linear.system import linearize_scene
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
    p.add_argument('--drive', default=None, metavar='ROTOR',
                   help="a system file's scene: vary only this rotor's K_D (default: all)")


def _claims_doc(scene, cr) -> dict:
    """Return the JSON keys every system's locus has: scene, system, claims, K_D*, meetings."""
    return {'scene': scene.name, 'system': scene.system_name,
            'claims': {k: {'statement': c.statement, 'holds': c.holds, 'detail': c.detail,
                           'exception': c.exception, 'data': c.data}
                       for k, c in cr.claims.items()},
            'K_D_star': cr.K_D_star, 'meetings': [mt.as_dict() for mt in cr.meetings],
            'meeting_points': [mt.lam for mt in cr.meetings]}


def _print_claims(cr) -> None:
    """Print claims (a) to (d) and every meeting K_D* (every system the same way)."""
    for key, c in cr.claims.items():
        print(f'  ({key}) {"PASS" if c.holds else "FAIL"}: {c.statement}\n      {c.detail}')
        if c.exception:
            print(f'      expected exception: {c.exception}')
    for mt in cr.meetings:
        print(f'  K_D* = {mt.K_D:.10g} N m s/rad: {mt.kind}, double root at {mt.lam:.8g} 1/s'
              + ('' if mt.verified else ' (NOT verified)'))


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


def _run_centrifuge(args: argparse.Namespace, scene) -> int:
    """Compute, print the claims, write the requested files; 0 if all claims hold, else 2."""
    one = linearize_scene(scene, drive=args.drive)     # refuses --drive: one drive
    for path in (args.csv, args.json, args.out):
        if path:
            check_output_file(path)
    lin = one.analytic
    p, sm, model = lin.params, lin.motion, lin.model
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
    _print_claims(cr)
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
        doc.update(_claims_doc(scene, cr))
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


def _run_system(args, scene) -> int:
    """Root locus over K_D (all drives, or --drive), every meeting and claims (a) to (d)."""
    from gyro_rotor.linear.system import check_claims
    for path, suf in ((args.json, ('.json',)), (args.csv, ('.csv',)), (args.out, ('.png',))):
        if path:
            check_output_file(path, suf)
    if args.points < 2 or args.points > 100_000:
        raise ParameterError(f'--points must be 2..100000, got {args.points}')
    lin = linearize_scene(scene, drive=getattr(args, 'drive', None))
    claims = check_claims(lin)
    scale = max(1.0, float(np.abs(np.linalg.eigvals(lin.A0)).max()))
    K_ref = scale / float(lin.fast_rates.min())
    lo = args.kd_min or 1e-4 * K_ref
    hi = args.kd_max or 1e4 * K_ref
    if not (0 < lo < hi and math.isfinite(hi)):
        raise ParameterError(f'need 0 < --kd-min < --kd-max, got {lo}, {hi}')
    grid = np.geomspace(lo, hi, args.points)
    roots = np.array([np.sort_complex(lin.eig(K)) for K in grid])
    print(f'scene {scene.name}: root locus over K_D of '
          f'{args.drive if getattr(args, "drive", None) else "all drives"} '
          f'({grid[0]:.3g} .. {grid[-1]:.3g}, {len(grid)} points)')
    _print_claims(claims)
    if args.json:
        doc = {**_claims_doc(scene, claims), 'drive': getattr(args, 'drive', None),
               'structural_zero_roots': claims.structural_zero_roots,
               'K_D': grid.tolist(),
               'roots': [[[z.real, z.imag] for z in row] for row in roots]}
        with open(args.json, 'w', encoding='utf-8') as f:
            json.dump(doc, f, indent=1)
    if args.csv:
        with open(args.csv, 'w', encoding='utf-8') as f:
            f.write('K_D,branch,re,im\n')
            for K, row in zip(grid, roots):
                for j, z in enumerate(row):
                    f.write(f'{K!r},{j},{z.real!r},{z.imag!r}\n')
    if args.out:
        _plot_system_locus(args.out, lin, claims, scene.name, float(grid[0]), float(grid[-1]))
    return 0 if claims.all_hold else CLAIM_FAILS


def _plot_system_locus(path, lin, claims, name, K_lo, K_hi) -> None:
    try:
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.pyplot as plt
    except ImportError:
        raise ParameterError('--out needs matplotlib') from None
    from gyro_rotor.linear.locus_plot import general_locus_figure
    fig = general_locus_figure(lin, claims, K_lo=K_lo, K_hi=K_hi,
                               title=f'root locus over K_D: scene {name}')
    fig.savefig(path)
    plt.close(fig)
    print(f'  wrote {path}')


def run(args: argparse.Namespace) -> int:
    """Run ``locus`` on the scene's system: the centrifuge's or a system file's."""
    return on_system(args, _run_centrifuge, _run_system)
