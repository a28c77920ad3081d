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

import sys
import time
from typing import Sequence

import numpy as np


def warm_up() -> float:
    """Compile every kernel (about 30 s cold, well under a second cached); wall seconds."""
    from gyro_rotor.numerics.ensemble import run_ensemble
    from gyro_rotor.numerics.integrators import METHODS, integrate, make_integrator
    from gyro_rotor.core.scene import load_scene
    t0 = time.perf_counter()
    # the kernels are compiled per model (kernels.KIND): the full model and the shipped
    # locked_housing scene's
    for scene_name in ('precession', 'locked_housing'):
        scene = load_scene(scene_name)
        model = scene.make_model()
        y0 = scene.initial_state(model)
        for name in METHODS:
            if name == 'split8' and model.name != 'full':
                continue
            integrate(model, y0, (0.0, 0.01), np.array([0.0, 0.01]), method=name)
            make_integrator(name, model, y0).advance_to(0.01)
    scene = load_scene('precession')
    model = scene.make_model()
    y0 = scene.initial_state(model)
    t_eval = np.linspace(0.0, 0.01, 3)
    for method in ('rk4', 'rk8'):
        run_ensemble(model, np.tile(y0, (2, 1)), t_eval, method=method)
    return time.perf_counter() - t0


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
    # python -m gyro_rotor.numerics.integrators.warmup [--live SCENE ...]
    if sys.argv[1:2] == ['--live']:
        print(f'gyro_rotor: live kernels ready ({warm_up_live(sys.argv[2:]):.1f} s)',
              file=sys.stderr)
    else:
        print(f'gyro_rotor: integrator kernels ready ({warm_up():.1f} s)', file=sys.stderr)
