"""``rotor_analysis``: records the simulation to MCAP and checks its stability live.

A thin adapter around :class:`gyro_rotor.recorder.BagRecorder` (raw subscriptions, the exact
bytes into a rosbag2 MCAP bag) and :class:`gyro_rotor.analysis.session.AnalysisSession` (the same
checks as ``gyro-rotor analyze BAG``). The received bytes of ``energy``, ``joint_states`` and
the simulation node's ``~/scene`` document are deserialized once and fed to the analysis.

Parameters: ``output`` (bag directory; default a fresh ``bags_out/rotor_<time>``),
``record`` (bool, default true), ``compression`` (none | zstd | lz4), ``scene`` (name or
path; empty = take it from the simulation node's latched ``/<sim_node>/scene`` document,
which follows live parameter changes), ``sim_node`` (default ``rotor_sim``), ``window_s``
(sliding fit window, default 8 s), ``min_fit_s`` (2 s), ``period`` (publication period of
the results, 1 s).

Publishes ``analysis`` (std_msgs/Float64MultiArray, one dimension labelled with
:data:`~gyro_rotor.analysis.results.ANALYSIS_LABEL`), ``analysis_modes`` (2-D: a row per predicted
mode, dim[0] labelled with the mode names, dim[1] with
:data:`~gyro_rotor.analysis.results.MODE_LABEL`), ``analysis_verdict`` (std_msgs/String) and
``/diagnostics`` (stamped with the simulation time of the newest sample judged: every stamp
the package writes is simulation time; the launch files run this node with use_sim_time, so
its ROS time is rotor_sim's ``/clock``). On SIGINT/SIGTERM the bag is finalized, with the
final live result as the MCAP metadata record ``gyro_rotor.live_result``.
"""

from __future__ import annotations

import json
import math
import sys
import threading

from diagnostic_msgs.msg import DiagnosticArray
from gyro_rotor.analysis.results import ANALYSIS_FIELDS, MODE_FIELDS
from gyro_rotor.analysis.session import AnalysisSession
from gyro_rotor.bag.wire import (energy_from_cdr, joints_from_cdr,
                                 scene_doc_for_bag, scene_ref)
from gyro_rotor.core.scene import load_scene
from gyro_rotor.errors import GyroRotorError
import gyro_rotor.ros.messages as ros_msgs
from gyro_rotor.ros.qos import profile
from gyro_rotor.ros.recorder import BagRecorder, check_writable, default_bag_path, sim_topics
from gyro_rotor.ros.runner import run_node
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy._rclpy_pybind11 import RCLError
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String
import yaml

__all__ = ['RotorAnalysisNode', 'main', 'OWN_TOPICS']

#: the node's own output topics (recorded as well)
OWN_TOPICS = {'analysis': 'std_msgs/msg/Float64MultiArray',
              'analysis_modes': 'std_msgs/msg/Float64MultiArray',
              'analysis_verdict': 'std_msgs/msg/String'}
_QOS = profile('results')
#: received messages that may wait for the analysis while it computes a result
_PENDING_MAX = 20000
_LATCHED = profile('latched')


def _flat_text(scene) -> str:
    """Return the scene's flat keys as YAML in their own order.

    A general system's constants keep the order of its file, so that the offline analysis
    reuses the compiled equations.
    """
    return yaml.safe_dump(scene.to_flat(), sort_keys=False)


def _float_range(lo: float, hi: float) -> list:
    return [FloatingPointRange(from_value=lo, to_value=hi, step=0.0)]


class RotorAnalysisNode(Node):
    """Recorder and live stability checks (see module doc)."""

    def __init__(self, node_name: str = 'rotor_analysis', **kwargs):
        # parameter services on (ros2 param list/get see the read-only parameters): the
        # recorder drains its subscriptions per callback, so six more services in the
        # executor's wait set cost little
        super().__init__(node_name, **kwargs)
        p = self.declare_parameter
        output = p('output', '', ParameterDescriptor(
            description='bag directory to create (default bags_out/rotor_<time>)',
            read_only=True)).value
        compression = p('compression', 'none', ParameterDescriptor(
            description='MCAP chunk compression: none (as rosbag2), zstd or lz4',
            read_only=True)).value
        self.record = p('record', True, ParameterDescriptor(
            description='record a bag', read_only=True)).value
        scene_name = p('scene', '', ParameterDescriptor(
            description="scene name or path; '' = from the sim node's ~/scene document",
            read_only=True)).value
        self.sim_node = p('sim_node', 'rotor_sim', ParameterDescriptor(
            description='name of the simulation node', read_only=True)).value
        window = p('window_s', 8.0, ParameterDescriptor(
            description='sliding window of the decay and mode fits [s] (0 = whole run)',
            floating_point_range=_float_range(0.0, 1e6), read_only=True)).value
        min_fit = p('min_fit_s', 2.0, ParameterDescriptor(
            description='shortest window to fit [s]',
            floating_point_range=_float_range(0.1, 1e6), read_only=True)).value
        period = p('period', 1.0, ParameterDescriptor(
            description='period of the published results [s]',
            floating_point_range=_float_range(0.05, 3600.0), read_only=True)).value
        self.options = {'window_s': float(window), 'min_fit_s': float(min_fit)}
        scene = load_scene(scene_name) if scene_name else None
        self.session = AnalysisSession(scene, **self.options)
        self.errors: list[str] = []
        # the recorder feeds the session from its spool thread; results are read here
        self._lock = threading.Lock()
        self._pending: list = []
        #: energy and joint_states messages received, and the count at the last result
        self.data_received = 0
        self._data_at_result = 0
        self._samples_at_result = 0
        self._reject_logged: set = set()

        topics = sim_topics(self.sim_node)
        self.scene_topic = self.resolve_topic_name(f'{self.sim_node}/scene')
        self.energy_topic = self.resolve_topic_name('energy')
        self.joints_topic = self.resolve_topic_name('joint_states')
        self.pub_analysis = self.create_publisher(Float64MultiArray, 'analysis', _QOS)
        self.pub_modes = self.create_publisher(Float64MultiArray, 'analysis_modes', _QOS)
        self.pub_verdict = self.create_publisher(String, 'analysis_verdict', _LATCHED)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', _QOS)
        self.recorder = None
        # set before the recorder starts: its spool thread may deliver the scene at once
        self._scene_recorded = scene is not None
        if self.record:
            path = default_bag_path() if not output else output
            check_writable(path)
            meta = {'gyro_rotor.analysis': {
                'options': json.dumps(self.options), 'sim_node': self.sim_node,
                'scene_parameter': scene_ref(scene_name) if '/' in scene_name else scene_name}}
            if scene is not None:
                meta['gyro_rotor.scene'] = {'name': scene.name, 'flat': _flat_text(scene)}
            self.recorder = BagRecorder(self, path, {**topics, **OWN_TOPICS},
                                        metadata=meta, on_message=self._on_bytes,
                                        compression=compression, on_error=self._error,
                                        latched=(f'{self.sim_node}/scene',
                                                 'analysis_verdict'), start=False)
            self.recorder.start()           # on_message may use self.recorder from now on
            self.get_logger().info(f'recording to {self.recorder.path}')
        else:
            deep = profile('state')
            self.create_subscription(Float64MultiArray, 'energy', self._guarded(
                self.energy_topic, self.session.on_energy), deep)
            self.create_subscription(JointState, 'joint_states', self._guarded(
                self.joints_topic, self.session.on_joints), deep)
            self.create_subscription(String, f'{self.sim_node}/scene', self._guarded(
                self.scene_topic, lambda m: self._on_scene(m.data)), _LATCHED)
        # results every ``period`` of steady time: with use_sim_time (the launch files) a
        # ROS-time timer would stop while the simulation pauses and fire in bursts at
        # real_time_factor 0; the stamps are simulation time all the same (_publish_diag)
        self.create_timer(float(period), self.publish_results,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))

    # -- input ----------------------------------------------------------------------------
    def _on_bytes(self, topic: str, data: bytes) -> None:
        # spool thread: while a result is computed (lock held) messages wait here, so the
        # bag writing goes on; beyond _PENDING_MAX the spool waits (nothing is dropped)
        self._pending.append((topic, data))
        if self._lock.acquire(blocking=len(self._pending) >= _PENDING_MAX):
            try:
                self._feed_pending()
            finally:
                self._lock.release()

    def _feed_pending(self) -> None:
        # the batch is taken off the list before it is fed: whatever one message does, it
        # is never fed again and never holds back the ones after it (issue 24)
        batch, self._pending = self._pending, []
        for topic, data in batch:
            self._feed(topic, data)

    def _feed(self, topic: str, data: bytes) -> None:
        """Feed one received message; count and report it if it cannot be used."""
        if topic in (self.energy_topic, self.joints_topic):
            self.data_received += 1
        try:
            if topic == self.energy_topic:      # decoded by layout, not by rclpy: 3x faster
                self.session.on_energy(energy_from_cdr(data))
            elif topic == self.joints_topic:
                self.session.on_joints(joints_from_cdr(data))
            elif topic == self.scene_topic:
                self._on_scene(deserialize_message(data, String).data)
        except Exception as err:    # noqa: B902 -- outside data: every failure is one message's
            self._reject(topic, err)

    def _guarded(self, topic: str, callback):
        """Return a subscription callback that counts a message it cannot use (record=False)."""
        def call(msg) -> None:
            if topic in (self.energy_topic, self.joints_topic):
                self.data_received += 1
            try:
                callback(msg)
            except Exception as err:    # noqa: B902 -- as in _feed
                self._reject(topic, err)
        return call

    def _reject(self, topic: str, err: BaseException) -> None:
        reason = self.session.reject(topic, err)
        key = (topic, type(err).__name__)
        if key not in self._reject_logged:      # the first of each kind is logged
            self._reject_logged.add(key)
            self.get_logger().warning(f'message on {topic} ignored ({reason}); further ones '
                                      'of this kind are counted in /diagnostics')

    def _on_scene(self, text: str) -> None:
        scene = self.session.on_scene_doc(text)
        if self.recorder is not None and not self._scene_recorded:
            self.recorder.add_metadata('gyro_rotor.scene', {
                'name': scene.name, 'flat': _flat_text(scene),
                'document': scene_doc_for_bag(text)})
            self._scene_recorded = True

    def _error(self, text: str) -> None:
        if text not in self.errors:
            self.errors.append(text)
            self.get_logger().error(text)

    # -- output ---------------------------------------------------------------------------
    def publish_results(self) -> None:
        """Evaluate and publish analysis, analysis_modes, analysis_verdict, /diagnostics.

        A timer may still fire after SIGINT/SIGTERM shut the context down (measured: 1 of 10
        demo runs ended with "publisher's context is invalid" and exit status 1): then
        nothing is published; the final result goes into the bag in :meth:`finalize`.
        """
        if not self.context.ok():
            return
        try:
            self._publish_results()
        except RCLError:
            if self.context.ok():
                raise

    def _publish_results(self) -> None:
        try:
            with self._lock:
                res = self.session.result()
                samples = self.session.analyzer.samples
                received = self.data_received
        except GyroRotorError as err:
            self._publish_diag('STALE', str(err), self._input_values())
            return
        except Exception as err:    # noqa: B902 -- never a frozen verdict: say it failed
            text = f'error: the analysis failed ({type(err).__name__}: {str(err)[:200]})'
            self.pub_verdict.publish(String(data=text))
            self._publish_diag('ERROR', text, self._input_values())
            return
        new_data = received - self._data_at_result
        stale = new_data >= 10 and samples == self._samples_at_result
        self._data_at_result, self._samples_at_result = received, samples
        if stale:
            # data arrives but none of it is used: the last verdict is no longer current
            text = (f'stale: {new_data} energy/joint_states messages since the last result, '
                    f'no sample usable; last verdict {res.verdict}')
            self.pub_verdict.publish(String(data=text))
            self._publish_diag('STALE', text, self._input_values())
            return
        vec = res.analysis_vector()
        self.pub_analysis.publish(ros_msgs.float_array(vec, ANALYSIS_FIELDS))
        names, rows = res.mode_matrix()
        self.pub_modes.publish(ros_msgs.float_array([v for row in rows for v in row], names,
                                                    MODE_FIELDS))
        self.pub_verdict.publish(String(data=f'{res.verdict}: {res.reason}'))
        values = dict(zip(ANALYSIS_FIELDS, vec))
        values['verdict'] = str(res.verdict)
        for i, line in enumerate(res.evidence):
            values[f'evidence_{i}'] = line
        for i, err in enumerate(self.errors[-3:]):
            values[f'error_{i}'] = err
        values.update(self._input_values())
        level = 'ERROR' if self.errors and res.level == 'OK' else res.level
        if self.session.rejected and level == 'OK':
            level = 'WARN'
        self._publish_diag(level, str(res.verdict), values)

    def _input_values(self) -> dict:
        """Diagnostics of the input: messages ignored (with why), the recorder's counters."""
        values: dict = {'rejected_messages': self.session.rejected_count}
        if self.session.rejected:
            values['rejected'] = self.session.rejected_text()
        if self.recorder is not None:
            values.update(self.recorder.stats())
        return values

    def _publish_diag(self, level: str, message: str, values: dict) -> None:
        # one time base for every stamp the package writes: simulation time (here that of
        # the newest sample analysed, so a verdict is stamped with the data it judged)
        t = round(self.session.t_sim * 1e9)
        clean = {k: (v if not (isinstance(v, float) and math.isnan(v)) else 'nan')
                 for k, v in values.items()}
        self.pub_diag.publish(ros_msgs.diagnostic_array(
            ros_msgs.stamp(int(t)), f'{self.get_name()}: stability', level, message, clean,
            hardware_id=f'scene:{self.session.scene.name if self.session.scene else "?"}'))

    def finalize(self) -> None:
        """Write the final live result into the bag and close it (idempotent)."""
        if self.recorder is None or self.recorder.writer.closed:
            return
        try:
            self.recorder.drain()           # every received message reached the session
            with self._lock:
                self._feed_pending()
            self.session.finish()
            res = self.session.result()
            self.recorder.add_metadata('gyro_rotor.live_result', {
                'verdict': str(res.verdict), 'samples': str(res.samples),
                'dropped': str(res.dropped), 'json': json.dumps(res.as_dict()),
                'rejected': json.dumps(self.session.rejected)})
        except Exception as err:    # noqa: B902 -- the bag is closed whatever happened
            self.recorder.add_metadata('gyro_rotor.live_result', {
                'error': f'{type(err).__name__}: {str(err)[:500]}',
                'rejected': json.dumps(self.session.rejected)})
        finally:
            self.recorder.close()

    def destroy_node(self):
        """Finalize the bag, then destroy the node."""
        self.finalize()
        return super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Run the node until SIGINT/SIGTERM; the bag is finalized on the way out."""
    return run_node(RotorAnalysisNode, args)


if __name__ == '__main__':
    sys.exit(main())
