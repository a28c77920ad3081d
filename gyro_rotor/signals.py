"""Signals as a stop request: the one handler of every loop of the package that spins rclpy.

Python's default SIGINT handler raises KeyboardInterrupt wherever the main thread happens
to be; inside rclpy's C calls (taking and deserializing a message) pybind11 turned it into
a ``RuntimeError``/``TypeError`` with a traceback (the monitor's, ce52d5c; the demo's,
2990b49), and under a node's teardown it cut the writing of the bag short. Here a signal
only *asks* for a stop: :class:`StopSignals` remembers the first one and counts the rest;
the loops call :meth:`StopSignals.check` at their boundaries, which raises :class:`Stopped`
there (a KeyboardInterrupt, so ``gyro-rotor``'s ``main()`` reports it as one: exit status
128 + the signal's number, 130 for Ctrl-C).

Users: the nodes' ``main()`` (:func:`gyro_rotor.ros.runner.run_node`: SIGINT and SIGTERM,
an executor woken by the signal), the demo (SIGINT, SIGTERM, SIGHUP), ``monitor``,
``soak`` and ``rt-bench``; ``gyro-rotor``'s ``main()`` itself, whose handler raises at once
(``at_once``, Python's default) but remembers that it did, so an exception that rclpy made
of the KeyboardInterrupt is still reported as the interrupt it was.

Pure Python (no rclpy): below every layer, like :mod:`gyro_rotor.errors`.
"""

from __future__ import annotations

import os
import signal
import threading
from typing import Callable, Iterable

__all__ = ['StopSignals', 'Stopped', 'STOP', 'exit_status']

#: the signals that end a process's work by default: Ctrl-C and ``kill``/launch's SIGTERM
STOP = (signal.SIGINT, signal.SIGTERM)


def exit_status(signum: int) -> int:
    """Return the shell's exit status of a process stopped by ``signum`` (128 + number)."""
    return 128 + int(signum)


class Stopped(KeyboardInterrupt):
    """A stop signal acted on at a loop boundary (raised by :meth:`StopSignals.check`)."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        #: the signal's number
        self.signum = int(signum)


class StopSignals:
    """Signals as a stop request: the first is remembered, the rest counted (module doc).

    Installed with :meth:`install`, removed (the previous handlers back, or the signals
    ignored) with :meth:`restore`. The handler does nothing but set attributes, so it is
    safe wherever the main thread is when the signal arrives (inside rclpy, in a callback,
    in a teardown). With ``wake``, a thread calls ``wake()`` whenever a signal arrives (it
    reads the wakeup fd of :func:`signal.set_wakeup_fd`), e.g. to wake an executor whose
    wait would otherwise delay the Python handler until it times out. With ``at_once``
    the handler raises :class:`Stopped` after recording (Python's default for SIGINT).

    Parameters
    ----------
    signums : iterable of int
        The signals handled (default :data:`STOP`).
    at_once : bool
        Raise :class:`Stopped` from the handler (for code that holds no rclpy loop).
    """

    def __init__(self, signums: Iterable[int] = STOP, *, at_once: bool = False):
        #: the signals handled
        self.signums = tuple(signums)
        #: the first signal (None until one arrives)
        self.signum: int | None = None
        #: signals after the first (ignored)
        self.repeats = 0
        self._at_once = at_once
        self._previous: dict = {}
        self._pipe: tuple[int, int] | None = None
        self._old_fd = -1
        self._waker: threading.Thread | None = None

    @property
    def requested(self) -> bool:
        """Return whether a stop signal arrived."""
        return self.signum is not None

    def __call__(self, signum, frame) -> None:
        """Handle a signal (see the class doc)."""
        if self.signum is None:
            self.signum = signum
        else:
            self.repeats += 1
        if self._at_once:
            raise Stopped(signum)

    def check(self) -> None:
        """Raise :class:`Stopped` if a signal arrived (call it where leaving is safe)."""
        if self.signum is not None:
            raise Stopped(self.signum)

    def install(self, wake: Callable[[], None] | None = None) -> 'StopSignals':
        """Handle the signals from now on (call ``wake()`` on each); return self.

        Outside the main thread (where Python refuses handlers) nothing is installed: the
        process's own handlers stay in charge.
        """
        try:
            for sig in self.signums:
                self._previous[sig] = signal.signal(sig, self)
        except ValueError:              # not the main thread
            self.restore()
            return self
        if wake is not None:
            r, w = os.pipe()
            os.set_blocking(w, False)
            self._old_fd = signal.set_wakeup_fd(w, warn_on_full_buffer=False)
            self._pipe = (r, w)
            self._waker = threading.Thread(target=self._wake_loop, args=(r, wake),
                                           name='signal-wake', daemon=True)
            self._waker.start()
        return self

    @staticmethod
    def _wake_loop(fd: int, wake: Callable[[], None]) -> None:
        while True:
            try:
                if not os.read(fd, 64):         # the write end closed: restore()
                    return
            except OSError:
                return
            try:
                wake()
            except Exception:  # noqa: B902 -- (an executor already shut down)
                pass

    def restore(self, ignore: bool = False) -> None:
        """Put the previous handlers back, or with ``ignore`` ignore the signals (idempotent)."""
        if self._pipe is not None:
            signal.set_wakeup_fd(self._old_fd)
            r, w = self._pipe
            self._pipe = None
            os.close(w)
            self._waker.join()
            os.close(r)
        for sig, handler in self._previous.items():
            signal.signal(sig, signal.SIG_IGN if ignore else
                          signal.SIG_DFL if handler is None else handler)
        self._previous = {}

    def __enter__(self) -> 'StopSignals':
        """Install (without a waker); see :meth:`install`."""
        return self.install()

    def __exit__(self, *exc) -> None:
        """Restore the previous handlers."""
        self.restore()
