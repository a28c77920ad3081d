"""``gyro-rotor sweep SCENE``: trajectories over a grid of parameters and initial conditions.

Pull-in maps (``--grid initial.dzdot=-200:200:400 --grid initial.dz=-3:3:60``) and design
maps (``--grid K_S=1:100:30:log --grid K_D=1e-3:10:40:log``) on Dask: a local cluster of
one worker process per core by default, ``--scheduler ADDRESS`` for an existing one,
``--serial`` in this process. Results go to ``--out DIR`` as Parquet, block by block;
``--resume`` computes only the blocks that are missing; the maps are drawn at the end.
"""

from __future__ import annotations

import argparse

from gyro_rotor.analysis.sweep.metrics import Metric, PointStatus
from gyro_rotor.errors import ParameterError

HELP = 'sweep a scene over grids of parameters/initial conditions on Dask; Parquet + maps'


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``sweep``."""
    p.add_argument('scene', help='scene name or path')
    p.add_argument('--grid', action='append', default=[], metavar='KEY=START:STOP:COUNT[:log]',
                   help='an axis over a scene key (repeatable), e.g. K_D=1e-3:10:40:log or '
                        'initial.dzdot=-200:200:400')
    p.add_argument('--t-end', type=float, default=None, help="duration [s] (default: the scene's)")
    p.add_argument('--rate', type=float, default=100.0,
                   help='sample rate the metrics are taken from [Hz] (default 100)')
    p.add_argument('--metrics', default=None,
                   help=f"comma-separated subset of {','.join(m.value for m in Metric)} "
                        '(default: all; every scene offers every metric)')
    p.add_argument('--tol', type=float, default=1e-3,
                   help='settling tolerance of the drive amplitude [rad] (default 1e-3)')
    p.add_argument('--out', required=True, help='output directory (Parquet blocks, maps)')
    where = p.add_mutually_exclusive_group()
    where.add_argument('--scheduler', default=None, metavar='ADDRESS',
                       help='address of a running Dask scheduler (tcp://host:8786)')
    where.add_argument('--serial', action='store_true', help='run in this process, no Dask')
    where.add_argument('--workers', type=int, default=None,
                       help='worker processes of the local cluster (default: one per core)')
    p.add_argument('--resume', action='store_true',
                   help='complete the sweep in --out: compute only the missing blocks')
    p.add_argument('--block', type=int, default=None,
                   help='points per task (default: about 2 s of work, capped by memory)')
    p.add_argument('--step', type=float, default=None,
                   help='RK4 step [s] (default 0.02 / the fastest model rate of the sweep)')
    p.add_argument('--maps', default=None, metavar='DIR',
                   help='directory for the heatmap PNGs (default: OUT/maps)')
    p.add_argument('--no-maps', action='store_true', help='do not draw the heatmaps')
    p.add_argument('--quiet', action='store_true', help='no progress bar')
    p.add_argument('--yes', action='store_true',
                   help=f'run a sweep of more than {ASK_POINTS:,} points or an estimated '
                        f'{ASK_WORK_S / 3600:g} h of work without asking')


#: a sweep this large (points, or estimated single-core work in seconds) is run only after
#: a yes on a terminal or with --yes (issue 24: 10^7 points started with 'eta 13683.5 s')
ASK_POINTS = 1_000_000
ASK_WORK_S = 3600.0


def _confirm(spec, yes: bool) -> None:
    """Ask before a huge sweep (refuse without a terminal unless --yes)."""
    import sys

    from gyro_rotor.analysis.sweep.task import US_PER_TRAJECTORY_STEP
    work = spec.n_points * spec.steps_per_trajectory * US_PER_TRAJECTORY_STEP * 1e-6
    if yes or (spec.n_points <= ASK_POINTS and work <= ASK_WORK_S):
        return
    what = (f'{spec.n_points:,} points, about {work / 3600:.3g} h of single-core work '
            f'({spec.steps_per_trajectory} RK4 steps each)')
    if not sys.stdin.isatty():
        raise ParameterError(f'the sweep has {what}: pass --yes to run it')
    answer = input(f'the sweep has {what}; run it? [y/N] ')
    if answer.strip().lower() not in ('y', 'yes'):
        raise ParameterError('sweep not started (answered no)')


def _step_text(spec) -> str:
    """Return the step taken, and the --step asked for where a sample interval cut it."""
    used = spec.step_used
    if used < spec.step * (1.0 - 1e-9):
        return (f'{used:.4g} s (--step {spec.step:.4g} s is longer than a sample interval: '
                'one step per sample)')
    return f'{used:.4g} s'


def run(args: argparse.Namespace) -> int:
    """Check everything, run the sweep, draw the maps, print a summary."""
    # imported here, not at the top: ``gyro-rotor --help`` loads every command's module
    from gyro_rotor.analysis.sweep.maps import plot_maps
    from gyro_rotor.analysis.sweep.runner import Executor, run_sweep
    from gyro_rotor.analysis.sweep.store import SweepStore
    from gyro_rotor.analysis.sweep.task import make_spec

    if args.workers is not None and args.workers < 1:
        raise ParameterError(f'--workers must be positive, got {args.workers}')
    metrics = (None if args.metrics is None else
               [m.strip() for m in args.metrics.split(',') if m.strip()])
    spec = make_spec(args.scene, args.grid, t_end=args.t_end, rate=args.rate, metrics=metrics,
                     tol=args.tol, block_size=args.block, step=args.step)
    _confirm(spec, args.yes)
    executor = (Executor.SERIAL if args.serial else
                Executor.ADDRESS if args.scheduler else Executor.LOCAL)
    print(f'sweep {spec.scene}: {spec.n_points} points ({" x ".join(spec.grid)}), '
          f'{spec.t_end:g} s, RK4 step {_step_text(spec)} ({spec.steps_per_trajectory} steps), '
          f'{spec.n_blocks} blocks of {spec.block_size}, {executor.value}')
    r = run_sweep(spec, args.out, executor=executor, workers=args.workers,
                  scheduler=args.scheduler, resume=args.resume, progress=not args.quiet)
    for path, why in r.refused.items():
        print(f'  ignored {path}: {why} (computed again)')
    table = SweepStore(args.out).read(r.spec)
    status = table.column('status').to_numpy()
    counts = {s.name.lower(): int((status == s).sum()) for s in PointStatus}
    done = (f'{r.points_run} points in {r.wall_s:.1f} s on {r.workers} worker(s): '
            f'{r.steps_per_s:.3g} trajectory-steps/s' if r.blocks_run else 'nothing to compute')
    print(f'  {len(r.blocks_run)} blocks run, {r.blocks_skipped} already there; {done}')
    print(f'  {table.num_rows}/{spec.n_points} points in {args.out}: '
          + ', '.join(f'{k} {v}' for k, v in counts.items()))
    if not args.no_maps:
        for path in plot_maps(table, spec, args.maps or f'{args.out}/maps'):
            print(f'  wrote {path}')
    return 0
