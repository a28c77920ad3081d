"""Time (issue 8): simulation time never goes backwards; stamps, /clock and the bag agree.

What the bag holds (documented in gyro_rotor.recorder): ``log_time`` is the recorder's
receive time (wall clock, ns since the epoch) and ``publish_time`` the publisher's DDS
source timestamp (the same host clock); the simulation time is in the messages (header
stamps, ``energy.t_sim``, ``/clock``), starting at 0. So the relations tested are: per
topic, the log-time order is the simulation-time order; every message was received after
it was sent; and across topics, the send order (publish_time) orders simulation time:
``/clock`` is published after the samples of its tick and before those of the next.
"""

from __future__ import annotations

import os
from pathlib import Path
import subprocess
import time

from gyro_rotor.bag.bagio import open_bag
from gyro_rotor.ros.messages import ENERGY_FIELDS
from gyro_rotor.tools.launch import NodeProcess
import node_helpers
import numpy as np
import pytest

pytestmark = pytest.mark.ros
F = {name: i for i, name in enumerate(ENERGY_FIELDS)}
RATE = 250.0
T_END = 2.0


def _ns(stamp) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _mcap_messages(bag: Path, topic: str) -> list:
    """(log_time, publish_time, decoded) of a topic, in log-time order (mcap reader)."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    with open(next(bag.glob('*.mcap')), 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        return [(m.log_time, m.publish_time, dec) for _, _, m, dec in
                reader.iter_decoded_messages(topics=[topic], log_time_order=True)]


@pytest.fixture(scope='module')
def clocked_bag(tmp_path_factory):
    """Record a run at real_time_factor 0 (every message recorded; /clock is the default)."""
    tmp = tmp_path_factory.mktemp('time')
    bag = tmp / 'bag'
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    an_log, sim_log = open(tmp / 'an.log', 'w'), open(tmp / 'sim.log', 'w')
    an = NodeProcess('gyro_rotor.ros.analysis_node', {      # as the launch files run it
        'output': str(bag), 'scene': 'precession', 'use_sim_time': True},
        stdout=an_log, stderr=subprocess.STDOUT, env=env)
    sim = None
    n = int(T_END * RATE) + 1
    try:
        deadline = time.monotonic() + 60
        while 'recording to' not in (tmp / 'an.log').read_text():
            assert time.monotonic() < deadline and an.poll() is None
            time.sleep(0.1)
        sim = NodeProcess('gyro_rotor.ros.sim_node', {
            'scene': 'precession', 'publish_rate': RATE, 'real_time_factor': 0.0,
            't_end': T_END, 'stop_at_t_end': True,      # /clock by default
            'wait_for_subscribers': 1}, stdout=sim_log, stderr=subprocess.STDOUT, env=env)
        deadline = time.monotonic() + 90
        while time.monotonic() < deadline:
            time.sleep(0.5)
            try:
                import warnings
                with warnings.catch_warnings():
                    warnings.simplefilter('ignore')
                    reader = open_bag(bag)
                    # every sample, and /diagnostics of both nodes (each about once a
                    # second of steady time: a run at rtf 0 can end before the first)
                    names = {node for _, _, data in reader.messages('/diagnostics')
                             for node in (b'rotor_sim:', b'rotor_analysis:') if node in data}
                    if sum(1 for _ in reader.messages('/energy')) >= n and len(names) == 2:
                        break
            except Exception:  # noqa: B902 -- the bag is still being written
                pass
    finally:
        if sim is not None:
            assert sim.stop() == 0
        assert an.stop() == 0, (tmp / 'an.log').read_text()
    return bag


def test_simulation_time_never_goes_backwards_and_stamps_agree(clocked_bag):
    n = int(T_END * RATE) + 1
    joints = _mcap_messages(clocked_bag, '/joint_states')
    energy = _mcap_messages(clocked_bag, '/energy')
    assert len(joints) == len(energy) == n
    js = np.array([_ns(m.header.stamp) for _, _, m in joints])
    t_sim = np.array([m.data[F['t_sim']] for _, _, m in energy])
    k = np.array([m.data[F['k']] for _, _, m in energy])
    # in the order the recorder received them, simulation time strictly increases
    assert np.all(np.diff(js) > 0) and np.all(np.diff(t_sim) > 0)
    # the stamps are the grid t_k = k / rate, the same on both topics
    np.testing.assert_array_equal(k, np.arange(n))
    np.testing.assert_array_equal(t_sim, k / RATE)
    np.testing.assert_array_equal(js, np.round(t_sim * 1e9).astype(np.int64))
    for topic in ('/axis', '/stator_pose', '/axis_marker'):
        st = np.array([_ns(m.header.stamp) for _, _, m in _mcap_messages(clocked_bag, topic)])
        assert len(st) and np.all(np.diff(st) > 0) and set(st) <= set(js)


def test_clock_agrees_with_the_stamps(clocked_bag):
    joints = _mcap_messages(clocked_bag, '/joint_states')
    clock = _mcap_messages(clocked_bag, '/clock')
    assert clock
    c = np.array([_ns(m.clock) for _, _, m in clock])
    js = np.array([_ns(m.header.stamp) for _, _, m in joints])
    assert np.all(np.diff(c) >= 0)
    # at real_time_factor 0 a tick ends on the grid: /clock is the stamp of its last sample
    assert set(c) <= set(js)
    assert c[-1] == js[-1] == int(T_END * 1e9)
    # send order: the samples of a tick go out before its /clock, the next tick's after it
    j_pub = np.array([p for _, p, _ in joints])
    for _, c_pub, msg in clock:
        before = js[j_pub <= c_pub]
        after = js[j_pub > c_pub]
        assert before.size == 0 or before.max() <= _ns(msg.clock)
        assert after.size == 0 or after.min() > _ns(msg.clock)


def test_bag_log_time_is_the_receive_time(clocked_bag):
    for topic in ('/joint_states', '/energy', '/clock'):
        msgs = _mcap_messages(clocked_bag, topic)
        log = np.array([lt for lt, _, _ in msgs], dtype=np.int64)
        pub = np.array([p for _, p, _ in msgs], dtype=np.int64)
        # publish_time is the DDS source timestamp, not a copy of the receive time
        assert np.count_nonzero(pub != log) > 0.9 * len(msgs)
        # received after it was sent, both on this host's wall clock (ns since the epoch)
        assert np.all(log >= pub)
        assert pub.min() > 1_500_000_000 * 10 ** 9
        # the log-time order is the send order within a topic
        assert np.all(np.diff(log) >= 0) and np.all(np.diff(pub) >= 0)


def test_time_is_monotonic_across_live_interventions():
    """Parameter changes, a kick, pause/resume and rtf switches never step time back."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import Float64MultiArray
    from std_srvs.srv import SetBool, Trigger
    from gyro_rotor.ros.sim_node import RotorSimNode
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    node = RotorSimNode(context=ctx, parameter_overrides=[
        Parameter('scene', value='precession'), Parameter('real_time_factor', value=1.0),
        Parameter('publish_rate', value=RATE), Parameter('publish_clock', value=True)])
    sim_thread = node_helpers.NodeThread(node, ctx)
    probe = rclpy.create_node('probe_time', context=ctx, start_parameter_services=False)
    deep = QoSProfile(depth=20000, reliability=ReliabilityPolicy.RELIABLE)
    energy, clock = [], []
    queues = [(probe.create_subscription(Float64MultiArray, 'energy', energy.append, deep),
               energy), (probe.create_subscription(Clock, '/clock', clock.append, deep), clock)]
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(probe)

    def spin_until(cond, timeout=20.0):
        node_helpers.spin_until(ex, cond, timeout, step=0.01, queues=queues)

    def more(n=10):
        n0 = len(energy)
        spin_until(lambda: len(energy) >= n0 + n)

    def call(srv, name, req):
        cl = probe.create_client(srv, name)
        spin_until(cl.service_is_ready)
        fut = cl.call_async(req)
        spin_until(fut.done)
        assert fut.result().success
    try:
        more()
        assert node.set_parameters([Parameter('K_S', value=30.0)])[0].successful
        more()
        assert node.set_parameters([Parameter('integrator', value='rk4')])[0].successful
        more()
        call(Trigger, '/rotor_sim/perturb', Trigger.Request())
        more()
        call(SetBool, '/rotor_sim/pause', SetBool.Request(data=True))
        for _ in range(20):
            ex.spin_once(timeout_sec=0.01)
        call(SetBool, '/rotor_sim/pause', SetBool.Request(data=False))
        more()
        for rtf in (0.0, 2.0, 1.0):
            assert node.set_parameters([Parameter('real_time_factor',
                                                  value=rtf)])[0].successful
            more(30)
        # rotor_sim's loop thread publishes /clock right after a tick's samples: hold it,
        # then take what is still in flight
        call(SetBool, '/rotor_sim/pause', SetBool.Request(data=True))
        spin_until(lambda: clock and _ns(clock[-1].clock) >= int(round(
            energy[-1].data[F['t_sim']] * 1e9)))
    finally:
        sim_thread.close()
        ex.shutdown()
        probe.destroy_node()
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)
    rows = np.array([list(m.data) for m in energy])
    assert np.all(np.diff(rows[:, F['t_sim']]) > 0)
    assert np.all(np.diff(rows[:, F['k']]) == 1)          # no grid point skipped or repeated
    np.testing.assert_array_equal(rows[:, F['t_sim']], rows[:, F['k']] / RATE)
    c = np.array([_ns(m.clock) for m in clock])
    assert np.all(np.diff(c) >= 0)
    assert c[-1] >= int(round(rows[-1, F['t_sim']] * 1e9))


def test_every_stamp_is_simulation_time_diagnostics_of_both_nodes_included(clocked_bag):
    """One time base (issue 16): header stamps, /clock and /diagnostics of both nodes.

    Simulation time starts at 0 and ends at T_END here; a wall-clock stamp (2026, about
    1.8e18 ns) or a stamp beyond the data would fail.
    """
    joints = _mcap_messages(clocked_bag, '/joint_states')
    js = np.array([_ns(m.header.stamp) for _, _, m in joints])
    t_end_ns = int(round(T_END * 1e9))
    assert js[0] == 0 and js[-1] == t_end_ns
    diags = _mcap_messages(clocked_bag, '/diagnostics')
    by_node: dict = {}
    for _, _, m in diags:
        for st in m.status:
            by_node.setdefault(st.name.split(':')[0], []).append(_ns(m.header.stamp))
    assert set(by_node) == {'rotor_sim', 'rotor_analysis'}, set(by_node)
    for node, stamps in by_node.items():
        st = np.array(stamps)
        assert np.all((st >= 0) & (st <= t_end_ns)), (node, st.min(), st.max())
        assert np.all(np.diff(st) >= 0), node
    # the analysis stamps its verdicts with the time of the data it judged
    assert max(by_node['rotor_analysis']) > 0


def test_analysis_node_with_use_sim_time_follows_the_clock_of_rotor_sim():
    """rotor_analysis run as the launch files run it: its ROS time is rotor_sim's /clock.

    A wall-clock ROS time (about 1.8e18 ns) or a clock that never left 0 would fail.
    """
    import rclpy
    from rclpy.clock import ClockType
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from gyro_rotor.ros.analysis_node import RotorAnalysisNode
    from gyro_rotor.ros.sim_node import RotorSimNode
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    sim = RotorSimNode(context=ctx, parameter_overrides=[       # /clock by default
        Parameter('scene', value='precession'), Parameter('real_time_factor', value=1.0),
        Parameter('publish_rate', value=RATE)])
    ana = RotorAnalysisNode(context=ctx, parameter_overrides=[
        Parameter('record', value=False), Parameter('scene', value='precession'),
        Parameter('use_sim_time', value=True)])
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(sim)
    ex.add_node(ana)
    try:
        clock = ana.get_clock()
        assert clock.clock_type == ClockType.ROS_TIME and clock.ros_time_is_active
        node_helpers.spin_until(ex, lambda: clock.now().nanoseconds >= 500_000_000, 20.0,
                                step=0.01)
        t_ana = clock.now().nanoseconds
        t_sim = int(round(sim.sim.stepper.t * 1e9))
        # ROS time of rotor_analysis = the last /clock: at most one tick (max_catch_up,
        # 0.25 s) behind the simulation, never ahead of it
        assert 0 <= t_sim - t_ana <= 250_000_000, (t_ana, t_sim)
    finally:
        ex.shutdown()
        ana.destroy_node()
        sim.destroy_node()
        rclpy.try_shutdown(context=ctx)
