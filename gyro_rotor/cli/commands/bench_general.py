"""``gyro-rotor bench-general``: speed of the general rotor systems (issue 15), measured."""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

HELP = ('benchmark the general rotor systems: generated RHS vs the hand-written kernel, '
        'compile and cache times, the default method vs sympy lambdify + scipy solve_ivp')


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the arguments of bench-general."""
    p.add_argument('--out', default=None, metavar='FILE.md',
                   help='markdown table to write (default: a new '
                   'bench_out/general-YYYYmmdd-HHMMSS/general.md, ignored by git; the committed '
                   'table: --out bench/general.md)')
    p.add_argument('--t-end', type=float, default=2.0, help='simulated seconds per run')
    p.add_argument('--level', type=float, default=1e-9, help='error level of the comparison')
    p.add_argument('--repeats', type=int, default=3, help='repeats of our runs (best wall)')


def run(args: argparse.Namespace) -> int:
    """Run the three benchmarks, print the tables and write them as markdown."""
    from gyro_rotor.cli.util import check_output_file
    from gyro_rotor.errors import ParameterError
    from gyro_rotor.numerics import general_bench as gb
    if not (math.isfinite(args.t_end) and args.t_end > 0) or not args.level > 0:
        raise ParameterError('--t-end and --level must be positive')
    if args.out is None:
        # never the tracked bench/general.md unless --out says so; a new file per run
        import time
        from gyro_rotor.cli.util import make_unique_dir, RUNS_DIR
        d = make_unique_dir(Path(RUNS_DIR) / time.strftime('general-%Y%m%d-%H%M%S'))
        args.out = str(d / 'general.md')
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    check_output_file(args.out, ('.md',))
    lines = ['# General rotor systems: benchmark', '',
             f'Command: `gyro-rotor bench-general --out {args.out} --t-end {args.t_end:g} '
             f'--level {args.level:g} --repeats {args.repeats}`', '']
    cost = gb.rhs_cost()
    lines += ['## Right-hand side per evaluation (centrifuge_euler vs hand-written kernel)', '',
              '| hand-written quaternion kernel [ns] | generated Euler-angle RHS [ns] | ratio |',
              '|---|---|---|',
              f'| {cost["hand_ns"]:.1f} | {cost["generated_ns"]:.1f} | {cost["ratio"]:.2f} |',
              '']
    ct = gb.compile_times()
    lines += ['## Generation and compilation (twin_gimbal: 3 coordinates, 2 rotors)', '',
              '| run | imports [s] | read system file [s] | compile_system [s] | first '
              'integration [s] | total [s] |', '|---|---|---|---|---|---|']
    for label in ('first', 'cached'):
        c = ct[label]
        total = c['imports'] + c['load_system'] + c['compile_system'] + c['first_run']
        lines.append(f'| {label} | {c["imports"]:.2f} | {c["load_system"]:.2f} | '
                     f'{c["compile_system"]:.2f} | {c["first_run"]:.2f} | {total:.2f} |')
    lines += ['', f'(load average at the time: {os.getloadavg()[0]:.1f})', '']
    rows = gb.work_precision(t_end=args.t_end, repeats=args.repeats)
    best = gb.best_at(rows, args.level)
    lines += [f'## Work precision at error <= {args.level:g} over {args.t_end:g} s', '',
              '| system | method | rtol | error | wall [ms] | nfev | speed-up of ours |',
              '|---|---|---|---|---|---|---|']
    for system in sorted({r.system for r in rows}):
        ours = next((r for (s, mth), r in best.items()
                     if s == system and mth.startswith(gb.DEFAULT_LABEL)), None)
        for (s, method), r in sorted(best.items()):
            if s != system:
                continue
            gain = f'{r.wall / ours.wall:.0f}x' if ours and r is not ours else '-'
            lines.append(f'| {s} | {method} | {r.rtol:g} | {r.err:.2e} | {r.wall * 1e3:.2f} '
                         f'| {r.nfev} | {gain} |')
        for label, prefix in (('scipy', 'lambdify+'), ('compiled peer', gb.PEER_PREFIX)):
            others = [r for (s, mth), r in best.items()
                      if s == system and mth.startswith(prefix)]
            if ours and others:
                fastest = min(others, key=lambda r: r.wall)
                lines.append(f'| {system} | **fastest {label}: {fastest.method}** | | | | | '
                             f'**{fastest.wall / ours.wall:.2f}x** |')
    lines += ['', '## All runs', '', '| system | method | rtol | error | wall [ms] | nfev |',
              '|---|---|---|---|---|---|']
    lines += [f'| {r.system} | {r.method} | {r.rtol:g} | {r.err:.2e} | {r.wall * 1e3:.2f} | '
              f'{r.nfev} |' for r in rows]
    text = '\n'.join(lines) + '\n'
    print(text)
    Path(args.out).write_text(text, encoding='utf-8')
    print(f'wrote {args.out}')
    return 0
