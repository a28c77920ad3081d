"""``gyro-rotor bench``: the benchmark of every scene, centrifuge or system file, one command.

``--table`` chooses what is measured (:class:`BenchTable`), ``--scenes`` on which scenes
(any scene: a shipped name, a path, ``name@KEY=VALUE`` overrides); one output directory
--out for every table, by default a new ``bench_out/bench-YYYYmmdd-HHMMSS`` (ignored by git;
a suffix -2, -3 if two runs start in the same second): the committed results in ``bench/``
are replaced only when ``--out bench`` is given.

``work_precision`` (the default) writes ``work_precision.csv`` (every run, with the 1-minute
load average at its end), ``work_precision.md`` (the default method, run as its own row
``auto`` since it chooses per tolerance, against the best compiled peer, CyRK or numbalsoda,
at errors 1e-6 and 1e-9 where they are installed, with what auto chose and the load
average; best milliseconds per simulated second at errors 1e-3, 1e-6, 1e-9 per scene and
method; E* drift; pole counts) and ``work_precision.png`` (error against wall time, log-log;
needs matplotlib).
``--quick`` is a smoke run of under a minute (3 scenes, 2 tolerances, auto, dop853, vern8,
radau9 and split8, scipy's LSODA, CyRK's DOP853 where installed, 1 repeat, 100-s drift
study, no pole counts).

``general`` writes ``general.md``: the generated right-hand side of centrifuge_euler against
the hand-written kernel, the generation and compilation times of twin_gimbal, and the
default method against sympy lambdify + scipy and CyRK on the system files' scenes
(default centrifuge_euler, twin_gimbal, elastic_frame) over --t-end at error --level.

``stiff`` writes ``general_stiff.md``: one system file's scene (default twin_gimbal) at
K_D = 1e2, 1e4, 1e6, auto against scipy's Radau, BDF and LSODA and (where installed) CyRK's
Radau and LSODA at error --level (default 1e-6).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import enum
import math
import os
from pathlib import Path
import platform
import sys
import time

from gyro_rotor.cli.util import check_number, error_hint, make_unique_dir, RUNS_DIR
from gyro_rotor.errors import GyroRotorError, ParameterError
from gyro_rotor.numerics.bench_scenes import (DEFAULT_SCENES, QUICK_SCENES, REPEATS,
                                              SYSTEM_SCENES)

HELP = ('benchmark any scene: work precision of the integrators against scipy and the '
        'compiled peers, the generated systems, stiff drives')


class BenchTable(enum.StrEnum):
    """What ``bench`` measures, and the file it writes (:attr:`file`)."""

    WORK_PRECISION = 'work_precision'
    GENERAL = 'general'
    STIFF = 'stiff'

    @property
    def file(self) -> str:
        """Return the markdown file of the table."""
        return {'work_precision': 'work_precision.md', 'general': 'general.md',
                'stiff': 'general_stiff.md'}[self.value]


#: the longest --t-end and --drift-t-end [s] (10 x the full drift run's 1000 s)
MAX_T_END_S = 1e4

#: per table: the default scenes, repeats and error level (the full sweep's)
_DEFAULT_SCENES = {BenchTable.WORK_PRECISION: DEFAULT_SCENES,
                   BenchTable.GENERAL: SYSTEM_SCENES, BenchTable.STIFF: ('twin_gimbal',)}
_DEFAULT_LEVEL = {BenchTable.GENERAL: 1e-9, BenchTable.STIFF: 1e-6}


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``bench``."""
    p.add_argument('--table', type=BenchTable, choices=list(BenchTable),
                   default=BenchTable.WORK_PRECISION,
                   help='what to measure (module doc): work_precision (default), general '
                   '(generated systems), stiff (a stiff drive on a system file)')
    p.add_argument('--scenes', default=None,
                   help='comma-separated scene specs, centrifuge or system file, e.g. '
                   "precession,stiff_drive@K_D=1e6,twin_gimbal (default: the table's "
                   'scenes; with --quick: ' + ','.join(QUICK_SCENES) + ')')
    p.add_argument('--quick', action='store_true',
                   help='a smoke run of well under a minute (see the module doc)')
    p.add_argument('--repeats', type=int, default=None,
                   help=f'repeats per run, best wall (default {REPEATS}; 1 with --quick)')
    p.add_argument('--out', default=None,
                   help='output directory (default: a new bench_out/bench-YYYYmmdd-HHMMSS, '
                   'ignored by git; the committed results are in bench: --out bench)')
    p.add_argument('--no-scipy', action='store_true', help='skip the scipy baselines')
    p.add_argument('--no-peers', action='store_true',
                   help='skip the compiled peers (CyRK, numbalsoda; run where installed: '
                   'pip install -r requirements-bench.txt)')
    p.add_argument('--drift-t-end', type=float, default=None,
                   help='horizon of the E* drift study on conservative [s] (0 = skip; '
                   'default 1000, 100 with --quick)')
    p.add_argument('--t-end', type=float, default=2.0,
                   help='tables general and stiff: simulated seconds per run (default 2)')
    p.add_argument('--level', type=float, default=None,
                   help='tables general and stiff: error level of the comparison (default '
                   '1e-9 for general, 1e-6 for stiff)')


def _fmt(v) -> str:
    return '-' if v is None else f'{v * 1e3:.3g}'


def md_table(header, rows) -> list[str]:
    """Return the markdown lines of a table: its header, the rule, a line per row of cells."""
    return (['| ' + ' | '.join(header) + ' |', '|' + '---|' * len(header)]
            + ['| ' + ' | '.join(str(c) for c in row) + ' |' for row in rows])


def _families(rows) -> dict:
    """Map each method to its family, in the order of the rows."""
    return {r.method: r.family for r in rows}


def _best(table, scene, methods, i):
    """Return (method, wall/sim) of the fastest of ``methods`` at error level i, or Nones."""
    cands = [(table[(scene, m)][i], m) for m in methods
             if (scene, m) in table and table[(scene, m)][i] is not None]
    if not cands:
        return None, None
    v, m = min(cands)
    return m, v


def _auto_best(rows, scene, level):
    """Return (cost, label, load) of auto's cheapest run at error <= level, or (None, '-', nan).

    The label names the method auto chose at that setting (it chooses per tolerance).
    """
    import gyro_rotor.numerics.bench as bench
    best = None
    for r in rows:
        if (r.scene == scene and r.method == bench.AUTO and r.status == 0
                and math.isfinite(r.err) and r.err <= level
                and (best is None or r.wall_per_sim < best.wall_per_sim)):
            best = r
    if best is None:
        return None, '-', math.nan
    rtol = float(best.setting.partition('=')[2])
    chosen = bench.auto_choice(bench.parse_scene_spec(scene)[0], rtol)
    return best.wall_per_sim, f'{chosen} ({best.setting})', best.load


def peer_table(rows, levels=(1e-6, 1e-9)) -> list[str]:
    """Markdown lines: the default method (auto) against the best compiled peer, per scene.

    Per scene and error level: auto's method and cost, the fastest compiled peer (CyRK,
    numbalsoda) and the fastest of gyro_rotor's methods at that error, the ratios peer /
    auto (the speed-up of auto, > 1 = auto faster) and auto / own best (1.00 = auto is the
    fastest own method). Costs in ms per simulated second.
    """
    import gyro_rotor.numerics.bench as bench
    idx = [bench.ERROR_LEVELS.index(lev) for lev in levels]
    best = bench.best_table(rows)
    fam = _families(rows)
    own = [m for m, f in fam.items() if f == 'gyro_rotor' and m != bench.AUTO]
    peers = [m for m, f in fam.items() if f == 'peer']
    scenes = list(dict.fromkeys(r.scene for r in rows))
    cells = []
    for s in scenes:
        for lev, i in zip(levels, idx):
            ours, auto, load = _auto_best(rows, s, lev)
            pm, pv = _best(best, s, peers, i)
            om, ov = _best(best, s, own, i)
            ratio = '-' if ours is None or pv is None else f'{pv / ours:.2f}x'
            own_ratio = '-' if ours is None or ov is None else f'{ours / ov:.2f}'
            cells.append([s, f'{lev:.0e}', auto, _fmt(ours),
                          '-' if pm is None else f'{_fmt(pv)} ({pm})', ratio,
                          '-' if om is None else f'{_fmt(ov)} ({om})', own_ratio, f'{load:.1f}'])
    return md_table(['scene', 'error', 'auto chose (at rtol)', 'auto [ms/s]',
                     'best compiled peer [ms/s]', 'peer / auto', 'best own [ms/s]',
                     'auto / own best', 'load'], cells)


def cost_table_lines(rows) -> list[str]:
    """Markdown lines: auto's cost table as this run measures it, beside the one in use.

    ``bench.steps_per_radian`` of the rows (nothing without its six scenes): the steps per
    radian each explicit pair needs for each error, and its error floor; the package's
    tables (methods.STEPS_PER_RADIAN, ERROR_FLOOR) are this output of a full sweep.
    """
    import gyro_rotor.numerics.bench as bench
    from gyro_rotor.numerics.integrators import methods
    fit = bench.steps_per_radian(rows)
    if fit is None:
        return []
    errs = methods.COST_ERRORS
    cells = []
    for m, vals in fit['steps'].items():
        for label, v, floor in (('this run', vals, fit['floor'][m]),
                                ('in use', methods.STEPS_PER_RADIAN[m],
                                 methods.ERROR_FLOOR[m])):
            cells.append([m, label, *('-' if x is None else f'{x:.3g}' for x in v),
                          f'{floor:.1e}'])
    return (['', "auto's cost table: steps per radian of the fastest rate to reach each "
             'error (fewest steps of the sweep, geometric mean over '
             f'{", ".join(bench.COST_SCENES)}; methods.STEPS_PER_RADIAN and ERROR_FLOOR are '
             'this table of a full sweep):', '']
            + md_table(['method', 'table', *(f'{e:.0e}' for e in errs), 'floor'], cells))


def write_markdown(path, rows, drift, poles, args, elapsed) -> str:
    """Write the markdown report and return its text."""
    import gyro_rotor.numerics.bench as bench
    best = bench.best_table(rows)
    load = (getattr(args, 'load_before', math.nan), getattr(args, 'load_after', math.nan))
    scenes = list(dict.fromkeys(r.scene for r in rows))
    fam = _families(rows)
    methods = list(fam)
    have_peers = any(f == 'peer' for f in fam.values())
    lines = [f'Machine: {platform.machine()}, {os.cpu_count()} cores, shared and noisy; '
             f'{"quick" if args.quick else "full"} sweep, best of {args.repeats} repeats per '
             f'run, {elapsed / 60:.1f} min, load average {load[0]:.1f} at the start and '
             f'{load[1]:.1f} at the end (all ratios are side by side in this one run). '
             f'Error = max over samples (100 Hz) of the symmetry-axis angle and |z| error '
             f'against a high-accuracy reference; cost = wall milliseconds per simulated '
             f'second at the cheapest setting of the sweep that reaches the error.', '']
    if have_peers:
        lines += ['The default method (auto) against the compiled peers (CyRK nbsolve2_ivp, '
                  'numbalsoda; numba cfunc right-hand side of the same equations, constants '
                  'folded):', ''] + peer_table(rows) + ['']
    else:
        from gyro_rotor.numerics import bench_peers
        why = ('skipped (--no-peers)' if getattr(args, 'no_peers', False)
               else bench_peers.missing_reason())
        lines += [f'Compiled peers: {why}.', '']
    lines += ['Best cost [ms per simulated second] at error <= 1e-3 / 1e-6 / 1e-9 per method '
              '(`-` = not reached within the sweep or budget). Lower case: gyro_rotor; upper '
              'case: scipy solve_ivp (numba right-hand side called from Python); '
              '`CyRK:...`, `numbalsoda:...`: the compiled peers.', '']
    lines += md_table(['scene', *methods],
                      [[s] + ['' if best.get((s, m)) is None
                              else ' / '.join(_fmt(x) for x in best[(s, m)]) for m in methods]
                       for s in scenes])
    lines += ['', 'The default method (auto): speed-up over the fastest scipy method at the '
              "same error, and its cost over the fastest of gyro_rotor's own methods (1.0 = "
              'auto is the fastest):', '']
    auto_rows = []
    for s in scenes:
        chosen = (_auto_best(rows, s, bench.ERROR_LEVELS[i])[1] for i in (1, 2))
        auto = '/'.join(dict.fromkeys(c.split(' ')[0] for c in chosen))
        cells = []
        for family in ('scipy', 'gyro_rotor'):
            for i in (1, 2):
                ours = _auto_best(rows, s, bench.ERROR_LEVELS[i])[0]
                other = [best[(s, m)][i] for m in methods
                         if fam[m] == family and (s, m) in best and m != bench.AUTO
                         and best[(s, m)][i] is not None]
                if ours is None or not other:
                    cells.append('-')
                elif family == 'gyro_rotor':
                    cells.append(f'{ours / min(other):.2f}')
                else:
                    cells.append(f'{min(other) / ours:.1f}x')
        auto_rows.append([s, auto, *cells])
    lines += md_table(['scene', 'auto', 'vs scipy at 1e-6', 'at 1e-9', 'vs own best at 1e-6',
                       'at 1e-9'], auto_rows)
    lines += cost_table_lines(rows)
    if drift:
        cps = [c for c in (10.0, 100.0, 1000.0) if c <= args.drift_t_end] or [args.drift_t_end]
        lines += ['', f'Relative E* drift on conservative (K_D = 0) at '
                  f'{", ".join(f"{c:g}" for c in cps)} s (default settings; scipy at rtol '
                  f'1e-10):', '']
        lines += md_table(['method', *(f'{c:g} s' for c in cps), 'wall s'],
                          [[m, *(f'{x:.1e}' for x in d), f'{w:.2f}']
                           for m, (d, w) in drift.items()])
    if poles:
        ref = poles['reference']
        lines += ['', f"Slipped poles on pole_slip at each method's default tolerance "
                  f'(reference {ref}):', '']
        lines += md_table(['method', 'poles', 'right'],
                          [[m, n, 'yes' if n == ref else 'NO'] for m, n in poles.items()
                           if m != 'reference'])
    text = '\n'.join(lines) + '\n'
    with open(path, 'w') as fh:
        fh.write(text)
    return text


def write_plot(path, rows) -> str | None:
    """Error against wall time per scene (log-log); a message if matplotlib is missing."""
    try:
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.pyplot as plt
    except ImportError:
        return 'matplotlib is not installed: no plot'
    fig = work_precision_figure(rows)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return None


def work_precision_figure(rows):
    """Return the work-precision figure: one panel per scene, a legend in each.

    Error against wall seconds per simulated second (log-log), one line per method:
    circles gyro_rotor's, squares scipy's, triangles the compiled peers; grey lines the
    error levels of the tables.
    """
    import gyro_rotor.numerics.bench as bench
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    scenes = list(dict.fromkeys(r.scene for r in rows))
    methods = list(dict.fromkeys(r.method for r in rows))
    ncol = min(3, max(len(scenes), 1))
    nrow = max(math.ceil(len(scenes) / ncol), 1)
    fig, axes = plt.subplots(nrow, ncol, figsize=(5.2 * ncol, 3.8 * nrow), squeeze=False)
    cmap = plt.get_cmap('tab10' if len(methods) <= 10 else 'tab20')
    for ax, s in zip(axes.flat, scenes):
        for i, m in enumerate(methods):
            pts = sorted((r.wall_per_sim, r.err) for r in rows
                         if r.scene == s and r.method == m and r.status == 0
                         and math.isfinite(r.err) and r.err > 0)
            if pts:
                x, y = zip(*pts)
                fam = next(r.family for r in rows if r.method == m)
                style = {'gyro_rotor': 'o-', 'scipy': 's--', 'peer': '^:'}.get(fam, 'd-.')
                ax.loglog(x, y, style, color=cmap(i % cmap.N), label=m, ms=3, lw=1)
        ax.set_title(s, fontsize=9)
        ax.set_xlabel('wall time per simulated time [s/s]', fontsize=8)
        ax.set_ylabel('error [rad]', fontsize=8)
        for lev in bench.ERROR_LEVELS:
            ax.axhline(lev, color='0.8', lw=0.5)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=6, ncol=2)
    for ax in list(axes.flat)[len(scenes):]:
        ax.axis('off')
    fig.tight_layout()
    return fig


def resolve_settings(args: argparse.Namespace) -> str | None:
    """Fill the defaults that depend on --quick; return an error text, or None if valid.

    The output directory defaults to a new ``bench_out/bench-YYYYmmdd-HHMMSS`` (created by
    :func:`run`, unique): the committed ``bench/`` is written only when ``--out bench`` is
    given.
    """
    import gyro_rotor.numerics.bench as bench
    table = args.table
    if args.repeats is None:
        args.repeats = 1 if args.quick else REPEATS
    if args.drift_t_end is None:
        args.drift_t_end = 100.0 if args.quick else 1000.0
    if args.level is None:
        args.level = _DEFAULT_LEVEL.get(table, 1e-9)
    if args.scenes is None:
        quick = args.quick and table == BenchTable.WORK_PRECISION
        args.scenes = ','.join(QUICK_SCENES if quick else _DEFAULT_SCENES[table])
    if args.out is None:
        args.out = os.path.join(RUNS_DIR, bench.default_out_dir())
        args.out_is_default = True
    if args.repeats < 1:
        return f'--repeats must be >= 1, got {args.repeats}'
    try:        # the benchmark's range: an error level of 1 or more is no bench
        check_number('--drift-t-end', args.drift_t_end, low=0.0, high=MAX_T_END_S,
                     what='s (0 = no drift run)')
        check_number('--t-end', args.t_end, low=0.0, low_open=True, high=MAX_T_END_S,
                     what='s')
        check_number('--level', args.level, low=0.0, low_open=True, high=1.0,
                     what='(a relative error)')
    except ParameterError as err:
        return str(err)
    specs = [s.strip() for s in args.scenes.split(',') if s.strip()]
    try:
        scenes = [bench.parse_scene_spec(spec)[0] for spec in specs]
    except (GyroRotorError, ValueError) as err:
        return f'--scenes: {err}{error_hint(err)}'
    if not specs:
        return '--scenes names no scene'
    if table != BenchTable.WORK_PRECISION:
        builtin = next((sc.name for sc in scenes if sc.builtin), None)
        if builtin:
            return (f'--table {table} measures the generated code of system files; scene '
                    f'{builtin} is the built-in centrifuge (centrifuge_euler is its system '
                    'file)')
    if table == BenchTable.STIFF and len(specs) != 1:
        return f'--table stiff takes one scene, got {len(specs)}'
    return None


def run(args: argparse.Namespace) -> int:
    """Run the table's measurements and write its files (module doc)."""
    err = resolve_settings(args)
    if err:
        print(f'ERROR: {err}', file=sys.stderr)
        return 1
    specs = [s.strip() for s in args.scenes.split(',') if s.strip()]
    args.load_before = os.getloadavg()[0]
    if getattr(args, 'out_is_default', False):
        args.out = str(make_unique_dir(args.out))
    else:
        os.makedirs(args.out, exist_ok=True)
    print(f'writing to {args.out}')
    if args.table == BenchTable.GENERAL:
        return _write(args, general_lines(args, specs))
    if args.table == BenchTable.STIFF:
        return _write(args, stiff_lines(args, specs[0]))
    return _work_precision(args, specs)


def _command(args: argparse.Namespace) -> str:
    """Return the command line that writes the table (its --out, --t-end, --level, ...)."""
    return (f'gyro-rotor bench --table {args.table} --scenes {args.scenes} --out {args.out} '
            f'--t-end {args.t_end:g} --level {args.level:g} --repeats {args.repeats}')


def _write(args: argparse.Namespace, lines: list) -> int:
    text = '\n'.join(lines) + '\n'
    print(text)
    out = Path(args.out) / args.table.file
    out.write_text(text, encoding='utf-8')
    print(f'wrote {out}')
    return 0


def _work_precision(args: argparse.Namespace, specs: list) -> int:
    """Run the work-precision sweep and write CSV, markdown and plot."""
    import gyro_rotor.numerics.bench as bench
    t0 = time.perf_counter()
    rows = []
    for spec in specs:
        rows += bench.run_sweep(spec, quick=args.quick, repeats=args.repeats,
                                scipy=not args.no_scipy, peers=not args.no_peers,
                                progress=print)
    methods = bench.QUICK_DRIFT_METHODS if args.quick else bench.DRIFT_METHODS
    drift = (bench.energy_drift(args.drift_t_end, methods=methods, progress=print)
             if args.drift_t_end > 0 else None)
    poles = None if args.quick else bench.pole_counts()
    if poles:
        print('pole counts:', poles)
    elapsed = time.perf_counter() - t0
    args.load_after = os.getloadavg()[0]
    csv_path = os.path.join(args.out, 'work_precision.csv')
    with open(csv_path, 'w', newline='') as fh:
        w = csv.writer(fh)
        fields = [f.name for f in dataclasses.fields(bench.BenchRow)]
        w.writerow(fields)
        for r in rows:
            w.writerow([getattr(r, f) for f in fields])
    md = write_markdown(os.path.join(args.out, 'work_precision.md'), rows, drift, poles, args,
                        elapsed)
    msg = write_plot(os.path.join(args.out, 'work_precision.png'), rows)
    print(md)
    print(f'wrote {csv_path}, work_precision.md' + ('' if msg else ', work_precision.png')
          + f' in {args.out} ({elapsed / 60:.1f} min)')
    if msg:
        print(msg)
    return 0


def general_lines(args: argparse.Namespace, specs: list) -> list:
    """Return the table ``general`` (generated systems) as markdown lines."""
    import gyro_rotor.numerics.bench as bench
    lines = ['# General rotor systems: benchmark', '',
             f'Command: `{_command(args)}`', '']
    cost = bench.rhs_cost()
    lines += ['## Right-hand side per evaluation (centrifuge_euler vs hand-written kernel)', '']
    lines += md_table(['hand-written quaternion kernel [ns]', 'generated Euler-angle RHS [ns]',
                       'ratio'], [[f'{cost["hand_ns"]:.1f}', f'{cost["generated_ns"]:.1f}',
                                   f'{cost["ratio"]:.2f}']])
    ct = bench.compile_times()
    lines += ['', '## Generation and compilation (twin_gimbal: 3 coordinates, 2 rotors)', '']
    parts = ('imports', 'load_system', 'compile_system', 'first_run')
    lines += md_table(['run', 'imports [s]', 'read system file [s]', 'compile_system [s]',
                       'first integration [s]', 'total [s]'],
                      [[label, *(f'{ct[label][k]:.2f}' for k in parts),
                        f'{sum(ct[label][k] for k in parts):.2f}']
                       for label in ('first', 'cached')])
    lines += ['', f'(load average at the time: {os.getloadavg()[0]:.1f})', '']
    rows = bench.system_work_precision(specs, t_end=args.t_end, repeats=args.repeats)
    best = bench.best_at(rows, args.level)
    lines += [f'## Work precision at error <= {args.level:g} over {args.t_end:g} s', '']
    lines += md_table(['system', 'method', 'rtol', 'error', 'wall [ms]', 'nfev',
                       'speed-up of ours'], [])
    for system in sorted({r.system for r in rows}):
        ours = next((r for (s, mth), r in best.items()
                     if s == system and mth.startswith(bench.DEFAULT_LABEL)), None)
        for (s, method), r in sorted(best.items()):
            if s != system:
                continue
            gain = f'{r.wall / ours.wall:.0f}x' if ours and r is not ours else '-'
            lines.append(f'| {s} | {method} | {r.rtol:g} | {r.err:.2e} | {r.wall * 1e3:.2f} '
                         f'| {r.nfev} | {gain} |')
        for label, prefix in (('scipy', 'lambdify+'), ('compiled peer', bench.PEER_PREFIX)):
            others = [r for (s, mth), r in best.items()
                      if s == system and mth.startswith(prefix)]
            if ours and others:
                fastest = min(others, key=lambda r: r.wall)
                lines.append(f'| {system} | **fastest {label}: {fastest.method}** | | | | | '
                             f'**{fastest.wall / ours.wall:.2f}x** |')
    lines += ['', '## All runs', '']
    lines += md_table(['system', 'method', 'rtol', 'error', 'wall [ms]', 'nfev'],
                      [[r.system, r.method, f'{r.rtol:g}', f'{r.err:.2e}', f'{r.wall * 1e3:.2f}',
                        r.nfev] for r in rows])
    return lines


def _shape(spec: str) -> str:
    """Return '3 coordinates, 2 rotors) with K_D set for both rotors' of a system file's scene."""
    import gyro_rotor.numerics.bench as bench
    system = bench.parse_scene_spec(spec)[0].system
    rotors = 'both rotors' if system.m == 2 else 'every rotor'
    return f'{system.n} coordinates, {system.m} rotors) with K_D set for {rotors}'


def stiff_lines(args: argparse.Namespace, spec: str) -> list:
    """Return the table ``stiff`` (:func:`~gyro_rotor.numerics.bench.stiff_table`) as markdown."""
    import gyro_rotor.numerics.bench as bench
    rows, checks = bench.stiff_table(name=spec, t_end=args.t_end, level=args.level,
                                     repeats=args.repeats)
    lines = ['# Stiff drive on a generated system: auto vs scipy and CyRK', '',
             f'Command: `{_command(args)}`', '',
             f'{spec} ({_shape(spec)}, '
             f'{args.t_end:g} s simulated, sampled at {bench.SAMPLE_RATE:g} Hz (every method '
             'returns the same samples; ours land their steps on them, scipy interpolates). '
             'Error: the largest |q - q_ref|, |z - z_ref| [rad] over the samples; reference: '
             'radau9 at rtol 1e-13, checked against rodas4 (forward-difference Jacobian) at '
             'rtol 1e-12. Wall: best of '
             f'{args.repeats} runs for every method (scipy on a sympy-lambdified right-hand '
             'side, `+jac`: with the lambdified Jacobian; `CyRK+numba:`, where CyRK is '
             'installed: its Radau and LSODA on a numba cfunc of the same lambdify, the '
             'constants substituted). Machine: '
             f'{platform.machine()}, {os.cpu_count()} cores, shared with other jobs (load '
             'average in the table).', '',
             f'## Cheapest run with error <= {args.level:g}', '']
    ours_all, cheapest = [], []
    for K_D in sorted(checks):
        best = {}
        for r in rows:
            if r.K_D == K_D and r.err <= args.level and (
                    r.method not in best or r.wall < best[r.method].wall):
                best[r.method] = r
        ours = min((r for m, r in best.items() if m.startswith('auto')),
                   key=lambda r: r.wall, default=None)
        scipy_best, peer_best = (
            min((r for m, r in best.items() if m.startswith(prefix)), key=lambda r: r.wall,
                default=None) for prefix in ('lambdify', bench.PEER_PREFIX))
        for r in sorted(best.values(), key=lambda r: r.wall):
            gain = [f'{other.wall / r.wall:.1f}x' if r is ours and other else ''
                    for other in (scipy_best, peer_best)]
            cheapest.append([f'{K_D:g}', r.method, f'{r.rtol:g}', f'{r.err:.2e}',
                             f'{r.ms_per_s:.2f}', r.nfev, f'{r.load:.1f}', *gain])
        if ours:
            ours_all.append(ours)
    lines += md_table(['K_D', 'method', 'rtol', 'error', 'ms per simulated s', 'nfev', 'load',
                       'scipy best / ours', 'CyRK best / ours'], cheapest)
    lines += ['']
    lines += md_table(['K_D', 'reference check: largest difference rodas4 - radau9 [rad]'],
                      [[f'{K_D:g}', f'{checks[K_D]:.1e}'] for K_D in sorted(checks)])
    if ours_all:
        costs = [r.ms_per_s for r in ours_all]
        lines += ['', f'auto over K_D = {", ".join(f"{r.K_D:g}" for r in ours_all)}: '
                  f'{", ".join(f"{c:.2f}" for c in costs)} ms per simulated s; largest / '
                  f'smallest = {max(costs) / min(costs):.2f}.']
    lines += ['', '## All runs', '']
    lines += md_table(['K_D', 'method', 'rtol', 'error', 'wall [ms]', 'ms per simulated s',
                       'nfev', 'load'],
                      [[f'{r.K_D:g}', r.method, f'{r.rtol:g}', f'{r.err:.2e}',
                        f'{r.wall * 1e3:.2f}', f'{r.ms_per_s:.2f}', r.nfev, f'{r.load:.1f}']
                       for r in rows])
    return lines
