"""The sweep specification and its unit of work: one block of points = one ensemble run.

The points of a sweep are cut into blocks of ``block_size`` consecutive flat indices
(block b holds points b B .. min((b + 1) B, n) - 1). The cut depends only on the
specification, never on the scheduler, and each block is integrated by one call of
:func:`gyro_rotor.numerics.ensemble.run_ensemble` (RK4, lockstep, compiled) with a step
``h`` common to the whole sweep. The ensemble integrates each trajectory independently
with that step, so a point's numbers do not depend on its block either: serial, on a
local cluster or on a remote one, the results are the same to the last bit.

Every scene takes the same path: :func:`make_spec` checks the grid and the metrics and fixes
the step, :func:`run_block` sets up the block's points, integrates them in one ensemble and
measures each. A point is the scene with the point's values (:meth:`Scene.with_changes`,
the scene's own checks), one model with its numbers per trajectory of
:func:`gyro_rotor.numerics.ensemble.run_ensemble`, measured by
:func:`~gyro_rotor.analysis.sweep.metrics.point_metrics`. What differs by the scene's system
is asked of it: which keys it sweeps (``check_sweep_key``) and its fastest rate over the
grid (``sweep_rate``, the step's scale), methods of
:class:`~gyro_rotor.core.centrifuge.Centrifuge` and
:class:`~gyro_rotor.core.system.generated.GeneratedSystem`.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from typing import Any, Mapping, Sequence
import warnings

from gyro_rotor.analysis.sweep.grid import SweepGrid
from gyro_rotor.analysis.sweep.metrics import Metric, METRIC_COLUMNS, point_metrics, PointStatus
from gyro_rotor.core.scene import flatten, Scene, scene_from_mapping, scene_path
from gyro_rotor.errors import GyroRotorError, ParameterError, SceneError
from gyro_rotor.node_settings import NODE_NAMES
from gyro_rotor.numerics.ensemble import run_ensemble
from gyro_rotor.numerics.simulate import MAX_SAMPLES
import numpy as np

__all__ = ['SweepSpec', 'make_spec', 'run_block', 'BlockResult', 'scene_flat',
           'US_PER_TRAJECTORY_STEP', 'TARGET_BLOCK_WORK_S', 'MAX_BLOCK_BYTES', 'STEP_FACTOR']

#: the ensemble's measured cost (README, integrators section) [us], for sizing blocks
US_PER_TRAJECTORY_STEP = 0.6
#: estimated work per block [s]: far above the measured per-task overhead of Dask
#: (a few ms, ``gyro-rotor sweep-bench``), so the overhead stays under 5 %
TARGET_BLOCK_WORK_S = 2.0
#: most bytes of ensemble samples one block holds in memory
MAX_BLOCK_BYTES = 64e6
#: RK4 step = STEP_FACTOR / the fastest model rate over the sweep (the ensemble's default)
STEP_FACTOR = 0.02


def scene_flat(scene: str) -> tuple[dict, str]:
    """Flat dotted mapping and path of a scene file (name or path), as ``load_scene`` reads it."""
    import yaml
    path = scene_path(scene)
    doc = yaml.safe_load(path.read_text(encoding='utf-8'))
    section = next((doc[k] for k in NODE_NAMES if isinstance(doc, dict) and k in doc), None)
    if not isinstance(section, dict) or not isinstance(section.get('ros__parameters'), dict):
        raise SceneError(f'scene file {path}: no rotor_sim: ros__parameters section')
    flat = flatten(section['ros__parameters'])
    flat.setdefault('scene', path.stem)
    scene_from_mapping(flat, path=str(path))         # the file's own checks (typed floats)
    return flat, str(path)


@dataclasses.dataclass(frozen=True)
class SweepSpec:
    """Everything that fixes a sweep's numbers (saved as ``sweep.json`` beside the results)."""

    scene: str
    base: Mapping[str, Any]
    grid: Sequence[str]
    t_end: float
    rate: float
    step: float
    metrics: Sequence[str]
    tol: float
    block_size: int

    @property
    def base_scene(self) -> Scene:
        """Return the scene of ``base`` (its keys as the file had them when the sweep began)."""
        return scene_from_mapping(dict(self.base), path=self.scene, strict_float=False)

    @property
    def sweep_grid(self) -> SweepGrid:
        """Return the parsed grid."""
        return SweepGrid.parse(list(self.grid))

    @property
    def n_points(self) -> int:
        """Return number of points."""
        return self.sweep_grid.n_points

    @property
    def n_blocks(self) -> int:
        """Return number of blocks."""
        return -(-self.n_points // self.block_size)

    @property
    def t_eval(self) -> np.ndarray:
        """Sample times 0, 1/rate, ..., t_end."""
        n = int(math.floor(self.t_end * self.rate + 1e-9))
        t = np.arange(n + 1) / self.rate
        return t if t[-1] >= self.t_end - 1e-12 else np.append(t, self.t_end)

    @property
    def steps_per_trajectory(self) -> int:
        """RK4 steps of one trajectory (the ensemble splits each sample interval evenly)."""
        return int(sum(n for _, n in self._intervals()))

    @property
    def step_used(self) -> float:
        """Return the longest RK4 step taken: ``step``, or a shorter sample interval."""
        return float(max(d / n for d, n in self._intervals()))

    def _intervals(self):
        """Yield (sample interval, RK4 steps in it): the ensemble splits each one evenly."""
        te = self.t_eval
        for a, b in zip(te[:-1], te[1:]):
            yield b - a, max(1, math.ceil((b - a) / self.step * (1.0 - 1e-12)))

    def block_points(self, b: int) -> np.ndarray:
        """Flat indices of block ``b``."""
        if not 0 <= b < self.n_blocks:
            raise ParameterError(f'block {b} out of range 0..{self.n_blocks - 1}')
        return np.arange(b * self.block_size, min((b + 1) * self.block_size, self.n_points))

    def to_json(self) -> str:
        """JSON text of the specification."""
        d = dataclasses.asdict(self)
        d['grid'], d['metrics'], d['base'] = list(self.grid), list(self.metrics), dict(self.base)
        return json.dumps(d, indent=1, sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> 'SweepSpec':
        """Inverse of :meth:`to_json`; also reads a ``sweep.json`` with the older ``general`` key.

        That key said whether the scene is a system file's, whose ``base`` then held only
        ``t_end``: such a specification does not say what its points are (ValueError).
        """
        d = json.loads(text)
        if d.pop('general', False):
            raise ValueError("written by an older version for a system file's scene, its "
                             'base holds no keys of the scene')
        return cls(**{**d, 'grid': tuple(d['grid']), 'metrics': tuple(d['metrics'])})


def _check_metrics(wanted) -> None:
    """Refuse an unknown metric (every system offers every :class:`Metric`)."""
    for m in wanted:
        if m not in tuple(Metric):
            raise ParameterError(f"unknown metric '{m}'; valid: "
                                 f"{', '.join(x.value for x in Metric)}")


def make_spec(scene: str, grid_specs: Sequence[str], *, t_end: float | None = None,
              rate: float = 100.0, metrics: Sequence[str] | None = None,
              tol: float = 1e-3, block_size: int | None = None,
              step: float | None = None) -> SweepSpec:
    """Check everything and build the specification (no integration is done here).

    Raises :class:`~gyro_rotor.errors.ParameterError` or ``SceneError`` naming the problem.
    """
    grid = SweepGrid.parse(grid_specs)
    base, path = scene_flat(scene)
    loaded = scene_from_mapping(base, path=path, strict_float=False)
    wanted = tuple(Metric) if metrics is None else tuple(metrics)
    _check_metrics(wanted)
    checked = grid.check(loaded)
    fastest = (None if step is not None
               else loaded.system.sweep_rate(grid.axes, [loaded, *checked]))
    t_end = loaded.t_end if t_end is None else float(t_end)
    for name, v in (('--t-end', t_end), ('--rate', rate), ('--tol', tol)):
        if not (math.isfinite(v) and v > 0):
            raise ParameterError(f'{name} must be positive and finite, got {v!r}')
    if t_end * rate < 1:
        raise ParameterError(f'--t-end x --rate = {t_end * rate:g}: at least one sample '
                             'interval is needed')
    if t_end * rate > MAX_SAMPLES:      # the samples of one trajectory (as simulate's limit)
        raise ParameterError(f'--t-end x --rate = {t_end * rate:g} samples per trajectory is '
                             f'more than {MAX_SAMPLES:g}: lower --rate or --t-end')
    h = float(step) if step is not None else STEP_FACTOR / max(fastest, 1.0)
    if not (math.isfinite(h) and h > 0):
        raise ParameterError(f'--step must be positive and finite, got {step!r}')
    spec = SweepSpec(scene=path, base=base, grid=tuple(a.spec for a in grid.axes), t_end=t_end,
                     rate=float(rate), step=h, metrics=tuple(str(m) for m in wanted),
                     tol=float(tol), block_size=1)
    if block_size is None:
        per_point = spec.steps_per_trajectory * US_PER_TRAJECTORY_STEP * 1e-6
        mem = MAX_BLOCK_BYTES / (spec.t_eval.size * 10 * 8.0)
        block_size = int(max(1, min(math.ceil(TARGET_BLOCK_WORK_S / per_point), mem)))
    elif block_size < 1:
        raise ParameterError(f'--block must be a positive number of points, got {block_size}')
    return dataclasses.replace(spec, block_size=int(min(block_size, grid.n_points)))


@dataclasses.dataclass
class BlockResult:
    """Columns of one block (point index, grid coordinates, status, message, metrics)."""

    block: int
    columns: dict
    work_s: float
    steps: int


@dataclasses.dataclass
class _Points:
    """A block's points as set up.

    ``idx``: the points set up (indices into the block), ``msg``: a set-up error per point,
    ``scenes``, ``models``: each point's scene and model (None where not set up), ``Y0``:
    the initial states of ``idx`` (len(idx), n).
    """

    idx: list
    msg: list
    scenes: list
    models: list
    Y0: np.ndarray | None = None


def _points(spec: SweepSpec, grid: SweepGrid, coords: dict, n: int) -> _Points:
    """Set up a block's points: the scene with each point's values, its model and state."""
    base = spec.base_scene
    scenes: list = [None] * n
    models: list = [None] * n
    Y0: list = [None] * n
    msg = [''] * n
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        for j in range(n):
            try:
                sc = base.with_changes(grid.overrides(coords, j))
                model = sc.make_model()
                Y0[j] = sc.initial_state(model)
                scenes[j], models[j] = sc, model
            except (GyroRotorError, ArithmeticError, ValueError) as err:
                msg[j] = f'set-up: {err}'
    idx = [j for j in range(n) if scenes[j] is not None]
    return _Points(idx, msg, scenes, models, np.array([Y0[j] for j in idx]) if idx else None)


def _integrate(spec: SweepSpec, pts: _Points, m: int):
    """Integrate the set-up points: samples (m, N, n); on an exception point by point.

    One ensemble of the first point's model, each trajectory with its own point's numbers.
    """
    params = [pts.models[j].params for j in pts.idx]

    def run(sel: slice):
        return run_ensemble(pts.models[pts.idx[0]], pts.Y0[sel], spec.t_eval, method='rk4',
                            step=spec.step, params=params[sel])
    try:
        res = run(slice(None))
        return res.y, int(res.nsteps), {}
    except (ArithmeticError, ValueError, GyroRotorError):
        pass
    out = np.full((m, *pts.Y0.shape), np.nan)
    errors, nsteps = {}, 0
    for c in range(len(pts.idx)):
        try:
            r = run(slice(c, c + 1))
            out[:, c, :], nsteps = r.y[:, 0, :], int(r.nsteps)
        except (ArithmeticError, ValueError, GyroRotorError) as err:
            errors[c] = f'integration: {type(err).__name__}: {err}'
    return out, nsteps, errors


def _abscissa(scene: Scene, cache: dict) -> float:
    """Return the spectral abscissa of any scene (:func:`~gyro_rotor.linear.system.assess`).

    The one linearization of every scene (:mod:`gyro_rotor.linear.system`); its modes are
    computed once per distinct linearization (a kick does not change it).
    """
    from gyro_rotor.linear.system import assess, linearize_scene
    try:
        lin = linearize_scene(scene)
        key = tuple(np.asarray(x).tobytes() for x in (lin.A_cons, lin.b_all, lin.c_all,
                                                      lin.K_all))
        if key not in cache:
            cache[key] = assess(lin)[1].spectral_abscissa
    except (GyroRotorError, ArithmeticError, np.linalg.LinAlgError):
        return math.nan
    return cache[key]


def run_block(spec: SweepSpec, b: int) -> BlockResult:
    """Integrate block ``b`` of the sweep and return its columns (a row per point, always)."""
    t0 = time.perf_counter()
    grid = spec.sweep_grid
    points = spec.block_points(b)
    n = points.size
    coords = grid.coordinates(points)
    metrics = {Metric(m) for m in spec.metrics}
    pts = _points(spec, grid, coords, n)
    cache: dict = {}
    t_eval = spec.t_eval
    msg = pts.msg
    names = [c for m in Metric if m in metrics for c in METRIC_COLUMNS[m]]
    cols = {c: np.full(n, np.nan) for c in names}
    status = np.full(n, int(PointStatus.FAILED), dtype=np.int8)
    nsteps = 0
    if pts.idx:
        Y, nsteps, errors = _integrate(spec, pts, t_eval.size)
        for c, j in enumerate(pts.idx):
            if c in errors:
                msg[j] = errors[c]
                continue
            y = Y[:, c, :]
            fin = np.all(np.isfinite(y), axis=1)
            if not np.all(fin):
                status[j] = PointStatus.DIVERGED
                msg[j] = f'non-finite state at t = {t_eval[np.argmin(fin)]:.6g} s'
                continue
            out = point_metrics(pts.scenes[j], pts.models[j], t_eval, y, metrics, tol=spec.tol)
            if Metric.ABSCISSA in metrics:
                out['spectral_abscissa'] = _abscissa(pts.scenes[j], cache)
            for k, v in out.items():
                cols[k][j] = v
            status[j] = PointStatus.OK
    columns = {'point': points.astype(np.int64), 'block': np.full(n, b, dtype=np.int32),
               **coords, 'status': status, 'message': np.array(msg, dtype=object), **cols}
    return BlockResult(block=b, columns=columns, work_s=time.perf_counter() - t0,
                       steps=nsteps * len(pts.idx))
