"""``gyro-rotor rt-bench``: achieved real-time factor and tick jitter of the rotor_sim node.

Runs :class:`~gyro_rotor.ros.sim_node.RotorSimNode` in this process (its own ROS context, a
SingleThreadedExecutor, all topics published as in operation) for a few wall seconds per
scene and real-time factor, and prints what its pacer measured: simulated over wall time,
the timer-tick intervals (mean, standard deviation = jitter, 99th percentile, maximum),
ticks whose work overran the period and ticks whose catch-up was capped.
"""

from __future__ import annotations

import argparse
import os
import time

HELP = "measure the simulation node's achieved real-time factor and tick jitter"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``rt-bench``."""
    p.add_argument('--scenes', nargs='+', default=['precession', 'fast_spin'],
                   help='scenes to run (default: precession fast_spin)')
    p.add_argument('--rtf', nargs='+', type=float, default=[1.0, 0.0],
                   help='real-time factors (0 = as fast as possible; default: 1 0)')
    p.add_argument('--duration', type=float, default=5.0, help='wall seconds per run')
    p.add_argument('--publish-rate', type=float, default=250.0, help='publish rate [Hz]')
    p.add_argument('--integrator', default='auto', help='integration method')


def bench_one(scene: str, rtf: float, duration: float, publish_rate: float,
              integrator: str = 'auto') -> dict:
    """Run the node for ``duration`` wall seconds; return the pacer's figures."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from gyro_rotor.ros.sim_node import RotorSimNode

    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    context = rclpy.context.Context()
    rclpy.init(context=context)
    node = RotorSimNode(context=context, parameter_overrides=[
        Parameter('scene', value=scene), Parameter('real_time_factor', value=float(rtf)),
        Parameter('publish_rate', value=float(publish_rate)),
        Parameter('integrator', value=integrator),
        Parameter('diagnostics_period', value=3600.0)])
    try:
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        executor.spin_once(timeout_sec=0.1)           # first tick anchors the time base
        node.pacer.take_window(node._now())
        end = time.monotonic() + duration
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.01)
        w = node.pacer.take_window(node._now())
        return {'scene': scene, 'rtf': rtf, 'wall': w.wall, 'sim': w.sim,
                'achieved_rtf': w.achieved_rtf, 'ticks': w.ticks, 'samples': w.samples,
                'interval_mean': w.interval_mean, 'jitter': w.interval_std,
                'interval_p99': w.interval_p99, 'interval_max': w.interval_max,
                'busy_mean': w.busy_mean, 'overruns': w.overruns, 'capped': w.capped,
                'integrator': node.stepper.method, 'nfev': node.stepper.nfev,
                'diverged': node.diverged}
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)


def run(args: argparse.Namespace) -> int:
    """Run every (scene, rtf) pair and print a table."""
    from gyro_rotor.cli.util import check_number
    from gyro_rotor.core.scene import NODE_RANGES
    check_number('--duration', args.duration, low=0.0, low_open=True, what='[s]')
    check_number('--publish-rate', args.publish_rate, low=NODE_RANGES['publish_rate'][0],
                 high=NODE_RANGES['publish_rate'][1], what='[Hz]')
    for rtf in args.rtf:
        check_number('--rtf', rtf, low=NODE_RANGES['real_time_factor'][0],
                     high=NODE_RANGES['real_time_factor'][1])
    rows = [bench_one(s, r, args.duration, args.publish_rate, args.integrator)
            for s in args.scenes for r in args.rtf]
    print(f'rotor_sim pacing, publish_rate {args.publish_rate:g} Hz, {args.duration:g} s '
          f'wall per run (cpu count {os.cpu_count()})')
    print('| scene | rtf | integrator | achieved RTF | samples/s | tick mean [ms] | '
          'jitter std [ms] | p99 [ms] | max [ms] | busy mean [ms] | overruns | capped |')
    print('|---|---|---|---|---|---|---|---|---|---|---|---|')
    for r in rows:
        print(f"| {r['scene']} | {r['rtf']:g} | {r['integrator']} | {r['achieved_rtf']:.4f} | "
              f"{r['samples'] / r['wall']:.0f} | {1e3 * r['interval_mean']:.3f} | "
              f"{1e3 * r['jitter']:.3f} | {1e3 * r['interval_p99']:.3f} | "
              f"{1e3 * r['interval_max']:.3f} | {1e3 * r['busy_mean']:.3f} | "
              f"{r['overruns']}/{r['ticks']} | {r['capped']} |"
              + (f" diverged: {r['diverged']}" if r['diverged'] else ''))
    return 0
