"""Recording of the simulation topics into a rosbag2 (MCAP) bag: the ROS side of bagio.

:class:`BagRecorder` attaches to a node. For every topic it creates one ``raw=True``
subscription (RELIABLE, KEEP_ALL, VOLATILE; KEEP_LAST ``depth`` TRANSIENT_LOCAL for the
latched ``~/scene`` document), so the bag holds the serialized bytes exactly as received, never
re-encoded. A topic's channel is registered at its first message, with the QoS profiles its
publishers offer and the type hash they announce (``Node.get_publishers_info_by_topic``),
as ``ros2 bag record`` does;
``log_time`` is the receive time (when DDS received the message for this reader, wall clock) and
``publish_time`` the publisher's DDS source timestamp (both ns since the epoch, this host's
clock); the simulation time is only in the messages (stamps, ``/clock``).

**Threads (issue 12).** Profiled at 1000 Hz, most of the recorder's CPU went into rclpy's
executor (one wake-up, wait-set rebuild and callback dispatch per few messages), and the
node's 1-Hz analysis blocked the executor for 50 ms (CPU) to 0.5 s (wall, under load) per
second. The subscriptions therefore live on a hidden node of their own (``_<node>_recorder``,
never spun by an executor), and a *receiving thread* polls them every ``poll_period``
seconds: it takes everything queued (``take_message``, raw CDR) and hands the batch to a
:class:`~gyro_rotor.bag.spool.BagSpool`, whose thread writes the MCAP file and calls
``on_message``. The spool's FIFO never drops; when it is full the receiving thread waits
and DDS holds the messages (the KEEP_ALL reader history, 5000 samples per topic in Fast
DDS, then the publisher's history). A message DDS still had to give up is reported by the
reader's MESSAGE_LOST event, polled per topic: :attr:`BagRecorder.lost`. The spool ends the
open chunk every ``flush_period`` seconds, so a killed recorder loses at most about a
second.

Each received message may also be handed to a callback (``on_message(topic, data)``, in the
spool's thread) so that the analysis uses the very bytes that were recorded.
"""

from __future__ import annotations

import os
from pathlib import Path
import shutil
import threading
import time
from typing import Callable, Mapping

from gyro_rotor.bag.bagio import BagWriter, normalize_qos, qos_profile_dict
from gyro_rotor.bag.spool import BagSpool, DEFAULT_MAX_BYTES
from gyro_rotor.bag.wire import sim_topics
from gyro_rotor.errors import BagError
from gyro_rotor.node_settings import recorder_node_name
import rclpy
from rclpy.event_handler import QoSSubscriptionEventType
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = ['BagRecorder', 'sim_topics', 'default_bag_path', 'check_writable', 'DRAIN_MAX',
           'MIN_FREE_BYTES', 'POLL_PERIOD']

#: free space check_writable requires [bytes] (about a minute at 1000 Hz)
MIN_FREE_BYTES = 32 * 1024 * 1024
#: most messages the receiving thread takes from one subscription in one pass
DRAIN_MAX = 2000
#: seconds the receiving thread sleeps when nothing was queued
POLL_PERIOD = 0.01
#: seconds between polls of the MESSAGE_LOST events
_LOST_PERIOD = 0.5
#: at shutdown, longest wait for the other nodes' publishers of the recorded topics to go
#: away before the last messages are taken [s] (see :meth:`BagRecorder.drain`)
SETTLE_S = 1.0


def default_bag_path(root: str | os.PathLike = 'bags_out') -> Path:
    """Return a fresh timestamped bag directory under ``root`` (not created here)."""
    stamp = time.strftime('%Y%m%d_%H%M%S', time.localtime())
    base = Path(root) / f'rotor_{stamp}'
    path, i = base, 1
    while path.exists():
        path = Path(f'{base}_{i}')
        i += 1
    return path


def check_writable(path: Path, min_free: int | None = None) -> None:
    """Raise BagError unless the bag directory ``path`` can be created (before any ROS work).

    Also refuses a file system with less than ``min_free`` bytes free (default
    :data:`MIN_FREE_BYTES`), so that a full disk is a clear error at start rather than a
    failed write later.
    """
    path = Path(path)
    if path.exists():
        raise BagError(f'output {path} exists already, not overwriting')
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
        raise BagError(f'output directory {parent} is not writable (bag {path})')
    need = MIN_FREE_BYTES if min_free is None else min_free
    free = shutil.disk_usage(parent).free
    if free < need:
        raise BagError(f'output directory {parent} has only {free // 1024} kB free, at least '
                       f'{need // 1024} kB needed to start recording (bag {path})')


def _import_type(type_name: str):
    import importlib
    pkg, _, name = type_name.split('/')
    return getattr(importlib.import_module(f'{pkg}.msg'), name)


class BagRecorder:
    """Record topics of ``node``'s graph into a bag (see module doc).

    Parameters
    ----------
    node : rclpy.node.Node
        The node whose namespace and remappings resolve the topic names; the
        subscriptions live on a hidden node of the same context.
    path : path
        Bag directory to create (must not exist).
    topics : mapping of topic name to type name
        Names may be relative (resolved in the node's namespace).
    metadata : mapping, optional
        MCAP metadata records written at open.
    depth : int
        Queue depth of the latched topics (KEEP_LAST); 0 makes every subscription
        KEEP_LAST 1000 (the behaviour before issue 8). The other topics are KEEP_ALL: a
        message the subscription cannot store is not acknowledged, so a reliable
        publisher that waits for acknowledgements (``rotor_sim`` at real_time_factor 0)
        is held back instead of losing messages.
    flush_period : float
        Seconds between flushes of the open chunk.
    on_message : callable, optional
        ``on_message(resolved_topic, data)`` for every received message (spool thread).
    latched : iterable of str
        Topics to subscribe TRANSIENT_LOCAL (latched documents).
    compression : {'none', 'zstd', 'lz4'}
        MCAP chunk compression (rosbag2 writes none by default).
    on_error : callable, optional
        ``on_error(text)`` once when a write fails (disk full, I/O error): recording then
        stops, ``on_message`` still gets every message, and :meth:`close` raises.
    max_bytes : int
        Payload bytes the spool's FIFO holds before the receiving thread waits.
    poll_period : float
        Seconds the receiving thread sleeps when no message was queued.
    start : bool
        Start receiving now; False: at :meth:`start` (once the owner can take messages).
    """

    def __init__(self, node: Node, path: str | os.PathLike, topics: Mapping[str, str], *,
                 metadata: Mapping[str, Mapping[str, str]] | None = None, depth: int = 1000,
                 flush_period: float = 0.5,
                 on_message: Callable[[str, bytes], None] | None = None,
                 latched: tuple = (), compression: str = 'none',
                 on_error: Callable[[str], None] | None = None,
                 max_bytes: int = DEFAULT_MAX_BYTES, poll_period: float = POLL_PERIOD,
                 start: bool = True):
        self.node = node
        self.path = Path(path)
        self.on_error = on_error
        self.writer = BagWriter(self.path, flush_interval_s=flush_period, metadata=metadata,
                                compression=compression)
        self.spool = BagSpool(self.writer, max_bytes=max_bytes, flush_period=flush_period,
                              on_message=on_message, on_error=self._fail)
        #: messages taken from DDS, per resolved topic
        self.received: dict[str, int] = {}
        #: messages DDS reported lost before this reader got them (MESSAGE_LOST), per topic
        self.lost: dict[str, int] = {}
        #: why recording stopped (a failed write), None while all is well
        self.failed: str | None = None
        self._types: dict[str, str] = {}
        self.drain_max = DRAIN_MAX
        self.poll_period = float(poll_period)
        self._last_log: dict[str, int] = {}
        self._rx = rclpy.create_node(
            recorder_node_name(node.get_name()), namespace=node.get_namespace(),
            context=node.context, use_global_arguments=False, enable_rosout=False,
            start_parameter_services=False)
        self._subs: list = []
        self._events: dict = {}
        latched_names = {node.resolve_topic_name(t) for t in latched}
        for topic, type_name in topics.items():
            name = node.resolve_topic_name(topic)
            self._types[name] = type_name
            latched_topic = name in latched_names
            keep_all = depth > 0       # latched topics too: a flood must not overwrite
            qos = QoSProfile(history=(HistoryPolicy.KEEP_ALL if keep_all
                                      else HistoryPolicy.KEEP_LAST),
                             depth=depth or 1000,
                             reliability=ReliabilityPolicy.RELIABLE,
                             durability=(DurabilityPolicy.TRANSIENT_LOCAL
                                         if latched_topic
                                         else DurabilityPolicy.VOLATILE))
            sub = self._rx.create_subscription(_import_type(type_name), name, _never, qos,
                                               raw=True)
            self._subs.append((name, sub))
            self.lost[name] = 0
            with sub.handle:
                self._events[name] = _rclpy.EventHandle(
                    sub.handle, QoSSubscriptionEventType.RCL_SUBSCRIPTION_MESSAGE_LOST)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._receive, name='bag-receiver',
                                        daemon=True)
        if start:
            self._thread.start()

    def start(self) -> None:
        """Start the receiving thread (if the constructor was told not to)."""
        if self._thread is not None and not self._thread.is_alive() and \
                not self._stop.is_set():
            self._thread.start()

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` has run."""
        return self.writer.closed

    def _add_topic(self, topic: str) -> None:
        """Register ``topic`` at its first message with what its publishers offer.

        As ``ros2 bag record``: the offered QoS profiles and the ``topic_type_hash`` come from
        the graph (``get_publishers_info_by_topic``); the hash falls back to the installed
        type description when no publisher offers a valid one.
        """
        infos = self._rx.get_publishers_info_by_topic(topic)
        profiles = [normalize_qos(i.qos_profile)[0] for i in infos] or [qos_profile_dict()]
        hashes = {str(i.topic_type_hash) for i in infos
                  if getattr(i, 'topic_type_hash', None) is not None}
        hashes.discard('INVALID')
        digest = hashes.pop() if len(hashes) == 1 else None
        self.spool.add_topic(topic, self._types[topic], profiles, topic_type_hash=digest)
        self.received[topic] = 0

    # -- the receiving thread -----------------------------------------------------------------
    def _receive(self) -> None:
        """Take what DDS queued, hand it to the spool; poll the MESSAGE_LOST events."""
        next_lost = time.monotonic() + _LOST_PERIOD
        while not self._stop.is_set():
            try:
                taken = self.receive_once()
            except Exception as err:    # noqa: B902 -- handles destroyed at shutdown
                if not self._stop.is_set():
                    self._fail(err)
                return
            now = time.monotonic()
            if now >= next_lost:
                self._poll_lost()
                next_lost = now + _LOST_PERIOD
            if not taken:
                self._stop.wait(self.poll_period)

    def receive_once(self) -> int:
        """Take up to ``drain_max`` queued messages per topic into the spool; return how many."""
        batch = []
        for name, sub in self._subs:
            handle, msg_type = sub.handle, sub.msg_type
            with handle:
                for _ in range(self.drain_max):
                    got = handle.take_message(msg_type, True)
                    if got is None:
                        break
                    batch.append(self._stamp(name, got[0], got[1]))
        if batch:
            self.spool.put_many(batch)
        return len(batch)

    def _stamp(self, topic: str, data: bytes, info) -> tuple:
        """Return the spool entry of a taken message (log_time: DDS reception time)."""
        if topic not in self.received:
            self._add_topic(topic)
        self.received[topic] += 1
        # rclpy gives the MessageInfo as a dict: received_timestamp is when DDS received
        # the message, source_timestamp when it was sent (both this host's clock)
        recv = info.get('received_timestamp') if type(info) is dict else None
        publish = info.get('source_timestamp') if type(info) is dict else None
        log = recv if recv and recv > 0 else time.time_ns()
        last = self._last_log.get(topic, 0)
        if log <= last:             # receive order stays the bag's log-time order
            log = last + 1
        self._last_log[topic] = log
        return (topic, data, log, publish if publish and publish > 0 else log)

    def _poll_lost(self) -> None:
        for name, ev in self._events.items():
            with ev:
                status = ev.take_event()
            if status is not None and status.total_count > self.lost[name]:
                self.lost[name] = int(status.total_count)

    def _record(self, topic: str, data: bytes, info=None) -> None:
        """Queue one message as if it had been taken from ``topic`` (tests, tools)."""
        self.spool.put_many([self._stamp(topic, data, info)])

    # -- control -----------------------------------------------------------------------------
    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Write an MCAP metadata record (e.g. the scene when it becomes known)."""
        if not self.writer.closed:
            self.spool.add_metadata(name, data)

    def flush(self) -> None:
        """Write everything received so far and end the open chunk (waits for the spool)."""
        if not self.writer.closed:
            self.spool.flush()

    def stats(self) -> dict:
        """Counters for diagnostics: received, lost in DDS, spool FIFO and back-pressure."""
        st = self.spool.stats
        return {'recorder_received': sum(self.received.values()),
                'recorder_lost_in_dds': sum(self.lost.values()),
                'recorder_queue': st.queued, 'recorder_queue_max': st.max_queued,
                'recorder_queue_max_mb': round(st.max_queued_bytes / 1e6, 3),
                'recorder_blocked_s': round(st.blocked_s, 3),
                'recorder_not_written': self.spool.not_written,
                'recorder_consumer_errors': self.spool.consumer_errors}

    def summary(self) -> str:
        """One line for the log at exit: counts per topic, losses, FIFO high water."""
        import json
        st = self.spool.stats
        return ('recorder counts: ' + json.dumps(
            {'received': self.received, 'lost_in_dds': self.lost,
             'queue_max': st.max_queued, 'queue_max_bytes': st.max_queued_bytes,
             'blocked_s': round(st.blocked_s, 3), 'blocks': st.blocks,
             'not_written': self.spool.not_written,
             'consumer_errors': self.spool.consumer_errors,
             'first_consumer_error': self.spool.consumer_error}))

    def _fail(self, err) -> None:
        """Stop writing after a failed write (disk full, ...) and say so loudly, once."""
        if self.failed:
            return
        self.failed = err if isinstance(err, str) else (
            f'recording stopped after {sum(self.received.values())} messages: cannot write '
            f'{self.path}: {getattr(err, "strerror", None) or err}')
        self.node.get_logger().error(self.failed)
        if self.on_error is not None:
            self.on_error(self.failed)

    @property
    def not_written(self) -> int:
        """Messages received after a failed write (not in the bag)."""
        return self.spool.not_written

    def drain(self, settle: float = SETTLE_S) -> None:
        """Stop receiving: take what DDS still holds, wait until the spool wrote it all.

        Afterwards ``on_message`` has seen every received message. Idempotent.

        A Ctrl-C (``ros2 launch``, a terminal) stops the recorder and the simulator at the
        same moment; the simulator publishes until its loop stops and then waits for its
        last messages to be acknowledged. So the receiving goes on until no other node
        publishes any of the recorded topics any more (the simulator destroyed its
        publishers), for at most ``settle`` seconds: the bag then holds everything the
        simulator sent.
        """
        if self._thread is None:
            return
        end = time.monotonic() + settle
        while self._thread.is_alive() and time.monotonic() < end and self._others_publish():
            time.sleep(0.02)
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()
        self._thread = None
        try:
            while self.receive_once():
                pass
            self._poll_lost()
        except Exception:       # noqa: B902 -- context already shut down
            pass
        for ev in self._events.values():
            ev.destroy_when_not_in_use()
        self._rx.destroy_node()
        if not self.writer.closed:
            self.spool.flush()
        self.node.get_logger().info(self.summary())

    def _others_publish(self) -> bool:
        """Return whether a node other than the owner publishes a recorded topic."""
        own = (self.node.get_name(), self.node.get_namespace())
        try:
            return any((i.node_name, i.node_namespace) != own
                       for name, _ in self._subs
                       for i in self._rx.get_publishers_info_by_topic(name))
        except Exception:       # noqa: B902 -- context already shut down
            return False

    def close(self) -> None:
        """Drain (:meth:`drain`), then finalize the bag (summary, footer, metadata.yaml).

        Idempotent.

        Raises
        ------
        BagError
            If writing failed during the recording or at close (the bag is then
            incomplete; ``gyro-rotor recover`` salvages what reached the disk).
        """
        self.drain()
        try:
            self.spool.close()
        except BagError:
            if not self.failed:
                raise
        if self.failed:
            raise BagError(f'{self.failed}; {self.not_written} messages not recorded')


def _never(*_args) -> None:
    """Subscription callback never called: the receiving thread takes the messages."""
