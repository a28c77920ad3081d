"""Equations of motion of the gyrostat on a synchronous drive, singularity-free.

Three models, each a class with the same interface, so that a scene models only what it
needs (docs/model.md sections 2 to 4; Magnus 1980, eqs. 18, 19, 23):

``full``            :class:`FullModel`, 4 DOF: stator orientation as a quaternion q (body to
                    space), stator body rates W, rotor angle z relative to the field, and
                    its rate. State (10): ``q_w q_x q_y q_z W_1 W_2 W_3 z zdot D``.
``upright_axis``    :class:`UprightAxisModel`, 2 DOF: the axis locked vertical (theta = 0);
                    housing twist chi and rotor. State (5): ``chi chidot z zdot D``.
``locked_housing``  :class:`LockedHousingModel`, 1 DOF: the paper's "arretiertes System",
                    rotor on its drive only. State (3): ``z zdot D``.

In every model ``z = phi - Omega0 t`` (eq. 7), the rotor angle relative to the rotating
field, so the equations are autonomous, and the last state ``D`` is the work dissipated by
the drive damping, ``dD/dt = K_D zdot^2``. Then (docs/model.md section 4)

    r(t) = E*(t) - E*(0) + D(t)

is zero along exact solutions (eq. 17 with the exact nonlinear law) and measures the
integration error live.

Full model (docs/model.md section 3). With k the vertical in body axes (cos theta = k_3),
H = (I W_1, I W_2, C_M W_3 + C_R (W_3 + Omega0 + zdot)):

    I dW_1/dt = M_1 - W_2 (H_3 - I W_3),    I dW_2/dt = M_2 + W_1 (H_3 - I W_3),
    C_M dW_3/dt = M_3 - Q,                  C_R (dW_3/dt + d^2z/dt^2) = Q,
    M = -(dV/dcos theta) (e_3 x k) - c_psi chi w,   w = (k_1/(1+k_3), k_2/(1+k_3), 1),
    dV/dcos theta = G s - c_theta theta/sin theta,  chi = 2 atan2(q_z, q_w),
    dq/dt = q * (0, W) / 2.

The restraint torque uses chi from the quaternion, which is exact for |chi| < 2 pi (a
housing wound more than a full turn against its restraint is outside every scene). The
form is regular everywhere except theta = pi (the axis pointing straight down), where the
twist direction w of the restraint has no limit: a run that gets there stops with an
:class:`~gyro_rotor.errors.IntegrationError`.
"""

from __future__ import annotations

import math
from typing import Callable, Mapping

from gyro_rotor.core.params import RotorParams
from gyro_rotor.core.rotations import (axis_from_quaternion, body_rates_from_euler,
                                       euler_from_quaternion, euler_rates_from_body,
                                       quaternion_from_euler, tilt, twist, wrap_angles)
from gyro_rotor.errors import did_you_mean, SceneError
import numpy as np

__all__ = ['Model', 'FullModel', 'UprightAxisModel', 'LockedHousingModel', 'MODELS',
           'make_model', 'drive_torque', 'drive_potential', 'drive_law',
           'pack_params', 'tilt_twist_torque', 'drive_rates', 'full_rhs', 'upright_rhs',
           'locked_rhs', 'axial_momentum', 'numba_able', 'tilt_ratio', 'twist_angle', 'atan_ratio',
           'perturb_state',
           'PERTURBATION_KEYS', 'AXIS_DOWN']

#: why a run of the centrifuge can fail at a finite state: its one singular orientation
AXIS_DOWN = 'the axis reached theta = pi (pointing straight down), where the model is singular'

try:  # pragma: no cover - exercised by whichever branch the install has
    from numba import types as _nb_types
    from numba.extending import overload as _overload, register_jitable

    def numba_able(f):
        """Numba's register_jitable, inlined into the caller (the kernels call it per stage)."""
        return register_jitable(inline='always')(f)

    def _all_scalars(*args):
        """Return True if every numba type in ``args`` is a float or an integer."""
        return all(isinstance(a, (_nb_types.Float, _nb_types.Integer)) for a in args)

    _HAVE_NUMBA = True
except ImportError:  # pragma: no cover
    def numba_able(f):
        """Stand-in for numba's register_jitable: the function as it is."""
        return f

    _HAVE_NUMBA = False

#: the kick of a centrifuge scene (``perturbation.KEY``, :func:`perturb_state`)
PERTURBATION_KEYS = ('dtheta', 'dthetadot', 'dpsidot', 'dchi', 'dz', 'dzdot')

#: layout of the packed parameter array P (:func:`pack_params`)
P_I, P_C_R, P_C_M, P_GS, P_C_THETA, P_C_PSI, P_K_S, P_K_D, P_OMEGA0, P_PP = range(10)


def pack_params(p: RotorParams) -> np.ndarray:
    """Pack RotorParams into the float array P read by the right-hand sides below.

    The order is (I, C_R, C_M, G s, c_theta, c_psi, K_S, K_D, Omega0, p).
    """
    return np.array([p.I, p.C_R, p.C_M, p.Gs, p.c_theta, p.c_psi, p.K_S, p.K_D, p.Omega0,
                     float(p.pole_pairs)])


# -- the equations, written once ---------------------------------------------------------------
# Each function below is plain arithmetic that runs unchanged on floats (Python lists, the
# plain-float right-hand side for scipy), on numpy arrays of trajectories (the ensemble's numpy
# backend: y of shape (n, N)) and compiled by numba inside the integrators' kernels
# (``numba_able`` = numba's register_jitable). Branches on values are written as 0/1 blends
# so that they hold elementwise on arrays; for floats they give the same bits as an if.
def _drive_law_scalar(z, zdot, K_S, K_D, pp):
    """Return :func:`drive_law` for floats, with an ``if`` instead of its blends."""
    if pp == 0:
        return -K_S * z - K_D * zdot
    return -(K_S / pp) * math.sin(pp * z) - K_D * zdot


# theta/sin theta and chi without atan2 (two thirds of an evaluation of the full model when
# they were atan2 calls on the critical path). With a = q_x^2 + q_y^2 = |q|^2 sin^2(theta/2) and
# b = q_w^2 + q_z^2 = |q|^2 cos^2(theta/2), t = tan(theta/2) = sqrt(a/b), and
#     theta/sin theta = (1 + t^2) atan(t)/t,    sin theta = 2 sqrt(a b)/(a + b),
# atan(t)/t an even function of t: a function of w = a/b, no square root. Where t <= 0.66
# (theta <= 67 degrees) it is Cephes' rational 1 + w P(w)/Q(w) (S. L. Moshier, atan.c); beyond,
# the angle by atan2. The twist chi = 2 atan2(q_z, q_w) takes the same rational of
# v = q_z/q_w where |v| < 0.66 and q_w > 0.
_ATAN_REACH = 0.66
_ATAN_P = (-8.750608600031904122785e-1, -1.615753718733365076637e1, -7.500855792314704667340e1,
           -1.228866684490136173410e2, -6.485021904942025371773e1)
_ATAN_Q = (2.485846490142306297962e1, 1.650270098316988542046e2, 4.328810604912902668951e2,
           4.853903996359136964868e2, 1.945506571482613964425e2)


@numba_able
def atan_ratio(w):
    """Return atan(t)/t for w = t^2 in [0, 0.66^2] (Cephes' rational, within 2 eps)."""
    p0, p1, p2, p3, p4 = _ATAN_P
    q0, q1, q2, q3, q4 = _ATAN_Q
    num = (((p0 * w + p1) * w + p2) * w + p3) * w + p4
    den = ((((w + q0) * w + q1) * w + q2) * w + q3) * w + q4
    return 1.0 + w * num / den


def _ratio_scalar(a, b):
    """Return :func:`tilt_ratio` for floats, with an ``if`` instead of its blend."""
    if a <= _ATAN_REACH * _ATAN_REACH * b:
        w = a / b
        return (1.0 + w) * atan_ratio(w)
    return math.atan2(math.sqrt(a), math.sqrt(b)) * (a + b) / math.sqrt(a * b)


def _twist_scalar(qz, qw):
    """Return :func:`twist_angle` for floats, with an ``if`` instead of its blend."""
    if abs(qz) < _ATAN_REACH * qw:
        v = qz / qw
        return 2.0 * v * atan_ratio(v * v)
    return 2.0 * math.atan2(qz, qw)


def drive_law(z, zdot, K_S, K_D, pp):
    """Drive torque Q on the rotor (eq. 23, or its sine law with pp = pole_pairs > 0).

    Q = -K_S z - K_D zdot  (linear, pp = 0),   Q = -(K_S/pp) sin(pp z) - K_D zdot  (sine).
    """
    lin = 1.0 * (pp == 0)
    ppn = pp + lin
    # the sine's argument is 0 for the linear law: sin(0) is its fast path (the blend still
    # takes the sine's value only where pp > 0, elementwise on arrays)
    sine = 1.0 - lin
    return lin * (-K_S * z) + sine * (-(K_S / ppn) * np.sin(ppn * z * sine)) - K_D * zdot


def tilt_ratio(a, b):
    """Return theta/sin theta from a = |q|^2 sin^2(theta/2), b = |q|^2 cos^2(theta/2) (above)."""
    near = 1.0 * (a <= _ATAN_REACH * _ATAN_REACH * b)
    w = near * a / (b + (1.0 - near))
    half = np.arctan2(np.sqrt(a), np.sqrt(b))   # theta/2
    return (near * ((1.0 + w) * atan_ratio(w))
            + (1.0 - near) * (half * (a + b) / (np.sqrt(a * b) + near)))


def twist_angle(qz, qw):
    """Return the housing's twist chi = 2 atan2(q_z, q_w) (exact for |chi| < 2 pi; above)."""
    near = 1.0 * (np.abs(qz) < _ATAN_REACH * qw)
    v = near * qz / (near * qw + (1.0 - near))
    return near * (2.0 * v * atan_ratio(v * v)) + (1.0 - near) * (2.0 * np.arctan2(qz, qw))


@numba_able
def tilt_twist_torque(qw, qx, qy, qz, Gs, c_theta, c_psi):
    """Restoring torques of eq. (19) in body axes from the stator quaternion (module doc).

    Returns (M_1, M_2, M_3): tilt M = -(dV/dcos theta) (e_3 x k) with dV/dcos theta =
    G s - c_theta theta/sin theta, plus twist -c_psi chi w, chi = 2 atan2(q_z, q_w). Written
    with a, b of :func:`tilt_ratio`: k_1,2 = 2 e_1,2/(a + b) and w_1,2 = k_1,2/(1 + k_3) =
    e_1,2/b, e_1 = q_x q_z - q_w q_y, e_2 = q_y q_z + q_w q_x.
    """
    a = qx * qx + qy * qy
    b = qw * qw + qz * qz
    e1 = qx * qz - qw * qy
    e2 = qy * qz + qw * qx
    dV2 = 2.0 * (Gs - c_theta * tilt_ratio(a, b)) / (a + b)   # dV/dcos theta * 2/|q|^2
    tw = c_psi * twist_angle(qz, qw)
    tw_b = tw / b
    return dV2 * e2 - tw_b * e1, -dV2 * e1 - tw_b * e2, -tw


if _HAVE_NUMBA:  # pragma: no branch
    # the kernels compile drive_law, tilt_ratio and twist_angle on floats as their scalar forms
    # above (an ``if`` where the blends compute both sides: a sine of 0, atan2, divisions; the
    # same numbers for floats, test_model checks it); on arrays as themselves
    @_overload(drive_law, inline='always')
    def _drive_law_typed(z, zdot, K_S, K_D, pp):
        return _drive_law_scalar if _all_scalars(z, zdot, K_S, K_D, pp) else drive_law

    @_overload(tilt_ratio, inline='always')
    def _tilt_ratio_typed(a, b):
        return _ratio_scalar if _all_scalars(a, b) else tilt_ratio

    @_overload(twist_angle, inline='always')
    def _twist_angle_typed(qz, qw):
        return _twist_scalar if _all_scalars(qz, qw) else twist_angle


@numba_able
def axial_momentum(y, P):
    """Return H_3 = C_M W_3 + C_R (W_3 + Omega0 + zdot) at state y of the full model."""
    W3 = y[6]
    return P[2] * W3 + P[1] * (W3 + P[8] + y[8])


@numba_able
def full_rhs(y, P, out):
    """dy/dt of the full model (module doc) at y into out; P from :func:`pack_params`."""
    I_ = P[0]
    C_R = P[1]
    C_M = P[2]
    qw = y[0]
    qx = y[1]
    qy = y[2]
    qz = y[3]
    W1 = y[4]
    W2 = y[5]
    W3 = y[6]
    zd = y[8]
    M1, M2, M3 = tilt_twist_torque(qw, qx, qy, qz, P[3], P[4], P[5])
    Q = drive_law(y[7], zd, P[6], P[7], P[9])
    g = axial_momentum(y, P) - I_ * W3   # H_3 - I W_3
    dW3 = (M3 - Q) / C_M
    out[0] = 0.5 * (-qx * W1 - qy * W2 - qz * W3)
    out[1] = 0.5 * (qw * W1 + qy * W3 - qz * W2)
    out[2] = 0.5 * (qw * W2 + qz * W1 - qx * W3)
    out[3] = 0.5 * (qw * W3 + qx * W2 - qy * W1)
    inv_I = 1.0 / I_
    out[4] = (M1 - W2 * g) * inv_I
    out[5] = (M2 + W1 * g) * inv_I
    out[6] = dW3
    out[7] = zd
    out[8] = Q / C_R - dW3
    out[9] = P[7] * zd * zd


@numba_able
def upright_rhs(y, P, out):
    """dy/dt of the upright_axis model (state chi chidot z zdot D)."""
    zd = y[3]
    Q = drive_law(y[2], zd, P[6], P[7], P[9])
    chidd = (-P[5] * y[0] - Q) / P[2]
    out[0] = y[1]
    out[1] = chidd
    out[2] = zd
    out[3] = Q / P[1] - chidd
    out[4] = P[7] * zd * zd


@numba_able
def locked_rhs(y, P, out):
    """dy/dt of the locked_housing model (state z zdot D)."""
    zd = y[1]
    Q = drive_law(y[0], zd, P[6], P[7], P[9])
    out[0] = zd
    out[1] = Q / P[1]
    out[2] = P[7] * zd * zd


def drive_torque(p: RotorParams, z, zdot):
    """Drive torque Q on the rotor for parameters ``p`` (:func:`drive_law`, eq. 23)."""
    return drive_law(z, zdot, p.K_S, p.K_D, float(p.pole_pairs))


def drive_potential(p: RotorParams, z):
    """U(z): K_S z^2/2 (linear) or (K_S/p^2)(1 - cos p z) (p pole pairs)."""
    if p.pole_pairs == 0:
        return 0.5 * p.K_S * np.square(z)
    pp = p.pole_pairs
    return (p.K_S / pp ** 2) * (1.0 - np.cos(pp * z))


_COMPILED: dict = {}


def _compiled(fn):
    """Return ``fn`` compiled by numba (cached per function), or None without numba."""
    if fn not in _COMPILED:
        try:
            from numba import njit
        except ImportError:  # pragma: no cover
            _COMPILED[fn] = None
        else:
            _COMPILED[fn] = njit(cache=True)(fn)
    return _COMPILED[fn]


def drive_rates(p: RotorParams) -> tuple[float, float]:
    """Return (the drive damping root, the fastest oscillation) of the centrifuge [1/s].

    The root K_D (1/C_R + 1/C_M) (real, docs/model.md section 7) and the largest of the
    nutation rate C_R Omega0 / I (eq. 18), the drive's frequency sqrt(K_S (1/C_R + 1/C_M)),
    the tilt frequency sqrt(|c_theta - G s| / I), the twist frequency sqrt(c_psi / C_M) and
    1 1/s as a floor: what auto weighs (stiff, conservative, the cost of an explicit pair).
    """
    inv_c = 1.0 / p.C_R + 1.0 / p.C_M
    osc = max(p.C_R * abs(p.Omega0) / p.I, math.sqrt(p.K_S * inv_c),
              math.sqrt(abs(p.c_theta - p.Gs) / p.I), math.sqrt(p.c_psi / p.C_M), 1.0)
    return p.K_D * inv_c, osc


#: below this |sin theta| the 3-1-3 angles of a state are singular: a state cannot be
#: rebuilt from them (solution I passes through theta = 0)
SIN_THETA_MIN = 1e-3


class Model:
    """Common interface of the models (see module doc); subclasses fill in the physics."""

    name = ''
    #: the symplectic method of long conservative runs (auto): gauss6 for the reduced models
    symplectic_method = 'gauss6'
    state_names: tuple = ()
    #: the model's right-hand side ``f(y, P, out)`` (one of the numba-able functions above)
    rhs_function = None
    #: index of z, zdot and D in the state vector
    iz = izd = idiss = -1

    def __init__(self, params: RotorParams):
        if not isinstance(params, RotorParams):
            raise TypeError('params must be a RotorParams')
        self.params = params
        self.rhs = self.make_rhs()

    @property
    def n(self) -> int:
        """Size of the state vector."""
        return len(self.state_names)

    def drive_rates(self, y=None) -> tuple[float, float]:
        """Return (drive damping root, fastest oscillation) [1/s] (:func:`drive_rates`)."""
        return drive_rates(self.params)

    @property
    def conservative(self) -> bool:
        """Return True without drive damping (K_D = 0): E* is conserved (eq. 17)."""
        return self.params.K_D == 0.0

    def make_rhs(self) -> Callable[[float, np.ndarray], np.ndarray]:
        """Return ``f(t, y) -> dy/dt`` (ndarray), compiled by numba where it is installed."""
        fn = _compiled(self.rhs_function)
        P = pack_params(self.params)
        n = self.n
        if fn is None:          # plain floats: faster than numpy scalars in plain Python
            fl, P_list = self.rhs_function, P.tolist()

            def rhs(t, y):
                out = [0.0] * n
                fl(y.tolist(), P_list, out)
                return np.array(out)
            return rhs

        def rhs_c(t, y):
            out = np.empty(n)
            fn(np.asarray(y, dtype=float), P, out)
            return out
        return rhs_c

    # -- energy ----------------------------------------------------------------------------
    def energy(self, Y) -> np.ndarray:  # pragma: no cover
        """Lyapunov function E* (eq. 13 for this scene) of states Y (rows or one state)."""
        raise NotImplementedError

    def energy_rate(self, Y) -> np.ndarray:
        """dE*/dt = -K_D zdot^2 along exact solutions (eq. 17)."""
        Y = np.asarray(Y, dtype=float)
        return -self.params.K_D * Y[..., self.izd] ** 2

    def residual(self, Y, E0: float | None = None) -> np.ndarray:
        """Energy-balance residual r = E* - E*(0) + D (docs/model.md section 4).

        ``E0`` is E*(0) + D(0), by default taken from the first row of ``Y``.
        """
        Y = np.atleast_2d(np.asarray(Y, dtype=float))
        E = self.energy(Y)
        if E0 is None:
            E0 = E[0] + Y[0, self.idiss]
        return E - E0 + Y[:, self.idiss]

    # -- outputs ---------------------------------------------------------------------------
    def quaternion(self, Y) -> np.ndarray:  # pragma: no cover
        """Stator quaternions of the states Y."""
        raise NotImplementedError

    def body_rates(self, Y) -> np.ndarray:  # pragma: no cover
        """Stator body angular velocity of states Y."""
        raise NotImplementedError

    def singular_at(self, y) -> str:
        """Return why the model is singular at state ``y`` (:data:`AXIS_DOWN`), else ''."""
        theta = self.outputs(np.zeros(1), np.asarray(y, dtype=float)[None])['theta'][0]
        return AXIS_DOWN if np.pi - abs(theta) < 1e-6 else ''

    def coordinate_errors(self, Y, R) -> tuple[float, float]:
        """Return the largest (attitude, rotor angle) errors of states Y against R [rad].

        The attitude error is the angle between the symmetry axes (each model's own
        attitude: the reduced models' states hold no quaternion); the rotor angle's is
        the largest |z - z_ref|. Rows of Y and R are taken at the same times.
        """
        a = axis_from_quaternion(self.quaternion(Y))
        b = axis_from_quaternion(self.quaternion(R))
        ang = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.sum(a * b, axis=1))
        return (float(np.max(ang)),
                float(np.max(np.abs(np.asarray(Y)[:, self.iz] - np.asarray(R)[:, self.iz]))))

    def quaternion_norm_error(self, Y) -> np.ndarray:
        """|q| - 1 (zero for the reduced models, whose orientation is exact)."""
        Y = np.asarray(Y, dtype=float)
        return np.zeros(Y.shape[:-1])

    def outputs(self, t, Y) -> dict:
        """Return the derived outputs of a trajectory (time ``t`` shape (m,), states ``Y`` (m, n)).

        Returns a dict of arrays: ``quaternion`` (m, 4), ``omega_body`` (m, 3), ``axis``
        (m, 3) symmetry axis in space, ``theta``, ``psi``, ``phi_M``, ``phi_R`` (3-1-3
        angles, outputs only), their rates ``thetadot``, ``psidot``, ``phi_M_dot``,
        ``phi_R_dot``, ``chi``, ``z``, ``zdot``, ``Q`` (drive torque), ``E_star``,
        ``dE_dt``, ``dissipation`` (K_D zdot^2), ``residual`` and ``qnorm_error``.
        """
        p = self.params
        t = np.asarray(t, dtype=float)
        Y = np.atleast_2d(np.asarray(Y, dtype=float))
        q = self.quaternion(Y)
        W = self.body_rates(Y)
        psi, theta, phi_M = euler_from_quaternion(q)
        psi = np.unwrap(psi) if psi.ndim else psi
        phi_M = np.unwrap(phi_M) if phi_M.ndim else phi_M
        chi = self.chi(Y)
        psidot, thetadot, phi_M_dot = euler_rates_from_body(theta, phi_M, W)
        z, zdot = Y[:, self.iz], Y[:, self.izd]
        phi = z + p.Omega0 * t
        E = self.energy(Y)
        return {
            't': t, 'quaternion': q, 'omega_body': W, 'axis': axis_from_quaternion(q),
            'theta': theta, 'psi': psi, 'phi_M': phi_M, 'phi_R': phi + phi_M,
            'thetadot': thetadot, 'psidot': psidot, 'phi_M_dot': phi_M_dot,
            'phi_R_dot': zdot + p.Omega0 + phi_M_dot, 'chi': chi, 'z': z, 'zdot': zdot,
            'Q': drive_torque(p, z, zdot), 'E_star': E, 'dE_dt': self.energy_rate(Y),
            'dissipation': p.K_D * zdot ** 2, 'residual': self.residual(Y),
            'qnorm_error': self.quaternion_norm_error(Y),
        }

    #: the CSV columns of a trajectory: (name [one naming for every system: a rate is
    #: NAME_dot], unit, key of :meth:`outputs`, component of a vector output or None)
    CSV_COLUMNS = (('t', 's', 't', None), ('theta', 'rad', 'theta', None),
                   ('psi', 'rad', 'psi', None), ('phi_R', 'rad', 'phi_R', None),
                   ('phi_M', 'rad', 'phi_M', None), ('theta_dot', 'rad/s', 'thetadot', None),
                   ('psi_dot', 'rad/s', 'psidot', None),
                   ('phi_R_dot', 'rad/s', 'phi_R_dot', None),
                   ('phi_M_dot', 'rad/s', 'phi_M_dot', None), ('axis_x', '1', 'axis', 0),
                   ('axis_y', '1', 'axis', 1), ('axis_z', '1', 'axis', 2),
                   ('chi', 'rad', 'chi', None), ('z', 'rad', 'z', None),
                   ('z_dot', 'rad/s', 'zdot', None), ('Q', 'N m', 'Q', None),
                   ('E_star', 'J', 'E_star', None), ('dE_dt', 'W', 'dE_dt', None),
                   ('residual', 'J', 'residual', None), ('qnorm_error', '1', 'qnorm_error', None))
    #: the columns a printed summary gives at the end of a run
    FINAL_STATE = ('theta', 'psi_dot', 'chi', 'z', 'z_dot')

    def csv_columns(self) -> tuple:
        """Return the CSV columns (name, unit, output key, component): :data:`CSV_COLUMNS`."""
        return self.CSV_COLUMNS

    def final_state(self) -> tuple:
        """Return the names of the CSV columns a summary prints at the end of a run."""
        return self.FINAL_STATE

    def chi(self, Y) -> np.ndarray:
        """Twist chi = phi_M + psi of the housing (continuous along a trajectory)."""
        return twist(self.quaternion(Y))

    def generalized_forces(self, Y) -> np.ndarray:
        """Generalized forces (Q_theta, Q_psi, Q_phi_R, Q_phi_M) of eqs. (19, 23), (m, 4).

        Q_theta = G s sin(theta) - c_theta theta, Q_psi = -c_psi chi, Q_phi_R = Q,
        Q_phi_M = -c_psi chi - Q (the drive reaction on the stator).
        """
        p = self.params
        Y = np.atleast_2d(np.asarray(Y, dtype=float))
        theta = tilt(self.quaternion(Y))
        chi = self.chi(Y)
        Q = drive_torque(p, Y[:, self.iz], Y[:, self.izd])
        return np.stack([p.Gs * np.sin(theta) - p.c_theta * theta, -p.c_psi * chi, Q,
                         -p.c_psi * chi - Q], axis=-1)

    def state_from_euler(self, theta=0.0, thetadot=0.0, psi=0.0, psidot=0.0, phi_M=0.0,
                         phi_M_dot=0.0, z=0.0, zdot=0.0) -> np.ndarray:  # pragma: no cover
        """State vector from 3-1-3 angles and rates of the stator and the rotor's z, zdot."""
        raise NotImplementedError

    # -- the live simulation's interface (gyro_rotor.numerics.live) ------------------------
    #: names of the joint_states columns (the wire layout, written here once; bag/wire.py's
    #: JOINT_NAMES is this): the 3-1-3 angles theta, psi, the rotor angle phi_R and phi_M
    joint_names = ('theta', 'psi', 'phi_R', 'phi_M')
    #: fields of the ``energy`` array (bag/wire.py's ENERGY_FIELDS is this)
    energy_fields = ('t_sim', 'E_star', 'dE_dt', 'dissipation', 'residual', 'z', 'zdot', 'seq',
                     'D', 'k')

    def field_speeds(self) -> np.ndarray:
        """Return the speed Omega0 of the drive's rotating field (eq. 7), one per rotor."""
        return np.array([self.params.Omega0])

    def dissipation(self, Y) -> np.ndarray:
        """Power of the drive damping K_D zdot^2 (= -dE*/dt, eq. 17) of rows of states."""
        zdot = np.atleast_2d(np.asarray(Y, dtype=float))[:, self.izd]
        return self.params.K_D * zdot * zdot

    def state_fields(self, Y) -> dict:
        """Return the ``energy`` fields read off rows of states: the rotor's z and zdot."""
        return {'z': Y[:, self.iz], 'zdot': Y[:, self.izd]}

    def kick(self, y, perturbation: Mapping[str, float]) -> np.ndarray:
        """Return the state y kicked by ``perturbation`` (:func:`perturb_state`, its checks)."""
        return perturb_state(self, y, perturbation)

    def carried_state(self, old: 'Model', y) -> np.ndarray:
        """Return the state y of the model ``old`` under this model's parameters.

        The rotor keeps its absolute spin Omega0 + zdot (eq. 7): zdot jumps by -delta Omega0
        (the field angle stays continuous); every other component is kept.
        """
        y = np.array(y, dtype=float)
        y[self.izd] -= self.params.Omega0 - old.params.Omega0
        return y

    #: the joint positions are angles: compared modulo 2 pi
    joint_angles = True

    def singular_joints(self, positions) -> frozenset:
        """Return the indices of the joints a state at ``positions`` does not determine.

        psi and phi_M (1, 3) where the 3-1-3 angles are singular, |sin theta| below
        :data:`SIN_THETA_MIN` (solution I passes through theta = 0).
        """
        return frozenset({1, 3}) if abs(math.sin(positions[0])) < SIN_THETA_MIN else frozenset()

    def state_from_joints(self, positions, velocities, z: float, zdot: float):
        """Return the state of a published joint_states message, the inverse of :meth:`joints`.

        ``positions``, ``velocities``: theta, psi, phi_R, phi_M and their rates; z, zdot
        come with E* (the field angle is not in the message). None where the message does
        not determine a state: another layout, z or zdot not finite, the full model at a
        singular theta (:meth:`singular_joints`), or a state this model cannot hold.
        """
        if len(positions) != 4 or not (math.isfinite(z) and math.isfinite(zdot)):
            return None
        if self.name == 'full' and self.singular_joints(positions):
            return None
        theta, psi, _, phi_M = positions
        thetadot, psidot, _, phi_M_dot = velocities
        # the twist chi = psi + phi_M of the housing is small (its spring); the wrapped angles
        # add multiples of 2 pi to it, which would flip the quaternion's sign and its chi
        phi_M = math.remainder(psi + phi_M, 2.0 * math.pi) - psi
        try:
            return np.asarray(self.state_from_euler(
                theta=theta, thetadot=thetadot, psi=psi, psidot=psidot, phi_M=phi_M,
                phi_M_dot=phi_M_dot, z=z, zdot=zdot), dtype=float)
        except ValueError:
            return None

    def joints(self, Y, field) -> tuple:
        """Return the joint_states of rows of states: (positions, velocities, efforts, q).

        Positions theta, psi, phi_R = field + z + phi_M, phi_M (3-1-3 angles, wrapped to
        (-pi, pi]), their rates, the generalized forces of eqs. (19, 23) and the stator
        quaternions q (k, 4); ``field`` (k, 1) is the field angle at each state.
        """
        p = self.params
        q = self.quaternion(Y)
        psi, theta, phi_M = euler_from_quaternion(q)
        psidot, thetadot, phi_M_dot = euler_rates_from_body(theta, phi_M, self.body_rates(Y))
        z, zdot = Y[:, self.iz], Y[:, self.izd]
        position = wrap_angles(np.column_stack([theta, psi, field[:, 0] + z + phi_M, phi_M]))
        velocity = np.column_stack([thetadot, psidot, p.Omega0 + zdot + phi_M_dot, phi_M_dot])
        return position, velocity, np.asarray(self.generalized_forces(Y), dtype=float), q


class FullModel(Model):
    """The full nonlinear 4-DOF gyrostat with the drive (quaternion form, see module doc)."""

    name = 'full'
    #: split8: exact flows of the free gyrostat and the torques, composed to order 8
    symplectic_method = 'split8'
    state_names = ('q_w', 'q_x', 'q_y', 'q_z', 'W_1', 'W_2', 'W_3', 'z', 'zdot', 'D')
    iz, izd, idiss = 7, 8, 9

    rhs_function = staticmethod(full_rhs)

    def energy(self, Y):
        """E* = I (W_1^2+W_2^2)/2 + C_M W_3^2/2 + C_R (zdot+W_3)^2/2 + U(z) + V (eq. 13)."""
        p = self.params
        Y = np.asarray(Y, dtype=float)
        W1, W2, W3, z, zd = (Y[..., i] for i in (4, 5, 6, 7, 8))
        q = Y[..., 0:4]
        theta = tilt(q)
        chi = twist(q, unwrap=False)
        V = p.Gs * np.cos(theta) + 0.5 * p.c_theta * theta ** 2 + 0.5 * p.c_psi * chi ** 2
        return (0.5 * p.I * (W1 ** 2 + W2 ** 2) + 0.5 * p.C_M * W3 ** 2
                + 0.5 * p.C_R * (zd + W3) ** 2 + drive_potential(p, z) + V)

    def quaternion(self, Y):
        """Stator quaternion, as integrated (not renormalized)."""
        return np.asarray(Y, dtype=float)[..., 0:4]

    def body_rates(self, Y):
        """Stator body rates W."""
        return np.asarray(Y, dtype=float)[..., 4:7]

    def quaternion_norm_error(self, Y):
        """|q| - 1 of the integrated quaternion."""
        return np.linalg.norm(self.quaternion(Y), axis=-1) - 1.0

    def state_from_euler(self, theta=0.0, thetadot=0.0, psi=0.0, psidot=0.0, phi_M=0.0,
                         phi_M_dot=0.0, z=0.0, zdot=0.0):
        """State from 3-1-3 angles and rates (regular at theta = 0)."""
        q = quaternion_from_euler(psi, theta, phi_M)
        W = body_rates_from_euler(psi, theta, phi_M, psidot, thetadot, phi_M_dot)
        return np.concatenate([q, W, [z, zdot, 0.0]]).astype(float)

    def state_from_body(self, quaternion, omega_body, z=0.0, zdot=0.0) -> np.ndarray:
        """State from a stator quaternion (w, x, y, z; normalized here) and body rates."""
        q = np.asarray(quaternion, dtype=float)
        q = q / np.linalg.norm(q)
        return np.concatenate([q, np.asarray(omega_body, dtype=float), [z, zdot, 0.0]])


class UprightAxisModel(Model):
    """Axis locked vertical: housing twist chi and rotor, 2 DOF (state chi chidot z zdot D).

    C_M chi'' = -c_psi chi - Q,   C_R (chi'' + z'') = Q.  This is the full model restricted
    to theta = 0, W = (0, 0, chidot); it stands for the limit c_theta -> infinity.
    """

    name = 'upright_axis'
    state_names = ('chi', 'chidot', 'z', 'zdot', 'D')
    iz, izd, idiss = 2, 3, 4

    rhs_function = staticmethod(upright_rhs)

    def energy(self, Y):
        """E* at theta = 0: C_M chidot^2/2 + C_R (zdot + chidot)^2/2 + U + G s + c_psi chi^2/2."""
        p = self.params
        Y = np.asarray(Y, dtype=float)
        chi, chid, z, zd = Y[..., 0], Y[..., 1], Y[..., 2], Y[..., 3]
        return (0.5 * p.C_M * chid ** 2 + 0.5 * p.C_R * (zd + chid) ** 2
                + drive_potential(p, z) + p.Gs + 0.5 * p.c_psi * chi ** 2)

    def quaternion(self, Y):
        """Rotation by chi about the vertical."""
        chi = np.asarray(Y, dtype=float)[..., 0]
        zero = np.zeros_like(chi)
        return np.stack([np.cos(chi / 2), zero, zero, np.sin(chi / 2)], axis=-1)

    def body_rates(self, Y):
        """W = (0, 0, chidot)."""
        chid = np.asarray(Y, dtype=float)[..., 1]
        zero = np.zeros_like(chid)
        return np.stack([zero, zero, chid], axis=-1)

    def chi(self, Y):
        """Twist chi, a state of this model."""
        return np.asarray(Y, dtype=float)[..., 0]

    def state_from_euler(self, theta=0.0, thetadot=0.0, psi=0.0, psidot=0.0, phi_M=0.0,
                         phi_M_dot=0.0, z=0.0, zdot=0.0):
        """State from angles; theta and thetadot must be 0 for this model."""
        if theta != 0.0 or thetadot != 0.0:
            raise ValueError('the upright_axis model holds theta = 0: theta and thetadot '
                             'must be 0')
        return np.array([psi + phi_M, psidot + phi_M_dot, z, zdot, 0.0])


class LockedHousingModel(Model):
    """Housing locked (the paper's "arretiertes System"): rotor on its drive, 1 DOF.

    C_R z'' = Q (eq. 8): a damped oscillator about synchronism (eqs. 9, 10) for the linear
    law, a damped pendulum (pole slips) for the sine law. State z zdot D.
    """

    name = 'locked_housing'
    state_names = ('z', 'zdot', 'D')
    iz, izd, idiss = 0, 1, 2

    rhs_function = staticmethod(locked_rhs)

    def energy(self, Y):
        """E* = C_R zdot^2/2 + U(z) + G s (housing at rest, axis vertical)."""
        p = self.params
        Y = np.asarray(Y, dtype=float)
        return 0.5 * p.C_R * Y[..., 1] ** 2 + drive_potential(p, Y[..., 0]) + p.Gs

    def quaternion(self, Y):
        """Identity (housing locked)."""
        Y = np.asarray(Y, dtype=float)
        q = np.zeros(Y.shape[:-1] + (4,))
        q[..., 0] = 1.0
        return q

    def body_rates(self, Y):
        """Zero (housing locked)."""
        Y = np.asarray(Y, dtype=float)
        return np.zeros(Y.shape[:-1] + (3,))

    def chi(self, Y):
        """Zero (housing locked)."""
        return np.zeros(np.asarray(Y, dtype=float).shape[:-1])

    def state_from_euler(self, theta=0.0, thetadot=0.0, psi=0.0, psidot=0.0, phi_M=0.0,
                         phi_M_dot=0.0, z=0.0, zdot=0.0):
        """State from angles; the housing angles are ignored (locked)."""
        return np.array([z, zdot, 0.0])


MODELS = {cls.name: cls for cls in (FullModel, UprightAxisModel, LockedHousingModel)}


def make_model(name: str, params: RotorParams) -> Model:
    """Make the model registered under ``name`` ('full', 'upright_axis', 'locked_housing')."""
    try:
        cls = MODELS[name]
    except KeyError:
        raise ValueError(f"unknown model '{name}'; valid: {', '.join(MODELS)}") from None
    return cls(params)


def perturb_state(model: Model, y: np.ndarray, perturbation: Mapping[str, float]) -> np.ndarray:
    """Apply a kick (dtheta, dthetadot, dpsidot, dchi, dz, dzdot) to a state.

    Full model: the orientation is turned by dtheta and dchi in the current 3-1-3 angles
    (psi, theta + dtheta, phi_M + dchi), and the rate kick is added to the body rates,
    W += J(psi, theta, phi_M) (dpsidot, dthetadot, 0) with J the map of
    :func:`~gyro_rotor.core.rotations.body_rates_from_euler` at the (new) angles. This is
    linear in the kick and regular at theta = 0, where the Euler rates themselves are not
    defined: every other component of W is kept. The quaternion keeps its hemisphere, so
    chi moves by exactly dchi. Reduced models: the same in their coordinates. z and zdot
    are kicked directly; the dissipated work D is kept.
    """
    for key in perturbation:
        if key not in PERTURBATION_KEYS:
            raise SceneError(f"unknown key 'perturbation.{key}'" + did_you_mean(
                f'perturbation.{key}', [f'perturbation.{k}' for k in PERTURBATION_KEYS]))
    d = {k: float(perturbation.get(k, 0.0)) for k in PERTURBATION_KEYS}
    for k, v in d.items():
        if not math.isfinite(v):
            raise SceneError(f'perturbation.{k} must be finite, got {v!r}')
    y = np.asarray(y, dtype=float)
    if model.name != 'full' and (d['dtheta'] or d['dthetadot']):
        raise SceneError(f'model {model.name} holds the axis vertical: dtheta and dthetadot '
                         f'cannot be applied')
    q = model.quaternion(y)
    W = model.body_rates(y)
    psi, theta, phi = (float(v) for v in euler_from_quaternion(q))
    if model.name == 'full':
        new = np.array(y, dtype=float)
        if d['dtheta'] or d['dchi']:
            theta, phi = theta + d['dtheta'], phi + d['dchi']
            new[0:4] = quaternion_from_euler(psi, theta, phi) * np.linalg.norm(q)
        new[4:7] = W + body_rates_from_euler(psi, theta, phi, d['dpsidot'], d['dthetadot'],
                                             0.0)
        new[model.iz] += d['dz']
        new[model.izd] += d['dzdot']
        return new
    psidot, thetadot, phidot = euler_rates_from_body(theta, phi, W)
    new = model.state_from_euler(theta=theta, thetadot=float(thetadot), psi=psi,
                                 psidot=float(psidot) + d['dpsidot'], phi_M=phi + d['dchi'],
                                 phi_M_dot=float(phidot), z=float(y[model.iz]) + d['dz'],
                                 zdot=float(y[model.izd]) + d['dzdot'])
    new[model.idiss] = y[model.idiss]
    return new
