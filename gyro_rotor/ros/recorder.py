"""Recording of the simulation topics into a rosbag2 (MCAP) bag: the ROS side of bagio.

:class:`BagRecorder` attaches to a node. For every topic it creates one ``raw=True``
subscription (RELIABLE, KEEP_ALL, VOLATILE; KEEP_LAST ``depth`` TRANSIENT_LOCAL for the
latched ``~/scene`` document), so the bag holds the serialized bytes exactly as received, never
re-encoded. A topic's channel is registered at its first message, with the QoS profiles its
publishers offer and the type hash they announce (``Node.get_publishers_info_by_topic``),
as ``ros2 bag record`` does;
``log_time`` is the receive time (when the recorder took the message, wall clock) and
``publish_time`` the publisher's DDS source timestamp (both ns since the epoch, this host's
clock); the simulation time is only in the messages (stamps, ``/clock``). Each callback
drains its subscription (up to ``DRAIN_MAX`` messages), which the executor's per-callback
cost makes necessary at 1000 Hz. A timer flushes the open chunk every ``flush_period`` seconds
and the writer ends a chunk at least every ``flush_period`` while messages arrive, so a
killed recorder loses at most about a second.

Each received message may also be handed to a callback (``on_message(topic, data)``) so
that the analysis uses the very bytes that were recorded.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path
import shutil
import time
from typing import Callable, Mapping

from gyro_rotor.bag.bagio import BagWriter, normalize_qos, qos_profile_dict
from gyro_rotor.bag.wire import sim_topics
from gyro_rotor.errors import BagError
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = ['BagRecorder', 'sim_topics', 'default_bag_path', 'check_writable', 'DRAIN_MAX',
           'MIN_FREE_BYTES']

#: free space check_writable requires [bytes] (about a minute at 1000 Hz)
MIN_FREE_BYTES = 32 * 1024 * 1024
#: most messages one callback takes from its subscription beyond the one it was given
DRAIN_MAX = 200


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
        ``on_message(resolved_topic, data)`` for every received message.
    latched : iterable of str
        Topics to subscribe TRANSIENT_LOCAL (latched documents).
    compression : {'none', 'zstd', 'lz4'}
        MCAP chunk compression (rosbag2 writes none by default).
    on_error : callable, optional
        ``on_error(text)`` once when a write fails (disk full, I/O error): recording then
        stops, ``on_message`` still gets every message, and :meth:`close` raises.
    """

    def __init__(self, node: Node, path: str | os.PathLike, topics: Mapping[str, str], *,
                 metadata: Mapping[str, Mapping[str, str]] | None = None, depth: int = 1000,
                 flush_period: float = 0.5,
                 on_message: Callable[[str, bytes], None] | None = None,
                 latched: tuple = (), compression: str = 'none',
                 on_error: Callable[[str], None] | None = None):
        self.node = node
        self.path = Path(path)
        self.on_message = on_message
        self.writer = BagWriter(self.path, flush_interval_s=flush_period, metadata=metadata,
                                compression=compression)
        self.received: dict[str, int] = {}
        #: why recording stopped (a failed write), None while all is well
        self.failed: str | None = None
        #: messages received after a failed write (not in the bag)
        self.not_written = 0
        self.on_error = on_error
        self._types: dict[str, str] = {}
        #: per recorded topic: whether its type hash came from the graph
        self.graph_hashes: dict[str, bool] = {}
        self._subs = []
        self._sub_of: dict = {}
        self.drain_max = DRAIN_MAX
        latched_names = {node.resolve_topic_name(t) for t in latched}
        for topic, type_name in topics.items():
            name = node.resolve_topic_name(topic)
            self._types[name] = type_name
            latched_topic = name in latched_names
            keep_all = depth > 0 and not latched_topic
            qos = QoSProfile(history=(HistoryPolicy.KEEP_ALL if keep_all
                                      else HistoryPolicy.KEEP_LAST),
                             depth=depth or 1000,
                             reliability=ReliabilityPolicy.RELIABLE,
                             durability=(DurabilityPolicy.TRANSIENT_LOCAL
                                         if latched_topic
                                         else DurabilityPolicy.VOLATILE))
            sub = node.create_subscription(
                _import_type(type_name), name, functools.partial(self._on_raw, name), qos,
                raw=True)
            self._subs.append(sub)
            self._sub_of[name] = sub
        self._timer = node.create_timer(flush_period, self.flush)

    def _add_topic(self, topic: str) -> None:
        """Register ``topic`` at its first message with what its publishers offer.

        As ``ros2 bag record``: the offered QoS profiles and the ``topic_type_hash`` come from
        the graph (``get_publishers_info_by_topic``); the hash falls back to the installed
        type description when no publisher offers a valid one.
        """
        infos = self.node.get_publishers_info_by_topic(topic)
        profiles = [normalize_qos(i.qos_profile)[0] for i in infos] or [qos_profile_dict()]
        hashes = {str(i.topic_type_hash) for i in infos
                  if getattr(i, 'topic_type_hash', None) is not None}
        hashes.discard('INVALID')
        digest = hashes.pop() if len(hashes) == 1 else None
        self.writer.add_topic(topic, self._types[topic], profiles, topic_type_hash=digest)
        self.received[topic] = 0
        self.graph_hashes[topic] = digest is not None

    def _on_raw(self, topic: str, data: bytes, info) -> None:
        """Record a message, then take and record what else is queued on the topic.

        ``info`` has no default, so that rclpy passes the MessageInfo (with the DDS source
        timestamp, the bag's ``publish_time``).

        The executor costs far more per callback than a take does, so each callback drains
        up to ``drain_max`` further messages of its subscription itself.
        """
        self._record(topic, data, info)
        sub = self._sub_of.get(topic)
        if sub is None:
            return
        for _ in range(self.drain_max):
            if self.writer.closed:
                return
            try:
                with sub.handle:
                    got = sub.handle.take_message(sub.msg_type, sub.raw)
            except Exception:   # noqa: B902 -- a destroyed handle (shutdown): stop draining
                return
            if got is None:
                return
            self._record(topic, got[0], got[1])

    def _record(self, topic: str, data: bytes, info=None) -> None:
        now = time.time_ns()
        if self.writer.closed:
            return
        if self.failed:
            self.not_written += 1
        else:
            # rclpy gives the MessageInfo as a dict (source_timestamp: the DDS send time)
            publish = info.get('source_timestamp') if type(info) is dict else None
            try:
                if topic not in self.received:
                    self._add_topic(topic)
                self.writer.write(topic, data, now, publish if publish and publish > 0 else now)
                self.received[topic] += 1
            except (OSError, BagError) as err:
                self._fail(err)
                self.not_written += 1
        if self.on_message is not None:
            self.on_message(topic, data)

    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Write an MCAP metadata record (e.g. the scene when it becomes known)."""
        if not self.writer.closed:
            self.writer.add_metadata(name, data)

    def flush(self) -> None:
        """End the open chunk and write it (timer callback)."""
        if not self.writer.closed and not self.failed:
            try:
                self.writer.flush()
            except (OSError, BagError) as err:
                self._fail(err)

    def _fail(self, err: Exception) -> None:
        """Stop writing after a failed write (disk full, ...) and say so loudly, once."""
        if self.failed:
            return
        total = sum(self.received.values())
        self.failed = (f'recording stopped after {total} messages: cannot write {self.path}: '
                       f'{getattr(err, "strerror", None) or err}')
        self.node.get_logger().error(self.failed)
        if self.on_error is not None:
            self.on_error(self.failed)

    def close(self) -> None:
        """Finalize the bag (summary, footer, metadata.yaml); idempotent.

        Raises
        ------
        BagError
            If writing failed during the recording or at close (the bag is then
            incomplete; ``gyro-rotor recover`` salvages what reached the disk).
        """
        if self._timer is not None:
            self.node.destroy_timer(self._timer)
            self._timer = None
        if not self.writer.closed:
            try:
                self.writer.close()
            except (OSError, BagError) as err:
                self._fail(err)
        if self.failed:
            raise BagError(f'{self.failed}; {self.not_written} messages not recorded')
