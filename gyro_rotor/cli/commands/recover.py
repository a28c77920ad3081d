"""``gyro-rotor recover BAG``: make a bag whose recorder was killed readable again."""

from __future__ import annotations

import argparse

HELP = ('repair a damaged bag or one left by a killed recorder (every intact chunk is kept, '
        'the loss counted and kept on record; originals saved as .orig)')


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``recover``."""
    p.add_argument('bag', help='bag directory (rosbag2, MCAP) or .mcap file')


def run(args: argparse.Namespace) -> int:
    """Recover and print what was done."""
    from gyro_rotor.bag.bagio import recover_bag
    rep = recover_bag(args.bag)
    for problem in rep.problems:
        print(f'found: {problem}')
    if rep.was_damaged:
        for f, o in zip(rep.rewritten, rep.originals):
            print(f'rewrote {f} (original kept as {o})')
    else:
        print(f'{rep.path}: every MCAP file is complete, nothing to rewrite')
    if rep.metadata_rewritten:
        print(f'rewrote {rep.path}/metadata.yaml with the real counts')
    print(f'{rep.message_count} messages readable: '
          + ', '.join(f'{t} {n}' for t, n in sorted(rep.messages_per_topic.items())))
    if rep.lost:
        print(f'{sum(rep.lost.values())} recorded messages lost: '
              + ', '.join(f'{t} {n}' for t, n in sorted(rep.lost.items()))
              + ' (kept on record in the bag)')
    if rep.unknown_loss:
        print('loss of unknown size: ' + '; '.join(rep.unknown_loss))
    if rep.lost_records:
        print('records lost: ' + '; '.join(rep.lost_records) + ' (kept on record in the bag)')
    return 0
