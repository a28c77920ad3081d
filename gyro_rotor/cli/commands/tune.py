"""``gyro-rotor tune SCENE``: the K_D that maximizes the slowest decay (paper's closing remark)."""

from __future__ import annotations

import argparse

from gyro_rotor.cli.util import load_scene_with_sets

HELP = "best drive damping K_D for the scene's K_S (fastest slowest decay) and its sensitivity"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``tune``."""
    p.add_argument('scene', nargs='?', default='precession', help='scene name or path')
    p.add_argument('--set', action='append', default=[], metavar='NAME=VALUE')
    p.add_argument('--K-S', dest='K_S', type=float, default=None,
                   help="drive stiffness to tune for [N m/rad] (default: the scene's)")


def run(args: argparse.Namespace) -> int:
    """Print the best common K_D of the drives and the sensitivity around it (every scene)."""
    # imported here, not at the top: ``gyro-rotor --help`` loads every command's module
    from gyro_rotor.linear.system import linearize_scene
    from gyro_rotor.linear.tune import tune

    sets = args.set + ([f'K_S={args.K_S!r}'] if args.K_S is not None else [])
    scene = load_scene_with_sets(args.scene, sets)
    lin = linearize_scene(scene)
    t = tune(lin)
    print(f'scene {scene.name}: system {scene.system_name} about {lin.about}')
    if t.excluded_modes:
        print(f'  not judged (zero root, or not reached by the drive): '
              f'{", ".join(t.excluded_modes)}')
    print(f'  best K_D = {t.K_D_best:.6g} N m s/rad: slowest decay rate {t.rate_best:.6g} 1/s '
          f'(tau = {t.tau_best:.6g} s), governed by {", ".join(t.governing_modes)}')
    print(f'  scene K_D = {", ".join(f"{k:g}" for k in t.K_D_current)}: rate '
          f'{t.rate_current:.6g} 1/s')
    print('  rate at ' + ', '.join(f'{k} x best: {v:.6g}' for k, v in t.rate_at.items()))
    print(f'  flatness: the rate at half the best K_D is {100 * t.relative_rate["0.5"]:.3g} % '
          f'of the best, at twice it {100 * t.relative_rate["2"]:.3g} %; rate >= 90% of best '
          f'for K_D in [{t.K_D_range_90[0]:.4g}, {t.K_D_range_90[1]:.4g}]')
    return 0
