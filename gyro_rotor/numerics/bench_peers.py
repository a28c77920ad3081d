"""Compiled peers of the benchmark: CyRK and numbalsoda on a numba right-hand side.

A speed-conscious user would not call scipy with a Python right-hand side: they would write
the equations once in numba and hand them to a compiled solver. This module is that user's
code, the benchmark's own copy of the full model (docs/model.md section 3, the equations of
:func:`gyro_rotor.core.model.full_rhs` without the dissipated-work state D, so 9 states
``q_w q_x q_y q_z W_1 W_2 W_3 z zdot``), written as the peers' documentation shows:

- **CyRK** (``nbsolve2_ivp``, C++ solvers: RK45, DOP853, Vern7, Vern8, Radau, BDF, LSODA):
  a ``numba.cfunc`` of signature ``void(double* dy, double t, double* y, double* args)``
  (``CyRK.cyjit``, whose address ``nb_diffeq_addr`` gives);
- **numbalsoda** (``lsoda``, ``dop853``: LSODA and Hairer's DOP853 in C/C++): a
  ``numba.cfunc`` of signature ``lsoda_sig = void(double t, double* u, double* du,
  double* p)``.

The scene's parameters are compile-time constants of the closure (numba folds them, and the
drive law's branch on the pole count), as such a user writes it; one compilation per
parameter set, outside the timings. :func:`peer_rhs_python` is the same function callable
from Python, for the test that compares it with the package's model at random states.

The usual user's path on a system file is slower still, and is the baseline of the generated
systems' tables: :func:`lambdified_rhs` (and its Jacobian :func:`lambdified_jac`), sympy's
``lambdify`` of the derived equations to numpy, for scipy's ``solve_ivp``.

Neither package is a requirement of gyro_rotor: they are the benchmark's extras
(``requirements-bench.txt``); :func:`available` says which are installed.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import math

import numpy as np

__all__ = ['available', 'PEER_METHODS', 'PeerRHS', 'make_peer_rhs', 'peer_run',
           'peer_rhs_python', 'missing_reason', 'make_general_peer', 'general_peer_rhs_python',
           'GENERAL_PEER_METHODS', 'lambdified_rhs', 'lambdified_jac']

#: (package, method) pairs that the benchmark runs, per package
PEER_METHODS = {
    'cyrk': ('RK45', 'DOP853', 'Vern7', 'Vern8', 'Radau', 'LSODA'),
    'numbalsoda': ('DOP853', 'LSODA'),
}
_IMPORT_NAME = {'cyrk': 'CyRK', 'numbalsoda': 'numbalsoda'}
#: CyRK's methods in the general systems' benchmark (the implicit ones are far behind there)
GENERAL_PEER_METHODS = ('RK45', 'DOP853', 'Vern7', 'Vern8', 'LSODA')


def available() -> tuple:
    """Return the peer packages that are installed ('cyrk', 'numbalsoda')."""
    return tuple(p for p, mod in _IMPORT_NAME.items() if importlib.util.find_spec(mod))


def missing_reason() -> str | None:
    """Return why a peer is missing (for skips and the table), or None if all are there."""
    miss = [p for p in _IMPORT_NAME if p not in available()]
    if not miss:
        return None
    return (f'{" and ".join(miss)} not installed (benchmark extras: pip install -r '
            'requirements-bench.txt; numbalsoda builds from source with gfortran and cmake)')


def _body_factory(params):
    """Return the njit right-hand side ``body(y, dy)`` with the parameters folded in.

    The equations of core.model.full_rhs (module doc), written out as a user would, with
    the drive law chosen at compile time.
    """
    from numba import njit
    I_ = float(params.I)
    C_R = float(params.C_R)
    C_M = float(params.C_M)
    Gs = float(params.Gs)
    c_theta = float(params.c_theta)
    c_psi = float(params.c_psi)
    K_S = float(params.K_S)
    K_D = float(params.K_D)
    Omega0 = float(params.Omega0)
    pp = int(params.pole_pairs)
    sine = pp > 0
    ppf = float(max(pp, 1))

    @njit(inline='always', error_model='numpy')
    def body(y, dy):
        qw = y[0]
        qx = y[1]
        qy = y[2]
        qz = y[3]
        W1 = y[4]
        W2 = y[5]
        W3 = y[6]
        z = y[7]
        zd = y[8]
        n = qw * qw + qx * qx + qy * qy + qz * qz
        k1 = 2.0 * (qx * qz - qw * qy) / n
        k2 = 2.0 * (qy * qz + qw * qx) / n
        k3 = (qw * qw - qx * qx - qy * qy + qz * qz) / n
        st = math.sqrt(k1 * k1 + k2 * k2)
        th = math.atan2(st, k3)
        if th < 1e-4:
            t2 = th * th
            ratio = 1.0 + t2 / 6.0 + 7.0 * t2 * t2 / 360.0
        else:
            ratio = th / st
        dV = Gs - c_theta * ratio
        tw = c_psi * 2.0 * math.atan2(qz, qw)
        tw_k = tw / (1.0 + k3)
        M1 = dV * k2 - tw_k * k1
        M2 = -dV * k1 - tw_k * k2
        M3 = -tw
        if sine:
            Q = -(K_S / ppf) * math.sin(ppf * z) - K_D * zd
        else:
            Q = -K_S * z - K_D * zd
        g = C_M * W3 + C_R * (W3 + Omega0 + zd) - I_ * W3
        dW3 = (M3 - Q) / C_M
        dy[0] = 0.5 * (-qx * W1 - qy * W2 - qz * W3)
        dy[1] = 0.5 * (qw * W1 + qy * W3 - qz * W2)
        dy[2] = 0.5 * (qw * W2 + qz * W1 - qx * W3)
        dy[3] = 0.5 * (qw * W3 + qx * W2 - qy * W1)
        dy[4] = (M1 - W2 * g) / I_
        dy[5] = (M2 + W1 * g) / I_
        dy[6] = dW3
        dy[7] = zd
        dy[8] = Q / C_R - dW3
    return body


@dataclasses.dataclass
class PeerRHS:
    """The compiled right-hand sides of one parameter set: cfunc addresses per package."""

    n: int
    cyrk_address: int | None
    lsoda_address: int | None
    keep: tuple          # the cfunc objects (their addresses live as long as they do)


def make_peer_rhs(params, packages=None) -> PeerRHS:
    """Compile the peers' right-hand sides for ``params`` (RotorParams of a full model).

    ``packages``: the peers to compile for (default: every installed one).
    """
    from numba import cfunc
    body = _body_factory(params)
    have = [p for p in available() if packages is None or p in packages]
    keep = []
    cy_addr = ls_addr = None
    if 'cyrk' in have:
        from CyRK import cyjit

        def diffeq(dy, t, y, args):
            body(y, dy)
        cf = cyjit(diffeq)
        keep.append(cf)
        cy_addr = cf.address
    if 'numbalsoda' in have:
        from numbalsoda import lsoda_sig

        @cfunc(lsoda_sig)
        def rhs(t, u, du, p):
            body(u, du)
        keep.append(rhs)
        ls_addr = rhs.address
    return PeerRHS(9, cy_addr, ls_addr, tuple(keep))


def peer_rhs_python(params):
    """Return ``f(y9) -> dy9``: the peers' right-hand side callable from Python (tests)."""
    from numba import njit
    body = _body_factory(params)

    @njit
    def f(y):
        dy = np.empty(9)
        body(y, dy)
        return dy
    return f


_CYRK_RUN = None


def _cyrk_runner():
    """Return the njit function that runs nbsolve2_ivp and copies out the samples."""
    global _CYRK_RUN
    if _CYRK_RUN is None:
        from CyRK import nbsolve2_ivp
        from numba import njit

        @njit
        def run(addr, t_end, y0, method, t_eval, rtol, atol, max_steps):
            sol = nbsolve2_ivp(addr, (0.0, t_end), y0, method=method, t_eval=t_eval,
                               rtol=rtol, atol=atol, max_num_steps=max_steps)
            ok = sol.success
            steps = sol.steps_taken
            if ok:
                Y = sol.y.T.copy()
            else:
                Y = np.empty((0, y0.shape[0]))
            sol.free()
            return ok, Y, steps
        _CYRK_RUN = run
    return _CYRK_RUN


def peer_run(peer: PeerRHS, package: str, method: str, y0, t_eval, rtol, atol,
             max_steps: int = 3_000_000):
    """Run one peer solver; return (Y (m, peer.n) or None, steps or -1).

    CyRK: ``nbsolve2_ivp`` (one call compiled by numba, the solution copied out and freed);
    numbalsoda: ``lsoda`` or ``dop853`` (``mxstep``: max_steps for dop853, whose budget is
    the whole run's; LSODA's is per output interval).
    """
    y0 = np.ascontiguousarray(y0[:peer.n], dtype=float)
    te = np.ascontiguousarray(t_eval, dtype=float)
    if package == 'cyrk':
        ok, Y, steps = _cyrk_runner()(peer.cyrk_address, float(te[-1]), y0, method, te,
                                      float(rtol), float(atol), int(max_steps))
        return (Y if ok and Y.shape[0] == te.shape[0] else None), int(steps)
    if package == 'numbalsoda':
        import numbalsoda
        if method == 'LSODA':      # its mxstep counts the steps of one output interval
            fn, mx = numbalsoda.lsoda, max(500, max_steps // te.shape[0])
        else:                      # Hairer's nmax: the steps of the whole run
            fn, mx = numbalsoda.dop853, max_steps
        Y, ok = fn(peer.lsoda_address, y0, te, rtol=float(rtol), atol=float(atol),
                   mxstep=int(mx))
        return (Y if ok else None), -1
    raise ValueError(f'unknown peer package {package!r}')


# -- general rotor systems ---------------------------------------------------------------------
def _general_body(scene):
    """Return the njit ``body(y, dy)`` of a system file's scene: numba on sympy's lambdify.

    The user's path: the mass matrix Mbar and the force vector F of the derived equations
    (:func:`gyro_rotor.core.system.equations.derive`) lambdified to numpy with common
    subexpressions (``cse=True``) and the scene's constants substituted, compiled by numba,
    the accelerations from ``np.linalg.solve(Mbar, F + drive torques)``. The state is the
    package's (q, qdot, z, zdot, D), so the runs compare sample by sample.
    """
    import sympy
    from numba import njit
    from gyro_rotor.core.system.equations import derive
    system = scene.system.reduced
    eq = derive(system, jacobians=False)
    n, m = eq.n, eq.m
    N = n + m
    z = sympy.symbols(f'z0:{m}', real=True)
    args = list(eq.q) + list(z) + list(eq.v)
    sub = dict(zip(eq.consts, [float(v) for v in system.constants.values()]))
    sub.update(zip(eq.Omega0, [float(d.Omega0) for d in system.drives]))
    f_M = njit(inline='always')(sympy.lambdify(args, eq.Mbar.xreplace(sub), 'numpy', cse=True))
    f_F = njit(inline='always')(sympy.lambdify(args, eq.F.xreplace(sub), 'numpy', cse=True))
    KS = np.array([float(d.K_S) for d in system.drives])
    KD = np.array([float(d.K_D) for d in system.drives])
    # positions of the lambdified arguments in the state (q, qdot, z, zdot, D)
    pos = (list(range(n)) + [2 * n + j for j in range(m)] + list(range(n, 2 * n))
           + [2 * n + m + j for j in range(m)])
    call = ', '.join(f'y[{i}]' for i in pos)
    src = f"""
def body(y, dy):
    Mb = np.asarray(f_M({call}), dtype=np.float64)
    Fv = np.asarray(f_F({call}), dtype=np.float64).reshape({N})
    for j in range({m}):
        Fv[{n} + j] += -KS[j] * y[{2 * n} + j] - KD[j] * y[{2 * n + m} + j]
    acc = np.linalg.solve(Mb, Fv)
    dsum = 0.0
    for i in range({n}):
        dy[i] = y[{n} + i]
        dy[{n} + i] = acc[i]
    for j in range({m}):
        zd = y[{2 * n + m} + j]
        dy[{2 * n} + j] = zd
        dy[{2 * n + m} + j] = acc[{n} + j]
        dsum += KD[j] * zd * zd
    dy[{2 * N}] = dsum
"""
    ns = {'np': np, 'f_M': f_M, 'f_F': f_F, 'KS': KS, 'KD': KD}
    exec(compile(src, f'<peer rhs of {system.name}>', 'exec'), ns)
    return njit(inline='always')(ns['body']), 2 * N + 1


def make_general_peer(scene) -> PeerRHS:
    """Compile CyRK's right-hand side of a system file's scene (numba lambdify, module doc)."""
    body, size = _general_body(scene)
    if 'cyrk' not in available():
        return PeerRHS(size, None, None, ())
    from CyRK import cyjit

    def diffeq(dy, t, y, args):
        body(y, dy)
    cf = cyjit(diffeq)
    return PeerRHS(size, cf.address, None, (cf,))


def general_peer_rhs_python(scene):
    """Return ``f(y) -> dy`` of the general peer, callable from Python (tests)."""
    from numba import njit
    body, size = _general_body(scene)

    @njit
    def f(y):
        dy = np.empty(size)
        body(y, dy)
        return dy
    return f


# -- the usual user's path: sympy lambdify to numpy, for scipy -------------------------------
def _lambdified(scene, jacobians: bool):
    """Return sympy's lambdify to numpy of the scene's equations, as the user writes it.

    (eq, lambdify of an expression in the state and constants, forces(y) -> (a, Mbar, F)
    with the drive torques in F, KS, KD).
    """
    import sympy
    from gyro_rotor.core.system.equations import derive
    eq = derive(scene.system.reduced, jacobians=jacobians)
    n, m, N = eq.n, eq.m, eq.n + eq.m
    z = sympy.symbols(f'z0:{m}', real=True)
    args = list(eq.q) + list(z) + list(eq.v) + list(eq.consts) + list(eq.Omega0)
    f_M = sympy.lambdify(args, eq.Mbar, 'numpy')
    f_F = sympy.lambdify(args, eq.F, 'numpy')
    consts = list(scene.system.constants.values())
    Om = [d.Omega0 for d in scene.system.drives]
    KS = np.array([d.K_S for d in scene.system.drives])
    KD = np.array([d.K_D for d in scene.system.drives])

    def forces(y):
        q, qd, zz, zd = y[:n], y[n:2 * n], y[2 * n:2 * n + m], y[2 * n + m:2 * N]
        a = [*q, *zz, *qd, *zd, *consts, *Om]
        F = np.asarray(f_F(*a), dtype=float).reshape(N)
        F[n:] += -KS * zz - KD * zd
        return a, np.asarray(f_M(*a), dtype=float), F
    return eq, (lambda expr: sympy.lambdify(args, expr, 'numpy')), forces, KS, KD


def lambdified_rhs(scene):
    """Build the user's path: sympy lambdify of Mbar and F to numpy, solve per call."""
    eq, _, forces, KS, KD = _lambdified(scene, jacobians=False)
    n, m, N = eq.n, eq.m, eq.n + eq.m

    def rhs(t, y):
        _, M, F = forces(y)
        acc = np.linalg.solve(M, F)
        zd = y[2 * n + m:2 * N]
        return np.concatenate([y[n:2 * n], acc[:n], zd, acc[n:], [float(KD @ (zd * zd))]])
    return rhs


def lambdified_jac(scene):
    """Return the user's Jacobian: lambdified Mbar, dMbar/dq, dF/dq, dF/dv, assembled with numpy.

    da/dx = Mbar^-1 (dF/dx + dQ/dx - (dMbar/dx) a), da/dv = Mbar^-1 (dF/dv + dQ/dv) (the
    derivatives of :mod:`~gyro_rotor.core.system.codegen`'s ``jac``, here from lambdify).
    """
    eq, lam, forces, KS, KD = _lambdified(scene, jacobians=True)
    n, m, N = eq.n, eq.m, eq.n + eq.m
    f_dM = lam([eq.Mbar.diff(qk) for qk in eq.q])
    f_Fq = lam(eq.F_q)
    f_Fv = lam(eq.F_v)
    ix = np.r_[0:n, 2 * n:2 * n + m]
    iv = np.r_[n:2 * n, 2 * n + m:2 * N]

    def jac(t, y):
        a_, M, F = forces(y)
        zd = y[2 * n + m:2 * N]
        acc = np.linalg.solve(M, F)
        Gx = np.zeros((N, N))
        if n:
            Gx[:, :n] = np.asarray(f_Fq(*a_), dtype=float).reshape(N, n)
            for k, dM in enumerate(f_dM(*a_)):
                Gx[:, k] -= np.asarray(dM, dtype=float) @ acc
        Gx[n:, n:] -= np.diag(KS)
        Gv = np.asarray(f_Fv(*a_), dtype=float).reshape(N, N).copy()
        Gv[n:, n:] -= np.diag(KD)
        J = np.zeros((2 * N + 1, 2 * N + 1))
        J[ix, iv] = 1.0
        J[np.ix_(iv, ix)] = np.linalg.solve(M, Gx)
        J[np.ix_(iv, iv)] = np.linalg.solve(M, Gv)
        J[2 * N, 2 * n + m:2 * N] = 2.0 * KD * zd
        return J
    return jac
