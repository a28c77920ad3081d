"""The shipped bags carry /clock (issue 27): ``ros2 bag play`` republishes the recorded time.

Without a recorded ``/clock``, ``ros2 bag play --clock`` would publish a clock of its own,
unrelated to the message stamps (which are simulation time). Every bag under ``bags/``
must have ``/clock``, and its times must be the stamps' own: on the sample grid of
``joint_states``, never going back, up to the last sample.
"""

from pathlib import Path
import warnings

from gyro_rotor.bag.bagio import open_bag
import numpy as np
import pytest

BAGS = Path(__file__).resolve().parents[1] / 'bags'
SHIPPED = sorted(p.name for p in BAGS.iterdir() if (p / 'metadata.yaml').is_file())


def _ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def test_the_four_bags_are_shipped():
    assert set(SHIPPED) >= {'precession', 'upright', 'pole_slip', 'twin_gimbal'}


@pytest.mark.parametrize('name', SHIPPED)
def test_every_shipped_bag_has_clock_agreeing_with_the_stamps(name):
    with warnings.catch_warnings():
        warnings.simplefilter('error')              # a shipped bag is whole: no recovery
        reader = open_bag(BAGS / name)
    assert not reader.truncated
    assert '/clock' in reader.topics, f'{name}: no /clock ({sorted(reader.topics)})'
    assert reader.topics['/clock'].type == 'rosgraph_msgs/msg/Clock'
    clock = np.array([_ns(m.clock) for _, _, m in reader.decoded('/clock')])
    joints = np.array([_ns(m.header.stamp) for _, _, m in reader.decoded('/joint_states')])
    assert clock.size > 0.5 * joints.size / 4         # about one per tick (250 Hz, 4 ms ticks)
    assert np.all(np.diff(clock) >= 0)                # simulation time never goes back
    assert set(clock) <= set(joints)                  # each /clock is a sample's stamp
    assert clock[-1] == joints[-1]                    # ... up to the last one
