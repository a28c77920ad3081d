"""The URDFs of the shipped systems: robot_state_publisher's TF is the model's kinematics.

Every shipped system has ``urdf/NAME.urdf`` (the built-in centrifuge ``centrifuge.urdf``),
whose moving joints are the names rotor_sim publishes on ``joint_states``. For the
centrifuge the chain is the model's 3-1-3 convention (rotations against the quaternion
model, 1e-12); for every system the chain's rotor spin is the system's guidance (eq. 2):
the angular velocity of rotor k's link along its spin axis is B_k(q) qdot + zdot_k at
random states, 1e-12 (robot_state_publisher itself cannot run here).
"""

import math
from pathlib import Path
import xml.etree.ElementTree as ET

from gyro_rotor.bag import wire
from gyro_rotor.core.rotations import axis_from_quaternion, quaternion_from_euler
from gyro_rotor.core.system.model import joint_names
from gyro_rotor.core.system.system_file import list_systems, load_system
import numpy as np
import pytest
import sympy

REPO = Path(__file__).resolve().parents[1]
URDF = REPO / 'urdf' / 'centrifuge.urdf'
#: joint_states names, as rotor_sim publishes them (the pure wire layouts: no rclpy needed)
JOINT_NAMES = wire.JOINT_NAMES
MOVING = ('revolute', 'continuous', 'prismatic')


def _rpy(r, p, y):
    """URDF rpy: fixed-axis roll, pitch, yaw, R = Rz(y) Ry(p) Rx(r)."""
    cr, sr, cp, sp, cy, sy = (math.cos(r), math.sin(r), math.cos(p), math.sin(p),
                              math.cos(y), math.sin(y))
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def _axis_angle(axis, a):
    """Rodrigues' rotation about the unit vector ``axis`` by ``a``."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(a) * K + (1 - math.cos(a)) * K @ K


def _joints(path=URDF):
    root = ET.parse(path).getroot()
    out = {}
    for j in root.findall('joint'):
        origin = j.find('origin')
        xyz = [float(v) for v in (origin.get('xyz', '0 0 0') if origin is not None
                                  else '0 0 0').split()]
        rpy = [float(v) for v in (origin.get('rpy', '0 0 0') if origin is not None
                                  else '0 0 0').split()]
        axis = j.find('axis')
        out[j.get('name')] = {'type': j.get('type'), 'parent': j.find('parent').get('link'),
                              'child': j.find('child').get('link'), 'xyz': xyz, 'rpy': rpy,
                              'axis': [float(v) for v in (axis.get('xyz').split()
                                                          if axis is not None else (1, 0, 0))]}
    return root, out


def _chain(joints, link):
    """Return the joints from the root down to ``link``, and the root's name."""
    by_child = {j['child']: (name, j) for name, j in joints.items()}
    chain = []
    while link in by_child:
        name, j = by_child[link]
        chain.append((name, j))
        link = j['parent']
    return chain[::-1], link


def _kinematics(joints, link, q, qdot=None):
    """World rotation and angular velocity of ``link`` at joint positions/rates (dicts)."""
    chain, root = _chain(joints, link)
    R, w = np.eye(3), np.zeros(3)
    for name, j in chain:
        R = R @ _rpy(*j['rpy'])
        if j['type'] in ('revolute', 'continuous'):
            w = w + (qdot or {}).get(name, 0.0) * (R @ np.asarray(j['axis']))
            R = R @ _axis_angle(j['axis'], q[name])
    return R, w, root


def _link_rotation(joints, link, q):
    R, _, root = _kinematics(joints, link, q)
    return R, root


def test_urdf_joints_are_the_joint_states_names():
    root, joints = _joints()
    assert root.tag == 'robot'
    assert set(joints) == set(JOINT_NAMES)
    links = {ln.get('name') for ln in root.findall('link')}
    for j in joints.values():
        assert j['parent'] in links and j['child'] in links
        assert j['xyz'] == [0.0, 0.0, 0.0]          # every joint turns about F
    assert joints['theta']['type'] == 'revolute'
    assert all(joints[n]['type'] == 'continuous' for n in ('psi', 'phi_R', 'phi_M'))


def test_urdf_forward_kinematics_is_the_models_3_1_3_convention():
    """Housing = Rz(psi) Rx(theta) Rz(phi_M), rotor likewise with phi_R; axis e_3; 1e-12."""
    _, joints = _joints()
    rng = np.random.default_rng(7)
    for _ in range(200):
        psi, phi_R, phi_M = rng.uniform(-math.pi, math.pi, 3)
        theta = rng.uniform(0.0, math.pi)
        q = {'psi': psi, 'theta': theta, 'phi_R': phi_R, 'phi_M': phi_M}
        for link, phi in (('housing', phi_M), ('rotor', phi_R)):
            R, root = _link_rotation(joints, link, q)
            assert root == 'world'
            w, x, y, z = quaternion_from_euler(psi, theta, phi)
            R_model = np.array([
                [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
            assert np.max(np.abs(R - R_model)) < 1e-12
            axis = axis_from_quaternion(quaternion_from_euler(psi, theta, phi))
            assert np.max(np.abs(R[:, 2] - axis)) < 1e-12


def test_urdf_fails_on_a_wrong_convention():
    """The kinematics check can fail: a 3-2-3 chain (theta about y) is caught."""
    _, joints = _joints()
    joints['theta']['axis'] = [0.0, 1.0, 0.0]
    R, _ = _link_rotation(joints, 'housing', {'psi': 0.3, 'theta': 0.4, 'phi_R': 0.0,
                                              'phi_M': 0.2})
    axis = axis_from_quaternion(quaternion_from_euler(0.3, 0.4, 0.2))
    assert np.max(np.abs(R[:, 2] - axis)) > 1e-3


# -- every shipped system --------------------------------------------------------------
SYSTEMS = tuple(list_systems())


def test_every_shipped_system_has_a_urdf():
    assert set(SYSTEMS) >= {'centrifuge_euler', 'twin_gimbal', 'elastic_frame'}
    assert {p.stem for p in (REPO / 'urdf').glob('*.urdf')} == set(SYSTEMS) | {'centrifuge'}


def _spin_error(system, joints, rng, samples=200) -> float:
    """Max |rotor spin of the chain - (B_k(q) qdot + zdot_k)| over random states."""
    consts = dict(zip(system.constant_symbols(), system.constants.values()))
    B = sympy.lambdify(system.q_symbols(), system.guidance.subs(consts), 'numpy')
    names = joint_names(system)
    worst = 0.0
    for _ in range(samples):
        pos, rate = rng.uniform(-1.2, 1.2, len(names)), rng.uniform(-3.0, 3.0, len(names))
        q, qdot = dict(zip(names, pos)), dict(zip(names, rate))
        expected = np.asarray(B(*pos[:system.n]), float) @ rate[:system.n] + rate[system.n:]
        for k, rotor in enumerate(system.rotors):
            j = joints[f'z_{rotor}']
            R, w, root = _kinematics(joints, j['child'], q, qdot)
            assert root == 'world'
            spin_axis = R @ np.asarray(j['axis'])    # the rotor joint's axis turns with it
            worst = max(worst, abs(w @ spin_axis - expected[k]))
    return worst


@pytest.mark.parametrize('name', SYSTEMS)
def test_system_urdf_is_its_joint_states_and_its_guidance(name):
    """Moving joints = joint_states names; one tree from world; rotor spin = eq. (2)."""
    system = load_system(name)
    root, joints = _joints(REPO / 'urdf' / f'{name}.urdf')
    assert root.tag == 'robot'
    moving = {n for n, j in joints.items() if j['type'] in MOVING}
    assert moving == set(joint_names(system))
    links = {ln.get('name') for ln in root.findall('link')}
    children = [j['child'] for j in joints.values()]
    assert len(children) == len(set(children)) and set(children) == links - {'world'}
    assert _spin_error(system, joints, np.random.default_rng(3)) < 1e-12


def test_system_urdf_check_can_fail():
    """A rotor mounted at the wrong angle (gam1 negated) breaks eq. (2) and is caught."""
    system = load_system('twin_gimbal')
    _, joints = _joints(REPO / 'urdf' / 'twin_gimbal.urdf')
    joints['gam1']['rpy'] = [-v for v in joints['gam1']['rpy']]
    assert _spin_error(system, joints, np.random.default_rng(3), samples=20) > 1e-3
