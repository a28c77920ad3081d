"""Benchmarks: speed against error, measured, never assumed (pure Python, no rclpy).

One set of pieces for every table (``gyro-rotor bench``, :mod:`gyro_rotor.cli.commands.bench`):
the benchmark error of samples against a reference (:func:`errors`, any model), the wall
time as the best of repeats (:func:`best_of`), the tolerance sweep that stops once a run is
slow (:func:`tolerance_sweep`), scipy's ``solve_ivp`` (:func:`scipy_run`) and the compiled
peers (:mod:`gyro_rotor.numerics.bench_peers`) as baselines.

**Work precision** (:func:`run_sweep`, any scene, centrifuge or system file): for every
scene (and the K_D variants of stiff_drive) and every method over a sweep of
tolerances (adaptive; RTOLS, 1e-3 to 1e-12 at 1 and 3 a decade) or steps (fixed-step),
one run over the scene's duration sampled at
SAMPLE_RATE Hz is compared with a high-accuracy reference (this project's DOP853 at
rtol 1e-13, or RODAS4 at 1e-13 where the scene is stiff, not the stiff default radau9;
RODAS4 agrees with scipy's Radau at 1e-12 to 2e-12 on stiff_drive). Recorded per run:

- ``err``: the benchmark error, max over samples of max(angle between simulated and
  reference symmetry axes [rad], |z - z_ref| [rad]); for a system file, whose state holds
  no axis, the largest |q - q_ref| (in ``axis_err``) and |z - z_ref| [rad];
- ``axis_err``, ``z_err``, ``end_err`` (max-norm of the end-state difference), ``residual``
  (max |r| of the energy balance, J), ``qnorm`` (max ||q| - 1|);
- ``wall_per_sim``: wall seconds per simulated second (the best of the repeats: on a shared
  machine other work only ever slows a run down, so the fastest repeat is the one least
  disturbed; every family is timed the same way, and the repeats run in rounds over all the
  scene's runs, :func:`timed_in_rounds`, so that a slow spell falls on every method alike);
- ``nfev``, ``nsteps``; ``status`` (0 ok; a run over its budget stops and reports its
  cost rate over the part it did, with err = nan; after such a run, or one slower than
  SLOW_RUN wall seconds, the method's tighter settings are skipped).

scipy's ``solve_ivp`` (RK45, DOP853, Radau, LSODA) runs on the same model as the baseline,
with the model's right-hand side compiled by numba (``Model.rhs``; about 1.4 us a call, so
scipy's own per-step overhead dominates its cost). The compiled peers (family ``peer``,
:mod:`gyro_rotor.numerics.bench_peers`, where installed): CyRK's ``nbsolve2_ivp`` (RK45,
DOP853, Vern7, Vern8, Radau, LSODA) and numbalsoda's ``dop853`` and ``lsoda``, on a numba
cfunc of the same equations with the scene's constants folded in, over the same tolerance
sweep; their rows are named ``CyRK:DOP853``, ``numbalsoda:LSODA``, ... (a system file's
scene: CyRK on a numba lambdify of its equations). Also: the E* drift of each method on the
conservative scene over 1000 s, and the slipped-pole count on pole_slip at each method's
default tolerance.

**Generated systems** (issue 15; the tables ``general`` and ``stiff``):

- :func:`rhs_cost`: nanoseconds per right-hand-side evaluation of the generated code of
  ``centrifuge_euler`` against the hand-written quaternion kernel
  (:func:`gyro_rotor.numerics.integrators.kernels.rhs`), both called in a compiled loop at
  the same physical state.
- :func:`compile_times`: generation + compilation of a system in a fresh cache, and the
  load from the cache, each in its own Python process (imports included, interpreter start
  not), and the first integration there (the project's kernels for first-class right-hand
  sides: compiled once per machine, then loaded from numba's cache).
- :func:`system_work_precision`: the default method (the project's integrators on the
  generated right-hand side, :func:`gyro_rotor.numerics.simulate.integrate` with ``auto``)
  against the usual user's path, sympy ``lambdify`` to numpy plus scipy ``solve_ivp`` (RK45,
  DOP853, Radau, LSODA) on the same equations
  (:func:`gyro_rotor.numerics.bench_peers.lambdified_rhs`): error (max over samples at 100
  Hz of the largest |q - q_ref|, |z - z_ref|) against wall time over a tolerance sweep, the
  reference being dop853 at rtol 1e-13; and, where installed, the speed-conscious user's
  path: CyRK's ``nbsolve2_ivp`` (RK45, DOP853, Vern7, Vern8, LSODA) on a numba cfunc of the
  same lambdify with the constants substituted
  (:func:`gyro_rotor.numerics.bench_peers.make_general_peer`), rows ``CyRK+numba:<method>``.
- :func:`stiff_table`: a stiff drive on twin_gimbal, K_D = 1e2, 1e4, 1e6: ``auto`` (radau9
  with the generated Jacobian) against scipy's Radau, BDF and LSODA on the lambdified
  right-hand side, with and without a lambdified Jacobian, and, where installed, CyRK's
  Radau and LSODA on the numba cfunc of :func:`system_work_precision`, in wall milliseconds
  per simulated second at a given error (issue 25, item 4; issue 26).

Results are data; :mod:`gyro_rotor.cli.commands.bench` prints, writes and plots.
"""

from __future__ import annotations

import dataclasses
import math
import os
import random
import subprocess
import sys
import tempfile
import time
from typing import Callable

from gyro_rotor.core.peer_equations import PeerEquations
from gyro_rotor.core.scene import load_scene, Scene
from gyro_rotor.core.system.codegen import pack
from gyro_rotor.numerics import bench_peers
from gyro_rotor.numerics.bench_scenes import (DEFAULT_SCENES, QUICK_SCENES, REPEATS,
                                              SYSTEM_SCENES)
from gyro_rotor.numerics.integrators import choose_method, integrate, kernels, METHODS
from gyro_rotor.numerics.integrators.base import kernel_args
from gyro_rotor.numerics.kernel_system import kernel_model, methods_for
from gyro_rotor.numerics.simulate import integrate as integrate_model
import numpy as np

__all__ = ['BenchRow', 'DEFAULT_SCENES', 'QUICK_SCENES', 'run_sweep', 'reference',
           'best_table', 'energy_drift', 'pole_counts', 'parse_scene_spec', 'ERROR_LEVELS',
           'auto_choice', 'default_out_dir', 'errors', 'best_of', 'timed_in_rounds',
           'tolerance_sweep',
           'scipy_run', 'rhs_cost', 'compile_times', 'system_work_precision', 'WPRow',
           'best_at', 'SYSTEM_SCENES', 'DEFAULT_LABEL', 'stiff_table', 'StiffRow',
           'STIFF_K_D', 'COST_SCENES', 'steps_per_radian']

SAMPLE_RATE = 100.0
ERROR_LEVELS = (1e-3, 1e-6, 1e-9)
SCIPY = ('RK45', 'DOP853', 'Radau', 'LSODA')
QUICK_SCIPY = ('LSODA',)
#: the quick sweep's compiled peer (where installed): CyRK's DOP853 only
QUICK_PEERS = {'cyrk': ('DOP853',)}
#: the peers' row names: PEER_LABEL[package] + ':' + method
PEER_LABEL = {'cyrk': 'CyRK', 'numbalsoda': 'numbalsoda'}
# tolerance sweeps (atol = rtol * ATOL_RATIO) and step sweeps (step = factor / model rate).
# The full sweep takes two tolerances a decade (1 and 3): a method whose error lands just
# above a level must otherwise pay for ten times the tolerance, about 1.3 to 1.4 times the
# cost for an eighth-order pair (pole_slip's vern8 at rtol 1e-9: error 1.1e-9, so rtol 1e-10)
RTOLS = {'full': (1e-3, 3e-4, 1e-4, 3e-5, 1e-5, 3e-6, 1e-6, 3e-7, 1e-7, 3e-8, 1e-8, 3e-9,
                  1e-9, 3e-10, 1e-10, 3e-11, 1e-11, 3e-12, 1e-12),
         'quick': (1e-5, 1e-8)}
# (rk8 from 3.2: at 0.8 it was already at error 1.4e-10 on fast_spin, so the sweep missed
# its cheaper settings for 1e-6 and 1e-3; where 0.01 s x model rate is below the factor the
# step is the sample spacing anyway, fixed-step methods land on every sample)
STEP_FACTORS = {'rk4': (0.2, 0.1, 0.05, 0.02, 0.01, 0.005),
                'rk8': (3.2, 1.6, 0.8, 0.4, 0.2, 0.1, 0.05),
                'gauss6': (0.4, 0.2, 0.1, 0.05, 0.025),
                'split8': (0.6, 0.45, 0.33, 0.25, 0.18, 0.13, 0.1)}
#: the default method, run as its own row over the tolerance sweep: it chooses by the scene,
#: the requested rtol and the sample rate (methods.choose_method), so per setting
AUTO = 'auto'
#: the quick sweep runs only these of our methods (auto, the ones it picks, and dop853)
QUICK_METHODS = (AUTO, 'dop853', 'vern8', 'radau9', 'split8')
ATOL_RATIO = 1e-2
#: budgets: our compiled methods stop after this many steps, scipy after this many RHS calls
MAX_STEPS = 3_000_000
SCIPY_MAX_NFEV = 200_000
#: a run slower than this [wall s] ends its method's sweep (tighter settings are slower)
SLOW_RUN = 8.0
#: a repeat slower than this [wall s] is the last of its run (the noise of slow runs is small)
SLOW_REPEAT = 2.0


@dataclasses.dataclass
class BenchRow:
    """One run of the sweep (see module doc)."""

    scene: str
    method: str
    family: str          # 'gyro_rotor', 'scipy' or 'peer'
    setting: str         # 'rtol=1e-08' or 'h=1.2e-04'
    err: float
    axis_err: float
    z_err: float
    end_err: float
    residual: float
    qnorm: float
    wall_per_sim: float
    nfev: int
    nsteps: int
    status: int
    load: float = math.nan   # 1-minute load average when the run ended


def parse_scene_spec(spec: str) -> tuple[Scene, str]:
    """'stiff_drive@K_D=1e6' -> (scene with the override, label)."""
    name, _, rest = spec.partition('@')
    overrides = {}
    if rest:
        for item in rest.split(','):
            k, _, v = item.partition('=')
            overrides[k.strip()] = float(v)
    return load_scene(name, overrides=overrides or None), spec


def default_out_dir(now: float | None = None) -> str:
    """Return a new output directory name, ``bench-YYYYmmdd-HHMMSS`` (not the committed bench/)."""
    return time.strftime('bench-%Y%m%d-%H%M%S', time.localtime(now))


def _t_eval(t_end: float) -> np.ndarray:
    n = int(round(t_end * SAMPLE_RATE))
    return np.linspace(0.0, t_end, n + 1)


def auto_choice(scene: Scene, rtol: float | None = None) -> str:
    """Return the method 'auto' picks for the scene over its duration at ``rtol``.

    With the benchmark's samples (SAMPLE_RATE); rtol None: the default tolerance.
    """
    model = scene.make_model()
    return choose_method(model, scene.t_end, rtol, SAMPLE_RATE, scene.initial_state(model))[0]


def _is_stiff(scene: Scene) -> bool:
    model = scene.make_model()
    return choose_method(model, y0=scene.initial_state(model))[0] == 'radau9'


def reference(scene: Scene, t_eval: np.ndarray) -> np.ndarray:
    """High-accuracy reference samples (see module doc)."""
    model = scene.make_model()
    y0 = scene.initial_state(model)
    method = 'rodas4' if _is_stiff(scene) else 'dop853'
    res = integrate(kernel_model(model), y0, (0.0, t_eval[-1]), t_eval, method, rtol=1e-13,
                    atol=1e-15)
    if not res.success:
        raise RuntimeError(f'reference for {scene.name} failed: {res.message}')
    return res.y


def errors(model, Y: np.ndarray | None, R: np.ndarray) -> dict:
    """Error measures of samples Y against the reference R (same times), any model.

    ``err`` is the benchmark error: max(axis_err, z_err). ``axis_err``: the angle between
    the simulated and reference symmetry axes [rad] of the centrifuge, or the largest
    |q - q_ref| of a system file; ``z_err``: the largest |z - z_ref|. Y None (a run that
    failed): every measure NaN.
    """
    if Y is None or len(Y) < len(R):
        nan = math.nan
        return {'err': nan, 'axis_err': nan, 'z_err': nan, 'end_err': nan,
                'residual': nan, 'qnorm': nan}
    axis_err, z_err = model.coordinate_errors(Y, R)
    return {'err': max(axis_err, z_err), 'axis_err': axis_err, 'z_err': z_err,
            'end_err': float(np.max(np.abs(Y[-1] - R[-1]))),
            'residual': float(np.max(np.abs(model.residual(Y)))),
            'qnorm': float(np.max(np.abs(model.quaternion_norm_error(Y))))}


def best_of(fn: Callable, repeats: int, slow: float = math.inf) -> tuple:
    """Run ``fn()`` ``repeats`` times; return (its last result, the least wall seconds).

    On a shared machine other work only ever slows a run down, so the fastest repeat is the
    one least disturbed; a repeat slower than ``slow`` seconds is the last.
    """
    walls = []
    out = None
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        out = fn()
        walls.append(time.perf_counter() - t0)
        if walls[-1] > slow:
            break
    return out, min(walls)


def tolerance_sweep(rtols, run: Callable, slow: float, enough: Callable | None = None) -> list:
    """Return ``[run(rtol) for rtol in rtols]``, ending after a row slower than ``slow`` [s].

    Tighter settings are slower still; ``enough(rows)`` may end the sweep earlier. Each row
    has ``wall`` [s].
    """
    rows = []
    for rtol in rtols:
        rows.append(run(rtol))
        if rows[-1].wall > slow or (enough is not None and enough(rows)):
            break
    return rows


class _Budget(Exception):
    pass


def scipy_run(fun, y0, t_eval, method, rtol, atol, jac=None,
              max_nfev: int | None = SCIPY_MAX_NFEV) -> tuple:
    """Run scipy's ``solve_ivp`` from 0 to ``t_eval[-1]``, sampled at ``t_eval``.

    Returns (Y or None, nfev, nsteps, status, t_done).

    ``max_nfev``: the budget of right-hand-side calls (None: none); a run over it stops with
    status -3 at the time it reached (``t_done``), to report its cost rate.
    """
    from scipy.integrate import solve_ivp
    state = {'n': 0, 't': 0.0}

    def counted(t, y):
        state['n'] += 1
        if t > state['t']:
            state['t'] = t
        if state['n'] > max_nfev:
            raise _Budget()
        return fun(t, y)
    kw = {} if jac is None else {'jac': jac}
    try:
        sol = solve_ivp(fun if max_nfev is None else counted, (0.0, t_eval[-1]), y0,
                        method=method, t_eval=t_eval, rtol=rtol, atol=atol, **kw)
    except _Budget:
        return None, state['n'], 0, -3, max(state['t'], 1e-12)
    Y = sol.y.T if sol.status == 0 else None
    return Y, int(sol.nfev), int(len(sol.t)), int(sol.status), t_eval[-1]


def _ours_run(model, y0, t_eval, method, rtol=None, atol=None, step=None):
    res = integrate(model, y0, (0.0, t_eval[-1]), t_eval, method, rtol=rtol, atol=atol,
                    step=step, max_steps=MAX_STEPS)
    t_done = res.t[-1] if res.t.size and res.t[-1] > 0 else t_eval[-1] * 1e-9
    if res.status == -3:
        # the budget ran out between samples: use the steps' share of the horizon
        t_done = max(t_done, res.nsteps * (step or 0.0))
    Y = res.y if res.success else None
    return Y, res.nfev, res.nsteps, res.status, (t_eval[-1] if res.success else t_done)


def _peer_run(peer, package, size, y0, t_eval, method, rtol, atol):
    """Run a compiled peer: (Y (m, size) or None, nfev (-1), steps, status, t_done)."""
    Y, steps = bench_peers.peer_run(peer, package, method, y0, t_eval, rtol, atol,
                                    max_steps=MAX_STEPS)
    if Y is None:
        return None, -1, steps, -3, t_eval[-1]
    if Y.shape[1] < size:
        # the centrifuge peers' model has no D: its column is NaN (no residual measured)
        Y = np.column_stack([Y, np.full(len(Y), np.nan)])
    return Y, -1, steps, 0, t_eval[-1]


def _load() -> float:
    try:
        return os.getloadavg()[0]
    except OSError:  # pragma: no cover - platforms without it
        return math.nan


def _centrifuge_full_peers(scene: Scene, quick: bool):
    """Return the peers of the centrifuge's full model: CyRK and numbalsoda, as installed."""
    table = QUICK_PEERS if quick else bench_peers.PEER_METHODS
    have = {p: table[p] for p in bench_peers.available() if p in table}
    return (bench_peers.make_peer_rhs(scene.system.params, list(have)) if have else None), have


def _generated_peers(scene: Scene, quick: bool):
    """Return the peer of a system file's generated equations: CyRK, if installed."""
    if 'cyrk' not in bench_peers.available():
        return None, {}
    methods = QUICK_PEERS['cyrk'] if quick else bench_peers.GENERAL_PEER_METHODS
    return bench_peers.make_general_peer(scene), {'cyrk': methods}


#: the compiled peers of each system's ``peer_equations``
PEERS = {PeerEquations.CENTRIFUGE_FULL: _centrifuge_full_peers,
         PeerEquations.GENERATED: _generated_peers}


def _peers(scene: Scene, quick: bool):
    """Return (compiled peer or None, {package: methods}) of the scene's sweep.

    The peers of the equations its system says they copy (``peer_equations``, :data:`PEERS`);
    none if they copy none.
    """
    make = PEERS.get(scene.system.peer_equations)
    return make(scene, quick) if make else (None, {})


def run_sweep(spec: str, *, quick: bool = False, repeats: int = REPEATS, scipy: bool = True,
              peers: bool = True, methods=None,
              progress: Callable[[str], None] | None = None) -> list[BenchRow]:
    """All runs of one scene spec, any system (see module doc); returns the rows."""
    scene, label = parse_scene_spec(spec)
    model = scene.make_model()
    view = kernel_model(model)
    y0 = scene.initial_state(model)
    te = _t_eval(scene.t_end)
    R = reference(scene, te)
    rate = kernel_args(view, model.params)[2]
    stiff = _is_stiff(scene)
    rtols = RTOLS['quick' if quick else 'full']
    jobs = []
    own = methods_for(model)
    for name in (methods or (QUICK_METHODS if quick else (AUTO,) + own)):
        if name != AUTO and name not in own:
            continue
        if name == AUTO or METHODS[name].adaptive:
            for r in rtols:
                jobs.append(('gyro_rotor', name, f'rtol={r:.0e}',
                             {'rtol': r, 'atol': r * ATOL_RATIO}))
        elif name in STEP_FACTORS:
            if name == 'gauss6' and stiff:
                continue       # fixed-point stages cannot converge at useful steps
            if name == 'split8' and stiff:
                continue       # explicit sub-flows
            facs = STEP_FACTORS[name]
            facs = facs[1::3] if quick else facs
            for f in facs:
                h = min(f / rate, scene.t_end)
                jobs.append(('gyro_rotor', name, f'h={h:.2e}', {'step': h}))
    if scipy:
        for name in (QUICK_SCIPY if quick else SCIPY):
            for r in rtols:
                jobs.append(('scipy', name, f'rtol={r:.0e}', {'rtol': r, 'atol': r * ATOL_RATIO}))
    peer, have = _peers(scene, quick) if peers else (None, {})
    for package, table in have.items():
        for m in table:
            for r in rtols:
                jobs.append(('peer', f'{PEER_LABEL[package]}:{m}', f'rtol={r:.0e}',
                             {'package': package, 'method': m, 'rtol': r,
                              'atol': r * ATOL_RATIO}))
    for name in dict.fromkeys(j[1] for j in jobs if j[0] == 'gyro_rotor'):
        # compile (or load from numba's cache) before timing
        integrate(view, y0, (0.0, te[1]), te[:2], name, max_steps=1000)
    for package in have:
        bench_peers.peer_run(peer, package, 'DOP853', y0, te[:2], 1e-3, 1e-5)

    def job(family, name, kw):
        if family == 'scipy':
            return lambda: scipy_run(model.rhs, y0, te, name, kw['rtol'], kw['atol'])
        if family == 'peer':
            return lambda: _peer_run(peer, kw['package'], y0.size, y0, te, kw['method'],
                                     kw['rtol'], kw['atol'])
        return lambda: _ours_run(view, y0, te, name, **kw)

    def row(family, name, setting, out, wall):
        Y, nfev, nsteps, status, t_done = out
        e = errors(model, Y, R)
        if progress:
            progress(f'{label:22s} {name:17s} {setting:14s} err {e["err"]:.2e} '
                     f'wall/sim {wall / t_done:.3e} s  nfev {nfev}  status {status}')
        return BenchRow(scene=label, method=name, family=family, setting=setting,
                        wall_per_sim=wall / t_done, nfev=nfev, nsteps=nsteps, status=status,
                        load=_load(), **e)
    return timed_in_rounds([(j[0], j[1], j[2], job(j[0], j[1], j[3])) for j in jobs], row,
                           repeats, progress)


def timed_in_rounds(jobs: list, row: Callable, repeats: int,
                    progress: Callable[[str], None] | None = None,
                    clock: Callable[[], float] = time.perf_counter) -> list:
    """Run every job once, then the repeats in rounds over all of them; return the rows.

    ``jobs``: (family, name, setting, fn) with ``fn() -> (Y, nfev, nsteps, status,
    t_done)``; ``row(family, name, setting, out, wall)`` makes a row of the first run. A
    row's ``wall_per_sim`` is the least over its runs. The repeats of one job are spread
    over the whole sweep, not run back to back: this machine's speed drifts by tens of per
    cent over minutes (stop 37: the same radau9 runs of stiff_drive, repeated back to back,
    took 0.246 ms/s as auto's and 0.422 ms/s as radau9's two minutes later, 0.34 and 0.35
    when alternated), and a slow spell must fall on every method alike, not on one.

    The order of a round. A method's runs (its settings, consecutive in ``jobs``: a block)
    stay together, and the block's first run is run once untimed before it is timed: a
    run right after another package's code is slower (fast_spin, vern8 at rtol 3e-4, best
    of 40 at load 1: 0.103 ms/s after a CyRK run, 0.107 after numbalsoda, 0.099 after a
    run of its own), and a shuffle of single runs (the run at 1a6f9fa) put one before
    nearly every run (auto against the method it ran at the same rtol, same steps: median
    1.020 and 19 % above 1.05, against 1.011 and 11 % in the fixed order). Round 1 runs
    the blocks in their order, round k >= 2 in an order shuffled by ``random.Random(k)``:
    a rotation of the jobs (the runs at 8422299 and 312932d) kept the last block (a peer)
    before the first (auto) in every round, and auto's first settings stayed slower than
    the same computations (312932d: 6 to 18 us a run; precession, auto run after the
    package's own methods instead: 1.058 against 1.111 on its first setting). After a run
    over its budget (status -3) or slower than SLOW_RUN, the method's tighter settings
    are skipped; a run slower than SLOW_REPEAT is not repeated. ``clock``: seconds.
    """
    rows, again, over_budget = [], [], set()
    for family, name, setting, fn in jobs:
        if name in over_budget:
            continue        # tighter settings of a method that ran out of budget: skip
        t0 = clock()
        out = fn()
        wall = clock() - t0
        rows.append(row(family, name, setting, out, wall))
        if out[3] == -3 or wall > SLOW_RUN:
            over_budget.add(name)
        if wall <= SLOW_REPEAT:
            again.append((len(rows) - 1, (family, name), fn, out[4]))
    blocks: list[list] = []
    for entry in again:
        if blocks and blocks[-1][0][1] == entry[1]:
            blocks[-1].append(entry)
        else:
            blocks.append([entry])
    for k in range(2, max(1, repeats) + 1):
        if progress and again:
            progress(f'repeat {k} of {repeats}: {len(again)} runs')
        order = list(blocks)
        random.Random(k).shuffle(order)
        for block in order:
            block[0][2]()           # untimed: the method's code back in the caches
            for i, _, fn, t_done in block:
                t0 = clock()
                fn()
                w = (clock() - t0) / t_done
                if w < rows[i].wall_per_sim:
                    rows[i] = dataclasses.replace(rows[i], wall_per_sim=w)
    return rows


def best_table(rows: list[BenchRow], levels=ERROR_LEVELS) -> dict:
    """{(scene, method): [best wall/sim at err <= level or None for each level]}."""
    out: dict = {}
    for r in rows:
        key = (r.scene, r.method)
        cur = out.setdefault(key, [None] * len(levels))
        for i, lev in enumerate(levels):
            if r.status == 0 and math.isfinite(r.err) and r.err <= lev:
                if cur[i] is None or r.wall_per_sim < cur[i]:
                    cur[i] = r.wall_per_sim
    return out


#: the scenes whose rows give auto's cost table (methods.STEPS_PER_RADIAN)
COST_SCENES = ('precession', 'nutation', 'upright', 'fast_spin', 'conservative', 'pole_slip')


def steps_per_radian(rows: list[BenchRow]) -> dict | None:
    """Return auto's cost table as this sweep measures it, or None without its scenes.

    For each of methods.COST_METHODS and each error of methods.COST_ERRORS: the fewest steps
    of a run that reached the error, per radian of the scene's fastest rate (rate x t_end),
    geometric mean over COST_SCENES (None where a scene never reached it); and each
    method's floor, the smallest error it reached on them. :data:`methods.STEPS_PER_RADIAN`
    and :data:`methods.ERROR_FLOOR` are this function's output for a full sweep.
    """
    from gyro_rotor.numerics.integrators import methods as M
    from gyro_rotor.numerics.integrators.base import model_rate
    done = {r.scene for r in rows}
    if not set(COST_SCENES) <= done:
        return None
    radians = {}
    for name in COST_SCENES:
        scene = load_scene(name)
        radians[name] = model_rate(scene.system.params) * scene.t_end
    table, floors = {}, {}
    for m in M.COST_METHODS:
        ok = [r for r in rows if r.method == m and r.scene in radians and r.status == 0
              and math.isfinite(r.err)]
        vals = []
        for e in M.COST_ERRORS:
            fewest = [min((r.nsteps for r in ok if r.scene == sc and r.err <= e), default=None)
                      for sc in COST_SCENES]
            vals.append(None if None in fewest else math.exp(
                sum(math.log(n / radians[sc]) for n, sc in zip(fewest, COST_SCENES))
                / len(COST_SCENES)))
        table[m] = tuple(vals)
        floors[m] = min((r.err for r in ok), default=math.nan)
    return {'steps': table, 'floor': floors}


QUICK_DRIFT_METHODS = ('auto', 'dop853')
DRIFT_METHODS = ('auto', 'split8', 'gauss6', 'dop853', 'rk8', 'rk4', 'rodas4', 'radau9',
                 'scipy:DOP853', 'scipy:LSODA')


def energy_drift(t_end: float = 1000.0, checkpoints=(10.0, 100.0, 1000.0),
                 methods=DRIFT_METHODS, progress=None) -> dict:
    """Relative E* drift |E*(t) - E*(0)| / E*(0) on the conservative scene at checkpoints.

    Each method at its default setting ('auto': the default method over ``t_end``); scipy's
    at rtol 1e-10, atol 1e-12. Returns {method: (drifts at checkpoints, wall seconds)}.
    """
    scene = load_scene('conservative')
    model = scene.make_model()
    y0 = scene.initial_state(model)
    cps = np.array([c for c in checkpoints if c <= t_end] or [t_end])
    te = np.concatenate([[0.0], cps])
    E0 = float(model.energy(y0))
    out = {}
    for name in methods:
        t0 = time.perf_counter()
        if name.startswith('scipy:'):
            from scipy.integrate import solve_ivp
            sol = solve_ivp(model.rhs, (0.0, t_end), y0, method=name[6:], t_eval=te,
                            rtol=1e-10, atol=1e-12)
            Y = sol.y.T
        else:
            Y = integrate(model, y0, (0.0, t_end), te, name).y
        wall = time.perf_counter() - t0
        drift = np.abs(model.energy(Y[1:]) - E0) / E0
        out[name] = (drift, wall)
        if progress:
            progress(f'drift {name:14s} ' + ' '.join(f'{d:.2e}' for d in drift)
                     + f'  ({wall:.1f} s)')
    return out


def slip_count(model, y_end) -> int:
    """Net number of 2 pi / p advances of z (the slipped poles), from z(0) = 0."""
    p = model.params.pole_pairs
    return int(round(float(y_end[model.iz]) * p / (2.0 * math.pi)))


def pole_counts(methods=('dop853', 'rodas4', 'radau9', 'rk4', 'rk8', 'gauss6', 'split8',
                         'scipy:RK45',
                         'scipy:DOP853', 'scipy:Radau', 'scipy:LSODA')) -> dict:
    """Slipped-pole count on pole_slip per method at its default tolerance, and the reference.

    Returns {'reference': n, method: n, ...}.
    """
    from scipy.integrate import solve_ivp
    scene = load_scene('pole_slip')
    model = scene.make_model()
    y0 = scene.initial_state(model)
    T = scene.t_end
    ref = integrate(model, y0, (0.0, T), None, 'dop853', rtol=1e-13, atol=1e-15)
    out = {'reference': slip_count(model, ref.y[-1])}
    for name in methods:
        if name.startswith('scipy:'):
            sol = solve_ivp(model.rhs, (0.0, T), y0, method=name[6:])
            out[name] = slip_count(model, sol.y[:, -1])
        else:
            out[name] = slip_count(model, integrate(model, y0, (0.0, T), None, name).y[-1])
    return out


# -- generated systems (issue 15): the right-hand side, compilation, work precision -----------
#: the label of our rows in the table ``general``: simulate.integrate with method 'auto'
DEFAULT_LABEL = 'default'
#: the label prefix of the compiled peer's rows (CyRK on a numba lambdify)
PEER_PREFIX = 'CyRK+numba:'
#: the tolerance sweep of the table ``general`` (atol = 1e-3 rtol), ours and the baselines'
SYSTEM_RTOLS = (1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12)
#: in the tables of generated systems, a baseline run slower than this [wall s] ends its sweep
SYSTEM_SLOW_RUN = 5.0


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
    hand = best_of(lambda: _loop_hand(kind, yh.copy(), Ph, oh, count), repeats)[1]
    gen = best_of(lambda: _loop_generated(model.compiled.rhs, yg.copy(), Pg, og, count),
                  repeats)[1]
    hand, gen = hand / count * 1e9, gen / count * 1e9
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
    """One run of the generated systems' work-precision sweep (``wall`` [s])."""

    system: str
    method: str
    rtol: float
    err: float
    wall: float
    nfev: int


def _system_case(spec: str, t_end: float, K_D: float | None = None):
    """Return (scene, model, y0, sample times) of a scene spec over ``t_end``.

    ``K_D``: every rotor's drive damping (an override on top of the spec's).
    """
    if K_D is not None:
        spec = f"{spec}{',' if '@' in spec else '@'}K_D={K_D!r}"
    scene = parse_scene_spec(spec)[0]
    model = scene.make_model()
    te = np.arange(int(round(t_end * SAMPLE_RATE)) + 1) / SAMPLE_RATE
    return scene, model, scene.initial_state(model), te


def system_work_precision(names=SYSTEM_SCENES, t_end: float = 2.0,
                          repeats: int = REPEATS) -> list[WPRow]:
    """Error against wall time: the default method vs lambdify + solve_ivp (module doc)."""
    rows = []
    for name in names:
        scene, model, y0, te = _system_case(name, t_end)
        ref = integrate_model(model, y0, te, method='dop853', rtol=1e-13, atol=1e-15).y

        def ours(rtol):
            run, wall = best_of(lambda: integrate_model(model, y0, te, rtol=rtol,
                                                        atol=rtol * 1e-3), repeats)
            return WPRow(name, f'{DEFAULT_LABEL} ({run.method})', rtol,
                         errors(model, run.y, ref)['err'], wall, run.nfev)
        rows += [ours(rtol) for rtol in SYSTEM_RTOLS]
        if 'cyrk' in bench_peers.available():
            peer = bench_peers.make_general_peer(scene)
            bench_peers.peer_run(peer, 'cyrk', 'DOP853', y0, te[:2], 1e-3, 1e-6)   # compile
            for method in bench_peers.GENERAL_PEER_METHODS:
                def run_peer(rtol, method=method):
                    (Y, *_), wall = best_of(lambda: _peer_run(peer, 'cyrk', y0.size, y0, te,
                                                              method, rtol, rtol * 1e-3),
                                            repeats)
                    return WPRow(name, f'{PEER_PREFIX}{method}', rtol,
                                 errors(model, Y, ref)['err'], wall, -1)
                rows += tolerance_sweep(SYSTEM_RTOLS, run_peer, SYSTEM_SLOW_RUN)
        rhs = bench_peers.lambdified_rhs(scene)
        for method in SCIPY:
            def run_scipy(rtol, method=method):
                (Y, nfev, *_), wall = best_of(lambda: scipy_run(rhs, y0, te, method, rtol,
                                                                rtol * 1e-3, max_nfev=None), 1)
                return WPRow(name, f'lambdify+{method}', rtol, errors(model, Y, ref)['err'],
                             wall, nfev)
            rows += tolerance_sweep(SYSTEM_RTOLS, run_scipy, SYSTEM_SLOW_RUN)
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
#: CyRK's stiff solvers in the stiff table (where installed), on the same tolerances
STIFF_PEER_METHODS = ('Radau', 'LSODA')


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


def stiff_table(K_Ds=STIFF_K_D, name: str = 'twin_gimbal', t_end: float = 2.0,
                level: float = 1e-6, repeats: int = REPEATS) -> tuple[list, dict]:
    """Stiff drives: ``auto`` against scipy's Radau, BDF, LSODA and CyRK's over K_D (module doc).

    For each K_D (scene override ``K_D``: every rotor's), the error of a run is that of
    :func:`system_work_precision` (largest |q - q_ref|, |z - z_ref| over the samples at 100
    Hz) against radau9 at rtol 1e-13, itself checked against rodas4 (forward-difference
    Jacobian, independent code) at rtol 1e-12: ``checks[K_D]`` is their difference. scipy
    runs on the lambdified right-hand side (:func:`~.bench_peers.lambdified_rhs`), without
    and with the lambdified Jacobian (:func:`~.bench_peers.lambdified_jac`); where CyRK is
    installed, its Radau and LSODA (STIFF_PEER_METHODS) on a numba cfunc of the same
    lambdify with the constants substituted (:func:`~.bench_peers.make_general_peer`, as in
    :func:`system_work_precision`), rows ``CyRK+numba:<method>``: a speed-conscious user's
    stiff solvers. A sweep stops once two runs met ``level`` or one took longer than
    SYSTEM_SLOW_RUN. Every wall time is the best of ``repeats`` runs. Returns (rows, checks).
    """
    rows, checks = [], {}
    for K_D in K_Ds:
        scene, model, y0, te = _system_case(name, t_end, K_D)
        ref = integrate_model(model, y0, te, method='radau9', rtol=1e-13, atol=1e-16).y
        other = integrate_model(model, y0, te, method='rodas4', rtol=1e-12, atol=1e-15).y
        checks[K_D] = errors(model, other, ref)['err']
        for rtol in STIFF_OUR_RTOLS:
            run, wall = best_of(lambda: integrate_model(model, y0, te, rtol=rtol,
                                                        atol=rtol * 1e-3), repeats)
            rows.append(StiffRow(K_D, f'auto ({run.method})', rtol,
                                 errors(model, run.y, ref)['err'], wall, t_end, run.nfev,
                                 _load()))
        if 'cyrk' in bench_peers.available():
            peer = bench_peers.make_general_peer(scene)
            bench_peers.peer_run(peer, 'cyrk', 'Radau', y0, te[:2], 1e-3, 1e-6)   # compile
            for method in STIFF_PEER_METHODS:
                def run_peer(rtol, method=method):
                    (Y, *_), wall = best_of(lambda: _peer_run(peer, 'cyrk', y0.size, y0, te,
                                                              method, rtol, rtol * 1e-3),
                                            repeats)
                    return StiffRow(K_D, f'{PEER_PREFIX}{method}', rtol,
                                    errors(model, Y, ref)['err'], wall, t_end, -1, _load())
                rows += tolerance_sweep(
                    STIFF_SCIPY_RTOLS, run_peer, SYSTEM_SLOW_RUN,
                    lambda done: sum(r.err <= level for r in done) >= 2)
        fun, jac = bench_peers.lambdified_rhs(scene), bench_peers.lambdified_jac(scene)
        for method in STIFF_SCIPY_METHODS:
            for label, J in (('', None), ('+jac', jac)):
                def run_scipy(rtol, method=method, J=J, label=label):
                    (Y, nfev, *_), wall = best_of(
                        lambda: scipy_run(fun, y0, te, method, rtol, rtol * 1e-3, jac=J,
                                          max_nfev=None), repeats)
                    return StiffRow(K_D, f'lambdify+{method}{label}', rtol,
                                    errors(model, Y, ref)['err'], wall, t_end, nfev, _load())
                rows += tolerance_sweep(
                    STIFF_SCIPY_RTOLS, run_scipy, SYSTEM_SLOW_RUN,
                    lambda done: sum(r.err <= level for r in done) >= 2)
    return rows, checks
