"""Linearization about the steady motions I and II (Magnus 1980, eqs. 18, 19, 23).

Every linearization here is ``x' = A x`` in coordinates where the steady motion is an
equilibrium, with ``A`` linear in K_D: ``A = A_0 - K_D b c^T`` (the drive damping is a
rank-one feedback of the rotor's lag rate zdot). Both an *analytic* Jacobian (derived by
hand from the Lagrangian below) and a *finite-difference* one are provided; the latter is
taken through the full quaternion model of :mod:`gyro_rotor.core.model` (an independent code
path) by exact kinematic maps, so that their agreement checks the derivation.

Solution II (docs/model.md section 6): reduced coordinates
``x = (theta, thetadot, psidot, chi, chidot, z, zdot)``. With chi = phi_M + psi replacing
phi_M, the angle psi is cyclic and x has the equilibrium
``(theta0, 0, psidot0, 0, 0, 0, 0)``. Writing C = C_R + C_M, u = 1 - cos(theta) and
W_3 = chidot - u psidot (stator spin), the Lagrangian (18, 19) becomes

    T = 1/2 [I thetadot^2 + I sin^2(theta) psidot^2 + C_M W_3^2
             + C_R (W_3 + Omega0 + zdot)^2],
    V = G s cos(theta) + c_theta theta^2/2 + c_psi chi^2/2,

and the drive torque Q = -K_S z - K_D zdot (eq. 23; the sine law linearizes to the same
K_S) is the generalized force of z. With h_3 = C W_3 + C_R (Omega0 + zdot) (axial
angular momentum), the Lagrange equations M(theta) v' = g(x) for v = (thetadot, psidot,
chidot, zdot) read

    M = [[I, 0,                   0,      0     ],
         [0, I sin^2 + C u^2,     -C u,   -C_R u],
         [0, -C u,                C,      C_R   ],
         [0, -C_R u,              C_R,    C_R   ]],
    g_theta = I psidot^2 sin cos - psidot sin h_3 + G s sin(theta) - c_theta theta,
    g_psi   = -thetadot [(2 I sin cos + 2 C u sin) psidot
                         - sin (C chidot + C_R zdot + C_R Omega0)],
    g_chi   = C sin psidot thetadot - c_psi chi,
    g_z     = C_R sin psidot thetadot + Q.

(g_psi = 0 expresses the conservation of p_psi = I sin^2 psidot - u h_3: psi is cyclic,
which gives the zero root.) At the equilibrium g = 0, so the Jacobian of v' = M^-1 g is
M(theta0)^-1 (dg/dx): no derivative of M is needed. The non-zero entries of dg/dx at
(theta0, 0, psidot0, 0, 0, 0, 0), with s0, c0, u0 and h30 = C_R Omega0 - C u0 psidot0:

    dg_theta/dtheta    = I psidot0^2 cos(2 theta0) - psidot0 c0 h30 + C s0^2 psidot0^2
                         + G s c0 - c_theta
    dg_theta/dpsidot   = 2 I psidot0 s0 c0 - s0 h30 + C u0 s0 psidot0
    dg_theta/dchidot   = -C s0 psidot0,      dg_theta/dzdot = -C_R s0 psidot0
    dg_psi/dthetadot   = -(2 I s0 c0 + 2 C u0 s0) psidot0 + s0 C_R Omega0
    dg_chi/dthetadot   = C s0 psidot0,       dg_chi/dchi = -c_psi
    dg_z/dthetadot     = C_R s0 psidot0,     dg_z/dz = -K_S,   dg_z/dzdot = -K_D

Solution I (theta0 = 0): the reduced coordinates are singular there (psidot undefined).
The stator is at rest, so solution I is an equilibrium of the full model itself; it is
linearized in Cartesian tilt coordinates ``x = (alpha, beta, W_1, W_2, chi, chidot, z,
zdot)``, where (alpha, beta, chi) = 2 (q_x, q_y, q_z)/q_w (twice the Rodrigues vector:
small rotations about the body axes 1, 2 and the twist) and W the body rates. With
H = C_R Omega0 and k = c_theta - G s:

    alpha' = W_1,   I W_1' = -k alpha - H W_2,
    beta'  = W_2,   I W_2' = -k beta  + H W_1,
    C_M chi'' = -c_psi chi - Q,   C_R (chi'' + z'') = Q.

The tilt block does not contain K_D at all: the drive damping does not reach the tilt
modes (Hagedorn's exclusion in the paper's footnote).

Reduced models: ``upright_axis`` x = (chi, chidot, z, zdot) (the last block above) and
``locked_housing`` x = (z, zdot), C_R z'' = Q (eq. 8).

Every system offers its linear pieces as :class:`LinearParts` (``linear_parts`` of the
centrifuge, :func:`analytic_parts` of its analytic linearization, and of a system file's
:class:`~gyro_rotor.core.system.generated.GeneratedSystem`, the exact derivatives of its
generated equations); :func:`gyro_rotor.linear.system.linearize_scene` builds the one
linearization of every scene from them.
"""

from __future__ import annotations

import dataclasses
import enum
import math

from gyro_rotor.core.model import drive_torque, FullModel, make_model
from gyro_rotor.core.params import RotorParams
from gyro_rotor.core.steady import SteadyMotion
from gyro_rotor.errors import ParameterError
import numpy as np

__all__ = ['Coords', 'LinearSystem', 'LinearParts', 'linearize', 'analytic_parts', 'jacobian_fd',
           'reduced_rhs', 'reduced_rhs_lagrange', 'equilibrium', 'coordinates',
           'STATE_NAMES_II', 'STATE_NAMES_I', 'STATE_NAMES_UPRIGHT', 'STATE_NAMES_LOCKED']

STATE_NAMES_II = ('theta', 'thetadot', 'psidot', 'chi', 'chidot', 'z', 'zdot')
STATE_NAMES_I = ('alpha', 'beta', 'W_1', 'W_2', 'chi', 'chidot', 'z', 'zdot')
STATE_NAMES_UPRIGHT = ('chi', 'chidot', 'z', 'zdot')
STATE_NAMES_LOCKED = ('z', 'zdot')

#: the coordinate of each state of the analytic linearizations (the rates' coordinates:
#: thetadot is theta's, W_1 alpha's, ...)
_COORDINATE = {'thetadot': 'theta', 'psidot': 'psi', 'chidot': 'chi', 'zdot': 'z',
               'W_1': 'alpha', 'W_2': 'beta'}

#: relative step of the central finite differences (of order eps^(1/3))
FD_STEP = 1e-6

#: coordinate group of each state (tilt, twist or drive), per coordinate system
GROUPS = {
    'II': ('tilt', 'tilt', 'tilt', 'twist', 'twist', 'drive', 'drive'),
    'I': ('tilt', 'tilt', 'tilt', 'tilt', 'twist', 'twist', 'drive', 'drive'),
    'upright': ('twist', 'twist', 'drive', 'drive'),
    'locked': ('drive', 'drive'),
}


@dataclasses.dataclass(frozen=True)
class LinearSystem:
    """x' = A x about a steady motion; unpacks as ``A, state_names = lin``.

    ``A`` = ``A0 - K_D * np.outer(b, c)``: ``b`` is the acceleration response to a unit
    torque on z (column), ``c`` picks zdot. ``groups`` names the coordinate group of
    each state ('tilt', 'twist', 'drive'); ``weights`` scale the states to sqrt(energy)
    units (for modal energy shares); ``coords`` a :class:`Coords`.
    """

    A: np.ndarray
    state_names: tuple
    A0: np.ndarray
    b: np.ndarray
    c: np.ndarray
    groups: tuple
    weights: np.ndarray
    coords: Coords
    motion: SteadyMotion
    model: str
    params: RotorParams

    def __iter__(self):
        return iter((self.A, self.state_names))

    def with_K_D(self, K_D: float) -> np.ndarray:
        """Return A at another drive damping (the steady motion does not depend on K_D)."""
        return self.A0 - float(K_D) * np.outer(self.b, self.c)


class Coords(enum.StrEnum):
    """The reduced coordinates of a linearization (module doc).

    II: about solution II (tilted axis, psi cyclic); I: about solution I (axis vertical,
    tilt components); UPRIGHT: the upright_axis model; LOCKED: the locked_housing model;
    GENERAL: a system file's own coordinates (deviations of q, z and their rates,
    ``linear_parts`` of :class:`~gyro_rotor.core.system.generated.GeneratedSystem`).
    """

    II = 'II'
    I = 'I'  # noqa: E741 -- the paper's name of solution I
    UPRIGHT = 'upright'
    LOCKED = 'locked'
    GENERAL = 'general'


@dataclasses.dataclass(frozen=True)
class LinearParts:
    """A system's linear pieces about its steady motion: A(K) = A0 - K b c' (module doc).

    ``A0``, ``b``, ``c``: the drives varied (``vary``, their indices) undamped, the others
    at their K_D; ``A_cons``, ``b_all``, ``c_all``, ``K_all``: every drive (A_cons: all
    undamped); ``names`` the states, ``coordinate`` the coordinate each state belongs to
    (a rate belongs to its angle); ``about`` the steady motion in words; ``analytic`` the
    centrifuge's analytic linearization (else None) and ``coords`` its coordinates.
    """

    A0: np.ndarray
    b: np.ndarray
    c: np.ndarray
    A_cons: np.ndarray
    b_all: np.ndarray
    c_all: np.ndarray
    K_all: np.ndarray
    vary: tuple
    names: tuple
    coordinate: tuple
    about: str
    analytic: LinearSystem | None = None
    coords: Coords = Coords.GENERAL


def coordinates(model: str, motion: SteadyMotion) -> Coords:
    """Which coordinate system serves ``model`` about ``motion``."""
    if model == 'locked_housing':
        return Coords.LOCKED
    if model == 'upright_axis':
        if motion.branch != 0:
            raise ParameterError(f'model upright_axis holds the axis vertical: it has only '
                                 f'solution I, not {motion.name}')
        return Coords.UPRIGHT
    if model != 'full':
        raise ParameterError(f"unknown model '{model}'; valid: full, upright_axis, "
                             'locked_housing')
    return Coords.I if motion.branch == 0 else Coords.II


def equilibrium(model: str, motion: SteadyMotion) -> np.ndarray:
    """Return the steady motion as an equilibrium of the reduced coordinates."""
    coords = coordinates(model, motion)
    if coords == Coords.II:
        return np.array([motion.theta0, 0.0, motion.psidot0, 0.0, 0.0, 0.0, 0.0])
    return np.zeros(len(_names(coords)))


def _names(coords: str) -> tuple:
    return {'II': STATE_NAMES_II, 'I': STATE_NAMES_I, 'upright': STATE_NAMES_UPRIGHT,
            'locked': STATE_NAMES_LOCKED}[coords]


# -- analytic Jacobian ------------------------------------------------------------------------
def _analytic_A0_b(p: RotorParams, coords: str, motion: SteadyMotion):
    """(A0, b) of the analytic linearization (module doc); A = A0 - K_D b c^T."""
    I, C_R, Cs = p.I, p.C_R, p.C_R + p.C_M
    Om = p.Omega0
    if coords == Coords.II:
        th, w = motion.theta0, motion.psidot0
        s0, c0 = math.sin(th), math.cos(th)
        u0 = 1.0 - c0
        h30 = C_R * Om - Cs * u0 * w
        M = np.array([[I, 0.0, 0.0, 0.0],
                      [0.0, I * s0 * s0 + Cs * u0 * u0, -Cs * u0, -C_R * u0],
                      [0.0, -Cs * u0, Cs, C_R],
                      [0.0, -C_R * u0, C_R, C_R]])
        G = np.zeros((4, 7))
        G[0, 0] = (I * w * w * math.cos(2 * th) - w * c0 * h30 + Cs * s0 * s0 * w * w
                   + p.Gs * c0 - p.c_theta)
        G[0, 2] = 2 * I * w * s0 * c0 - s0 * h30 + Cs * u0 * s0 * w
        G[0, 4] = -Cs * s0 * w
        G[0, 6] = -C_R * s0 * w
        G[1, 1] = -(2 * I * s0 * c0 + 2 * Cs * u0 * s0) * w + s0 * C_R * Om
        G[2, 1] = Cs * s0 * w
        G[2, 3] = -p.c_psi
        G[3, 1] = C_R * s0 * w
        G[3, 5] = -p.K_S
        Minv = np.linalg.inv(M)
        acc = Minv @ G                     # rows: thetadd, psidd, chidd, zdd
        A0 = np.zeros((7, 7))
        A0[0, 1] = A0[3, 4] = A0[5, 6] = 1.0
        A0[[1, 2, 4, 6], :] = acc
        b = np.zeros(7)
        b[[1, 2, 4, 6]] = Minv[:, 3]       # a unit torque on z (the K_D term's direction)
        return A0, b
    # the chi-z block: M [chidd, zdd] = [-c_psi chi - Q... ] in (chi, z) velocities
    Mcz = np.array([[Cs, C_R], [C_R, C_R]])
    Mi = np.linalg.inv(Mcz)
    if coords == Coords.LOCKED:
        A0 = np.array([[0.0, 1.0], [-p.K_S / C_R, 0.0]])
        return A0, np.array([0.0, 1.0 / C_R])
    # upright block (chi, chidot, z, zdot); generalized forces (-c_psi chi, Q)
    blk = np.zeros((4, 4))
    blk[0, 1] = blk[2, 3] = 1.0
    Kcz = np.array([[-p.c_psi, 0.0], [0.0, -p.K_S]])   # d(forces)/d(chi, z)
    acc = Mi @ Kcz
    blk[1, [0, 2]] = acc[0]
    blk[3, [0, 2]] = acc[1]
    bb = np.array([0.0, Mi[0, 1], 0.0, Mi[1, 1]])
    if coords == Coords.UPRIGHT:
        return blk, bb
    # solution I, Cartesian tilt
    k = p.c_theta - p.Gs
    H = C_R * Om
    A0 = np.zeros((8, 8))
    A0[0, 2] = A0[1, 3] = 1.0
    A0[2, 0] = -k / I
    A0[2, 3] = -H / I
    A0[3, 1] = -k / I
    A0[3, 2] = H / I
    A0[4:, 4:] = blk
    b = np.zeros(8)
    b[4:] = bb
    return A0, b


def _c_vector(coords: str) -> np.ndarray:
    names = _names(coords)
    c = np.zeros(len(names))
    c[names.index('zdot')] = 1.0
    return c


# -- nonlinear reduced right-hand sides -------------------------------------------------------
def reduced_rhs(params: RotorParams, x, coords: str = 'II', *, _model=None) -> np.ndarray:
    """Return x' of the reduced coordinates, computed through the full quaternion model.

    The full model's right-hand side is evaluated at the state that ``x`` describes and
    its derivative is mapped back by the exact kinematics (3-1-3 angle rates for 'II',
    Rodrigues parameters for 'I'); for 'upright' and 'locked' the reduced models'
    right-hand sides are used directly. Independent of the Lagrangian derivation in the
    module doc, hence a check of it.
    """
    x = np.asarray(x, dtype=float)
    if coords in (Coords.UPRIGHT, Coords.LOCKED):
        m = _model or make_model('upright_axis' if coords == Coords.UPRIGHT else 'locked_housing',
                                 params)
        y = np.append(x, 0.0)
        return m.rhs(0.0, y)[:-1]
    m = _model or FullModel(params)
    if coords == Coords.II:
        th, thd, psd, chi, chid, z, zd = x
        y = m.state_from_euler(theta=th, thetadot=thd, psi=0.0, psidot=psd, phi_M=chi,
                               phi_M_dot=chid - psd, z=z, zdot=zd)
        dy = m.rhs(0.0, y)
        dW1, dW2, dW3 = dy[4:7]
        phd = chid - psd                              # phi_M' (phi_M = chi at psi = 0)
        sf, cf = math.sin(chi), math.cos(chi)
        st, ct = math.sin(th), math.cos(th)
        thdd = dW1 * cf - dW2 * sf - phd * psd * st
        psdd = (dW1 * sf + dW2 * cf + phd * thd - psd * ct * thd) / st
        chidd = psdd + dW3 - psdd * ct + psd * st * thd
        return np.array([thd, thdd, psdd, chid, chidd, zd, dy[8]])
    if coords == Coords.I:
        al, be, W1, W2, chi, W3, z, zd = x
        q = np.array([1.0, al / 2, be / 2, chi / 2])
        q /= np.linalg.norm(q)
        y = np.concatenate([q, [W1, W2, W3, z, zd, 0.0]])
        dy = m.rhs(0.0, y)
        qd = dy[0:4]
        gd = 2.0 * (qd[1:4] * q[0] - q[1:4] * qd[0]) / q[0] ** 2
        return np.array([gd[0], gd[1], dy[4], dy[5], gd[2], dy[6], zd, dy[8]])
    raise ParameterError(f"unknown coordinates '{coords}'")


def reduced_rhs_lagrange(params: RotorParams, x) -> np.ndarray:
    """Return x' about solution II from the Lagrange equations M(theta) v' = g(x) (module doc).

    The nonlinear equations from which the analytic Jacobian is taken; a test holds them
    against :func:`reduced_rhs` (the full model) at arbitrary states.
    """
    p = params
    th, thd, psd, chi, chid, z, zd = (float(v) for v in x)
    I, C_R, Cs, Om = p.I, p.C_R, p.C_R + p.C_M, p.Omega0
    s, c = math.sin(th), math.cos(th)
    u = 1.0 - c
    W3 = chid - u * psd
    h3 = Cs * W3 + C_R * (Om + zd)
    Q = float(drive_torque(p, z, zd))
    M = np.array([[I, 0.0, 0.0, 0.0],
                  [0.0, I * s * s + Cs * u * u, -Cs * u, -C_R * u],
                  [0.0, -Cs * u, Cs, C_R],
                  [0.0, -C_R * u, C_R, C_R]])
    g = np.array([
        I * psd * psd * s * c - psd * s * h3 + p.Gs * s - p.c_theta * th,
        -thd * ((2 * I * s * c + 2 * Cs * u * s) * psd - s * (Cs * chid + C_R * zd + C_R * Om)),
        Cs * s * psd * thd - p.c_psi * chi,
        C_R * s * psd * thd + Q])
    acc = np.linalg.solve(M, g)
    return np.array([thd, acc[0], acc[1], chid, acc[2], zd, acc[3]])


def jacobian_fd(params: RotorParams, motion: SteadyMotion, model: str = 'full',
                step: float = FD_STEP) -> np.ndarray:
    """Return the central finite-difference Jacobian of :func:`reduced_rhs` at the equilibrium.

    The full model is evaluated; the step is ``step`` times max(1, |x_i|) per coordinate.
    """
    coords = coordinates(model, motion)
    x0 = equilibrium(model, motion)
    mname = {'II': 'full', 'I': 'full', 'upright': 'upright_axis',
             'locked': 'locked_housing'}[coords]
    m = make_model(mname, params)
    n = len(x0)
    J = np.empty((n, n))
    for i in range(n):
        h = step * max(1.0, abs(x0[i]))
        xp, xm = x0.copy(), x0.copy()
        xp[i] += h
        xm[i] -= h
        J[:, i] = (reduced_rhs(params, xp, coords, _model=m)
                   - reduced_rhs(params, xm, coords, _model=m)) / (2 * h)
    return J


# -- the public entry point -----------------------------------------------------------------
def _weights(p: RotorParams, coords: str, motion: SteadyMotion) -> np.ndarray:
    """sqrt(stiffness) for positions and sqrt(inertia) for rates: states in sqrt(J)."""
    tiny = 1e-12
    k_th = max(abs(p.c_theta - p.Gs), tiny)
    Cs = p.C_R + p.C_M
    if coords == Coords.II:
        s0, u0 = math.sin(motion.theta0), 1.0 - math.cos(motion.theta0)
        w = [k_th, p.I, p.I * s0 * s0 + Cs * u0 * u0, p.c_psi, Cs, p.K_S, p.C_R]
    elif coords == Coords.I:
        w = [k_th, k_th, p.I, p.I, p.c_psi, Cs, p.K_S, p.C_R]
    elif coords == Coords.UPRIGHT:
        w = [p.c_psi, Cs, p.K_S, p.C_R]
    else:
        w = [p.K_S, p.C_R]
    return np.sqrt(np.maximum(np.array(w, dtype=float), tiny))


def linearize(params: RotorParams, steady_motion: SteadyMotion,
              model: str = 'full') -> LinearSystem:
    """Linearize ``model`` about ``steady_motion``; unpacks as ``A, state_names``.

    Parameters
    ----------
    params : RotorParams
    steady_motion : SteadyMotion
        Solution I (branch 0) or II (branch 1 or 2), from
        :func:`~gyro_rotor.core.steady.steady_motion`.
    model : str
        'full' (reduced coordinates of solution II, Cartesian tilt for solution I),
        'upright_axis' or 'locked_housing'.
    """
    if not isinstance(params, RotorParams):
        raise TypeError('params must be a RotorParams')
    if not isinstance(steady_motion, SteadyMotion):
        raise TypeError('steady_motion must be a SteadyMotion (gyro_rotor.core.steady)')
    coords = coordinates(model, steady_motion)
    A0, b = _analytic_A0_b(params, coords, steady_motion)
    c = _c_vector(coords)
    return LinearSystem(A=A0 - params.K_D * np.outer(b, c), state_names=_names(coords), A0=A0,
                        b=b, c=c, groups=GROUPS[coords],
                        weights=_weights(params, coords, steady_motion),
                        coords=coords, motion=steady_motion, model=model, params=params)


def analytic_parts(ls: LinearSystem) -> LinearParts:
    """Return the centrifuge's analytic linearization ``ls`` as its :class:`LinearParts`.

    One drive: b its torque direction, c its zdot; A_cons = A0 (the drive is the one varied).
    """
    b, c = ls.b[:, None], ls.c[:, None]
    p, sm = ls.params, ls.motion
    return LinearParts(A0=ls.A0, b=b, c=c, A_cons=ls.A0, b_all=b, c_all=c,
                       K_all=np.array([p.K_D], dtype=float), vary=(0,), names=ls.state_names,
                       coordinate=tuple(_COORDINATE.get(x, x) for x in ls.state_names),
                       about=f'{sm.name}: theta0 = {sm.theta0:g} rad, psidot0 = '
                             f'{sm.psidot0:.9g} rad/s (model {ls.model}, K_S = {p.K_S:g})',
                       analytic=ls, coords=ls.coords)
