"""Exceptions of gyro_rotor.

Each subclasses a built-in category as well (python-control's ``exception.py``), so a
caller may catch either ``GyroRotorError`` or the usual ``ValueError``/``RuntimeError``.
The command line catches ``GyroRotorError`` only at its boundary, prints ``ERROR: ...``
and exits non-zero.
"""

__all__ = [
    'GyroRotorError', 'ParameterError', 'SceneError', 'NoSteadyMotionError',
    'IntegrationError', 'BagError', 'AnalysisError',
]


class GyroRotorError(Exception):
    """Base class of every error that gyro_rotor raises on purpose."""


class ParameterError(GyroRotorError, ValueError):
    """A physical or numerical parameter is invalid; the message names field and value."""


class SceneError(GyroRotorError, ValueError):
    """A scene file is malformed, has an unknown key or a value of the wrong type."""


class NoSteadyMotionError(GyroRotorError, ValueError):
    """No steady motion II exists for the requested tilt (negative discriminant)."""


class IntegrationError(GyroRotorError, RuntimeError):
    """The integration failed: non-finite state, step size underflow, divergence."""


class BagError(GyroRotorError, RuntimeError):
    """A bag cannot be written or read: the message names the path and the problem."""


class AnalysisError(GyroRotorError, RuntimeError):
    """An analysis cannot be carried out on the given data."""
