"""``gyro-rotor simulate SCENE``: integrate a scene and print its summary.

Exit status: 0; :data:`DIVERGED_OR_UNSTABLE` (2) when the run diverged or grew, said in
the last line: ``DIVERGED:`` where the energy identity broke by the live simulation's guard
(:mod:`gyro_rotor.numerics.guard` with the scene's ``max_residual``) or the integration
stopped early (a non-finite state): the samples before that are kept, summarized and
written; or where the analysis of the samples finds the identity broken by its stricter
limit; ``UNSTABLE:`` where it finds growing motion with the identity sound; 1 for bad input
(``ERROR:``), as every command.
"""

from __future__ import annotations

import argparse

from gyro_rotor.cli.util import (check_number, check_output_file, load_scene_with_sets,
                                 write_output)
from gyro_rotor.node_settings import NODE_KEYS
from gyro_rotor.numerics.guard import describe_break, first_break
from gyro_rotor.numerics.simulate import DEFAULT_RATE, simulate

HELP = ('simulate a scene (name or YAML path) and print a summary; exit 2 if the run '
        'diverged or grew')
#: exit status of a run that diverged (energy identity broken) or grew (unstable)
DIVERGED_OR_UNSTABLE = 2


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


def _analysis(tr):
    """Return the analysis of the samples: pole slips, growth, divergence.

    Every sample counts for the slips and the energy identity; growth is judged on the
    newest window of the live node's length only (no checkpoints): its cost does not grow
    with the run's length.
    """
    from gyro_rotor.analysis.checks import RotorAnalyzer, samples_from_trajectory
    ana = RotorAnalyzer(tr.scene, checkpoint_s=0)
    ana.add_many(samples_from_trajectory(tr))
    return ana.result()


def _guard(tr):
    """Cut the run before the first sample the live guard rejects; return (run, why or '').

    A run the integrator stopped early (:func:`simulate` ``keep_failed``) is cut there.
    """
    E, r = tr.out['E_star'], tr.out['residual']
    E_ref = E[0] + tr.y[0, tr.model.idiss] - r[0]
    limit = tr.scene.node.get('max_residual', NODE_KEYS['max_residual'][1])
    i = first_break(E, r, E_ref, limit)
    if i is None:
        return tr, '' if tr.success else tr.message.rstrip('.')
    return tr.head(max(i, 1)), describe_break(tr.t[i], E[i], r[i], E_ref, limit)


def _verdict(guard: str, res) -> str:
    """Return the last line of a run that diverged or grew ('' if it did neither)."""
    from gyro_rotor.analysis.verdict import Verdict
    if guard:
        return (f'DIVERGED: the integration diverged: {guard}; the samples before it are '
                'kept')
    if res.verdict in (Verdict.DIVERGED, Verdict.UNSTABLE):
        return f'{str(res.verdict).upper()}: {res.reason}'
    return ''


def run(args: argparse.Namespace) -> int:
    """Run the simulation and print the summary; 2 if it diverged or grew (module doc)."""
    if args.out:
        check_output_file(args.out, ('.csv', '.npz'), overwrite=args.force)
    for name, tol in (('--rtol', args.rtol), ('--atol', args.atol)):
        if tol is not None:     # rotor_sim's range: a tolerance above 1 is no tolerance
            check_number(name, tol, low=0.0, low_open=True, high=1.0)
    scene = load_scene_with_sets(args.scene, args.set)
    tr, guard = _guard(simulate(scene, t_end=args.t_end, rate=args.rate, method=args.method,
                                rtol=args.rtol, atol=args.atol, keep_failed=True))
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
    res = _analysis(tr)
    if any(scene.pole_pairs):
        print(f'  pole slips:   {res.pole_slips} (z passed a maximum of the drive potential)')
    print(f"  {s['method']}: steps {s['nsteps']}, {s['nfev']} RHS evaluations, "
          f"{s['samples']} samples, wall time {s['wall_time']:.3f} s")
    if args.out:
        print(f'  wrote {args.out} ({s["samples"]} rows)')
    last = _verdict(guard, res)
    if last:
        print(last)
    return DIVERGED_OR_UNSTABLE if last else 0
