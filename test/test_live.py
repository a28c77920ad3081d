"""Pure tests of gyro_rotor.numerics.live (no ROS): the simulation behind rotor_sim."""

import math
import subprocess
import sys
import time

from gyro_rotor.core.model import drive_torque
from gyro_rotor.core.scene import load_scene
from gyro_rotor.errors import GyroRotorError
from gyro_rotor.node_settings import NODE_KEYS
from gyro_rotor.numerics import guard
from gyro_rotor.numerics.live import ENERGY_COLUMNS, Level, LiveSimulation, wrap_angles
from gyro_rotor.numerics.realtime import resolve_method
import numpy as np
import pytest
from random_systems import unstable_scene

RATE = 250.0


class FakeClock:
    """A steady clock the test moves by hand."""

    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def make_sim(clock=None, budget=None, **cfg):
    scene = load_scene('precession')
    base = {k: scene.node.get(k, spec[1]) for k, spec in NODE_KEYS.items()
            if k != 'use_sim_time'}
    base.update({'publish_rate': RATE, 'real_time_factor': 1.0, **cfg})
    events = []
    sim = LiveSimulation(scene, base, scene.perturbation, budget=budget,
                         clock=clock or FakeClock(), log=lambda lv, text: events.append((lv,
                                                                                        text)))
    return sim, events


def run_ticks(sim, clock, n, dt=0.02):
    blocks = []
    for _ in range(n):
        clock.now += dt
        b = sim.tick()
        if b is not None:
            blocks.append(b)
    return blocks


def test_sample_block_carries_every_derived_output_as_arrays():
    clock = FakeClock()
    sim, _ = make_sim(clock)
    blocks = run_ticks(sim, clock, 11)
    E = {c: np.concatenate([b.energy[c] for b in blocks]) for c in ENERGY_COLUMNS}
    t = np.concatenate([b.t for b in blocks])
    n = len(t)
    assert n == 51                                       # t = 0 .. 0.2 s at 250 Hz, each once
    np.testing.assert_array_equal(E['k'], np.arange(n))
    np.testing.assert_array_equal(E['seq'], np.arange(n))
    np.testing.assert_array_equal(E['t_sim'], E['k'] / RATE)
    p = sim.scene.system.params
    np.testing.assert_allclose(E['dissipation'], p.K_D * E['zdot'] ** 2, rtol=1e-15)
    np.testing.assert_array_equal(E['dE_dt'], -E['dissipation'])
    assert np.max(np.abs(E['residual'])) < 1e-8           # eq. 17: E* + D is conserved
    assert np.all(np.diff(E['E_star']) <= 1e-10)
    # joints: the model's own outputs at the same states (angles wrapped to (-pi, pi])
    last = blocks[-1]
    out = sim.model.outputs(last.t, np.array([sim.last[1]]))
    assert last.t[-1] == sim.last[0]
    np.testing.assert_allclose(last.position[-1, [0, 1, 3]],
                               wrap_angles(np.array([out['theta'][0], out['psi'][0],
                                                     out['phi_M'][0]])), atol=1e-12)
    np.testing.assert_allclose(last.velocity[-1, [0, 1, 3]],
                               [out['thetadot'][0], out['psidot'][0], out['phi_M_dot'][0]],
                               rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(last.effort[:, 2], drive_torque(p, last.energy['z'],
                                                               last.energy['zdot']), rtol=1e-12)
    np.testing.assert_allclose(last.axis, out['axis'][0], atol=1e-12)
    pos = np.concatenate([b.position for b in blocks])
    assert np.all(pos > -math.pi) and np.all(pos <= math.pi)
    assert wrap_angles(np.array([-math.pi, 3 * math.pi]))[0] == math.pi


def test_parameter_changes_are_checked_then_applied_with_the_baseline_moved():
    clock = FakeClock()
    sim, _ = make_sim(clock)
    run_ticks(sim, clock, 5)
    before, stepper = sim.scene.system.params, sim.stepper
    for bad in ({'K_D': -1.0}, {'A_R': 0.0}, {'integrator': 'euler'}, {'rtol': -1.0}):
        with pytest.raises(GyroRotorError):
            sim.check(bad)
    assert sim.scene.system.params == before and sim.stepper is stepper
    y, E_ref = sim.stepper.y.copy(), sim.baseline.E_ref
    sim.check({'K_S': 40.0})
    sim.apply({'K_S': 40.0})
    assert sim.model.params.K_S == 40.0
    assert sim.baseline.E_ref - E_ref == pytest.approx(0.5 * 20.0 * y[7] ** 2, rel=1e-9,
                                                       abs=1e-15)
    zdot = sim.stepper.y[8]
    sim.apply({'Omega0': 320.0})                      # the rotor keeps its absolute spin
    assert sim.stepper.y[8] == pytest.approx(zdot - (320.0 - before.Omega0))
    blocks = run_ticks(sim, clock, 5)
    assert max(np.max(np.abs(b.energy['residual'])) for b in blocks) < 1e-8


def test_an_omega0_change_keeps_the_rotor_angle_continuous():
    """phi_R = field + z + phi_M across a live Omega0 change: the field angle carries on.

    Published angle against the trapezoid of the published rate (about 320 rad/s, 1.3 rad
    per sample); a field angle that restarted from Omega0_new t would jump by
    delta Omega0 t = 0.47 rad here.
    """
    clock = FakeClock()
    sim, _ = make_sim(clock)
    blocks = run_ticks(sim, clock, 5)
    n_before = sum(len(b) for b in blocks)
    sim.apply({'Omega0': 320.0})
    blocks += run_ticks(sim, clock, 3)
    t = np.concatenate([b.t for b in blocks])
    phi_R = np.unwrap(np.concatenate([b.position[:, 2] for b in blocks]))
    rate = np.concatenate([b.velocity[:, 2] for b in blocks])
    assert len(t) > n_before + 10
    step = np.diff(phi_R) - 0.5 * (rate[1:] + rate[:-1]) * np.diff(t)
    assert np.abs(step).max() < 1e-4, (np.abs(step).max(), n_before)


def test_a_kick_is_checked_by_the_scene_before_it_is_taken():
    clock = FakeClock()
    sim, _ = make_sim(clock)
    kick = dict(sim.perturbation)
    for bad, word in (({'perturbation.dthetta': 0.1},
                       "unknown key 'perturbation.dthetta'; did you mean 'perturbation.dtheta'"),
                      ({'perturbation.dz': 'abc'}, 'perturbation.dz must be a number')):
        with pytest.raises(GyroRotorError, match=word):
            sim.check(bad)
    assert sim.perturbation == kick
    sim.check({'perturbation.dz': 0.25})
    sim.apply({'perturbation.dz': 0.25})
    assert sim.perturbation == {**kick, 'dz': 0.25}
    z = sim.stepper.y[7]
    sim.perturb()
    assert sim.stepper.y[7] == pytest.approx(z + 0.25, abs=1e-15)


def test_residual_guard_stops_keeps_the_last_good_state_and_reset_recovers(monkeypatch):
    clock = FakeClock()
    sim, events = make_sim(clock)
    run_ticks(sim, clock, 3)
    # a bound of zero (no relative term, no joules): the round-off of E* trips it
    monkeypatch.setattr(guard, 'RELATIVE_LIMIT', 0.0)
    sim.apply({'max_residual': 0.0})
    run_ticks(sim, clock, 3)
    assert sim.diverged and 'residual' in sim.diverged
    t_stop, y_stop = sim.last
    assert run_ticks(sim, clock, 3) == [] and sim.last[0] == t_stop
    level, msg, values = sim.diagnostics()
    assert level == Level.ERROR and msg.startswith('diverged')
    assert events[-1][0] == Level.ERROR and f'{t_stop:.6f}' in events[-1][1]
    sim.apply({'max_residual': 1.0})
    assert sim.reset().startswith('reset')
    assert sim.diverged is None and run_ticks(sim, clock, 2)


def test_any_exception_of_the_integrator_is_caught_by_the_guard(monkeypatch):
    """Issue 12: a ZeroDivisionError out of the compiled RHS crashed the node's timer."""
    clock = FakeClock()
    sim, events = make_sim(clock)
    run_ticks(sim, clock, 3)
    t_good, y_good = sim.last[0], sim.last[1].copy()

    def divide(t, deadline=None):
        raise ZeroDivisionError('division by zero')
    monkeypatch.setattr(sim.stepper, 'advance_to', divide)
    assert run_ticks(sim, clock, 2) == []              # no exception out of tick()
    assert 'ZeroDivisionError' in sim.diverged
    assert sim.last[0] == t_good and np.array_equal(sim.last[1], y_good)
    level, msg, _ = sim.diagnostics()
    assert level == Level.ERROR and 'ZeroDivisionError' in msg
    with pytest.raises(GyroRotorError, match='reset first'):
        sim.perturb()
    sim.reset()
    assert sim.diverged is None and run_ticks(sim, clock, 2)


def test_a_real_blow_up_is_a_divergence_not_an_exception():
    """rk4 with a 4 ms step on K_S = 1e8 (the flaky node test) ends as a divergence."""
    clock = FakeClock()
    sim, _ = make_sim(clock)
    run_ticks(sim, clock, 3)
    for change in ({'integrator': 'rk4'}, {'step_size': 0.004}, {'K_S': 1e8}):
        sim.check(change)
        sim.apply(change)
    run_ticks(sim, clock, 20)
    assert sim.diverged
    assert np.all(np.isfinite(sim.last[1]))


def test_work_budget_switches_to_autos_method_and_says_so():
    # a deadline already past: every tick is cut after its first step (as fast as possible:
    # each tick has a chunk of work whatever the clock)
    first = resolve_method('auto', load_scene('precession').make_model())[0]   # an explicit pair
    sim, events = make_sim(time.monotonic, budget=-1.0, integrator=first,
                           real_time_factor=0.0)
    sim.tick()
    assert sim.pacer.cut and sim.switch == ''       # one cut may be a kernel's first load
    sim.tick()
    assert sim.pacer.cut and sim.stepper.method == first      # auto's choice here
    assert "auto's choice already" in sim.switch
    sim.check({'K_D': 1e5})
    sim.apply({'K_D': 1e5})                         # stiff: the drive damping root 1.5e7 1/s
    assert sim.stepper.method == first              # the user's method, until it is too slow
    t0 = sim.stepper.t
    sim.tick()
    assert sim.stepper.method == first
    sim.tick()
    auto, reason = resolve_method('auto', sim.model, y=sim.stepper.y)
    assert auto != first and sim.stepper.method == auto         # radau9 today
    assert sim.stepper.t > t0                       # the cut tick made progress
    assert f'switched to {auto} ({reason})' in sim.switch
    assert (Level.WARN, sim.switch) in events
    level, msg, values = sim.diagnostics()
    assert level == Level.WARN and 'work budget' in msg and f'switched to {auto}' in msg
    assert values['integrator'] == auto and values['budget_cuts'] == 4
    assert values['integrator_reason'].startswith('work budget')
    sim.apply({'real_time_factor': 2.0})            # a restart keeps auto's method ...
    sim.perturb()
    assert sim.stepper.method == auto
    sim.check({'integrator': 'rk4'})
    sim.apply({'integrator': 'rk4'})                # ... until the user picks one again
    assert sim.stepper.method == 'rk4'


def test_reset_forgets_the_previous_runs_cannot_keep_up():
    """Issue 24, finding 15: after ~/reset the diagnostics showed the old run's message."""
    first = resolve_method('auto', load_scene('precession').make_model())[0]
    sim, _ = make_sim(time.monotonic, budget=-1.0, integrator=first, real_time_factor=0.0)
    sim.tick()
    sim.tick()
    assert "auto's choice already" in sim.switch
    sim.reset()
    level, msg, values = sim.diagnostics()
    assert sim.switch == '' and values['method_switch'] == ''
    assert 'cannot keep up' not in msg and level != Level.WARN


def test_budget_cut_keeps_the_grid_whole():
    """Cut ticks lose simulation time, never a sample: k runs on without gaps."""
    sim, _ = make_sim(time.monotonic, budget=-1.0, real_time_factor=0.0)
    ks = []
    for _ in range(400):
        b = sim.tick()
        if b is not None:
            ks += b.energy['k'].tolist()
    assert sim.pacer.budget_cuts > 0 and len(ks) > 2
    np.testing.assert_array_equal(ks, np.arange(len(ks)))


def test_live_does_not_import_rclpy():
    code = 'import sys, gyro_rotor.numerics.live; assert "rclpy" not in sys.modules'
    subprocess.run([sys.executable, '-c', code], check=True)


def test_a_kick_the_model_cannot_evaluate_is_refused_and_changes_nothing():
    """The full model is singular with the axis down: a kick to theta = pi is refused.

    The right-hand side's twist direction is e_12/b, b = |q|^2 cos^2(theta/2): a kick to pi up
    to round-off leaves b at 1e-33 or so, finite and enormous, so the refusal cannot rest on
    a non-finite right-hand side (the atan2 form's 1 + k_3 cancelled to 0 there); it is the
    model's own singular_at (within 1e-6 rad of pi).
    """
    clock = FakeClock()
    sim, _ = make_sim(clock)
    run_ticks(sim, clock, 3)
    from gyro_rotor.core.rotations import euler_from_quaternion
    theta = float(euler_from_quaternion(sim.model.quaternion(sim.stepper.y))[1])
    sim.apply({'perturbation.dtheta': math.pi - theta})
    y, E_ref, stepper = sim.stepper.y.copy(), sim.baseline.E_ref, sim.stepper
    with pytest.raises(GyroRotorError, match='kick refused: the axis reached theta = pi'):
        sim.perturb()
    assert sim.stepper is stepper and np.array_equal(sim.stepper.y, y)
    assert sim.baseline.E_ref == E_ref and sim.diverged is None
    assert run_ticks(sim, clock, 2)


def test_guard_breaks_on_a_blow_up_at_any_energy():
    """A blow-up makes |r| of the order of E* itself: broken at 1e45 J as at 10 J.

    Found under load: the bound max_residual x max(1 J, |E*|, |E_ref|) let a sample with
    E* ~ r ~ 1.7e45 J through (relative 1.0 <= 1.0) and rotor_sim published it. A growth
    with the identity kept to 1e-11 of E* is sound at every energy.
    """
    from gyro_rotor.numerics.guard import breaks_identity, describe_break
    E_ref, limit = 5e3, 1.0
    for E in (10.0, 1e8, 1.7e45):
        assert breaks_identity(E, 0.5 * E + 2.0 * limit, E_ref, limit)
        assert not breaks_identity(E, 1e-11 * E, E_ref, limit)
    assert breaks_identity(np.nan, 0.0, E_ref, limit)
    assert not breaks_identity(10.0, 0.99, E_ref, limit)       # joules below 1e6 J
    assert breaks_identity(10.0, 1.01, E_ref, limit)
    assert describe_break(0.5, 1.7e45, 1.7e45, E_ref, limit).endswith(
        'exceeds max(max_residual 1 J, 1e-06 x max(|E*|, |E_ref|)) = 1.7e+39 J')


def test_residual_guard_is_relative_to_the_energy_scale(tmp_path):
    """Review finding 7: a statically unstable system's motion grows to |E*| ~ 1e14 J.

    Its residual (1e-14 relative, about 1 J there) stopped the integration at
    t = 2.19 s with an absolute bound of 1 J; the bound is max(max_residual, 1e-6 x
    max(|E*|, |E_ref|)).
    """
    scene = load_scene(unstable_scene(tmp_path, 10.0))
    cfg = {k: scene.node.get(k, spec[1]) for k, spec in NODE_KEYS.items()
           if k != 'use_sim_time'}
    cfg.update({'publish_rate': RATE, 'real_time_factor': 1.0})
    clock = FakeClock()
    sim = LiveSimulation(scene, cfg, scene.perturbation, budget=None, clock=clock,
                         log=lambda *a: None)
    blocks = run_ticks(sim, clock, 150)
    E = np.concatenate([b.energy['E_star'] for b in blocks])
    r = np.concatenate([b.energy['residual'] for b in blocks])
    assert sim.diverged is None and sim.last[0] >= 2.9
    assert np.max(np.abs(E)) > 1e14 and np.max(np.abs(r)) > cfg['max_residual']
    assert np.all(np.abs(r) <= 1e-9 * np.maximum(np.abs(E), 1.0))    # integration error
