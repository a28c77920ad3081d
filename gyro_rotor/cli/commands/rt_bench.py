"""``gyro-rotor rt-bench``: real-time factor and tick timing of the rotor_sim node.

Runs :class:`~gyro_rotor.ros.sim_node.RotorSimNode` in this process (its own ROS context, a
SingleThreadedExecutor for services and parameters, the node's own real-time loop thread,
all topics published as in operation) for a few wall seconds per scene and real-time
factor, and prints what it measured:

* the achieved real-time factor: simulated time over wall time between the deadlines of
  the ticks at the window's two ends (so a stall at the very end of the window, caught up
  by the next tick, does not count as time lost; lost time shows as the pacer's capped or
  cut ticks);
* **tick lateness**: when each tick woke minus its absolute deadline (p50, p99, max), and
  when its samples were published minus the deadline (p99, max);
* **late** deadlines: those whose samples went out more than one period after them
  (skipped deadlines included: no sample is lost, but they are late), every one counted;
* the intervals between ticks (mean, p99, max), the mean work of a tick and the ticks
  whose work overran the period;
* the 1-minute load average at the end of each run (the machine may be shared) and the
  scheduling the loop thread got (SCHED_FIFO if the process may raise its priority, the
  process' other threads then SCHED_FIFO at a lower priority);
* per rate, a **reference** row: a thread of the same scheduling that only sleeps to the
  same deadlines (no integration, no ROS), measured right after: the lateness that the
  machine itself (kernel, other processes, a virtual machine's host) adds.

A benchmark, not a test: the figures depend on the machine and on what else runs on it.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
import time

from gyro_rotor.signals import StopSignals

HELP = "measure the simulation node's achieved real-time factor and tick lateness"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``rt-bench``."""
    p.add_argument('--scenes', nargs='+', default=['precession', 'fast_spin'],
                   help='scenes to run (default: precession fast_spin)')
    p.add_argument('--rtf', nargs='+', type=float, default=[1.0],
                   help='real-time factors (0 = as fast as possible; default: 1)')
    p.add_argument('--duration', type=float, default=10.0, help='wall seconds per run')
    p.add_argument('--publish-rate', nargs='+', type=float, default=[250.0, 1000.0],
                   help='publish rates [Hz] (default: 250 1000)')
    p.add_argument('--integrator', default='auto', help='integration method')
    p.add_argument('--realtime-priority', type=int, default=None,
                   help='SCHED_FIFO priority of the loop thread (0: normal scheduling; '
                        "default: the node's)")
    p.add_argument('--no-reference', action='store_true',
                   help='leave out the reference rows (a thread that only sleeps)')
    p.add_argument('--note', default='', help='a line printed under the table (conditions)')
    p.add_argument('--out', type=Path, default=None,
                   help='also append the table to this file (markdown)')


def bench_one(scene: str, rtf: float, duration: float, publish_rate: float,
              integrator: str = 'auto', realtime_priority: int | None = None,
              signals: StopSignals | None = None, wake: list | None = None) -> dict:
    """Run the node for ``duration`` wall seconds; return its figures.

    ``signals``: a stop request checked between two spins (``Stopped`` ends the run);
    ``wake``: the node's guard condition is on it while the node runs, for the signals'
    waker to end the executor's wait (as in rotor_sim's main()).
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from gyro_rotor.ros.runner import spin_for
    from gyro_rotor.ros.sim_node import RotorSimNode

    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    context = rclpy.context.Context()
    rclpy.init(context=context)
    overrides = [Parameter('scene', value=scene), Parameter('real_time_factor', value=float(rtf)),
                 Parameter('publish_rate', value=float(publish_rate)),
                 Parameter('integrator', value=integrator),
                 Parameter('diagnostics_period', value=3600.0)]
    if realtime_priority is not None:
        overrides.append(Parameter('realtime_priority', value=int(realtime_priority)))
    node = RotorSimNode(context=context, parameter_overrides=overrides, own_process=True)
    executor = SingleThreadedExecutor(context=context)
    guard = None
    try:
        if wake is not None:
            guard = node.create_guard_condition(lambda: None)
            wake.append(guard)
        executor.add_node(node)
        spin_for(executor, 1.0, signals)      # the loop starts, the first ticks settle
        with node.lock:                       # (between two ticks)
            node.pacer.take_window(node.tick_time or node._now())
        node.deadlines.take_window()
        spin_for(executor, duration, signals)
        with node.lock:
            w = node.pacer.take_window(node.tick_time or node._now())
        late = node.deadlines.take_window()
        return {'scene': scene, 'rtf': rtf, 'rate': publish_rate, 'wall': w.wall,
                'sim': w.sim, 'achieved_rtf': w.achieved_rtf, 'ticks': w.ticks,
                'samples': w.samples, 'interval_mean': w.interval_mean,
                'interval_p99': w.interval_p99, 'interval_max': w.interval_max,
                'busy_mean': w.busy_mean, 'overruns': w.overruns, 'capped': w.capped,
                'late': late, 'integrator': node.stepper.method, 'diverged': node.diverged,
                'scheduling': node.scheduling + ('' if node.scheduling_others == 'unchanged'
                                                 else f', others {node.scheduling_others}'),
                'load': os.getloadavg()[0]}
    finally:
        if guard is not None:
            wake.remove(guard)
        node.on_shutdown()
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)


def reference_one(rate: float, duration: float, realtime_priority: int | None = None,
                  signals: StopSignals | None = None) -> dict:
    """Sleep to deadlines at ``rate`` for ``duration`` s in a thread, doing nothing else.

    ``signals``: a stop request checked every 0.1 s (``Stopped`` ends the thread and the run).
    """
    import threading
    from gyro_rotor.numerics.realtime import (Deadlines, set_thread_priority,
                                              set_timer_slack)
    from gyro_rotor.ros.sim_node import DEFAULT_RT_PRIORITY
    prio = DEFAULT_RT_PRIORITY if realtime_priority is None else realtime_priority
    out = {}
    halt = threading.Event()

    def run():
        set_timer_slack(1)
        err = set_thread_priority(prio) if prio else None
        d = Deadlines(1.0 / rate)
        d.start()
        end = time.monotonic() + duration
        while time.monotonic() < end and not halt.is_set():
            d.wait()
            d.done()
        set_thread_priority(0)
        out['late'] = d.take_window()
        out['scheduling'] = f'SCHED_FIFO {prio}' if prio and err is None else 'SCHED_OTHER'

    t = threading.Thread(target=run)
    t.start()
    try:
        while t.is_alive():
            t.join(0.1)
            if signals is not None:
                signals.check()
    finally:
        halt.set()
        t.join()
    la = out['late']
    nan = float('nan')
    return {'scene': '(reference: sleep only)', 'rtf': 1.0, 'rate': rate, 'wall': duration,
            'sim': nan, 'achieved_rtf': nan, 'ticks': la.ticks, 'samples': 0,
            'interval_mean': nan, 'interval_p99': nan, 'interval_max': nan,
            'busy_mean': nan, 'overruns': 0, 'capped': 0, 'late': la, 'integrator': '-',
            'diverged': None, 'scheduling': out['scheduling'], 'load': os.getloadavg()[0]}


def _ms(x: float) -> str:
    return f'{1e3 * x:.3f}'


def table(rows: list[dict], duration: float) -> list[str]:
    """Return the markdown lines of the table of ``rows``."""
    lines = [f'rotor_sim real-time loop, {duration:g} s wall per run (cpu count '
             f'{os.cpu_count()}); lateness = wake-up minus deadline, published = samples '
             'out minus deadline; late = deadlines whose samples went out more than one '
             'period after them', '',
             '| scene | rate [Hz] | rtf | integrator | scheduling | achieved RTF | '
             'late p50 [ms] | late p99 [ms] | late max [ms] | published p99 [ms] | '
             'published max [ms] | late | interval p99 [ms] | interval max [ms] | '
             'busy mean [ms] | overruns | load avg |',
             '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|']
    for r in rows:
        la = r['late']
        paced = r['rtf'] > 0
        lines.append(
            f"| {r['scene']} | {r['rate']:g} | {r['rtf']:g} | {r['integrator']} | "
            f"{r['scheduling']} | {r['achieved_rtf']:.4f} | ".replace('nan', '-')
            + (f'{_ms(la.lateness_p50)} | {_ms(la.lateness_p99)} | {_ms(la.lateness_max)} | '
               f'{_ms(la.done_p99)} | {_ms(la.done_max)} | {la.late}/{la.ticks + la.skipped} | '
               if paced else '- | - | - | - | - | - | ')
            + f"{_ms(r['interval_p99'])} | {_ms(r['interval_max'])} | {_ms(r['busy_mean'])} | "
            f"{r['overruns']}/{r['ticks']} | {r['load']:.2f} |".replace('nan', '-')
            + (f" diverged: {r['diverged']}" if r['diverged'] else ''))
    return lines


def run(args: argparse.Namespace) -> int:
    """Run every (rate, scene, rtf) triple and print a table."""
    from gyro_rotor.cli.util import check_number
    from gyro_rotor.node_settings import NODE_RANGES
    check_number('--duration', args.duration, low=0.0, low_open=True, what='[s]')
    for rate in args.publish_rate:
        check_number('--publish-rate', rate, low=NODE_RANGES['publish_rate'][0],
                     high=NODE_RANGES['publish_rate'][1], what='[Hz]')
    for rtf in args.rtf:
        check_number('--rtf', rtf, low=NODE_RANGES['real_time_factor'][0],
                     high=NODE_RANGES['real_time_factor'][1])
    rows = []
    guards: list = []                       # the running node's, woken by a signal
    signals = StopSignals().install(wake=lambda: guards and guards[-1].trigger())
    try:                                    # a signal ends the run between two spins
        for rate in args.publish_rate:
            rows += [bench_one(s, r, args.duration, rate, args.integrator,
                               args.realtime_priority, signals, guards)
                     for s in args.scenes for r in args.rtf]
            if not args.no_reference:
                rows.append(reference_one(rate, args.duration, args.realtime_priority,
                                          signals))
    finally:
        signals.restore()
    lines = table(rows, args.duration)
    if args.note:
        lines += ['', args.note]
    text = '\n'.join(lines) + '\n'
    print(text, end='')
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        with open(args.out, 'a') as f:
            f.write(text + '\n')
    return 0
