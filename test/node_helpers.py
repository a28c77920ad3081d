"""Helpers shared by the tests that run nodes: conditions to wait on, never fixed sleeps.

See test/README.md: a node test waits for an event (a log line, a message, a service
answer) or a condition on what the nodes produced (messages on disk in the bag), each with a
generous deadline that only a broken node reaches.
"""

import fcntl
import hashlib
import os
from pathlib import Path
import subprocess
import sys
import time
import warnings

import pytest

_REPO = Path(__file__).resolve().parents[1]


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


def rostools_env() -> str:
    """Return the env.sh of a rostools build with this checkout in its overlay, or skip.

    ``GYRO_ROTOR_ROSTOOLS`` names a rostools DEST (run_tests.sh sets it to the one that
    bootstrap built): there a failed build of the overlay fails the test. Otherwise, where
    ``../shared/rostools`` is beside the checkout and the venv has colcon already (nothing
    to download: a rostools build ran for it before), one is built into the temp directory
    (about 15 s, then a few seconds per rebuild of the overlay).
    """
    build = _REPO.parent / 'shared' / 'rostools' / 'build.sh'
    venv = Path(sys.prefix)
    dest = os.environ.get('GYRO_ROTOR_ROSTOOLS')
    asked = bool(dest)
    if not dest:
        if not build.is_file():
            pytest.skip('ros2 launch is not installed: set GYRO_ROTOR_ROSTOOLS to a rostools '
                        'build (../shared/rostools/build.sh VENV DEST --package .)')
        if not (venv / 'bin' / 'colcon').is_file():
            pytest.skip(f'ros2 launch is not installed and {venv} has no colcon (a first '
                        'rostools build downloads it): run ../shared/rostools/build.sh '
                        f'{venv} DEST --package {_REPO}, then GYRO_ROTOR_ROSTOOLS=DEST')
        key = hashlib.sha256(str(venv).encode()).hexdigest()[:12]     # one per venv
        dest = str(Path(os.environ.get('TMPDIR', '/tmp')) /
                   f'gyro_rotor_rostools_{os.getuid()}_{key}')
    if not build.is_file():
        env_sh = Path(dest) / 'env.sh'
        if not env_sh.is_file():
            pytest.skip(f'GYRO_ROTOR_ROSTOOLS={dest} has no env.sh')
        return str(env_sh)          # (no build.sh to rebuild the overlay with: as it is)
    env_sh = Path(dest) / 'env.sh'
    with open(f'{dest}.lock', 'w') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        r = subprocess.run(['bash', str(build), str(venv), dest, '--package', str(_REPO)],
                           capture_output=True, text=True, timeout=300)
        if r.returncode == 0:
            # the overlay is a copy of the package at another path: numba's cache of the
            # checkout does not serve it, and the first node started from it would compile
            # the kernels (minutes on a cold cache) inside a test's deadline. Compiled here
            # once, outside the checkout (so that the copy is imported); later calls load them.
            # Only the live stepping of the scene the launch tests and the ROS tutorial run
            # (28 s of CPU cold, against 223 s for every method's every path)
            r = subprocess.run(['bash', '-c', f'set +u; source {env_sh}; exec python -m '
                                'gyro_rotor.numerics.integrators.warmup --live precession'],
                               cwd=dest,
                               capture_output=True, text=True, timeout=900)
    if r.returncode != 0:
        why = (f'rostools build or warm-up failed (exit {r.returncode}): '
               f'{(r.stderr or r.stdout).strip().splitlines()[-1:]}')
        (pytest.fail if asked else pytest.skip)(why)
    return str(env_sh)
