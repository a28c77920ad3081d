"""``gyro-rotor campbell SCENE``: Campbell diagram (tracked modes) over the field speed."""

from __future__ import annotations

import argparse
import math

from gyro_rotor.cli.util import (check_output_file, load_scene_with_sets, write_json,
                                 write_output)
from gyro_rotor.errors import ParameterError

HELP = ('Campbell diagram of a scene: frequencies and decay rates of every mode (tracked by '
        'continuity) over the field speed Omega0, critical speeds marked')


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the arguments of the campbell command."""
    p.add_argument('scene', help='scene name or path (general or centrifuge)')
    p.add_argument('--set', action='append', default=[], metavar='NAME=VALUE')
    p.add_argument('--omega-min', type=float, default=None,
                   help='smallest Omega0 of the first drive [rad/s] (default 0.05 x nominal)')
    p.add_argument('--omega-max', type=float, default=None,
                   help='largest Omega0 [rad/s] (default 2 x nominal)')
    p.add_argument('--points', type=int, default=200, help='number of speeds (2..20000)')
    p.add_argument('--json', default=None, metavar='FILE', help='write the diagram as JSON')
    p.add_argument('--out', default=None, metavar='FILE.png', help='plot (needs matplotlib)')


def _speed_range(args, W0: float) -> tuple:
    """Return --omega-min, --omega-max (default 0.05 and 2 x nominal), refused if reversed.

    The speeds scale the scene's own: they lie on its side of 0 (its sense of rotation;
    0 itself is allowed), the smallest first.
    """
    if W0 == 0:
        raise ParameterError('campbell: the first drive has Omega0 = 0; nothing to scale')
    default = sorted((0.05 * W0, 2.0 * W0))
    lo = args.omega_min if args.omega_min is not None else default[0]
    hi = args.omega_max if args.omega_max is not None else default[1]
    side = 'must be >= 0' if W0 > 0 else 'must be <= 0'
    for name, v in (('--omega-min', lo), ('--omega-max', hi)):
        if not math.isfinite(v) or v * W0 < 0:
            raise ParameterError(
                f'{name} {side} rad/s (finite, in the sense of rotation of the scene: '
                f'Omega0 = {W0:g} rad/s, whose speed the diagram scales), got {v!r}')
    if hi <= lo:
        raise ParameterError(f'--omega-max ({hi:g}) must exceed --omega-min ({lo:g})')
    return lo, hi


def run(args: argparse.Namespace) -> int:
    """Compute, print and write the Campbell diagram."""
    from gyro_rotor.linear.campbell import campbell
    import numpy as np
    if args.json:
        check_output_file(args.json, ('.json',))
    if args.out:
        check_output_file(args.out, ('.png',))
    if not 2 <= args.points <= 20000:
        raise ParameterError(f'--points must be 2..20000, got {args.points}')
    scene = load_scene_with_sets(args.scene, args.set)
    lo, hi = _speed_range(args, scene.Omega0)
    cb = campbell(scene, np.linspace(lo, hi, args.points))
    print(f'scene {scene.name}: Campbell diagram over Omega0 = {lo:.4g} .. {hi:.4g} rad/s '
          f'({args.points} speeds, every drive scaled with the first); modes tracked by '
          'eigenvector continuity')
    if cb.skipped:
        print(f'  no steady motion at {len(cb.skipped)} speeds (Omega0 {min(cb.skipped):.4g} '
              f'.. {max(cb.skipped):.4g} rad/s): left out')
    j0 = cb.named_at
    print(f'  modes at Omega0 = {cb.Omega0[j0]:.4g} rad/s, named there (frequency, decay '
          'rate):')
    for k, label in enumerate(cb.labels):
        d = cb.decay[j0, k]
        print(f'    mode {k}: {label:40s} {cb.frequencies[j0, k]:10.4g} Hz  '
              + ('undamped' if d == 0 else f'{d:.4g} 1/s')
              + ('  UNSTABLE: a root grows' if cb.unstable[j0, k] else ''))
    for k in np.flatnonzero(cb.unstable.any(axis=0)):
        at = cb.Omega0[cb.unstable[:, k]]
        print(f'  UNSTABLE: mode {k} ({cb.labels[k]}) has a growing root (Re above its '
              f'resolution) at {at.size} of the {cb.Omega0.size} speeds, Omega0 '
              f'{at.min():.4g} .. {at.max():.4g} rad/s; fastest growth '
              f'{-cb.decay[:, k].min():.4g} 1/s')
    nreal = cb.real_roots()
    if nreal.min() != nreal.max():
        print(f'  the number of real roots changes over the range ({nreal.min()} .. '
              f'{nreal.max()}): pairs meet on the real axis; the modes stay tracked')
    for c in cb.critical:
        print(f'  critical speed: mode {c["mode"]} ({c["label"]}) crosses {c["order"]} x rotor '
              f'speed at Omega0 = {c["Omega0"]:.6g} rad/s ({c["Omega0"] * 30 / math.pi:.5g} '
              f'rpm, {c["frequency_hz"]:.4g} Hz)')
    if not cb.critical:
        print('  no critical speed in this range')
    if args.json:
        write_json(args.json, {'scene': scene.name, **cb.as_dict()})
        print(f'  wrote {args.json}')
    if args.out:
        fig = campbell_figure(cb, scene.name)
        write_output(args.out, lambda path: fig.savefig(path, dpi=120, bbox_inches='tight'))
        import matplotlib.pyplot as plt
        plt.close(fig)
        print(f'  wrote {args.out}')
    return 0


def campbell_figure(cb, name: str):
    """Return the Campbell figure (matplotlib): frequencies above, decay rates below.

    One colour per tracked mode (its legend entry names it and its frequency at the
    scene's speed); dashed and dotted lines the 1x and 2x rotor speed; red circles the
    critical speeds. The frequency axis is zoomed to the modes; a mode that is real over
    part of the range has no frequency line there. The decay axis is symmetric-log, so
    that an undamped mode (Re = 0 within round-off) lies at 0, drawn dashed.
    """
    try:
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.pyplot as plt
        from matplotlib.ticker import MaxNLocator
    except ImportError:
        raise ParameterError('--out needs matplotlib') from None
    import numpy as np
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(9.5, 7.5), sharex=True,
                                 gridspec_kw={'height_ratios': (3, 2)})
    rpm = cb.Omega0 * 30 / math.pi
    colors = plt.get_cmap('tab10' if len(cb.labels) <= 10 else 'tab20').colors
    F = cb.frequencies
    fmax = float(F.max()) if F.size else 0.0
    re = np.where(np.abs(cb.roots.real) <= cb.resolution, 0.0, cb.roots.real)
    for k, label in enumerate(cb.labels):
        col = colors[k % len(colors)]
        undamped = bool(np.all(cb.decay[:, k] == 0))
        style = '--' if undamped else '-'
        tag = (f'{label} (undamped)' if undamped else
               f'{label} (UNSTABLE)' if cb.unstable[:, k].any() else label)
        if F[:, k].max() > 0:
            a1.plot(rpm, np.where(F[:, k] > 0, F[:, k], np.nan), style, color=col, lw=1.6,
                    label=tag)
        for c in cb.modes[k]:
            a2.plot(rpm, -re[:, c], style, color=col, lw=1.4,
                    label=tag if (c == cb.modes[k][0] and F[:, k].max() == 0) else None)
    for order, style in ((1, '--'), (2, ':')):
        a1.plot(rpm, order * np.abs(cb.Omega0) / (2 * math.pi), style, color='0.25', lw=1.0,
                label=f'{order}x rotor speed')
    if cb.critical:
        xs = [c['Omega0'] * 30 / math.pi for c in cb.critical]
        ys = [c['frequency_hz'] for c in cb.critical]
        a1.plot(xs, ys, 'o', mfc='none', mec='tab:red', ms=8, mew=1.8,
                label='critical speed (mode meets 1x or 2x)')
        if len(cb.critical) <= 4:      # more would overlap: the command prints them all
            for x, y in zip(xs, ys):
                a1.annotate(f'{x:.4g} rpm', (x, y), textcoords='offset points', xytext=(7, -4),
                            fontsize=7, color='tab:red')
    a1.set_ylim(0.0, 1.12 * fmax if fmax > 0 else 1.0)
    a1.set_xlim(float(rpm.min()), float(rpm.max()))
    a1.set_ylabel('frequency |Im lambda| / 2 pi [Hz]')
    a1.set_title(f'Campbell diagram: {name} (modes tracked by eigenvector continuity)')
    at = cb.named_at
    a1.legend(loc='upper left', bbox_to_anchor=(1.01, 1.0), fontsize=8, borderaxespad=0,
              title=f'modes (f at {rpm[at]:.4g} rpm)', title_fontsize=8)
    positive = -re[-re > 0]
    lin = 10 ** math.floor(math.log10(float(positive.min()) if positive.size else 1.0))
    a2.set_yscale('symlog', linthresh=lin)
    top = float(np.max(np.abs(re))) if re.size else 1.0
    a2.set_ylim(-2 * top if np.any(re > 0) else -lin, 3 * max(top, lin))
    a2.axhline(0.0, color='0.4', lw=0.8)
    a2.set_ylabel('decay rate -Re lambda [1/s]\n(symlog; 0: undamped)')
    a2.set_xlabel('field speed Omega0 [rpm]')
    if a2.get_legend_handles_labels()[0]:
        a2.legend(loc='upper left', bbox_to_anchor=(1.01, 1.0), fontsize=8, borderaxespad=0,
                  title='real over the whole range', title_fontsize=8)
    for a in (a1, a2):
        a.grid(True, alpha=0.3)
        a.xaxis.set_major_locator(MaxNLocator(nbins=8))
    fig.tight_layout()
    return fig
