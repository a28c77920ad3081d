"""``gyro-rotor soak``: the nodes under load for minutes; loss, memory, real-time factor.

Runs ``rotor_sim`` and ``rotor_analysis`` (recording) as processes for ``--duration``
simulated seconds at ``--rate`` and prints messages published vs recorded per topic,
memory growth, the achieved real-time factor and the bag size per minute
(:func:`gyro_rotor.tools.soak.run_soak`). ``--find-max-rate`` runs short soaks at increasing
rates instead and reports the highest rate without loss on this machine. ``--load`` runs
a busy process (``yes > /dev/null``) per core beside the nodes for the whole run. The figures go
to ``OUT/soak.json`` as well. Exit status 0 only if nothing was lost.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
import time

from gyro_rotor.errors import ParameterError

HELP = 'soak benchmark: both nodes recording for minutes; loss, memory, real-time factor'


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``soak``."""
    p.add_argument('--rate', type=float, default=1000.0, help='publish rate [Hz] (1000)')
    p.add_argument('--duration', type=float, default=600.0,
                   help='simulated seconds (600; at --rtf 1 also the wall time)')
    p.add_argument('--scene', default='precession', help='scene name or path (precession)')
    p.add_argument('--rtf', type=float, default=1.0,
                   help='real-time factor (1; 0 = as fast as possible, flow-controlled)')
    p.add_argument('--out', default=None, help='output directory (soak_runs/<time>)')
    p.add_argument('--find-max-rate', action='store_true',
                   help='search the highest rate with zero loss (short runs per rate)')
    p.add_argument('--rates', default='250,500,1000,1500,2000,3000',
                   help='rates tried by --find-max-rate [Hz, comma separated]')
    p.add_argument('--load', type=int, nargs='?', const=os.cpu_count() or 1, default=0,
                   metavar='N',
                   help='run N busy processes (yes > /dev/null) beside the nodes; --load '
                        f'alone: one per core ({os.cpu_count()})')
    p.add_argument('--run-seconds', type=float, default=20.0,
                   help='simulated seconds per rate with --find-max-rate (20)')


def run(args: argparse.Namespace) -> int:
    """Run the soak (or the rate search); 0 if nothing was lost."""
    from gyro_rotor.tools.soak import find_max_rate, run_soak
    from gyro_rotor.cli.util import check_number
    from gyro_rotor.node_settings import NODE_RANGES       # rotor_sim's own limits
    if args.load < 0:
        raise ParameterError(f'--load must be >= 0 busy processes, got {args.load}')
    check_number('--rate', args.rate, low=1.0, high=10000.0, what='Hz')
    t_max = NODE_RANGES['t_end'][1]
    check_number('--duration', args.duration, low=0.0, low_open=True, high=t_max, what='s')
    check_number('--run-seconds', args.run_seconds, low=0.0, low_open=True, high=t_max,
                 what='s')
    check_number('--rtf', args.rtf, low=0.0, high=NODE_RANGES['real_time_factor'][1],
                 what='(0 = as fast as possible)')
    out = Path(args.out) if args.out else Path('soak_runs') / time.strftime('%Y%m%d-%H%M%S')
    if args.find_max_rate:
        try:
            rates = [float(r) for r in args.rates.split(',') if r.strip()]
        except ValueError as err:
            raise ParameterError(f'--rates must be numbers separated by commas: {err}') \
                from err
        if not rates:
            raise ParameterError('--rates is empty')
        for r in rates:         # every rate before the first run, not when its turn comes
            check_number('--rates', r, low=1.0, high=10000.0, what='Hz (each of them)')
        print(f'searching the highest rate without loss: {rates} Hz, {args.run_seconds:g} s '
              f'each, scene {args.scene}, output {out}')
        best, results = find_max_rate(rates, duration=args.run_seconds, scene=args.scene,
                                      out=out, load=args.load)
        (out / 'max_rate.json').write_text(json.dumps(
            {'best_rate': best, 'runs': [r.as_dict() for r in results]}, indent=1,
            default=str))
        print(f'highest rate with zero loss and real-time factor >= 0.98: '
              f'{best if best is not None else "none"} Hz')
        return 0 if best is not None else 1
    res = run_soak(rate=args.rate, duration=args.duration, scene=args.scene, out=out,
                   rtf=args.rtf, load=args.load)
    print(res.text())
    print(f'figures: {out / "soak.json"}')
    return 0 if res.zero_loss else 1
