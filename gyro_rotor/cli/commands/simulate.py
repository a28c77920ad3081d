"""``gyro-rotor simulate SCENE``: integrate a scene and print its summary."""

from __future__ import annotations

import argparse

from gyro_rotor.cli.util import check_output_file, parse_sets
from gyro_rotor.numerics.simulate import DEFAULT_RATE, simulate

HELP = 'simulate a scene (name or YAML path) and print a summary'


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``simulate``."""
    p.add_argument('scene', nargs='?', default='precession', help='scene name or path')
    p.add_argument('--t-end', type=float, default=None, help='duration [s]')
    p.add_argument('--set', action='append', default=[], metavar='NAME=VALUE',
                   help='override a scene key, e.g. --set K_D=0.1 --set initial.dzdot=2.0')
    p.add_argument('--rate', type=float, default=DEFAULT_RATE, help='output sample rate [Hz]')
    p.add_argument('--out', default=None, help='write samples to FILE.csv or FILE.npz')
    p.add_argument('--method', default='auto', help='integration method (default: auto)')
    p.add_argument('--rtol', type=float, default=None, help='relative tolerance')
    p.add_argument('--atol', type=float, default=None, help='absolute tolerance')


def run(args: argparse.Namespace) -> int:
    """Run the simulation and print the summary."""
    if args.out:
        check_output_file(args.out, ('.csv', '.npz'))
    tr = simulate(args.scene, t_end=args.t_end, rate=args.rate, method=args.method,
                  rtol=args.rtol, atol=args.atol, overrides=parse_sets(args.set))
    if args.out:
        tr.save(args.out)
    s = tr.summary()
    print(f"scene {s['scene']} (model {s['model']}), {s['t_end']:g} s with {s['method']} "
          f"({s['setting']})")
    if s['method_reason']:
        print(f"  auto: {s['method']}, {s['method_reason']}")
    print(f"  final state:  theta {s['theta_end']:.9f} rad, psidot {s['psidot_end']:.9f} "
          f"rad/s, chi {s['chi_end']:.3e} rad, z {s['z_end']:.3e} rad, "
          f"zdot {s['zdot_end']:.3e} rad/s")
    print(f"  E*:           first {s['E_star_first']:.12g} J, last {s['E_star_last']:.12g} J")
    print(f"  max |residual| {s['max_abs_residual']:.3e} J, max ||q|-1| "
          f"{s['max_qnorm_drift']:.3e}")
    print(f"  {s['nfev']} RHS evaluations, {s['samples']} samples, wall time "
          f"{s['wall_time']:.3f} s")
    if args.out:
        print(f'  wrote {args.out}')
    return 0
