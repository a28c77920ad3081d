"""``gyro-rotor monitor``: ``ros2 topic hz`` and ``echo`` together for the rotor topics.

Subscribes (raw, best effort, so that it never slows a publisher) to every topic of a
running gyro_rotor system, however it was started, and prints once a second: the rate
and jitter per topic, missing sequence numbers of ``energy``, the latest E*, dE*/dt,
residual and z, the latest joint positions by name (a general system's coordinates and
rotor lags z_ROTOR), the latest diagnostics of each node and the analysis verdict.
"""

from __future__ import annotations

import argparse
import importlib
import math
import sys
import time

from gyro_rotor.bag.wire import array_labels
from gyro_rotor.errors import ParameterError
from gyro_rotor.tools.monitor import array_values, TopicStats

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
        self.node = node
        self.namespace = namespace if namespace.endswith('/') else namespace + '/'
        self.stats: dict[str, TopicStats] = {}
        self.subs = {}
        self.latest: dict[str, object] = {}
        self.diag: dict[str, tuple[str, str]] = {}

    def discover(self) -> None:
        """Subscribe to new topics of the graph."""
        from gyro_rotor.ros.qos import profile
        # best effort matches every publisher and never slows one down; a deep queue keeps
        # the monitor from dropping what it is slow to take
        qos = profile('monitor')
        for topic, types in self.node.get_topic_names_and_types():
            if topic in self.subs or topic in _SKIP or not types:
                continue
            if not (topic.startswith(self.namespace) or topic in ('/diagnostics', '/clock')):
                continue
            cls = _message_class(types[0])
            if cls is None:
                continue
            self.stats[topic] = TopicStats(topic, types[0])
            self.subs[topic] = self.node.create_subscription(
                cls, topic, self._callback(topic, cls), qos, raw=True)

    def _callback(self, topic: str, cls):
        from rclpy.serialization import deserialize_message

        def cb(data: bytes) -> None:
            seq = None
            name = cls.__name__
            if name in ('Float64MultiArray', 'DiagnosticArray', 'String', 'JointState'):
                msg = deserialize_message(data, cls)
                if name == 'JointState':      # the joints by name: a general system's too
                    self.latest[topic] = dict(zip(msg.name, msg.position))
                elif name == 'Float64MultiArray' and msg.layout.dim:
                    values = array_values(array_labels(msg.layout.dim), msg.data)
                    self.latest[topic] = values
                    if 'seq' in values:
                        seq = int(values['seq'])
                elif name == 'DiagnosticArray':
                    for st in msg.status:
                        level = st.level[0] if isinstance(st.level, bytes) else int(st.level)
                        self.diag[st.name] = (_LEVEL.get(level, str(level)), st.message)
                else:
                    self.latest[topic] = msg.data
            self.stats[topic].add(time.monotonic(), len(data), seq)
        return cb

    def render(self) -> str:
        """Render the current table as text."""
        now = time.monotonic()
        lines = [f'{"topic":32s} {"type":36s} {"count":>8s} {"Hz":>8s} {"jitter ms":>9s} '
                 f'{"lost":>5s}']
        for topic in sorted(self.stats):
            s = self.stats[topic]
            rate, jit = s.rate(now), s.jitter()
            lines.append(f'{topic:32s} {s.type_name:36s} {s.count:8d} '
                         f'{"-" if math.isnan(rate) else f"{rate:8.1f}":>8s} '
                         f'{"-" if math.isnan(jit) else f"{1e3 * jit:9.2f}":>9s} '
                         f'{s.gaps if s.last_seq is not None else "-":>5}')
        for topic, values in sorted(self.latest.items()):
            lines += _value_lines(topic, values)
        for name, (level, message) in sorted(self.diag.items()):
            lines.append(f'[{level}] {name}: {message}')
        if not self.stats:
            lines.append('(no rotor topics yet: is rotor_sim running in this ROS domain?)')
        return '\n'.join(lines)


_KEYS = ('t_sim', 'E_star', 'dE_dt', 'residual', 'z', 'zdot')


def _value_lines(topic: str, values) -> list[str]:
    """Lines of the latest values of a topic (a row per mode for a 2-D array)."""
    if not isinstance(values, dict):
        return [f'{topic}: {values}']
    if values and all(isinstance(v, dict) for v in values.values()):
        return [f'{topic} {row}: ' + ', '.join(f'{k} {v:.6g}' for k, v in cols.items())
                for row, cols in values.items()]
    keys = [k for k in _KEYS if k in values] or list(values)[:8]
    return [f'{topic}: ' + ', '.join(f'{k} {values[k]:.6g}' for k in keys)]


def run(args: argparse.Namespace) -> int:
    """Spin a monitoring node and print the table every period."""
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from gyro_rotor.cli.util import check_number
    check_number('--period', args.period, low=0.0, low_open=True, what='[s]')
    check_number('--duration', args.duration, low=0.0, what='[s] (0 = until Ctrl-C)')
    if args.domain_id is not None and not 0 <= args.domain_id <= 232:
        raise ParameterError(f'--domain-id must be in 0..232, got {args.domain_id}')
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
        while context.ok():
            mon.discover()
            ex.spin_once(timeout_sec=0.05)
            now = time.monotonic()
            if now >= next_print:
                next_print += args.period
                text = mon.render()
                print(('\x1b[2J\x1b[H' if tty else '') + text + ('' if tty else '\n'),
                      flush=True)
            if args.duration and now - t0 >= args.duration:
                break
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        ex.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    return 0
