"""Parameters of the elastically restrained centrifuge (Magnus 1980, section 4).

A :class:`RotorParams` is immutable and valid by construction: ``__post_init__`` refuses
non-finite values, non-positive inertias, negative stiffness or damping and a bad pole
count with a :class:`~gyro_rotor.errors.ParameterError` that names the field and the
value. A restraint too weak to hold the axis statically (``c_theta <= G s``) is allowed,
since the gyroscopic stiffness of the spinning rotor can still hold it, but it gets a
:class:`StaticallyUnstableWarning`.

Symbols (SI units) follow the paper, eqs. (18), (19), (23):

=========  ====================================================================
A_R, A_M   transverse moments of inertia of rotor, stator about F  [kg m^2]
C_R, C_M   polar moments of inertia about the symmetry axis        [kg m^2]
G, s       total weight [N]; distance F to centre of gravity S      [m]
c_theta    restraint stiffness against tilt theta of the axis       [N m/rad]
c_psi      restraint stiffness against twist chi = phi_M + psi      [N m/rad]
K_S, K_D   drive stiffness [N m/rad] and drive damping              [N m s/rad]
Omega0     speed of the rotating field relative to the stator       [rad/s]
pole_pairs 0: linear drive law Q = -K_S z - K_D zdot (eq. 23);
           p > 0: Q = -(K_S/p) sin(p z) - K_D zdot (pull-out torque K_S/p)
=========  ====================================================================
"""

from __future__ import annotations

import dataclasses
import enum
import math
import numbers
from typing import Any
import warnings

from gyro_rotor.errors import did_you_mean, ParameterError

__all__ = ['RotorParams', 'DriveLaw', 'StaticallyUnstableWarning', 'PARAM_FIELDS', 'MAX_MAGNITUDE',
           'PARAM_UNITS', 'PARAM_DESCRIPTIONS']


#: largest magnitude of any parameter in SI units: far beyond any real machine, small enough
#: that squares and products of parameters stay finite in double precision
MAX_MAGNITUDE = 1e12


class StaticallyUnstableWarning(UserWarning):
    """c_theta <= G s: only the gyroscopic stiffness can hold the axis up."""


class DriveLaw(enum.Enum):
    """Restoring law of the synchronous drive (eq. 23 and its sine form)."""

    LINEAR = 'linear'
    SINE = 'sine'


PARAM_UNITS = {
    'A_R': 'kg m^2', 'A_M': 'kg m^2', 'C_R': 'kg m^2', 'C_M': 'kg m^2', 'G': 'N', 's': 'm',
    'c_theta': 'N m/rad', 'c_psi': 'N m/rad', 'K_S': 'N m/rad', 'K_D': 'N m s/rad',
    'Omega0': 'rad/s', 'pole_pairs': '1',
}

PARAM_DESCRIPTIONS = {
    'A_R': 'transverse moment of inertia of the rotor about the fixed point F',
    'A_M': 'transverse moment of inertia of the motor stator (housing) about F',
    'C_R': 'polar moment of inertia of the rotor about the symmetry axis',
    'C_M': 'polar moment of inertia of the stator about the symmetry axis',
    'G': 'total weight',
    's': 'distance from the fixed point F to the centre of gravity S (S above F if > 0)',
    'c_theta': 'restraint stiffness against tilt theta of the symmetry axis',
    'c_psi': 'restraint stiffness against twist chi = phi_M + psi of the housing',
    'K_S': 'drive stiffness (synchronous coupling of the rotor to the rotating field)',
    'K_D': 'drive damping',
    'Omega0': 'speed of the rotating field relative to the stator',
    'pole_pairs': '0 = linear drive law (eq. 23); p > 0 = sine law with pull-out torque K_S/p',
}


@dataclasses.dataclass(frozen=True)
class RotorParams:
    """Validated, immutable parameters of the gyrostat and its drive (see module doc)."""

    A_R: float = 0.05
    A_M: float = 0.08
    C_R: float = 0.02
    C_M: float = 0.01
    G: float = 98.1
    s: float = 0.05
    c_theta: float = 50.0
    c_psi: float = 20.0
    K_S: float = 20.0
    K_D: float = 0.05
    Omega0: float = 314.16
    pole_pairs: int = 0

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            if f.name == 'pole_pairs':
                continue
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                raise ParameterError(
                    f'parameter {f.name} must be a real number, got {value!r}')
            value = float(value)
            if not math.isfinite(value):
                raise ParameterError(f'parameter {f.name} must be finite, got {value!r}')
            if abs(value) > MAX_MAGNITUDE:
                raise ParameterError(
                    f'parameter {f.name} = {value!r} is outside the supported range '
                    f'|{f.name}| <= {MAX_MAGNITUDE:g} {PARAM_UNITS[f.name]}')
            object.__setattr__(self, f.name, value)
        for name in ('A_R', 'A_M', 'C_R', 'C_M'):
            if getattr(self, name) <= 0.0:
                raise ParameterError(
                    f'inertia {name} must be positive, got {getattr(self, name)!r} kg m^2')
        for name in ('G', 'c_theta', 'c_psi', 'K_S', 'K_D'):
            if getattr(self, name) < 0.0:
                raise ParameterError(
                    f'parameter {name} must not be negative, got {getattr(self, name)!r} '
                    f'{PARAM_UNITS[name]}')
        p = self.pole_pairs
        if isinstance(p, bool) or not isinstance(p, numbers.Real):
            raise ParameterError(f'pole_pairs must be a non-negative integer, got {p!r}')
        if not math.isfinite(float(p)) or float(p) != int(p) or p < 0:
            raise ParameterError(f'pole_pairs must be a non-negative integer, got {p!r}')
        object.__setattr__(self, 'pole_pairs', int(p))
        if self.c_theta <= self.G * self.s:
            warnings.warn(
                f'c_theta = {self.c_theta} N m/rad <= G s = {self.G * self.s} N m: the '
                f'restraint cannot hold the axis statically; only the gyroscopic stiffness '
                f'of the spinning rotor can', StaticallyUnstableWarning, stacklevel=3)

    # -- derived quantities -------------------------------------------------------------
    @property
    def I(self) -> float:  # noqa: E743 -- the paper's symbol I = A_R + A_M
        """Total transverse moment of inertia I = A_R + A_M about F."""
        return self.A_R + self.A_M

    @property
    def drive_law(self) -> DriveLaw:
        """LINEAR for pole_pairs == 0, else SINE."""
        return DriveLaw.LINEAR if self.pole_pairs == 0 else DriveLaw.SINE

    @property
    def Gs(self) -> float:
        """Return the static tilt moment coefficient G s [N m]."""
        return self.G * self.s

    # -- conversions ---------------------------------------------------------------------
    def replace(self, **changes: Any) -> 'RotorParams':
        """Return a copy with some fields changed (validated again)."""
        unknown = set(changes) - set(PARAM_FIELDS)
        if unknown:
            raise ParameterError(_unknown_message(sorted(unknown)[0]))
        return dataclasses.replace(self, **changes)

    def to_mapping(self) -> dict:
        """Return the parameters as a plain dict (name -> value)."""
        return dataclasses.asdict(self)


PARAM_FIELDS = tuple(f.name for f in dataclasses.fields(RotorParams))


def _unknown_message(key: str) -> str:
    hint = did_you_mean(key, PARAM_FIELDS) or f'; valid: {", ".join(PARAM_FIELDS)}'
    return f"unknown parameter '{key}'{hint}"
