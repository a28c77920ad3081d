"""Compiled primitives: the building blocks that every kernel of the integrators uses.

The lowest layer of :mod:`gyro_rotor.numerics.integrators`: ``njit`` (numba's, or a
stand-in that runs the same functions as plain Python), the model kinds and the
right-hand side :func:`rhs` chosen at compile time by the type of ``kind``,
:func:`state_size`, the projection hook :func:`normalize_quaternion`, the status codes
(:class:`Status` and its plain int constants OK, UNDERFLOW, ...), the step size control
constants, :func:`initial_step`, :func:`land_step`, :func:`all_finite`, the vector stage
sum :func:`lincomb` and the small LU solver. The run loops (:mod:`~.kernels`, the
generated ones of :mod:`~.rk_codegen`, :mod:`~.radau`, :mod:`~.radau_jac`,
:mod:`~.splitting`) import them from here; this module imports none of them, so the import
graph has no circle (issue 25).

Every function is compiled with numpy's error model (a division by zero gives inf or NaN,
never an exception) and cached (``cache=True``), as the kernels.
"""

from __future__ import annotations

import enum
import math

from gyro_rotor.core.model import (full_rhs, FullModel, locked_rhs, LockedHousingModel,
                                   pack_params, upright_rhs, UprightAxisModel)
import numpy as np

try:  # pragma: no cover - exercised by whichever branch the install has
    from numba import njit
    HAVE_NUMBA = True
except ImportError:  # pragma: no cover
    HAVE_NUMBA = False

    def njit(*args, **kwargs):
        """Stand-in for numba.njit: return the function unchanged."""
        if len(args) == 1 and callable(args[0]):
            return args[0]
        return lambda f: f

__all__ = ['HAVE_NUMBA', 'njit', 'KIND', 'FullKind', 'UprightKind', 'LockedKind',
           'Status', 'OK', 'UNDERFLOW', 'NONFINITE', 'BUDGET', 'NOCONV', 'SAFETY',
           'MIN_FACTOR', 'MAX_FACTOR', 'LAND_SHRINK', 'LAND_STRETCH', 'PI_BETA',
           'PI_MIN_FACTOR', 'PI_MAX_FACTOR', 'PI_ERR_FLOOR', 'pi_accept_factor',
           'pi_reject_factor', 'pack_params',
           'rhs', 'state_size', 'normalize_quaternion', 'all_finite', 'finite_increasing',
           'initial_step',
           'land_step', 'land_on_sample', 'equal_steps', 'fixed_segment', 'store_samples',
           'start_run', 'finish_run', 'too_small', 'clip_to_sample', 'lu_factor', 'lu_solve',
           'LANES', 'FAST_MATH', 'lincomb']


class FullKind(enum.IntEnum):
    """Kind of the full model (one enum class per model: numba types each class apart)."""

    FULL = 0


class UprightKind(enum.IntEnum):
    """Kind of the upright_axis model."""

    UPRIGHT_AXIS = 1


class LockedKind(enum.IntEnum):
    """Kind of the locked_housing model."""

    LOCKED_HOUSING = 2


#: the kinds of the hand-written models: each its own type in compiled code, so that a
#: kernel is compiled per model with that model's right-hand side inlined (a plain int
#: 0, 1, 2 still works, through a run-time branch that costs about 40 % of the full
#: model's evaluation)
KIND = {'full': FullKind.FULL, 'upright_axis': UprightKind.UPRIGHT_AXIS,
        'locked_housing': LockedKind.LOCKED_HOUSING}

# step size control (as scipy's rk.py and Hairer's codes)
SAFETY = 0.9
MIN_FACTOR = 0.2   # smallest decrease of the step in one go
MAX_FACTOR = 10.0  # largest increase of the step in one go
#: DOP853 lands a step exactly on the one sample time within it when that changes the step
#: by a factor between LAND_SHRINK and LAND_STRETCH: the sample then needs no dense output,
#: which costs about half a step (3 evaluations and the interpolant's coefficients). A
#: stretched step is still accepted only if its error estimate is within the tolerance.
LAND_SHRINK = 2.0 / 3.0
LAND_STRETCH = 1.1
#: the PI (Lund-stabilised) step size control of Hairer's dop853.f (Hairer, Norsett, Wanner I,
#: sec. II.4, eq. 4.13 with Gustafsson's stabilisation, IV.2): after an accepted step
#: h_new = h SAFETY err^-(1/q - PI_BETA/5) err_old^PI_BETA, between PI_MIN_FACTOR and
#: PI_MAX_FACTOR (dop853.f's fac1 = 0.333, fac2 = 6); err_old is the last accepted error, at
#: least PI_ERR_FLOOR. The memory of err_old damps the grow-reject cycles of the plain control
PI_BETA = 0.04
PI_MIN_FACTOR = 0.333
PI_MAX_FACTOR = 6.0
PI_ERR_FLOOR = 1e-4


class Status(enum.IntEnum):
    """Status codes of the run loops and steppers (read by numba as integer constants)."""

    FINISHED = 0
    STEP_UNDERFLOW = -1
    NON_FINITE = -2
    BUDGET = -3
    NO_CONVERGENCE = -4


# numba reads module-level ints as compile-time constants (IntEnum members it does not)
OK = int(Status.FINISHED)
UNDERFLOW = int(Status.STEP_UNDERFLOW)
NONFINITE = int(Status.NON_FINITE)
BUDGET = int(Status.BUDGET)
NOCONV = int(Status.NO_CONVERGENCE)


def rhs(kind, y, P, out):
    """Write dy/dt at state ``y`` into ``out``.

    ``kind`` is a model number (KIND: the hand-written models, :func:`_model_rhs`) or a
    compiled right-hand side ``f(y, P, out)`` passed as a numba first-class function (a
    general rotor system, :mod:`gyro_rotor.core.system.codegen`). In compiled code the
    choice is made at compile time by the type of ``kind`` (the overload below), so the
    hand-written models run exactly their own code.
    """
    if callable(kind):
        kind(y, P, out)
    else:
        _model_rhs(kind, y, P, out)


def state_size(kind, y):
    """Return the size of the state: a compile-time constant for the hand-written models.

    In compiled code the models' sizes (10, 5, 3) are constants of the kernel compiled for
    each model, so that LLVM unrolls the loops over the components; for a general system
    (a first-class function) it is ``y.shape[0]``.
    """
    return y.shape[0]


def _is_full(kind):
    """Return True for the full (quaternion) model, False for others and for functions."""
    return not callable(kind) and kind == 0


if HAVE_NUMBA:  # pragma: no branch - compile-time choice on the type of kind
    from numba import types
    from numba.extending import overload

    from numba.extending import typeof_impl

    _KIND_RHS = {FullKind: full_rhs, UprightKind: upright_rhs, LockedKind: locked_rhs}

    def _register_kind_type(cls):
        # numba's generic typeof of an IntEnum member builds and interns its type on every
        # call (about 10 us a kernel call from Python); these are fixed
        ty = types.IntEnumMember(cls, types.int64)
        typeof_impl.register(cls)(lambda val, c: ty)

    for _cls in _KIND_RHS:
        _register_kind_type(_cls)

    @overload(rhs, jit_options={'error_model': 'numpy'}, inline='always')
    def _rhs_typed(kind, y, P, out):
        if isinstance(kind, types.IntEnumMember) and kind.instance_class in _KIND_RHS:
            fn = _KIND_RHS[kind.instance_class]
            return lambda kind, y, P, out: fn(y, P, out)
        if isinstance(kind, types.Integer):
            return _model_rhs.py_func
        return lambda kind, y, P, out: kind(y, P, out)

    _KIND_SIZE = {FullKind: len(FullModel.state_names),        # 10, 5, 3
                  UprightKind: len(UprightAxisModel.state_names),
                  LockedKind: len(LockedHousingModel.state_names)}

    @overload(state_size, inline='always')
    def _state_size_typed(kind, y):
        if isinstance(kind, types.IntEnumMember) and kind.instance_class in _KIND_SIZE:
            size = _KIND_SIZE[kind.instance_class]
            return lambda kind, y: size
        return lambda kind, y: y.shape[0]

    @overload(_is_full)
    def _is_full_typed(kind):
        if isinstance(kind, types.IntEnumMember):
            full = kind.instance_class is FullKind
            return lambda kind: full
        if isinstance(kind, types.Integer):
            return lambda kind: kind == 0
        return lambda kind: False


@njit(cache=True, error_model='numpy')
def _model_rhs(kind, y, P, out):
    """dy/dt of model ``kind`` at state ``y`` into ``out`` (the functions of core.model).

    Compiled with numpy's error model: a division by zero (a state with q = 0, or the axis
    exactly at theta = pi) gives inf or nan, which the loops report as a non-finite state
    (status -2) or a rejected step, never as an exception out of a run.
    """
    if kind == 0:
        full_rhs(y, P, out)
    elif kind == 1:
        upright_rhs(y, P, out)
    else:
        locked_rhs(y, P, out)


@njit(cache=True, error_model='numpy')
def normalize_quaternion(kind, y, f):
    """Apply the projection hook: scale q (and dq/dt, linear in q) of the full model to |q| = 1.

    The other equations depend on q only through its direction, so ``f`` stays the exact
    right-hand side at the projected state. A norm that overflowed (a diverging step) makes
    q NaN, so that the run stops as non-finite; scaling by 1 / inf would give q = 0 exactly,
    a finite state on which the next right-hand side divides by |q|^2 = 0.
    """
    if not _is_full(kind):
        return
    n = math.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2] + y[3] * y[3])
    s = 1.0 / n if 0.0 < n < math.inf else math.nan
    for i in range(4):
        y[i] *= s
        f[i] *= s


@njit(cache=True, error_model='numpy')
def all_finite(y):
    """Return True if every component of ``y`` is finite."""
    for i in range(y.shape[0]):
        if not math.isfinite(y[i]):
            return False
    return True


@njit(cache=True, error_model='numpy')
def finite_increasing(t):
    """Return True if ``t`` is non-empty, finite and strictly increasing (a run's samples)."""
    if t.shape[0] == 0:
        return False
    for i in range(t.shape[0]):
        if not math.isfinite(t[i]) or (i > 0 and not t[i] > t[i - 1]):
            return False
    return True


@njit(cache=True, error_model='numpy')
def initial_step(kind, P, y, f, rtol, atol, order, h_max, ytmp, ftmp):
    """Return the starting step size.

    Hairer, Norsett, Wanner I, sec. II.4; scipy's select_initial_step.
    """
    n = y.shape[0]
    d0 = 0.0
    d1 = 0.0
    for m in range(n):
        sc = atol + abs(y[m]) * rtol
        d0 += (y[m] / sc) ** 2
        d1 += (f[m] / sc) ** 2
    d0 = math.sqrt(d0 / n)
    d1 = math.sqrt(d1 / n)
    if d0 < 1e-5 or d1 < 1e-5:
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    h0 = min(h0, h_max)
    for m in range(n):
        ytmp[m] = y[m] + h0 * f[m]
    rhs(kind, ytmp, P, ftmp)
    d2 = 0.0
    for m in range(n):
        sc = atol + abs(y[m]) * rtol
        d2 += ((ftmp[m] - f[m]) / sc) ** 2
    d2 = math.sqrt(d2 / n) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / (order + 1))
    return min(100.0 * h0, h1, h_max)


@njit(cache=True, error_model='numpy')
def pi_accept_factor(err, err_old, q):
    """Return h_new / h after a step accepted with error norm ``err`` (PI control, above).

    ``err_old`` is the error of the previous accepted step (PI_ERR_FLOOR at the start),
    ``q`` the order of the error estimate (err ~ h^q).
    """
    if err == 0.0:
        return PI_MAX_FACTOR
    fac = SAFETY * err ** (0.2 * PI_BETA - 1.0 / q) * err_old ** PI_BETA
    return min(PI_MAX_FACTOR, max(PI_MIN_FACTOR, fac))


@njit(cache=True, error_model='numpy')
def pi_reject_factor(err, q):
    """Return h_new / h after a step rejected with error norm ``err`` > 1 (dop853.f).

    A non-finite error (a diverging trial step) shrinks the step by MIN_FACTOR.
    """
    if not math.isfinite(err):
        return MIN_FACTOR
    return max(PI_MIN_FACTOR, SAFETY * err ** (0.2 * PI_BETA - 1.0 / q))


@njit(cache=True, error_model='numpy')
def land_step(t_eval, k, t, h, h_max, dense_cost):
    """Return the step that lands on the sample t_eval[k] in m equal steps, or 0.0 (no landing).

    A sample inside a step costs the interpolant, ``dense_cost`` steps' worth of evaluations.
    Reaching the next sample from t in m = ceil(d / (LAND_STRETCH h)) equal steps of d / m
    instead of steps h costs m - d / h more steps; landing is chosen when that is at most
    ``dense_cost``, only when the step h would reach no sample beyond this one (that would need
    the interpolant anyway), and never beyond h_max. Decided again at every step.
    """
    nt = t_eval.shape[0]
    if k >= nt:
        return 0.0
    d = t_eval[k] - t
    if not (d > 0.0 and h > 0.0):
        return 0.0
    if k + 1 < nt and t_eval[k + 1] <= t + h:
        return 0.0
    r = d / h
    m = math.ceil(r / LAND_STRETCH)
    if m < 1:
        m = 1
    if m - r > dense_cost:
        return 0.0
    h_land = d / m
    if h_land > h_max:
        return 0.0
    return h_land


@njit(cache=True, error_model='numpy')
def land_on_sample(t_eval, k, t, h, h_max):
    """Return the step from t that ends exactly on the sample t_eval[k], or 0.0 (DOP853's rule).

    The step lands when the sample is the only one the step h reaches and the step that
    lands on it is between LAND_SHRINK and LAND_STRETCH times h (and not longer than h_max).
    """
    nt = t_eval.shape[0]
    if k >= nt:
        return 0.0
    d = t_eval[k] - t
    if not (LAND_SHRINK * h <= d <= LAND_STRETCH * h and d <= h_max and d > 0.0):
        return 0.0
    return d if k + 1 >= nt or t_eval[k + 1] > t + h else 0.0


@njit(cache=True, error_model='numpy')
def equal_steps(span, h_max):
    """Return the fewest equal steps no longer than ``h_max`` that cover ``span`` (at least 1).

    The fixed-step runs cut the interval between consecutive samples into these, so every
    sample is hit exactly; a span a hair (relative 1e-12) over a multiple of h_max does not
    cost one more step.
    """
    m = int(math.ceil(span / h_max * (1.0 - 1e-12)))
    if m < 1:
        m = 1
    return m


@njit(cache=True, error_model='numpy')
def fixed_segment(t_eval, k, t, h_max, y, Y_out):
    """Store ``y`` for the samples t_eval[k], ... not after ``t``; return the next segment.

    The fixed-step runs go from sample to sample (increasing) in :func:`equal_steps`.
    Returns (k, m, h): the first sample after ``t`` and the ``m`` equal steps ``h`` from t
    to it; m = 0 when no sample is left.
    """
    nt = t_eval.shape[0]
    while k < nt and not t_eval[k] - t > 0.0:
        for j in range(y.shape[0]):
            Y_out[k, j] = y[j]
        k += 1
    if k == nt:
        return k, 0, 0.0
    span = t_eval[k] - t
    m = equal_steps(span, h_max)
    return k, m, span / m


@njit(cache=True, error_model='numpy')
def store_samples(t_eval, k, t, y, Y_out):
    """Copy ``y`` into the rows of ``Y_out`` of the samples t_eval[k], ... up to ``t``.

    Returns the index of the first sample after ``t``.
    """
    while k < t_eval.shape[0] and t_eval[k] <= t:
        for j in range(y.shape[0]):
            Y_out[k, j] = y[j]
        k += 1
    return k


@njit(cache=True, error_model='numpy', inline='always')
def start_run(kind, P, y0, t0, t_eval, rtol, atol, order, h_max, h_init, Y_out):
    """Begin an adaptive run of ``order`` from (t0, y0): its state, f(y) and first step.

    Returns (y, f, ytmp, ftmp, k, h, nfev, status): ``y`` a copy of y0 (the run's state),
    ``f`` = f(y), two work vectors; ``k`` the first sample after t0 (those at t0 stored in
    ``Y_out``); ``h`` = ``h_init`` if positive, else :func:`initial_step`; status NONFINITE
    for a non-finite derivative (a singular state ends the run at once), else OK.
    """
    n = state_size(kind, y0)
    y = y0.copy()
    f = np.empty(n)
    ytmp = np.empty(n)
    ftmp = np.empty(n)
    k = store_samples(t_eval, 0, t0, y, Y_out)
    rhs(kind, y, P, f)
    status = OK if all_finite(f) else NONFINITE
    if h_init > 0.0:
        return y, f, ytmp, ftmp, k, h_init, 1, status
    h = initial_step(kind, P, y, f, rtol, atol, order, h_max, ytmp, ftmp)
    return y, f, ytmp, ftmp, k, h, 2, status


@njit(cache=True, error_model='numpy')
def finish_run(counts, status, nfev, nsteps, nrej, h):
    """Write (nfev, nsteps, rejected, step size) into ``counts`` and return ``status``."""
    counts[0] = nfev
    counts[1] = nsteps
    counts[2] = nrej
    counts[3] = h
    return status


@njit(cache=True, error_model='numpy')
def too_small(t, h):
    """Return True if the step h from t is below 10 spacings of the numbers at t (or NaN)."""
    return not h >= 10.0 * abs(math.nextafter(t, math.inf) - t)


@njit(cache=True, error_model='numpy')
def clip_to_sample(t_eval, k, t, h, h_max, t_end):
    """Return (h, h_free, clipped, t_next): the step at most h_max, clipped to the next sample.

    ``h_free`` is the step before clipping, ``t_next`` the sample t_eval[k] (or ``t_end``);
    a clipped step ends exactly on it.
    """
    if h > h_max:
        h = h_max
    h_free = h
    t_next = t_eval[k] if k < t_eval.shape[0] else t_end
    if t + h >= t_next:
        return t_next - t, h_free, True, t_next
    return h, h_free, False, t_next


@njit(cache=True, error_model='numpy')
def lu_factor(M, piv):
    """In-place LU factorization with partial pivoting; False if singular."""
    n = M.shape[0]
    for k in range(n):
        p = k
        big = abs(M[k, k])
        for i in range(k + 1, n):
            if abs(M[i, k]) > big:
                big = abs(M[i, k])
                p = i
        if big == 0.0:
            return False
        piv[k] = p
        if p != k:
            for j in range(n):
                tmp = M[k, j]
                M[k, j] = M[p, j]
                M[p, j] = tmp
        inv = 1.0 / M[k, k]
        for i in range(k + 1, n):
            M[i, k] *= inv
            lik = M[i, k]
            if lik != 0.0:
                for j in range(k + 1, n):
                    M[i, j] -= lik * M[k, j]
    return True


@njit(cache=True, error_model='numpy')
def lu_solve(M, piv, b):
    """Solve with the factors of :func:`lu_factor`, in place on ``b``."""
    n = M.shape[0]
    for k in range(n):
        p = piv[k]
        if p != k:
            tmp = b[k]
            b[k] = b[p]
            b[p] = tmp
    for i in range(n):
        acc = b[i]
        for j in range(i):
            acc -= M[i, j] * b[j]
        b[i] = acc
    for i in range(n - 1, -1, -1):
        acc = b[i]
        for j in range(i + 1, n):
            acc -= M[i, j] * b[j]
        b[i] = acc / M[i, i]


#: the components :func:`lincomb` computes in one call: one vector of four doubles (AVX)
LANES = 4
#: the fast-math flags of the kernels that allow them (the generated Runge-Kutta kernels,
#: radau's, :func:`lincomb`): LLVM may fuse multiply-adds, reassociate sums and multiply by
#: reciprocals; not 'nnan'/'ninf', so NaN and inf still propagate and the run loops still
#: stop on a non-finite state. A tuple: its order is part of the generated kernels' text
FAST_MATH = ('contract', 'reassoc', 'arcp', 'nsz')


def lincomb(out, base, h, coeffs, arrays, m):
    """Write ``base + h sum_j coeffs[j] arrays[j]`` into ``out`` at components m ... m + 3.

    A Runge-Kutta stage sum (``base`` None: ``h sum_j coeffs[j] arrays[j]``, an error sum or
    an interpolant's coefficient), LANES components at once; ``coeffs`` and ``arrays`` are
    tuples of equal length, and the caller keeps m + LANES <= n.

    Compiled, it is vector code (:func:`_lincomb_vec`): numba leaves LLVM's SLP vectorizer
    off (numba PR 8852), and the loop vectorizer never sees the models' loops over 10
    components, which are unrolled first, so the generated kernels' sums were scalar code.
    """
    for r in range(m, m + LANES):
        acc = 0.0
        for c, a in zip(coeffs, arrays):
            acc += c * a[r]
        out[r] = h * acc if base is None else base[r] + h * acc


if HAVE_NUMBA:  # pragma: no branch
    from llvmlite import ir
    from numba.extending import intrinsic

    @intrinsic
    def _lincomb_vec(typingctx, out, base, h, coeffs, arrays, m):
        """LLVM IR of :func:`lincomb`: <4 x double> loads, multiply-adds and one store.

        The last of ``arrays`` is read as four scalar loads: in the kernels it is the stage
        the right-hand side has just written, component by component, and a vector load
        of four recent scalar stores waits for them to reach the cache (no store
        forwarding): as one vector load it made a DOP853 step 12 % slower than the scalar
        sums, read this way 5 % faster.
        """
        vec = ir.VectorType(ir.DoubleType(), LANES)
        zeros = ir.Constant(ir.VectorType(ir.IntType(32), LANES), [0] * LANES)

        def codegen(context, builder, sig, args):
            out_v, base_v, h_v, c_v, a_v, m_v = args

            def at(aryty, val):
                data = context.make_array(aryty)(context, builder, val).data
                return builder.bitcast(builder.gep(data, [m_v]), vec.as_pointer())

            def splat(x):
                one = builder.insert_element(ir.Constant(vec, ir.Undefined), x,
                                             ir.Constant(ir.IntType(32), 0))
                return builder.shuffle_vector(one, ir.Constant(vec, ir.Undefined), zeros)

            def lanes(aryty, val):
                data = context.make_array(aryty)(context, builder, val).data
                v = ir.Constant(vec, ir.Undefined)
                for r in range(LANES):
                    idx = builder.add(m_v, ir.Constant(m_v.type, r))
                    v = builder.insert_element(v, builder.load(builder.gep(data, [idx])),
                                               ir.Constant(ir.IntType(32), r))
                return v

            acc = None
            last = len(coeffs) - 1
            for j in range(len(coeffs)):
                if j == last:
                    x = lanes(arrays[j], builder.extract_value(a_v, j))
                else:
                    x = builder.load(at(arrays[j], builder.extract_value(a_v, j)), align=8)
                term = builder.fmul(splat(builder.extract_value(c_v, j)), x, flags=FAST_MATH)
                acc = term if acc is None else builder.fadd(acc, term, flags=FAST_MATH)
            b = builder.fmul(splat(h_v), acc, flags=FAST_MATH)
            if base is not types.none:
                b = builder.fadd(builder.load(at(base, base_v), align=8), b, flags=FAST_MATH)
            builder.store(b, at(out, out_v), align=8)
            return context.get_dummy_value()

        vectors = (out,) + tuple(arrays) + (() if base is types.none else (base,))
        ok = (all(isinstance(a, types.Array) and a.dtype == types.float64 and a.layout == 'C'
                  and a.ndim == 1 for a in vectors)
              and 0 < len(coeffs) == len(arrays) and isinstance(m, types.Integer))
        return (types.none(out, base, h, coeffs, arrays, m), codegen) if ok else None

    @overload(lincomb, inline='always')
    def _lincomb_typed(out, base, h, coeffs, arrays, m):
        def impl(out, base, h, coeffs, arrays, m):
            _lincomb_vec(out, base, h, coeffs, arrays, m)
        return impl
