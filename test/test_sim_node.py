"""The simulation node, in-process (node + probe in one executor) and as a separate process.

Rates are checked per *simulated* second through the stamps (exact by construction: the
node publishes every grid sample t_k = k / publish_rate), wall-clock rates only loosely.
"""

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402, I100
from geometry_msgs.msg import PoseStamped, Vector3Stamped  # noqa: E402
from gyro_rotor.numerics import guard  # noqa: E402
from gyro_rotor.ros.messages import ENERGY_FIELDS, ENERGY_LABEL, JOINT_NAMES  # noqa: E402
from gyro_rotor.ros.sim_node import RotorSimNode  # noqa: E402
from node_helpers import NodeThread, spin_until  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402

pytestmark = pytest.mark.ros
RATE = 250.0
#: the probe's queues: deep, so that a loaded machine cannot overflow them between spins
PROBE_QOS = QoSProfile(depth=20000, reliability=ReliabilityPolicy.RELIABLE)
F = {name: i for i, name in enumerate(ENERGY_FIELDS)}


class Rig:
    """rotor_sim spun in a thread of its own, and a probe node in the test's executor."""

    def __init__(self):
        self.context = rclpy.context.Context()
        rclpy.init(context=self.context)
        self.node = RotorSimNode(context=self.context, parameter_overrides=[
            Parameter('scene', value='precession'),
            Parameter('real_time_factor', value=1.0),
            Parameter('publish_rate', value=RATE),
            Parameter('diagnostics_period', value=0.5)])
        self.probe = rclpy.create_node('probe', context=self.context,
                                       start_parameter_services=False)
        self.energy, self.joints, self.diags = [], [], []
        self.queues = [
            (self.probe.create_subscription(Float64MultiArray, 'energy', self.energy.append,
                                            PROBE_QOS), self.energy),
            (self.probe.create_subscription(JointState, 'joint_states', self.joints.append,
                                            PROBE_QOS), self.joints)]
        self.probe.create_subscription(DiagnosticArray, '/diagnostics', self.diags.append, 10)
        self.sim_thread = NodeThread(self.node, self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.probe)

    def spin_until(self, cond, timeout=15.0):
        spin_until(self.executor, cond, timeout, queues=self.queues)

    def spin_for(self, seconds):
        end = time.monotonic() + seconds
        spin_until(self.executor, lambda: time.monotonic() >= end, seconds + 1.0, step=0.01,
                   queues=self.queues)

    def call(self, srv_type, name, request):
        client = self.probe.create_client(srv_type, name)
        self.spin_until(lambda: client.service_is_ready())
        future = client.call_async(request)
        self.spin_until(future.done)
        self.probe.destroy_client(client)
        return future.result()

    def energy_rows(self, start=0):
        return np.array([list(m.data) for m in self.energy[start:]])

    def close(self):
        self.sim_thread.close()
        self.executor.shutdown()
        self.probe.destroy_node()
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


@pytest.fixture
def own_context():
    """Yield (context, executor) of the test's own; its nodes destroyed and it shut down after."""
    context = rclpy.context.Context()
    rclpy.init(context=context)
    ex = SingleThreadedExecutor(context=context)
    yield context, ex
    nodes = ex.get_nodes()
    ex.shutdown()
    for node in nodes:
        node.destroy_node()
    rclpy.try_shutdown(context=context)


@pytest.fixture(scope='module')
def rig():
    r = Rig()
    yield r
    r.close()


def test_topics_at_the_configured_rate_with_consistent_stamps(rig):
    wall0 = time.monotonic()
    n0 = len(rig.energy)
    rig.spin_until(lambda: len(rig.energy) - n0 >= 2 * RATE + 10)
    wall = time.monotonic() - wall0
    rows = rig.energy_rows(n0)
    last_ns = int(round(rows[-1, F['t_sim']] * 1e9))     # its joint_states may lag a little
    rig.spin_until(lambda: any(m.header.stamp.sec * 10 ** 9 + m.header.stamp.nanosec
                               == last_ns for m in rig.joints[-50:]))
    assert rig.energy[-1].layout.dim[0].label == ENERGY_LABEL
    # nothing lost: consecutive sequence numbers and grid indices; t = k / rate exactly
    assert np.all(np.diff(rows[:, F['seq']]) == 1)
    assert np.all(np.diff(rows[:, F['k']]) == 1)
    np.testing.assert_array_equal(rows[:, F['t_sim']], rows[:, F['k']] / RATE)
    # samples per simulated second (from the stamps of joint_states) = publish_rate
    stamps = np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9
                       for m in rig.joints])
    t_a = np.ceil(stamps[0])
    per_second = np.count_nonzero((stamps >= t_a) & (stamps < t_a + 1.0))
    if stamps[-1] >= t_a + 1.0:
        assert per_second == RATE
    assert set(np.round(rows[:, F['t_sim']] * 1e9)) <= set(np.round(stamps * 1e9))
    # simulation time never runs ahead of rtf * wall time; loosely keeps up with it
    span = rows[-1, F['t_sim']] - rows[0, F['t_sim']]
    assert span <= wall + 2.0 / RATE
    assert span > 0.2 * wall
    js = rig.joints[-1]
    assert tuple(js.name) == JOINT_NAMES
    assert len(js.position) == len(js.velocity) == len(js.effort) == 4


def test_energy_layout_effort_and_lyapunov(rig):
    n0 = len(rig.energy)
    rig.spin_until(lambda: len(rig.energy) - n0 >= 100)
    rows = rig.energy_rows(n0)
    p = rig.node.sim.scene.system.params
    z, zdot = rows[:, F['z']], rows[:, F['zdot']]
    np.testing.assert_allclose(rows[:, F['dissipation']], p.K_D * zdot ** 2, rtol=1e-12)
    np.testing.assert_allclose(rows[:, F['dE_dt']], -rows[:, F['dissipation']])
    # E* non-increasing (eq. 17) and the energy balance closes
    assert np.all(np.diff(rows[:, F['E_star']]) <= 1e-10)
    assert np.max(np.abs(rows[:, F['residual']])) < 1e-8
    # effort[2] is the drive torque Q = -K_S z - K_D zdot of the same sample
    by_stamp = {(m.header.stamp.sec, m.header.stamp.nanosec): m for m in rig.joints}
    for row in rows[-15:-10]:
        ns = int(round(row[F['t_sim']] * 1e9))
        js = by_stamp[(ns // 10 ** 9, ns % 10 ** 9)]
        assert js.effort[2] == pytest.approx(-p.K_S * row[F['z']] - p.K_D * row[F['zdot']],
                                             rel=1e-9, abs=1e-12)
    assert z.shape == zdot.shape


def test_diagnostics_carry_byte_levels_and_pacing_figures(rig):
    rig.spin_until(lambda: len(rig.diags) >= 2)
    st = rig.diags[-1].status[0]
    assert isinstance(st.level, bytes)
    assert st.level in (DiagnosticStatus.OK, DiagnosticStatus.WARN)
    values = {kv.key: kv.value for kv in st.values}
    for key in ('integrator', 'achieved_rtf', 'overruns', 'quaternion_norm_error',
                'residual', 'scene'):
        assert key in values
    from gyro_rotor.core.scene import load_scene
    from gyro_rotor.numerics.realtime import resolve_method
    auto = resolve_method('auto', load_scene('precession').make_model())[0]   # the scene's choice
    assert values['scene'] == 'precession' and values['integrator'] == auto
    assert 'rotor_sim' in st.name
    # the real-time loop's timing against its deadlines, and the scheduling it got
    for key in ('tick_late_p99', 'tick_late_max', 'late_ticks', 'late_ticks_total'):
        assert float(values[key]) >= 0.0, key
    assert values['scheduling'].startswith(('SCHED_FIFO', 'SCHED_OTHER'))


def test_perturb_and_reset_services(rig):
    rig.spin_until(lambda: len(rig.energy) > 10)
    node = rig.node
    assert rig.call(SetBool, '/rotor_sim/pause', SetBool.Request(data=True)).success
    y0, t0 = node.stepper.y.copy(), node.stepper.t
    E_ref0 = node.sim.baseline.E_ref
    res = rig.call(Trigger, '/rotor_sim/perturb', Trigger.Request())
    assert res.success, res.message
    y1 = node.stepper.y
    assert node.stepper.t == t0
    assert y1[8] == pytest.approx(y0[8] + 1.0)                 # perturbation.dzdot = 1.0
    assert y1[9] == y0[9]                                       # dissipated work kept
    jump = float(node.sim.model.energy(y1) - node.sim.model.energy(y0))
    assert node.sim.baseline.E_ref - E_ref0 == pytest.approx(jump, rel=1e-12, abs=1e-15)
    assert rig.call(SetBool, '/rotor_sim/pause', SetBool.Request(data=False)).success
    n0 = len(rig.energy)
    rig.spin_until(lambda: len(rig.energy) - n0 >= 20)
    rows = rig.energy_rows(n0)
    assert np.max(np.abs(rows[:, F['residual']])) < 1e-8      # baseline moved with E*
    seq_before = rig.energy[-1].data[F['seq']]
    n0 = len(rig.energy)
    res = rig.call(Trigger, '/rotor_sim/reset', Trigger.Request())
    assert res.success, res.message
    rig.spin_until(lambda: any(m.data[F['k']] == 0 for m in rig.energy[n0:]))
    rig.spin_until(lambda: len(rig.energy) - n0 >= 20)
    rows = rig.energy_rows(n0)
    after = rows[np.argmax(rows[:, F['k']] == 0):]
    np.testing.assert_array_equal(after[:, F['k']], np.arange(len(after)))
    assert after[0, F['seq']] > seq_before                    # seq continues over resets
    assert np.all(np.diff(rows[:, F['seq']]) == 1)


def test_pause_holds_time_and_resume_continues_without_a_gap(rig):
    n0 = len(rig.energy)
    res = rig.call(SetBool, '/rotor_sim/pause', SetBool.Request(data=True))
    assert res.success
    t_paused = rig.node.stepper.t
    rig.spin_for(0.3)
    assert rig.node.stepper.t == t_paused
    assert all(m.data[F['t_sim']] <= t_paused for m in rig.energy[n0:])
    res = rig.call(SetBool, '/rotor_sim/pause', SetBool.Request(data=False))
    assert res.success
    rig.spin_until(lambda: rig.energy[-1].data[F['t_sim']] > t_paused + 0.04)
    rows = rig.energy_rows(n0)
    assert np.all(np.diff(rows[:, F['k']]) == 1)       # no grid point skipped or repeated
    assert np.all(np.diff(rows[:, F['seq']]) == 1)


def test_invalid_parameter_changes_are_refused_valid_ones_applied(rig):
    node = rig.node
    for name, value, word in (('K_D', -1.0, 'K_D'), ('A_R', 0.0, 'A_R'),
                              ('model', 'upright_axis', 'read-only'),
                              ('integrator', 'euler', 'euler')):
        (result,) = node.set_parameters([Parameter(name, value=value)])
        assert not result.successful
        assert word in result.reason
    assert node.sim.scene.system.params.K_D == 0.05 and node.sim.scene.system.params.A_R == 0.05
    # K_S: E* jumps by (K_S' - K_S) z^2 / 2, the residual baseline moves with it (the
    # node's lock holds its loop thread between the reading of the state and the change)
    with node.lock:
        y = node.stepper.y.copy()
        E_ref = node.sim.baseline.E_ref
        (result,) = node.set_parameters([Parameter('K_S', value=40.0)])
        assert result.successful, result.reason
        assert node.sim.scene.system.params.K_S == 40.0 and node.sim.model.params.K_S == 40.0
        assert node.sim.baseline.E_ref - E_ref == pytest.approx(0.5 * 20.0 * y[7] ** 2,
                                                                rel=1e-9, abs=1e-15)
        seq_change = node.sim.seq      # samples from here on were computed with K_S = 40
    rig.spin_until(lambda: rig.energy[-1].data[F['seq']] > seq_change + 20)
    rows = rig.energy_rows()
    rows = rows[rows[:, F['seq']] >= seq_change]
    assert np.max(np.abs(rows[:, F['residual']])) < 1e-8
    assert np.all(np.diff(rows[:, F['E_star']]) <= 1e-10)
    # Omega0: the rotor keeps its absolute spin rate, zdot takes the difference
    with node.lock:
        zdot = node.stepper.y[8]
        (result,) = node.set_parameters([Parameter('Omega0', value=320.0)])
        assert result.successful, result.reason
        assert node.stepper.y[8] == pytest.approx(zdot - (320.0 - 314.16))
    node.set_parameters([Parameter('Omega0', value=314.16), Parameter('K_S', value=20.0)])


def test_divergence_guard_stops_keeps_state_and_reports_error(rig, monkeypatch):
    node = rig.node
    # a bound of zero (no relative term, no joules): the round-off of E* trips it
    monkeypatch.setattr(guard, 'RELATIVE_LIMIT', 0.0)
    n0 = len(rig.diags)
    (result,) = node.set_parameters([Parameter('max_residual', value=0.0)])
    assert result.successful
    rig.spin_until(lambda: node.diverged is not None)
    t_stop = node.sim.last[0]
    # the first ERROR status (an OK one published just before the divergence may come later)
    rig.spin_until(lambda: any(d.status[0].level == DiagnosticStatus.ERROR
                               for d in rig.diags[n0:]))
    st = next(d.status[0] for d in rig.diags[n0:]
              if d.status[0].level == DiagnosticStatus.ERROR)
    assert 'residual' in st.message
    # the last good sample arrives, and nothing after it
    rig.spin_until(lambda: any(m.data[F['t_sim']] == t_stop for m in rig.energy[-500:]))
    n1 = len(rig.energy)
    rig.spin_for(0.2)
    assert all(m.data[F['t_sim']] <= t_stop for m in rig.energy[n1:])
    assert np.all(np.isfinite(node.sim.last[1]))
    node.set_parameters([Parameter('max_residual', value=1.0)])
    assert rig.call(Trigger, '/rotor_sim/reset', Trigger.Request()).success
    n2 = len(rig.energy)
    rig.spin_until(lambda: len(rig.energy) - n2 >= 5)
    assert node.diverged is None


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM])
def test_separate_process_publishes_and_shuts_down_cleanly(sig):
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    # in a namespace of its own: the rig's node (module fixture) publishes in the background
    proc = subprocess.Popen(
        [sys.executable, '-m', 'gyro_rotor.ros.sim_node', '--ros-args', '-p', 'scene:=precession',
         '-p', 'real_time_factor:=0.0', '-r', '__ns:=/separate'],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, text=True)
    context = rclpy.context.Context()
    rclpy.init(context=context)
    try:
        probe = rclpy.create_node('probe_proc', context=context)
        energy, joints = [], []
        probe.create_subscription(Float64MultiArray, '/separate/energy', energy.append,
                                  PROBE_QOS)
        probe.create_subscription(JointState, '/separate/joint_states', joints.append,
                                  PROBE_QOS)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(probe)
        # the process starts in 2.4 s here, in 16.7 s under 4 CPU hogs (measured, stop 40)
        deadline = time.monotonic() + 90.0
        while (len(energy) < 50 or len(joints) < 50) and time.monotonic() < deadline:
            assert proc.poll() is None, proc.stderr.read()
            executor.spin_once(timeout_sec=0.05)
        assert len(energy) >= 50 and len(joints) >= 50
        rows = np.array([list(m.data) for m in energy])
        assert np.all(np.diff(rows[:, F['t_sim']]) > 0)
        executor.shutdown()
        probe.destroy_node()
    finally:
        proc.send_signal(sig)
        try:
            out, err = proc.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, err = proc.communicate()
        rclpy.shutdown(context=context)
    assert proc.returncode == 0, err
    assert 'Traceback' not in err, err


@pytest.mark.parametrize('arg, expected', [
    ('K_D:=1', 'parameter K_D: 1 (integer) is not a double in [0, 1e+09] (write 1.0)'),
    ('A_R:=-0.05', 'parameter A_R: -0.05 is out of range: expected a double in [0, 1e+06]'),
    ('publish_rate:=fast', "parameter publish_rate: 'fast' (string) is not a double in "
                           '[1, 10000]'),
    ('pole_pairs:=1.5', 'parameter pole_pairs: 1.5 (double) is not an integer in [0, 64]'),
    ('stop_at_t_end:=1', 'parameter stop_at_t_end: 1 (integer) is not true or false'),
    ('A_R:=0.0', "parameters of scene 'precession': inertia A_R must be positive"),
    ('integrator:=euler', "unknown integrator 'euler'"),
    ('scene:=no_such_scene', "unknown scene 'no_such_scene'"),
    ('K_D', "Couldn't parse parameter override rule: '-p K_D'"),
    ('use_sim_time:=true', 'use_sim_time cannot be true for rotor_sim: it is the clock source'),
])
def test_bad_start_up_parameter_is_one_error_line_and_exit_status_1(arg, expected):
    proc = subprocess.run([sys.executable, '-m', 'gyro_rotor.ros.sim_node', '--ros-args', '-p',
                           arg], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1, proc.stderr
    errors = [line for line in proc.stderr.splitlines() if line.startswith('ERROR:')]
    assert len(errors) == 1 and expected in errors[0], proc.stderr
    assert 'Traceback' not in proc.stderr and 'published counts' not in proc.stderr


def test_live_change_of_the_wrong_type_names_parameter_value_and_type(rig):
    for name, value, reason in (
            ('K_S', 'stiff', "parameter K_S: 'stiff' (string) is not a double in [0, 1e+09]"),
            ('K_S', 30, 'parameter K_S: 30 (integer) is not a double in [0, 1e+09] (write '
                        '30.0)'),
            ('stop_at_t_end', 1.0, 'parameter stop_at_t_end: 1.0 (double) is not true or '
                                   'false'),
            ('K_S', -1.0, 'K_S')):
        (result,) = rig.node.set_parameters([Parameter(name, value=value)])
        assert not result.successful and reason in result.reason, result.reason
    assert rig.node.sim.scene.system.params.K_S == 20.0
    assert rig.node.get_parameter('K_S').value == 20.0


def test_wait_for_node_holds_time_until_that_node_subscribes(own_context):
    """A viewer that subscribes first cannot stand in for the recorder (wait_for_node)."""
    context, ex = own_context
    node = RotorSimNode(context=context, parameter_overrides=[
        Parameter('scene', value='precession'), Parameter('real_time_factor', value=0.0),
        Parameter('wait_for_subscribers', value=1),
        Parameter('wait_for_node', value='rotor_analysis')])
    ex.add_node(node)
    viewer = rclpy.create_node('foxglove_bridge', context=context)
    for topic, cls in (('energy', Float64MultiArray), ('joint_states', JointState)):
        viewer.create_subscription(cls, topic, lambda m: None, PROBE_QOS)
    ex.add_node(viewer)
    ticks = []
    node.create_timer(0.0, lambda: ticks.append(node.stepper.t))
    deadline = time.monotonic() + 20
    while not (node.pub['energy'].get_subscription_count() >= 1 and len(ticks) > 200):
        assert time.monotonic() < deadline
        ex.spin_once(timeout_sec=0.01)
    assert node.stepper.t == 0.0 and node._waiting      # the viewer alone: held at 0
    # the recorder's hidden node counts as rotor_analysis
    rec = rclpy.create_node('_rotor_analysis_recorder', context=context)
    for topic, cls in (('energy', Float64MultiArray), ('joint_states', JointState)):
        rec.create_subscription(cls, topic, lambda m: None, PROBE_QOS)
    ex.add_node(rec)
    while node.stepper.t == 0.0:
        assert time.monotonic() < deadline
        ex.spin_once(timeout_sec=0.01)
    assert not node._waiting


def test_use_sim_time_is_refused_live(rig):
    """rotor_sim publishes /clock: following it would be a loop (issue 27)."""
    (result,) = rig.node.set_parameters([Parameter('use_sim_time', value=True)])
    assert not result.successful and 'clock source' in result.reason
    assert rig.node.get_parameter('use_sim_time').value is False
    (result,) = rig.node.set_parameters([Parameter('use_sim_time', value=False)])
    assert result.successful


@pytest.mark.parametrize('scene', ['nutation', 'twin_gimbal'])
def test_a_scene_file_applies_to_the_node_under_any_name(scene):
    """The scene files are keyed ``/**``: a renamed, namespaced node reads them as well."""
    from gyro_rotor.core.scene import config_dirs
    path = next(p for d in config_dirs() for p in (d / f'{scene}.yaml',
                                                   d / 'systems' / 'scenes' / f'{scene}.yaml')
                if p.is_file())
    context = rclpy.context.Context()
    rclpy.init(context=context)
    try:
        node = RotorSimNode('sim2', namespace='/lab', context=context,
                            cli_args=['--ros-args', '--params-file', str(path)])
        try:
            assert node.get_fully_qualified_name() == '/lab/sim2'
            assert node.sim.scene.name == scene
            assert node.get_parameter('scene').value == scene
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


def test_three_d_topics_at_their_own_rate(rig):
    """axis, stator_pose, axis_marker at visualization_rate (50 Hz) of simulation time."""
    got = {}
    subs = [rig.probe.create_subscription(cls, topic, got.setdefault(topic, []).append,
                                          PROBE_QOS)
            for topic, cls in (('axis', Vector3Stamped), ('stator_pose', PoseStamped))]
    try:
        n0 = len(rig.energy)
        rig.spin_until(lambda: len(rig.energy) - n0 >= RATE and len(got['axis']) >= 20)
        for topic in ('axis', 'stator_pose'):
            t = np.array([m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec
                          for m in got[topic]])
            dt = np.diff(t)
            assert np.all(np.abs(dt - 1 / 50) < 0.5 / RATE), dt       # 50 Hz on the grid
            assert set(np.round(t * RATE, 6)) <= set(np.round(t * RATE))
    finally:
        for sub in subs:
            rig.probe.destroy_subscription(sub)


def test_the_loop_runs_once_an_executor_spins_the_node_and_stops_with_it(own_context):
    """A node only constructed (to read its parameters, say) does not integrate."""
    context, ex = own_context
    node = RotorSimNode(context=context, parameter_overrides=[
        Parameter('scene', value='precession'), Parameter('publish_rate', value=500.0)])
    time.sleep(0.2)
    assert node._thread is None and node.published['joint_states'] == 0
    ex.add_node(node)
    deadline = time.monotonic() + 20
    while node.published['joint_states'] < 100:
        assert time.monotonic() < deadline
        ex.spin_once(timeout_sec=0.05)
    assert node._thread.is_alive() and node._thread.name == 'rotor_sim-loop'
    assert node.scheduling.startswith(('SCHED_FIFO', 'SCHED_OTHER'))
    thread = node._thread
    node.stop_loop()
    assert not thread.is_alive()
    n = node.published['joint_states']
    time.sleep(0.1)
    assert node.published['joint_states'] == n


def test_a_loop_that_never_sleeps_gives_up_its_real_time_priority(rig):
    """Under SCHED_FIFO a loop that cannot keep up would hold a CPU: it is demoted."""
    from gyro_rotor.ros import sim_node
    node = rig.node
    saved = node.scheduling, node.rt_priority
    try:
        node.scheduling = 'SCHED_FIFO 20'
        node.deadlines.busy_streak = sim_node.BUSY_DEMOTE_TICKS - 1
        node._check_busy()                          # not yet
        assert node.scheduling == 'SCHED_FIFO 20'
        node.deadlines.busy_streak = max(sim_node.BUSY_DEMOTE_TICKS, int(
            sim_node.BUSY_DEMOTE_S / node.deadlines.period) + 1)
        node._check_busy()
        assert node.scheduling == 'SCHED_OTHER (demoted)' and node.rt_priority == 0
    finally:
        node.scheduling, node.rt_priority = saved
