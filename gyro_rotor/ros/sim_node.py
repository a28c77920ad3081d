"""``rotor_sim``: the full nonlinear gyrostat in real time on ROS 2 (a thin adapter).

The node declares every scene key as a parameter (:mod:`gyro_rotor.ros.sim_params`),
loads the scene named by ``scene`` (of any rotor system) and hands it to a
:class:`~gyro_rotor.numerics.live.LiveSimulation`, which integrates it in real time and
returns each tick's samples on the output grid t_k = k / publish_rate with every derived
output. The node publishes them:

* ``joint_states`` (sensor_msgs/JointState): theta, psi, phi_R, phi_M; effort = the
  generalized forces (Q_theta, Q_psi, Q, -c_psi chi - Q) of eqs. (19, 23) (a system
  file's scene: its coordinates q and the rotor lags z_ROTOR, no efforts and no 3-D
  topics);
* ``energy`` (std_msgs/Float64MultiArray, layout in :mod:`gyro_rotor.ros.messages`);
* ``axis`` (Vector3Stamped), ``stator_pose`` (PoseStamped), ``axis_marker`` (Marker), the
  3-D views, at ``visualization_rate`` (default 50 Hz of simulation time: RViz and
  Foxglove need no more), each the sample of the first tick past a multiple of
  1 / visualization_rate;
* ``/diagnostics`` about once a second, ``/clock`` (unless ``publish_clock`` is false);
* ``~/scene`` (std_msgs/String, transient local): the current scene as YAML.

Services ``~/reset``, ``~/perturb`` (std_srvs/Trigger) and ``~/pause`` (std_srvs/SetBool).
Run: ``rotor_sim --ros-args -p scene:=nutation`` or ``python -m gyro_rotor.ros.sim_node``.

**The real-time loop.** The integration and the publishing of the state topics run on a
thread of their own (started when an executor first spins the node), which sleeps to
absolute deadlines ``t0 + k / publish_rate`` on the steady clock, aligned with the times
at which the samples are due (:class:`~gyro_rotor.numerics.realtime.Deadlines`); the
executor serves the services, the parameters and the diagnostics, under one lock with the
loop. The loop thread runs under SCHED_FIFO at ``realtime_priority`` while the simulation
runs in real time (real_time_factor > 0), if the process may do that (CAP_SYS_NICE or an
RLIMIT_RTPRIO), and in rotor_sim's own process the other threads (executor, DDS) under
SCHED_FIFO at :data:`OTHERS_RT_PRIORITY`, below it; the log says which it got. At
real_time_factor 0 it runs unpaced at normal priority; a loop that cannot keep up (it
never sleeps) gives up SCHED_FIFO. The interpreter's switch interval is
:data:`SWITCH_INTERVAL` while a loop runs. The diagnostics report how late the ticks
were against their deadlines (``tick_late_p99``, ``tick_late_max``, ``late_ticks``).

**Time.** rotor_sim is the clock source (``/clock``): it refuses ``use_sim_time`` true, at
start and live.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, Vector3Stamped
from gyro_rotor.core.rotations import axis_from_quaternion
from gyro_rotor.errors import GyroRotorError, ParameterError
from gyro_rotor.node_settings import recorder_node_name
from gyro_rotor.numerics.live import Level, LiveSimulation
from gyro_rotor.numerics.realtime import (Deadlines, set_thread_priority,
                                          set_threads_priority, set_timer_slack, sleep_until)
import gyro_rotor.ros.messages as ros_msgs
from gyro_rotor.ros.qos import profile
from gyro_rotor.ros.runner import run_node
from gyro_rotor.ros.sim_params import declare_node_parameter, declare_parameters, type_error
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String
from std_srvs.srv import SetBool, Trigger
from visualization_msgs.msg import Marker
import yaml

__all__ = ['RotorSimNode', 'main', 'STATE_QOS']

#: QoS of the state topics (bag/wire.QOS['state']): reliable; the history (10 s at 1000 Hz)
#: is what a reader can still have repaired after a dropped datagram (issue 12)
STATE_QOS = profile('state')
_LATCHED = profile('latched')
#: flow control at real_time_factor 0: longest block per tick waiting for acknowledgements
ACK_WAIT = Duration(seconds=0.05)
#: at real_time_factor 0, sleep per tick while waiting, paused, finished or diverged [s]
IDLE_SLEEP = 0.005
#: at shutdown, longest wait for the last messages to be acknowledged [s]
SHUTDOWN_ACK_WAIT = 2.0
#: ... and the most samples per state topic that may be in flight unacknowledged
ACK_WINDOW = STATE_QOS.depth // 2
#: ... and how long a subscriber may stay silent before the simulator goes on without it [s]
ACK_GIVE_UP = 5.0
#: the interpreter's switch interval while the loop runs in real time [s] (Python's default,
#: 5 ms, is how long the loop thread may wait for the GIL when another thread of the
#: process computes: the executor's diagnostics, a service)
SWITCH_INTERVAL = 2e-4
#: a loop thread under SCHED_FIFO that found its deadline passed at this many consecutive
#: ticks, and for at least BUSY_DEMOTE_S, never slept: it would hold a CPU against every
#: ordinary process, so it goes back to normal scheduling (and says so)
BUSY_DEMOTE_TICKS, BUSY_DEMOTE_S = 50, 0.5
#: SCHED_FIFO priority of the process' other threads (the executor's, the DDS threads)
#: while the loop runs under SCHED_FIFO in a process of its own: below the loop's. The
#: loop takes the GIL and DDS locks that those threads hold at times; preempted by
#: ordinary processes while they held one, they stalled it (measured, precession at 1 kHz
#: with a CPU hog per core, three 10-s runs each: lateness max 8.3-10.7 ms, samples out
#: up to 14.1 ms late, 0-23 late ticks with the other threads at normal priority; 0.4-0.7
#: ms, 1.0-1.7 ms, 1-4 with them at SCHED_FIFO 10)
OTHERS_RT_PRIORITY = 10
#: SCHED_FIFO priority of the loop thread in real time (if permitted): above the default
#: of ordinary processes (SCHED_OTHER), below the kernel's own threaded interrupts (50)
DEFAULT_RT_PRIORITY = 20
USE_SIM_TIME_REFUSED = ('use_sim_time cannot be true for rotor_sim: it is the clock source '
                        '(it publishes /clock); set use_sim_time on the other nodes')
_TOPICS = ('joint_states', 'energy', 'axis', 'stator_pose', 'axis_marker', 'clock',
           'diagnostics')


class AckWindow:
    """Flow control at real_time_factor 0: whether the next chunk may be computed.

    As fast as possible is meant for batch recording, so it must not outrun a reliable
    subscriber. At most ``ACK_WINDOW`` samples of ``joint_states`` and ``energy`` may be
    unacknowledged by their reliable subscriptions (less than the publisher's history, so
    that DDS never overwrites an unacknowledged sample); a KEEP_ALL subscription that
    cannot store more does not acknowledge, which holds the simulator back. A full window
    blocks each call for at most ``ACK_WAIT``, so that services are still served; a
    subscriber silent for ``ACK_GIVE_UP`` s (killed) is given up on for that window.
    """

    def __init__(self, publishers, log):
        self.publishers, self.log = publishers, log
        self.unacked = self.timeouts = 0
        self.wait_s = 0.0
        self._since: float | None = None

    def ready(self, chunk: int) -> bool:
        """Return whether ``chunk`` more samples may be published now."""
        if self.unacked + chunk <= ACK_WINDOW:
            return True
        start = time.monotonic()
        ok = all(pub.wait_for_all_acked(ACK_WAIT) for pub in self.publishers)
        now = time.monotonic()
        self.wait_s += now - start
        if not ok:
            self._since = now if self._since is None else self._since
            if now - self._since < ACK_GIVE_UP:
                return False
            self.timeouts += 1
            self.log.warn(f'a subscriber did not acknowledge for {ACK_GIVE_UP:g} s: '
                          'continuing without it')
        self._since = None
        self.unacked = 0
        return True


_process_lock = threading.Lock()
_process_users = [0, None]          # loop threads running, the switch interval before


def _process_settings(delta: int) -> None:
    """Count a loop thread in (+1) or out (-1): :data:`SWITCH_INTERVAL` while any runs.

    Measured with a thread sleeping to 1-kHz deadlines under SCHED_FIFO while another
    thread of the process computes without pause: woken 13-15 ms late at p99 with
    Python's 5 ms (it waits for the GIL), 2.4 ms with 0.2 ms. (The cyclic garbage
    collector, checked too, did not run at all in 30 s of a running node: its objects die
    by reference counting.)
    """
    with _process_lock:
        if delta > 0 and _process_users[0] == 0:
            _process_users[1] = sys.getswitchinterval()
            sys.setswitchinterval(min(SWITCH_INTERVAL, _process_users[1]))
        _process_users[0] += delta
        if delta < 0 and _process_users[0] == 0 and _process_users[1] is not None:
            sys.setswitchinterval(_process_users[1])


class RotorSimNode(Node):
    """The simulation node (see module doc); importable so that tests can compose it."""

    def __init__(self, node_name: str = 'rotor_sim', *, own_process: bool = False, **kwargs):
        """Make the node; ``own_process``: the process is rotor_sim's alone (_schedule)."""
        super().__init__(node_name, **kwargs)
        self._own_process = own_process
        if self.get_parameter('use_sim_time').value:
            raise ParameterError(USE_SIM_TIME_REFUSED)
        scene, cfg, perturbation = declare_parameters(self)
        self.viz_rate = declare_node_parameter(
            self, 'visualization_rate', 50.0, 'rate of the 3-D topics axis, stator_pose and '
            'axis_marker per second of simulation time [Hz] (at most the publish rate; 0: '
            'none); live')
        self.rt_priority = declare_node_parameter(
            self, 'realtime_priority', DEFAULT_RT_PRIORITY, 'SCHED_FIFO priority of the '
            'integration thread while real_time_factor > 0, if the process may raise it '
            '(0: normal scheduling)', read_only=True)
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        #: the simulation (everything but ROS)
        self.sim = LiveSimulation(scene, cfg, perturbation, log=self._log)
        #: held by the loop thread while it ticks and publishes, and by every service,
        #: parameter change and diagnostics call on the executor
        self.lock = threading.RLock()
        self.pub = {'joint_states': self.create_publisher(JointState, 'joint_states', STATE_QOS),
                    'energy': self.create_publisher(Float64MultiArray, 'energy', STATE_QOS),
                    'axis': self.create_publisher(Vector3Stamped, 'axis', STATE_QOS),
                    'stator_pose': self.create_publisher(PoseStamped, 'stator_pose', STATE_QOS),
                    'axis_marker': self.create_publisher(Marker, 'axis_marker', STATE_QOS),
                    'diagnostics': self.create_publisher(DiagnosticArray, '/diagnostics', 10),
                    'clock': self.create_publisher(ClockMsg, '/clock', STATE_QOS),
                    'scene': self.create_publisher(String, '~/scene', _LATCHED)}
        # reused for every sample (publish serializes synchronously)
        names, fields = self.sim.joint_names, self.sim.energy_fields
        self._msg_joints = ros_msgs.joint_state(ros_msgs.stamp(0), (0.0,) * len(names),
                                                (0.0,) * len(names), (), names=names)
        self._msg_energy = ros_msgs.float_array([0.0] * len(fields), fields)
        #: messages published per topic over the node's life (in the diagnostics)
        self.published = dict.fromkeys(_TOPICS, 0)
        self.acks = AckWindow((self.pub['joint_states'], self.pub['energy']), self.get_logger())
        self._t_clock: float | None = None
        self._viz_k: int | None = None          # index of the last 3-D sample published
        reset = self._service(self.sim.reset, self._publish_scene)
        self.create_service(Trigger, '~/reset', reset)
        self.create_service(Trigger, '~/perturb', self._service(self.sim.perturb))
        self.create_service(SetBool, '~/pause', self._service(self.sim.pause))
        self._waiting = cfg['wait_for_subscribers'] > 0 or bool(cfg['wait_for_node'])
        #: the loop's deadlines (period 1 / publish_rate) and its scheduling
        self.deadlines = Deadlines(1.0 / cfg['publish_rate'])
        self.scheduling = 'not started'
        #: the scheduling of the process' other threads (set in a process of its own)
        self.scheduling_others = 'unchanged'
        self._rt_error: str | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._aligned: tuple | None = None
        #: the scheduled (steady-clock) time of the last tick in real time (None: none yet)
        self.tick_time: float | None = None
        # the loop starts when an executor first spins the node (a node that is only
        # constructed, e.g. to inspect its parameters, does not run)
        self._starter = self.create_timer(0.0, self._start_loop, clock=self._steady)
        self._diag_timer = None
        self._make_diag_timer()
        self.add_on_set_parameters_callback(self._on_set)
        self.add_post_set_parameters_callback(self._post_set)
        self._publish_scene()
        self.get_logger().info(
            f"scene '{scene.name}' (model {self.sim.model.name}), integrator "
            f'{self.sim.stepper.method}, publish_rate {cfg["publish_rate"]:g} Hz, '
            f'real_time_factor {cfg["real_time_factor"]:g}')

    @property
    def stepper(self):
        """Return the integrator of the simulation, whose figures tools read."""
        return self.sim.stepper

    @property
    def pacer(self):
        """Return the pacer of the simulation, whose figures tools read."""
        return self.sim.pacer

    @property
    def diverged(self) -> str | None:
        """Return why the integration stopped (None while it runs)."""
        return self.sim.diverged

    def _now(self) -> float:
        return self.sim.clock()

    def _log(self, level: Level, text: str) -> None:
        # one call site per severity (rclpy refuses a second severity at one call site)
        if level == Level.ERROR:
            self.get_logger().error(text)
            self._publish_diagnostics()
        elif level == Level.WARN:
            self.get_logger().warn(text)
        else:
            self.get_logger().info(text)

    # -- parameters --------------------------------------------------------------------------
    def _on_set(self, params) -> SetParametersResult:
        """Validate a change before it is accepted (types, then the simulation's check)."""
        for p in params:
            if p.name == 'use_sim_time' and p.value:
                return SetParametersResult(successful=False, reason=USE_SIM_TIME_REFUSED)
            reason = type_error(p, self.parameter_types)
            if reason:
                return SetParametersResult(successful=False, reason=reason)
        try:
            with self.lock:
                self.sim.check({p.name: p.value for p in params})
        except GyroRotorError as err:
            return SetParametersResult(successful=False, reason=str(err))
        except Exception as err:  # noqa: B902 -- a refusal, never a dead node
            return SetParametersResult(successful=False,
                                       reason=f'{type(err).__name__}: {err}')
        return SetParametersResult(successful=True)

    def _post_set(self, params) -> None:
        """Apply accepted changes without restart."""
        changes = {p.name: p.value for p in params}
        if 'visualization_rate' in changes:
            self.viz_rate = float(changes['visualization_rate'])
            self._viz_k = None
        with self.lock:
            self.sim.apply(changes)
        if 'diagnostics_period' in changes:
            self._make_diag_timer()
        self._publish_scene()

    def _make_diag_timer(self) -> None:
        if self._diag_timer is not None:
            self.destroy_timer(self._diag_timer)
        self._diag_timer = self.create_timer(self.sim.cfg['diagnostics_period'],
                                             self._publish_diagnostics, clock=self._steady)

    # -- the loop thread ---------------------------------------------------------------------
    def _start_loop(self) -> None:
        """Start the loop thread (once, from the executor's first spin)."""
        self.destroy_timer(self._starter)
        if self._thread is None and not self._stop.is_set():
            _process_settings(+1)
            self._thread = threading.Thread(target=self._loop, name='rotor_sim-loop',
                                            daemon=True)
            self._thread.start()

    def stop_loop(self, timeout: float = 5.0) -> None:
        """Stop the loop thread and wait for it (idempotent)."""
        self._stop.set()
        thread, self._thread = self._thread, None
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)

    def _loop(self) -> None:
        """Tick until stopped: to absolute deadlines in real time, unpaced at rtf 0."""
        set_timer_slack(1)
        rt = False
        try:
            while not self._stop.is_set():
                real_time = self.sim.pacer.rtf > 0
                if real_time != rt or self.scheduling == 'not started':
                    rt = real_time
                    self._schedule(rt)
                if real_time:
                    self._align()
                    scheduled, woke = self.deadlines.wait(self._stop)
                    if self._stop.is_set():
                        break
                    self._tick(scheduled, woke)
                    self.deadlines.done()
                    self._check_busy()
                else:
                    self._aligned = None
                    self._tick(None, None)
        except Exception as err:  # noqa: B902 -- (the context shut down under the loop)
            if not self._stop.is_set() and self.context.ok():
                self.get_logger().error(f'the loop thread stopped: {type(err).__name__}: '
                                        f'{err}')
        finally:
            if rt:
                set_thread_priority(0)
            _process_settings(-1)

    def _check_busy(self) -> None:
        """Go back to normal scheduling when the loop under SCHED_FIFO never sleeps."""
        streak = self.deadlines.busy_streak
        if self.scheduling.startswith('SCHED_FIFO') and streak >= BUSY_DEMOTE_TICKS and \
                streak * self.deadlines.period >= BUSY_DEMOTE_S:
            set_thread_priority(0)
            if self.scheduling_others != 'unchanged':
                set_threads_priority(0, exclude=(threading.get_native_id(),))
                self.scheduling_others = 'SCHED_OTHER'
            self.rt_priority = 0
            self.scheduling = 'SCHED_OTHER (demoted)'
            self.get_logger().warn(
                f'the integration thread did not sleep for {streak} ticks (it cannot keep '
                'up): back to normal scheduling, so that it does not hold a CPU against '
                'every other process')

    def _schedule(self, real_time: bool) -> None:
        """SCHED_FIFO at realtime_priority in real time if permitted; log what it got.

        In a process of its own (``rotor_sim``'s main, ``gyro-rotor rt-bench``) the other
        threads go under SCHED_FIFO at :data:`OTHERS_RT_PRIORITY` with it, and back.
        """
        prio = self.rt_priority if real_time else 0
        error = set_thread_priority(prio)
        if self._own_process and (prio and error is None or
                                  self.scheduling_others != 'unchanged'):
            others = min(OTHERS_RT_PRIORITY, prio - 1) if prio else 0
            n = set_threads_priority(others, exclude=(threading.get_native_id(),))
            self.scheduling_others = ((f'SCHED_FIFO {others}' if others else 'SCHED_OTHER')
                                      if isinstance(n, int) else f'unchanged ({n})')
        if prio and error is None:
            self.scheduling = f'SCHED_FIFO {prio}'
        elif prio:
            self.scheduling = 'SCHED_OTHER'
            if self._rt_error is None:
                self._rt_error = error
                self.get_logger().warn(
                    f'the integration thread keeps normal scheduling: SCHED_FIFO priority '
                    f'{prio} is not permitted ({error}); expect late ticks on a loaded '
                    'machine (grant CAP_SYS_NICE or an rtprio limit to raise it)')
            return
        else:
            self.scheduling = 'SCHED_OTHER'
        if real_time or self.rt_priority:
            self.get_logger().info(
                f'integration thread: {self.scheduling}'
                + (' (real_time_factor 0: unpaced, normal priority)' if not real_time else
                   ' (realtime_priority 0)' if not prio else
                   f', deadlines every {1e3 * self.deadlines.period:g} ms')
                + ('' if self.scheduling_others == 'unchanged' else
                   f'; the other threads of the process: {self.scheduling_others}'))

    def _align(self) -> None:
        """Align the deadlines with the pacer's time base when that moved (start, kick, ...).

        Each sample is then produced at the deadline at which it is due, not up to a period
        later.
        """
        with self.lock:
            anchor, due = self.sim.pacer.anchor, self.sim.pacer.due()
        if anchor is not None and anchor != self._aligned and due is not None:
            self.deadlines.start(due)
            self._aligned = anchor

    def _tick(self, scheduled: float | None, woke: float | None) -> None:
        sim = self.sim
        if self._waiting:
            if not self._subscribers_ready():
                return self._idle()       # the pacer anchors its clock at the first real tick
            self._waiting = False
            node = sim.cfg['wait_for_node']
            self.get_logger().info(f"{sim.cfg['wait_for_subscribers']} subscriber(s) matched"
                                   + (f', {node} among them' if node else '')
                                   + ': simulation time starts')
        if sim.pacer.rtf == 0 and not sim.diverged and not self.acks.ready(
                sim.pacer.chunk_samples):
            return
        with self.lock:
            block = sim.tick(scheduled, woke)
            self.tick_time = scheduled
            if block is not None:
                self._publish_block(block)
            t = sim.stepper.t
            if sim.cfg['publish_clock'] and not sim.diverged and t != self._t_clock:
                # only when time moved: a paused or finished simulator sends nothing new
                self.pub['clock'].publish(ros_msgs.clock(ros_msgs.stamp(t)))
                self._t_clock = t
                self.published['clock'] += 1
            idle = block is None and (sim.pacer.paused or sim.pacer.finished or sim.diverged)
        if idle:
            self._idle()

    def _subscribers_ready(self) -> bool:
        """Return whether joint_states and energy have the subscribers to wait for."""
        n, node = self.sim.cfg['wait_for_subscribers'], self.sim.cfg['wait_for_node']
        pubs = (self.pub['joint_states'], self.pub['energy'])
        if min(p.get_subscription_count() for p in pubs) < n:
            return False
        if not node:
            return True
        names = {node, recorder_node_name(node)}
        return all(any(i.node_name in names for i in
                       self.get_subscriptions_info_by_topic(p.topic_name)) for p in pubs)

    def _idle(self) -> None:
        """At real_time_factor 0 nothing paces the loop: do not spin hot with nothing to do."""
        if self.sim.pacer.rtf == 0:
            sleep_until(time.monotonic() + IDLE_SLEEP)

    def _publish_block(self, b) -> None:
        """Publish joint_states and energy for every sample, the 3-D topics at their rate."""
        n = len(b)
        js, en = self._msg_joints, self._msg_energy
        stamp = js.header.stamp
        ns = np.round(b.t * 1e9).astype(np.int64).tolist()
        rows = np.column_stack([b.energy[f] for f in self.sim.energy_fields]).tolist()
        pos, vel, eff = b.position.tolist(), b.velocity.tolist(), b.effort.tolist()
        pub_j, pub_e = self.pub['joint_states'].publish, self.pub['energy'].publish
        for i in range(n):
            stamp.sec, stamp.nanosec = divmod(ns[i], 1_000_000_000)
            js.position, js.velocity, js.effort = pos[i], vel[i], eff[i]
            pub_j(js)
            en.data = rows[i]
            pub_e(en)
        self.acks.unacked += n
        self.published['joint_states'] += n
        self.published['energy'] += n
        if b.quaternion is None or self.viz_rate <= 0:  # a general system: no 3-D pose
            return
        # the 3-D views: the first sample at or past each multiple of 1 / visualization_rate
        frame = self.sim.cfg['frame_id']
        for i, k in enumerate(np.floor(b.t * self.viz_rate + 1e-9).astype(np.int64).tolist()):
            if k == self._viz_k:
                continue
            self._viz_k = k
            q = b.quaternion if b.quaternions is None else b.quaternions[i]
            axis = axis_from_quaternion(q)
            st = ros_msgs.stamp(ns[i])
            self.pub['axis'].publish(ros_msgs.axis_vector(st, frame, axis))
            self.pub['stator_pose'].publish(ros_msgs.stator_pose(st, frame, q))
            self.pub['axis_marker'].publish(ros_msgs.axis_marker(st, frame, axis))
            for topic in ('axis', 'stator_pose', 'axis_marker'):
                self.published[topic] += 1

    # -- diagnostics, scene, services --------------------------------------------------------
    def _publish_diagnostics(self) -> None:
        """Publish the simulation's status, decided and sent under the loop's lock.

        The loop thread reports a divergence at once (:meth:`_log`); a periodic report
        decided before it and sent after it (outside the lock) said 'running' after the
        ERROR, as a fresh clone's test_reliability saw once on a fast machine.
        """
        with self.lock:
            level, msg, values = self.sim.diagnostics()
            late = self.deadlines.take_window()
            values.update(ack_wait_s=self.acks.wait_s, ack_timeouts=self.acks.timeouts,
                          scheduling=self.scheduling, scheduling_others=self.scheduling_others,
                          tick_late_p99=late.lateness_p99,
                          tick_late_max=late.lateness_max, late_ticks=late.late,
                          late_ticks_total=self.deadlines.late_total,
                          **{f'published_{k}': v for k, v in self.published.items()})
            self.published['diagnostics'] += 1
            self.pub['diagnostics'].publish(ros_msgs.diagnostic_array(
                ros_msgs.stamp(self.sim.stepper.t), f'{self.get_name()}: simulation', level,
                msg, values, hardware_id=f'scene:{self.sim.scene.name}'))

    def _publish_scene(self) -> None:
        with self.lock:
            doc = self.sim.scene_doc()
        self.pub['scene'].publish(ros_msgs.text(yaml.safe_dump(doc, sort_keys=False)))

    def _service(self, action, after=None):
        """Wrap a simulation action as a service callback (Trigger or SetBool)."""
        def callback(request, response):
            try:
                args = (request.data,) if hasattr(request, 'data') else ()
                with self.lock:
                    response.message = action(*args)
                response.success = True
            except Exception as err:  # noqa: B902 -- a service never takes the node down
                response.success, response.message = False, str(err)
            if after is not None and response.success:
                after()
            return response
        return callback

    def on_shutdown(self) -> None:
        """Stop the loop, report the published counts (the soak compares them), flush."""
        self.stop_loop()
        try:        # (stderr may be a pipe whose reader is gone: a killed ros2 launch)
            print(f'published counts: {json.dumps(self.published)}', file=sys.stderr,
                  flush=True)
        except OSError:
            pass
        # a reliable writer's unacknowledged messages die with it: give them a moment
        for pub in (self.pub['joint_states'], self.pub['energy']):
            pub.wait_for_all_acked(Duration(seconds=SHUTDOWN_ACK_WAIT))

    def destroy_node(self):
        """Stop the loop thread, then destroy the node."""
        self.stop_loop()
        return super().destroy_node()


#: Fast DDS profile of the simulator's writers: a reliable writer asks its readers for
#: acknowledgements every heartbeat period (default 3 s); the flow control at
#: real_time_factor 0 waits for them, so the period bounds its throughput
FASTDDS_PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <data_writer profile_name="gyro_rotor_sim_writer" is_default_profile="true">
    <times>
      <heartbeatPeriod><sec>0</sec><nanosec>{ns}</nanosec></heartbeatPeriod>
    </times>
  </data_writer>
</profiles>
"""
#: heartbeat period of the simulator's writers [ns]: with 5 ms (suspected: repair traffic) the
#: recorder stalled in a 150-s soak under load; 50 ms allows ACK_WINDOW / 50 ms = 10k samples/s
HEARTBEAT_NS = 50_000_000


def use_fastdds_profile() -> str | None:
    """Point Fast DDS at :data:`FASTDDS_PROFILE` unless a profile file is configured.

    Must run before ``rclpy.init``; returns the file used (None if the user's is kept).
    """
    if os.environ.get('FASTRTPS_DEFAULT_PROFILES_FILE') or \
            os.environ.get('FASTDDS_DEFAULT_PROFILES_FILE'):
        return None
    path = os.path.join(tempfile.gettempdir(), f'gyro_rotor_sim_fastdds_{HEARTBEAT_NS}.xml')
    if not os.path.exists(path):
        tmp = f'{path}.{os.getpid()}'
        with open(tmp, 'w') as f:
            f.write(FASTDDS_PROFILE.format(ns=HEARTBEAT_NS))
        os.replace(tmp, path)
    os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = path
    return path


def main(args: list[str] | None = None) -> int:
    """Run ``rotor_sim`` until SIGINT/SIGTERM (see :mod:`gyro_rotor.ros.runner`)."""
    use_fastdds_profile()
    return run_node(lambda: RotorSimNode(own_process=True), args)


if __name__ == '__main__':
    sys.exit(main())
