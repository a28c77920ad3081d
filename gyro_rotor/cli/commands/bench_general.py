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
    p.add_argument('--stiff', action='store_true',
                   help='only the stiff-drive table: twin_gimbal at K_D = 1e2, 1e4, 1e6, auto '
                   'vs scipy Radau/BDF/LSODA at error --level (use --level 1e-6; the committed '
                   'table: --out bench/general_stiff.md)')


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
        stem = 'general_stiff' if args.stiff else 'general'
        d = make_unique_dir(Path(RUNS_DIR) / time.strftime(f'{stem}-%Y%m%d-%H%M%S'))
        args.out = str(d / f'{stem}.md')
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    check_output_file(args.out, ('.md',))
    if args.stiff:
        return _write(args.out, _stiff_lines(args))
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
    return _write(args.out, lines)


def _write(out: str, lines: list) -> int:
    text = '\n'.join(lines) + '\n'
    print(text)
    Path(out).write_text(text, encoding='utf-8')
    print(f'wrote {out}')
    return 0


def _stiff_lines(args: argparse.Namespace) -> list:
    """Return the stiff-drive table (general_bench.stiff_table) as markdown lines."""
    import platform
    from gyro_rotor.numerics import general_bench as gb
    rows, checks = gb.stiff_table(t_end=args.t_end, level=args.level, repeats=args.repeats)
    lines = ['# Stiff drive on a generated system: auto vs scipy', '',
             f'Command: `gyro-rotor bench-general --stiff --out {args.out} --t-end '
             f'{args.t_end:g} --level {args.level:g} --repeats {args.repeats}`', '',
             f'twin_gimbal (3 coordinates, 2 rotors) with K_D set for both rotors, '
             f'{args.t_end:g} s simulated, sampled at {gb.SAMPLE_RATE:g} Hz (every method '
             'returns the same samples; ours land their steps on them, scipy interpolates). '
             'Error: the largest |q - q_ref|, |z - z_ref| [rad] over the samples; reference: '
             'radau9 at rtol 1e-13, checked against rodas4 (forward-difference Jacobian) at '
             'rtol 1e-12. Wall: best of '
             f'{args.repeats} runs for every method (scipy on a sympy-lambdified right-hand '
             'side, `+jac`: with the lambdified Jacobian). Machine: '
             f'{platform.machine()}, {os.cpu_count()} cores, shared with other jobs (load '
             'average in the table).', '',
             f'## Cheapest run with error <= {args.level:g}', '',
             '| K_D | method | rtol | error | ms per simulated s | nfev | load | scipy best / '
             'ours |', '|---|---|---|---|---|---|---|---|']
    ours_all = []
    for K_D in sorted(checks):
        best = {}
        for r in rows:
            if r.K_D == K_D and r.err <= args.level and (
                    r.method not in best or r.wall < best[r.method].wall):
                best[r.method] = r
        ours = min((r for m, r in best.items() if m.startswith('auto')),
                   key=lambda r: r.wall, default=None)
        scipy_best = min((r for m, r in best.items() if m.startswith('lambdify')),
                         key=lambda r: r.wall, default=None)
        for r in sorted(best.values(), key=lambda r: r.wall):
            gain = (f'{scipy_best.wall / r.wall:.1f}x' if r is ours and scipy_best else '')
            lines.append(f'| {K_D:g} | {r.method} | {r.rtol:g} | {r.err:.2e} | '
                         f'{r.ms_per_s:.2f} | {r.nfev} | {r.load:.1f} | {gain} |')
        if ours:
            ours_all.append(ours)
    lines += ['', '| K_D | reference check: largest difference rodas4 - radau9 [rad] |',
              '|---|---|']
    lines += [f'| {K_D:g} | {checks[K_D]:.1e} |' for K_D in sorted(checks)]
    if ours_all:
        costs = [r.ms_per_s for r in ours_all]
        lines += ['', f'auto over K_D = {", ".join(f"{r.K_D:g}" for r in ours_all)}: '
                  f'{", ".join(f"{c:.2f}" for c in costs)} ms per simulated s; largest / '
                  f'smallest = {max(costs) / min(costs):.2f}.']
    lines += ['', '## All runs', '',
              '| K_D | method | rtol | error | wall [ms] | ms per simulated s | nfev | load |',
              '|---|---|---|---|---|---|---|---|']
    lines += [f'| {r.K_D:g} | {r.method} | {r.rtol:g} | {r.err:.2e} | {r.wall * 1e3:.2f} | '
              f'{r.ms_per_s:.2f} | {r.nfev} | {r.load:.1f} |' for r in rows]
    return lines
