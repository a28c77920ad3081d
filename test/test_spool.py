"""Tests of gyro_rotor.bag.spool: the bag writer's thread and its FIFO that never drops.

No test waits a fixed time: each synchronizes on an event or on a condition of the spool
(with a generous deadline that only a broken spool reaches).
"""

from __future__ import annotations

import struct
import threading
import time

from gyro_rotor.bag.bagio import open_bag, qos_profile_dict
from gyro_rotor.bag.spool import BagSpool
from gyro_rotor.bag.writer import BagWriter
from gyro_rotor.errors import BagError
import pytest

FLOAT64 = 'std_msgs/msg/Float64'
DEADLINE = 60.0


def f64(value: float) -> bytes:
    """Return the CDR (little endian) of std_msgs/Float64."""
    return b'\x00\x01\x00\x00' + struct.pack('<d', value)


def wait_until(cond, what: str) -> None:
    """Wait for ``cond()`` (a condition, not a duration); fail after DEADLINE."""
    end = time.monotonic() + DEADLINE
    while not cond():
        assert time.monotonic() < end, f'timed out waiting for {what}'
        time.sleep(0.001)


def test_every_message_written_in_order_and_seen_by_the_consumer(tmp_path):
    seen = []
    spool = BagSpool(BagWriter(tmp_path / 'b'), on_message=lambda t, d: seen.append((t, d)))
    spool.add_topic('/a', FLOAT64, qos_profile_dict())
    spool.add_topic('/b', FLOAT64, qos_profile_dict())
    sent = []
    for i in range(500):
        batch = [('/a' if k % 2 else '/b', f64(i * 3 + k), 10**9 + i * 3 + k, 10**9)
                 for k in range(3)]
        spool.put_many(batch)
        sent += batch
    spool.add_metadata('x', {'k': 'v'})
    assert spool.flush(timeout=DEADLINE)
    assert seen == [(t, d) for t, d, _, _ in sent]
    assert spool.stats.queued == 0 and spool.stats.written == 1500
    spool.close()
    reader = open_bag(tmp_path / 'b')
    assert {t: i.count for t, i in reader.topics.items()} == {'/a': 500, '/b': 1000}
    got = [(t, lt, data) for t, lt, data in reader.messages()]
    assert sorted(got, key=lambda r: r[1]) == [(t, lt, d) for t, d, lt, _ in sent]


def test_full_fifo_makes_the_producer_wait_and_drops_nothing(tmp_path):
    release = threading.Event()
    seen = []

    def slow_consumer(topic, data):
        release.wait(DEADLINE)
        seen.append(data)

    spool = BagSpool(BagWriter(tmp_path / 'b'), max_bytes=100, on_message=slow_consumer)
    spool.add_topic('/a', FLOAT64, qos_profile_dict())
    done = threading.Event()

    def producer():
        for i in range(40):                     # 12 bytes each: 480 bytes > max_bytes
            spool.put_many([('/a', f64(i), 10**9 + i, 10**9 + i)])
        done.set()

    threading.Thread(target=producer, daemon=True).start()
    wait_until(lambda: spool.stats.blocks >= 1, 'the producer to block on the full FIFO')
    assert not done.is_set()
    assert spool.stats.queued_bytes <= 100
    release.set()
    assert done.wait(DEADLINE)
    assert spool.flush(timeout=DEADLINE)
    spool.close()
    assert seen == [f64(i) for i in range(40)]
    assert spool.stats.max_queued_bytes <= 100 and spool.stats.blocked_s > 0
    assert open_bag(tmp_path / 'b').topics['/a'].count == 40


def test_failed_write_is_reported_once_and_close_raises(tmp_path):
    errors, seen = [], []
    writer = BagWriter(tmp_path / 'b')

    def broken_write(*args):
        raise OSError(28, 'No space left on device')

    writer.write = broken_write
    spool = BagSpool(writer, on_message=lambda t, d: seen.append(d), on_error=errors.append)
    spool.add_topic('/a', FLOAT64, qos_profile_dict())
    for i in range(5):
        spool.put_many([('/a', f64(i), 10**9 + i, 10**9 + i)])
    assert spool.flush(timeout=DEADLINE)
    assert len(errors) == 1 and 'No space left' in errors[0]
    assert spool.not_written == 5 and len(seen) == 5     # the live consumer still got them
    with pytest.raises(BagError, match='5 messages not recorded'):
        spool.close()


def test_consumer_exception_is_counted_and_recording_goes_on(tmp_path):
    def bad_consumer(topic, data):
        raise ValueError('bug in the consumer')

    spool = BagSpool(BagWriter(tmp_path / 'b'), on_message=bad_consumer)
    spool.add_topic('/a', FLOAT64, qos_profile_dict())
    for i in range(3):
        spool.put_many([('/a', f64(i), 10**9 + i, 10**9 + i)])
    spool.close()
    assert spool.consumer_errors == 3 and 'bug in the consumer' in spool.consumer_error
    assert open_bag(tmp_path / 'b').topics['/a'].count == 3


def test_closed_spool_refuses_more(tmp_path):
    spool = BagSpool(BagWriter(tmp_path / 'b'))
    spool.close()
    spool.close()                                   # idempotent
    with pytest.raises(BagError, match='closing'):
        spool.put_many([('/a', f64(0), 1, 1)])
    with pytest.raises(BagError, match='max_bytes'):
        BagSpool(BagWriter(tmp_path / 'c'), max_bytes=0)


def test_an_idle_spool_flushes_its_open_chunk_without_being_asked(tmp_path):
    """The open chunk reaches the disk after flush_period with no further message or flush().

    What a recorder killed by SIGKILL keeps (test_analysis_node); waited for as an event,
    the chunk on disk, not as a duration.
    """
    from node_helpers import bag_on_disk
    spool = BagSpool(BagWriter(tmp_path / 'b'), flush_period=0.05)
    spool.add_topic('/a', FLOAT64, qos_profile_dict())
    spool.put_many([('/a', f64(1.0), 10**9, 10**9), ('/a', f64(2.0), 10**9 + 1, 10**9)])
    wait_until(lambda: len(bag_on_disk(tmp_path / 'b', '/a')) == 2, 'the chunk on disk')
    assert spool.stats.queued == 0
    spool.close()
