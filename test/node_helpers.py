"""Helpers shared by the tests that run nodes: conditions to wait on, never fixed sleeps.

See test/README.md: a node test waits for an event (a log line, a message, a service
answer) or a condition on what the nodes produced (messages on disk in the bag), each with a
generous deadline that only a broken node reaches.
"""

from pathlib import Path
import time
import warnings


def wait_until(cond, what: str, proc=None, timeout: float = 60.0, step: float = 0.05):
    """Poll ``cond()`` until it returns a true value and return that value.

    Fails with ``what`` after ``timeout`` seconds, or at once when ``proc`` (a process that
    must keep running) has exited.
    """
    deadline = time.monotonic() + timeout
    while True:
        value = cond()
        if value:
            return value
        if proc is not None:
            assert proc.poll() is None, f'process exited (status {proc.poll()}) before {what}'
        assert time.monotonic() < deadline, f'timed out after {timeout:g} s waiting for {what}'
        time.sleep(step)


def wait_for_log(log: Path, text: str, proc, timeout: float = 60.0) -> None:
    """Wait until ``text`` appears in the log file of ``proc`` (which must keep running)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if text in log.read_text():
            return
        assert proc.poll() is None, log.read_text()
        time.sleep(0.1)
    raise AssertionError(f'no {text!r} in {log}: {log.read_text()}')


def bag_on_disk(bag: Path, topic: str) -> list:
    """Return ``(log_time, data)`` of ``topic`` in the chunks of a bag that reached the disk.

    The bag may be open in a recorder: its file then has no footer and is scanned up to
    the last complete record (an empty list while not even the header is there).
    """
    from gyro_rotor.bag.bagio import open_bag
    from gyro_rotor.errors import GyroRotorError
    try:
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')
            return [(t, d) for _, t, d in open_bag(bag).messages(topic)]
    except GyroRotorError:
        return []


def spin_until(executor, cond, timeout: float = 20.0, step: float = 0.02) -> None:
    """Spin ``executor`` until ``cond()`` holds; fail after ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < deadline
        executor.spin_once(timeout_sec=step)
