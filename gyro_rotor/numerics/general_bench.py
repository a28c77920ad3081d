"""Benchmarks of the general rotor systems (issue 15): speed measured, never assumed.

Three measurements, each returned as data (``gyro-rotor bench-general`` prints and saves):

- :func:`rhs_cost`: nanoseconds per right-hand-side evaluation of the generated code of
  ``centrifuge_euler`` against the hand-written quaternion kernel
  (:func:`gyro_rotor.numerics.integrators.kernels.rhs`), both called in a compiled loop at
  the same physical state.
- :func:`compile_times`: generation + compilation of a system in a fresh cache, and the
  load from the cache, each in its own Python process (imports included, interpreter start
  not), and the first integration there (the project's kernels for first-class right-hand
  sides: compiled once per machine, then loaded from numba's cache).
- :func:`work_precision`: the default method of general systems (the project's integrators
  on the generated right-hand side, :func:`gyro_rotor.numerics.simulate.integrate` with
  ``auto``) against the usual user's path, sympy ``lambdify`` to numpy plus scipy
  ``solve_ivp`` (RK45, DOP853, Radau, LSODA) on the same equations: error (max over samples
  at 100 Hz of the largest |q - q_ref|, |z - z_ref|) against wall time over a tolerance
  sweep, the reference being dop853 at rtol 1e-13; and, where installed, the speed-conscious
  user's path: CyRK's ``nbsolve2_ivp`` (RK45, DOP853, Vern7, Vern8, LSODA) on a numba cfunc of
  the same lambdify with the constants substituted
  (:func:`gyro_rotor.numerics.bench_peers.make_general_peer`), rows ``CyRK+numba:<method>``.
- :func:`stiff_table` (``--stiff``): a stiff drive on twin_gimbal, K_D = 1e2, 1e4, 1e6:
  ``auto`` (radau9 with the generated Jacobian) against scipy's Radau, BDF and LSODA on the
  lambdified right-hand side, with and without a lambdified Jacobian, in wall milliseconds
  per simulated second at a given error (issue 25, item 4).
"""

from __future__ import annotations

import dataclasses
import math
import os
import subprocess
import sys
import tempfile
import time

from gyro_rotor.core.scene import load_scene
from gyro_rotor.core.system.codegen import pack
from gyro_rotor.core.system.equations import derive
from gyro_rotor.numerics.integrators import kernels
from gyro_rotor.numerics.simulate import integrate
import numpy as np

__all__ = ['rhs_cost', 'compile_times', 'work_precision', 'WPRow', 'best_at', 'SCIPY_METHODS',
           'DEFAULT_LABEL', 'stiff_table', 'StiffRow', 'STIFF_K_D']

SCIPY_METHODS = ('RK45', 'DOP853', 'Radau', 'LSODA')
#: the label of our rows: general.integrate with method 'auto'
DEFAULT_LABEL = 'default'
#: the label prefix of the compiled peer's rows (CyRK on a numba lambdify)
PEER_PREFIX = 'CyRK+numba:'
OUR_RTOLS = (1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12)
SCIPY_RTOLS = (1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12)
SAMPLE_RATE = 100.0
#: a scipy run slower than this [wall s] ends that method's sweep
SLOW_RUN = 5.0


@kernels.njit(error_model='numpy')      # as the integrators' kernels
def _loop_hand(kind, y, P, out, count):
    acc = 0.0
    for i in range(count):
        y[8] += 1e-15
        kernels.rhs(kind, y, P, out)
        acc += out[4]
    return acc


@kernels.njit(error_model='numpy')      # as the integrators' kernels
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
    scene = load_scene('centrifuge_euler')
    model = scene.make_model()
    e = {'theta': 0.4, 'thetadot': 0.3, 'psi': 0.1, 'psidot': 1.5, 'phi_M': 0.2,
         'phi_M_dot': -0.7, 'z': 0.05, 'zdot': 0.4}
    yg = model.state([e['theta'], e['psi'], e['phi_M']],
                     [e['thetadot'], e['psidot'], e['phi_M_dot']], [e['z']], [e['zdot']])
    yh = FullModel(RotorParams()).state_from_euler(**e)
    Ph = kernels.pack_params(RotorParams())
    Pg = pack(model.system)
    oh, og = np.empty(10), np.empty(9)
    kind = kernels.KIND['full']        # the full model's kind, as the integrators pass it
    _loop_hand(kind, yh.copy(), Ph, oh, 10)
    _loop_generated(model.compiled.rhs, yg.copy(), Pg, og, 10)
    th, tg = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        _loop_hand(kind, yh.copy(), Ph, oh, count)
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
from gyro_rotor.core.system.model import GeneralModel
from gyro_rotor.numerics.simulate import integrate
t1 = time.perf_counter()
s = load_system({name!r})
t2 = time.perf_counter()
c = compile_system(s)
t3 = time.perf_counter()
model = GeneralModel(s, c)
integrate(model, model.state([0.01] * model.n, [0.0] * model.n, [0.0] * model.m,
                             [0.0] * model.m), [0.0, 0.01])
t4 = time.perf_counter()
print(t1 - t0, t2 - t1, t3 - t2, t4 - t3, int(c.from_cache))
"""


def compile_times(name: str = 'twin_gimbal') -> dict:
    """Seconds to generate + compile ``name`` in a fresh cache, then to load it from there.

    Each in a new process with empty caches (ours and numba's), split into: imports (numba,
    sympy, gyro_rotor), reading the system file (parse and checks), compile_system
    (generate and compile, or load) and a first integration (dop853: compiles, or loads,
    the project's kernels for a first-class right-hand side, shared by every system).
    """
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        # numba's cache in a fresh directory too: the first run compiles everything it
        # uses, the integrator kernels for first-class right-hand sides included
        env = {**os.environ, 'GYRO_ROTOR_CACHE': tmp, 'NUMBA_CACHE_DIR': f'{tmp}/numba'}
        for label in ('first', 'cached'):
            res = subprocess.run([sys.executable, '-c', _COMPILE_SCRIPT.format(name=name)],
                                 env=env, capture_output=True, text=True, check=True)
            imports, load, comp, first, from_cache = res.stdout.split()[-5:]
            out[label] = {'imports': float(imports), 'load_system': float(load),
                          'compile_system': float(comp), 'first_run': float(first),
                          'from_cache': bool(int(from_cache))}
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
    """Error against wall time: the default method vs lambdify + solve_ivp (module doc)."""
    from scipy.integrate import solve_ivp
    rows = []
    for name in names:
        scene = load_scene(name)
        model = scene.make_model()
        te = np.arange(int(round(t_end * SAMPLE_RATE)) + 1) / SAMPLE_RATE
        y0 = scene.initial_state(model)
        ref = integrate(model, y0, te, method='dop853', rtol=1e-13, atol=1e-15).y
        n, m = model.n, model.m
        for rtol in OUR_RTOLS:
            walls = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                run = integrate(model, y0, te, rtol=rtol, atol=rtol * 1e-3)
                walls.append(time.perf_counter() - t0)
            rows.append(WPRow(name, f'{DEFAULT_LABEL} ({run.method})', rtol,
                              _err(run.y, ref, n, m), min(walls), run.nfev))
        rows += _peer_rows(name, scene, y0, te, ref, n, m, repeats)
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


def _peer_rows(name, scene, y0, te, ref, n, m, repeats) -> list[WPRow]:
    """Return the rows of CyRK (nbsolve2_ivp) on a numba lambdify of the same equations."""
    from gyro_rotor.numerics import bench_peers
    if 'cyrk' not in bench_peers.available():
        return []
    peer = bench_peers.make_general_peer(scene)
    bench_peers.peer_run(peer, 'cyrk', 'DOP853', y0, te[:2], 1e-3, 1e-6)   # compile
    rows = []
    for method in bench_peers.GENERAL_PEER_METHODS:
        for rtol in SCIPY_RTOLS:
            walls = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                Y, steps = bench_peers.peer_run(peer, 'cyrk', method, y0, te, rtol,
                                                rtol * 1e-3)
                walls.append(time.perf_counter() - t0)
            err = _err(Y, ref, n, m) if Y is not None else math.nan
            rows.append(WPRow(name, f'{PEER_PREFIX}{method}', rtol, err, min(walls), -1))
            if min(walls) > SLOW_RUN:
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


# -- stiff drives on a generated system (issue 25, item 4) ------------------------------------
#: the drive damping of the stiff table (``K_D`` sets every rotor's)
STIFF_K_D = (1e2, 1e4, 1e6)
#: our tolerances in the stiff table (rtol; atol = 1e-3 rtol)
STIFF_OUR_RTOLS = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)
#: scipy's stiff solvers and tolerances in the stiff table
STIFF_SCIPY_METHODS = ('Radau', 'BDF', 'LSODA')
STIFF_SCIPY_RTOLS = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9)


@dataclasses.dataclass
class StiffRow:
    """One run of the stiff table: ``wall`` [s] for ``t_end`` simulated seconds."""

    K_D: float
    method: str
    rtol: float
    err: float
    wall: float
    t_end: float
    nfev: int
    load: float

    @property
    def ms_per_s(self) -> float:
        """Wall milliseconds per simulated second."""
        return self.wall * 1e3 / self.t_end


def _lambdified_jac(scene):
    """Return the user's Jacobian: lambdified Mbar, dMbar/dq, dF/dq, dF/dv, assembled with numpy.

    da/dx = Mbar^-1 (dF/dx + dQ/dx - (dMbar/dx) a), da/dv = Mbar^-1 (dF/dv + dQ/dv) (the
    derivatives of :mod:`~gyro_rotor.core.system.codegen`'s ``jac``, here from lambdify).
    """
    import sympy
    eq = derive(scene.system)
    n, m, N = eq.n, eq.m, eq.n + eq.m
    z = sympy.symbols(f'z0:{m}', real=True)
    args = list(eq.q) + list(z) + list(eq.v) + list(eq.consts) + list(eq.Omega0)
    f_M = sympy.lambdify(args, eq.Mbar, 'numpy')
    f_F = sympy.lambdify(args, eq.F, 'numpy')
    f_dM = sympy.lambdify(args, [eq.Mbar.diff(qk) for qk in eq.q], 'numpy')
    f_Fq = sympy.lambdify(args, eq.F_q, 'numpy')
    f_Fv = sympy.lambdify(args, eq.F_v, 'numpy')
    consts = list(scene.system.constants.values())
    Om = [d.Omega0 for d in scene.system.drives]
    KS = np.array([d.K_S for d in scene.system.drives])
    KD = np.array([d.K_D for d in scene.system.drives])
    ix = np.r_[0:n, 2 * n:2 * n + m]
    iv = np.r_[n:2 * n, 2 * n + m:2 * N]

    def jac(t, y):
        q, qd, zz, zd = y[:n], y[n:2 * n], y[2 * n:2 * n + m], y[2 * n + m:2 * N]
        a_ = [*q, *zz, *qd, *zd, *consts, *Om]
        M = np.asarray(f_M(*a_), dtype=float)
        F = np.asarray(f_F(*a_), dtype=float).reshape(N)
        F[n:] += -KS * zz - KD * zd
        acc = np.linalg.solve(M, F)
        Gx = np.zeros((N, N))
        if n:
            Gx[:, :n] = np.asarray(f_Fq(*a_), dtype=float).reshape(N, n)
            for k, dM in enumerate(f_dM(*a_)):
                Gx[:, k] -= np.asarray(dM, dtype=float) @ acc
        Gx[n:, n:] -= np.diag(KS)
        Gv = np.asarray(f_Fv(*a_), dtype=float).reshape(N, N).copy()
        Gv[n:, n:] -= np.diag(KD)
        J = np.zeros((2 * N + 1, 2 * N + 1))
        J[ix, iv] = 1.0
        J[np.ix_(iv, ix)] = np.linalg.solve(M, Gx)
        J[np.ix_(iv, iv)] = np.linalg.solve(M, Gv)
        J[2 * N, 2 * n + m:2 * N] = 2.0 * KD * zd
        return J
    return jac


def stiff_table(K_Ds=STIFF_K_D, name: str = 'twin_gimbal', t_end: float = 2.0,
                level: float = 1e-6, repeats: int = 3) -> tuple[list, dict]:
    """Stiff drives: ``auto`` against scipy's Radau, BDF, LSODA over K_D (module doc).

    For each K_D (scene override ``K_D``: every rotor's), the error of a run is that of
    :func:`work_precision` (largest |q - q_ref|, |z - z_ref| over the samples at 100 Hz)
    against radau9 at rtol 1e-13, itself checked against rodas4 (forward-difference
    Jacobian, independent code) at rtol 1e-12: ``checks[K_D]`` is their difference. scipy
    runs on the lambdified right-hand side (:func:`_lambdified`), without and with the
    lambdified Jacobian (:func:`_lambdified_jac`); a sweep stops once two runs met
    ``level`` or one took longer than SLOW_RUN. Every wall time is the best of ``repeats``
    runs. Returns (rows, checks).
    """
    from scipy.integrate import solve_ivp
    rows, checks = [], {}
    for K_D in K_Ds:
        scene = load_scene(name, {'K_D': K_D})
        model = scene.make_model()
        te = np.arange(int(round(t_end * SAMPLE_RATE)) + 1) / SAMPLE_RATE
        y0 = scene.initial_state(model)
        n, m = model.n, model.m
        ref = integrate(model, y0, te, method='radau9', rtol=1e-13, atol=1e-16).y
        other = integrate(model, y0, te, method='rodas4', rtol=1e-12, atol=1e-15).y
        checks[K_D] = _err(other, ref, n, m)
        for rtol in STIFF_OUR_RTOLS:
            walls = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                run = integrate(model, y0, te, rtol=rtol, atol=rtol * 1e-3)
                walls.append(time.perf_counter() - t0)
            rows.append(StiffRow(K_D, f'auto ({run.method})', rtol, _err(run.y, ref, n, m),
                                 min(walls), t_end, run.nfev, os.getloadavg()[0]))
        fun, jac = _lambdified(scene), _lambdified_jac(scene)
        for method in STIFF_SCIPY_METHODS:
            for label, kw in (('', {}), ('+jac', {'jac': jac})):
                met = 0
                for rtol in STIFF_SCIPY_RTOLS:
                    walls = []
                    for _ in range(repeats):
                        t0 = time.perf_counter()
                        sol = solve_ivp(fun, (0.0, te[-1]), y0, method=method, t_eval=te,
                                        rtol=rtol, atol=rtol * 1e-3, **kw)
                        walls.append(time.perf_counter() - t0)
                    wall = min(walls)
                    err = _err(sol.y.T, ref, n, m) if sol.success else math.nan
                    rows.append(StiffRow(K_D, f'lambdify+{method}{label}', rtol, err, wall,
                                         t_end, int(sol.nfev), os.getloadavg()[0]))
                    met += err <= level
                    if met >= 2 or wall > SLOW_RUN:
                        break
    return rows, checks
