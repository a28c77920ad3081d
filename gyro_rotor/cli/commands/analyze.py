"""``gyro-rotor analyze BAG``: the live node's stability checks on a recorded bag.

Exit status: 0 if the verdict is confirmed (every applicable criterion passed:
asymptotically stable, or marginal where the linear theory predicts it), :data:`NOT_CONFIRMED`
(2) for any other verdict (not confirmed, insufficient data, unstable, diverged), 1 for bad
input.
"""

from __future__ import annotations

import argparse
import json
import sys

HELP = ('analyze a recorded bag: Lyapunov, decay fits, eigenvalues from data vs predicted, '
        'pole slips, verdict; text/JSON report and plots; exit 0 confirmed, 2 not')
#: exit status for a verdict that is not confirmed (1 is bad input)
NOT_CONFIRMED = 2


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``analyze``."""
    p.add_argument('bag', help='bag directory (rosbag2, MCAP) or .mcap file')
    p.add_argument('--out', default=None, metavar='DIR',
                   help='write report.txt, report.json and plots (energy.png, '
                        'eigenvalues.png, state.png) into DIR')
    p.add_argument('--json', default=None, metavar='FILE',
                   help="write the JSON report ('-': to stdout, the text to stderr)")
    p.add_argument('--scene', default=None,
                   help='scene name or path (default: the one recorded in the bag)')
    p.add_argument('--window', type=float, default=None, metavar='S',
                   help="fit window [s] (default: the live node's; 0 = whole segments)")
    p.add_argument('--no-plots', action='store_true', help='no plots (faster)')


def run(args: argparse.Namespace) -> int:
    """Print the text report; 0 if the verdict is confirmed, else 2 (1 for bad input)."""
    import math

    from gyro_rotor.analysis.offline import analyze_bag
    from gyro_rotor.analysis.report import (json_report, strict_json, text_report,
                                            write_report)
    from gyro_rotor.cli.util import check_output_dir, check_output_file
    from gyro_rotor.errors import BagError, ParameterError
    if not args.bag.strip():
        raise BagError('the bag path is empty (give a bag directory or an .mcap file)')
    if args.window is not None and not args.window >= 0:
        bad = 'NaN' if math.isnan(args.window) else repr(args.window)
        raise ParameterError(f'--window must be >= 0 s (0 = whole segments), got {bad}')
    to_stdout = args.json == '-'
    if args.json and not to_stdout:
        check_output_file(args.json)
    if args.out:
        check_output_dir(args.out)
    bag = analyze_bag(args.bag, scene=args.scene, window_s=args.window)
    # with the JSON on stdout (to pipe it), the text goes to stderr
    text = sys.stderr if to_stdout else sys.stdout
    text.write(text_report(bag.result, bag))
    files = write_report(bag, args.out, None if to_stdout else args.json,
                         plots=not args.no_plots)
    if to_stdout:
        print(json.dumps(strict_json(json_report(bag.result, bag)), indent=1))
    for f in files:
        print(f'wrote {f}', file=text)
    res = bag.result
    why = [] if res.confirmed else [res.reason]
    if bag.cut_note:
        why.append(bag.cut_note)
    # a damaged bag says so in the result line, whatever the verdict (issue 24)
    damage = f' [damaged bag: {bag.loss}]' if bag.damaged else ''
    print(f'RESULT: {"CONFIRMED" if res.confirmed else "NOT CONFIRMED"}: {res.verdict}'
          + (f' ({"; ".join(why)})' if why else '') + damage, file=text)
    return 0 if res.confirmed else NOT_CONFIRMED
