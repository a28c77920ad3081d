"""``gyro-rotor simulate SCENE``: integrate a scene and print its summary."""

from __future__ import annotations

import argparse

from gyro_rotor.cli.util import check_output_file, load_scene_with_sets, write_output
from gyro_rotor.numerics.simulate import DEFAULT_RATE, simulate

HELP = 'simulate a scene (name or YAML path) and print a summary'


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``simulate``."""
    p.add_argument('scene', nargs='?', default='precession', help='scene name or path')
    p.add_argument('--t-end', type=float, default=None, help='duration [s]')
    p.add_argument('--set', action='append', default=[], metavar='NAME=VALUE',
                   help='override a scene key, e.g. --set K_D=0.1 --set initial.dzdot=2.0')
    p.add_argument('--rate', type=float, default=DEFAULT_RATE, help='output sample rate [Hz]')
    p.add_argument('--out', default=None,
                   help='write samples to FILE.csv (header: name [unit]) or FILE.npz')
    p.add_argument('--method', default='auto', help='integration method (default: auto)')
    p.add_argument('--rtol', type=float, default=None, help='relative tolerance')
    p.add_argument('--atol', type=float, default=None, help='absolute tolerance')
    p.add_argument('--force', action='store_true', help='overwrite an existing --out file')


def _pole_slips(tr) -> str:
    """Pole slips of a synchronous drive (z over a potential maximum), '' without poles."""
    if not any(tr.scene.pole_pairs):
        return ''
    from gyro_rotor.analysis.checks import RotorAnalyzer, samples_from_trajectory
    ana = RotorAnalyzer(tr.scene, window_s=0)
    ana.add_many(samples_from_trajectory(tr))
    r = ana.result()
    return f'  pole slips:   {r.pole_slips} (z passed a maximum of the drive potential)'


def run(args: argparse.Namespace) -> int:
    """Run the simulation and print the summary."""
    if args.out:
        check_output_file(args.out, ('.csv', '.npz'), overwrite=args.force)
    scene = load_scene_with_sets(args.scene, args.set)
    tr = simulate(scene, t_end=args.t_end, rate=args.rate, method=args.method,
                  rtol=args.rtol, atol=args.atol)
    if args.out:
        write_output(args.out, tr.save)
    s = tr.summary()
    print(f"scene {s['scene']} (model {s['model']}), {s['t_end']:g} s with {s['method']} "
          f"({s['setting']})")
    if s['method_reason']:
        print(f"  auto: {s['method']}, {s['method_reason']}")
    print('  final state:  ' + ', '.join(f'{k} {v:.9g} {u}' for k, v, u in s['final']))
    print(f"  E*:           first {s['E_star_first']:.12g} J, last {s['E_star_last']:.12g} J")
    print(f"  max |residual| {s['max_abs_residual']:.3e} J, max ||q|-1| "
          f"{s['max_qnorm_drift']:.3e}")
    slips = _pole_slips(tr)
    if slips:
        print(slips)
    print(f"  {s['method']}: steps {s['nsteps']}, {s['nfev']} RHS evaluations, "
          f"{s['samples']} samples, wall time {s['wall_time']:.3f} s")
    if args.out:
        print(f'  wrote {args.out} ({s["samples"]} rows)')
    return 0
