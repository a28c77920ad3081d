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


if __name__ == '__main__':
    print(f'gyro_rotor: integrator kernels ready ({warm_up():.1f} s)', file=sys.stderr)
