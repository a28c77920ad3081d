"""``gyro-rotor sweep-bench``: throughput of a 10^5-point pull-in sweep, serial and on Dask."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from gyro_rotor.analysis.sweep.bench import BENCH_GRID, bench_table, run_bench
from gyro_rotor.errors import ParameterError

HELP = ('benchmark gyro-rotor sweep: trajectory-steps/s serial and on 1, 2 local workers, '
        'task overhead, estimate for N workers')


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``sweep-bench``."""
    p.add_argument('--out', default='bench', help='directory for sweep_bench.md (default bench)')
    p.add_argument('--t-end', type=float, default=0.5, help='duration per trajectory [s]')
    p.add_argument('--grid', action='append', default=None,
                   help=f'grid axes (default: {" ".join(BENCH_GRID)})')
    p.add_argument('--workers', type=int, nargs='+', default=[1, 2],
                   help='local worker counts to measure (default 1 2)')


def run(args: argparse.Namespace) -> int:
    """Run, print and save the benchmark table."""
    if any(w < 1 for w in args.workers):
        raise ParameterError(f'--workers must be positive, got {args.workers}')
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    load0 = os.getloadavg()[0]
    rows, extra = run_bench(str(out), t_end=args.t_end, grid=args.grid or BENCH_GRID,
                            workers=args.workers, progress=print)
    text = bench_table(rows, extra, (load0, os.getloadavg()[0]))
    (out / 'sweep_bench.md').write_text(text, encoding='utf-8')
    print(text)
    print(f'wrote {out / "sweep_bench.md"}')
    return 0
