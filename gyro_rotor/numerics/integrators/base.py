"""The integrator contract, modelled on scipy's ``OdeSolver`` (scipy/integrate/_ivp/base.py).

The base class owns the bookkeeping (``t``, ``y``, ``status``, ``nfev``, ``nsteps``, the
public :meth:`Integrator.step` and :meth:`Integrator.advance_to`); a method implements
only ``_step_impl(t_limit) -> (success, message)`` for one accepted step that ends at or
before ``t_limit`` (exactly on it when clipped) and
``_run(t_eval)`` for the compiled loop that samples a whole interval.

Input is checked once, at construction: a non-finite state, non-positive or non-finite
tolerances and a step larger than the horizon are refused with a
:class:`~gyro_rotor.errors.ParameterError` naming the value. A numerical failure during
the run is a *status* (``'failed'`` with a message), never an exception; stepping a
finished or failed integrator is misuse and raises ``RuntimeError``.

Quaternion hook: the full model's state carries the stator quaternion q, which the exact
flow keeps on the unit sphere. Methods with ``renormalize = True`` project it back after
every accepted step (:func:`~gyro_rotor.numerics.integrators.kernels.normalize_quaternion`: q and
dq/dt are scaled together, which keeps the stored derivative exact because the other
equations see q only through its direction). The Gauss method keeps |q| = 1 by itself
(it preserves quadratic invariants) and does not project.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import Any

from gyro_rotor.core.model import drive_rates, Model
from gyro_rotor.errors import ParameterError
from gyro_rotor.numerics.integrators import kernels, primitives
import numpy as np

__all__ = ['Integrator', 'LoopStepped', 'IntegrationResult', 'STATUS_MESSAGES', 'model_rate',
           'kernel_args', 'rates_of']

STATUS_MESSAGES = {
    0: 'The solver successfully reached the end of the integration interval.',
    -1: 'Required step size is less than spacing between numbers.',
    -2: 'The state became non-finite (diverged).',
    -3: 'The step budget (max_steps) was exhausted.',
    -4: 'The implicit stage iteration did not converge (step too large for the method).',
}


@dataclasses.dataclass
class IntegrationResult:
    """Samples of one integration: ``t`` (m,), ``y`` (m, n) and the cost counters."""

    t: np.ndarray
    y: np.ndarray
    method: str
    nfev: int
    nsteps: int
    status: int
    message: str
    njev: int = 0
    nrejected: int = 0

    @property
    def success(self) -> bool:
        """Return True if the end of the interval was reached."""
        return self.status == 0


def _check_positive(name: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f'{name} must be a positive number, got {value!r}') from None
    if not (math.isfinite(v) and v > 0.0):
        raise ParameterError(f'{name} must be positive and finite, got {value!r}')
    return v


class Integrator:
    """Base class of the integrators (see module doc).

    Parameters
    ----------
    model : Model
        The equations of motion (``gyro_rotor.core.model``); its parameters are packed once.
    y0 : array_like, shape (n,)
        Initial state; must be finite.
    t0 : float
        Initial time [s].
    t_bound : float
        End of the horizon [s]; ``inf`` for an open-ended run (the ROS node), which then
        advances with :meth:`advance_to`.
    rtol, atol : float, optional
        Tolerances of adaptive methods (class defaults ``default_rtol``/``default_atol``).
    step : float, optional
        Step of fixed-step methods, or the largest step of adaptive ones [s]. Default:
        ``step_factor / model_rate(params)`` for fixed-step methods.
    max_steps : int
        Step budget; exhausting it fails the run with status -3.
    """

    name = ''
    #: order of the method (global error ~ h^order)
    order = 0
    adaptive = False
    #: a fixed-step method that derives its default step from rtol (split8)
    step_from_tolerance = False
    implicit = False
    renormalize = True
    default_rtol = 1e-10
    default_atol = 1e-12
    #: default fixed step = step_factor / (fastest rate of the model, see model_rate)
    step_factor = 0.05

    def __init__(self, model: Model, y0, t0: float = 0.0, t_bound: float = math.inf, *,
                 rtol: float | None = None, atol: float | None = None,
                 step: float | None = None, max_steps: int = 50_000_000):
        self.model = model
        self.kind, self.P, rate = kernel_args(model, getattr(model, 'params', None))
        y = np.array(y0, dtype=float).reshape(-1)
        if y.shape != (model.n,):
            raise ParameterError(f'y0 must have {model.n} components for model {model.name}, '
                                 f'got shape {np.shape(y0)}')
        if not primitives.all_finite(y):
            raise ParameterError('all components of the initial state y0 must be finite, '
                                 f'got {y.tolist()}')
        t0 = float(t0)
        t_bound = float(t_bound)
        if not math.isfinite(t0) or math.isnan(t_bound) or t_bound < t0:
            raise ParameterError(f't_bound must be >= t0 = {t0}, got {t_bound!r}')
        self.rtol = _check_positive('rtol', self.default_rtol if rtol is None else rtol)
        self.atol = _check_positive('atol', self.default_atol if atol is None else atol)
        if step is None:
            self.h = self.step_factor / rate
            if math.isfinite(t_bound) and t_bound > t0:
                self.h = min(self.h, t_bound - t0)
            self.h_max = self.h if not self.adaptive else math.inf
        else:
            self.h = _check_positive('step', step)
            if math.isfinite(t_bound) and self.h > t_bound - t0:
                raise ParameterError(f'step {self.h} s is larger than the horizon '
                                     f'{t_bound - t0} s')
            self.h_max = self.h
        if int(max_steps) < 1:
            raise ParameterError(f'max_steps must be a positive integer, got {max_steps!r}')
        self.max_steps = int(max_steps)
        self.t = t0
        self.t_bound = t_bound
        self.y = y
        self.t_old: float | None = None
        self.status = 'running' if t_bound > t0 else 'finished'
        self.message: str | None = None
        self.nfev = 0
        self.njev = 0
        self.nsteps = 0
        self.nrejected = 0
        self.step_size: float | None = None
        self._f: np.ndarray | None = None     # f(y), evaluated when a step needs it

    @property
    def f(self) -> np.ndarray:
        """dy/dt at the current state (evaluated on first use after a run: one evaluation)."""
        if self._f is None:
            self._f = self._rhs(self.y)
        return self._f

    @f.setter
    def f(self, value: np.ndarray) -> None:
        self._f = value

    # -- helpers ---------------------------------------------------------------------------
    def _rhs(self, y: np.ndarray) -> np.ndarray:
        out = np.empty_like(y)
        kernels.rhs(self.kind, y, self.P, out)
        self.nfev += 1
        return out

    def project(self, y: np.ndarray, f: np.ndarray) -> None:
        """Apply the quaternion hook (module doc): scale q and dq/dt to |q| = 1, in place."""
        if self.renormalize:
            kernels.normalize_quaternion(self.kind, y, f)

    # -- the public contract ---------------------------------------------------------------
    def step(self) -> str | None:
        """Take one accepted step toward ``t_bound``; returns the failure message or None."""
        return self._advance(self.t_bound)

    def advance_to(self, t_target: float) -> str:
        """Step until ``t == t_target`` exactly, never beyond (the last step is clipped).

        Returns the status; a failed run stops where it failed. ``t_target`` must lie in
        [t, t_bound].
        """
        t_target = float(t_target)
        if not (self.t <= t_target <= self.t_bound):
            raise ParameterError(f't_target must lie in [{self.t}, {self.t_bound}], '
                                 f'got {t_target!r}')
        while self.t < t_target and self.status == 'running':
            self._advance(t_target)
        return self.status

    def _advance(self, t_limit: float) -> str | None:
        if self.status != 'running':
            raise RuntimeError('Attempt to step on a failed or finished solver.')
        t_old = self.t
        success, message = self._step_impl(t_limit)
        if success:
            self.t_old = t_old
            self.step_size = self.t - t_old
            self.nsteps += 1
            if not np.all(np.isfinite(self.y)):
                success, message = False, STATUS_MESSAGES[-2]
            elif self.nsteps >= self.max_steps and self.t < self.t_bound:
                success, message = False, STATUS_MESSAGES[-3]
        if not success:
            self.status = 'failed'
            self.message = message
            return message
        if self.t >= self.t_bound:
            self.status = 'finished'
        return None

    def run(self, t_eval) -> IntegrationResult:
        """Integrate to ``t_eval[-1]`` in the compiled loop, sampling at ``t_eval``.

        ``t_eval`` must be increasing, start at or after ``t`` and end at or before
        ``t_bound``. The integrator's state moves to the end (or to where it failed).
        """
        if self.status != 'running':
            raise RuntimeError('Attempt to run a failed or finished solver.')
        te = np.asarray(t_eval, dtype=float).reshape(-1)
        if not primitives.finite_increasing(te):
            raise ParameterError('t_eval must be a non-empty, finite, increasing array')
        if te[0] < self.t or te[-1] > self.t_bound:
            raise ParameterError(f't_eval must lie in [{self.t}, {self.t_bound}], got '
                                 f'[{te[0]}, {te[-1]}]')
        # the rows the loop stores are whole; column 0 NaN marks those it did not reach
        Y = np.empty((te.size, self.model.n))
        Y[:, 0] = np.nan
        counts = np.zeros(6)
        status = int(self._run(te, Y, counts))
        self.nfev += int(counts[0])
        self.nsteps += int(counts[1])
        self.nrejected += int(counts[2])
        self.njev += int(counts[4])
        done = ~np.isnan(Y[:, 0])
        k = int(np.count_nonzero(done))
        if status == 0:
            self.t, self.y = float(te[-1]), Y[-1].copy()
            self._f = None
            self.status = 'finished' if self.t >= self.t_bound else 'running'
        else:
            self.status = 'failed'
            self.message = STATUS_MESSAGES[status]
        return IntegrationResult(t=te[:k], y=Y[:k], method=self.name, nfev=self.nfev,
                                 nsteps=self.nsteps, status=status,
                                 message=STATUS_MESSAGES[status], njev=self.njev,
                                 nrejected=self.nrejected)

    # -- for subclasses --------------------------------------------------------------------
    def _step_impl(self, t_limit: float) -> tuple[bool, str | None]:  # pragma: no cover
        raise NotImplementedError

    def _run(self, t_eval: np.ndarray, Y: np.ndarray,
             counts: np.ndarray) -> int:  # pragma: no cover
        raise NotImplementedError


class LoopStepped(Integrator):
    """A method whose one step is its compiled run loop with a budget of one step.

    Subclasses implement ``_loop(t_eval, Y, counts, max_steps)``: the run loop, which
    returns the status and leaves (nfev, nsteps, rejected, next step, njev, t at the end) in
    ``counts`` and the state there in ``self._ylast``.
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._h_next = 0.0
        self._ylast = np.empty(self.model.n)

    def _loop(self, t_eval, Y, counts, max_steps):  # pragma: no cover
        raise NotImplementedError

    def _call(self, t_eval, Y, counts, max_steps):
        status = self._loop(t_eval, Y, counts, max_steps)
        self._h_next = counts[3]
        return status

    def _step_impl(self, t_limit):
        counts = np.zeros(6)
        Y = np.empty((1, self.model.n))
        status = self._call(np.array([t_limit]), Y, counts, 1)
        self.nfev += int(counts[0])
        self.njev += int(counts[4])
        self.nrejected += int(counts[2])
        if status not in (kernels.OK, kernels.BUDGET) or counts[1] < 1:
            return False, STATUS_MESSAGES[status if status < 0 else -1]
        self.t = t_limit if status == kernels.OK else float(counts[5])
        self.y = self._ylast.copy()
        self.f = self._rhs(self.y)
        return True, None

    def _run(self, t_eval, Y, counts):
        return self._call(t_eval, Y, counts, self.max_steps - self.nsteps)


def kernel_args(model, params) -> tuple:
    """Return (kind, P, fastest rate) of ``model`` with ``params`` for the kernels.

    A hand-written :class:`Model` is a KIND number with :func:`kernels.pack_params`; a
    general rotor system (:class:`gyro_rotor.numerics.kernel_system.KernelSystem`) passes its
    generated right-hand side as a first-class function with its own parameter array.
    """
    if isinstance(model, Model):
        try:
            kind, P, rate = _centrifuge_args(model.name, params)
        except TypeError:       # an unhashable parameter object: computed each time
            return kernels.KIND[model.name], kernels.pack_params(params), model_rate(params)
        return kind, P.copy(), rate
    if hasattr(model, 'kernel_rhs'):
        return model.kernel_rhs, model.pack(params), model.rate(params)
    raise TypeError('model must be a gyro_rotor.core.model.Model or a general system '
                    '(gyro_rotor.numerics.kernel_system.KernelSystem)')


def model_rate(p) -> float:
    """Return the centrifuge's fastest rate [1/s], for the default steps of fixed-step methods.

    The larger of its drive damping root and its fastest oscillation
    (:func:`gyro_rotor.core.model.drive_rates`: the nutation rate C_R Omega0 / I, eq. 18, the
    drive's frequency, the tilt and twist frequencies, 1 1/s as a floor).
    """
    return max(rates_of(p))


def rates_of(p) -> tuple[float, float]:
    """Return :func:`~gyro_rotor.core.model.drive_rates` of ``p``, remembered per parameter set.

    A RotorParams is frozen and hashable: every run asks for its rates (the default step,
    auto's choice), a fixed cost of each of the benchmark's and an ensemble's runs. Other
    parameter objects (unhashable) are computed each time.
    """
    try:
        return _rates_cached(p)
    except TypeError:
        return drive_rates(p)


_rates_cached = functools.lru_cache(maxsize=256)(drive_rates)


@functools.lru_cache(maxsize=256)
def _centrifuge_args(name: str, params) -> tuple:
    """Return :func:`kernel_args` of a centrifuge model, remembered per (frozen) parameter set.

    Packing the parameters and their rates was about a third of an integrator's construction,
    a fixed cost of every run; the caller gets its own copy of P.
    """
    return kernels.KIND[name], kernels.pack_params(params), model_rate(params)
