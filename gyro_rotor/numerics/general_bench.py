"""Benchmarks of the general rotor systems (issue 15): speed measured, never assumed.

Three measurements, each returned as data (``gyro-rotor bench-general`` prints and saves):

- :func:`rhs_cost`: nanoseconds per right-hand-side evaluation of the generated code of
  ``centrifuge_euler`` against the hand-written quaternion kernel
  (:func:`gyro_rotor.numerics.integrators.kernels.rhs`), both called in a compiled loop at
  the same physical state.
- :func:`compile_times`: generation + compilation of a system in a fresh cache, and the
  load from the cache, each in its own Python process (imports included, interpreter start
  not).
- :func:`work_precision`: the generated Dormand-Prince loop against the usual user's path,
  sympy ``lambdify`` to numpy plus scipy ``solve_ivp`` (RK45, DOP853, Radau, LSODA) on the
  same equations: error (max over samples at 100 Hz of the largest |q - q_ref|, |z -
  z_ref|) against wall time over a tolerance sweep, the reference being the generated loop
  at rtol 1e-13.
"""

from __future__ import annotations

import dataclasses
import math
import os
import subprocess
import sys
import tempfile
import time

from gyro_rotor.core.system.codegen import pack
from gyro_rotor.core.system.equations import derive
from gyro_rotor.core.system.scene import load_general_scene
from gyro_rotor.numerics.integrators import kernels
import numpy as np

__all__ = ['rhs_cost', 'compile_times', 'work_precision', 'WPRow', 'best_at', 'SCIPY_METHODS']

SCIPY_METHODS = ('RK45', 'DOP853', 'Radau', 'LSODA')
OUR_RTOLS = (1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12)
SCIPY_RTOLS = (1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12)
SAMPLE_RATE = 100.0
#: a scipy run slower than this [wall s] ends that method's sweep
SLOW_RUN = 5.0


@kernels.njit
def _loop_hand(y, P, out, count):
    acc = 0.0
    for i in range(count):
        y[8] += 1e-15
        kernels.rhs(0, y, P, out)
        acc += out[4]
    return acc


@kernels.njit
def _loop_generated(f, y, P, out, count):
    acc = 0.0
    for i in range(count):
        y[7] += 1e-15
        f(y, P, out)
        acc += out[3]
    return acc


def rhs_cost(count: int = 2_000_000, repeats: int = 5) -> dict:
    """Nanoseconds per evaluation: generated centrifuge_euler vs the hand-written kernel."""
    from gyro_rotor.core.model import FullModel
    from gyro_rotor.core.params import RotorParams
    scene = load_general_scene('centrifuge_euler')
    model = scene.make_model()
    e = {'theta': 0.4, 'thetadot': 0.3, 'psi': 0.1, 'psidot': 1.5, 'phi_M': 0.2,
         'phi_M_dot': -0.7, 'z': 0.05, 'zdot': 0.4}
    yg = model.state([e['theta'], e['psi'], e['phi_M']],
                     [e['thetadot'], e['psidot'], e['phi_M_dot']], [e['z']], [e['zdot']])
    yh = FullModel(RotorParams()).state_from_euler(**e)
    Ph = kernels.pack_params(RotorParams())
    Pg = pack(model.system)
    oh, og = np.empty(10), np.empty(9)
    _loop_hand(yh.copy(), Ph, oh, 10)
    _loop_generated(model.compiled.rhs, yg.copy(), Pg, og, 10)
    th, tg = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        _loop_hand(yh.copy(), Ph, oh, count)
        th.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        _loop_generated(model.compiled.rhs, yg.copy(), Pg, og, count)
        tg.append(time.perf_counter() - t0)
    hand, gen = min(th) / count * 1e9, min(tg) / count * 1e9
    return {'hand_ns': hand, 'generated_ns': gen, 'ratio': gen / hand, 'count': count}


_COMPILE_SCRIPT = """
import time
t0 = time.perf_counter()
import numba, sympy
from gyro_rotor.core.system.system_file import load_system
from gyro_rotor.core.system.codegen import compile_system
t1 = time.perf_counter()
s = load_system({name!r})
t2 = time.perf_counter()
c = compile_system(s)
t3 = time.perf_counter()
print(t1 - t0, t2 - t1, t3 - t2, int(c.from_cache))
"""


def compile_times(name: str = 'twin_gimbal') -> dict:
    """Seconds to generate + compile ``name`` in a fresh cache, then to load it from there.

    Each in a new process, split into: imports (numba, sympy, gyro_rotor), reading the
    system file (parse and checks), and compile_system (generate and compile, or load).
    """
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, 'GYRO_ROTOR_CACHE': tmp}
        for label in ('first', 'cached'):
            res = subprocess.run([sys.executable, '-c', _COMPILE_SCRIPT.format(name=name)],
                                 env=env, capture_output=True, text=True, check=True)
            imports, load, comp, from_cache = res.stdout.split()[-4:]
            out[label] = {'imports': float(imports), 'load_system': float(load),
                          'compile_system': float(comp), 'from_cache': bool(int(from_cache))}
    return out


@dataclasses.dataclass
class WPRow:
    """One run of the work-precision sweep."""

    system: str
    method: str
    rtol: float
    err: float
    wall: float
    nfev: int


def _lambdified(scene):
    """Build the user's path: sympy lambdify of Mbar and F to numpy, solve per call."""
    import sympy
    eq = derive(scene.system, jacobians=False)
    n, m, N = eq.n, eq.m, eq.n + eq.m
    z = sympy.symbols(f'z0:{m}', real=True)
    args = list(eq.q) + list(z) + list(eq.v) + list(eq.consts) + list(eq.Omega0)
    f_M = sympy.lambdify(args, eq.Mbar, 'numpy')
    f_F = sympy.lambdify(args, eq.F, 'numpy')
    consts = list(scene.system.constants.values())
    Om = [d.Omega0 for d in scene.system.drives]
    KS = np.array([d.K_S for d in scene.system.drives])
    KD = np.array([d.K_D for d in scene.system.drives])

    def rhs(t, y):
        q, qd, zz, zd = y[:n], y[n:2 * n], y[2 * n:2 * n + m], y[2 * n + m:2 * N]
        a = [*q, *zz, *qd, *zd, *consts, *Om]
        F = np.asarray(f_F(*a), dtype=float).reshape(N)
        F[n:] += -KS * zz - KD * zd
        acc = np.linalg.solve(np.asarray(f_M(*a), dtype=float), F)
        return np.concatenate([qd, acc[:n], zd, acc[n:], [float(KD @ (zd * zd))]])
    return rhs


def _err(Y, ref, n, m) -> float:
    pos = list(range(n)) + list(range(2 * n, 2 * n + m))
    return float(np.abs(Y[:, pos] - ref[:, pos]).max())


def work_precision(names=('centrifuge_euler', 'twin_gimbal', 'elastic_frame'),
                   t_end: float = 2.0, repeats: int = 3) -> list[WPRow]:
    """Error against wall time: generated loop vs lambdify + solve_ivp (module doc)."""
    from scipy.integrate import solve_ivp
    rows = []
    for name in names:
        scene = load_general_scene(name)
        model = scene.make_model()
        te = np.arange(int(round(t_end * SAMPLE_RATE)) + 1) / SAMPLE_RATE
        y0 = scene.initial_state(model)
        ref = model.integrate(y0, te, rtol=1e-13, atol=1e-15).y
        n, m = model.n, model.m
        for rtol in OUR_RTOLS:
            walls = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                run = model.integrate(y0, te, rtol=rtol, atol=rtol * 1e-3)
                walls.append(time.perf_counter() - t0)
            rows.append(WPRow(name, 'generated dopri5', rtol, _err(run.y, ref, n, m),
                              min(walls), run.nfev))
        rhs = _lambdified(scene)
        for method in SCIPY_METHODS:
            for rtol in SCIPY_RTOLS:
                t0 = time.perf_counter()
                sol = solve_ivp(rhs, (0.0, te[-1]), y0, method=method, t_eval=te, rtol=rtol,
                                atol=rtol * 1e-3)
                wall = time.perf_counter() - t0
                err = _err(sol.y.T, ref, n, m) if sol.success else math.nan
                rows.append(WPRow(name, f'lambdify+{method}', rtol, err, wall, int(sol.nfev)))
                if wall > SLOW_RUN:
                    break
    return rows


def best_at(rows: list[WPRow], level: float) -> dict:
    """Per (system, method): the fastest run with error <= level (or None)."""
    best: dict = {}
    for r in rows:
        if not (r.err <= level):
            continue
        key = (r.system, r.method)
        if key not in best or r.wall < best[key].wall:
            best[key] = r
    return best
