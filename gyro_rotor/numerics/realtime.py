"""Real-time pacing of a simulation: pure Python, no rclpy (unit-testable with a fake clock).

The simulation node calls :meth:`Pacer.tick` from a steady-clock timer with the current
steady (monotonic) clock reading. The pacer then advances the integrator **exactly** to

    t_target = t_sim0 + rtf (now - wall0)

however many timer ticks rcl skipped (it measures elapsed time, never assumes one step
per tick), and returns the states on the output grid ``t_k = k / sample_rate`` that it
passed on the way. So every simulated second carries exactly ``sample_rate`` samples,
whatever the wall-clock timing was, and a consumer can prove from the sample index that
none was dropped.

If the simulation cannot keep up (a tick would have to catch up more than
``max_catch_up`` wall seconds of simulation), the catch-up is capped, the tick counted as
*capped* and the lost simulated time accumulated; the time base is then re-anchored, so
simulation time falls behind ``rtf`` times wall time visibly (the achieved real-time
factor drops) rather than silently. A tick whose own work took longer than the timer
period counts as an *overrun*.

With ``rtf = 0`` ("as fast as possible") each tick advances by a fixed chunk of
``chunk_samples`` output samples.

**Work budget.** A tick may be given a ``deadline`` (a ``time.monotonic()`` reading): the
steppers check it after every step, so a tick whose work would exceed it (a live change
to a stiff or very fast system) stops at the step where the budget ran out, with the
stepper's ``t, y`` at that step's end. The tick returns the samples it reached, counts as
*cut* (``budget_cuts``), and the simulation time not reached is counted as lost (the time
base is re-anchored), so the caller is back in its event loop within about one step of the
deadline.

The integrators behind the pacer share the minimal interface of :class:`Stepper` (``t``,
``y``, ``nfev``, ``advance_to(t, deadline)``, ``method``): :class:`DenseStepper` wraps a scipy
``OdeSolver`` class (DOP853 by default) and reaches ``t_target`` with its dense output;
:class:`IntegratorStepper` adapts a method of :mod:`gyro_rotor.numerics.integrators`;
:func:`make_stepper` picks one by name.
"""

from __future__ import annotations

import dataclasses
import math
import os
import sys
import threading
import time
from typing import Callable, Protocol

from gyro_rotor.errors import IntegrationError, ParameterError
from gyro_rotor.numerics.defaults import DEFAULT_ATOL, DEFAULT_RTOL, SCIPY_METHODS
import numpy as np

__all__ = ['Stepper', 'DenseStepper', 'IntegratorStepper', 'make_stepper',
           'resolve_method', 'Pacer', 'Sample', 'WorkBudgetExceeded',
           'WindowStats', 'SCIPY_METHODS', 'DEFAULT_RTOL', 'DEFAULT_ATOL',
           'EnergyBaseline', 'Deadlines', 'LatenessStats', 'sleep_until', 'set_thread_priority',
           'set_timer_slack', 'set_threads_priority']

#: relative slack when comparing grid times with a target time
_GRID_EPS = 1e-9

Rhs = Callable[[float, np.ndarray], np.ndarray]


class Stepper(Protocol):
    """What the pacer needs from an integrator."""

    method: str
    t: float
    y: np.ndarray
    nfev: int

    def advance_to(self, t_target: float, deadline: float | None = None) -> np.ndarray:
        """Integrate to exactly ``t_target`` (>= t) and return y(t_target).

        Raises :class:`WorkBudgetExceeded` (``t, y`` at the last step) when a step ends
        after ``deadline`` (a ``time.monotonic()`` reading) short of ``t_target``.
        """


class WorkBudgetExceeded(Exception):
    """A stepper ran out of its work budget before the target; ``t, y`` are consistent."""


def _over(deadline: float | None) -> bool:
    return deadline is not None and time.monotonic() > deadline


def _check_finite(t: float, y: np.ndarray, method: str) -> None:
    if not np.all(np.isfinite(y)):
        raise IntegrationError(f'{method}: the state became non-finite at t = {t:.9g} s')


def _check_rhs(t: float, f: np.ndarray, method: str) -> None:
    """Refuse a start where the right-hand side is not finite.

    The compiled kernels (numpy's error model) give inf or NaN where the model divides by
    zero (the axis at theta = pi) instead of raising.
    """
    if not np.all(np.isfinite(f)):
        raise IntegrationError(f'{method}: the right-hand side is not finite at t = {t:.9g} s '
                               '(a state the model cannot evaluate, e.g. the axis at '
                               'theta = pi)')


def _arithmetic(method: str, t: float, err: ArithmeticError) -> IntegrationError:
    """Return the IntegrationError for an exception raised by the right-hand side.

    A diverging solution can reach states where the model's formulas divide by zero (the
    compiled kernels follow Python's rules and raise ZeroDivisionError) or overflow.
    """
    return IntegrationError(f'{method}: the right-hand side failed near t = {t:.9g} s '
                            f'({type(err).__name__}: {err})')


class DenseStepper:
    """A scipy ``OdeSolver`` (e.g. DOP853) stepping freely, sampled with its dense output.

    The solver takes its own steps (independent of the targets); a target inside the last
    step is read from the step's interpolant, as ``solve_ivp(t_eval=...)`` does. The last
    good state stays available when a step fails or produces non-finite values
    (:class:`~gyro_rotor.errors.IntegrationError` is raised, the stepper is then dead).
    """

    def __init__(self, fun: Rhs, t0: float, y0: np.ndarray, method: str = 'DOP853',
                 rtol: float = DEFAULT_RTOL, atol: float = DEFAULT_ATOL):
        import scipy.integrate
        if method not in SCIPY_METHODS:
            raise ParameterError(f"unknown integrator '{method}'; valid: "
                                 f"{', '.join(SCIPY_METHODS)}, rk4")
        for name, v in (('rtol', rtol), ('atol', atol)):
            if not (math.isfinite(v) and v > 0):
                raise ParameterError(f'{name} must be positive and finite, got {v!r}')
        self.method = method
        self.rtol, self.atol = float(rtol), float(atol)
        y0 = np.array(y0, dtype=float)
        _check_finite(t0, y0, method)
        self._solver = getattr(scipy.integrate, method)(fun, float(t0), y0, np.inf,
                                                        rtol=rtol, atol=atol)
        _check_rhs(t0, np.asarray(fun(float(t0), y0), dtype=float), method)
        self.t = float(t0)
        self.y = y0
        self._dense = None
        self._dense_t = None
        self.failed = False

    @property
    def nfev(self) -> int:
        """Right-hand side evaluations so far."""
        return int(self._solver.nfev)

    def advance_to(self, t_target: float, deadline: float | None = None) -> np.ndarray:
        """Integrate to exactly ``t_target`` and return y(t_target) (see :class:`Stepper`)."""
        s = self._solver
        if self.failed:
            raise IntegrationError(f'{self.method}: the integrator failed earlier')
        if t_target < self.t:
            raise RuntimeError(f'advance_to({t_target}) is before t = {self.t}')
        while s.t < t_target:
            try:
                msg = s.step()
            except ArithmeticError as err:
                self.failed = True
                raise _arithmetic(self.method, s.t, err) from err
            if s.status == 'failed' or not np.all(np.isfinite(s.y)):
                self.failed = True
                raise IntegrationError(f'{self.method}: step failed at t = {s.t:.9g} s'
                                       + (f': {msg}' if msg else ': non-finite state'))
            if s.t < t_target and _over(deadline):
                self.t, self.y = float(s.t), s.y.copy()
                raise WorkBudgetExceeded(self.method)
        if s.t == t_target:
            y = s.y.copy()
        else:
            if self._dense_t != s.t:
                self._dense = s.dense_output()
                self._dense_t = s.t
            y = self._dense(t_target)
        _check_finite(t_target, y, self.method)
        self.t, self.y = float(t_target), y
        return y


class IntegratorStepper:
    """Adapter of a :mod:`gyro_rotor.numerics.integrators` method to :class:`Stepper`.

    Its ``advance_to`` clips the last step onto the target; a failed status, or an
    arithmetic exception of the compiled right-hand side, becomes an
    :class:`~gyro_rotor.errors.IntegrationError`, with the last good state kept in
    ``t, y``. With a ``deadline`` it steps one accepted step at a time (the loop of
    ``Integrator.advance_to``) and checks the clock after each.
    """

    def __init__(self, integrator):
        self.integrator = integrator
        self.method = integrator.name
        self.rtol = integrator.rtol
        self.atol = integrator.atol
        self.t = float(integrator.t)
        self.y = np.array(integrator.y, dtype=float)
        _check_rhs(self.t, integrator.f, self.method)

    @property
    def nfev(self) -> int:
        """Right-hand side evaluations so far."""
        return int(self.integrator.nfev)

    def advance_to(self, t_target: float, deadline: float | None = None) -> np.ndarray:
        """Integrate to exactly ``t_target`` and return y(t_target) (see :class:`Stepper`)."""
        if t_target < self.t:
            raise RuntimeError(f'advance_to({t_target}) is before t = {self.t}')
        integ = self.integrator
        try:
            if deadline is None:
                status = integ.advance_to(t_target)
            else:
                while integ.t < t_target and integ.status == 'running':
                    integ._advance(t_target)      # one accepted step, clipped at the target
                    if integ.t < t_target and integ.status == 'running' and _over(deadline):
                        self.t, self.y = float(integ.t), np.array(integ.y, dtype=float)
                        raise WorkBudgetExceeded(self.method)
                status = integ.status
        except ArithmeticError as err:
            integ.status = 'failed'
            raise _arithmetic(self.method, integ.t, err) from err
        y = np.array(integ.y, dtype=float)
        if status == 'failed' or not np.all(np.isfinite(y)):
            raise IntegrationError(f'{self.method}: failed near t = '
                                   f'{self.integrator.t:.9g} s: {self.integrator.message}')
        self.t, self.y = float(t_target), y
        return y


def resolve_method(method: str, model, t_end: float = math.inf, y=None) -> tuple[str, str]:
    """'auto' -> (method, reason) for ``model`` at the state y: the integrators' choice."""
    if method != 'auto':
        return method, 'requested'
    from gyro_rotor.numerics.integrators import choose_method
    return choose_method(model, t_end, y0=y)


def make_stepper(method: str, fun: Rhs, t0: float, y0: np.ndarray, *, rtol: float = 0.0,
                 atol: float = 0.0, step_size: float = 0.0, model=None) -> Stepper:
    """Make a stepper by name.

    With ``model`` given, a method of :mod:`gyro_rotor.numerics.integrators` (``rk4``, ``rk8``,
    ``dop853``, ``gauss6``, ``rodas4``); the scipy names (``DOP853``, ``Radau``, ...):
    scipy's OdeSolver with dense output. Zero tolerances or step size mean the method's
    default.
    """
    from gyro_rotor.numerics.integrators import make_integrator, METHODS
    if model is not None and method in METHODS:
        try:
            integ = make_integrator(method, model, y0, t0, math.inf, rtol=rtol or None,
                                    atol=atol or None, step=step_size or None)
        except ValueError as err:
            raise ParameterError(str(err)) from err
        return IntegratorStepper(integ)
    if method in SCIPY_METHODS:
        return DenseStepper(fun, t0, y0, method, rtol or DEFAULT_RTOL, atol or DEFAULT_ATOL)
    raise ParameterError(f"unknown integrator '{method}'; valid: "
                         f"{', '.join(['auto', *METHODS, *SCIPY_METHODS])}")


@dataclasses.dataclass(frozen=True)
class Sample:
    """One output sample: grid index k (t = k / sample_rate) and the state there."""

    k: int
    t: float
    y: np.ndarray


@dataclasses.dataclass(frozen=True)
class WindowStats:
    """Pacing figures over a window of wall time (see :meth:`Pacer.take_window`)."""

    wall: float              # wall seconds in the window (not paused)
    sim: float               # simulated seconds advanced in the window
    achieved_rtf: float      # sim / wall (nan if the window is empty)
    ticks: int
    samples: int
    overruns: int            # ticks whose work took longer than the period
    budget_cuts: int         # ticks stopped by their work budget (sim time lost)
    capped: int              # ticks whose catch-up was capped (sim time lost)
    lost_sim_time: float     # simulated seconds given up by capping
    interval_mean: float     # mean wall interval between ticks [s]
    interval_std: float      # its standard deviation (tick jitter) [s]
    interval_max: float
    interval_p99: float      # 99th percentile of the interval [s]
    busy_mean: float         # mean wall time of a tick's work [s]
    busy_max: float


class Pacer:
    """Advance a :class:`Stepper` in step with a steady clock (see module doc).

    Parameters
    ----------
    stepper : Stepper
        The integrator; ``stepper.t`` is the current simulation time.
    sample_rate : float
        Output grid rate [Hz]: samples at ``t_k = k / sample_rate`` (the publish rate).
    rtf : float
        Real-time factor (simulated seconds per wall second); 0 = as fast as possible.
    max_catch_up : float
        Most wall seconds of simulation one tick may catch up [s].
    period : float
        The timer period [s], to count overruns (default 1 / sample_rate).
    chunk_samples : int
        Samples per tick with ``rtf = 0``.
    t_end : float or None
        Stop at this simulation time (the pacer then idles; ``finished`` is true).
    """

    def __init__(self, stepper: Stepper, sample_rate: float, rtf: float = 1.0,
                 max_catch_up: float = 0.25, period: float | None = None,
                 chunk_samples: int = 1, t_end: float | None = None):
        if not (math.isfinite(sample_rate) and sample_rate > 0):
            raise ParameterError(f'sample_rate must be positive, got {sample_rate!r}')
        if not (math.isfinite(max_catch_up) and max_catch_up > 0):
            raise ParameterError(f'max_catch_up must be positive, got {max_catch_up!r}')
        if chunk_samples < 1:
            raise ParameterError(f'chunk_samples must be >= 1, got {chunk_samples!r}')
        self.sample_rate = float(sample_rate)
        self.max_catch_up = float(max_catch_up)
        self.period = float(period) if period else 1.0 / self.sample_rate
        self.chunk_samples = int(chunk_samples)
        self.rtf = 0.0
        self.set_rtf(rtf, None)
        self.paused = False
        self.finished = False
        self.stepper = stepper
        self._t_end = t_end
        self._k_next = self._first_k(stepper.t)
        self._anchor: tuple[float, float] | None = None     # (wall0, t_sim0)
        self._last_tick: float | None = None
        self._tick_start = 0.0
        #: whether the last tick was stopped by its work budget
        self.cut = False
        # totals
        self.ticks = self.samples = self.overruns = self.capped = self.budget_cuts = 0
        self.lost_sim_time = 0.0
        self._reset_window(None)

    # -- control ---------------------------------------------------------------------------
    @property
    def t_end(self) -> float | None:
        """Return the simulation time to stop at (None: never)."""
        return self._t_end

    @t_end.setter
    def t_end(self, t_end: float | None) -> None:
        """Move the stop: a pacer finished at the old one continues if the new one is later.

        It continues in real time from where it stopped (the time it idled is not caught up).
        """
        self._t_end = t_end
        was = self.finished
        self.finished = t_end is not None and self.stepper.t >= t_end
        if was and not self.finished:
            self._anchor = None

    @property
    def anchor(self) -> tuple[float, float] | None:
        """Return the time base (wall0, t_sim0): t_target = t_sim0 + rtf (now - wall0)."""
        return self._anchor

    @property
    def k_next(self) -> int:
        """Return the grid index of the next sample to produce."""
        return self._k_next

    def due(self) -> float | None:
        """Return when the next sample is due on the steady clock (None: not known).

        Known while running in real time (rtf > 0) with a time base; a loop sleeping to
        absolute deadlines aligns them with it, so that each sample is produced at the
        first deadline at or after its due time, not one period later.
        """
        if self._anchor is None or self.rtf <= 0 or self.paused or self.finished:
            return None
        wall0, t0 = self._anchor
        return wall0 + (self.grid_time(self._k_next) - t0) / self.rtf

    def _first_k(self, t: float) -> int:
        """Index of the first grid point at or after t."""
        return int(math.ceil(t * self.sample_rate - _GRID_EPS))

    def grid_time(self, k: int) -> float:
        """t_k = k / sample_rate."""
        return k / self.sample_rate

    def set_rtf(self, rtf: float, now: float | None) -> None:
        """Change the real-time factor (re-anchors the time base at ``now``)."""
        if not (math.isfinite(rtf) and rtf >= 0):
            raise ParameterError(f'real_time_factor must be >= 0 and finite, got {rtf!r}')
        self.rtf = float(rtf)
        if now is not None and getattr(self, 'stepper', None) is not None:
            self._anchor = (now, self.stepper.t)

    def restart(self, stepper: Stepper, now: float | None = None) -> None:
        """Continue with a new stepper (reset, kick, parameter change) from its t.

        Continuing at the same time (a kick or a parameter change right on a grid point,
        as every tick at rtf 0 ends) does not repeat that grid point's sample.
        """
        k = self._first_k(stepper.t)
        if stepper.t >= self.stepper.t:
            k = max(k, self._k_next)
        self.stepper = stepper
        self._k_next = k
        self.finished = self.t_end is not None and stepper.t >= self.t_end
        if now is not None and self._anchor is not None:
            self._anchor = (now, stepper.t)

    def pause(self, now: float) -> None:
        """Stop advancing; ticks are still counted."""
        self.paused = True

    def resume(self, now: float) -> None:
        """Continue from the current simulation time (re-anchored at ``now``)."""
        if self.paused:
            self.paused = False
            self._anchor = (now, self.stepper.t)
            self._window_wall0 = now
            self._window_t0 = self.stepper.t
            self._last_tick = None

    # -- stepping --------------------------------------------------------------------------
    def tick(self, now: float, deadline: float | None = None,
             woke: float | None = None) -> list[Sample]:
        """Advance to the target time for steady-clock reading ``now``; return grid samples.

        With a ``deadline`` (a ``time.monotonic()`` reading) the work stops at the first
        step that ends after it (see the module doc: ``cut``, ``budget_cuts``). ``woke``:
        when the tick really started, if ``now`` is its scheduled time (a loop sleeping to
        absolute deadlines passes the deadline as ``now``, so that the target time lands on
        the grid); the interval and busy-time figures use it. Raises
        :class:`~gyro_rotor.errors.IntegrationError` from the stepper (its last good state
        remains ``stepper.t, stepper.y``).
        """
        self.cut = False
        woke = now if woke is None else woke
        self._tick_start = woke
        if self._last_tick is not None:
            dt = woke - self._last_tick
            self._w_intervals.append(dt)
        self._last_tick = woke
        self.ticks += 1
        self._w_ticks += 1
        if self._window_wall0 is None:
            self._window_wall0, self._window_t0 = now, self.stepper.t
        if self.paused or self.finished:
            return []
        st = self.stepper
        if self.rtf > 0:
            if self._anchor is None:
                self._anchor = (now, st.t)
            wall0, t0 = self._anchor
            t_target = t0 + self.rtf * (now - wall0)
            cap = self.rtf * self.max_catch_up
            if t_target - st.t > cap:
                self.capped += 1
                self._w_capped += 1
                lost = t_target - st.t - cap
                self.lost_sim_time += lost
                self._w_lost += lost
                t_target = st.t + cap
                self._anchor = (now, t_target)
        else:
            t_target = self.grid_time(self._k_next + self.chunk_samples - 1)
        if self.t_end is not None and t_target >= self.t_end:
            t_target = self.t_end
            self.finished = True
        if t_target < st.t:
            t_target = st.t
        out: list[Sample] = []
        try:
            self._advance(t_target, out, deadline)
        except WorkBudgetExceeded:
            self._cut(t_target, max(now, deadline))
        self.samples += len(out)
        self._w_samples += len(out)
        return out

    def _advance(self, t_target: float, out: list, deadline: float | None) -> None:
        """Step to t_target, appending the grid samples passed on the way to ``out``."""
        st = self.stepper
        slack = _GRID_EPS / self.sample_rate
        while True:
            tk = self.grid_time(self._k_next)
            if tk > t_target + slack:
                break
            tk = max(tk, st.t)
            y = st.advance_to(tk, deadline)
            out.append(Sample(self._k_next, tk, np.array(y, copy=True)))
            self._k_next += 1
            if st.t < t_target and _over(deadline):      # (steps that end on the grid)
                raise WorkBudgetExceeded(st.method)
        if t_target > st.t:
            st.advance_to(t_target, deadline)

    def _cut(self, t_target: float, when: float) -> None:
        """Book a tick stopped by its budget at ``when``; the rest of its target is lost."""
        self.cut = True
        self.finished = False
        self.budget_cuts += 1
        self._w_budget += 1
        if self.rtf > 0:
            lost = t_target - self.stepper.t
            self.lost_sim_time += lost
            self._w_lost += lost
            self._anchor = (when, self.stepper.t)

    def end_tick(self, now: float) -> None:
        """Record the end of a tick's work (for overrun and busy-time figures)."""
        busy = now - self._tick_start
        self._w_busy.append(busy)
        if self.rtf > 0 and busy > self.period:
            self.overruns += 1
            self._w_overruns += 1

    # -- statistics ------------------------------------------------------------------------
    def _reset_window(self, now: float | None) -> None:
        self._window_wall0 = now
        self._window_t0 = self.stepper.t if getattr(self, 'stepper', None) else 0.0
        self._w_intervals: list[float] = []
        self._w_busy: list[float] = []
        self._w_ticks = self._w_samples = self._w_overruns = self._w_capped = 0
        self._w_budget = 0
        self._w_lost = 0.0

    def take_window(self, now: float) -> WindowStats:
        """Figures since the last call (or the start) and a fresh window."""
        wall = 0.0 if self._window_wall0 is None else now - self._window_wall0
        sim = self.stepper.t - self._window_t0
        iv = np.array(self._w_intervals) if self._w_intervals else np.array([math.nan])
        busy = np.array(self._w_busy) if self._w_busy else np.array([math.nan])
        stats = WindowStats(
            wall=wall, sim=sim,
            achieved_rtf=(sim / wall) if wall > 0 and not self.paused else math.nan,
            ticks=self._w_ticks, samples=self._w_samples, overruns=self._w_overruns,
            capped=self._w_capped, budget_cuts=self._w_budget, lost_sim_time=self._w_lost,
            interval_mean=float(np.mean(iv)), interval_std=float(np.std(iv)),
            interval_max=float(np.max(iv)), interval_p99=float(np.percentile(iv, 99)),
            busy_mean=float(np.mean(busy)),
            busy_max=float(np.max(busy)))
        self._reset_window(now)
        return stats


class EnergyBaseline:
    """Bookkeeping of the energy-balance residual r = E* + D - E_ref across interventions.

    Along an undisturbed solution E* + D is constant (eq. 17), so r measures the
    integration error only. An intervention (a parameter change such as K_S, a kick, a
    reset) changes E* at an instant without any integration error; :meth:`rebase` moves
    E_ref by that jump so that r stays continuous across it.
    """

    def __init__(self, energy: Callable[[np.ndarray], float], idiss: int, y0: np.ndarray):
        self.idiss = idiss
        self.restart(energy, y0)

    def restart(self, energy: Callable[[np.ndarray], float], y0: np.ndarray) -> None:
        """Start a new baseline E_ref = E*(y0) + D(y0) (reset)."""
        self.energy = energy
        self.E_ref = float(energy(y0)) + float(y0[self.idiss])

    def rebase(self, energy_new: Callable[[np.ndarray], float], y_new: np.ndarray,
               y_old: np.ndarray) -> float:
        """Account for a jump from (old energy, y_old) to (new energy, y_new); return it."""
        jump = float(energy_new(y_new)) - float(self.energy(y_old))
        self.E_ref += jump
        self.energy = energy_new
        return jump

    def residual(self, y: np.ndarray, E: float | None = None) -> float:
        """Return the residual r = E*(y) + D(y) - E_ref."""
        E = float(self.energy(y)) if E is None else E
        return E + float(y[self.idiss]) - self.E_ref


# -- the loop's clock: absolute deadlines, lateness, scheduling priority ------------------------
def _clock_nanosleep():
    """Return libc's clock_nanosleep (ctypes releases the GIL while it sleeps), or None."""
    import ctypes
    import ctypes.util
    try:
        libc = ctypes.CDLL(ctypes.util.find_library('c') or 'libc.so.6', use_errno=True)
        fn = libc.clock_nanosleep
    except (OSError, AttributeError):
        return None

    class Timespec(ctypes.Structure):
        _fields_ = [('tv_sec', ctypes.c_long), ('tv_nsec', ctypes.c_long)]

    fn.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.POINTER(Timespec), ctypes.c_void_p]
    fn.restype = ctypes.c_int
    return fn, Timespec


_NANOSLEEP = None
#: CLOCK_MONOTONIC and TIMER_ABSTIME of <time.h> (Linux): time.monotonic() reads that clock
_CLOCK_MONOTONIC, _TIMER_ABSTIME = 1, 1


def sleep_until(deadline: float, stop=None) -> None:
    """Sleep until ``time.monotonic()`` reaches ``deadline`` (an absolute reading) [s].

    Uses ``clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME)`` where available, so that the
    time spent computing the sleep cannot shift the wake-up; ``time.sleep`` elsewhere.
    ``stop``: a ``threading.Event`` that ends a long sleep early (waits longer than 50 ms
    are spent in ``stop.wait`` up to 2 ms before the deadline).
    """
    global _NANOSLEEP
    if _NANOSLEEP is None:
        _NANOSLEEP = _clock_nanosleep() or False
    if stop is not None:
        rest = deadline - time.monotonic()
        if rest > 0.05 and stop.wait(rest - 0.002):
            return
    if _NANOSLEEP and sys.platform.startswith('linux'):
        fn, Timespec = _NANOSLEEP
        sec = math.floor(deadline)
        ts = Timespec(sec, min(int((deadline - sec) * 1e9), 999_999_999))
        while fn(_CLOCK_MONOTONIC, _TIMER_ABSTIME, ctypes_byref(ts), None) == 4:   # EINTR
            pass
        return
    rest = deadline - time.monotonic()
    if rest > 0:
        time.sleep(rest)


def ctypes_byref(obj):
    """Return ``ctypes.byref(obj)`` (imported on first use)."""
    import ctypes
    return ctypes.byref(obj)


@dataclasses.dataclass(frozen=True)
class LatenessStats:
    """Timing of a loop's ticks against their absolute deadlines over a window [s].

    ``lateness`` of a tick is when it woke minus its deadline; ``done`` is when its samples
    were published minus the deadline. A deadline passed while an earlier tick was still
    running (or the thread was not scheduled) is *skipped*: the next tick serves the latest
    deadline passed, with every sample of the skipped ones (the pacer integrates by elapsed
    time), so no sample is lost, but they go out late. ``late`` counts the deadlines whose
    samples went out more than one period after them: the skipped ones and the ticks with
    ``done`` above the period.
    """

    ticks: int
    period: float
    lateness_p50: float
    lateness_p99: float
    lateness_max: float
    done_p99: float
    done_max: float
    skipped: int
    late: int


class Deadlines:
    """Absolute deadlines ``t0 + k period`` on the monotonic clock, and how late ticks are.

    :meth:`wait` sleeps to the next deadline and returns ``(deadline, woke)``; when the
    loop fell behind, it returns at once with the latest deadline already passed (the ones
    in between are counted as skipped), so the loop never works off a backlog of deadlines.
    :meth:`done` records the end of the tick's work. :attr:`busy_streak` counts the
    consecutive waits that found their deadline passed (the loop never slept).
    ``clock`` and ``sleep_until`` are injectable (tests use a fake clock).
    """

    def __init__(self, period: float, clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[..., None] = sleep_until):
        if not (math.isfinite(period) and period > 0):
            raise ParameterError(f'period must be positive, got {period!r}')
        self.period = float(period)
        self.clock, self.sleep = clock, sleep
        self._t0: float | None = None
        self._k = 0
        self.late_total = 0
        self._current: float | None = None
        #: consecutive calls of :meth:`wait` that did not sleep
        self.busy_streak = 0

        self._lock = threading.Lock()       # the figures are taken from another thread
        self._reset()

    def _reset(self) -> None:
        self._late: list[float] = []
        self._done: list[float] = []
        self._skipped = 0
        self._n_late = 0

    def start(self, now: float | None = None) -> None:
        """Put the first deadline at ``now`` (default: the clock now)."""
        self._t0 = self.clock() if now is None else now
        self._k = 0

    def wait(self, stop=None) -> tuple[float, float]:
        """Sleep to the next deadline; return (deadline, woke) (see the class doc)."""
        if self._t0 is None:
            self.start()
        deadline = self._t0 + self._k * self.period
        now = self.clock()
        if now < deadline:
            if stop is None:
                self.sleep(deadline)
            else:
                self.sleep(deadline, stop)
            now = self.clock()
            self.busy_streak = 0
        else:
            self.busy_streak += 1
            behind = int((now - deadline) / self.period)
            if behind:
                self._k += behind
                deadline = self._t0 + self._k * self.period
                with self._lock:
                    self._skipped += behind
                    self._n_late += behind
                    self.late_total += behind
        self._k += 1
        self._current = deadline
        with self._lock:
            self._late.append(now - deadline)
        return deadline, now

    def done(self, now: float | None = None) -> None:
        """Record the end of the current tick's work (its samples published)."""
        if self._current is None:
            return
        d = (self.clock() if now is None else now) - self._current
        with self._lock:
            self._done.append(d)
            if d > self.period:
                self._n_late += 1
                self.late_total += 1
        self._current = None

    def restart(self, now: float | None = None) -> None:
        """Start the deadlines afresh at ``now`` (after a pause in the loop)."""
        self.start(now)

    def take_window(self) -> LatenessStats:
        """Figures since the last call (or the start) and a fresh window."""
        with self._lock:
            late_s, done_s, skipped, n_late = self._late, self._done, self._skipped, \
                self._n_late
            self._reset()
        late = np.array(late_s) if late_s else np.array([math.nan])
        done = np.array(done_s) if done_s else np.array([math.nan])
        return LatenessStats(
            ticks=len(late_s), period=self.period,
            lateness_p50=float(np.percentile(late, 50)),
            lateness_p99=float(np.percentile(late, 99)), lateness_max=float(np.max(late)),
            done_p99=float(np.percentile(done, 99)), done_max=float(np.max(done)),
            skipped=skipped, late=n_late)


def set_thread_priority(priority: int) -> str | None:
    """Put the calling thread under SCHED_FIFO at ``priority`` (1..99); 0: SCHED_OTHER.

    Returns None when done, else why not (e.g. no CAP_SYS_NICE and an RLIMIT_RTPRIO of 0).
    """
    if not hasattr(os, 'sched_setscheduler'):
        return 'this platform has no sched_setscheduler'
    try:
        if priority > 0:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(int(priority)))
        else:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    except OSError as err:
        limit = ''
        if hasattr(os, 'RLIMIT_RTPRIO'):
            import resource
            limit = f'; RLIMIT_RTPRIO {resource.getrlimit(resource.RLIMIT_RTPRIO)[0]}'
        return f'{err.strerror or err}{limit}'
    return None


def set_threads_priority(priority: int, exclude: tuple = ()) -> int | str:
    """Put every thread of this process but ``exclude`` (native ids) under SCHED_FIFO.

    ``priority`` 0: back to SCHED_OTHER. Returns how many threads were set, or why not
    (Linux: /proc/self/task; SCHED_FIFO needs CAP_SYS_NICE or an RLIMIT_RTPRIO).
    """
    if not hasattr(os, 'sched_setscheduler'):
        return 'this platform has no sched_setscheduler'
    try:
        tids = [int(t) for t in os.listdir('/proc/self/task')]
    except OSError as err:
        return f'no /proc/self/task ({err.strerror or err})'
    policy = os.SCHED_FIFO if priority > 0 else os.SCHED_OTHER
    n = 0
    for tid in tids:
        if tid in exclude:
            continue
        try:
            os.sched_setscheduler(tid, policy, os.sched_param(max(0, int(priority))))
            n += 1
        except ProcessLookupError:
            continue                        # (a thread that ended meanwhile)
        except OSError as err:
            return err.strerror or str(err)
    return n


def set_timer_slack(ns: int = 1) -> bool:
    """Set the calling thread's timer slack [ns] (Linux; default 50 us); return success."""
    if not sys.platform.startswith('linux'):
        return False
    import ctypes
    import ctypes.util
    try:
        libc = ctypes.CDLL(ctypes.util.find_library('c') or 'libc.so.6', use_errno=True)
        return libc.prctl(29, ctypes.c_ulong(ns), 0, 0, 0) == 0     # PR_SET_TIMERSLACK
    except (OSError, AttributeError):
        return False
