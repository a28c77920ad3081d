"""A :class:`~gyro_rotor.bag.writer.BagWriter` run by a thread of its own, fed through a FIFO.

The recorder's receiving thread only takes messages from DDS and :meth:`BagSpool.put` s them;
the MCAP writing (and the per-message consumer, the live analysis) runs in the spool's
thread. The FIFO is bounded (``max_bytes`` of payload) and **never drops**: a ``put`` into a
full FIFO waits until the writer made room (back-pressure), and the time producers waited is
counted (:attr:`SpoolStats.blocked_s`), so an overloaded recorder says so. Commands (a new
topic, a metadata record, a flush) travel through the same FIFO, in order with the messages.
Pure Python: no rclpy.
"""

from __future__ import annotations

import collections
import dataclasses
import threading
import time
from typing import Any, Callable, Mapping

from gyro_rotor.bag.writer import BagWriter
from gyro_rotor.errors import BagError

__all__ = ['BagSpool', 'SpoolStats', 'DEFAULT_MAX_BYTES']

#: payload bytes the FIFO holds before ``put`` waits (about 3 min of rotor_sim at 1000 Hz)
DEFAULT_MAX_BYTES = 64 * 1024 * 1024
_MSG, _TOPIC, _META, _FLUSH, _STOP = range(5)


@dataclasses.dataclass
class SpoolStats:
    """What the spool did so far (read without a lock: a consistent-enough snapshot)."""

    queued: int = 0             # messages in the FIFO now
    queued_bytes: int = 0       # their payload bytes
    max_queued: int = 0         # high-water mark of ``queued``
    max_queued_bytes: int = 0   # high-water mark of ``queued_bytes``
    written: int = 0            # messages handed to the BagWriter (or counted not written)
    blocked_s: float = 0.0      # total time producers waited for room (back-pressure)
    blocks: int = 0             # puts that had to wait


class BagSpool:
    """Write a bag in a thread of its own, fed through a bounded FIFO that never drops.

    Parameters
    ----------
    writer : BagWriter
        The open bag; from now on only the spool's thread touches it (until :meth:`close`).
    max_bytes : int
        Payload bytes the FIFO holds before :meth:`put` waits for room.
    flush_period : float
        Seconds after which an idle writer ends and writes its open chunk.
    on_message : callable, optional
        ``on_message(topic, data)`` for every message, in FIFO order, in the spool's
        thread (also after a failed write).
    on_error : callable, optional
        ``on_error(text)`` once, when a write fails: messages are then counted in
        :attr:`not_written` instead, and :meth:`close` raises.
    """

    def __init__(self, writer: BagWriter, *, max_bytes: int = DEFAULT_MAX_BYTES,
                 flush_period: float = 0.5,
                 on_message: Callable[[str, bytes], None] | None = None,
                 on_error: Callable[[str], None] | None = None):
        if not max_bytes > 0:
            raise BagError(f'max_bytes must be > 0, got {max_bytes!r}')
        self.writer = writer
        self.max_bytes = int(max_bytes)
        self.flush_period = float(flush_period)
        self.on_message = on_message
        self.on_error = on_error
        self.stats = SpoolStats()
        #: why writing stopped (a failed write), None while all is well
        self.failed: str | None = None
        #: messages not in the bag because writing had failed
        self.not_written = 0
        #: exceptions raised by ``on_message`` (the first one's text): counted, not fatal
        self.consumer_errors = 0
        self.consumer_error: str | None = None
        self._fifo: collections.deque = collections.deque()
        self._cond = threading.Condition()
        self._closing = False
        self._flushes_done = 0
        self._flushes_asked = 0
        self._thread = threading.Thread(target=self._run, name='bag-spool', daemon=True)
        self._thread.start()

    # -- producers ----------------------------------------------------------------------------
    def put_many(self, items: list) -> None:
        """Queue ``(topic, data, log_time_ns, publish_time_ns)`` tuples in order."""
        size = sum(len(it[1]) for it in items)
        with self._cond:
            if self._closing:
                raise BagError(f'cannot queue messages: bag {self.writer.path} is closing')
            st = self.stats
            if st.queued and st.queued_bytes + size > self.max_bytes:
                t0 = time.monotonic()
                st.blocks += 1
                while st.queued and st.queued_bytes + size > self.max_bytes:
                    self._cond.wait(0.5)
                st.blocked_s += time.monotonic() - t0
            self._fifo.append((_MSG, items, size))
            st.queued += len(items)
            st.queued_bytes += size
            st.max_queued = max(st.max_queued, st.queued)
            st.max_queued_bytes = max(st.max_queued_bytes, st.queued_bytes)
            self._cond.notify_all()

    def add_topic(self, topic: str, type_name: str, qos: Any = None,
                  topic_type_hash: str | None = None) -> None:
        """Register a topic (in order: before its first :meth:`put`)."""
        self._command(_TOPIC, (topic, type_name, qos, topic_type_hash))

    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Queue an MCAP metadata record."""
        self._command(_META, (name, dict(data)))

    def flush(self, timeout: float | None = None) -> bool:
        """Write everything queued so far and end the open chunk; wait for it.

        Returns whether it was done within ``timeout`` seconds (None: wait as long as it
        takes). Called from the spool's own thread it only queues the flush.
        """
        with self._cond:
            if self._closing:
                raise BagError(f'bag {self.writer.path} is closing')
            self._flushes_asked += 1
            target = self._flushes_asked
            self._fifo.append((_FLUSH, None, 0))
            self._cond.notify_all()
        if threading.current_thread() is self._thread:
            return False
        with self._cond:
            return self._cond.wait_for(lambda: self._flushes_done >= target, timeout)

    def _command(self, kind: int, arg) -> None:
        with self._cond:
            if self._closing:
                raise BagError(f'bag {self.writer.path} is closing')
            self._fifo.append((kind, arg, 0))
            self._cond.notify_all()

    def close(self) -> None:
        """Write what is queued, stop the thread and close the bag; idempotent.

        Raises
        ------
        BagError
            If a write failed (the bag is then incomplete).
        """
        with self._cond:
            if not self._closing:
                self._closing = True
                self._fifo.append((_STOP, None, 0))
                self._cond.notify_all()
        self._thread.join()
        if not self.writer.closed:
            try:
                self.writer.close()
            except (OSError, BagError) as err:
                self._fail(err)
        if self.failed:
            raise BagError(f'{self.failed}; {self.not_written} messages not recorded')

    # -- the spool's thread -------------------------------------------------------------------
    def _run(self) -> None:
        last_flush = time.monotonic()
        dirty = False
        while True:
            with self._cond:
                if not self._fifo:
                    self._cond.wait(self.flush_period if dirty else None)
                batch = list(self._fifo)
                self._fifo.clear()
            for kind, arg, size in batch:
                if kind == _STOP:
                    return
                try:
                    dirty = self._do(kind, arg, size) or (dirty and kind != _FLUSH)
                except Exception as err:    # noqa: B902 -- a bug must not hang producers
                    self._fail(err)
                if kind == _FLUSH:
                    last_flush = time.monotonic()
            if dirty and time.monotonic() - last_flush >= self.flush_period:
                self._do(_FLUSH, 'periodic', 0)
                last_flush, dirty = time.monotonic(), False

    def _do(self, kind: int, arg, size: int) -> bool:
        """Carry out one FIFO entry; return whether the bag has unflushed messages."""
        if kind == _MSG:
            self._write(arg, size)
            return True
        if kind == _FLUSH:
            if not self.failed:
                try:
                    self.writer.flush()
                except (OSError, BagError) as err:
                    self._fail(err)
            if arg is None:             # asked for by flush(): count it for the waiter
                with self._cond:
                    self._flushes_done += 1
                    self._cond.notify_all()
            return False
        if self.failed:
            return False
        try:
            if kind == _TOPIC:
                topic, type_name, qos, digest = arg
                self.writer.add_topic(topic, type_name, qos, topic_type_hash=digest)
            else:
                self.writer.add_metadata(*arg)
        except (OSError, BagError) as err:
            self._fail(err)
        return False

    def _write(self, items: list, size: int) -> None:
        write, on_message = self.writer.write, self.on_message
        for topic, data, log_time, publish_time in items:
            if not self.failed:
                try:
                    write(topic, data, log_time, publish_time)
                except (OSError, BagError) as err:
                    self._fail(err)
                    self.not_written += 1
            else:
                self.not_written += 1
            if on_message is not None:
                try:
                    on_message(topic, data)
                except Exception as err:    # noqa: B902 -- the bag goes on; counted
                    self.consumer_errors += 1
                    self.consumer_error = self.consumer_error or repr(err)
        with self._cond:
            st = self.stats
            st.queued -= len(items)
            st.queued_bytes -= size
            st.written += len(items)
            self._cond.notify_all()

    def _fail(self, err: Exception) -> None:
        if self.failed:
            return
        total = self.writer.message_count
        self.failed = (f'recording stopped after {total} messages: cannot write '
                       f'{self.writer.path}: {getattr(err, "strerror", None) or err}')
        if self.on_error is not None:
            self.on_error(self.failed)
