"""Verner's pairs (vern7, vern8, vern9): coefficients, kernels, methods.

The coefficients by the order conditions, the kernels by their convergence order on a
problem with a known solution, the methods end to end.
"""

import functools
import math

from gyro_rotor.core.model import LockedHousingModel
from gyro_rotor.core.params import RotorParams
from gyro_rotor.numerics.integrators import integrate, METHODS, rk_generated, tableaux
from gyro_rotor.numerics.integrators.base import kernel_args
import numpy as np
import pytest

NAMES = tuple(tableaux.VERNER)


# -- order conditions: the rooted trees up to order 10 -----------------------------------------
@functools.lru_cache(None)
def _trees(n):
    """Rooted trees with n nodes, each a sorted tuple of its subtrees (canonical form)."""
    if n == 1:
        return ((),)
    return tuple(sorted({tuple(sorted(f)) for f in _forests(n - 1, n - 1)}))


@functools.lru_cache(None)
def _forests(n, largest):
    """Multisets of trees of total size n, no tree larger than ``largest``."""
    if n == 0:
        return ((),)
    out = []
    for k in range(min(n, largest), 0, -1):
        for t in _trees(k):
            for rest in _forests(n - k, k):
                out.append((t,) + rest)
    return tuple(out)


@functools.lru_cache(None)
def _size(t):
    return 1 + sum(_size(c) for c in t)


@functools.lru_cache(None)
def _gamma(t):
    return _size(t) * math.prod(_gamma(c) for c in t)


def test_tree_counts():
    """The enumeration gives the known numbers of rooted trees (OEIS A000081)."""
    assert [len(_trees(n)) for n in range(1, 11)] == [1, 1, 2, 4, 9, 20, 48, 115, 286, 719]


def _residuals(A, w, order, theta=1.0):
    """Largest |w . Phi(t) - theta^|t| / gamma(t)| over the trees of each order 1..order."""
    cache = {}

    def phi(t):
        if t not in cache:
            v = np.ones(A.shape[0])
            for c in t:
                v = v * (A @ phi(c))
            cache[t] = v
        return cache[t]
    m = len(w)
    return [max(abs(float(w @ phi(t)[:m]) - theta ** n / _gamma(t)) for t in _trees(n))
            for n in range(1, order + 1)]


@pytest.mark.parametrize('name', NAMES)
def test_verner_pair_orders(name):
    """B is of order p exactly, B - E of order p - 1 exactly (the next order fails by far)."""
    pair = tableaux.VERNER[name]
    p, s, A = pair.order, pair.n_stages, pair.A
    res = _residuals(A, pair.B, p + 1)
    assert max(res[:p]) < 1e-12, res
    assert res[p] > 1e-8, res            # not of order p + 1: the check can fail
    res = _residuals(A, pair.B - pair.E, p)
    assert max(res[:p - 1]) < 1e-12, res
    assert res[p - 1] > 1e-8, res
    # the consistency of the rows: c_i = sum_j a_ij, the derivative row at c = 1 is B
    c = A.sum(axis=1)
    assert np.all((c >= 0.0) & (c <= 1.0 + 1e-13))     # float sums of large a_ij
    assert np.array_equal(A[s, :s], pair.B) and not A[s, s:].any()
    assert np.allclose(pair.R.sum(axis=1)[:s], pair.B, atol=1e-11)
    assert np.allclose(pair.R.sum(axis=1)[s:], 0.0, atol=1e-11)


@pytest.mark.parametrize('name', NAMES)
@pytest.mark.parametrize('theta', [0.25, 0.6, 0.9])
def test_verner_interpolant_order(name, theta):
    """b_i(theta) satisfies the order conditions of order p at theta (scaled by theta^|t|)."""
    pair = tableaux.VERNER[name]
    p = pair.order
    w = pair.R @ theta ** np.arange(1, p + 1)
    res = _residuals(pair.A, w, p + 1, theta)
    assert max(res[:p]) < 1e-9, res      # large interpolant weights: round-off ~1e-11
    assert res[p] > 1e-8, res


# -- convergence on the pendulum of the locked housing (closed-form solution) -----------------
def _pendulum():
    """locked_housing, sine drive with one pole pair, no damping: z'' = -(K_S/C_R) sin z.

    From z(0) = z0, z'(0) = 0: z = 2 asin(k sn(K(k) - w t, k)), z' = -2 k w cn(K - w t, k),
    k = sin(z0 / 2), w^2 = K_S / C_R (Jacobi elliptic functions; scipy's m = k^2). Nonlinear
    (a linear problem satisfies more order conditions than the method's order).
    """
    from scipy.special import ellipj, ellipk
    p = RotorParams(C_R=1.0, K_S=4.0, K_D=0.0, pole_pairs=1)
    model = LockedHousingModel(p)
    w = math.sqrt(p.K_S / p.C_R)
    z0 = 2.0
    k = math.sin(z0 / 2.0)
    K = ellipk(k * k)

    def exact(t):
        sn, cn, _, _ = ellipj(K - w * t, k * k)
        return 2.0 * math.asin(k * sn), -2.0 * k * w * cn
    return model, np.array([z0, 0.0, 0.0]), exact


def _fixed_step_errors(name, h, n, theta=0.37):
    """Return the largest errors of n fixed steps h on the pendulum: (step ends, interpolant).

    The interpolant is evaluated at fraction theta of each step.
    """
    model, y0, exact = _pendulum()
    kind, P, _ = kernel_args(model, model.params)
    pair = tableaux.VERNER[name]
    step = getattr(rk_generated, f'{name}_step')
    dense = getattr(rk_generated, f'{name}_dense')
    ev = getattr(rk_generated, f'{name}_eval')
    m = model.n
    K, F = np.empty((pair.A.shape[0], m)), np.empty((pair.order, m))
    y, f = y0.copy(), model.rhs(0.0, y0)
    ytmp, ynew, fnew, out = np.empty(m), np.empty(m), np.empty(m), np.empty(m)
    e_end = e_mid = 0.0
    for i in range(n):
        step(kind, P, y, f, h, 1e-6, 1e-8, K, ytmp, ynew, fnew)
        dense(kind, P, y, h, K, ytmp, F)
        ev(kind, F, y, theta, out)
        z, zd = exact((i + theta) * h)
        e_mid = max(e_mid, abs(out[0] - z), abs(out[1] - zd))
        y, f = ynew.copy(), fnew.copy()
        z, zd = exact((i + 1) * h)
        e_end = max(e_end, abs(y[0] - z), abs(y[1] - zd))
    return e_end, e_mid


@pytest.mark.parametrize('name', NAMES)
def test_verner_convergence_order(name):
    """Fixed steps over 12 s: the error falls at least as h^p, at step ends and inside steps.

    Inside the steps: the interpolant; a wrong coefficient drops the order to 1-6.

    Measured orders (h = 0.25 to 0.125): 8.8 (vern7), 8.8 (vern8), 10.2 (vern9): the
    pendulum at 2 rad amplitude is not yet asymptotic there, finer steps reach round-off
    first with vern9.
    """
    p = tableaux.VERNER[name].order
    (e1, d1), (e2, d2) = _fixed_step_errors(name, 0.25, 48), _fixed_step_errors(name, 0.125, 96)
    for a, b in ((e1, e2), (d1, d2)):
        assert p - 0.5 < math.log2(a / b) < p + 2.5, (name, a, b)
    assert d2 < 2.0 * e2 + 1e-13      # the interpolant is as accurate as the steps


@pytest.mark.parametrize('name', NAMES)
def test_verner_run_meets_tolerance_and_matches_step_api(name):
    """The compiled run loop reaches the tolerance at 100 Hz samples; so does the step API.

    On the pendulum; step/dense_output (the stepping API) agree with the exact solution too.
    """
    model, y0, exact = _pendulum()
    te = np.linspace(0.0, 5.0, 501)
    res = integrate(model, y0, (0.0, 5.0), te, name, rtol=1e-9, atol=1e-11)
    assert res.success and res.method == name
    ref = np.array([exact(t) for t in te])
    assert np.max(np.abs(res.y[:, :2] - ref)) < 1e-8
    solver = METHODS[name](model, y0, 0.0, 5.0, rtol=1e-9, atol=1e-11)
    while solver.t < 2.0:
        solver.step()
    t_mid = 0.5 * (solver.t_old + solver.t)
    assert np.max(np.abs(solver.dense_output(t_mid)[:2] - exact(t_mid))) < 1e-8


@pytest.mark.parametrize('name', NAMES)
def test_verner_on_the_hard_scene(name):
    """On precession at rtol 1e-8: the axis agrees with dop853 at rtol 1e-12 to about 1e-7."""
    from gyro_rotor.core.scene import load_scene
    sc = load_scene('precession')
    m = sc.make_model()
    y0 = sc.initial_state(m)
    te = np.linspace(0.0, 2.0, 201)
    ref = integrate(m, y0, (0.0, 2.0), te, 'dop853', rtol=1e-12, atol=1e-14)
    res = integrate(m, y0, (0.0, 2.0), te, name, rtol=1e-8, atol=1e-10)
    assert res.success
    assert np.max(np.abs(res.y[:, :9] - ref.y[:, :9])) < 1e-6
    assert res.nfev > 0 and res.nsteps > 0
