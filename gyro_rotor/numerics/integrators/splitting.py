"""Compiled kernels of the splitting method: exact sub-flows, composed to high order.

The full model (docs/model.md section 3) with K_D = 0 is a Lie-Poisson system with the
Hamiltonian E* = T + V + U (eq. 13): T the kinetic energy of the gyrostat in the body
angular momentum H = (I W_1, I W_2, C_M W_3 + p_z) and the rotor's momentum
p_z = C_R (W_3 + Omega0 + zdot), V(q) the restraint potential of eq. (19), U(z) the drive's.
Both parts have exact flows:

*drift* (flow of T: the free axisymmetric gyrostat). H_3, p_z, hence W_3 and zdot stay
    constant; the spatial angular momentum h = R(q) H is fixed, and the orientation is
    q(t) = exp(t |h|/I about h) * q * exp(t beta about e_3), beta = W_3 - H_3/I, while
    (W_1, W_2) turn by the angle -beta t and z advances by zdot t. The quaternion is
    multiplied by unit quaternions only: it stays on the unit sphere up to round-off.
*kick* (flow of V + U and of the drive damping, positions q and z frozen). The body torque
    M(q) (:func:`~gyro_rotor.core.model.tilt_twist_torque`) and the drive torque are then
    constant: W_1, W_2 change linearly, and the axial pair (W_3, zdot) follows a linear
    ODE that is solved exactly (zdot relaxes with exp(-K_D (1/C_R + 1/C_M) t), zero for
    K_D = 0); the dissipated work D gets the exact integral of K_D zdot^2.

Strang's kick(h/2) drift(h) kick(h/2) is symmetric and of order 2 (for K_D = 0
symplectic: its E* error stays bounded instead of drifting); the symmetric compositions of
Kahan and Li (1997) with step fractions ``W`` raise it to order 6 (9 stages) or 8 (17).
References: McLachlan and Quispel, Splitting methods, Acta Numerica 11 (2002); Hairer,
Lubich, Wanner, Geometric Numerical Integration, sec. VII.5 (the free rigid body flow).
"""

from __future__ import annotations

import math

from gyro_rotor.core.model import axial_momentum, drive_law, tilt_twist_torque
from gyro_rotor.numerics.integrators.primitives import (all_finite, BUDGET, finish_run,
                                                        fixed_segment, njit, NONFINITE, OK)

__all__ = ['kick', 'drift', 'composed_step', 'split_run']


@njit(cache=True, error_model='numpy')
def kick(P, y, t):
    """Advance the state by the flow of the torques over ``t`` (module doc), in place."""
    I_ = P[0]
    C_R = P[1]
    C_M = P[2]
    K_D = P[7]
    M1, M2, M3 = tilt_twist_torque(y[0], y[1], y[2], y[3], P[3], P[4], P[5])
    QS = drive_law(y[7], 0.0, P[6], 0.0, P[9])
    a = 1.0 / C_R + 1.0 / C_M
    lam = K_D * a
    ck = a * QS - M3 / C_M               # d zdot/dt = ck - lam zdot
    zd = y[8]
    if lam == 0.0:
        zd_new = zd + ck * t
    else:
        x = lam * t
        e1 = -math.expm1(-x) / lam
        e2 = -math.expm1(-2.0 * x) / (2.0 * lam)
        zd_new = zd * math.exp(-x) + ck * e1
        if abs(x) > 1e-3:
            zinf = ck / lam
            dz = zd - zinf
            i2 = zinf * zinf * t + 2.0 * zinf * dz * e1 + dz * dz * e2
        else:
            i2 = (zd * zd * e2 + 2.0 * zd * ck * t * t * (0.5 - x / 2.0 + 7.0 * x * x / 24.0)
                  + ck * ck * t * t * t * (1.0 / 3.0 - x / 4.0))
        y[9] += K_D * i2
    y[4] += t * M1 / I_
    y[5] += t * M2 / I_
    y[6] += (t * M3 - C_R * (zd_new - zd)) / (C_M + C_R)
    y[8] = zd_new


@njit(cache=True, error_model='numpy')
def drift(P, y, t):
    """Advance the state by the exact free-gyrostat flow over ``t`` (module doc), in place."""
    H3 = axial_momentum(y, P)
    I_ = P[0]
    qw = y[0]
    qx = y[1]
    qy = y[2]
    qz = y[3]
    H1 = I_ * y[4]
    H2 = I_ * y[5]
    # spatial momentum h = q H q*  (v + 2 w (u x v) + 2 u x (u x v), u = (qx, qy, qz))
    cx = qy * H3 - qz * H2
    cy = qz * H1 - qx * H3
    cz = qx * H2 - qy * H1
    hx = H1 + 2.0 * (qw * cx + qy * cz - qz * cy)
    hy = H2 + 2.0 * (qw * cy + qz * cx - qx * cz)
    hz = H3 + 2.0 * (qw * cz + qx * cy - qy * cx)
    hn = math.sqrt(hx * hx + hy * hy + hz * hz)
    if hn > 0.0:
        half = 0.5 * hn * t / I_
        sa = math.sin(half) / hn
        aw = math.cos(half)
        ax = sa * hx
        ay = sa * hy
        az = sa * hz
    else:
        aw = 1.0
        ax = 0.0
        ay = 0.0
        az = 0.0
    phi = (y[6] - H3 / I_) * t
    bw = math.cos(0.5 * phi)
    bz = math.sin(0.5 * phi)
    # r = a * q
    rw = aw * qw - ax * qx - ay * qy - az * qz
    rx = aw * qx + ax * qw + ay * qz - az * qy
    ry = aw * qy - ax * qz + ay * qw + az * qx
    rz = aw * qz + ax * qy - ay * qx + az * qw
    # q_new = r * (bw, 0, 0, bz)
    nw = rw * bw - rz * bz
    nx = rx * bw + ry * bz
    ny = ry * bw - rx * bz
    nz = rz * bw + rw * bz
    s = 1.0 / math.sqrt(nw * nw + nx * nx + ny * ny + nz * nz)
    y[0] = nw * s
    y[1] = nx * s
    y[2] = ny * s
    y[3] = nz * s
    c = math.cos(phi)
    sn = math.sin(phi)
    W1 = y[4]
    W2 = y[5]
    y[4] = c * W1 + sn * W2
    y[5] = -sn * W1 + c * W2
    y[7] += y[8] * t


@njit(cache=True, error_model='numpy')
def composed_step(P, y, h, W):
    """One step of the composition of Strang steps with fractions ``W`` (adjacent kicks merged)."""
    s = W.shape[0]
    kick(P, y, 0.5 * W[0] * h)
    for i in range(s):
        drift(P, y, W[i] * h)
        if i + 1 < s:
            kick(P, y, 0.5 * (W[i] + W[i + 1]) * h)
    kick(P, y, 0.5 * W[s - 1] * h)


@njit(cache=True, error_model='numpy')
def split_run(P, y0, t0, t_eval, h_max, W, max_steps, Y_out, counts):
    """Fixed-step composition through the sample times (as the other fixed-step runs).

    ``counts`` = (flow evaluations as kicks + drifts, nsteps).
    """
    flows = 2 * W.shape[0] + 1
    y = y0.copy()
    nsteps = 0
    k, m, h = fixed_segment(t_eval, 0, t0, h_max, y, Y_out)
    while m > 0:
        for i in range(m):
            composed_step(P, y, h, W)
            nsteps += 1
            if not all_finite(y):
                return finish_run(counts, NONFINITE, nsteps * flows, nsteps, 0, 0.0)
            if nsteps >= max_steps:
                return finish_run(counts, BUDGET, nsteps * flows, nsteps, 0, 0.0)
        k, m, h = fixed_segment(t_eval, k, t_eval[k], h_max, y, Y_out)
    return finish_run(counts, OK, nsteps * flows, nsteps, 0, 0.0)
