"""Steady motions I and II: exact rates, eq. (22), and the full model staying on them."""

import math

from gyro_rotor.core.model import FullModel
from gyro_rotor.core.params import RotorParams, StaticallyUnstableWarning
from gyro_rotor.core.scene import load_scene
from gyro_rotor.core.steady import steady_motion, steady_state
from gyro_rotor.errors import NoSteadyMotionError, NotApplicableError, ParameterError
from gyro_rotor.numerics.simulate import simulate
import numpy as np
import pytest


def test_exact_rate_solves_the_theta_equation():
    p = RotorParams()
    th = 0.1
    for branch in (1, 2):
        x = steady_motion(p, th, branch).psidot0
        a = p.I * math.cos(th) + (p.C_R + p.C_M) * (1 - math.cos(th))
        b = p.G * p.s - p.c_theta * th / math.sin(th)
        assert a * x * x - p.C_R * p.Omega0 * x + b == pytest.approx(0.0, abs=1e-9)


def test_branches_follow_the_papers_text():
    """Branch 1: slow precession against the rotor's sense; branch 2: fast, with it."""
    p = RotorParams()
    b1, b2 = steady_motion(p, 0.1, 1), steady_motion(p, 0.1, 2)
    assert b1.psidot0 < 0 < b2.psidot0
    assert abs(b1.psidot0) < abs(b2.psidot0)


def test_eq22_is_close_but_not_exact():
    p = RotorParams()
    for branch, bound in ((1, 1e-3), (2, 1e-2)):
        sm = steady_motion(p, 0.1, branch)
        assert 0 < abs(sm.relative_difference) < bound
    # the approximation a = I cos(theta0) becomes exact as theta0 -> 0
    assert abs(steady_motion(p, 1e-3, 1).relative_difference) < 1e-7


def test_printed_sin_squared_is_wrong():
    """Eq. (22) as printed (sin^2 under the root) misses the theta equation by far."""
    p = RotorParams()
    th = 0.1
    h = p.C_R * p.Omega0
    printed = h / (2 * math.cos(th) * p.I) * (1 - math.sqrt(
        1 - 4 * math.cos(th) * p.I * (p.G * p.s * math.sin(th) - p.c_theta * th)
        / (h * h * math.sin(th) ** 2)))
    exact = steady_motion(p, th, 1).psidot0
    assert abs(printed - exact) / abs(exact) > 1.0


def test_no_steady_motion_ii_is_a_clear_error():
    # Only a restraint weaker than G s (b > 0) can make the discriminant negative: then a
    # rotor too slow cannot hold the tilt gyroscopically.
    with pytest.warns(StaticallyUnstableWarning):
        p = RotorParams(Omega0=10.0, c_theta=1.0)
    with pytest.raises(NoSteadyMotionError, match='discriminant'):
        steady_motion(p, 0.5, 1)
    with pytest.warns(StaticallyUnstableWarning), pytest.raises(NoSteadyMotionError):
        load_scene('precession', overrides={'Omega0': 10.0, 'c_theta': 1.0,
                                            'initial.theta0': 0.5})
    # with a statically stable restraint, II exists at any speed (b < 0 < a)
    assert steady_motion(RotorParams(Omega0=10.0), 0.5, 1).discriminant > 0


@pytest.mark.parametrize('bad', [(0.0, 1), (-0.1, 2), (math.nan, 1), (0.1, 3), (0.1, 0)])
def test_bad_steady_requests(bad):
    with pytest.raises(ParameterError):
        steady_motion(RotorParams(), *bad)


@pytest.mark.parametrize('branch', [1, 2])
def test_full_model_stays_on_solution_ii(branch):
    """Started exactly on II, theta and psidot stay constant for 10 s."""
    scene = load_scene('precession', overrides={
        'initial.branch': branch, 'initial.dtheta': 0.0, 'initial.dthetadot': 0.0,
        'initial.dchi': 0.0, 'initial.dz': 0.0, 'initial.dzdot': 0.0})
    sm = scene.system.steady()
    model = FullModel(scene.system.params)
    assert np.allclose(scene.initial_state(model), steady_state(model, sm))
    tr = simulate(scene, t_end=10.0, rate=20.0)
    assert np.max(np.abs(tr.theta - sm.theta0)) < 1e-8
    assert np.max(np.abs(tr.psidot - sm.psidot0)) < 1e-7 * max(1.0, abs(sm.psidot0))
    assert np.max(np.abs(tr.chi)) < 1e-8
    assert np.max(np.abs(tr.z)) < 1e-8


def test_branches_for_a_reversed_field():
    """Omega0 < 0 mirrors the motion: branch 1 stays the slow one, eq. (22) agrees."""
    p = RotorParams()
    q = p.replace(Omega0=-p.Omega0)
    for branch in (1, 2):
        fwd, rev = steady_motion(p, 0.1, branch), steady_motion(q, 0.1, branch)
        assert rev.psidot0 == pytest.approx(-fwd.psidot0)
        assert rev.relative_difference == pytest.approx(-fwd.relative_difference)
    assert abs(steady_motion(q, 0.1, 1).psidot0) < abs(steady_motion(q, 0.1, 2).psidot0)


def test_field_at_rest_has_an_exact_rate_and_no_closed_form():
    sm = steady_motion(RotorParams(Omega0=0.0), 0.1, 1)
    assert math.isfinite(sm.psidot0) and math.isnan(sm.psidot0_eq22)


def test_eq22_is_not_defined_at_a_right_angle_tilt(capsys):
    """Adversarial finding: at theta0 = pi/2, eq. (22) divided by cos = 6.1e-17 (7.9e17 rad/s)."""
    from gyro_rotor.cli.main import main
    from gyro_rotor.core.steady import precession_rate_eq22
    for branch in (1, 2):
        assert math.isnan(precession_rate_eq22(RotorParams(), math.pi / 2, branch))
        assert math.isfinite(precession_rate_eq22(RotorParams(), 1.5, branch))
    assert main(['steady', 'precession', '--theta0', repr(math.pi / 2)]) == 0
    out = capsys.readouterr().out
    assert out.count('eq. (22) corrected: not defined here') == 2 and 'e+17' not in out


def test_values_a_system_does_not_have_are_refused_without_naming_an_option():
    """Core says which value does not apply; the command line names its option (issue #25)."""
    twin, prec = load_scene('twin_gimbal'), load_scene('precession')
    with pytest.raises(NotApplicableError, match=r'^theta0 applies to the centrifuge'):
        twin.system.steady_motions(0.1, twin.name)
    with pytest.raises(NotApplicableError, match=r'^drive is for the scenes of system files'):
        prec.system.linear_parts(prec, 'R')
