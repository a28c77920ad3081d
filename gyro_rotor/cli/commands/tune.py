"""``gyro-rotor tune SCENE``: the K_D that maximizes the slowest decay (paper's closing remark)."""

from __future__ import annotations

import argparse
import math

from gyro_rotor.cli.util import on_system
from gyro_rotor.linear.stability import scene_operating_point
from gyro_rotor.linear.tune import best_K_D
import numpy as np

HELP = "best drive damping K_D for the scene's K_S (fastest slowest decay) and its sensitivity"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``tune``."""
    p.add_argument('scene', nargs='?', default='precession', help='scene name or path')
    p.add_argument('--set', action='append', default=[], metavar='NAME=VALUE')
    p.add_argument('--K-S', dest='K_S', type=float, default=None,
                   help="drive stiffness to tune for [N m/rad] (default: the scene's)")


def _run_centrifuge(args: argparse.Namespace, scene) -> int:
    """Print the best K_D and the sensitivity around it."""
    p, sm, model = scene_operating_point(scene)
    t = best_K_D(p, sm, model, K_S=args.K_S)
    print(f'scene {scene.name} (model {model}) about {sm.name}, K_S = {t.K_S:g} N m/rad')
    if t.excluded_modes:
        print(f'  not judged (zero root, or not reached by the drive): '
              f'{", ".join(t.excluded_modes)}')
    print(f'  best K_D = {t.K_D_best:.6g} N m s/rad: slowest decay rate {t.rate_best:.6g} 1/s '
          f'(tau = {t.tau_best:.6g} s), governed by {", ".join(t.governing_modes)}')
    print(f'  scene K_D = {t.K_D_current:g}: rate {t.rate_current:.6g} 1/s')
    print('  rate at ' + ', '.join(f'{k} x best: {v:.6g}' for k, v in t.rate_at.items()))
    print(f'  rate >= 90% of best for K_D in [{t.K_D_range_90[0]:.4g}, '
          f'{t.K_D_range_90[1]:.4g}]; d ln(rate)/d ln(K_D) = {t.dlnrate_dlnKD[0]:+.3g} below, '
          f'{t.dlnrate_dlnKD[1]:+.3g} above')
    return 0


def _run_system(args, scene) -> int:
    """Find the common K_D of all drives that makes the slowest reached mode decay fastest."""
    from gyro_rotor.linear.system import _unreached, linearize_scene
    if getattr(args, 'K_S', None) is not None:
        scene = scene.with_drives(K_S=args.K_S)
    lin = linearize_scene(scene)
    un, zeros, scale = _unreached(lin)

    def slowest(K):
        lam = lin.eig(K)
        keep = np.abs(lam) > 1e-7 * scale
        for u in un:
            keep &= np.abs(lam - u) > 1e-7 * scale
        return float(lam[keep].real.max()) if np.any(keep) else 0.0
    K_ref = scale / float(lin.fast_rates.min())
    grid = np.geomspace(1e-6 * K_ref, 1e4 * K_ref, 401)
    vals = np.array([slowest(K) for K in grid])
    i = int(np.argmin(vals))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    g = (math.sqrt(5) - 1) / 2
    for _ in range(80):
        c, d = b - g * (b - a), a + g * (b - a)
        if slowest(c) < slowest(d):
            b = d
        else:
            a = c
    K = 0.5 * (a + b)
    print(f'scene {scene.name}: best common K_D = {K:.6g} N m s/rad: slowest reached mode '
          f'decays at {-slowest(K):.6g} 1/s (time constant {-1 / slowest(K):.4g} s)')
    print(f"  at the scene's K_D = {lin.K_each.tolist()}: slowest reached decay "
          f'{-float(max(slowest(k) for k in lin.K_each)):.6g} 1/s')
    if un.size:
        print(f'  {un.size} roots are not reached by the drives and stay undamped at every '
              f'K_D: {", ".join(f"{x.imag:.6g}j" for x in un if x.imag > 0)}')
    return 0


def run(args: argparse.Namespace) -> int:
    """Run ``tune`` on the scene's system: the centrifuge's or a system file's."""
    return on_system(args, _run_centrifuge, _run_system)
