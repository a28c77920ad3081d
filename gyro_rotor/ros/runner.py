"""The one ``main()`` of the package's nodes: start, spin, stop on a signal, tear down.

rclpy's own signal handlers would shut the context down under a running callback (whose
next publish then fails); instead SIGINT and SIGTERM both raise KeyboardInterrupt in the
main thread, between callbacks or inside one, and the node is torn down here: its
``on_shutdown()`` if it has one (last words while the context is still up), then
``destroy_node()``. Errors a user can cause (a bad parameter, an unreadable scene, an
unwritable output directory, malformed ``--ros-args``) end in one ``ERROR:`` line on
stderr and exit status 1, never in a traceback.
"""

from __future__ import annotations

import signal
import sys
from typing import Callable

from gyro_rotor.errors import GyroRotorError
import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

__all__ = ['run_node']


def _raise_interrupt(signum, frame):
    raise KeyboardInterrupt


def _error(err: BaseException) -> int:
    text = str(err).splitlines()[0] if str(err) else type(err).__name__
    text = text.split(', at /')[0]          # rcl appends its source locations
    print(f'ERROR: {text}', file=sys.stderr, flush=True)
    return 1


def run_node(make_node: Callable[[], Node], args: list[str] | None = None) -> int:
    """Run the node that ``make_node()`` builds until SIGINT/SIGTERM; return the exit status."""
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except RuntimeError as err:            # rcl's refusal of malformed --ros-args
        return _error(err)
    previous = {sig: signal.signal(sig, _raise_interrupt)
                for sig in (signal.SIGINT, signal.SIGTERM)}
    node = None
    status = 0
    try:
        node = make_node()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (GyroRotorError, ParameterException) as err:
        status = _error(err)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, signal.SIG_IGN if handler is None else handler)
        if node is not None:
            status = max(status, _teardown(node))
        rclpy.try_shutdown()
    return status


def _teardown(node: Node) -> int:
    try:
        if hasattr(node, 'on_shutdown'):
            node.on_shutdown()
        node.destroy_node()
    except GyroRotorError as err:
        return _error(err)
    return 0
