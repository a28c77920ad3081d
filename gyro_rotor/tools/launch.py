"""Starting the nodes as processes, without ROS 2 launch (not installable from PyPI).

:func:`claim_domain_id` takes a free ROS_DOMAIN_ID (a lock file per id, held while the
claim lives), so that a demo, a soak run or a test cannot hear another one;
:class:`NodeProcess` starts ``python -m gyro_rotor.<node> --ros-args -p name:=value ...``
with that domain and localhost-only discovery, and stops it with SIGINT (then SIGTERM,
then SIGKILL) so that the nodes finish cleanly: the recorder finalizes its bag.
"""

from __future__ import annotations

import fcntl
import os
import signal
import subprocess
import sys
import tempfile
from typing import Any, IO, Mapping

__all__ = ['claim_domain_id', 'DomainClaim', 'NodeProcess', 'ros_param']


class DomainClaim:
    """A claimed ROS_DOMAIN_ID; ``release()`` (or the context exit) frees it."""

    def __init__(self, domain_id: int, lock: IO):
        self.domain_id = domain_id
        self._lock = lock

    def release(self) -> None:
        """Free the domain id."""
        if self._lock is not None:
            self._lock.close()
            self._lock = None

    def __enter__(self) -> 'DomainClaim':
        return self

    def __exit__(self, *exc: Any) -> None:
        self.release()


def claim_domain_id(first: int = 101, last: int = 232) -> DomainClaim:
    """Claim a ROS_DOMAIN_ID in [first, last] that no other gyro_rotor process holds."""
    start = first + os.getpid() % (last - first + 1)
    for i in range(last - first + 1):
        domain = first + (start - first + i) % (last - first + 1)
        path = os.path.join(tempfile.gettempdir(), f'gyro_rotor_domain_{domain}.lock')
        f = open(path, 'w')
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.close()
            continue
        return DomainClaim(domain, f)
    raise RuntimeError(f'no free ROS_DOMAIN_ID in {first}..{last}')


def ros_param(name: str, value: Any) -> str:
    """``name:=value`` for ``--ros-args -p`` (floats keep their point, bools lower case)."""
    if isinstance(value, bool):
        text = 'true' if value else 'false'
    elif isinstance(value, float):
        text = repr(value)
    else:
        text = str(value)
    return f'{name}:={text}'


def _die_with_parent() -> None:
    """In the child: ask Linux for SIGTERM when the parent dies (even by SIGKILL).

    ``prctl(PR_SET_PDEATHSIG, SIGTERM)``; a no-op where there is no prctl.
    """
    try:
        import ctypes
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGTERM, 0, 0, 0)      # 1 = PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


class NodeProcess:
    """One node as a child process (stdout/stderr to files or pipes)."""

    def __init__(self, module: str, params: Mapping[str, Any] | None = None, *,
                 domain_id: int | None = None, stdout=None, stderr=None,
                 extra_args: list[str] | None = None, env: Mapping[str, str] | None = None,
                 die_with_parent: bool = False):
        self.module = module
        cmd = [sys.executable, '-m', module, '--ros-args']
        for k, v in (params or {}).items():
            cmd += ['-p', ros_param(k, v)]
        cmd += list(extra_args or [])
        e = dict(os.environ if env is None else env)
        e['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
        if domain_id is not None:
            e['ROS_DOMAIN_ID'] = str(domain_id)
        self.cmd = cmd
        self.proc = subprocess.Popen(cmd, env=e, stdout=stdout, stderr=stderr,
                                     stdin=subprocess.DEVNULL, start_new_session=True,
                                     preexec_fn=_die_with_parent if die_with_parent else None)

    @property
    def pid(self) -> int:
        """Process id."""
        return self.proc.pid

    def poll(self) -> int | None:
        """Exit code, or None while it runs."""
        return self.proc.poll()

    def stop(self, timeout: float = 20.0) -> int:
        """SIGINT, then SIGTERM, then SIGKILL, each after ``timeout``/2 s; the exit code."""
        for sig, wait in ((signal.SIGINT, timeout), (signal.SIGTERM, timeout / 2),
                          (signal.SIGKILL, timeout / 2)):
            if self.proc.poll() is not None:
                break
            try:
                self.proc.send_signal(sig)
            except ProcessLookupError:
                break
            try:
                self.proc.wait(wait)
            except subprocess.TimeoutExpired:
                continue
        return self.proc.wait()

    def kill(self) -> int:
        """SIGKILL (for fault tests)."""
        if self.proc.poll() is None:
            self.proc.kill()
        return self.proc.wait()
