"""The integration methods (data + one kernel each), the registry and the driver.

==========  =====  ========  ==================================================================
name        order  kind      properties
==========  =====  ========  ==================================================================
rk4         4      explicit  classical Runge-Kutta, fixed step (the real-time node's stepper)
rk8         8      explicit  DOP853's 8th-order formula at a fixed step (no error control)
dop853      8(5,3) explicit  adaptive, embedded error estimate, 7th-order dense output
gauss6      6      implicit  3-stage Gauss-Legendre collocation, fixed step: symmetric and
                             symplectic, keeps |q| = 1 exactly (quadratic invariant); E* error
                             stays bounded over long conservative runs instead of drifting
rodas4      4(3)   implicit  Rosenbrock, L-stable and stiffly accurate, adaptive; Jacobian by
                             forward differences each step; for the stiff drive (large K_D)
radau9      9      implicit  Radau IIA collocation (5 stages), L-stable, stiffly accurate,
                             adaptive; Newton matrix = exact Jacobian of the drive damping
                             only (rank one, closed-form inverse): cost independent of K_D;
                             the default for the stiff drive
vern7       7(6)   explicit  Verner's most efficient pair, adaptive, order-7 interpolant
vern8       8(7)   explicit  Verner's most efficient pair, adaptive, order-8 interpolant
vern9       9(8)   explicit  Verner's most efficient pair, adaptive, order-9 interpolant
split8      8      explicit  splitting into exact flows (free gyrostat; torques), composed to
                             order 8, fixed step: symplectic for K_D = 0, |q| = 1 by
                             construction; E* error bounded over long conservative runs
==========  =====  ========  ==================================================================

Every method runs on the singularity-free state of :mod:`gyro_rotor.core.model`; the inner
loops are the compiled kernels of :mod:`gyro_rotor.numerics.integrators.kernels`.
On a generated rotor system (a model with ``kernel_jac``, :mod:`gyro_rotor.numerics.kernel_system`)
radau9 is :class:`~.radau_jac.Radau9Jac`: the same method with the generated exact Jacobian
(:data:`GENERATED_METHODS`).
"""

from __future__ import annotations

import bisect
import functools
import math

from gyro_rotor.core.model import Model
from gyro_rotor.errors import ParameterError
from gyro_rotor.numerics.integrators import (kernels, radau, splitting as split,
                                             tableaux as tb)
from gyro_rotor.numerics.integrators.base import (IntegrationResult, Integrator, LoopStepped,
                                                  rates_of, STATUS_MESSAGES)
from gyro_rotor.numerics.integrators.radau_jac import Radau9Jac
import numpy as np

__all__ = ['RK4', 'RK8', 'DOP853', 'Vern7', 'Vern8', 'Vern9', 'Gauss6', 'Rodas4', 'Radau9',
           'Split8', 'METHODS', 'integrate', 'choose_method', 'STIFF_RATIO',
           'CONSERVATIVE_DRIFT_LIMIT', 'DRIFT_PER_PERIOD', 'method_cost', 'cheapest_explicit',
           'COST_METHODS', 'STEPS_PER_RADIAN', 'COST_ERRORS', 'ERROR_FLOOR']

#: 'auto' takes the stiff method when the drive's damping rate exceeds the fastest
#: oscillation rate by this factor (explicit steps would be bounded by stability, not error)
STIFF_RATIO = 20.0
#: relative E* drift of dop853 per period of the fastest oscillation, per unit of rtol: a
#: non-symplectic method's E* error grows linearly, by about the same amount each period (its
#: steps per period are set by the tolerance). Measured on conservative over 100 s and 1000 s
#: (871 and 8,717 periods of 54.8 rad/s) with the PI step size control: 4.2e-5 rtol per period
#: at rtol 1e-10 and 2.9e-5 at 1e-11, over both horizons (the plain control drifted 8e-5)
DRIFT_PER_PERIOD = 3.6e-5
#: 'auto' takes the structure-preserving method for K_D = 0 runs long enough that dop853's
#: E* drift would reach this fraction of its tolerance, i.e. after
#: CONSERVATIVE_DRIFT_LIMIT / DRIFT_PER_PERIOD = 1,250 periods of the fastest oscillation
CONSERVATIVE_DRIFT_LIMIT = 0.045


class FixedStepRK(Integrator):
    """Fixed-step Runge-Kutta with a class-level tableau ``A, B, C``.

    Explicit (:func:`kernels.rk_step`), or for an ``implicit`` class the Gauss method
    (:func:`kernels.gauss_step`, at most ``max_iter`` sweeps of its fixed-point iteration;
    a step where it does not converge fails the run with status -4).
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    max_iter = 0

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        n = self.model.n
        self._K = np.empty((self.B.shape[0], n))
        self._ytmp = np.empty(n)
        self._ynew = np.empty(n)

    def _step_impl(self, t_limit):
        h = self.h
        clipped = self.t + h * (1.0 + 1e-9) >= t_limit
        if clipped:
            h = t_limit - self.t
        if self.implicit:
            ne = kernels.gauss_step(self.kind, self.P, self.y, self.f, h, self.A, self.B,
                                    self._K, self._ytmp, self._ynew, self.max_iter)
            if ne < 0:
                return False, STATUS_MESSAGES[-4]
        else:
            kernels.rk_step(self.kind, self.P, self.y, self.f, h, self.A, self.B, self._K,
                            self._ytmp, self._ynew)
            ne = self.B.shape[0] - 1
        self.nfev += ne
        y = self._ynew.copy()
        f = self._rhs(y)
        self.project(y, f)
        self.y, self.f = y, f
        self.t = t_limit if clipped else self.t + h
        return True, None

    def _run(self, t_eval, Y, counts):
        return kernels.fixed_run(self.kind, self.P, self.y, self.t, t_eval, self.h, self.A,
                                 self.B, self.implicit, self.renormalize,
                                 self.max_steps - self.nsteps, self.max_iter, Y, counts)


class RK4(FixedStepRK):
    """Classical Runge-Kutta, order 4, fixed step (default step 0.02 / model rate)."""

    name = 'rk4'
    order = 4
    step_factor = 0.02
    A, B, C = tb.RK4_A, tb.RK4_B, tb.RK4_C


class RK8(FixedStepRK):
    """DOP853's 8th-order formula (12 stages) at a fixed step (default 0.2 / model rate)."""

    name = 'rk8'
    order = 8
    step_factor = 0.2
    A = np.ascontiguousarray(tb.DOP853_A[:12, :12])
    B, C = tb.DOP853_B, tb.DOP853_C[:12]


class EmbeddedRK(Integrator):
    """An explicit pair with error control and an interpolant: the kernels of :mod:`~.rk_codegen`.

    Adaptive, error control in the RMS norm (step exponent 1/order), the derivative at the
    end of a step is the next step's first stage; a sample inside a step costs the
    interpolant's extra stages, so :meth:`run` lands steps on samples when that is cheaper.
    :meth:`sizes` gives the evaluations a step, the rows of the stages' array and the
    interpolant's coefficients.
    """

    adaptive = True
    default_rtol = 1e-10
    default_atol = 1e-12

    @classmethod
    def sizes(cls) -> tuple[int, int, int]:  # pragma: no cover
        """Return (stages a step, stages with the interpolant's, interpolant coefficients)."""
        raise NotImplementedError

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._y_old = None
        self._h_next = 0.0
        self._K = None      # the stepping API's work arrays (_buffers; run() needs none)

    def _buffers(self) -> None:
        """Allocate the work arrays of :meth:`step` and :meth:`dense_output` on first use."""
        if self._K is None:
            n = self.model.n
            self._s, rows, coefs = self.sizes()
            self._n_extra = rows - self._s - 1
            gen = kernels.rk_generated
            self._kstep = getattr(gen, f'{self.name}_step')
            self._kdense = getattr(gen, f'{self.name}_dense')
            self._keval = getattr(gen, f'{self.name}_eval')
            self._K = np.empty((rows, n))
            self._F = np.empty((coefs, n))
            self._ytmp = np.empty(n)
            self._ynew = np.empty(n)
            self._fnew = np.empty(n)

    def _step_impl(self, t_limit):
        self._buffers()
        expo = -1.0 / self.order
        if self._h_next <= 0.0:
            self._h_next = kernels.initial_step(self.kind, self.P, self.y, self.f, self.rtol,
                                                self.atol, self.order - 1, self.h_max,
                                                self._ytmp, self._fnew)
            self.nfev += 1
        h = min(self._h_next, self.h_max)
        while True:
            if not h >= 10.0 * abs(math.nextafter(self.t, math.inf) - self.t):  # or NaN
                return False, STATUS_MESSAGES[-1]
            clipped = self.t + h >= t_limit
            if clipped:
                h = t_limit - self.t
            err = self._kstep(self.kind, self.P, self.y, self.f, h, self.rtol, self.atol,
                              self._K, self._ytmp, self._ynew, self._fnew)
            self.nfev += self._s
            if math.isfinite(err) and err <= 1.0:
                break
            self.nrejected += 1
            h *= (max(kernels.MIN_FACTOR, kernels.SAFETY * err ** expo)
                  if math.isfinite(err) else kernels.MIN_FACTOR)
        y, f = self._ynew.copy(), self._fnew.copy()
        self.project(y, f)
        self._y_old, self._f_old, self._h_old, self._t_old_step = self.y, self.f, h, self.t
        self._dense_ready = False
        self.y, self.f = y, f
        self.t = t_limit if clipped else self.t + h
        fac = (kernels.MAX_FACTOR if err == 0.0
               else min(kernels.MAX_FACTOR, kernels.SAFETY * err ** expo))
        self._h_next = max(h * fac, self._h_next if clipped else 0.0)
        return True, None

    def _dense(self, h):
        """Compute the interpolant's coefficients over the last step (its extra stages)."""
        self._kdense(self.kind, self.P, self._y_old, h, self._K, self._ytmp, self._F)

    def dense_output(self, t: float) -> np.ndarray:
        """State at ``t`` inside the last step (the interpolant: its extra evaluations)."""
        if self._y_old is None:
            raise RuntimeError('Dense output is available only after a step.')
        t0, h = self._t_old_step, self._h_old
        if not (t0 <= t <= self.t):
            raise ParameterError(f't must lie in the last step [{t0}, {self.t}], got {t!r}')
        if not self._dense_ready:
            self._dense(h)
            self.nfev += self._n_extra
            self._dense_ready = True
        out = np.empty(self.model.n)
        self._keval(self.kind, self._F, self._y_old, (t - t0) / h, out)
        return out

    def _run(self, t_eval, Y, counts):
        krun = getattr(kernels.rk_generated, f'{self.name}_run')
        return krun(self.kind, self.P, self.y, self.t, t_eval, self.rtol, self.atol, self.h_max,
                    self._h_next, self.renormalize, self.max_steps - self.nsteps, Y, counts)


class DOP853(EmbeddedRK):
    """Dormand-Prince 8(5,3): adaptive, error control in the RMS norm, dense output.

    12 evaluations a step, 3 more for the 7th-order dense output. In :meth:`run`, a step
    that reaches exactly one sample time and would end within a factor 2/3 to 1.1 of it
    ends on it instead (``kernels.LAND_SHRINK``, ``LAND_STRETCH``): that sample needs no
    dense output, which costs about half a step.
    References: Hairer, Norsett, Wanner I, sec. II.10; scipy's DOP853 (same control).
    """

    name = 'dop853'
    order = 8

    @classmethod
    def sizes(cls) -> tuple[int, int, int]:
        """Return (12, 16, 7): 12 stages a step, 3 more and 7 coefficients for the dense output."""
        return 12, 16, 7

    def _dense(self, h):
        kernels.rk_generated.dop853_dense(self.kind, self.P, self._y_old, self.y, self._f_old,
                                          self.f, h, self._K, self._ytmp, self._F)


class Verner(EmbeddedRK):
    """Verner's most efficient pair p(p-1) with its order-p interpolant (tableaux.VERNER).

    Adaptive, error control in the RMS norm as dop853 (the p-1 formula's estimate, step
    exponent 1/p); steps land on samples when that is cheaper than the interpolant
    (``kernels.land_step``). Reference: Verner, Numer. Algorithms 53 (2010) 383-396.
    """

    @classmethod
    def sizes(cls) -> tuple[int, int, int]:
        """Return the pair's (stages a step, stages with the interpolant's, order)."""
        pair = tb.VERNER[cls.name]
        return pair.n_stages, pair.A.shape[0], pair.order


class Vern7(Verner):
    """Verner 7(6), 10 stages a step, order-7 interpolant (5 extra stages)."""

    name = 'vern7'
    order = 7


class Vern8(Verner):
    """Verner 8(7), 13 stages a step, order-8 interpolant (7 extra stages)."""

    name = 'vern8'
    order = 8


class Vern9(Verner):
    """Verner 9(8), 16 stages a step, order-9 interpolant (9 extra stages)."""

    name = 'vern9'
    order = 9


class Gauss6(FixedStepRK):
    """3-stage Gauss-Legendre collocation, order 6, fixed step (default 0.1 / model rate).

    Symmetric and symplectic; preserves quadratic invariants exactly, so |q| = 1 needs no
    projection. Stages by fixed-point iteration to round-off (a step too large for that
    to converge fails the run with status -4). Not for stiff scenes.
    References: Hairer, Lubich, Wanner, Geometric Numerical Integration, sec. II.1.3.
    """

    name = 'gauss6'
    order = 6
    implicit = True
    renormalize = False
    step_factor = 0.1
    max_iter = 60
    A, B, C = tb.GAUSS6_A, tb.GAUSS6_B, tb.GAUSS6_C


class Rodas4(Integrator):
    """RODAS4 (Hairer and Wanner II, sec. IV.7): Rosenbrock 4(3), L-stable, adaptive.

    Linear solves only (no Newton iteration): one LU of W = I/(h gamma) - J per step, J by
    forward differences (kernels.fd_jacobian). Cost does not grow with the stiffness K_D
    (1/C_R + 1/C_M).
    """

    name = 'rodas4'
    order = 4
    adaptive = True
    implicit = True
    default_rtol = 1e-9
    default_atol = 1e-11

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        n = self.model.n
        self._K = np.empty((6, n))
        self._J = np.empty((n, n))
        self._W = np.empty((n, n))
        self._piv = np.zeros(n, dtype=np.int64)
        self._buf = [np.empty(n) for _ in range(5)]
        self._h_next = 0.0

    def _step_impl(self, t_limit):
        ytmp, fa, fb, ynew, rb = self._buf
        if self._h_next <= 0.0:
            self._h_next = kernels.initial_step(self.kind, self.P, self.y, self.f, self.rtol,
                                                self.atol, 3, self.h_max, ytmp, fa)
            self.nfev += 1
        self.nfev += kernels.fd_jacobian(self.kind, self.P, self.y, self._J, ytmp, self.f, fb)
        self.njev += 1
        h = min(self._h_next, self.h_max)
        while True:
            if not h >= 10.0 * abs(math.nextafter(self.t, math.inf) - self.t):  # or NaN
                return False, STATUS_MESSAGES[-1]
            clipped = self.t + h >= t_limit
            h_try = t_limit - self.t if clipped else h
            err = kernels.rodas_step(self.kind, self.P, self.y, self.f, self._J, h_try,
                                     self.rtol, self.atol, tb.RODAS4_A, tb.RODAS4_C,
                                     tb.RODAS4_M, tb.RODAS4_GAMMA, self._K, ytmp, ynew,
                                     self._W, self._piv, rb)
            self.nfev += 5
            if math.isfinite(err) and err <= 1.0:
                break
            self.nrejected += 1
            h = h_try * (max(kernels.MIN_FACTOR, kernels.SAFETY * err ** -0.25)
                         if math.isfinite(err) else kernels.MIN_FACTOR)
        y = ynew.copy()
        f = self._rhs(y)
        self.project(y, f)
        self.y, self.f = y, f
        self.t = t_limit if clipped else self.t + h_try
        fac = 6.0 if err == 0.0 else min(6.0, kernels.SAFETY * err ** -0.25)
        fac = max(kernels.MIN_FACTOR, fac)
        self._h_next = max(h_try * fac, h) if clipped else h_try * fac
        return True, None

    def _run(self, t_eval, Y, counts):
        return kernels.rodas_run(self.kind, self.P, self.y, self.t, t_eval, self.rtol,
                                 self.atol, self.h_max, self._h_next, self.renormalize,
                                 self.max_steps - self.nsteps, tb.RODAS4_A, tb.RODAS4_C,
                                 tb.RODAS4_M, tb.RODAS4_GAMMA, Y, counts)


class Radau9(LoopStepped):
    """Radau IIA, 5 stages, order 9: L-stable, stiffly accurate, adaptive (:mod:`~.radau`).

    The stage equations are solved by simplified Newton iterations with the exact Jacobian
    of the stiff part only (the drive damping, rank one), so a step costs no Jacobian and
    no n x n factorization and its cost does not depend on K_D. Steps land on the sample
    times. References: Hairer and Wanner II, sec. IV.5 and IV.8.
    """

    name = 'radau9'
    order = 9
    adaptive = True
    implicit = True
    default_rtol = 1e-9
    default_atol = 1e-11
    #: the stage iteration converges to at least this relative level (radau.ITER_RTOL_MAX)
    iter_rtol_max = radau.ITER_RTOL_MAX

    def _loop(self, t_eval, Y, counts, max_steps):
        return radau.radau_run(self.kind, self.P, self.y, self.t, t_eval, self.rtol, self.atol,
                               self.h_max, self._h_next, self.renormalize, max_steps,
                               tb.RADAU5_A, tb.RADAU5_AINV, tb.RADAU5_C, tb.RADAU5_BH,
                               tb.RADAU5_GAMMA0, tb.RADAU5_LAM, tb.RADAU5_PROJ,
                               self.iter_rtol_max, Y, counts, self._ylast)


class Split8(Integrator):
    """Splitting of the free gyrostat and the torques, composed to order 8, fixed step.

    Strang's kick-drift-kick of exact sub-flows (:mod:`~.splitting`) composed by Kahan and
    Li's s17odr8a: symmetric, and for K_D = 0 a Lie-Poisson (symplectic) map, so the E*
    error stays bounded over long conservative runs, at explicit cost. The quaternion is
    moved only by unit quaternions (exactly on the unit sphere up to round-off). Full model
    only. Default step from the tolerance: ``h = 0.365 (rtol / 1e-8)^(1/8) / model_rate``
    (calibrated on the conservative scene over 100 s: at rtol 1e-10 the axis error is that
    of dop853 at the same rtol, about 1e-11; the former 0.27 gave 8.5e-13 at 2.3 times
    dop853's cost).
    """

    name = 'split8'
    order = 8
    renormalize = False
    step_from_tolerance = True
    default_rtol = 1e-10
    default_atol = 1e-12
    W = tb.KL8_W

    def __init__(self, model, *args, **kwargs):
        if getattr(model, 'name', '') != 'full':
            name = getattr(model, 'name', model)
            raise ParameterError(f"integrator split8 needs the full model, not '{name}'")
        rtol = kwargs.get('rtol')
        r = self.default_rtol if rtol is None else rtol
        if isinstance(r, (int, float)) and math.isfinite(r) and r > 0:
            self.step_factor = 0.365 * (r / 1e-8) ** 0.125
        super().__init__(model, *args, **kwargs)

    def _step_impl(self, t_limit):
        h = self.h
        clipped = self.t + h * (1.0 + 1e-9) >= t_limit
        if clipped:
            h = t_limit - self.t
        y = self.y.copy()
        split.composed_step(self.P, y, h, self.W)
        self.nfev += 2 * self.W.shape[0] + 1
        self.y = y
        self.f = self._rhs(y)
        self.t = t_limit if clipped else self.t + h
        return True, None

    def _run(self, t_eval, Y, counts):
        return split.split_run(self.P, self.y, self.t, t_eval, self.h, self.W,
                               self.max_steps - self.nsteps, Y, counts)


METHODS: dict[str, type[Integrator]] = {
    cls.name: cls for cls in (RK4, RK8, DOP853, Vern7, Vern8, Vern9, Gauss6, Rodas4, Radau9,
                              Split8)}
#: a generated rotor system (a model with ``kernel_jac``) runs these classes under the same
#: names: radau9 with its exact generated Jacobian (:mod:`~.radau_jac`)
GENERATED_METHODS: dict[str, type[Integrator]] = {Radau9Jac.name: Radau9Jac}


#: the explicit adaptive methods that 'auto' chooses among by cost (a non-stiff scene)
COST_METHODS = ('dop853', 'vern7', 'vern8', 'vern9')
#: benchmark error levels of :data:`STEPS_PER_RADIAN` (max over 100-Hz samples of the axis
#: angle and |z| error against a reference, ``gyro-rotor bench``)
COST_ERRORS = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11)
#: measured work-precision: the steps per radian of the fastest rate (``model_rate``) that
#: each method needs to reach each error of COST_ERRORS, at the cheapest tolerance of the
#: benchmark's sweep (rtol 1e-3 ... 1e-12 at 1 and 3 a decade, atol = rtol / 100), geometric
#: mean over precession, nutation, upright, fast_spin, conservative and pole_slip: what
#: ``gyro-rotor bench`` prints as "auto's cost table" (bench.steps_per_radian; from the nsteps
#: and err columns, which do not depend on the machine's load), here of the run at 326fd6a
#: (the same table and floors as at 8422299 and 312932d; the same steps as at 68b020f, 512ca0d)
#: The decade sweep before it gave a table under which auto's picks, replayed on that run's
#: rows, cost up to 1.26 times the fastest own method (pole_slip at 1e-9); this one 1.16, with
#: STEP_OVERHEAD anywhere from 2 to 6 (fitted and replayed on the same six scenes)
STEPS_PER_RADIAN = {
    'dop853': (0.461, 0.555, 0.761, 1.04, 1.39, 1.75, 2.31, 3.03, 3.98),
    'vern7': (0.637, 0.889, 1.29, 1.4, 1.96, 2.54, 3.29, 4.41, 6.07),
    'vern8': (0.453, 0.465, 0.656, 0.947, 1.29, 1.54, 2.1, 2.4, 3.24),
    'vern9': (0.536, 0.582, 0.875, 1.13, 1.36, 1.61, 1.96, 2.43, 2.84),
}
#: the smallest benchmark error each method reached in that sweep (its floor: 'auto' never
#: takes a method whose floor is above the requested tolerance; dop853 is the fallback)
ERROR_FLOOR = {'dop853': 1.2e-14, 'vern7': 7.7e-15, 'vern8': 7.0e-15, 'vern9': 4.6e-15}
#: a step's work besides its evaluations (stage sums, error norm, landing, projection,
#: copies), in evaluations. Measured without samples on precession, nutation and pole_slip
#: (a right-hand side alone 25 ns): dop853 6.1-8.2, the Verner pairs 5.3-20.5. auto's picks
#: hardly depend on it: replayed on the half-decade sweep (bench/work_precision.csv), they
#: cost at most 1.16 times the fastest own method at any value from 2 to 6; kept at 2
STEP_OVERHEAD = 2.0
#: with several steps per sample interval, steps land on the samples (kernels.land_step):
#: the interpolant is then needed for about this fraction of the samples
LANDED_DENSE = 0.25
# the tables in log-log, once (auto's choice is part of every run's fixed cost)
_LOG_ERRORS = tuple(math.log(e) for e in COST_ERRORS)
_NEG_LOG_ERRORS = tuple(-e for e in _LOG_ERRORS)
_LOG_STEPS = {m: tuple(math.log(v) for v in vals) for m, vals in STEPS_PER_RADIAN.items()}


def method_cost(name: str, rate: float, tol: float, sample_rate: float = 0.0) -> float:
    """Return the predicted evaluations per simulated second of ``name`` at error ``tol``.

    N = rate * STEPS_PER_RADIAN[name](tol) steps a second (interpolated in log-log between
    the COST_ERRORS, extrapolated by the end segments) of s evaluations plus STEP_OVERHEAD,
    and the interpolant's extra stages x for the samples inside steps: on every step when
    steps are longer than the sample spacing (N < sample_rate), else on LANDED_DENSE of the
    samples.
    """
    lev = _LOG_ERRORS
    val = _LOG_STEPS[name]
    x = math.log(tol)
    if x > lev[0]:
        i = 0
    elif x < lev[-1]:
        i = len(lev) - 2
    else:   # the segment [lev[i], lev[i + 1]] (decreasing) that holds x
        i = max(min(bisect.bisect_left(_NEG_LOG_ERRORS, -x) - 1, len(lev) - 2), 0)
    w = (x - lev[i]) / (lev[i + 1] - lev[i])
    steps = rate * math.exp(val[i] + w * (val[i + 1] - val[i]))
    s, rows, _ = METHODS[name].sizes()
    extra = rows - s - 1
    dense = steps if steps < sample_rate else LANDED_DENSE * sample_rate
    return steps * (s + STEP_OVERHEAD) + dense * extra


def cheapest_explicit(rate: float, tol: float, sample_rate: float = 0.0) -> tuple[str, dict]:
    """Return the cheapest of COST_METHODS at ``tol`` and every candidate's predicted cost."""
    floors = tuple(ERROR_FLOOR[m] for m in COST_METHODS)
    best, costs = _cheapest(float(rate), float(tol), float(sample_rate), floors,
                            STEP_OVERHEAD, LANDED_DENSE)
    return best, dict(costs)


@functools.lru_cache(maxsize=256)
def _cheapest(rate: float, tol: float, sample_rate: float, floors: tuple,
              overhead: float, landed: float) -> tuple[str, tuple]:
    """:func:`cheapest_explicit`, remembered: auto's choice is part of every run's fixed cost.

    The four cost predictions took about two thirds of auto's choice (24-27 us of a run's
    Python overhead at load 7); a sweep, an ensemble or the benchmark's repeats ask the same
    question again and again. The key holds the tables :func:`method_cost` reads at call
    time (``floors``: ERROR_FLOOR of COST_METHODS, STEP_OVERHEAD, LANDED_DENSE), so a changed
    table (a test's monkeypatch) is never answered from the cache.
    """
    costs = {m: method_cost(m, rate, tol, sample_rate)
             for m, floor in zip(COST_METHODS, floors) if floor <= tol or m == 'dop853'}
    return min(costs, key=costs.get), tuple(costs.items())


def choose_method(model, t_end: float = 0.0, rtol: float | None = None,
                  sample_rate: float = 0.0, y0=None) -> tuple[str, str]:
    """Return auto's choice for a run of ``model`` from ``y0``: ``(method name, reason)``.

    One rule for every system: ``model`` is a centrifuge model, a system file's
    (:class:`~gyro_rotor.core.system.model.GeneralModel`, linearized at ``y0``) or the
    kernels' view of one; it gives its drive damping root and fastest oscillation
    (``drive_rates``), whether it is conservative and its symplectic method.

    - radau9 when the drive's damping root (K_D (1/C_R + 1/C_M) for the centrifuge, a real
      root of the linearization, docs/model.md section 7) exceeds the fastest oscillation by
      STIFF_RATIO: an explicit method would need steps near its inverse;
    - the model's symplectic method (split8 for the full centrifuge, gauss6 otherwise) for
      conservative runs (K_D = 0) long enough that dop853's secular E* drift,
      DRIFT_PER_PERIOD rtol per period of the fastest oscillation, would reach
      CONSERVATIVE_DRIFT_LIMIT rtol (1,250 periods: 143 s on the conservative scene): the
      symplectic method keeps the E* error bounded. On shorter runs the drift stays below
      0.045 of the tolerance, and dop853 reaches a given trajectory error at about half
      split8's cost (over 100 s at one step per 10-ms sample: split8's error 3.4e-6, that
      of DOP853's formula at a fixed step 1.7e-7, and split8's step costs 1.5 times as much);
    - otherwise the cheapest of the explicit adaptive methods (dop853, vern7, vern8, vern9)
      by the measured cost model (:func:`method_cost`) at an error equal to the requested
      ``rtol`` (default: dop853's default tolerance), with the samples at ``sample_rate`` Hz
      (0: no samples inside the steps, the stepping API), at the rate max(root, oscillation).
    """
    name, reason = _choose(model, t_end, rtol, sample_rate, y0)
    return name, reason()


def _choose(model, t_end: float, rtol: float | None, sample_rate: float, y0) -> tuple:
    """Return (auto's method, a function that returns the reason): :func:`choose_method`.

    The reason's text is formatted only when asked for (:func:`make_integrator` does not: the
    choice is part of every run's fixed cost).
    """
    model = getattr(model, 'model', model)          # the kernels' view of a system file
    stiff, osc = rates_of(model.params) if isinstance(model, Model) else model.drive_rates(y0)
    if stiff > STIFF_RATIO * osc:
        return 'radau9', lambda: (
            f'stiff: the drive damping root {stiff:.3g} 1/s is {stiff / osc:.3g} times the '
            f'fastest oscillation ({osc:.3g} rad/s); an L-stable implicit method steps by '
            'accuracy')
    periods = t_end * osc / (2.0 * math.pi)
    drift = DRIFT_PER_PERIOD * periods      # dop853's E* drift over the run, in units of rtol
    conservative = model.conservative
    if conservative and drift >= CONSERVATIVE_DRIFT_LIMIT:
        sym = model.symplectic_method
        what = ('a symplectic splitting keeps the E* error bounded at explicit cost'
                if sym == 'split8' else 'a symplectic method keeps the E* error bounded')
        return sym, lambda: (
            f'conservative (K_D = 0) over {t_end:g} s = {periods:.3g} periods of the fastest '
            f'oscillation ({osc:.3g} rad/s), where dop853 would drift E* by about {drift:.2g} '
            f'rtol: {what}')
    tol = DOP853.default_rtol if rtol is None else float(rtol)
    best, costs = cheapest_explicit(max(stiff, osc), tol, sample_rate)

    def reason() -> str:
        ranked = sorted(costs.items(), key=lambda kv: kv[1])
        table = ', '.join(f'{m} {c:.3g}' for m, c in ranked)
        cost = (f'the cheapest explicit pair at error {tol:.0e} by the measured cost model '
                f'(evaluations per simulated second at {sample_rate:g}-Hz samples: {table})')
        if conservative:
            return (f'conservative (K_D = 0) but short: {periods:.3g} periods of the fastest '
                    f'oscillation ({osc:.3g} rad/s), dop853 drifts E* by about {drift:.2g} '
                    f'rtol only; {cost}')
        return (f'non-stiff (drive damping root {stiff:.3g} 1/s, fastest oscillation '
                f'{osc:.3g} rad/s): {cost}')
    return best, reason


def make_integrator(method: str, model: Model, y0, t0: float = 0.0,
                    t_bound: float = math.inf, sample_rate: float = 0.0,
                    **kwargs) -> Integrator:
    """Make an integrator from the registry by name ('auto' uses :func:`choose_method`).

    ``sample_rate`` [Hz]: the samples 'auto' plans for (:func:`integrate` passes its own).
    """
    if method == 'auto':
        method = _choose(model, t_bound - t0, kwargs.get('rtol'), sample_rate, y0)[0]
    try:
        cls = METHODS[method]
    except KeyError:
        raise ParameterError(f"unknown integrator '{method}'; valid: auto, "
                             f"{', '.join(METHODS)}") from None
    if hasattr(type(model), 'kernel_jac'):       # a generated system (not evaluated here)
        cls = GENERATED_METHODS.get(method, cls)
    return cls(model, y0, t0, t_bound, **kwargs)


def integrate(model: Model, y0, t_span, t_eval=None, method: str = 'auto', *,
              rtol: float | None = None, atol: float | None = None,
              step: float | None = None, max_steps: int = 50_000_000) -> IntegrationResult:
    """Integrate ``model`` over ``t_span`` in one compiled loop, sampled at ``t_eval``.

    ``t_eval`` defaults to the two ends. A numerical failure is reported in the result's
    ``status``/``message`` (samples up to the failure), not raised.
    """
    t0, t1 = (float(v) for v in t_span)
    if not (math.isfinite(t0) and math.isfinite(t1) and t1 > t0):
        raise ParameterError(f't_span must be two finite times with t1 > t0, got {t_span!r}')
    te = np.array([t0, t1]) if t_eval is None else np.asarray(t_eval, dtype=float)
    samples = (te.size - 1) / (t1 - t0) if te.size > 2 else 0.0
    solver = make_integrator(method, model, y0, t0, t1, samples, rtol=rtol, atol=atol,
                             step=step, max_steps=max_steps)
    return solver.run(te)
