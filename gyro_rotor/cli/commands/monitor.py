"""``gyro-rotor monitor``: ``ros2 topic hz`` and ``echo`` together for the rotor topics.

Subscribes (raw, best effort, so that it never slows a publisher) to every topic of a
running gyro_rotor system, however it was started, and prints once a second: the rate
and jitter per topic, the sequence numbers of ``energy`` it missed, the latest E*,
dE*/dt, residual and z, the latest joint positions by name (a general system's
coordinates and rotor lags z_ROTOR), the latest diagnostics of each node and the
analysis verdict.

Printed to a terminal, the screen is redrawn each period (a multi-line document such as
rotor_sim's ``~/scene`` as one summary line). Printed to a file or pipe, each period adds
only what changed: the topics that received messages, the values and diagnostics that
differ from the last print, a document when it is new or changed. Numbers that are not
results yet (NaN, e.g. before the analysis has its first window) are not printed. From
rotor_sim's ``~/scene`` the monitor knows the system: a general system publishes no 3-D
pose, so ``axis``, ``stator_pose`` and ``axis_marker`` are not listed with count 0.
"""

from __future__ import annotations

import argparse
import importlib
import math
import sys
import time

from gyro_rotor.errors import ParameterError
from gyro_rotor.signals import StopSignals
from gyro_rotor.tools.monitor import Changes, known_values, message_values, \
    system_from_joints, system_topics, TopicStats

HELP = 'monitor the rotor topics of a running system: rates, E*, residual, diagnostics'

_SKIP = ('/rosout', '/parameter_events')
_LEVEL = {0: 'OK', 1: 'WARN', 2: 'ERROR', 3: 'STALE'}


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``monitor``."""
    p.add_argument('--duration', type=float, default=0.0,
                   help='stop after this many seconds (default: until Ctrl-C)')
    p.add_argument('--period', type=float, default=1.0, help='print period [s]')
    p.add_argument('--domain-id', type=int, default=None,
                   help="ROS_DOMAIN_ID to join (default: the environment's)")
    p.add_argument('--namespace', default='/', help='only topics under this namespace')


def _message_class(type_name: str):
    pkg, _, name = type_name.partition('/msg/')
    try:
        return getattr(importlib.import_module(f'{pkg}.msg'), name)
    except (ImportError, AttributeError):
        return None


class Monitor:
    """The monitoring node's state: stats per topic and the latest decoded values."""

    def __init__(self, node, namespace: str = '/'):
        """Start with no topic; ``node`` subscribes (None in tests that feed callbacks)."""
        self.node = node
        self.namespace = namespace if namespace.endswith('/') else namespace + '/'
        self.stats: dict[str, TopicStats] = {}
        self.subs = {}
        self.latest: dict[str, object] = {}
        self.docs: dict[str, str] = {}
        self.diag: dict[str, tuple[str, str]] = {}
        #: what the scene document says about the system (None until it arrived)
        self.system: dict | None = None
        self.changes = Changes()
        self.t0 = time.monotonic()

    def discover(self) -> None:
        """Subscribe to new topics of the graph."""
        from gyro_rotor.ros.qos import profile
        from rclpy.qos import DurabilityPolicy
        # best effort matches every publisher and never slows one down; a deep queue keeps
        # the monitor from dropping what it is slow to take. A latched topic (the scene
        # document, the verdict) is read transient local: its one message arrives however
        # late the monitor joins
        qos, latched = profile('monitor'), profile('latched')
        for topic, types in self.node.get_topic_names_and_types():
            if topic in self.subs or topic in _SKIP or not types:
                continue
            if not (topic.startswith(self.namespace) or topic in ('/diagnostics', '/clock')):
                continue
            cls = _message_class(types[0])
            if cls is None:
                continue
            pubs = self.node.get_publishers_info_by_topic(topic)
            keep = any(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
                       for i in pubs)
            self.stats[topic] = TopicStats(topic, types[0])
            self.subs[topic] = self.node.create_subscription(
                cls, topic, self._callback(topic, cls), latched if keep else qos, raw=True)

    def _callback(self, topic: str, cls):
        from rclpy.serialization import deserialize_message

        def cb(data: bytes) -> None:
            seq = None
            name = cls.__name__
            if name in ('Float64MultiArray', 'DiagnosticArray', 'String', 'JointState'):
                msg = deserialize_message(data, cls)
                if name == 'JointState':      # the joints by name: a general system's too
                    self.latest[topic] = dict(zip(msg.name, msg.position))
                    if self.system is None:
                        self.system = system_from_joints(msg.name)
                elif name == 'Float64MultiArray' and msg.layout.dim:
                    values = message_values(msg)
                    self.latest[topic] = values
                    if 'seq' in values:
                        seq = int(values['seq'])
                elif name == 'DiagnosticArray':
                    for st in msg.status:
                        level = st.level[0] if isinstance(st.level, bytes) else int(st.level)
                        self.diag[st.name] = (_LEVEL.get(level, str(level)), st.message)
                elif '\n' in msg.data.strip():   # a document (rotor_sim's ~/scene)
                    self.docs[topic] = msg.data
                    info = system_topics(msg.data) if topic.endswith('/scene') else None
                    if info is not None:
                        self.system = info
                else:
                    self.latest[topic] = msg.data
            self.stats[topic].add(time.monotonic(), len(data), seq)
        return cb

    def hidden(self, topic: str) -> bool:
        """Return True for a topic the system never publishes (nothing arrived on it)."""
        return (self.system is not None and self.stats[topic].count == 0
                and topic.rsplit('/', 1)[-1] in self.system['absent'])

    def render(self, *, changed_only: bool = False, full_docs: bool = False) -> str:
        """Render the table as text: everything, or (``changed_only``) what changed.

        ``full_docs``: a document in full (else one summary line).
        """
        now = time.monotonic()
        sy = self.system or {}
        out = [f'monitor {now - self.t0:.0f} s'
               + (f': scene {sy["scene"]}' if sy.get('scene') else '')
               + (f', system {sy["system"]}' if sy else '')]
        rows, missed = [], False
        silent = [t for t in sorted(self.stats)
                  if self.stats[t].count == 0 and not self.hidden(t)]
        for topic in sorted(self.stats):
            s = self.stats[topic]
            if self.hidden(topic) or topic in silent:
                continue
            state = f'{s.count} {s.gaps}'
            if not self.changes.changed(f'row {topic}', state) and changed_only:
                continue
            rate, jit = s.rate(now), s.jitter()
            missed |= s.gaps > 0
            rows.append(f'{topic:32s} {s.type_name:36s} {s.count:8d} '
                        f'{"-" if math.isnan(rate) else f"{rate:8.1f}":>8s} '
                        f'{"-" if math.isnan(jit) else f"{1e3 * jit:9.2f}":>9s} '
                        f'{s.gaps if s.last_seq is not None else "-":>6}')
        if rows:
            out.append(f'{"topic":32s} {"type":36s} {"count":>8s} {"Hz":>8s} {"jitter ms":>9s} '
                       f'{"missed":>6s}')
            out += rows
        if silent:
            line = f'no message yet on {", ".join(silent)}'
            if self.changes.changed('silent', line) or not changed_only:
                out.append(line)
        for topic, values in sorted(self.latest.items()):
            for line in _value_lines(topic, values):
                key = line.split(': ', 1)[0]
                if self.changes.changed(f'value {key}', line) or not changed_only:
                    out.append(line)
        for topic, text in sorted(self.docs.items()):
            new = self.changes.changed(f'doc {topic}', text)
            if full_docs and (new or not changed_only):
                out.append(f'{topic} ({len(text.splitlines())} lines):')
                out += ['  ' + ln for ln in text.rstrip().splitlines()]
            elif new or not changed_only:
                out.append(f'{topic}: a {len(text.splitlines())}-line document'
                           + (' (new)' if new else '') + f'; `ros2 topic echo --once {topic}`'
                           ' prints it')
        for name, (level, message) in sorted(self.diag.items()):
            line = f'[{level}] {name}: {message}'
            if self.changes.changed(f'diag {name}', line) or not changed_only:
                out.append(line)
        out += self._notes(missed, changed_only)
        if not self.stats:
            out.append('(no rotor topics yet: is rotor_sim running in this ROS domain?)')
        elif changed_only and len(out) == 1:
            out.append('(nothing changed)')
        return '\n'.join(out)

    def _notes(self, missed: bool, changed_only: bool) -> list:
        notes = []
        hidden = [t for t in sorted(self.stats) if self.hidden(t)]
        if hidden:
            notes.append(f'({self.system["system"]} publishes no 3-D pose: '
                         f'{", ".join(hidden)} not listed)')
        if missed:
            notes.append('(missed: sequence numbers this monitor did not receive; it '
                         'subscribes best effort so as never to slow the simulation, a '
                         'recorder subscribes reliably and keeps them)')
        return [n for n in notes if self.changes.changed(f'note {n}', n) or not changed_only]


_KEYS = ('t_sim', 'E_star', 'dE_dt', 'residual', 'z', 'zdot')


def _value_lines(topic: str, values) -> list[str]:
    """Lines of the latest values of a topic (a row per mode for a 2-D array).

    NaN is not a value yet (the analysis before its first window): such numbers are left
    out, and a topic with nothing else says so.
    """
    if not isinstance(values, dict):
        return [f'{topic}: {values}']
    known = known_values(values)
    if not known:
        return [f'{topic}: no result yet'] if values else []
    if all(isinstance(v, dict) for v in values.values()):
        return [f'{topic} {row}: ' + ', '.join(f'{k} {v:.6g}' for k, v in cols.items())
                for row, cols in known.items()]
    keys = [k for k in _KEYS if k in known] or list(known)[:8]
    return [f'{topic}: ' + ', '.join(f'{k} {known[k]:.6g}' for k in keys)]


def _namespace(namespace: str) -> str:
    """Return ``namespace`` made absolute; refuse one that is not a valid ROS namespace."""
    from rclpy.exceptions import InvalidNamespaceException
    from rclpy.validate_namespace import validate_namespace
    ns = '/' + namespace.strip('/')
    try:
        validate_namespace(ns)
    except InvalidNamespaceException as err:
        reason = str(err).splitlines()[0].removeprefix('Invalid namespace: ').rstrip(':')
        raise ParameterError(f'--namespace {namespace!r} is not a ROS namespace: {reason}'
                             ) from None
    return ns


def run(args: argparse.Namespace) -> int:
    """Spin a monitoring node and print the table every period."""
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from gyro_rotor.cli.util import check_number
    check_number('--period', args.period, low=0.0, low_open=True, what='[s]')
    check_number('--duration', args.duration, low=0.0, what='[s] (0 = until Ctrl-C)')
    if args.domain_id is not None and not 0 <= args.domain_id <= 232:
        raise ParameterError(f'--domain-id must be in 0..232, got {args.domain_id}')
    args.namespace = _namespace(args.namespace)
    # Ctrl-C (or SIGTERM) asks the loop to stop, its normal end (exit status 0)
    stop = StopSignals()
    context = rclpy.context.Context()
    kwargs = {} if args.domain_id is None else {'domain_id': args.domain_id}
    rclpy.init(context=context, **kwargs)
    node = rclpy.create_node('gyro_rotor_monitor', context=context)
    ex = SingleThreadedExecutor(context=context)
    ex.add_node(node)
    mon = Monitor(node, args.namespace)
    t0 = time.monotonic()
    next_print = t0 + args.period
    tty = sys.stdout.isatty()
    try:
        stop.install()
        while context.ok() and not stop.requested:
            mon.discover()
            ex.spin_once(timeout_sec=0.05)
            now = time.monotonic()
            if now >= next_print:
                next_print += args.period
                if tty:         # the screen redrawn: everything, documents in one line
                    print('\x1b[2J\x1b[H' + mon.render(), flush=True)
                else:           # a log: only what changed, documents in full when new
                    print(mon.render(changed_only=True, full_docs=True) + '\n', flush=True)
            if args.duration and now - t0 >= args.duration:
                break
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        ex.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        stop.restore()
    return 0
