"""The one ``main()`` of the package's nodes: start, spin, stop on a signal, tear down.

**Signals.** rclpy's own signal handlers would shut the context down under a running
callback (whose next publish then fails), and Python's default SIGINT handler raises
KeyboardInterrupt wherever the main thread happens to be. Here SIGINT and SIGTERM only
*ask* for a stop (:class:`gyro_rotor.signals.StopSignals`): the first one ends the spin
loop at the next callback boundary (a thread woken by the signal through
:func:`signal.set_wakeup_fd` triggers a guard condition of the node, so the main thread
can wait for work without a polling timeout that would wake it, and take the GIL from
rotor_sim's real-time loop, several times a second), then the node is torn down: its
``on_shutdown()`` if it has one (last words while the context is still up), then
``destroy_node()`` (the recorder finalizes its bag there). Every further SIGINT or SIGTERM
until the end of the teardown is counted and ignored: a terminal's Ctrl-C reaches each
node twice under ``ros2 launch`` (once from the process group, once forwarded by launch),
and launch sends SIGTERM if a node is still running after its ``sigterm_timeout``; none of
them may cut the teardown short, or the bag is lost and launch reports "process has died".
After the teardown the two signals stay ignored for the rest of the process (its
interpreter's finalization: Python would reset a handler of its own to the default action
there, and a late forwarded SIGINT would kill the process, exit status -2): everything is
written by then. However the signals arrive, the exit status is 0 and there is no
traceback. In-process (tests), ``run_node(..., restore_signals=True)`` puts the previous
handlers back instead.

**Started by launch.** The upstream ``ros2 launch`` of Jazzy dies at once on a SIGTERM of
its own (ros2/launch#666): its nodes are orphaned and would run (and record) on. A node
whose parent process is a launch process therefore asks the kernel for a SIGTERM when
that parent dies (``PR_SET_PDEATHSIG``, Linux), and stops as on any SIGTERM. (Only under
launch: a node started from a shell, e.g. with ``nohup``, is left alone.)

**BLAS on one thread.** numpy's OpenBLAS starts one thread per core, and they spin between
calls. In a node that is the worst of both: rotor_analysis judges a window with small
matrix products (:mod:`~gyro_rotor.analysis.decay`), which a second thread only slows down
(44 ms a window on one thread against 82-102 ms on two, with one other busy process on the
2-core machine), and the spinning threads take the cores from rotor_sim's real-time loop.
``run_node`` therefore limits BLAS to one thread in the node's process
(``threadpoolctl``), and puts the previous limit back when the node is done.

Errors a user can cause (a bad parameter, an unreadable scene, an unwritable output
directory, malformed ``--ros-args``) end in one ``ERROR:`` line on stderr and exit status
1, never in a traceback.
"""

from __future__ import annotations

import math
import os
import signal
import sys
import time
from typing import Callable

from gyro_rotor.errors import GyroRotorError
from gyro_rotor.signals import StopSignals
import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from threadpoolctl import threadpool_limits

__all__ = ['run_node', 'spin_for', 'SPIN_TIMEOUT', 'exit_with_parent', 'parent_is_launch']

#: longest wait of one spin of the executor [s] (a stop signal wakes it at once)
SPIN_TIMEOUT = 2.0


def _error(err: BaseException) -> int:
    text = str(err).splitlines()[0] if str(err) else type(err).__name__
    text = text.split(', at /')[0]          # rcl appends its source locations
    print(f'ERROR: {text}', file=sys.stderr, flush=True)
    return 1


def parent_is_launch() -> bool:
    """Return whether the parent process is a launch process (``ros2 launch ...``)."""
    try:
        with open(f'/proc/{os.getppid()}/cmdline', 'rb') as f:
            argv = f.read().decode(errors='replace').split('\0')
    except OSError:
        return False
    return any(a == 'launch' or os.path.basename(a).startswith(('launch', 'ros2-launch'))
               for a in argv[:3])


def exit_with_parent(sig: int = signal.SIGTERM) -> bool:
    """Have the kernel send ``sig`` to this process when its parent dies (Linux); success."""
    if not sys.platform.startswith('linux'):
        return False
    import ctypes
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(1, ctypes.c_ulong(int(sig)), 0, 0, 0) != 0:     # PR_SET_PDEATHSIG
            return False
    except (OSError, AttributeError):
        return False
    return True


def run_node(make_node: Callable[[], Node], args: list[str] | None = None, *,
             restore_signals: bool = False) -> int:
    """Run the node that ``make_node()`` builds until SIGINT/SIGTERM; return the exit status.

    A process's ``main()``: SIGINT and SIGTERM stay ignored afterwards (module doc), unless
    ``restore_signals``. Under launch, the death of the launch process is a SIGTERM. BLAS
    runs on one thread while the node runs (module doc).
    """
    guard: list = []
    stop = StopSignals().install(wake=lambda: guard and guard[0].trigger())
    if not restore_signals and parent_is_launch() and exit_with_parent():
        if not parent_is_launch():          # the parent died before the request
            stop(signal.SIGTERM, None)
    try:
        with threadpool_limits(limits=1, user_api='blas'):
            return _run(make_node, args, stop, guard)
    finally:
        stop.restore(ignore=not restore_signals)


def spin_for(executor, seconds: float, signals: StopSignals | None = None,
             step: float = SPIN_TIMEOUT) -> None:
    """Spin ``executor`` for about ``seconds``; raise ``Stopped`` once ``signals`` has a request.

    ``seconds`` may be ``math.inf``: a node's main loop (:func:`run_node`) spins until the
    request.

    Each spin waits for work for at most ``step`` s. The request is checked between two
    spins, never inside one (the handler only records the signal): it is acted on within
    ``step``, or at once where the signals' waker triggers a guard condition of the
    executor's node (as in :func:`run_node`).
    """
    end = time.monotonic() + seconds
    while True:
        if signals is not None:
            signals.check()
        rest = end - time.monotonic()
        if rest <= 0:
            return
        executor.spin_once(timeout_sec=min(step, rest))


def _run(make_node: Callable[[], Node], args: list[str] | None, stop: StopSignals,
         holder: list) -> int:
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except RuntimeError as err:            # rcl's refusal of malformed --ros-args
        return _error(err)
    node = executor = None
    status = 0
    try:
        node = make_node()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        # a signal triggers it: its (empty) callback ends the executor's wait
        holder.append(node.create_guard_condition(lambda: None))
        spin_for(executor, math.inf, stop)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (GyroRotorError, ParameterException) as err:
        status = _error(err)
    finally:
        holder.clear()
        if executor is not None:
            executor.shutdown(timeout_sec=0)
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
