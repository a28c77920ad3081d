"""Run a sweep's blocks: serially in this process, or as Dask tasks on a cluster.

``Executor.SERIAL`` calls :func:`~.task.run_block` block after block. ``Executor.LOCAL``
starts a ``distributed.LocalCluster`` with one worker process per core (``processes=True``,
``threads_per_worker=1``: the compiled ensemble holds the GIL) and ``Executor.ADDRESS``
connects to an existing scheduler (its workers need gyro_rotor installed). Each block is
one task (``retries`` re-runs a task that raised; a task whose worker died is rescheduled
by the scheduler). The driver writes each block's Parquet file as its task completes, so
the output grows incrementally and no shared file system is needed; one file per block
index makes every point appear exactly once, whatever was retried.
"""

from __future__ import annotations

import dataclasses
import enum
import os
import sys
import time
from typing import Callable, TextIO

from gyro_rotor.analysis.sweep.store import SweepStore
from gyro_rotor.analysis.sweep.task import BlockResult, run_block, SweepSpec
from gyro_rotor.errors import ParameterError

__all__ = ['Executor', 'SweepRun', 'run_sweep', 'TextProgress', 'start_client', 'TASK_RETRIES']

#: re-runs of a task that raised (a worker that died is handled by the scheduler)
TASK_RETRIES = 2


class Executor(enum.StrEnum):
    """Where the blocks run."""

    SERIAL = 'serial'
    LOCAL = 'local'
    ADDRESS = 'address'


@dataclasses.dataclass
class SweepRun:
    """What a call of :func:`run_sweep` did."""

    spec: SweepSpec
    executor: Executor
    workers: int
    blocks_total: int
    blocks_skipped: int
    blocks_run: list
    points_run: int
    trajectory_steps: int
    work_s: float
    wall_s: float
    #: block files found on --resume that are not blocks of this sweep: file -> why
    refused: dict = dataclasses.field(default_factory=dict)

    @property
    def steps_per_s(self) -> float:
        """Trajectory-steps per wall second."""
        return self.trajectory_steps / self.wall_s if self.wall_s > 0 else float('nan')


class TextProgress:
    """A one-line text progress bar on a stream (redrawn with CR on a terminal)."""

    def __init__(self, total_points: int, stream: TextIO | None = None, width: int = 30):
        self.total = max(1, total_points)
        self.done = 0
        self.stream = stream if stream is not None else sys.stderr
        self.width = width
        self.t0 = time.perf_counter()
        self.tty = hasattr(self.stream, 'isatty') and self.stream.isatty()
        self._last_tenth = -1

    def update(self, points: int) -> None:
        """Count ``points`` more finished points and redraw."""
        self.done += points
        frac = self.done / self.total
        el = time.perf_counter() - self.t0
        eta = el / frac - el if frac > 0 else float('nan')
        n = int(round(frac * self.width))
        line = (f'[{"#" * n}{"." * (self.width - n)}] {self.done}/{self.total} points '
                f'{100 * frac:5.1f}%  {el:6.1f} s  eta {eta:6.1f} s')
        if self.tty:
            self.stream.write('\r' + line + ('\n' if self.done >= self.total else ''))
        elif int(frac * 10) != self._last_tenth or self.done >= self.total:
            self._last_tenth = int(frac * 10)
            self.stream.write(line + '\n')
        self.stream.flush()


def start_client(executor: Executor, *, workers: int | None = None,
                 scheduler: str | None = None):
    """Return a ``distributed.Client``: a new LocalCluster or the scheduler at ``scheduler``."""
    from distributed import Client, LocalCluster
    if executor is Executor.ADDRESS:
        try:
            return Client(scheduler, timeout='10s')
        except (OSError, TimeoutError, ValueError) as err:
            raise ParameterError(f'--scheduler {scheduler}: cannot connect: {err}') from None
    n = workers or os.cpu_count() or 1
    if n < 1:
        raise ParameterError(f'--workers must be positive, got {n}')
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                           dashboard_address=':0', silence_logs=40)
    return Client(cluster)


def _serial(spec, todo, on_result):
    for b in todo:
        on_result(run_block(spec, b))


def _dask(spec, todo, on_result, client):
    from distributed import as_completed
    token = f'{os.getpid()}-{time.time_ns()}'
    futures = [client.submit(run_block, spec, b, key=f'gyro-rotor-sweep-{token}-{b}',
                             pure=False, retries=TASK_RETRIES) for b in todo]
    for fut in as_completed(futures):
        on_result(fut.result())
        fut.release()


def run_sweep(spec: SweepSpec, out, *, executor: Executor = Executor.LOCAL,
              workers: int | None = None, scheduler: str | None = None, client=None,
              resume: bool = False, progress: TextProgress | bool | None = None,
              on_block: Callable[[BlockResult], None] | None = None) -> SweepRun:
    """Run the blocks of ``spec`` not yet in ``out`` and write each as it finishes.

    ``client``: an existing ``distributed.Client`` (then ``executor`` only labels the run).
    ``on_block`` is called in the driver after each block is written (tests use it to
    interrupt a sweep or kill a worker).
    """
    store = SweepStore(out)
    spec = store.prepare(spec, resume=resume)
    done = store.done_blocks(spec) if resume else set()
    refused = dict(store.refused)
    todo = [b for b in range(spec.n_blocks) if b not in done]
    if progress is True:
        progress = TextProgress(sum(spec.block_points(b).size for b in todo))
    ran: list = []
    acc = {'points': 0, 'steps': 0, 'work': 0.0}

    def on_result(res: BlockResult) -> None:
        store.write(res, spec)
        ran.append(res.block)
        acc['points'] += res.columns['point'].size
        acc['steps'] += res.steps
        acc['work'] += res.work_s
        if progress:
            progress.update(res.columns['point'].size)
        if on_block is not None:
            on_block(res)
    t0 = time.perf_counter()
    n_workers = 1
    if not todo and client is None:
        n_workers = 0                 # nothing to compute: no cluster is started
    elif executor is Executor.SERIAL and client is None:
        _serial(spec, todo, on_result)
    else:
        own = client is None
        if own:
            client = start_client(executor, workers=workers, scheduler=scheduler)
        try:
            n_workers = len(client.scheduler_info(n_workers=-1)['workers'])
            if todo:
                _dask(spec, todo, on_result, client)
        finally:
            if own:
                cluster = getattr(client, 'cluster', None)
                client.close()
                if cluster is not None:
                    cluster.close()
    return SweepRun(spec=spec, executor=executor, workers=n_workers, blocks_total=spec.n_blocks,
                    blocks_skipped=len(done), blocks_run=ran, points_run=acc['points'],
                    trajectory_steps=acc['steps'], work_s=acc['work'],
                    wall_s=time.perf_counter() - t0, refused=refused)
