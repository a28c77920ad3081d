"""``rotor_sim``: the full nonlinear gyrostat in real time on ROS 2 (a thin adapter).

The node declares every scene key as a parameter (:mod:`gyro_rotor.ros.sim_params`),
loads the scene named by ``scene`` and hands it to a
:class:`~gyro_rotor.numerics.live.LiveSimulation` (for a general scene of any rotor
system, a :class:`~gyro_rotor.numerics.live_general.GeneralLiveSimulation`: joints q and
z_ROTOR, no 3-D topics), which integrates it from a
steady-clock timer and returns each tick's samples on the output grid
t_k = k / publish_rate with every derived output. The node publishes them:

* ``joint_states`` (sensor_msgs/JointState): theta, psi, phi_R, phi_M; effort = the
  generalized forces (Q_theta, Q_psi, Q, -c_psi chi - Q) of eqs. (19, 23);
* ``energy`` (std_msgs/Float64MultiArray, layout in :mod:`gyro_rotor.ros.messages`);
* ``axis`` (Vector3Stamped), ``stator_pose`` (PoseStamped), ``axis_marker`` (Marker);
* ``/diagnostics`` about once a second, ``/clock`` (unless ``publish_clock`` is false);
* ``~/scene`` (std_msgs/String, transient local): the current scene as YAML.

Services ``~/reset``, ``~/perturb`` (std_srvs/Trigger) and ``~/pause`` (std_srvs/SetBool).
Run: ``rotor_sim --ros-args -p scene:=nutation`` or ``python -m gyro_rotor.ros.sim_node``.

**Time.** rotor_sim is the clock source (``/clock``): it refuses ``use_sim_time`` true, at
start and live.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, Vector3Stamped
from gyro_rotor.core.system.scene import GeneralScene
from gyro_rotor.errors import GyroRotorError, ParameterError
from gyro_rotor.numerics.live import Level, LiveSimulation
from gyro_rotor.numerics.live_general import GeneralLiveSimulation
import gyro_rotor.ros.messages as ros_msgs
from gyro_rotor.ros.qos import profile
from gyro_rotor.ros.runner import run_node
from gyro_rotor.ros.sim_params import declare_parameters, type_error
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


class RotorSimNode(Node):
    """The simulation node (see module doc); importable so that tests can compose it."""

    def __init__(self, node_name: str = 'rotor_sim', **kwargs):
        super().__init__(node_name, **kwargs)
        if self.get_parameter('use_sim_time').value:
            raise ParameterError(USE_SIM_TIME_REFUSED)
        scene, cfg, perturbation = declare_parameters(self)
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        #: the simulation (everything but ROS)
        kind = GeneralLiveSimulation if isinstance(scene, GeneralScene) else LiveSimulation
        self.sim = kind(scene, cfg, perturbation, log=self._log)
        self.pub = {'joint_states': self.create_publisher(JointState, 'joint_states', STATE_QOS),
                    'energy': self.create_publisher(Float64MultiArray, 'energy', STATE_QOS),
                    # one message per tick: as deep as the state topics, so that a recorder
                    # busy with those does not lose them (depth 10 lost 0.2 % at 1000 Hz)
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
        self._msg_energy = ros_msgs.energy_array(dict.fromkeys(fields, 0.0), fields)
        #: messages published per topic over the node's life (in the diagnostics)
        self.published = dict.fromkeys(_TOPICS, 0)
        self.acks = AckWindow((self.pub['joint_states'], self.pub['energy']), self.get_logger())
        self._t_clock: float | None = None
        reset = self._service(self.sim.reset, self._publish_scene)
        self.create_service(Trigger, '~/reset', reset)
        self.create_service(Trigger, '~/perturb', self._service(self.sim.perturb))
        self.create_service(SetBool, '~/pause', self._service(self.sim.pause))
        self._waiting = cfg['wait_for_subscribers'] > 0 or bool(cfg['wait_for_node'])
        self._timer = self._diag_timer = None
        self._make_timers(tick=True, diag=True)
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
        was_fast = self.sim.pacer.rtf == 0
        self.sim.apply(changes)
        self._make_timers(tick=was_fast != (self.sim.pacer.rtf == 0),
                          diag='diagnostics_period' in changes)
        self._publish_scene()

    def _make_timers(self, tick: bool, diag: bool) -> None:
        cfg = self.sim.cfg
        if tick:
            if self._timer is not None:
                self.destroy_timer(self._timer)
            period = 1.0 / cfg['publish_rate'] if cfg['real_time_factor'] > 0 else 0.0
            self._timer = self.create_timer(period, self._tick, clock=self._steady)
        if diag:
            if self._diag_timer is not None:
                self.destroy_timer(self._diag_timer)
            self._diag_timer = self.create_timer(cfg['diagnostics_period'],
                                                 self._publish_diagnostics, clock=self._steady)

    # -- ticks -------------------------------------------------------------------------------
    def _tick(self) -> None:
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
        block = sim.tick()
        if block is not None:
            self._publish_block(block)
        t = sim.stepper.t
        if sim.cfg['publish_clock'] and not sim.diverged and t != self._t_clock:
            # only when time moved: a paused or finished simulator sends nothing new
            self.pub['clock'].publish(ros_msgs.clock(ros_msgs.stamp(t)))
            self._t_clock = t
            self.published['clock'] += 1
        if block is None and (sim.pacer.paused or sim.pacer.finished or sim.diverged):
            self._idle()

    def _subscribers_ready(self) -> bool:
        """Return whether joint_states and energy have the subscribers to wait for."""
        n, node = self.sim.cfg['wait_for_subscribers'], self.sim.cfg['wait_for_node']
        pubs = (self.pub['joint_states'], self.pub['energy'])
        if min(p.get_subscription_count() for p in pubs) < n:
            return False
        if not node:
            return True
        names = {node, f'_{node}_recorder'}
        return all(any(i.node_name in names for i in
                       self.get_subscriptions_info_by_topic(p.topic_name)) for p in pubs)

    def _idle(self) -> None:
        """At real_time_factor 0 the timer has period 0: do not spin hot with nothing to do."""
        if self.sim.pacer.rtf == 0:
            time.sleep(IDLE_SLEEP)

    def _publish_block(self, b) -> None:
        """Publish joint_states and energy for every sample, the 3-D topics for the last."""
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
        if b.quaternion is None:          # a general system: no 3-D pose of its own
            return
        st, frame = ros_msgs.stamp(ns[-1]), self.sim.cfg['frame_id']
        self.pub['axis'].publish(ros_msgs.axis_vector(st, frame, b.axis))
        self.pub['stator_pose'].publish(ros_msgs.stator_pose(st, frame, b.quaternion))
        self.pub['axis_marker'].publish(ros_msgs.axis_marker(st, frame, b.axis))
        for topic in ('axis', 'stator_pose', 'axis_marker'):
            self.published[topic] += 1

    # -- diagnostics, scene, services --------------------------------------------------------
    def _publish_diagnostics(self) -> None:
        level, msg, values = self.sim.diagnostics()
        values.update(ack_wait_s=self.acks.wait_s, ack_timeouts=self.acks.timeouts,
                      **{f'published_{k}': v for k, v in self.published.items()})
        self.published['diagnostics'] += 1
        self.pub['diagnostics'].publish(ros_msgs.diagnostic_array(
            ros_msgs.stamp(self.sim.stepper.t), f'{self.get_name()}: simulation', level, msg,
            values, hardware_id=f'scene:{self.sim.scene.name}'))

    def _publish_scene(self) -> None:
        text = yaml.safe_dump(self.sim.scene_doc(), sort_keys=False)
        self.pub['scene'].publish(ros_msgs.text(text))

    def _service(self, action, after=None):
        """Wrap a simulation action as a service callback (Trigger or SetBool)."""
        def callback(request, response):
            try:
                args = (request.data,) if hasattr(request, 'data') else ()
                response.message = action(*args)
                response.success = True
            except Exception as err:  # noqa: B902 -- a service never takes the node down
                response.success, response.message = False, str(err)
            if after is not None and response.success:
                after()
            return response
        return callback

    def on_shutdown(self) -> None:
        """Report the published counts (the soak compares them) and flush reliable writers."""
        try:        # (stderr may be a pipe whose reader is gone: a killed ros2 launch)
            print(f'published counts: {json.dumps(self.published)}', file=sys.stderr,
                  flush=True)
        except OSError:
            pass
        # a reliable writer's unacknowledged messages die with it: give them a moment
        for pub in (self.pub['joint_states'], self.pub['energy']):
            pub.wait_for_all_acked(Duration(seconds=SHUTDOWN_ACK_WAIT))


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
    return run_node(RotorSimNode, args)


if __name__ == '__main__':
    sys.exit(main())
