"""``gyro-rotor simulate SCENE``: integrate a scene and print its summary.

Exit status: 0; :data:`DIVERGED_OR_UNSTABLE` (2) when the run diverged or grew, said in
the last line:

* ``DIVERGED:`` where the energy identity broke by the live simulation's guard
  (:mod:`gyro_rotor.numerics.guard` with the scene's ``max_residual``), or the analysis of
  the samples finds it broken by its stricter limit, or the integration stopped early (a
  non-finite state) without growth the identity vouches for: the samples before that are
  kept, summarized and written;
* ``UNSTABLE:`` where the analysis finds growing motion with the identity sound (also when
  the integration then stopped at a non-finite state: the growth left the range of
  floating point, which the line says), or where the linear theory predicts growing modes
  and the run is too short for the analysis to measure them (shorter than its fits'
  ``min_fit_s``): the line names the predicted modes and what E* did.

The demo of such a scene fails its named check instead (exit 1): the verdict is not
confirmed. 1 for bad input (``ERROR:``), as every command.
"""

from __future__ import annotations

import argparse

from gyro_rotor.cli.util import (check_number, check_output_file, load_scene_with_sets,
                                 write_output)
from gyro_rotor.node_settings import NODE_KEYS
from gyro_rotor.numerics.defaults import DEFAULT_RATE

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
    """Return the analysis of the samples (pole slips, growth, divergence), its min_fit_s.

    Every sample counts for the slips and the energy identity; growth is judged on the
    newest window of the live node's length only (no checkpoints): its cost does not grow
    with the run's length.
    """
    from gyro_rotor.analysis.checks import RotorAnalyzer
    from gyro_rotor.analysis.samples import iter_samples
    import numpy as np
    ana = RotorAnalyzer(tr.scene, checkpoint_s=0)
    # an unstable system's growth reaches 1e304 J before the state overflows: its squares
    # overflow in the fits (to inf, which they handle), not worth a RuntimeWarning each
    with np.errstate(over='ignore', under='ignore'):
        ana.add_many(iter_samples(tr))
        return ana.result(), ana.min_fit_s


def _guard(tr):
    """Cut the run before the first sample the live guard rejects.

    Return (run, why or '', whether the energy identity broke). A run the integrator
    stopped early (:func:`simulate` ``keep_failed``) is cut there: why is its message, the
    identity not broken.
    """
    from gyro_rotor.numerics.guard import describe_break, first_break
    E, r = tr.out['E_star'], tr.out['residual']
    E_ref = E[0] + tr.y[0, tr.model.idiss] - r[0]
    limit = tr.scene.node.get('max_residual', NODE_KEYS['max_residual'][1])
    i = first_break(E, r, E_ref, limit)
    if i is None:
        return tr, ('' if tr.success else tr.message.rstrip('.')), False
    return tr.head(max(i, 1)), describe_break(tr.t[i], E[i], r[i], E_ref, limit), True


def _verdict(guard: str, broken: bool, res, tr, min_fit_s: float) -> str:
    """Return the last line of a run that diverged or grew ('' if it did neither).

    ``guard``: why the run was cut ('' if it was not); ``broken``: by the energy identity
    (else the integrator stopped); ``res``: the analysis of the samples kept.
    """
    from gyro_rotor.analysis.verdict import Verdict
    E = tr.out['E_star']
    if guard and not broken and tr.budget:      # slow, not divergent: say which
        return (f'STOPPED: {guard} (not a divergence: the run needs more steps than its '
                'budget); the samples before it are kept')
    if guard and (broken or res.verdict is not Verdict.UNSTABLE):
        return (f'DIVERGED: the integration diverged: {guard}; the samples before it are '
                'kept')
    if guard:
        # growth the identity vouches for, until the state left floating point's range
        return (f'UNSTABLE: {res.reason}; then the integration stopped after the last '
                f'finite sample (t = {tr.t[-1]:.6g} s, E* = {E[-1]:.6g} J): {guard}; the '
                'samples before it are kept')
    if res.verdict in (Verdict.DIVERGED, Verdict.UNSTABLE):
        return f'{str(res.verdict).upper()}: {res.reason}'
    grow = res.prediction.growing_modes
    if grow and res.verdict is Verdict.INSUFFICIENT_DATA:
        # too short for the analysis' fits: the linear theory's growth, and what E* did
        modes = ', '.join(f'{m.name} (Re lambda = {m.eigenvalue.real:+.4g} 1/s)'
                          for m in grow)
        return (f'UNSTABLE: the linear theory predicts growing modes: {modes}; this '
                f'{tr.t[-1] - tr.t[0]:.6g} s run is too short for the analysis to measure '
                f'them (its fits need {min_fit_s:g} s): E* went from {E[0]:.6g} J to '
                f'{E[-1]:.6g} J')
    return ''


def run(args: argparse.Namespace) -> int:
    """Run the simulation and print the summary; 2 if it diverged or grew (module doc)."""
    # imported here, not at the top: ``gyro-rotor --help`` loads every command's module
    from gyro_rotor.numerics.simulate import simulate

    if args.out:
        check_output_file(args.out, ('.csv', '.npz'), overwrite=args.force)
    for name, tol in (('--rtol', args.rtol), ('--atol', args.atol)):
        if tol is not None:     # rotor_sim's range: a tolerance above 1 is no tolerance
            check_number(name, tol, low=0.0, low_open=True, high=1.0)
    scene = load_scene_with_sets(args.scene, args.set)
    tr, guard, broken = _guard(simulate(scene, t_end=args.t_end, rate=args.rate,
                                        method=args.method, rtol=args.rtol, atol=args.atol,
                                        keep_failed=True))
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
    res, min_fit_s = _analysis(tr)
    if any(scene.pole_pairs):
        print(f'  pole slips:   {res.pole_slips} (z passed a maximum of the drive potential)')
    print(f"  {s['method']}: steps {s['nsteps']}, {s['nfev']} RHS evaluations, "
          f"{s['samples']} samples, wall time {s['wall_time']:.3f} s")
    if args.out:
        print(f'  wrote {args.out} ({s["samples"]} rows)')
    last = _verdict(guard, broken, res, tr, min_fit_s)
    if last:
        print(last)
    return DIVERGED_OR_UNSTABLE if last else 0
