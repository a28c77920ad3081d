"""``gyro-rotor tune SCENE``: the K_D that maximizes the slowest decay (paper's closing remark)."""

from __future__ import annotations

import argparse

from gyro_rotor.cli.util import parse_sets
from gyro_rotor.core.scene import load_scene
from gyro_rotor.linear.stability import scene_operating_point
from gyro_rotor.linear.tune import best_K_D

HELP = "best drive damping K_D for the scene's K_S (fastest slowest decay) and its sensitivity"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``tune``."""
    p.add_argument('scene', nargs='?', default='precession', help='scene name or path')
    p.add_argument('--set', action='append', default=[], metavar='NAME=VALUE')
    p.add_argument('--K-S', dest='K_S', type=float, default=None,
                   help="drive stiffness to tune for [N m/rad] (default: the scene's)")


def run(args: argparse.Namespace) -> int:
    """Print the best K_D and the sensitivity around it."""
    scene = load_scene(args.scene, overrides=parse_sets(args.set))
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
