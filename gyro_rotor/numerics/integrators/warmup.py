"""Compile the integrators' numba kernels once, into numba's on-disk cache.

``python -m gyro_rotor.numerics.integrators.warmup`` (run by ``bootstrap.sh`` after an install)
runs every method briefly through both of its paths (the compiled ``run`` loop of
``integrate`` and the ``advance_to`` stepping of the nodes), and the ensemble, so that
neither the first demo nor a node started by a test waits for the JIT compiler. Importing
the integrators writes the generated Runge-Kutta kernels into the cache first, if they are
not there yet (:func:`~.rk_codegen.load`). Without numba it does nothing useful but does
no harm.
"""

from __future__ import annotations

import concurrent.futures
import multiprocessing
import os
import sys
import time
from typing import Sequence

import numpy as np

#: the methods whose kernels take longest to compile, first, so that the workers of
#: :func:`warm_up` finish together (cold, both models, the other core busy: vern9 242 s,
#: vern8 195, vern7 157, dop853 159; rk4, rodas4 and radau9 34-41 s, the rest under 2 s)
SLOWEST_FIRST = ('vern9', 'vern8', 'vern7', 'dop853')
#: the models the kernels are compiled for (kernels.KIND): the full model and the shipped
#: locked_housing scene's
WARM_SCENES = ('precession', 'locked_housing')


def warm_up(workers: int | None = None, jobs: Sequence[str] | None = None) -> float:
    """Compile every kernel: cold 658 s on one worker, 355 s on two; cached under 2 s.

    (Measured on the quiet 2-core machine, AMD EPYC, with empty numba and kernel caches.)

    One job a method (both its paths on both WARM_SCENES' models) and one for the ensemble
    (``jobs``: by default all, SLOWEST_FIRST first), on ``workers`` processes (default: the
    cores this process may run on): the jobs compile different functions, and numba writes
    each cache file whole (a temporary file renamed into place), so the processes share the
    cache safely. A job's error is raised here. Returns wall seconds.
    """
    t0 = time.perf_counter()
    jobs = warm_jobs() if jobs is None else list(jobs)
    if workers is None:
        workers = len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else (
            os.cpu_count() or 1)
    workers = max(1, min(int(workers), len(jobs)))
    if workers == 1:
        for job in jobs:
            _warm_job(job)
    else:
        # spawned, not forked: a fork would copy this process's LLVM state
        ctx = multiprocessing.get_context('spawn')
        with concurrent.futures.ProcessPoolExecutor(workers, mp_context=ctx) as pool:
            list(pool.map(_warm_job, jobs))         # a job's exception is raised here
    return time.perf_counter() - t0


def warm_jobs() -> list[str]:
    """Return :func:`warm_up`'s jobs: every method, SLOWEST_FIRST first, and the ensemble."""
    from gyro_rotor.numerics.integrators import METHODS
    jobs = [m for m in SLOWEST_FIRST if m in METHODS]
    return jobs + [m for m in METHODS if m not in jobs] + ['ensemble']


def _warm_job(job: str) -> str:
    """Compile one job of :func:`warm_up`: a method's kernels, or the ensemble's."""
    from gyro_rotor.core.scene import load_scene
    from gyro_rotor.numerics.ensemble import run_ensemble
    from gyro_rotor.numerics.integrators import integrate, make_integrator
    if job == 'ensemble':
        scene = load_scene('precession')
        model = scene.make_model()
        y0 = scene.initial_state(model)
        t_eval = np.linspace(0.0, 0.01, 3)
        for method in ('rk4', 'rk8'):
            run_ensemble(model, np.tile(y0, (2, 1)), t_eval, method=method)
        return job
    for scene_name in WARM_SCENES:
        scene = load_scene(scene_name)
        model = scene.make_model()
        if job == 'split8' and model.name != 'full':
            continue
        y0 = scene.initial_state(model)
        integrate(model, y0, (0.0, 0.01), np.array([0.0, 0.01]), method=job)
        make_integrator(job, model, y0).advance_to(0.01)
    return job


def warm_up_live(scenes: Sequence[str]) -> float:
    """Compile only what rotor_sim runs on ``scenes``: their live stepping; wall seconds.

    The node's defaults (:data:`~gyro_rotor.node_settings.NODE_KEYS`, with and without
    ``stop_at_t_end``, which may change auto's choice), a tick, a kick and a tick: a copy
    of the package installed elsewhere (a colcon overlay) then starts its nodes without
    the JIT compiler, at a fraction of :func:`warm_up`'s cost.
    """
    from gyro_rotor.core.scene import load_scene
    from gyro_rotor.node_settings import NODE_KEYS
    from gyro_rotor.numerics.live import LiveSimulation
    t0 = time.perf_counter()
    for name in scenes:
        scene = load_scene(name)
        for stop in (False, True):
            cfg = {k: spec[1] for k, spec in NODE_KEYS.items()}
            cfg.update(real_time_factor=0.0, stop_at_t_end=stop)
            sim = LiveSimulation(scene, cfg, scene.perturbation, budget=None)
            sim.pacer.t_end = 0.02
            sim.tick()
            sim.perturb()
            sim.pacer.t_end = 0.04
            sim.tick()
    return time.perf_counter() - t0


if __name__ == '__main__':
    # python -m gyro_rotor.numerics.integrators.warmup [--live SCENE ...]; the functions of
    # the package's module, not of __main__, so that the workers find them by name
    from gyro_rotor.numerics.integrators import warmup
    if sys.argv[1:2] == ['--live']:
        print(f'gyro_rotor: live kernels ready ({warmup.warm_up_live(sys.argv[2:]):.1f} s)',
              file=sys.stderr)
    else:
        print(f'gyro_rotor: integrator kernels ready ({warmup.warm_up():.1f} s)',
              file=sys.stderr)
