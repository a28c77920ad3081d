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
import threading
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


def run_reading(cmd: list, on_line, within_s: float, tmp_path: Path) -> tuple[int, str, str]:
    """Run ``cmd``, call ``on_line(line, proc)`` on each line of its stdout as it comes.

    Return (exit status, stdout, stderr). ``within_s`` bounds the run (the process is killed
    after it): a failure bound, not a pace. stderr goes to a file under ``tmp_path``.
    """
    err_path = tmp_path / 'stderr.txt'
    with open(err_path, 'w') as err:
        p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=err, text=True)
    watchdog = threading.Timer(within_s, p.kill)
    watchdog.start()
    lines = []
    try:
        for line in p.stdout:        # read to the end: on_line may signal the process
            lines.append(line)
            on_line(line, p)
        p.wait()
    finally:
        watchdog.cancel()
        if p.poll() is None:
            p.kill()
            p.wait()
    return p.returncode, ''.join(lines), err_path.read_text()


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


def spin_until(executor, cond, timeout: float = 20.0, step: float = 0.02,
               queues=()) -> None:
    """Spin ``executor`` until ``cond()`` holds; fail after ``timeout`` seconds.

    ``queues``: ``(subscription, sink)`` pairs drained (:func:`drain`) after every spin.
    """
    deadline = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < deadline, f'condition not met within {timeout:g} s'
        executor.spin_once(timeout_sec=step)
        for subscription, sink in queues:
            drain(subscription, sink)


class NodeThread:
    """A node spun by an executor of its own in a thread, as it runs in its own process.

    A probe in the test's executor then waits only on its own subscriptions. With the node
    in the probe's executor (every ``spin_once`` a wait set of the node's services, timers
    and publisher events besides the probe's), under 4 CPU hogs and a second test process
    the probe took 510 energy messages in 12.3 s while the node published 250 a second: its
    backlog grew from test to test, and a test waiting for the sample after a reset waited
    behind it (measured, stop 40). Quiet, the probe's thread costs 0.7 ms of CPU per message
    this way against 0.9 ms before.
    """

    def __init__(self, node, context):
        from rclpy.executors import SingleThreadedExecutor
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, name='node-executor', daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        while not self._stop.is_set():
            self.executor.spin_once(timeout_sec=0.05)

    def close(self) -> None:
        """Stop spinning and shut the executor down (the node stays to be destroyed)."""
        self._stop.set()
        self._thread.join()
        self.executor.shutdown()


def drain(subscription, sink: list) -> None:
    """Append every message waiting on ``subscription`` to ``sink``, without the executor.

    The executor takes one message per ``spin_once`` (a wait set built each time: 0.7 ms of
    CPU per message here). A probe that drains its queues after each spin takes whatever
    arrived since in one go, so the less CPU it gets the more it takes per spin: under 4
    CPU hogs it kept up with 500 messages a second on 0.13 of a core (backlog 0 to 8
    messages over 12 s; measured, stop 40).
    """
    with subscription.handle:
        while (taken := subscription.handle.take_message(subscription.msg_type,
                                                         subscription.raw)) is not None:
            sink.append(taken[0])


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
