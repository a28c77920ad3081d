"""Pure tests of gyro_rotor.numerics.realtime (no ROS): pacing with a fake steady clock."""

import math
import os
import subprocess
import sys
import time

from gyro_rotor.errors import IntegrationError, ParameterError
from gyro_rotor.numerics.realtime import (DenseStepper, EnergyBaseline, make_stepper, Pacer,
                                          WorkBudgetExceeded)
import numpy as np
import pytest


def oscillator(t, y):
    """Return the rate of y'' = -y: y = (cos t, -sin t) from (1, 0)."""
    return np.array([y[1], -y[0]])


def exact(t):
    return np.array([math.cos(t), -math.sin(t)])


class EulerStepper:
    """A fixed-step stepper of :func:`oscillator` (explicit Euler) that checks its deadline."""

    method = 'euler'

    def __init__(self, h: float):
        self.h, self.t, self.y, self.nfev = h, 0.0, np.array([1.0, 0.0]), 0

    def advance_to(self, t_target, deadline=None):
        while self.t < t_target:
            h = min(self.h, t_target - self.t)
            self.y, self.t, self.nfev = self.y + h * oscillator(self.t, self.y), self.t + h, \
                self.nfev + 1
            if self.t < t_target and deadline is not None and time.monotonic() > deadline:
                raise WorkBudgetExceeded(self.method)
        return self.y


def oscillator_pacer(**options):
    """Return (stepper, pacer): a DenseStepper of :func:`oscillator` from (1, 0) at t = 0."""
    st = DenseStepper(oscillator, 0.0, np.array([1.0, 0.0]))
    return st, Pacer(st, **options)


@pytest.mark.parametrize('method', ['DOP853', 'Radau'])
def test_advance_to_lands_exactly_on_target(method):
    st = make_stepper(method, oscillator, 0.0, np.array([1.0, 0.0]), rtol=1e-10, atol=1e-12,
                      step_size=1e-3)
    for t in (0.0123, 0.5, 0.5, 1.7777, 3.0):
        y = st.advance_to(t)
        assert st.t == t
        np.testing.assert_allclose(y, exact(t), atol=1e-8)
    with pytest.raises(RuntimeError):
        st.advance_to(1.0)


def test_skipped_ticks_land_exactly_on_target_and_keep_the_grid():
    st, pacer = oscillator_pacer(sample_rate=100.0, rtf=1.0, max_catch_up=0.25)
    wall0 = 1000.0
    ticks = [0.0, 0.01, 0.02, 0.0537, 0.06, 0.0999, 0.2]   # irregular, with skipped ticks
    seen = []
    for dt in ticks:
        samples = pacer.tick(wall0 + dt)
        assert st.t == pytest.approx(dt, abs=1e-12)      # t_target = rtf * elapsed exactly
        seen += samples
    ks = [s.k for s in seen]
    assert ks == list(range(21))                          # every grid point once, in order
    for s in seen:
        assert s.t == pytest.approx(s.k / 100.0, abs=1e-15)
        np.testing.assert_allclose(s.y, exact(s.t), atol=1e-9)


def test_real_time_factor_scales_simulation_time():
    st, pacer = oscillator_pacer(sample_rate=50.0, rtf=0.5)
    samples = pacer.tick(10.0)
    samples += pacer.tick(10.2)
    assert st.t == pytest.approx(0.1, abs=1e-12)
    assert [s.k for s in samples] == [0, 1, 2, 3, 4, 5]
    pacer.set_rtf(2.0, 10.2)
    pacer.tick(10.3)
    assert st.t == pytest.approx(0.3, abs=1e-12)


def test_catch_up_is_capped_counted_and_reanchored():
    st, pacer = oscillator_pacer(sample_rate=100.0, rtf=1.0, max_catch_up=0.1)
    pacer.tick(0.0)
    samples = pacer.tick(0.5)                      # a 0.5 s stall: only 0.1 s caught up
    assert st.t == pytest.approx(0.1, abs=1e-12)
    assert len(samples) == 10
    assert pacer.capped == 1
    assert pacer.lost_sim_time == pytest.approx(0.4, abs=1e-12)
    pacer.tick(0.55)                               # re-anchored: no further catching up
    assert st.t == pytest.approx(0.15, abs=1e-12)
    w = pacer.take_window(0.55)
    assert w.capped == 1
    assert w.achieved_rtf == pytest.approx(0.15 / 0.55)


def test_rtf_zero_advances_a_fixed_chunk_per_tick():
    st, pacer = oscillator_pacer(sample_rate=200.0, rtf=0.0, chunk_samples=3)
    pacer.tick(0.0)                                # wall time is irrelevant at rtf 0
    pacer.tick(0.0)
    samples = pacer.tick(0.0)
    assert [s.k for s in samples] == [6, 7, 8]
    assert st.t == pytest.approx(8 / 200.0, abs=1e-15)


def test_pause_holds_time_and_resume_does_not_jump():
    st, pacer = oscillator_pacer(sample_rate=100.0, rtf=1.0)
    pacer.tick(0.0)
    pacer.tick(0.1)
    pacer.pause(0.1)
    assert pacer.tick(5.0) == []
    assert st.t == pytest.approx(0.1)
    pacer.resume(5.0)
    samples = pacer.tick(5.05)
    assert st.t == pytest.approx(0.15, abs=1e-12)
    assert [s.k for s in samples] == [11, 12, 13, 14, 15]
    assert pacer.capped == 0


def test_t_end_stops_the_pacer():
    st, pacer = oscillator_pacer(sample_rate=10.0, rtf=1.0, t_end=0.35)
    samples = pacer.tick(0.0)
    samples += pacer.tick(0.2)
    samples += pacer.tick(0.3)
    assert not pacer.finished
    samples += pacer.tick(0.9)
    assert pacer.finished and st.t == pytest.approx(0.35)
    assert [s.k for s in samples] == [0, 1, 2, 3]
    assert pacer.tick(1.0) == []
    # a later t_end continues from the stop, in real time from the next tick (the demo
    # holds the simulation at its kick's time this way): no catch-up of the idle second
    capped = pacer.capped
    pacer.t_end = 0.6
    assert not pacer.finished
    assert pacer.tick(2.0) == []                    # re-anchors at (2.0, 0.35)
    samples = pacer.tick(2.1)
    assert st.t == pytest.approx(0.45) and [s.k for s in samples] == [4]
    assert pacer.capped == capped
    pacer.t_end = 0.45                              # an earlier stop: finished at once
    assert pacer.finished and pacer.tick(3.0) == []


def test_overruns_count_ticks_longer_than_the_period():
    st, pacer = oscillator_pacer(sample_rate=100.0, rtf=1.0)
    pacer.tick(0.0)
    pacer.end_tick(0.005)
    pacer.tick(0.01)
    pacer.end_tick(0.025)                          # 15 ms > 10 ms period
    assert pacer.overruns == 1
    w = pacer.take_window(0.03)
    assert w.overruns == 1 and w.ticks == 2 and w.busy_max == pytest.approx(0.015)


def test_nonfinite_state_raises_and_keeps_the_last_good_state():
    st2 = DenseStepper(lambda t, y: y * y, 0.0, np.array([1.0]))   # blows up at t = 1
    with pytest.raises(IntegrationError):
        st2.advance_to(2.0)
    assert st2.t < 1.0 and np.all(np.isfinite(st2.y))


def test_bad_arguments_are_refused():
    y0 = np.array([1.0, 0.0])
    with pytest.raises(ParameterError, match='unknown integrator'):
        make_stepper('euler', oscillator, 0.0, y0)
    with pytest.raises(ParameterError, match='rtol'):
        DenseStepper(oscillator, 0.0, y0, rtol=-1.0)
    with pytest.raises(ParameterError, match='real_time_factor'):
        Pacer(DenseStepper(oscillator, 0.0, y0), 100.0, rtf=-1.0)


def test_energy_baseline_keeps_the_residual_continuous_across_a_jump():
    # E = k x^2 / 2 + v^2 / 2, D in slot 2; a stiffness change from k = 1 to k = 4
    y = np.array([0.5, 0.2, 0.1])
    eb = EnergyBaseline(lambda s: 0.5 * s[0] ** 2 + 0.5 * s[1] ** 2, 2, y)
    assert eb.residual(y) == pytest.approx(0.0)
    y2 = y + np.array([0.0, 0.0, 0.01])            # pretend integration error of 0.01 J
    r_before = eb.residual(y2)
    jump = eb.rebase(lambda s: 2.0 * s[0] ** 2 + 0.5 * s[1] ** 2, y2, y2)
    assert jump == pytest.approx(1.5 * 0.25)       # (4 - 1) x^2 / 2
    assert eb.residual(y2) == pytest.approx(r_before)


def test_realtime_does_not_import_rclpy():
    code = 'import sys, gyro_rotor.numerics.realtime; assert "rclpy" not in sys.modules'
    subprocess.run([sys.executable, '-c', code], check=True)


def test_integrators_package_methods_behind_the_same_interface():
    from gyro_rotor.numerics.realtime import IntegratorStepper
    from gyro_rotor.core.scene import load_scene
    scene = load_scene('precession')
    model = scene.make_model()
    y0 = scene.initial_state(model)
    ours = make_stepper('dop853', model.rhs, 0.0, y0, model=model)
    ref = make_stepper('DOP853', model.rhs, 0.0, y0)
    assert isinstance(ours, IntegratorStepper)
    pacer = Pacer(ours, sample_rate=250.0, rtf=1.0)
    pacer.tick(0.0)
    pacer.tick(0.1234)
    assert ours.t == pytest.approx(0.1234, abs=1e-12)
    np.testing.assert_allclose(ours.y, ref.advance_to(ours.t), rtol=0, atol=1e-8)


def test_restart_on_a_grid_point_does_not_repeat_its_sample():
    """At rtf 0 every tick ends on the grid; a change there must not publish k twice."""
    st, pacer = oscillator_pacer(sample_rate=100.0, rtf=0.0, chunk_samples=5)
    first = pacer.tick(0.0)
    assert [s.k for s in first] == [0, 1, 2, 3, 4] and st.t == pytest.approx(0.04)
    pacer.restart(DenseStepper(oscillator, st.t, st.y))
    assert [s.k for s in pacer.tick(0.0)] == [5, 6, 7, 8, 9]
    pacer.restart(DenseStepper(oscillator, 0.0, np.array([1.0, 0.0])))   # back to 0
    assert [s.k for s in pacer.tick(0.0)] == [0, 1, 2, 3, 4]


def test_deadline_cuts_a_tick_keeps_the_grid_and_books_the_lost_time():
    st = EulerStepper(1e-3)
    pacer = Pacer(st, sample_rate=100.0, rtf=1.0)
    pacer.tick(0.0)
    out = pacer.tick(0.2, deadline=-1.0)            # a deadline already past: one step
    assert pacer.cut and pacer.budget_cuts == 1
    assert out == [] and st.t == pytest.approx(1e-3)
    assert pacer.lost_sim_time == pytest.approx(0.2 - 1e-3)
    out = pacer.tick(0.25)                          # re-anchored at the cut: 0.05 s more
    assert not pacer.cut and [s.k for s in out] == [1, 2, 3, 4, 5]
    assert pacer.take_window(0.25).budget_cuts == 1


@pytest.mark.parametrize('method', ['DOP853'])
def test_an_arithmetic_error_of_the_rhs_is_an_integration_error(method):
    def divide(t, y):
        return np.array([1.0 / 0.0 if t > 0.05 else 1.0])   # Python floats: ZeroDivisionError
    st = make_stepper(method, divide, 0.0, np.array([0.0]), step_size=0.01)
    with pytest.raises(IntegrationError, match='ZeroDivisionError'):
        st.advance_to(1.0)
    assert np.all(np.isfinite(st.y))


def test_an_overflowed_quaternion_norm_is_a_divergence_not_q_equal_zero():
    """Issue 12's flaky ZeroDivisionError: |q| overflowed, 1 / inf made q exactly 0."""
    from gyro_rotor.numerics.integrators import kernels
    y = np.zeros(10)
    y[0:4] = 1e160                                  # finite, but |q|^2 overflows
    f = np.ones(10)
    kernels.normalize_quaternion(0, y, f)
    assert not np.any(np.isfinite(y[0:4]))          # before the fix: exactly 0.0
    y[0:4] = (3.0, 0.0, 4.0, 0.0)                   # an ordinary norm is still projected
    kernels.normalize_quaternion(0, y, f)
    np.testing.assert_allclose(y[0:4], (0.6, 0.0, 0.8, 0.0), rtol=1e-15)


# -- the real-time loop's clock (issue 27) ------------------------------------------------------
class FakeClock:
    """A steady clock that ``sleep_until`` advances to the deadline plus a wake-up delay."""

    def __init__(self, t=100.0, delay=2e-5):
        self.t, self.delay, self.sleeps = t, delay, []

    def __call__(self):
        return self.t

    def sleep(self, deadline, stop=None):
        self.sleeps.append(deadline)
        self.t = max(self.t, deadline) + self.delay


def test_deadlines_are_absolute_and_lateness_is_measured_against_them():
    from gyro_rotor.numerics.realtime import Deadlines
    clock = FakeClock()
    d = Deadlines(0.001, clock=clock, sleep=clock.sleep)
    d.start(100.0)
    got = []
    for _ in range(5):
        scheduled, woke = d.wait()
        got.append(scheduled)
        clock.t += 3e-4                                  # the tick's work
        d.done()
    # the deadlines are t0 + k period, however long the work and the wake-up took
    np.testing.assert_allclose(got, 100.0 + 1e-3 * np.arange(5), rtol=0, atol=1e-12)
    assert clock.sleeps == pytest.approx(got[1:], abs=1e-12)   # (the first is due at once)
    w = d.take_window()
    assert w.ticks == 5 and w.skipped == 0 and w.late == 0
    assert w.lateness_p99 == pytest.approx(2e-5) and w.done_max == pytest.approx(3.2e-4)
    assert d.take_window().ticks == 0                    # a fresh window


def test_passed_deadlines_are_skipped_and_counted_late_never_worked_off():
    from gyro_rotor.numerics.realtime import Deadlines
    clock = FakeClock(t=99.9, delay=0.0)
    d = Deadlines(0.001, clock=clock, sleep=clock.sleep)
    d.start(100.0)
    d.wait()
    assert d.busy_streak == 0
    clock.t += 3.5e-3                                    # a stall of 3.5 periods
    d.done()
    scheduled, woke = d.wait()                           # no sleep: the latest passed one
    assert scheduled == pytest.approx(100.003) and woke == pytest.approx(100.0035)
    assert d.busy_streak == 1
    d.done()
    scheduled, _ = d.wait()                              # back on the grid, asleep again
    assert scheduled == pytest.approx(100.004) and d.busy_streak == 0
    d.done()
    w = d.take_window()
    # skipped: 100.001 and 100.002; late: those two and the stalled tick (done 3.5 ms)
    assert w.skipped == 2 and w.late == 3 and d.late_total == 3
    assert w.lateness_max == pytest.approx(5e-4)


def test_deadlines_refuse_a_bad_period():
    from gyro_rotor.numerics.realtime import Deadlines
    for bad in (0.0, -1.0, math.inf, math.nan):
        with pytest.raises(ParameterError):
            Deadlines(bad)


def test_sleep_until_wakes_at_the_absolute_deadline():
    import time
    from gyro_rotor.numerics.realtime import sleep_until
    for _ in range(3):
        deadline = time.monotonic() + 0.01
        sleep_until(deadline)
        assert time.monotonic() >= deadline
    import threading
    stop = threading.Event()
    stop.set()
    start = time.monotonic()
    sleep_until(start + 5.0, stop)                       # a long sleep ends with stop
    assert time.monotonic() - start < 1.0


def test_thread_priority_is_raised_or_the_reason_given():
    import threading
    from gyro_rotor.numerics.realtime import set_thread_priority
    out = {}

    def run():
        out['fifo'] = set_thread_priority(10)
        out['policy'] = os.sched_getscheduler(0) if hasattr(os, 'sched_getscheduler') else None
        out['other'] = set_thread_priority(0)
    t = threading.Thread(target=run)
    t.start()
    t.join()
    assert out['other'] is None
    if out['fifo'] is None:
        assert out['policy'] == os.SCHED_FIFO
    else:
        assert isinstance(out['fifo'], str) and out['fifo']       # why not, for the log


def test_pacer_targets_the_scheduled_time_and_says_when_the_next_sample_is_due():
    """A loop passes the deadline as ``now`` (the target lands on the grid), ``woke`` apart."""
    st, pacer = oscillator_pacer(sample_rate=1000.0, rtf=1.0)
    assert pacer.due() is None                            # no time base yet
    out = pacer.tick(50.0, woke=50.0004)
    assert [s.k for s in out] == [0] and st.t == 0.0
    assert pacer.anchor == (50.0, 0.0) and pacer.k_next == 1
    assert pacer.due() == pytest.approx(50.001, abs=1e-12)
    out = pacer.tick(50.001, woke=50.0013)
    assert [s.k for s in out] == [1] and st.t == pytest.approx(0.001, abs=1e-15)
    pacer.end_tick(50.0015)
    w = pacer.take_window(50.002)
    assert w.interval_mean == pytest.approx(0.0009)        # between the wake-ups
    assert w.busy_max == pytest.approx(0.0002)             # from the wake-up
    pacer.pause(50.002)
    assert pacer.due() is None
