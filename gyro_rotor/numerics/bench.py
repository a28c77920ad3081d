"""Work-precision benchmark: speed against error on the hard scenes (pure Python, no rclpy).

For every scene (and the K_D variants of stiff_drive) and every method over a sweep of
tolerances (adaptive) or steps (fixed-step), one run over the scene's duration sampled at
SAMPLE_RATE Hz is compared with a high-accuracy reference (this project's DOP853 at
rtol 1e-13, or RODAS4 at 1e-13 where the scene is stiff, not the stiff default radau9;
RODAS4 agrees with scipy's Radau at 1e-12 to 2e-12 on stiff_drive). Recorded per run:

- ``err``: the benchmark error, max over samples of max(angle between simulated and
  reference symmetry axes [rad], |z - z_ref| [rad]);
- ``axis_err``, ``z_err``, ``end_err`` (max-norm of the end-state difference), ``residual``
  (max |r| of the energy balance, J), ``qnorm`` (max ||q| - 1|);
- ``wall_per_sim``: wall seconds per simulated second (the best of the repeats: on a shared
  machine other work only ever slows a run down, so the fastest repeat is the one least
  disturbed; every family is timed the same way);
- ``nfev``, ``nsteps``; ``status`` (0 ok; a run over its budget stops and reports its
  cost rate over the part it did, with err = nan; after such a run, or one slower than
  SLOW_RUN wall seconds, the method's tighter settings are skipped).

scipy's ``solve_ivp`` (RK45, DOP853, Radau, LSODA) runs on the same model as the baseline,
with the model's right-hand side compiled by numba (``Model.rhs``; about 1.4 us a call, so
scipy's own per-step overhead dominates its cost). The compiled peers (family ``peer``,
:mod:`gyro_rotor.numerics.bench_peers`, where installed): CyRK's ``nbsolve2_ivp`` (RK45,
DOP853, Vern7, Vern8, Radau, LSODA) and numbalsoda's ``dop853`` and ``lsoda``, on a numba
cfunc of the same equations with the scene's constants folded in, over the same tolerance
sweep; their rows are named ``CyRK:DOP853``, ``numbalsoda:LSODA``, ... Also: the E* drift of
each method on the conservative scene over 1000 s, and the slipped-pole count on pole_slip at
each method's default tolerance. Results are data; :mod:`gyro_rotor.commands.bench` prints
and plots.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from typing import Callable

from gyro_rotor.core.scene import load_scene, Scene
from gyro_rotor.numerics.integrators import integrate, METHODS
import numpy as np

__all__ = ['BenchRow', 'DEFAULT_SCENES', 'QUICK_SCENES', 'run_sweep', 'reference',
           'best_table', 'energy_drift', 'pole_counts', 'parse_scene_spec', 'ERROR_LEVELS',
           'auto_choice', 'default_out_dir']

SAMPLE_RATE = 100.0
ERROR_LEVELS = (1e-3, 1e-6, 1e-9)
DEFAULT_SCENES = ('precession', 'nutation', 'upright', 'stiff_drive@K_D=100', 'stiff_drive',
                  'stiff_drive@K_D=1e6', 'fast_spin', 'conservative', 'conservative@t_end=100',
                  'pole_slip')
#: the short sweep (``--quick``, under a minute): one scene per kind of method
QUICK_SCENES = ('precession', 'stiff_drive', 'conservative')
SCIPY = ('RK45', 'DOP853', 'Radau', 'LSODA')
QUICK_SCIPY = ('LSODA',)
#: the quick sweep's compiled peer (where installed): CyRK's DOP853 only
QUICK_PEERS = {'cyrk': ('DOP853',)}
#: the peers' row names: PEER_LABEL[package] + ':' + method
PEER_LABEL = {'cyrk': 'CyRK', 'numbalsoda': 'numbalsoda'}
# tolerance sweeps (atol = rtol * ATOL_RATIO) and step sweeps (step = factor / model rate)
RTOLS = {'full': (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12),
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
    from gyro_rotor.numerics.integrators import choose_method
    return choose_method(scene.make_model(), scene.t_end, rtol, SAMPLE_RATE)[0]


def _is_stiff(scene: Scene) -> bool:
    from gyro_rotor.numerics.integrators import choose_method
    return choose_method(scene.make_model())[0] == 'radau9'


def reference(scene: Scene, t_eval: np.ndarray) -> np.ndarray:
    """High-accuracy reference samples (see module doc)."""
    model = scene.make_model()
    y0 = scene.initial_state(model)
    method = 'rodas4' if _is_stiff(scene) else 'dop853'
    res = integrate(model, y0, (0.0, t_eval[-1]), t_eval, method, rtol=1e-13, atol=1e-15)
    if not res.success:
        raise RuntimeError(f'reference for {scene.name} failed: {res.message}')
    return res.y


def _axis(Y: np.ndarray) -> np.ndarray:
    q = Y[:, 0:4] / np.linalg.norm(Y[:, 0:4], axis=1)[:, None]
    w, x, y, z = q.T
    return np.column_stack([2 * (x * z + w * y), 2 * (y * z - w * x),
                            w * w - x * x - y * y + z * z])


def errors(model, Y: np.ndarray, R: np.ndarray) -> dict:
    """Error measures of samples Y against the reference R (same times)."""
    m = min(len(Y), len(R))
    if m < len(R):
        nan = math.nan
        return {'err': nan, 'axis_err': nan, 'z_err': nan, 'end_err': nan,
                'residual': nan, 'qnorm': nan}
    a, b = _axis(Y), _axis(R)
    ang = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.sum(a * b, axis=1))
    axis_err = float(np.max(ang))
    z_err = float(np.max(np.abs(Y[:, model.iz] - R[:, model.iz])))
    return {'err': max(axis_err, z_err), 'axis_err': axis_err, 'z_err': z_err,
            'end_err': float(np.max(np.abs(Y[-1] - R[-1]))),
            'residual': float(np.max(np.abs(model.residual(Y)))),
            'qnorm': float(np.max(np.abs(model.quaternion_norm_error(Y))))}


class _Budget(Exception):
    pass


def _scipy_run(model, y0, t_eval, method, rtol, atol):
    from scipy.integrate import solve_ivp
    base = model.rhs
    state = {'n': 0, 't': 0.0}

    def fun(t, y):
        state['n'] += 1
        if t > state['t']:
            state['t'] = t
        if state['n'] > SCIPY_MAX_NFEV:
            raise _Budget()
        return base(t, y)
    t0 = time.perf_counter()
    try:
        sol = solve_ivp(fun, (0.0, t_eval[-1]), y0, method=method, t_eval=t_eval, rtol=rtol,
                        atol=atol)
    except _Budget:
        wall = time.perf_counter() - t0
        return None, wall, state['n'], 0, -3, max(state['t'], 1e-12)
    wall = time.perf_counter() - t0
    Y = sol.y.T if sol.status == 0 else None
    return Y, wall, int(sol.nfev), int(len(sol.t)), int(sol.status), t_eval[-1]


def _ours_run(model, y0, t_eval, method, rtol=None, atol=None, step=None):
    t0 = time.perf_counter()
    res = integrate(model, y0, (0.0, t_eval[-1]), t_eval, method, rtol=rtol, atol=atol,
                    step=step, max_steps=MAX_STEPS)
    wall = time.perf_counter() - t0
    t_done = res.t[-1] if res.t.size and res.t[-1] > 0 else t_eval[-1] * 1e-9
    if res.status == -3:
        # the budget ran out between samples: use the steps' share of the horizon
        t_done = max(t_done, res.nsteps * (step or 0.0))
    Y = res.y if res.success else None
    return Y, wall, res.nfev, res.nsteps, res.status, (t_eval[-1] if res.success else t_done)


def _peer_run(peer, package, model, y0, t_eval, method, rtol, atol):
    from gyro_rotor.numerics import bench_peers
    t0 = time.perf_counter()
    Y9, steps = bench_peers.peer_run(peer, package, method, y0, t_eval, rtol, atol,
                                     max_steps=MAX_STEPS)
    wall = time.perf_counter() - t0
    if Y9 is None:
        return None, wall, -1, steps, -3, t_eval[-1]
    # the peers' model has no D: its column is NaN (the residual is then not measured)
    Y = np.column_stack([Y9, np.full(len(Y9), np.nan)])
    return Y, wall, -1, steps, 0, t_eval[-1]


def _load() -> float:
    try:
        return os.getloadavg()[0]
    except OSError:  # pragma: no cover - platforms without it
        return math.nan


def _repeat(fn: Callable, repeats: int):
    walls = []
    out = None
    for _ in range(max(1, repeats)):
        out = fn()
        walls.append(out[1])
        if out[1] > 2.0:      # slow runs: one is enough (their noise is small)
            break
    return out, min(walls)


def run_sweep(spec: str, *, quick: bool = False, repeats: int = 3, scipy: bool = True,
              peers: bool = True, methods=None,
              progress: Callable[[str], None] | None = None) -> list[BenchRow]:
    """All runs of one scene spec (see module doc); returns the rows."""
    from gyro_rotor.numerics.integrators import model_rate
    scene, label = parse_scene_spec(spec)
    model = scene.make_model()
    y0 = scene.initial_state(model)
    te = _t_eval(scene.t_end)
    R = reference(scene, te)
    rate = model_rate(scene.params)
    stiff = _is_stiff(scene)
    rtols = RTOLS['quick' if quick else 'full']
    jobs = []
    for name in (methods or (QUICK_METHODS if quick else (AUTO,) + tuple(METHODS))):
        if name == AUTO or METHODS[name].adaptive:
            for r in rtols:
                jobs.append(('gyro_rotor', name, f'rtol={r:.0e}',
                             {'rtol': r, 'atol': r * ATOL_RATIO}))
        elif name in STEP_FACTORS:
            if name == 'gauss6' and stiff:
                continue       # fixed-point stages cannot converge at useful steps
            if name == 'split8' and (stiff or scene.model != 'full'):
                continue       # explicit sub-flows; full model only
            facs = STEP_FACTORS[name]
            facs = facs[1::3] if quick else facs
            for f in facs:
                h = min(f / rate, scene.t_end)
                jobs.append(('gyro_rotor', name, f'h={h:.2e}', {'step': h}))
    if scipy:
        for name in (QUICK_SCIPY if quick else SCIPY):
            for r in rtols:
                jobs.append(('scipy', name, f'rtol={r:.0e}', {'rtol': r, 'atol': r * ATOL_RATIO}))
    peer = None
    if peers and scene.model == 'full':
        from gyro_rotor.numerics import bench_peers
        table = QUICK_PEERS if quick else bench_peers.PEER_METHODS
        have = [p for p in bench_peers.available() if p in table]
        if have:
            peer = bench_peers.make_peer_rhs(scene.params, have)
        for package in have:
            for m in table[package]:
                for r in rtols:
                    jobs.append(('peer', f'{PEER_LABEL[package]}:{m}', f'rtol={r:.0e}',
                                 {'package': package, 'method': m, 'rtol': r,
                                  'atol': r * ATOL_RATIO}))
    for name in dict.fromkeys(j[1] for j in jobs if j[0] == 'gyro_rotor'):
        # compile (or load from numba's cache) before timing
        integrate(model, y0, (0.0, te[1]), te[:2], name, max_steps=1000)
    if peer is not None:
        for package in have:
            bench_peers.peer_run(peer, package, 'DOP853', y0, te[:2], 1e-3, 1e-5)
    rows = []
    over_budget = set()
    for family, name, setting, kw in jobs:
        if name in over_budget:
            continue        # tighter settings of a method that ran out of budget: skip
        if family == 'scipy':
            fn = (lambda name=name, kw=kw: _scipy_run(model, y0, te, name, kw['rtol'],
                                                      kw['atol']))
        elif family == 'peer':
            fn = (lambda kw=kw: _peer_run(peer, kw['package'], model, y0, te, kw['method'],
                                          kw['rtol'], kw['atol']))
        else:
            fn = (lambda name=name, kw=kw: _ours_run(model, y0, te, name, **kw))
        (Y, _, nfev, nsteps, status, t_done), wall = _repeat(fn, repeats)
        e = errors(model, Y, R) if Y is not None else errors(model, np.empty((0, model.n)), R)
        rows.append(BenchRow(scene=label, method=name, family=family, setting=setting,
                             wall_per_sim=wall / t_done, nfev=nfev, nsteps=nsteps,
                             status=status, load=_load(), **e))
        if status == -3 or wall > SLOW_RUN:
            over_budget.add(name)
        if progress:
            progress(f'{label:22s} {name:17s} {setting:14s} err {e["err"]:.2e} '
                     f'wall/sim {wall / t_done:.3e} s  nfev {nfev}  status {status}')
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
