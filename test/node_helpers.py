"""Helpers shared by the tests that run nodes: waiting on a log line, spinning until."""

from pathlib import Path
import time


def wait_for_log(log: Path, text: str, proc, timeout: float = 60.0) -> None:
    """Wait until ``text`` appears in the log file of ``proc`` (which must keep running)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if text in log.read_text():
            return
        assert proc.poll() is None, log.read_text()
        time.sleep(0.1)
    raise AssertionError(f'no {text!r} in {log}: {log.read_text()}')


def spin_until(executor, cond, timeout: float = 20.0, step: float = 0.02) -> None:
    """Spin ``executor`` until ``cond()`` holds; fail after ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < deadline
        executor.spin_once(timeout_sec=step)
