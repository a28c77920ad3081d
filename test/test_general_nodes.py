"""Any rotor system in the nodes (issue 16 item 1).

The live simulation of a system file's scene, rotor_sim's parameters for it, and ``gyro-rotor
demo`` on every shipped system file's scene (the bag read by three readers, offline verdict ==
live verdict == the linear theory's).
"""

import json
import math
from pathlib import Path
import subprocess
import sys

from gyro_rotor.analysis.offline import analyze_bag
from gyro_rotor.analysis.prediction import predict
from gyro_rotor.bag.bagio import open_bag
from gyro_rotor.core.scene import list_scenes, load_scene, scene_from_flat
from gyro_rotor.core.system.model import GeneralModel, joint_names
from gyro_rotor.errors import GyroRotorError
from gyro_rotor.node_settings import NODE_KEYS
from gyro_rotor.numerics.live import LiveSimulation
import numpy as np
import pytest
import yaml

SHIPPED = ('centrifuge_euler', 'elastic_frame', 'twin_gimbal')


def _sim(name='twin_gimbal', **kick):
    cfg = {k: v[1] for k, v in NODE_KEYS.items()}
    cfg['real_time_factor'] = 0.0
    return LiveSimulation(load_scene(name), cfg, kick, budget=None)


def _run_to(sim, t):
    blocks = []
    while sim.stepper.t < t and not sim.diverged:
        b = sim.tick()
        if b is not None:
            blocks.append(b)
    return blocks


def test_the_shipped_system_file_scenes_are_the_ones_tested():
    assert tuple(list_scenes(builtin=False)) == SHIPPED


def test_outputs_name_coordinates_and_rotor_lags():
    sim = _sim()
    scene = sim.scene
    assert sim.joint_names == ('alpha', 'beta1', 'beta2', 'z_R1', 'z_R2')
    assert sim.joint_names == joint_names(scene.system)
    b = _run_to(sim, 0.2)[-1]
    assert b.position.shape[1] == b.velocity.shape[1] == 5 and b.effort.shape[1] == 0
    assert set(b.energy) == set(GeneralModel.energy_fields) and b.quaternion is None
    y = sim.last[1]
    m = sim.model
    sq, sqd, sz, szd = m.slices()
    np.testing.assert_array_equal(b.position[-1], np.concatenate([y[sq], y[sz]]))
    np.testing.assert_array_equal(b.velocity[-1], np.concatenate([y[sqd], y[szd]]))
    K_D = np.array([d.K_D for d in scene.system.drives])
    assert b.energy['dE_dt'][-1] == pytest.approx(-(y[szd] ** 2) @ K_D, rel=1e-12)
    assert abs(b.energy['residual']).max() < 1e-9


def test_a_bad_constant_is_refused_and_changes_nothing():
    sim = _sim()
    _run_to(sim, 0.1)
    y, E_ref, scene = sim.stepper.y.copy(), sim.baseline.E_ref, sim.scene
    for change, word in (({'constants.J_g': -1.0}, 'not positive definite'),
                         ({'constants.nope': 1.0}, "unknown constant 'nope'"),
                         ({'drive.R1.K_D': -1.0}, 'K_D'),
                         ({'drive.R3.K_D': 1.0}, "unknown key 'drive.R3.K_D'"),
                         ({'perturbation.qdot': [1.0]}, '3 finite numbers'),
                         ({'integrator': 'split8'}, 'general systems integrate with')):
        with pytest.raises(GyroRotorError, match=word):
            sim.check(change)
    assert sim.scene is scene and sim.baseline.E_ref == E_ref
    np.testing.assert_array_equal(sim.stepper.y, y)


def test_a_constant_change_moves_the_baseline_by_the_jump_of_E_star():
    sim = _sim()
    _run_to(sim, 0.2)
    y = sim.stepper.y.copy()
    E_old = float(sim.model.energy(y))
    E_ref = sim.baseline.E_ref
    sim.check({'constants.c_a': 60.0})
    sim.apply({'constants.c_a': 60.0})
    assert sim.diverged is None and sim.scene.system.constants['c_a'] == 60.0
    # V = c_a alpha^2 / 2: E* jumps by (60 - 40) alpha^2 / 2, the baseline with it
    assert sim.baseline.E_ref - E_ref == pytest.approx(10.0 * y[0] ** 2, rel=1e-9)
    assert float(sim.model.energy(y)) - E_old == pytest.approx(10.0 * y[0] ** 2, rel=1e-9)
    blocks = _run_to(sim, 0.6)
    resid = np.concatenate([b.energy['residual'] for b in blocks])
    assert np.abs(resid).max() < 1e-9
    E = np.concatenate([b.energy['E_star'] for b in blocks])
    assert np.all(np.diff(E) <= 1e-12)          # still a Lyapunov function (eq. 17)


def test_an_omega0_change_keeps_the_absolute_spin_of_that_rotor():
    sim = _sim()
    _run_to(sim, 0.1)
    zdot = sim.stepper.y[sim.model.slices()[3]].copy()
    sim.apply({'drive.R2.Omega0': 260.0})
    np.testing.assert_allclose(sim.stepper.y[sim.model.slices()[3]],
                               zdot - np.array([0.0, 10.0]), rtol=0, atol=1e-12)


def test_a_kick_adds_to_the_state_and_moves_the_baseline():
    sim = _sim(qdot=[0.0, 0.0, 0.05])
    _run_to(sim, 0.1)
    y = sim.stepper.y.copy()
    E_ref = sim.baseline.E_ref
    sim.perturb()
    assert sim.stepper.y[5] == pytest.approx(y[5] + 0.05, abs=1e-15)
    assert sim.baseline.E_ref > E_ref
    blocks = _run_to(sim, 0.3)
    assert np.abs(np.concatenate([b.energy['residual'] for b in blocks])).max() < 1e-9


def test_the_scene_document_rebuilds_the_scene_without_the_system_file():
    for name in SHIPPED:
        scene = load_scene(name)
        flat = yaml.safe_load(yaml.safe_dump(scene.to_flat()))
        flat['system'] = 'a/file/that/does/not/exist.yaml'
        again = scene_from_flat(flat)
        assert again.system.constants == scene.system.constants
        assert again.system.drives == scene.system.drives
        np.testing.assert_array_equal(again.initial_state(), scene.initial_state())


def _readers(bag: Path) -> dict:
    """Message counts of joint_states by three readers: mcap, rosbags, the package's own."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import get_typestore, Stores
    (mcap_file,) = bag.glob('*.mcap')
    with open(mcap_file, 'rb') as f:
        names = [dec.name for _, ch, _, dec in make_reader(
            f, decoder_factories=[DecoderFactory()]).iter_decoded_messages(
                topics=['/joint_states'])]
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as r:
        conns = [c for c in r.connections if c.topic == '/joint_states']
        rb = [r.deserialize(raw, c.msgtype).name for c, _, raw in r.messages(connections=conns)]
    own = open_bag(bag)
    return {'mcap': (len(names), names[0]), 'rosbags': (len(rb), list(rb[0])),
            'own': (own.topics['/joint_states'].count, None)}


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.parametrize('name', SHIPPED)
def test_demo_of_a_system_file_scene_live_equals_offline_equals_theory(name, tmp_path):
    out = tmp_path / 'demo'
    r = subprocess.run([sys.executable, '-m', 'gyro_rotor', 'demo', name, '--duration', '10',
                        '--rtf', '0', '--quiet', '--out', str(out)], capture_output=True,
                       text=True, timeout=300)
    assert 'Traceback' not in r.stderr, r.stderr[-3000:]
    scene = load_scene(name)
    expected = predict(scene).verdict
    # twin_gimbal: E*'s slowest showing term (the 6.11 Hz gimbal mode, 0.062 1/s) is not
    # decided in the 8 s window, the decay criterion alone stays NOT YET: not confirmed
    undecided = name == 'twin_gimbal'
    if undecided:
        expected = 'insufficient data'
        assert r.returncode == 1, r.stdout[-3000:] + r.stderr[-3000:]
        assert 'RESULT: NOT CONFIRMED: insufficient data' in r.stdout
    else:
        assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
        assert f'RESULT: CONFIRMED: {expected}' in r.stdout
    bag = out / 'bag'
    counts = _readers(bag)
    joints = list(joint_names(scene.system))
    assert counts['mcap'][1] == counts['rosbags'][1] == joints
    assert counts['mcap'][0] == counts['rosbags'][0] == counts['own'][0] == 2501
    reader = open_bag(bag)
    assert reader.topics['/energy'].count == 2501
    assert '/axis' not in reader.topics or reader.topics['/axis'].count == 0
    live = json.loads(reader.metadata['gyro_rotor.live_result']['json'])
    offline = analyze_bag(bag)
    assert live['verdict'] == str(offline.result.verdict) == expected
    assert offline.result.samples == 2501 and offline.result.unpaired == 0
    assert {c.name: str(c.status) for c in offline.result.criteria} == {
        'Lyapunov': 'PASS', 'energy balance': 'PASS',
        'decay': 'NOT YET' if undecided else 'PASS', 'modes': 'PASS', 'data': 'PASS',
        'scene': 'PASS'}
    assert math.isfinite(offline.result.judged.E_last)
    # the analysis of a recording of another system is refused with one line
    r = subprocess.run([sys.executable, '-m', 'gyro_rotor', 'analyze', str(bag), '--scene',
                        'precession'], capture_output=True, text=True, timeout=120)
    assert r.returncode == 1 and r.stderr.startswith('ERROR: joint_states names ')
    assert r.stderr.count('\n') == 1 and 'a recording of another system' in r.stderr


def test_a_centrifuge_bag_is_not_analysed_as_a_general_system():
    bag = Path(__file__).resolve().parents[1] / 'bags' / 'precession'
    r = subprocess.run([sys.executable, '-m', 'gyro_rotor', 'analyze', str(bag), '--scene',
                        'twin_gimbal'], capture_output=True, text=True, timeout=120)
    assert r.returncode == 1, r.stdout[-2000:]
    assert r.stderr == ('ERROR: joint_states names theta, psi, phi_R, phi_M but scene '
                        "'twin_gimbal' has the joints alpha, beta1, beta2, z_R1, z_R2: a "
                        'recording of another system\n')


@pytest.mark.ros
def test_rotor_sim_declares_a_system_file_scenes_parameters_and_checks_changes():
    rclpy = pytest.importorskip('rclpy')
    from gyro_rotor.ros.sim_node import RotorSimNode
    from rclpy.parameter import Parameter
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    try:
        node = RotorSimNode(context=ctx, parameter_overrides=[
            Parameter('scene', value='twin_gimbal'), Parameter('constants.c_a', value=50.0),
            Parameter('real_time_factor', value=0.0)])
        try:
            names = set(node._parameters)
            assert {'system', 'constants.c_a', 'drive.R1.K_D', 'drive.R2.pole_pairs',
                    'initial.q', 'perturbation.zdot'} <= names
            assert node.sim.scene.system.constants['c_a'] == 50.0     # the start override
            for params, word in (([Parameter('constants.J_g', value=-1.0)],
                                  'not positive definite'),
                                 ([Parameter('constants.c_a', value=40)], 'write 40.0'),
                                 ([Parameter('drive.R1.K_D', value=-1.0)], 'K_D'),
                                 ([Parameter('initial.q', value=[0.0, 0.0, 0.0])],
                                  'read-only')):
                (res,) = node.set_parameters(params)
                assert not res.successful and word in res.reason, res.reason
            E_ref = node.sim.baseline.E_ref
            (res,) = node.set_parameters([Parameter('drive.R1.K_S', value=12.0)])
            assert res.successful, res.reason
            assert node.sim.scene.system.drives[0].K_S == 12.0
            z1 = node.sim.stepper.y[node.sim.model.slices()[2]][0]
            assert node.sim.baseline.E_ref - E_ref == pytest.approx(1.0 * z1 ** 2, abs=1e-15)
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)


def test_the_live_layouts_are_the_wire_layouts():
    from gyro_rotor.bag import wire
    from gyro_rotor.core.model import MODELS
    from gyro_rotor.numerics.live import ENERGY_COLUMNS
    for model in MODELS.values():        # every model of the centrifuge
        assert model.joint_names == wire.JOINT_NAMES
        assert model.energy_fields == ENERGY_COLUMNS == wire.ENERGY_FIELDS
    cfg = {k: v[1] for k, v in NODE_KEYS.items()}
    sim = LiveSimulation(load_scene('precession'), cfg, budget=None)
    assert sim.joint_names == wire.JOINT_NAMES and sim.energy_fields == wire.ENERGY_FIELDS


def test_the_committed_general_bag_gives_the_live_verdict_offline():
    """bags/twin_gimbal (bags/record.sh): read without the system file, live == offline."""
    bag = Path(__file__).resolve().parents[1] / 'bags' / 'twin_gimbal'
    ana = analyze_bag(bag)
    assert ana.live is not None and ana.live['verdict'] == str(ana.result.verdict)
    # E*'s slowest showing term (the 6.11 Hz gimbal mode, 0.062 1/s) is not decided in 8 s
    # windows: the decay criterion alone is NOT YET, every other one passes
    assert str(ana.result.verdict) == 'insufficient data'
    assert {c.name.value: str(c.status) for c in ana.result.criteria
            if str(c.status) != 'PASS'} == {'decay': 'NOT YET'}
    assert ana.result.samples == ana.live['samples'] == 3001
    assert ana.result.dropped == 0 and ana.result.unpaired == 0 and not ana.truncated
    live_modes = {m['name']: m['status'] for m in ana.live['segments'][-1]['modes']}
    assert {m.name: str(m.status) for m in ana.result.judged.modes} == live_modes
    record = yaml.safe_load(open_bag(bag).metadata['gyro_rotor.scene']['flat'])
    assert record['system_doc']['name'] == 'twin_gimbal'     # the system travels in the bag


def test_a_scene_document_of_the_same_scene_changes_nothing_in_the_analysis():
    """The scene from a file and the same scene from rotor_sim's document (no file path)."""
    from gyro_rotor.analysis.analyzer import RotorAnalyzer
    scene = load_scene('twin_gimbal')
    again = scene_from_flat(yaml.safe_load(yaml.safe_dump(
        scene.to_flat())))
    assert again.system.reduced.path is None and scene.system.reduced.path is not None
    a = RotorAnalyzer(scene)
    assert not a.set_scene(again) and a.param_changes == 0
    assert a.set_scene(scene.with_changes({'drive.R1.K_D': 0.05})) and a.param_changes == 1


def test_the_scene_list_names_the_system_file_scenes(capsys):
    from gyro_rotor.cli.main import main
    assert main(['scenes']) == 0
    lines = capsys.readouterr().out.splitlines()
    for name in SHIPPED:
        line = next(ln for ln in lines if ln.startswith(name + ' '))
        assert f'system {load_scene(name).system.name}' in line


# -- found in review: each of these failed before its fix ---------------------------------
def _locked_scene(tmp_path):
    path = tmp_path / 'locked.yaml'
    path.write_text(yaml.safe_dump({'rotor_sim': {'ros__parameters': {
        'scene': 'locked', 'system': 'twin_gimbal', 'locked': ['beta2'],
        'initial': {'q': [0.006, 0.015, 0.0], 'qdot': [0.0, 0.06, 0.0]},
        'perturbation': {'qdot': [0.0, 0.01, 0.0]}}}}))
    return str(path)


def test_a_ros_double_array_kick_is_taken_and_a_bad_one_refused():
    import array
    sim = _sim()
    sim.check({'perturbation.qdot': array.array('d', [0.0, 0.1, 0.0])})
    sim.apply({'perturbation.qdot': array.array('d', [0.0, 0.1, 0.0])})
    assert sim.perturbation['qdot'] == [0.0, 0.1, 0.0]
    for bad in (array.array('d', [0.0, 0.1]), 'abc', [0.0, math.nan, 0.0]):
        with pytest.raises(GyroRotorError, match='must be 3 finite numbers'):
            sim.check({'perturbation.qdot': bad})


def test_a_scene_with_a_locked_coordinate_runs_and_kicks_the_free_ones(tmp_path):
    cfg = {k: v[1] for k, v in NODE_KEYS.items()}
    scene = load_scene(_locked_scene(tmp_path))
    assert scene.system.coordinates == ('alpha', 'beta1')
    sim = LiveSimulation(scene, cfg, {'qdot': [0.0, 0.01, 0.0]}, budget=None)
    assert sim.joint_names == ('alpha', 'beta1', 'z_R1', 'z_R2')
    y = sim.stepper.y.copy()
    sim.perturb()
    assert sim.stepper.y[3] == pytest.approx(y[3] + 0.01)       # beta1_dot (n = 2)
    with pytest.raises(GyroRotorError, match='locked coordinate beta2 cannot be kicked'):
        sim.check({'perturbation.qdot': [0.0, 0.0, 0.1]})


def test_a_live_t_end_survives_a_later_change_of_the_drives():
    sim = _sim()
    sim.apply({'t_end': 50.0})
    sim.apply({'drive.R1.K_D': 0.05})
    assert sim.scene.t_end == 50.0 and sim.scene_doc()['flat']['t_end'] == 50.0


def test_a_common_drive_key_sets_every_drive_after_a_per_rotor_one():
    scene = load_scene('twin_gimbal').with_changes({'drive.R1.K_D': 0.05})
    assert [d.K_D for d in scene.with_changes({'K_D': 0.5}).system.drives] == [0.5, 0.5]


def test_a_sine_law_run_ending_on_an_unpaired_sample_is_judged():
    from gyro_rotor.analysis.analyzer import RotorAnalyzer
    from gyro_rotor.analysis.samples import samples_from_trajectory, SamplePairer
    from gyro_rotor.numerics.simulate import simulate
    scene = load_scene('twin_gimbal', {'drive.R2.pole_pairs': 1})
    samples = samples_from_trajectory(simulate(scene, t_end=3.0, rate=250.0))
    assert len(samples) == 751
    pairer = SamplePairer()
    pairer.add_energy(10 ** 10, {'t_sim': 10.0, 'E_star': samples[-1].E_star, 'seq': 751,
                                 'k': 751, 'residual': 0.0})
    (lost,) = pairer.flush()                       # its joint state never came
    assert not lost.joints
    a = RotorAnalyzer(scene)
    a.add_many(samples + [lost])
    res = a.result()
    assert a.non_finite == 0 and res.segments[-1].well == 0


def test_the_deviation_channels_keep_theta_and_drop_only_the_cyclic_direction():
    pred = predict(load_scene('centrifuge_euler'))
    P = np.array(pred.active_q)
    assert P.shape == (2, 3)
    assert np.linalg.norm(P @ [1.0, 0.0, 0.0]) == pytest.approx(1.0)   # theta is seen
    assert np.linalg.norm(P @ [0.0, 1.0, -1.0]) < 1e-9               # the cyclic drift is not


@pytest.mark.ros
def test_rotor_sim_refuses_another_system_and_runs_a_locked_scene(tmp_path):
    rclpy = pytest.importorskip('rclpy')
    from gyro_rotor.ros.sim_node import RotorSimNode
    from rclpy.parameter import Parameter
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    try:
        with pytest.raises(GyroRotorError, match="'elastic_frame' is not the system of scene"):
            RotorSimNode(context=ctx, parameter_overrides=[
                Parameter('scene', value='twin_gimbal'),
                Parameter('system', value='elastic_frame')])
        node = RotorSimNode(context=ctx, parameter_overrides=[
            Parameter('scene', value=_locked_scene(tmp_path))])
        try:
            assert node.sim.joint_names == ('alpha', 'beta1', 'z_R1', 'z_R2')
            (res,) = node.set_parameters([Parameter(
                'perturbation.qdot', Parameter.Type.DOUBLE_ARRAY, [0.0, 0.2, 0.0])])
            assert res.successful, res.reason
            (res,) = node.set_parameters([Parameter(
                'perturbation.qdot', Parameter.Type.DOUBLE_ARRAY, [0.0, 0.2])])
            assert not res.successful and 'must be 3 finite numbers' in res.reason
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)
