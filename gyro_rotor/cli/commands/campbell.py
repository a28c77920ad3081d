"""``gyro-rotor campbell SCENE``: Campbell diagram of a general scene over the field speed."""

from __future__ import annotations

import argparse
import json
import math

from gyro_rotor.cli.util import check_output_file, parse_sets
from gyro_rotor.errors import ParameterError, SceneError
import numpy as np

HELP = ('Campbell diagram of a general scene: frequencies and decay rates of every mode over '
        'Omega0, critical speeds marked')


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the arguments of the campbell command."""
    p.add_argument('scene', help='general scene name or path (a scene with a system key)')
    p.add_argument('--set', action='append', default=[], metavar='NAME=VALUE')
    p.add_argument('--omega-min', type=float, default=None,
                   help='smallest Omega0 of the first drive [rad/s] (default 0.05 x nominal)')
    p.add_argument('--omega-max', type=float, default=None,
                   help='largest Omega0 [rad/s] (default 2 x nominal)')
    p.add_argument('--points', type=int, default=200, help='number of speeds (2..20000)')
    p.add_argument('--json', default=None, metavar='FILE', help='write the diagram as JSON')
    p.add_argument('--out', default=None, metavar='FILE.png', help='plot (needs matplotlib)')


def run(args: argparse.Namespace) -> int:
    """Compute, print and write the Campbell diagram."""
    from gyro_rotor.core.system.scene import is_general_scene, load_general_scene
    from gyro_rotor.linear.general import campbell
    if args.json:
        check_output_file(args.json, ('.json',))
    if args.out:
        check_output_file(args.out, ('.png',))
    if not 2 <= args.points <= 20000:
        raise ParameterError(f'--points must be 2..20000, got {args.points}')
    if not is_general_scene(args.scene):
        raise SceneError(f"campbell needs a general scene (with a system key); '{args.scene}' "
                         'is a centrifuge scene (its general form is the scene '
                         'centrifuge_euler)')
    scene = load_general_scene(args.scene, overrides=parse_sets(args.set))
    W0 = scene.system.drives[0].Omega0
    lo = args.omega_min if args.omega_min is not None else 0.05 * W0
    hi = args.omega_max if args.omega_max is not None else 2.0 * W0
    if not (math.isfinite(lo) and math.isfinite(hi) and lo != hi):
        raise ParameterError(f'need two different finite speeds, got {lo}, {hi}')
    cb = campbell(scene, np.linspace(lo, hi, args.points))
    print(f'scene {scene.name}: Campbell diagram over Omega0 = {lo:.4g} .. {hi:.4g} rad/s '
          f'({args.points} speeds, every drive scaled with the first)')
    j0 = int(np.argmin(np.abs(cb.Omega0 - W0)))
    print(f'  at Omega0 = {cb.Omega0[j0]:.4g} rad/s: frequencies [Hz] '
          + ', '.join(f'{f:.4g}' for f in cb.frequencies[j0]))
    for c in cb.critical:
        print(f'  critical speed: mode {c["mode"]} crosses {c["order"]} x rotor speed at '
              f'Omega0 = {c["Omega0"]:.6g} rad/s ({c["Omega0"] * 30 / math.pi:.5g} rpm)')
    if not cb.critical:
        print('  no critical speed in this range')
    if args.json:
        with open(args.json, 'w', encoding='utf-8') as f:
            json.dump({'scene': scene.name, 'Omega0': cb.Omega0.tolist(),
                       'frequencies_hz': cb.frequencies.tolist(),
                       'decay_rates': cb.decay.tolist(), 'critical_speeds': cb.critical},
                      f, indent=1)
    if args.out:
        _plot(args.out, cb, scene.name)
    return 0


def _plot(path, cb, name) -> None:
    try:
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.pyplot as plt
    except ImportError:
        raise ParameterError('--out needs matplotlib') from None
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(7, 7), sharex=True)
    rpm = cb.Omega0 * 30 / math.pi
    a1.plot(rpm, cb.frequencies, 'b-', lw=1)
    for k in (1, 2):
        a1.plot(rpm, k * np.abs(cb.Omega0) / (2 * math.pi), 'k--', lw=0.8)
    for c in cb.critical:
        a1.plot([c['Omega0'] * 30 / math.pi], [c['order'] * abs(c['Omega0']) / (2 * math.pi)],
                'ro')
    a1.set_ylabel('frequency [Hz]')
    a1.set_title(f'Campbell diagram: {name}')
    a2.semilogy(rpm, np.maximum(cb.decay, 1e-12), 'g-', lw=1)
    a2.set_ylabel('decay rate -Re [1/s]')
    a2.set_xlabel('field speed [rpm]')
    for a in (a1, a2):
        a.grid(True, alpha=0.3)
    fig.savefig(path, dpi=120)
    plt.close(fig)
