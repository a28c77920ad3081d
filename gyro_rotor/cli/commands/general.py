"""The commands simulate, steady, eig, locus and tune for general scenes (a ``system`` key).

:mod:`gyro_rotor.cli.main` sends a general scene here; centrifuge scenes keep their own
commands. Each function takes the parsed arguments of its command and returns the exit
status.
"""

from __future__ import annotations

import argparse
import json
import math

from gyro_rotor.cli.util import check_output_file, parse_sets, write_output
from gyro_rotor.errors import ParameterError
import numpy as np

__all__ = ['handles', 'extend_parser', 'dispatch', 'RUNNERS', 'csv_columns']


def handles(scene) -> bool:
    """Return True if ``scene`` names a general scene (a file with a ``system`` key)."""
    from gyro_rotor.core.scene import load_scene
    return scene is not None and not load_scene(scene, check=False).builtin


def extend_parser(command: str, p: argparse.ArgumentParser) -> None:
    """Add the options only general scenes have (``locus --drive ROTOR``)."""
    if command == 'locus':
        p.add_argument('--drive', default=None, metavar='ROTOR',
                       help="general scenes: vary only this rotor's K_D (default: all)")


def _scene(args, check: bool = True):
    from gyro_rotor.core.scene import load_scene
    overrides = parse_sets(getattr(args, 'set', []))
    if getattr(args, 't_end', None) is not None:
        overrides['t_end'] = args.t_end
    return load_scene(args.scene, overrides=overrides, check=check)


def csv_columns(system) -> list[str]:
    """CSV columns: t, each coordinate and NAME_dot, each z_ROTOR and zdot_ROTOR, E*, r."""
    cols = ['t']
    for c in system.coordinates:
        cols += [c, f'{c}_dot']
    for r in system.rotors:
        cols += [f'z_{r}', f'zdot_{r}']
    return cols + ['E_star', 'residual']


def simulate(args) -> int:
    """Simulate a general scene; print a summary, write the CSV."""
    if args.out:
        check_output_file(args.out, ('.csv',), overwrite=getattr(args, 'force', False))
    from gyro_rotor.numerics.general import integrate, METHODS
    if args.method not in ('auto',) + METHODS:
        raise ParameterError(f"general scenes integrate with auto, {', '.join(METHODS)} (the "
                             f"project's integrators that need only the right-hand side), "
                             f'got --method {args.method}')
    if not (math.isfinite(args.rate) and args.rate > 0):
        raise ParameterError(f'--rate must be positive, got {args.rate}')
    scene = _scene(args)
    model = scene.make_model()
    n_samples = int(math.floor(scene.t_end * args.rate + 1e-9)) + 1
    if n_samples > 10_000_000:
        raise ParameterError(f'{n_samples} samples asked for; at most 10000000')
    te = np.arange(n_samples) / args.rate if n_samples > 1 else np.array([0.0, scene.t_end])
    run = integrate(model, scene.initial_state(model), te, method=args.method,
                    rtol=args.rtol or 1e-9, atol=args.atol or 1e-12)
    E = model.energy(run.y)
    r = model.residual(run.y)
    print(f'scene {scene.name}: system {scene.system.name} (n = {model.n}, m = {model.m}'
          f'{", locked " + ", ".join(scene.locked) if scene.locked else ""}), t_end = '
          f'{scene.t_end} s')
    print(f'  generated code: {"cache" if model.compiled.from_cache else "new"} '
          f'({model.compiled.seconds:.2f} s), {model.compiled.path}')
    print(f'  {run.method}: steps {run.nsteps}, rejected {run.nrejected}, rhs evaluations '
          f'{run.nfev}')
    print(f'  E*(0) = {E[0]:.10g} J, E*(end) = {E[-1]:.10g} J, dissipated D = '
          f'{run.y[-1, model.iD]:.6g} J, max |residual| = {np.abs(r).max():.3g} J')
    if args.out:
        n, m = model.n, model.m
        cols = [te]
        for i in range(n):
            cols += [run.y[:, i], run.y[:, n + i]]
        for k in range(m):
            cols += [run.y[:, 2 * n + k], run.y[:, 2 * n + m + k]]
        data = np.column_stack(cols + [E, r])
        write_output(args.out, lambda tmp: np.savetxt(
            tmp, data, delimiter=',', header=','.join(csv_columns(scene.system)),
            comments='', fmt='%.17g'))
        print(f'  wrote {args.out} ({len(te)} rows)')
    return 0


def steady(args) -> int:
    """Check the scene's steady motion and solve for one from that guess (Newton)."""
    from gyro_rotor.core.scene import steady_residual
    from gyro_rotor.linear.general import solve_steady
    scene = _scene(args, check=False)
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


def eig(args) -> int:
    """Eigenvalues and modes (PBH reach, names) about the scene's steady motion.

    One line per mode (a complex pair once, Im >= 0). A real part within the root's
    resolution (:mod:`gyro_rotor.linear.roundoff`, the rule of every system) prints as 0
    and the mode as undamped: no decay time from round-off.
    """
    from gyro_rotor.linear.general import linearize_scene, modes
    from gyro_rotor.linear.roundoff import decay_text, fmt_re, resolutions
    if args.json:
        check_output_file(args.json, ('.json',))
    scene = _scene(args)
    lin = linearize_scene(scene)
    ms = sorted(modes(lin), key=lambda x: (-x.value.real, x.value.imag))
    lam_r, res_r = resolutions(lin.A_scene(), lin.A_cons)
    res = [float(res_r[int(np.argmin(np.abs(lam_r - x.value)))]) for x in ms]
    shown = [(x, r) for x, r in zip(ms, res) if x.value.imag >= -r]
    print(f'scene {scene.name}: {len(ms)} roots of system {scene.system.name} about its steady '
          f'motion, K_D = {lin.K_each.tolist()} (one line per complex pair)')
    print(f'  {"mode":36s} {"Re [1/s]":>13s} {"Im [rad/s]":>13s} {"f [Hz]":>9s} '
          f'{"decay time":>13s}  reached')
    for x, r in shown:
        im = abs(x.value.imag) if abs(x.value.imag) > r else 0.0
        decay = '-' if x.structural_zero else decay_text(x.value.real, r)
        print(f'  {x.name:36s} {fmt_re(x.value.real, r)} {im:13.6f} {im / (2 * math.pi):9.4f} '
              f'{decay:>13s}  {"yes" if x.reached else "no"}')
    judged = [(x, r) for x, r in zip(ms, res) if not x.structural_zero]
    if judged:
        x, r = max(judged, key=lambda t: t[0].value.real)
        sa = x.value.real if abs(x.value.real) > r else 0.0
        print(f'  spectral abscissa {fmt_re(sa, 0.0, 0).strip() if sa else "0"} 1/s (slowest: '
              f'{x.name}; a |Re| within the resolution of its root, about {r:.1e} 1/s '
              'here, prints as 0)')
    undamped = [f'{x.name} at {abs(x.value.imag) / (2 * math.pi):.4g} Hz' for x, r in shown
                if not x.structural_zero and abs(x.value.real) <= r]
    if undamped:
        print(f'  undamped (Re = 0 within round-off): {", ".join(undamped)}')
    if args.json:
        doc = {'scene': scene.name, 'system': scene.system.name,
               'K_D': lin.K_each.tolist(),
               'eigenvalues': [[x.value.real, x.value.imag] for x in ms],
               'modes': [{'re': x.value.real, 'im': x.value.imag, 'reached': x.reached,
                          'name': x.name, 'structural_zero': x.structural_zero,
                          'resolution': r, 'undamped': abs(x.value.real) <= r}
                         for x, r in zip(ms, res)]}
        with open(args.json, 'w', encoding='utf-8') as f:
            json.dump(doc, f, indent=1)
    return 0


def locus(args) -> int:
    """Root locus over K_D (all drives, or --drive), every meeting and claims (a) to (d)."""
    from gyro_rotor.cli.commands.locus import CLAIM_FAILS
    from gyro_rotor.linear.general import check_claims, linearize_scene
    for path, suf in ((args.json, ('.json',)), (args.csv, ('.csv',)), (args.out, ('.png',))):
        if path:
            check_output_file(path, suf)
    if args.points < 2 or args.points > 100_000:
        raise ParameterError(f'--points must be 2..100000, got {args.points}')
    scene = _scene(args)
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
    for key, c in claims.claims.items():
        print(f'  ({key}) {"PASS" if c.holds else "FAIL"}: {c.statement}\n      {c.detail}')
        if c.exception:
            print(f'      expected exception: {c.exception}')
    for x in claims.meetings:
        print(f'  K_D* = {x.K_D:.10g} N m s/rad: {x.kind}, double root at {x.lam:.8g} 1/s'
              + ('' if x.verified else ' (NOT verified)'))
    if args.json:
        details = {'net_meetings': claims.claims['d'].data['net_meetings'],
                   'structural_zero_roots': claims.structural_zero_roots,
                   **{k: c.data for k, c in claims.claims.items()}}
        doc = {'scene': scene.name, 'system': scene.system.name,
               'drive': getattr(args, 'drive', None),
               'K_D_star': claims.K_D_star,
               'meeting_points': [x.lam for x in claims.meetings],
               'meetings': [x.as_dict() for x in claims.meetings],
               'claims': {k: c.holds for k, c in claims.claims.items()},
               'details': details,
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
        _plot_locus(args.out, lin, claims, scene.name, float(grid[0]), float(grid[-1]))
    return 0 if claims.all_hold else CLAIM_FAILS


def _plot_locus(path, lin, claims, name, K_lo, K_hi) -> None:
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


def tune(args) -> int:
    """Find the common K_D of all drives that makes the slowest reached mode decay fastest."""
    from gyro_rotor.linear.general import _unreached, linearize_scene
    scene = _scene(args)
    if getattr(args, 'K_S', None) is not None:
        scene = scene.with_drives(K_S=args.K_S)
    lin = linearize_scene(scene)
    un, zeros, scale = _unreached(lin)

    def slowest(K):
        lam = lin.eig(K)
        keep = np.abs(lam) > 1e-7 * scale
        for u in un:
            keep &= np.abs(lam - u) > 1e-7 * scale
        return float(lam[keep].real.max()) if np.any(keep) else 0.0
    K_ref = scale / float(lin.fast_rates.min())
    grid = np.geomspace(1e-6 * K_ref, 1e4 * K_ref, 401)
    vals = np.array([slowest(K) for K in grid])
    i = int(np.argmin(vals))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    g = (math.sqrt(5) - 1) / 2
    for _ in range(80):
        c, d = b - g * (b - a), a + g * (b - a)
        if slowest(c) < slowest(d):
            b = d
        else:
            a = c
    K = 0.5 * (a + b)
    print(f'scene {scene.name}: best common K_D = {K:.6g} N m s/rad: slowest reached mode '
          f'decays at {-slowest(K):.6g} 1/s (time constant {-1 / slowest(K):.4g} s)')
    print(f"  at the scene's K_D = {lin.K_each.tolist()}: slowest reached decay "
          f'{-float(max(slowest(k) for k in lin.K_each)):.6g} 1/s')
    if un.size:
        print(f'  {un.size} roots are not reached by the drives and stay undamped at every '
              f'K_D: {", ".join(f"{x.imag:.6g}j" for x in un if x.imag > 0)}')
    return 0


RUNNERS = {'simulate': simulate, 'steady': steady, 'eig': eig, 'locus': locus, 'tune': tune}


def dispatch(args) -> int | None:
    """Run the general form of ``args.command`` for a general scene; None for the others."""
    if args.command not in RUNNERS:
        return None
    if handles(getattr(args, 'scene', None)):
        return int(RUNNERS[args.command](args) or 0)
    if getattr(args, 'drive', None) is not None:
        raise ParameterError('--drive is for general scenes (with a system key); the '
                             'centrifuge has one drive')
    return None
