"""Steady motions of the centrifuge (Magnus 1980, eqs. 20 to 22; docs/model.md section 5).

Solution I (eq. 20): theta = 0, rotor at Omega0 about the vertical, housing at rest.

Solution II (eq. 21): tilt theta0, steady precession psidot0 about the vertical, chi = 0,
phi_M_dot = -psidot0, z = zdot = 0. The theta equation of the Lagrangian (18, 19) gives
exactly

    a psidot0^2 - C_R Omega0 psidot0 + b = 0,
    a = I cos(theta0) + (C_R + C_M)(1 - cos(theta0)),   b = G s - c_theta theta0/sin(theta0).

The paper's closed form (22) takes a = I cos(theta0) (an approximation) and prints
sin^2(theta0) under the root where the theta equation gives sin(theta0); the *corrected*
closed form used here is

    psidot0 = C_R Omega0 / (2 I cos th0) [1 -/+ sqrt(1 - 4 I cos th0 (G s sin th0 - c_theta th0)
                                                         / (C_R^2 Omega0^2 sin th0))].

Branch 1 (the minus root for Omega0 > 0; in general the root of smaller |psidot0|) is the
slow precession against the rotor's sense, branch 2 the fast "nutation" in the rotor's
sense (the paper's text; its eq. 22 attaches the labels the other way round). Where the
discriminant is negative there is no steady motion II and
:class:`~gyro_rotor.errors.NoSteadyMotionError` says so.
"""

from __future__ import annotations

import dataclasses
import math
import sys

from gyro_rotor.core.params import RotorParams
from gyro_rotor.errors import NoSteadyMotionError, ParameterError
import numpy as np

__all__ = ['SteadyMotion', 'steady_motion', 'precession_rate_exact',
           'precession_rate_eq22', 'BRANCH_NAMES']

BRANCH_NAMES = {0: 'I (upright)', 1: 'II, branch 1 (precession)',
                2: 'II, branch 2 (nutation)'}


@dataclasses.dataclass(frozen=True)
class SteadyMotion:
    """A steady motion: tilt theta0, precession rate psidot0 (exact) and eq. (22)'s value."""

    branch: int
    theta0: float
    psidot0: float
    psidot0_eq22: float
    discriminant: float

    @property
    def phi_M_dot0(self) -> float:
        """Stator spin rate relative to the node line, -psidot0 (eq. 21)."""
        return -self.psidot0

    @property
    def relative_difference(self) -> float:
        """(eq. 22 - exact) / |exact| (0 for solution I)."""
        if self.psidot0 == 0.0:
            return 0.0
        return (self.psidot0_eq22 - self.psidot0) / abs(self.psidot0)

    @property
    def name(self) -> str:
        """Human-readable branch name."""
        return BRANCH_NAMES[self.branch]


def _check(theta0: float, branch: int) -> None:
    if branch not in (0, 1, 2):
        raise ParameterError(f'branch must be 0 (solution I), 1 or 2, got {branch!r}')
    if not math.isfinite(theta0):
        raise ParameterError(f'theta0 must be finite, got {theta0!r}')
    if branch == 0 and theta0 != 0.0:
        raise ParameterError(f'solution I (branch 0) has theta0 = 0, got {theta0!r}')
    if branch != 0 and not 0.0 < theta0 < math.pi:
        raise ParameterError(f'solution II needs 0 < theta0 < pi, got theta0 = {theta0!r}')


def precession_rate_exact(p: RotorParams, theta0: float, branch: int) -> tuple[float, float]:
    """Exact psidot0 of solution II on ``branch`` (1 or 2) and the discriminant.

    Roots of a x^2 - C_R Omega0 x + b = 0 (module doc), computed without cancellation.
    """
    _check(theta0, branch)
    c, s = math.cos(theta0), math.sin(theta0)
    a = p.I * c + (p.C_R + p.C_M) * (1.0 - c)
    b = p.Gs - p.c_theta * theta0 / s
    h = p.C_R * p.Omega0
    disc = h * h - 4.0 * a * b
    if disc < 0.0:
        raise NoSteadyMotionError(
            f'no steady motion II at theta0 = {theta0!r} rad: the discriminant '
            f'(C_R Omega0)^2 - 4 a b = {disc:.6g} is negative (the drive spins too slowly '
            f'for the gyroscopic stiffness to balance the tilt moment)')
    if a == 0.0:
        raise NoSteadyMotionError(f'no steady motion II at theta0 = {theta0!r}: a = 0')
    root = math.sqrt(disc)
    # q = (h + sign(h) root)/2 avoids cancellation: the roots are q/a (the larger |psidot0|)
    # and b/q (the smaller). Branch 1 is the slow root, branch 2 the fast one, whatever the
    # sign of Omega0 (for Omega0 > 0 they are the minus and plus roots of the module doc).
    sgn = 1.0 if h >= 0.0 else -1.0
    qv = 0.5 * (h + sgn * root)
    fast = qv / a
    slow = b / qv if qv != 0.0 else 0.0
    return (slow if branch == 1 else fast), disc


def precession_rate_eq22(p: RotorParams, theta0: float, branch: int) -> float:
    """psidot0 from the paper's closed form (22), with sin(theta0) under the root (corrected).

    Returns NaN where that approximate form has no real root although the exact one does.
    """
    _check(theta0, branch)
    c, s = math.cos(theta0), math.sin(theta0)
    h = p.C_R * p.Omega0
    if h == 0.0 or abs(c) <= 8.0 * sys.float_info.epsilon:
        # the closed form divides by C_R Omega0 and cos(theta0); cos of the double nearest
        # pi/2 is 6.1e-17, a rounded 0, not a number to divide by (it gave 7.9e17 rad/s)
        return math.nan
    rad = 1.0 - 4.0 * c * p.I * (p.Gs * s - p.c_theta * theta0) / (h * h * s)
    if rad < 0.0:
        return math.nan
    # the minus root is the slow one for either sign of Omega0 (sqrt(rad) > 1 when b < 0)
    sign = -1.0 if branch == 1 else 1.0
    return h / (2.0 * c * p.I) * (1.0 + sign * math.sqrt(rad))


def steady_motion(p: RotorParams, theta0: float = 0.0, branch: int = 1) -> SteadyMotion:
    """Steady motion I (branch 0) or II (branch 1 or 2) at tilt ``theta0`` [rad]."""
    theta0 = float(theta0)
    if branch == 0:
        _check(theta0, 0)
        return SteadyMotion(0, 0.0, 0.0, 0.0, (p.C_R * p.Omega0) * (p.C_R * p.Omega0))
    rate, disc = precession_rate_exact(p, theta0, branch)
    return SteadyMotion(branch, theta0, rate, precession_rate_eq22(p, theta0, branch), disc)


def steady_state(model, motion: SteadyMotion) -> np.ndarray:
    """State vector of ``model`` exactly on ``motion`` at t = 0 (psi = 0, chi = 0)."""
    return model.state_from_euler(theta=motion.theta0, thetadot=0.0, psi=0.0,
                                  psidot=motion.psidot0, phi_M=0.0,
                                  phi_M_dot=-motion.psidot0, z=0.0, zdot=0.0)
