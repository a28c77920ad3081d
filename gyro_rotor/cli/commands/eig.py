"""``gyro-rotor eig SCENE``: the named modes about the scene's steady motion and the verdict."""

from __future__ import annotations

import argparse
import json
import math

from gyro_rotor.cli.util import check_output_file, on_system
from gyro_rotor.errors import ParameterError
from gyro_rotor.linear.roundoff import decay_text, floor, fmt_re, resolutions
from gyro_rotor.linear.stability import analyze, ModeKind
from gyro_rotor.linear.system import linearize_scene, modes
import numpy as np

HELP = 'eigenvalues, named modes, drive penetration and the stability verdict of a scene'


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``eig``."""
    p.add_argument('scene', nargs='?', default='precession', help='scene name or path')
    p.add_argument('--set', action='append', default=[], metavar='NAME=VALUE',
                   help='override a scene key, e.g. --set K_D=0.1')
    p.add_argument('--json', default=None, metavar='FILE', help='also write the modes as JSON')


def _run_centrifuge(args: argparse.Namespace, scene) -> int:
    """Print the mode table and the verdict."""
    if args.json:
        check_output_file(args.json)
    one = linearize_scene(scene).analytic
    p, sm, model = one.params, one.motion, one.model
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
    res = floor(one.A0)

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
            json.dump({'scene': scene.name, 'system': scene.system_name, 'model': model,
                       'branch': sm.branch, 'theta0': sm.theta0, 'psidot0': sm.psidot0,
                       'K_D': r.K_D, 'state_names': list(r.state_names),
                       'modes': [{**m.as_dict(), 're': m.eigenvalue.real,
                                  'im': m.eigenvalue.imag, 'reached': m.reached_by_drive}
                                 for m in r.modes],
                       'spectral_abscissa': r.spectral_abscissa, 'verdict': r.verdict,
                       'marginal_modes': r.marginal_modes, 'reason': r.reason}, f, indent=1,
                      default=str)
        print(f'  wrote {args.json}')
    return 0


def _run_system(args, scene) -> int:
    """Eigenvalues and modes (PBH reach, names) about the scene's steady motion.

    One line per mode (a complex pair once, Im >= 0). A real part within the root's
    resolution (:mod:`gyro_rotor.linear.roundoff`, the rule of every system) prints as 0
    and the mode as undamped: no decay time from round-off.
    """
    if args.json:
        check_output_file(args.json, ('.json',))
    lin = linearize_scene(scene)
    ms = sorted(modes(lin), key=lambda x: (-x.eigenvalue.real, x.eigenvalue.imag))
    lam_r, res_r = resolutions(lin.A_scene(), lin.A_cons)
    res = [float(res_r[int(np.argmin(np.abs(lam_r - x.eigenvalue)))]) for x in ms]
    shown = [(x, r) for x, r in zip(ms, res) if x.eigenvalue.imag >= -r]
    print(f'scene {scene.name}: {len(ms)} roots of system {scene.system.name} about its steady '
          f'motion, K_D = {lin.K_each.tolist()} (one line per complex pair)')
    print(f'  {"mode":36s} {"Re [1/s]":>13s} {"Im [rad/s]":>13s} {"f [Hz]":>9s} '
          f'{"decay time":>13s}  reached')
    for x, r in shown:
        im = abs(x.eigenvalue.imag) if abs(x.eigenvalue.imag) > r else 0.0
        decay = '-' if x.kind == ModeKind.ZERO else decay_text(x.eigenvalue.real, r)
        print(f'  {x.name:36s} {fmt_re(x.eigenvalue.real, r)} {im:13.6f} '
              f'{im / (2 * math.pi):9.4f} '
              f'{decay:>13s}  {"yes" if x.reached_by_drive else "no"}')
    judged = [(x, r) for x, r in zip(ms, res) if not x.kind == ModeKind.ZERO]
    sa = 0.0
    if judged:
        x, r = max(judged, key=lambda t: t[0].eigenvalue.real)
        sa = x.eigenvalue.real if abs(x.eigenvalue.real) > r else 0.0
        print(f'  spectral abscissa {fmt_re(sa, 0.0, 0).strip() if sa else "0"} 1/s (slowest: '
              f'{x.name}; a |Re| within the resolution of its root, about {r:.1e} 1/s '
              'here, prints as 0)')
    undamped = [f'{x.name} at {abs(x.eigenvalue.imag) / (2 * math.pi):.4g} Hz' for x, r in shown
                if not x.kind == ModeKind.ZERO and abs(x.eigenvalue.real) <= r]
    if undamped:
        print(f'  undamped (Re = 0 within round-off): {", ".join(undamped)}')
    if args.json:
        doc = {'scene': scene.name, 'system': scene.system_name,
               'K_D': lin.K_each.tolist(), 'spectral_abscissa': sa,
               'eigenvalues': [[x.eigenvalue.real, x.eigenvalue.imag] for x in ms],
               'modes': [{'re': x.eigenvalue.real, 'im': x.eigenvalue.imag,
                          'reached': x.reached_by_drive,
                          'name': x.name, 'structural_zero': x.kind == ModeKind.ZERO,
                          'resolution': r, 'undamped': abs(x.eigenvalue.real) <= r}
                         for x, r in zip(ms, res)]}
        with open(args.json, 'w', encoding='utf-8') as f:
            json.dump(doc, f, indent=1)
    return 0


def run(args: argparse.Namespace) -> int:
    """Run ``eig`` on the scene's system: the centrifuge's or a system file's."""
    return on_system(args, _run_centrifuge, _run_system)
