"""The singularity-free model against an independent Lagrange implementation (eqs. 18, 19, 23)."""

import functools
import math
import subprocess
import sys

from gyro_rotor.core.model import FullModel, LockedHousingModel, UprightAxisModel
from gyro_rotor.core.params import RotorParams
from gyro_rotor.core.rotations import (body_rates_from_euler, euler_from_quaternion,
                                       euler_rates_from_body, quaternion_from_euler)
from gyro_rotor.core.scene import load_scene
from hypothesis import given, settings, strategies as st
import mpmath
import numpy as np
import pytest
from scipy.integrate import solve_ivp

EPS = np.finfo(float).eps
TINY = np.finfo(float).smallest_subnormal


def lagrange_rhs(p: RotorParams):
    """Lagrange equations of T (18), V (19), drive (23) in (theta, psi, phi_R, phi_M).

    Written from the Lagrangian alone, independent of gyro_rotor.core.model: mass matrix M(theta),
    M qdd = Q - dV/dq + dT/dq - (dM/dtheta thetadot) qd.
    """
    I, C_R, C_M = p.A_R + p.A_M, p.C_R, p.C_M

    def f(t, x):
        th, ps, pR, pM, thd, psd, pRd, pMd = x
        s, c = np.sin(th), np.cos(th)
        qd = np.array([thd, psd, pRd, pMd])
        M = np.array([[I, 0, 0, 0],
                      [0, I * s * s + (C_R + C_M) * c * c, C_R * c, C_M * c],
                      [0, C_R * c, C_R, 0],
                      [0, C_M * c, 0, C_M]])
        dM = np.array([[0, 0, 0, 0],
                       [0, 2 * I * s * c - 2 * (C_R + C_M) * c * s, -C_R * s, -C_M * s],
                       [0, -C_R * s, 0, 0],
                       [0, -C_M * s, 0, 0]])
        dT = np.array([0.5 * qd @ dM @ qd, 0, 0, 0])
        chi = pM + ps
        dV = np.array([-p.G * p.s * s + p.c_theta * th, p.c_psi * chi, 0, p.c_psi * chi])
        z = (pR - pM) - p.Omega0 * t
        zd = (pRd - pMd) - p.Omega0
        if p.pole_pairs:
            Q = -(p.K_S / p.pole_pairs) * np.sin(p.pole_pairs * z) - p.K_D * zd
        else:
            Q = -p.K_S * z - p.K_D * zd
        gen = np.array([0, 0, Q, -Q])
        qdd = np.linalg.solve(M, gen - dV + dT - dM @ qd * thd)
        return np.concatenate([qd, qdd])
    return f


@pytest.mark.parametrize('scene_name', ['precession', 'nutation', 'pole_slip_tilted'])
def test_agrees_with_euler_lagrange(scene_name):
    if scene_name == 'pole_slip_tilted':
        scene = load_scene('pole_slip', overrides={'initial.dtheta': 0.2})
    else:
        scene = load_scene(scene_name)
    p = scene.system.params
    model = FullModel(p)
    y0 = scene.initial_state(model)
    ic = scene.system.initial
    sm = scene.system.steady()
    th0, thd0 = sm.theta0 + ic.dtheta, ic.dthetadot
    psd0, pMd0 = sm.psidot0 + ic.dpsidot, -sm.psidot0
    x0 = [th0, 0.0, ic.dchi + ic.dz, ic.dchi, thd0, psd0, pMd0 + ic.dzdot + p.Omega0, pMd0]
    T = 2.0
    ref = solve_ivp(lagrange_rhs(p), (0, T), x0, method='DOP853', rtol=1e-13, atol=1e-13)
    sol = solve_ivp(model.rhs, (0, T), y0, method='DOP853', rtol=1e-13, atol=1e-13)
    th, ps, pR, pM, thd, psd, pRd, pMd = ref.y[:, -1]
    y = sol.y[:, -1]
    axis_ref = np.array([np.sin(ps) * np.sin(th), -np.cos(ps) * np.sin(th), np.cos(th)])
    axis = model.outputs(np.array([T]), y[None, :])['axis'][0]
    assert np.linalg.norm(axis - axis_ref) < 1e-9
    q_ref = quaternion_from_euler(ps, th, pM)
    assert min(np.linalg.norm(y[:4] - q_ref), np.linalg.norm(y[:4] + q_ref)) < 1e-9
    W_ref = body_rates_from_euler(ps, th, pM, psd, thd, pMd)
    assert np.linalg.norm(y[4:7] - W_ref) < 1e-8 * max(1.0, np.linalg.norm(W_ref))
    assert abs(y[7] - ((pR - pM) - p.Omega0 * T)) < 1e-9
    assert abs(y[8] - ((pRd - pMd) - p.Omega0)) < 1e-8


def test_energy_rate_identity_eq17():
    """dE*/dt along the vector field equals -K_D zdot^2 (finite difference of E*)."""
    rng = np.random.default_rng(1)
    for p in (RotorParams(), RotorParams(pole_pairs=3, K_D=0.7)):
        m = FullModel(p)
        for _ in range(5):
            y = m.state_from_euler(theta=rng.uniform(0.01, 1.0), thetadot=rng.normal(),
                                   psi=rng.normal(), psidot=rng.normal(), phi_M=rng.normal(),
                                   phi_M_dot=rng.normal(), z=rng.normal(), zdot=rng.normal())
            f = m.rhs(0.0, y)
            h = 1e-6
            dE = (m.energy(y + h * f) - m.energy(y - h * f)) / (2 * h)
            assert dE == pytest.approx(-p.K_D * y[8] ** 2, abs=1e-6)


def test_rhs_regular_at_theta_zero():
    m = FullModel(RotorParams())
    y = m.state_from_euler(theta=0.0, thetadot=0.3, psidot=0.2, phi_M_dot=-0.2)
    f0 = m.rhs(0.0, y)
    assert np.all(np.isfinite(f0))
    # continuous through theta = 0: the change is O(theta * c_theta / I) ~ 4e-7 here
    y2 = m.state_from_euler(theta=1e-9, thetadot=0.3, psidot=0.2, phi_M_dot=-0.2)
    assert np.allclose(m.rhs(0.0, y2), f0, atol=1e-6)


def test_quaternion_euler_roundtrip():
    rng = np.random.default_rng(2)
    psi, th, phi = rng.uniform(-3, 3, 50), rng.uniform(0.01, 3.1, 50), rng.uniform(-3, 3, 50)
    q = quaternion_from_euler(psi, th, phi)
    ps2, th2, ph2 = euler_from_quaternion(q)
    assert np.allclose(th2, th)
    assert np.allclose(np.angle(np.exp(1j * (ps2 - psi))), 0, atol=1e-9)
    assert np.allclose(np.angle(np.exp(1j * (ph2 - phi))), 0, atol=1e-9)
    W = body_rates_from_euler(psi, th, phi, 0.3, -0.2, 5.0)
    psd, thd, phd = euler_rates_from_body(th, phi, W)
    assert np.allclose(psd, 0.3) and np.allclose(thd, -0.2) and np.allclose(phd, 5.0)


def to_full(model, Y) -> np.ndarray:
    """Return the full model's state(s) equivalent to a reduced model's."""
    Y = np.atleast_2d(np.asarray(Y, dtype=float))
    return np.column_stack([model.quaternion(Y), model.body_rates(Y), Y[:, model.iz],
                            Y[:, model.izd], Y[:, model.idiss]])


def test_reduced_models_are_the_full_model_restricted():
    p = RotorParams()
    full = FullModel(p)
    up = UprightAxisModel(p)
    y_up = np.array([0.05, 0.3, 0.1, -0.4, 0.0])
    y_full = to_full(up, y_up)[0]
    assert np.allclose(to_full(up, up.rhs(0, y_up)[None, :] * 0 + y_up)[0], y_full)
    f_full = full.rhs(0.0, y_full)
    f_up = up.rhs(0.0, y_up)
    assert f_full[6] == pytest.approx(f_up[1])       # chi'' = dW3/dt at theta = 0
    assert f_full[8] == pytest.approx(f_up[3])
    assert up.energy(y_up) == pytest.approx(full.energy(y_full))
    lk = LockedHousingModel(p)
    y_lk = np.array([0.1, -0.4, 0.0])
    assert lk.energy(y_lk) == pytest.approx(full.energy(to_full(lk, y_lk)[0]))


def test_core_does_not_import_rclpy():
    code = ('import sys\n'
            'import gyro_rotor, gyro_rotor.core.params, gyro_rotor.core.model\n'
            'import gyro_rotor.core.steady, gyro_rotor.core.scene, gyro_rotor.core.rotations\n'
            'import gyro_rotor.numerics.simulate, gyro_rotor.cli.main\n'
            'from gyro_rotor.numerics.simulate import simulate\n'
            'simulate("precession", t_end=0.1)\n'
            'bad = [m for m in sys.modules\n'
            '       if m.startswith(("rclpy", "sensor_msgs", "std_msgs"))]\n'
            'assert not bad, bad\n')
    subprocess.run([sys.executable, '-c', code], check=True)


def test_compiled_scalar_forms_equal_the_blends():
    # the kernels compile drive_law, tilt_ratio and twist_angle on floats as an if
    # (core.model): the same numbers as the 0/1 blends, both laws, both sides of the rational's
    # reach (theta = 2 atan 0.66 = 1.167, chi likewise) and the quaternion's other sign
    numba = pytest.importorskip('numba')
    from gyro_rotor.core.model import drive_law, tilt_ratio, twist_angle

    @numba.njit
    def compiled(z, zd, K_S, K_D, pp, a, b, qz, qw):
        return drive_law(z, zd, K_S, K_D, pp), tilt_ratio(a, b), twist_angle(qz, qw)
    blends = (numba.njit(drive_law), numba.njit(tilt_ratio), numba.njit(twist_angle))
    rng = np.random.default_rng(3)
    for pp in (0.0, 1.0, 2.0, 4.0):
        for th in (0.0, 3e-5, 1e-4, 0.3, 1.16, 1.1674, 1.17, 2.0, 3.1):
            z, zd, K_S, K_D = rng.normal(size=4) * (3.0, 5.0, 10.0, 0.5)
            a, b = np.sin(th / 2.0) ** 2, np.cos(th / 2.0) ** 2
            qz = np.sin(th / 2.0) * rng.choice((-1.0, 1.0))
            qw = np.cos(th / 2.0) * rng.choice((-1.0, 1.0))
            got = compiled(z, zd, K_S, K_D, pp, a, b, qz, qw)
            want = (blends[0](z, zd, K_S, K_D, pp), blends[1](a, b), blends[2](qz, qw))
            assert got == want, (pp, th)
            plain = (drive_law(z, zd, K_S, K_D, pp), tilt_ratio(a, b), twist_angle(qz, qw))
            assert np.allclose(got, plain, rtol=1e-15, atol=0.0)


@settings(max_examples=300, deadline=None)
@given(st.floats(0.0, 3.14159), st.floats(-3.14159, 3.14159), st.floats(0.5, 2.0))
def test_the_rational_angles_are_within_a_few_eps_of_atan2(theta, chi, norm):
    # theta/sin theta and chi = 2 atan2(q_z, q_w) without atan2 (core.model): against atan2 in
    # 40 digits, on a quaternion of any norm near 1, on both sides of the rational's reach,
    # compiled (the kernels' form) and as blends (floats and arrays)
    numba = pytest.importorskip('numba')
    from gyro_rotor.core.model import tilt_ratio, twist_angle
    compiled = _compiled_angles(numba)
    a = norm * math.sin(theta / 2.0) ** 2
    b = norm * math.cos(theta / 2.0) ** 2
    qz, qw = math.sqrt(norm) * math.sin(chi / 2.0), math.sqrt(norm) * math.cos(chi / 2.0)
    with mpmath.workdps(40):
        half = mpmath.atan2(mpmath.sqrt(mpmath.mpf(a)), mpmath.sqrt(mpmath.mpf(b)))
        ratio = float(2 * half / mpmath.sin(2 * half)) if half > 0 else 1.0
        twist = float(2 * mpmath.atan2(mpmath.mpf(qz), mpmath.mpf(qw)))
    arrays = (tilt_ratio(np.array([a]), np.array([b]))[0],
              twist_angle(np.array([qz]), np.array([qw]))[0])
    for r, c in (compiled(a, b, qz, qw), (tilt_ratio(a, b), twist_angle(qz, qw)), arrays):
        assert abs(r - ratio) <= 4 * EPS * ratio
        assert abs(c - twist) <= 4 * EPS * abs(twist) + 4 * TINY   # TINY: subnormal chi


@functools.lru_cache(maxsize=1)
def _compiled_angles(numba):
    from gyro_rotor.core.model import tilt_ratio, twist_angle

    @numba.njit
    def angles(a, b, qz, qw):
        return tilt_ratio(a, b), twist_angle(qz, qw)
    return angles
