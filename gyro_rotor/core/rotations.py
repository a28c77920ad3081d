"""Stator orientation: unit quaternion (body to space) and the paper's 3-1-3 Euler angles.

The equations of motion use the quaternion only (docs/model.md section 3); the 3-1-3 angles
(psi about the vertical, theta about the node line, phi_M about the symmetry axis) are
for initial conditions and outputs. They are singular at theta = 0, where only the sum
chi = psi + phi_M is defined; there :func:`euler_from_quaternion` puts the whole of chi
into psi and phi_M symmetrically (psi - phi_M = 0), a documented choice.

Quaternions are ``(q_w, q_x, q_y, q_z)``. With half angles,
``q_w = cos(theta/2) cos((psi+phi)/2)``, ``q_z = cos(theta/2) sin((psi+phi)/2)``,
``q_x = sin(theta/2) cos((psi-phi)/2)``, ``q_y = sin(theta/2) sin((psi-phi)/2)``, hence
chi = psi + phi_M = 2 atan2(q_z, q_w) exactly (for |chi| < 2 pi).

All functions accept scalars or numpy arrays (the last axis of ``q`` holds the components).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ['quaternion_from_euler', 'euler_from_quaternion', 'axis_from_quaternion',
           'vertical_in_body', 'tilt', 'twist', 'body_rates_from_euler',
           'euler_rates_from_body', 'wrap_angles']

_wrap = np.frompyfunc(math.remainder, 2, 1)


def wrap_angles(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to (-pi, pi] (exactly: IEEE remainder, -pi maps to pi)."""
    w = _wrap(np.asarray(a, dtype=float), 2 * math.pi).astype(float)
    w[w == -math.pi] = math.pi
    return w


def quaternion_from_euler(psi, theta, phi):
    """Return the unit quaternion (body to space) of the 3-1-3 rotation.

    The rotation is Rz(psi) Rx(theta) Rz(phi).
    """
    psi, theta, phi = np.broadcast_arrays(*(np.asarray(v, dtype=float)
                                            for v in (psi, theta, phi)))
    ct, st = np.cos(theta / 2), np.sin(theta / 2)
    sigma, delta = (psi + phi) / 2, (psi - phi) / 2
    return np.stack([ct * np.cos(sigma), st * np.cos(delta), st * np.sin(delta),
                     ct * np.sin(sigma)], axis=-1)


def vertical_in_body(q):
    """k: the space vertical e_z expressed in body axes (cos theta = k_3).

    Written homogeneously (divided by |q|^2) so that a small norm drift of q does not
    change the direction.
    """
    q = np.asarray(q, dtype=float)
    w, x, y, z = np.moveaxis(q, -1, 0)
    n = w * w + x * x + y * y + z * z
    return np.stack([2 * (x * z - w * y) / n, 2 * (y * z + w * x) / n,
                     (w * w - x * x - y * y + z * z) / n], axis=-1)


def axis_from_quaternion(q):
    """Return the symmetry axis e_3 of the stator expressed in space axes (unit vector)."""
    q = np.asarray(q, dtype=float)
    w, x, y, z = np.moveaxis(q, -1, 0)
    n = w * w + x * x + y * y + z * z
    return np.stack([2 * (x * z + w * y) / n, 2 * (y * z - w * x) / n,
                     (w * w - x * x - y * y + z * z) / n], axis=-1)


def tilt(q):
    """Tilt theta of the symmetry axis from the vertical, atan2(|k_12|, k_3) in [0, pi]."""
    k = vertical_in_body(q)
    return np.arctan2(np.hypot(k[..., 0], k[..., 1]), k[..., 2])


def twist(q, unwrap: bool = True):
    """Twist chi = psi + phi_M = 2 atan2(q_z, q_w) of the housing about the vertical.

    For a sequence (last axis components, first axis time) ``unwrap`` makes chi continuous.
    """
    q = np.asarray(q, dtype=float)
    chi = 2.0 * np.arctan2(q[..., 3], q[..., 0])
    if unwrap and chi.ndim >= 1 and chi.shape[0] > 1:
        chi = np.unwrap(chi, period=4 * np.pi, axis=0)
    return chi


def euler_from_quaternion(q):
    """3-1-3 angles (psi, theta, phi_M) of a quaternion; see the module note at theta = 0."""
    q = np.asarray(q, dtype=float)
    w, x, y, z = np.moveaxis(q, -1, 0)
    theta = tilt(q)
    sigma = twist(q, unwrap=False)       # psi + phi_M
    small = np.hypot(x, y) < 1e-300
    delta = np.where(small, 0.0, 2.0 * np.arctan2(y, x))
    psi = (sigma + delta) / 2
    phi = (sigma - delta) / 2
    return psi, theta, phi


def body_rates_from_euler(psi, theta, phi, psidot, thetadot, phidot):
    """Body angular velocity W of the stator from 3-1-3 angles and rates (regular at theta=0).

    W_1 = psidot sin(theta) sin(phi) + thetadot cos(phi),
    W_2 = psidot sin(theta) cos(phi) - thetadot sin(phi),
    W_3 = psidot cos(theta) + phidot.
    """
    st, ct = np.sin(theta), np.cos(theta)
    sp, cp = np.sin(phi), np.cos(phi)
    return np.stack(np.broadcast_arrays(psidot * st * sp + thetadot * cp,
                                        psidot * st * cp - thetadot * sp,
                                        psidot * ct + phidot), axis=-1).astype(float)


def euler_rates_from_body(theta, phi, W):
    """(psidot, thetadot, phidot) from body rates: singular at theta = 0.

    Where sin(theta) < 1e-12 the precession rate is undefined; psidot is reported as 0
    there (and phidot carries W_3), an output-only convention.
    """
    W = np.asarray(W, dtype=float)
    W1, W2, W3 = W[..., 0], W[..., 1], W[..., 2]
    st, ct = np.sin(theta), np.cos(theta)
    sp, cp = np.sin(phi), np.cos(phi)
    thetadot = W1 * cp - W2 * sp
    safe = np.abs(st) > 1e-12
    psidot = np.where(safe, (W1 * sp + W2 * cp) / np.where(safe, st, 1.0), 0.0)
    phidot = W3 - psidot * ct
    return psidot, thetadot, phidot
