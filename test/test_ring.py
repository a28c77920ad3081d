"""Tests of gyro_rotor.analysis.ring: the analysis' bounded row buffer."""

from gyro_rotor.analysis.ring import RowRing
import numpy as np
import pytest


def test_keeps_the_last_rows_oldest_first_and_a_fixed_size():
    ring = RowRing(4)
    assert ring.array().shape == (0, 5) and len(ring) == 0
    ring.append((0.0, 10.0))
    nbytes = ring.nbytes
    assert nbytes == 4 * 2 * 8
    np.testing.assert_array_equal(ring.array(), [[0.0, 10.0]])
    for i in range(1, 11):
        ring.append((float(i), 10.0 + i))
        kept = list(range(max(0, i - 3), i + 1))
        np.testing.assert_array_equal(ring.array(), [[k, 10.0 + k] for k in kept])
        assert len(ring) == len(kept) and ring.nbytes == nbytes
    assert ring.appended == 11


def test_array_is_a_copy():
    ring = RowRing(3)
    for i in range(3):
        ring.append((float(i),))
    a = ring.array()
    a[:] = -1.0
    np.testing.assert_array_equal(ring.array(), [[0.0], [1.0], [2.0]])


def test_refuses_another_width_and_no_capacity():
    ring = RowRing(3)
    ring.append((1.0, 2.0))
    with pytest.raises(ValueError, match='width 2'):
        ring.append((1.0, 2.0, 3.0))
    with pytest.raises(ValueError, match='capacity'):
        RowRing(0)
