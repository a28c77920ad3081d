"""Heatmaps of a sweep: one PNG per metric column over the first two grid axes (matplotlib Agg).

The pull-in map (column ``final_well``) is coloured by the well the rotor ends in, with
the pole-slip count drawn over it (contour lines, and the numbers in each cell on small
grids). A design map over (K_S, K_D) of ``settling_time`` carries the linear optimum
K_D(K_S) of ``gyro-rotor tune`` (:func:`gyro_rotor.linear.tune.tune`). Points that
failed or diverged are grey. With more than two axes the others are held at their first
value (said in the title); with one axis the metric is drawn as a curve.
"""

from __future__ import annotations

import math
from pathlib import Path

from gyro_rotor.analysis.sweep.grid import GridAxis, key_unit, Spacing
from gyro_rotor.analysis.sweep.metrics import COLUMN_UNITS, Metric, METRIC_COLUMNS, PointStatus
from gyro_rotor.analysis.sweep.task import SweepSpec
from gyro_rotor.errors import GyroRotorError
import numpy as np

__all__ = ['plot_maps', 'metric_grid', 'linear_optimum']

#: most cells of a map that get their slip count written in
MAX_ANNOTATED_CELLS = 400


def _edges(a: GridAxis) -> np.ndarray:
    v = a.values
    if v.size == 1:
        return np.array([v[0] - 0.5, v[0] + 0.5]) if a.spacing is Spacing.LIN else \
            np.array([v[0] / 1.5, v[0] * 1.5])
    if a.spacing is Spacing.LOG:
        lv = np.log(v)
        mid = 0.5 * (lv[1:] + lv[:-1])
        return np.exp(np.concatenate([[2 * lv[0] - mid[0]], mid, [2 * lv[-1] - mid[-1]]]))
    mid = 0.5 * (v[1:] + v[:-1])
    return np.concatenate([[2 * v[0] - mid[0]], mid, [2 * v[-1] - mid[-1]]])


def metric_grid(table, spec: SweepSpec, column: str) -> tuple[np.ndarray, np.ndarray, str]:
    """Return (values (n0, n1) over the first two axes, NaN unless OK; OK mask; note)."""
    grid = spec.sweep_grid
    shape = grid.shape + (1,) * (2 - len(grid.shape)) if len(grid.shape) < 2 else grid.shape
    full = np.full(grid.n_points, np.nan)
    ok = np.zeros(grid.n_points, dtype=bool)
    pt = table.column('point').to_numpy()
    st = table.column('status').to_numpy()
    col = table.column(column).to_numpy(zero_copy_only=False).astype(float)
    full[pt] = np.where(st == PointStatus.OK, col, np.nan)
    ok[pt] = st == PointStatus.OK
    full, ok = full.reshape(shape), ok.reshape(shape)
    note = ''
    if len(shape) > 2:
        idx = (slice(None), slice(None)) + (0,) * (len(shape) - 2)
        full, ok = full[idx], ok[idx]
        note = ', '.join(f'{a.key} = {a.values[0]:g}' for a in grid.axes[2:])
    return full, ok, note


def linear_optimum(spec: SweepSpec, K_S_values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return K_S and the best K_D of :func:`~gyro_rotor.linear.tune.tune` at each.

    Any scene: its K_S (every rotor's) set by :meth:`Scene.with_changes`, as the sweep's
    points are; a K_S where tune finds no optimum is left out.
    """
    from gyro_rotor.linear.system import linearize_scene
    from gyro_rotor.linear.tune import tune
    scene = spec.base_scene
    ks, kd = [], []
    for k in K_S_values:
        try:
            kd.append(tune(linearize_scene(scene.with_changes({'K_S': float(k)}))).K_D_best)
            ks.append(float(k))
        except (GyroRotorError, ArithmeticError, np.linalg.LinAlgError):
            continue
    return np.array(ks), np.array(kd)


def _label(key: str) -> str:
    return f'{key} [{key_unit(key)}]'


def _draw_slips(ax, table, spec, x, y):
    slips, _, _ = metric_grid(table, spec, 'pole_slips')
    if np.all(np.isnan(slips)):
        return
    if slips.size <= MAX_ANNOTATED_CELLS:
        for i, xi in enumerate(x):
            for j, yj in enumerate(y):
                if np.isfinite(slips[i, j]):
                    ax.text(xi, yj, f'{slips[i, j]:.0f}', ha='center', va='center', fontsize=5)
    elif slips.shape[1] > 1 and slips.shape[0] > 1 and np.nanmax(slips) > 0:
        levels = np.arange(0.5, np.nanmax(slips) + 1.0, max(1.0, math.ceil(np.nanmax(slips) / 12)))
        cs = ax.contour(x, y, slips.T, levels=levels, colors='k', linewidths=0.6)
        ax.clabel(cs, fmt=lambda v: f'{v + 0.5:.0f}', fontsize=6)


def _draw_scene_point(ax, spec: SweepSpec, key0: str, key1: str) -> None:
    """Mark the scene's own values of the two axes' keys (a star), if the scene has both."""
    x, y = spec.base.get(key0), spec.base.get(key1)
    if isinstance(x, (int, float)) and isinstance(y, (int, float)):
        ax.plot([x], [y], marker='*', color='w', mec='k', ms=11, ls='none',
                label=f'the scene ({key0} = {x:g}, {key1} = {y:g})')
        ax.legend(loc='best', fontsize=7)


def _draw_optimum(ax, spec: SweepSpec, a0: GridAxis, a1: GridAxis) -> None:
    """Draw the linear optimum K_D(K_S) over a (K_S, K_D) map, where tune finds one."""
    ks_axis = a0 if a0.key == 'K_S' else a1
    sel = ks_axis.values[np.unique(np.linspace(0, ks_axis.count - 1,
                                               min(12, ks_axis.count)).astype(int))]
    ks, kd = linear_optimum(spec, sel)
    if ks.size:
        xs, ys = (ks, kd) if a0.key == 'K_S' else (kd, ks)
        ax.plot(xs, ys, 'w--o', ms=3, lw=1.2, label='linear optimum K_D(K_S) (tune)')
        ax.legend(loc='best', fontsize=7)


def _heatmap(table, spec: SweepSpec, column: str, path: Path) -> None:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    grid = spec.sweep_grid
    vals, ok, note = metric_grid(table, spec, column)
    scene = Path(spec.scene).stem
    a0 = grid.axes[0]
    fig, ax = plt.subplots(figsize=(7.5, 5.5), dpi=120)
    unit = COLUMN_UNITS[column]
    title = f'{scene}: {column} [{unit}], t_end = {spec.t_end:g} s'
    if len(grid.axes) == 1:
        ax.plot(a0.values, vals[:, 0], '.-')
        ax.set_xlabel(_label(a0.key))
        ax.set_ylabel(f'{column} [{unit}]')
        if a0.spacing is Spacing.LOG:
            ax.set_xscale('log')
    else:
        a1 = grid.axes[1]
        xe, ye = _edges(a0), _edges(a1)
        ax.set_facecolor('0.6')        # failed / diverged / missing points
        cmap = 'coolwarm' if column == 'final_well' else 'viridis'
        m = ax.pcolormesh(xe, ye, np.ma.masked_invalid(vals).T, cmap=cmap, shading='flat')
        fig.colorbar(m, ax=ax, label=f'{column} [{unit}]')
        if column == 'final_well':
            _draw_slips(ax, table, spec, a0.values, a1.values)
            title += ' (numbers/lines: pole slips)'
        keys = (a0.key, a1.key)
        if column == 'settling_time' and set(keys) == {'K_S', 'K_D'}:
            _draw_optimum(ax, spec, a0, a1)
        _draw_scene_point(ax, spec, a0.key, a1.key)
        ax.set_xlabel(_label(a0.key))
        ax.set_ylabel(_label(a1.key))
        if a0.spacing is Spacing.LOG:
            ax.set_xscale('log')
        if a1.spacing is Spacing.LOG:
            ax.set_yscale('log')
        bad = int((~ok).sum())
        no_value = int((ok & ~np.isfinite(vals)).sum())
        grey = ([f'{bad} failed, diverged or missing points'] if bad else []) + \
            ([f'{no_value} points without a value (not settled by t_end, no fit)']
             if no_value else [])
        if grey:
            title += '\ngrey: ' + '; '.join(grey)
    if note:
        title += f'\n({note})'
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_maps(table, spec: SweepSpec, out_dir) -> list:
    """Write one PNG per metric column of the sweep into ``out_dir``; return their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for m in spec.metrics:
        for column in METRIC_COLUMNS[Metric(m)]:
            if column == 'pole_slips':
                continue                 # drawn over the final_well map
            path = out / f'{column}.png'
            _heatmap(table, spec, column, path)
            paths.append(path)
    return paths
