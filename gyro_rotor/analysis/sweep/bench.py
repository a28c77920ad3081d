"""The sweep benchmark: throughput of a pull-in sweep serial and on 1, 2, ... local workers.

A pull-in sweep of the ``pole_slip`` scene over initial slip speed and initial lag
(10^5 points by default) runs serially in this process and on a LocalCluster of each
worker count. Reported per run: trajectory-steps per wall second (RK4 steps x
trajectories), the scaling efficiency rate(w) / (w rate(1 worker)), and the task
overhead, measured two ways: the round trip of a no-op task through the same cluster per
block (the fixed cost Dask adds to each task) against the mean work of a block, and end to
end, 1 - (sum of the work measured inside the tasks) / (workers x wall). The estimate for
a cluster of N workers assumes each worker as fast as the measured single worker and the
measured per-task overhead: T(N) = ceil(blocks / N) (w_block + o_task).
"""

from __future__ import annotations

import dataclasses
import math
import os
import tempfile
import time
from typing import Callable, Sequence

__all__ = ['BenchRow', 'run_bench', 'bench_table', 'BENCH_GRID', 'noop_overhead']

#: 500 x 200 = 10^5 points: initial slip speed and initial lag of the pole_slip drive
BENCH_GRID = ('initial.dzdot=-200:200:500', 'initial.dz=-3:3:200')


@dataclasses.dataclass
class BenchRow:
    """One run of the benchmark."""

    label: str
    workers: int
    points: int
    blocks: int
    wall_s: float
    steps_per_s: float
    efficiency: float
    task_overhead: float
    end_to_end_overhead: float
    load: tuple = (math.nan, math.nan)


def _noop(x):
    return x


def noop_overhead(client, n_tasks: int = 200) -> float:
    """Wall seconds per no-op task through ``client``, times the workers (worker-seconds/task)."""
    from distributed import as_completed
    workers = len(client.scheduler_info(n_workers=-1)['workers'])
    t0 = time.perf_counter()
    futs = [client.submit(_noop, i, pure=False) for i in range(n_tasks)]
    for f in as_completed(futs):
        f.result()
    return (time.perf_counter() - t0) * workers / n_tasks


def _warm(spec) -> float:
    from gyro_rotor.analysis.sweep.task import make_spec, run_block
    t0 = time.perf_counter()
    run_block(make_spec(spec.scene, ['initial.dzdot=-60:-60:1'], t_end=0.05), 0)
    return time.perf_counter() - t0


def _row(label: str, r, o_task: float, rate1: float | None,
         load0: float) -> BenchRow:
    w = max(1, r.workers)
    block_work = r.work_s / max(1, len(r.blocks_run))
    eff = r.steps_per_s / (w * rate1) if rate1 else math.nan
    return BenchRow(label=label, workers=w, points=r.points_run, blocks=len(r.blocks_run),
                    wall_s=r.wall_s, steps_per_s=r.steps_per_s, efficiency=eff,
                    task_overhead=o_task / block_work if o_task == o_task else math.nan,
                    end_to_end_overhead=1.0 - r.work_s / (w * r.wall_s),
                    load=(load0, os.getloadavg()[0]))


def run_bench(out_dir: str | None = None, *, t_end: float = 0.3,
              grid: Sequence[str] = BENCH_GRID, workers: Sequence[int] = (1, 2),
              progress: Callable[[str], None] | None = None) -> tuple[list, dict]:
    """Run the benchmark; return the rows and the extrapolation inputs.

    The sweeps' Parquet files go to a temporary directory under ``out_dir`` (default: the
    system's temporary directory), removed at the end.
    """
    # imported here: the grid (``gyro-rotor sweep-bench --help``) need not load the sweep
    from gyro_rotor.analysis.sweep.runner import Executor, run_sweep, start_client
    from gyro_rotor.analysis.sweep.task import make_spec
    say = progress or (lambda s: None)
    spec = make_spec('pole_slip', list(grid), t_end=t_end)
    _warm(spec)
    rows: list = []
    tmp = tempfile.TemporaryDirectory(dir=out_dir)
    say(f'serial: {spec.n_points} points, {spec.n_blocks} blocks of {spec.block_size}, '
        f'{spec.steps_per_trajectory} steps each')
    load0 = os.getloadavg()[0]
    r = run_sweep(spec, os.path.join(tmp.name, 'serial'), executor=Executor.SERIAL)
    rows.append(_row('serial (in process)', r, math.nan, None, load0))
    say(f'  {r.wall_s:.1f} s, {r.steps_per_s:.4g} trajectory-steps/s')
    rate1 = o1 = block_work1 = None
    for w in workers:
        client = start_client(Executor.LOCAL, workers=w)
        try:
            client.wait_for_workers(w)
            client.run(_warm, spec)
            o_task = noop_overhead(client)
            say(f'{w} worker(s): no-op task {1e3 * o_task:.2f} worker-ms per task')
            load0 = os.getloadavg()[0]
            r = run_sweep(spec, os.path.join(tmp.name, f'w{w}'), executor=Executor.LOCAL,
                          client=client)
        finally:
            cluster = client.cluster
            client.close()
            cluster.close()
        if rate1 is None:
            rate1, o1 = r.steps_per_s / w, o_task
            block_work1 = r.work_s / max(1, len(r.blocks_run))
        rows.append(_row(f'LocalCluster, {w} worker(s)', r, o_task, rate1, load0))
        say(f'  {r.wall_s:.1f} s, {r.steps_per_s:.4g} trajectory-steps/s')
    tmp.cleanup()
    extra = {'rate1': rate1, 'o_task': o1, 'block_work': block_work1, 'blocks': spec.n_blocks,
             'steps_total': spec.n_points * spec.steps_per_trajectory, 'spec': spec}
    return rows, extra


def _estimate(extra: dict, n: int) -> tuple[float, float]:
    t = math.ceil(extra['blocks'] / n) * (extra['block_work'] + extra['o_task'])
    return t, extra['steps_total'] / t


def bench_table(rows: list, extra: dict, load: tuple) -> str:
    """Return the benchmark as a Markdown text (tables and the estimate)."""
    spec = extra['spec']
    lines = [f'Pull-in sweep of pole_slip, {spec.n_points} points ({" x ".join(spec.grid)}), '
             f't_end {spec.t_end:g} s, RK4 step {spec.step:.4g} s ({spec.steps_per_trajectory} '
             f'steps per trajectory), {spec.n_blocks} blocks of {spec.block_size} points; '
             f'machine: {os.cpu_count()} cores, load average {load[0]:.2f} before and '
             f'{load[1]:.2f} after (shared with other jobs).', '',
             '| run | workers | wall [s] | trajectory-steps/s | scaling efficiency | '
             'task overhead (no-op task / block work) | end-to-end overhead | '
             'load average (start, end of the run) |',
             '|---|---|---|---|---|---|---|---|']
    for r in rows:
        eff = '-' if math.isnan(r.efficiency) else f'{100 * r.efficiency:.0f} %'
        ov = '-' if math.isnan(r.task_overhead) else f'{100 * r.task_overhead:.3f} %'
        lines.append(f'| {r.label} | {r.workers} | {r.wall_s:.1f} | {r.steps_per_s:.4g} | '
                     f'{eff} | {ov} | {100 * r.end_to_end_overhead:.1f} % | '
                     f'{r.load[0]:.2f}, {r.load[1]:.2f} |')
    lines += ['', f'Estimate (not measured) for a cluster of N workers, each as fast as the '
              f'measured single worker ({extra["rate1"]:.4g} trajectory-steps/s), '
              f'{1e3 * extra["o_task"]:.2f} ms overhead per task, '
              f'{extra["block_work"]:.2f} s per block: T(N) = ceil({extra["blocks"]}/N) '
              f'(block + overhead).', '', '| N | T(N) [s] | trajectory-steps/s |',
              '|---|---|---|']
    for n in (1, 2, 8, 32, 128):
        t, rate = _estimate(extra, n)
        lines.append(f'| {n} | {t:.1f} | {rate:.3g} |')
    lines += ['', 'The machine is shared: the scaling efficiency compares runs made under the '
              'load averages in the table (the 1-minute average of the whole machine, '
              'this benchmark included), not a quiet machine.']
    lines += ['', f'Beyond N = {extra["blocks"]} workers the blocks run out: smaller '
              '--block sizes (down to about 20 x the overhead per task) keep them busy.']
    return '\n'.join(lines) + '\n'
