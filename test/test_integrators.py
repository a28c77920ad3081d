"""Integrators: tableaux, empirical order, invariants on every scene, hard cases, misuse."""

import math

from gyro_rotor.core import rotations
from gyro_rotor.core.model import make_model
from gyro_rotor.core.scene import list_scenes, load_scene
from gyro_rotor.errors import ParameterError
from gyro_rotor.numerics.integrators import (cheapest_explicit, choose_method, COST_METHODS,
                                             integrate, make_integrator, method_cost, METHODS,
                                             model_rate, tableaux)
from hypothesis import example, given, settings, strategies as st
import numpy as np
import pytest

STIFF = ('stiff_drive',)


def _setup(name='precession', **overrides):
    sc = load_scene(name, overrides=overrides or None)
    m = sc.make_model()
    return sc, m, sc.initial_state(m)


# -- tableaux ----------------------------------------------------------------------------------
@pytest.mark.parametrize('A, B, C, order', [
    (tableaux.RK4_A, tableaux.RK4_B, tableaux.RK4_C, 4),
    (tableaux.DOP853_A[:12, :12], tableaux.DOP853_B, tableaux.DOP853_C[:12], 8),
    (tableaux.GAUSS6_A, tableaux.GAUSS6_B, tableaux.GAUSS6_C, 6),
])
def test_tableau_consistency(A, B, C, order):
    assert math.isclose(B.sum(), 1.0, rel_tol=0, abs_tol=1e-14)
    np.testing.assert_allclose(A.sum(axis=1), C, atol=1e-14)
    for k in range(1, order + 1):           # quadrature conditions sum b c^(k-1) = 1/k
        assert math.isclose(B @ C ** (k - 1), 1.0 / k, abs_tol=1e-13), k
    assert math.isclose(B @ (A @ C), 1.0 / 6.0, abs_tol=1e-13)   # an order-3 tree


def test_dop853_extended_stages_and_error_weights():
    A, C = tableaux.DOP853_A, tableaux.DOP853_C
    np.testing.assert_allclose(A.sum(axis=1), C, atol=1e-13)
    np.testing.assert_allclose(A[12, :12], tableaux.DOP853_B, atol=1e-15)  # FSAL stage
    assert abs(tableaux.DOP853_E5.sum()) < 1e-14 and abs(tableaux.DOP853_E3.sum()) < 1e-14


def test_rodas4_is_stiffly_accurate():
    # y_new = (argument of the last stage) + k_6, and the error estimate is k_6 itself
    M, A = tableaux.RODAS4_M, tableaux.RODAS4_A
    np.testing.assert_array_equal(M[:5], A[5, :5])
    np.testing.assert_array_equal(A[5, :4], A[4, :4])
    assert M[5] == 1.0 and list(tableaux.RODAS4_E) == [0, 0, 0, 0, 0, 1]


# -- empirical order ---------------------------------------------------------------------------
@pytest.mark.parametrize('method, order, h, extra', [
    ('rk4', 4, 2e-3, {}), ('rk8', 8, 2e-2, {}), ('gauss6', 6, 1e-2, {}),
    ('rodas4', 4, 4e-3, {'rtol': 1e3, 'atol': 1e3}),      # huge tolerances: fixed steps
    ('dop853', 8, 2e-2, {'rtol': 1e3, 'atol': 1e3}),
    ('split8', 8, 1e-2, {}),
    ('radau9', 9, 1e-2, {'rtol': 1e3, 'atol': 1e3}),
])
def test_empirical_order(method, order, h, extra, monkeypatch):
    """Halving the step divides the error (max over 5 samples) by about 2^order."""
    # radau9 solves its stages to round-off here (else the iteration's error would show)
    monkeypatch.setattr(METHODS['radau9'], 'iter_rtol_max', 1e-14)
    _, m, y0 = _setup('precession')
    te = np.linspace(0, 0.4, 5)
    ref = integrate(m, y0, (0, 0.4), te, 'dop853', rtol=1e-14, atol=1e-16).y
    errs = []
    for hh in (h, h / 2):
        r = integrate(m, y0, (0, 0.4), te, method, step=hh, **extra)
        assert r.success
        errs.append(np.max(np.abs(r.y - ref)))
    p = math.log2(errs[0] / errs[1])
    assert abs(p - order) < 0.5, (errs, p)


# -- invariants on every scene -----------------------------------------------------------------
def _cases():
    for name in list_scenes(builtin=True):
        stiff = name in STIFF
        full = load_scene(name).system.model == 'full'
        for method in METHODS:
            if stiff and method not in ('rodas4', 'radau9'):
                continue          # explicit and fixed-point methods are not for K_D = 1e4
            if method == 'split8' and not full:
                continue          # the splitting's sub-flows are those of the full model
            yield name, method


@pytest.mark.parametrize('name, method', list(_cases()))
def test_quaternion_norm_and_energy_residual_at_tolerance_level(name, method):
    sc, m, y0 = _setup(name)
    T = min(sc.t_end, 0.5)
    r = integrate(m, y0, (0, T), np.linspace(0, T, 26), method)
    assert r.success, r.message
    scale = max(1.0, float(np.max(np.abs(m.energy(r.y)))))
    res = np.max(np.abs(m.residual(r.y)))
    solver = METHODS[method]
    tol = solver.default_rtol if solver.adaptive else 1e-9
    assert res < 1e3 * tol * scale, res
    # step ends are projected (or exact for gauss6); dense-output samples at tolerance level
    assert np.max(np.abs(m.quaternion_norm_error(r.y))) < 100 * tol


# -- hard cases --------------------------------------------------------------------------------
def test_pole_slip_count_right_for_every_method():
    sc, m, y0 = _setup('pole_slip')
    p = sc.system.params.pole_pairs

    def poles(res):
        return round(res.y[-1, m.iz] * p / (2 * math.pi))
    ref = poles(integrate(m, y0, (0, sc.t_end), None, 'dop853', rtol=1e-13, atol=1e-15))
    assert ref != 0                      # the scene does slip
    for method in METHODS:
        assert poles(integrate(m, y0, (0, sc.t_end), None, method)) == ref, method


def test_gauss6_energy_error_bounded_not_drifting():
    sc, m, y0 = _setup('conservative')
    te = np.linspace(0, 100.0, 21)
    r = integrate(m, y0, (0, 100.0), te, 'gauss6')
    E = m.energy(r.y)
    dev = np.abs(E - E[0]) / abs(E[0])
    assert dev.max() < 1e-12
    # no growth: the second half deviates no more than the first (up to round-off)
    assert dev[11:].max() <= 2.0 * dev[1:11].max() + 1e-14
    assert np.max(np.abs(m.quaternion_norm_error(r.y))) < 1e-13   # no projection needed


def test_split8_energy_error_bounded_not_drifting():
    """Symplectic splitting on the conservative scene: E* error tiny and not growing."""
    sc, m, y0 = _setup('conservative')
    te = np.linspace(0, 200.0, 41)
    r = integrate(m, y0, (0, 200.0), te, 'split8', step=5e-3)
    assert r.success, r.message
    E = m.energy(r.y)
    dev = np.abs(E - E[0]) / abs(E[0])
    assert dev.max() < 1e-12
    assert dev[21:].max() <= 2.0 * dev[1:21].max() + 1e-14   # no drift
    assert np.max(np.abs(m.quaternion_norm_error(r.y))) < 1e-13
    # dop853 at the same cost drifts: its E* error grows with time
    d = integrate(m, y0, (0, 200.0), te, 'dop853', rtol=1e-9, atol=1e-11)
    Ed = np.abs(m.energy(d.y) - E[0]) / abs(E[0])
    assert Ed[-1] > 1.5 * Ed[20] > 0.0


def test_split8_needs_the_full_model():
    _, m, y0 = _setup('locked_housing')
    with pytest.raises(ParameterError, match='full model'):
        integrate(m, y0, (0, 1.0), None, 'split8')


@pytest.mark.parametrize('method', ['radau9', 'rodas4'])
def test_stiff_method_step_count_independent_of_kd(method):
    """On stiff_drive at K_D = 1e2, 1e4, 1e6: the same number of steps (+-10 %).

    The drive damping root K_D (1/C_R + 1/C_M) goes from 1.5e4 to 1.5e8 1/s; an explicit
    method's steps would grow with it.
    """
    steps = []
    for kd in (1e2, 1e4, 1e6):
        sc, m, y0 = _setup('stiff_drive', K_D=kd)
        r = integrate(m, y0, (0, sc.t_end), None, method, rtol=1e-8, atol=1e-10)
        assert r.success, r.message
        steps.append(r.nsteps)
    assert max(steps) <= 1.1 * min(steps), steps


def test_radau9_accurate_on_stiff_drive_at_every_kd():
    """radau9 against a tight rodas4 reference: axis and z to 1e-8 at its default tolerance."""
    for kd in (1e2, 1e4, 1e6):
        sc, m, y0 = _setup('stiff_drive', K_D=kd)
        te = np.linspace(0, sc.t_end, 21)
        ref = integrate(m, y0, (0, sc.t_end), te, 'rodas4', rtol=1e-13, atol=1e-15).y
        r = integrate(m, y0, (0, sc.t_end), te, 'radau9')
        assert r.success, r.message
        assert np.max(np.abs(r.y[:, :9] - ref[:, :9])) < 1e-8, kd


def test_stiff_method_completes_kd_1e6_within_step_budget():
    sc, m, y0 = _setup('stiff_drive', K_D=1e6)
    assert choose_method(m)[0] == 'radau9'
    r = integrate(m, y0, (0, sc.t_end), None, 'radau9', max_steps=5000)
    assert r.success, r.message
    scale = float(np.max(np.abs(m.energy(r.y))))
    assert abs(m.residual(r.y)[-1]) < 1e-6 * scale
    # an explicit method hits the same budget long before the end
    e = integrate(m, y0, (0, sc.t_end), None, 'dop853', max_steps=5000)
    assert e.status == -3


def test_auto_choice():
    assert choose_method(load_scene('precession').make_model(), rtol=1e-6,
                         sample_rate=100.0)[0] == 'dop853'
    assert choose_method(load_scene('stiff_drive').make_model())[0] == 'radau9'
    assert choose_method(load_scene('conservative').make_model(), 1000.0)[0] == 'split8'
    assert choose_method(make_model('upright_axis', load_scene('conservative').system.params),
                         1000.0)[0] == 'gauss6'    # split8's sub-flows are the full model's
    assert 'stiff' in choose_method(load_scene('stiff_drive').make_model())[1]


def test_auto_conservative_threshold_counts_periods_of_the_fastest_oscillation():
    # 100 s of conservative is 870 periods of its fastest oscillation (54.8 rad/s): dop853's
    # E* drift stays below a tenth of rtol there, and split8 is about twice as costly per
    # trajectory error (bench), so auto keeps dop853; over 1000 s it takes split8
    p = load_scene('conservative').make_model()
    method, reason = choose_method(p, 100.0)
    assert method in COST_METHODS and 'periods' in reason and 'conservative' in reason
    assert choose_method(p, 1000.0)[0] == 'split8'
    # the threshold is a number of periods, not of seconds: ten times the spin makes the
    # nutation (C_R Omega0 / I = 483 rad/s) the fastest oscillation, and 100 s long
    fast = load_scene('conservative', overrides={'Omega0': 3141.6}).make_model()
    assert choose_method(fast, 100.0)[0] == 'split8'
    assert choose_method(fast, 10.0)[0] in COST_METHODS


def test_auto_takes_the_cheapest_explicit_pair_by_the_cost_model():
    # fast_spin (nutation 483 rad/s, 9 times the other rates): steps are much shorter than
    # the 10-ms samples, the interpolant is rarely needed, and the 8(7) pair needs fewer
    # evaluations than dop853 for the same error; at slow rates (precession, 54.8 rad/s) every
    # step holds samples and dop853's 3-stage interpolant wins at loose tolerances
    method, reason = choose_method(load_scene('fast_spin').make_model(), 2.0, rtol=1e-6,
                                   sample_rate=100.0)
    assert method == 'vern8' and 'non-stiff' in reason and '483 rad/s' in reason
    assert 'cost model' in reason and 'dop853' in reason       # the candidates' costs
    p = load_scene('precession').make_model()
    rate = model_rate(p.params)
    assert choose_method(p, 10.0, rtol=1e-5, sample_rate=100.0)[0] == 'dop853'
    # the choice is the minimum of the predicted costs
    for tol in (1e-4, 1e-6, 1e-9, 1e-12):
        for fs in (0.0, 100.0, 1000.0):
            best, costs = cheapest_explicit(rate, tol, fs)
            assert costs[best] == min(costs.values())
            assert choose_method(p, 10.0, rtol=tol, sample_rate=fs)[0] == best
    # more samples never make the interpolant-heavy pairs cheaper
    for m in COST_METHODS:
        assert method_cost(m, rate, 1e-8, 1000.0) >= method_cost(m, rate, 1e-8, 0.0)
    # tighter tolerances cost more steps, by the measured table
    for m in COST_METHODS:
        c = [method_cost(m, rate, t) for t in (1e-3, 1e-6, 1e-9, 1e-12, 1e-14)]
        assert all(a < b for a, b in zip(c, c[1:]))


def test_auto_never_takes_a_method_with_an_error_floor_above_the_tolerance(monkeypatch):
    from gyro_rotor.numerics.integrators import methods
    monkeypatch.setitem(methods.ERROR_FLOOR, 'vern8', 1e-9)
    p = load_scene('fast_spin').make_model()
    assert choose_method(p, 2.0, rtol=1e-8, sample_rate=100.0)[0] == 'vern8'
    assert choose_method(p, 2.0, rtol=1e-10, sample_rate=100.0)[0] != 'vern8'


def test_integrate_auto_runs_the_chosen_method():
    sc, m, y0 = _setup('fast_spin')
    te = np.linspace(0.0, 0.2, 21)
    res = integrate(m, y0, (0.0, 0.2), te, 'auto', rtol=1e-6, atol=1e-8)
    assert res.success and res.method == choose_method(m, 0.2, 1e-6, 100.0)[0]


def test_drift_per_period_matches_dop853():
    # the constant behind the threshold: dop853's relative E* drift on conservative per
    # period of the fastest oscillation, in units of rtol (within a factor 2)
    from gyro_rotor.numerics.integrators.methods import DRIFT_PER_PERIOD
    sc, m, y0 = _setup('conservative')
    T = 100.0
    p = sc.system.params
    periods = T * math.sqrt(p.K_S * (1 / p.C_R + 1 / p.C_M)) \
        / (2 * math.pi)
    for rtol in (1e-10, 1e-11):
        y = integrate(m, y0, (0.0, T), None, 'dop853', rtol=rtol, atol=rtol * 1e-2).y
        drift = abs(m.energy(y[-1]) - m.energy(y0)) / m.energy(y0)
        assert 0.5 < drift / (rtol * periods) / DRIFT_PER_PERIOD < 2.0, (rtol, drift)


# -- misuse and bad input ----------------------------------------------------------------------
@pytest.mark.parametrize('kwargs, match', [
    ({'y0': np.full(10, np.nan)}, 'finite'), ({'rtol': -1e-6}, 'rtol'),
    ({'atol': float('inf')}, 'atol'), ({'step': 5.0}, 'horizon'), ({'step': 0.0}, 'step'),
    ({'method': 'euler'}, 'unknown integrator'), ({'y0': np.ones(3)}, 'components'),
])
def test_bad_input_refused(kwargs, match):
    _, m, y0 = _setup()
    args = {'y0': y0, 'method': 'rk4', **kwargs}
    with pytest.raises(ParameterError, match=match):
        integrate(m, args.pop('y0'), (0, 1.0), None, args.pop('method'), **args)


@pytest.mark.parametrize('method', list(METHODS))
def test_state_machine_and_advance_to(method):
    _, m, y0 = _setup()
    s = make_integrator(method, m, y0, 0.0, 0.05)
    assert s.status == 'running' and s.nsteps == 0 and s.step_size is None
    s.step()
    assert s.nsteps == 1 and s.t > 0 and s.step_size == s.t
    assert s.advance_to(0.0123) == 'running' and s.t == 0.0123     # exactly, not beyond
    while s.status == 'running':
        s.step()
    assert s.status == 'finished' and s.t == 0.05
    with pytest.raises(RuntimeError):
        s.step()
    ref = integrate(m, y0, (0, 0.05), None, method).y[-1]
    np.testing.assert_allclose(s.y, ref, atol=1e-9)   # step() path == compiled loop


def test_failed_solver_refuses_to_step():
    _, m, y0 = _setup('stiff_drive')
    s = make_integrator('gauss6', m, y0, 0.0, 1.0, step=0.01)   # stages cannot converge
    msg = s.step()
    assert s.status == 'failed' and 'converge' in msg
    with pytest.raises(RuntimeError):
        s.step()
    r = integrate(m, y0, (0, 1.0), None, 'gauss6', step=0.01)
    assert not r.success and r.status == -4


# -- failures end the run ----------------------------------------------------------------------
@pytest.mark.parametrize('method', list(METHODS))
@pytest.mark.parametrize('fault', ['axis_down', 'nan_parameter'])
def test_each_compiled_method_ends_on_a_non_finite_right_hand_side(method, fault):
    """A right-hand side that is NaN or inf (no exception: numpy's error model) ends the run.

    The axis straight down (theta = pi) divides by zero in the model; a NaN parameter makes
    every derivative NaN. Either way each compiled loop returns 'non-finite' (-2) at once,
    instead of rejecting NaN steps forever.
    """
    _, m, y0 = _setup('precession')
    if fault == 'axis_down':
        y0 = y0.copy()
        y0[:4] = (0.0, 1.0, 0.0, 0.0)
    solver = make_integrator(method, m, y0, 0.0, 1.0)
    if fault == 'nan_parameter':
        solver.P[1] = np.nan            # C_R of kernels.pack_params
    r = solver.run(np.linspace(0.0, 1.0, 3))
    assert r.status == -2 and not r.success, (r.status, r.message)
    assert r.t[-1] == 0.0 and np.all(np.isfinite(r.y))


@settings(max_examples=12, deadline=None)
@given(log_delta=st.floats(math.log(1e-9), math.log(1e-5)),
       psi=st.floats(0.0, 2 * math.pi), phi=st.floats(0.0, 2 * math.pi),
       method=st.sampled_from(['dop853', 'vern8', 'radau9', 'rodas4']))
@example(log_delta=math.log(1e-9), psi=0.0, phi=0.0, method='dop853')
def test_a_start_near_the_axis_down_integrates_with_its_energy_balance(
        log_delta, psi, phi, method):
    """A start delta = 1e-9 .. 1e-5 rad from theta = pi runs, and E* + D stays balanced.

    Only theta = pi itself is singular (the test above). Near it the twist's rate divides by
    |q|^2 cos^2(theta / 2), which is tiny but not zero: the adaptive methods take small steps
    there. dop853, vern8 and radau9 are as accurate there as anywhere else (note 52:
    residuals 6e-12 to 1e-11); rodas4, whose Jacobian is a forward difference, less so (at
    delta 1e-9: 6.9e-7, inside the bound below, 5.2e-6; 2.2e-9 at delta 1e-5; stop 55).
    """
    _, m, y0 = _setup('precession')
    y0 = y0.copy()
    y0[:4] = rotations.quaternion_from_euler(psi, math.pi - math.exp(log_delta), phi)
    T = 0.1
    r = integrate(m, y0, (0, T), np.linspace(0, T, 11), method)
    assert r.success, r.message
    assert np.all(np.isfinite(r.y))
    scale = max(1.0, float(np.max(np.abs(m.energy(r.y)))))
    res = float(np.max(np.abs(m.residual(r.y))))
    assert res < 1e3 * METHODS[method].default_rtol * scale, res
    assert abs(np.linalg.norm(r.y[-1, :4]) - 1.0) < 1e-12


@pytest.mark.parametrize('method', [m for m in METHODS if m != 'split8'])   # exact sub-flows
def test_each_method_ends_when_its_steps_overflow(method):
    """Stages that overflow give a non-finite error norm: the run ends with a failure status."""
    _, m, y0 = _setup('precession')
    y0 = y0.copy()
    y0[4:7] = 1e150                     # body rates whose squares overflow
    r = make_integrator(method, m, y0, 0.0, 1.0).run(np.linspace(0.0, 1.0, 3))
    assert r.status < 0 and not r.success, (r.status, r.message)


@pytest.mark.parametrize('method', ['dop853', 'rodas4', 'radau9'])
def test_step_by_step_takes_the_steps_of_the_compiled_run(method):
    """advance_to (one step per call, as the live node steps) grows the step like run().

    radau9 steps by one-step runs of its compiled loop; the loop kept the step it had
    before the step-size update when it stopped at its step budget, so the live node
    crawled at its first tiny step after a stiff change (issue 12's live K_D = 1e5).
    """
    _, m, y0 = _setup('precession', K_D=1e5)
    T = 0.05
    whole = make_integrator(method, m, y0, 0.0, T)
    assert whole.run(np.array([0.0, T])).success
    stepwise = make_integrator(method, m, y0, 0.0, T)
    assert stepwise.advance_to(T) == 'finished'
    assert stepwise.nsteps <= 2 * whole.nsteps + 5, (stepwise.nsteps, whole.nsteps)


def test_dop853_lands_on_samples_instead_of_interpolating():
    # steps about as long as the sample spacing: each step ends exactly on its sample (no
    # dense output, 3 evaluations more), and the samples are as accurate as the steps
    sc, m, y0 = _setup('upright')
    te = np.linspace(0.0, sc.t_end, 1001)
    r = integrate(m, y0, (0.0, sc.t_end), te, 'dop853', rtol=3e-9, atol=3e-11)
    assert r.success and r.nsteps >= 900
    assert r.nfev < 12.5 * r.nsteps          # with a dense output per sample: 15 per step
    ref = integrate(m, y0, (0.0, sc.t_end), te, 'dop853', rtol=1e-13, atol=1e-15).y
    assert np.max(np.abs(r.y[:, :9] - ref[:, :9])) < 1e-7
    # a largest step below the spacing: never stretched beyond it to reach a sample
    h_max = 0.0095
    r = integrate(m, y0, (0.0, 1.0), te[:101], 'dop853', rtol=1e-6, atol=1e-8, step=h_max)
    assert r.success and r.nsteps >= 1.0 / h_max


# -- the generated straight-line kernels (rk_codegen) ------------------------------------------
def test_generated_kernels_are_written_on_first_use_and_reused(tmp_path, monkeypatch):
    """The kernels' module is the generator's text, written into the cache once, then reused.

    A file that is not the generator's text (edited, cut short) is written again.
    """
    from pathlib import Path
    from gyro_rotor.numerics.integrators import rk_codegen
    monkeypatch.setenv('GYRO_ROTOR_CACHE', str(tmp_path))
    notes = []
    first = rk_codegen.load(progress=notes.append)
    path = Path(first.__file__)
    assert path.parent == tmp_path / 'kernels'
    assert path.read_text() == rk_codegen.generate()
    assert len(notes) == 1 and str(path) in notes[0]
    stamp = path.stat().st_mtime_ns
    second = rk_codegen.load(progress=notes.append)
    assert (len(notes), second.__file__, path.stat().st_mtime_ns) == (1, str(path), stamp)
    path.write_text(rk_codegen.generate()[:1000])
    rk_codegen.load(progress=notes.append)
    assert len(notes) == 2 and path.read_text() == rk_codegen.generate()


def test_generated_kernels_without_a_writable_cache(tmp_path, monkeypatch):
    """A cache that cannot be made: the module goes to a temporary folder, with a note."""
    from gyro_rotor.numerics.integrators import rk_codegen
    blocker = tmp_path / 'a_file'
    blocker.write_text('')
    monkeypatch.setenv('GYRO_ROTOR_CACHE', str(blocker / 'cache'))
    notes = []
    module = rk_codegen.load(progress=notes.append)
    assert len(notes) == 1 and notes[0].startswith('cannot write the cache')
    assert not module.__file__.startswith(str(blocker))
    assert open(module.__file__).read() == rk_codegen.generate()


def test_generated_kernels_concurrent_first_use(tmp_path):
    """Processes that start together on a cold cache each import the whole module.

    (Each writes a temporary file and renames it: no process reads a partial file, and no
    temporary file is left.)
    """
    import os
    import subprocess
    import sys
    code = ('from gyro_rotor.numerics.integrators import rk_codegen, rk_generated; '
            'print(open(rk_generated.__file__).read() == rk_codegen.generate())')
    env = {**os.environ, 'GYRO_ROTOR_CACHE': str(tmp_path)}
    procs = [subprocess.Popen([sys.executable, '-c', code], env=env, text=True,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE)
             for _ in range(4)]
    outs = [p.communicate(timeout=300) for p in procs]
    assert [(p.returncode, out.strip()) for p, (out, _) in zip(procs, outs)] == [(0, 'True')] * 4
    assert [f.suffix for f in (tmp_path / 'kernels').iterdir() if f.is_file()] == ['.py']


@pytest.mark.parametrize('scene', ['precession', 'pole_slip', 'upright'])
def test_generated_dop853_step_and_dense_equal_the_tableau_loops(scene):
    """The straight-line DOP853 step, error norm and dense output are the generic ones.

    Summed in another order (and with fused multiply-adds), so equal to round-off: tens of
    eps times the sizes of the terms (each stage's round-off feeds the next stages), where
    a wrong coefficient would show as 1e-3 of them.
    """
    from gyro_rotor.numerics.integrators import kernels, rk_generated
    from gyro_rotor.numerics.integrators.base import kernel_args
    sc, m, y0 = _setup(scene)
    kind, P, _ = kernel_args(m, sc.system.params)
    rng = np.random.default_rng(7)
    tb = tableaux
    eps = np.finfo(float).eps
    n = m.n
    for _ in range(20):
        y = y0 + rng.normal(scale=0.1, size=y0.shape)
        f = m.rhs(0.0, y)
        h = float(rng.uniform(1e-4, 5e-2))
        K_a, K_b = np.empty((16, n)), np.empty((16, n))
        y_a, y_b, f_a, f_b, tmp = (np.empty(n) for _ in range(5))
        e_a = kernels.dop853_step(kind, P, y, f, h, 1e-6, 1e-8, tb.DOP853_A, tb.DOP853_B,
                                  tb.DOP853_E3, tb.DOP853_E5, K_a, tmp, y_a, f_a)
        e_b = rk_generated.dop853_step(kind, P, y, f, h, 1e-6, 1e-8, K_b, tmp, y_b, f_b)
        terms = np.abs(y) + h * (np.abs(tb.DOP853_B)[:, None] * np.abs(K_a[:12])).sum(axis=0)
        assert np.all(np.abs(y_a - y_b) <= 64 * eps * terms.max())     # stages couple all
        # f(y_new), of its own y_new (the RHS's round-off only; the two y_new differ slightly)
        assert np.all(np.abs(f_b - m.rhs(0.0, y_b)) <= 64 * eps * np.abs(f_b).max())
        # the error norm is a difference of stage sums that cancel to about the tolerance
        # (1e-6 here): its round-off is relative to the stages, not to itself
        assert math.isclose(e_a, e_b, rel_tol=1e-7, abs_tol=1e-300)
        # dense output from the same stages
        F_a, F_b = np.empty((7, n)), np.empty((7, n))
        K_b[:] = K_a
        kernels.dop853_dense(kind, P, y, y_a, f, f_a, h, tb.DOP853_A, tb.DOP853_C,
                             tb.DOP853_D, K_a, tmp, F_a)
        rk_generated.dop853_dense(kind, P, y, y_a, f, f_a, h, K_b, tmp, F_b)
        dterms = (h * (np.abs(tb.DOP853_D) @ np.abs(K_a))).max(axis=0) + np.abs(F_a[:3]).max(0)
        assert np.all(np.abs(F_a - F_b) <= 64 * eps * dterms)
        for x in (0.0, 0.3, 1.0):
            out_a, out_b = np.empty(n), np.empty(n)
            kernels.dense_eval(F_a, y, x, out_a)
            rk_generated.dop853_eval(kind, F_a, y, x, out_b)
            assert np.all(np.abs(out_a - out_b) <= 16 * eps * (np.abs(y) + np.abs(F_a).sum(0)))


def test_auto_choice_is_remembered_but_follows_a_changed_table(monkeypatch):
    # auto's choice is cached (a fixed cost of every run): a changed ERROR_FLOOR or
    # STEP_OVERHEAD is part of the key, never answered from the cache
    from gyro_rotor.numerics.integrators import methods
    p = load_scene('fast_spin').make_model()
    first = choose_method(p, 2.0, rtol=1e-10, sample_rate=100.0)[0]
    assert choose_method(p, 2.0, rtol=1e-10, sample_rate=100.0)[0] == first
    monkeypatch.setitem(methods.ERROR_FLOOR, first, 1e-9)
    assert choose_method(p, 2.0, rtol=1e-10, sample_rate=100.0)[0] != first
    monkeypatch.undo()
    monkeypatch.setattr(methods, 'STEP_OVERHEAD', 1e6)   # steps' overhead dwarfs the stages
    rate = model_rate(p.params)
    best, costs = cheapest_explicit(rate, 1e-10, 100.0)
    assert costs == {m: method_cost(m, rate, 1e-10, 100.0) for m in costs}


def test_radau_resolvent_is_the_inverse():
    # radau9's (I + mu A)^-1 from A's eigen-decomposition (radau.resolvent, three complex
    # reciprocals, no pivoting) against numpy's inverse, over mu = h K_D b_k from 0 to beyond
    # any run's (K_D = 1e6 at h = 0.01 is mu = 1.5e6)
    from gyro_rotor.numerics.integrators import tableaux as tb
    from gyro_rotor.numerics.integrators.radau import resolvent
    out = np.empty((5, 5))
    for mu in np.concatenate([[0.0], np.logspace(-8, 12, 81)]):
        resolvent(mu, tb.RADAU5_LAM, tb.RADAU5_PROJ, out)
        want = np.linalg.inv(np.eye(5) + mu * tb.RADAU5_A)
        assert np.abs(out - want).max() <= 1e-13 * np.abs(want).max(), mu


@pytest.mark.parametrize('terms', [1, 2, 5, 13])
@pytest.mark.parametrize('with_base', [True, False])
def test_lincomb_vector_sum_is_the_sum(terms, with_base):
    """The compiled vector stage sum is base + h sum_j c_j a_j, at m ... m + 3 only.

    Four components at once, the last array read lane by lane (primitives.lincomb).
    Against math.fsum of the exact products: within (terms + 2) eps of the sum of the
    magnitudes (fused and reassociated); a wrong lane, coefficient or array would be off
    by the size of a term. The pure-Python stand-in (no numba) is held to the same.
    """
    from numba import njit
    from gyro_rotor.numerics.integrators.primitives import LANES, lincomb
    rng = np.random.default_rng(terms + 100 * with_base)
    n = 11
    arrays = tuple(rng.normal(size=n) * 10.0 ** rng.uniform(-3, 3) for _ in range(terms))
    coeffs = tuple(float(c) for c in rng.normal(size=terms))
    base = rng.normal(size=n) if with_base else None
    h = float(rng.uniform(1e-3, 1.0))

    @njit
    def compiled(out, base, h, coeffs, arrays, m):
        lincomb(out, base, h, coeffs, arrays, m)

    eps = np.finfo(float).eps
    for fn in (compiled, lincomb):
        for m in range(n - LANES + 1):
            out = np.full(n, np.nan)
            fn(out, base, h, coeffs, arrays, m)
            inside = np.arange(m, m + LANES)
            assert np.isnan(np.delete(out, inside)).all()
            for r in inside:
                parts = [h * c * a[r] for c, a in zip(coeffs, arrays)]
                parts += [base[r]] if with_base else []
                size = sum(abs(p) for p in parts)
                assert abs(out[r] - math.fsum(parts)) <= (terms + 2) * eps * size, (fn, m, r)


def test_warm_up_on_worker_processes_runs_each_job_and_raises_a_jobs_error():
    # the bootstrap's warm-up compiles on one process a core; a job that fails there must
    # fail the warm-up, not vanish with its process (the kernels are cached here: seconds)
    from gyro_rotor.numerics.integrators import warmup
    assert warmup.warm_up(workers=2, jobs=['rk4', 'ensemble']) > 0.0
    with pytest.raises(ParameterError, match='no_such_method'):
        warmup.warm_up(workers=2, jobs=['rk4', 'no_such_method'])


def test_warm_up_covers_every_method_and_the_ensemble_slowest_first():
    from gyro_rotor.numerics.integrators import METHODS, warmup
    jobs = warmup.warm_jobs()
    assert sorted(jobs) == sorted(list(METHODS) + ['ensemble'])
    assert tuple(jobs[:len(warmup.SLOWEST_FIRST)]) == warmup.SLOWEST_FIRST
