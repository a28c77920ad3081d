"""Exceptions of gyro_rotor.

Each subclasses a built-in category as well (python-control's ``exception.py``), so a
caller may catch either ``GyroRotorError`` or the usual ``ValueError``/``RuntimeError``.
The command line catches ``GyroRotorError`` only at its boundary, prints ``ERROR: ...``
and exits non-zero.
"""

__all__ = [
    'GyroRotorError', 'ParameterError', 'NotApplicableError', 'SceneError', 'NotSteadyError',
    'SystemFileError', 'NoSteadyMotionError', 'IntegrationError', 'BagError', 'AnalysisError',
]


class GyroRotorError(Exception):
    """Base class of every error that gyro_rotor raises on purpose."""


class ParameterError(GyroRotorError, ValueError):
    """A physical or numerical parameter is invalid; the message names field and value."""


class NotApplicableError(ParameterError):
    """A value was given that the system does not have; the message begins with its name.

    The centrifuge's tilt theta0 for a system file, a rotor to vary for the centrifuge's
    one drive; the command line names its option there.
    """


class SceneError(GyroRotorError, ValueError):
    """A scene file is malformed, has an unknown key or a value of the wrong type."""


class NotSteadyError(SceneError):
    """A system file's scene whose steady motion is not one: the accelerations do not vanish.

    ``scene``: the scene's path or name; the command line names the command that solves
    for a steady motion from the scene's guess.
    """

    def __init__(self, message: str, scene: str = ''):
        super().__init__(message)
        self.scene = scene

    def __reduce__(self):
        return type(self), (str(self), self.scene)


class SystemFileError(GyroRotorError, ValueError):
    """A system file (a rotor system of the general theory) is malformed: names file and key."""


class NoSteadyMotionError(GyroRotorError, ValueError):
    """No steady motion II exists for the requested tilt (negative discriminant)."""


class IntegrationError(GyroRotorError, RuntimeError):
    """The integration failed: non-finite state, step size underflow, divergence."""


class BagError(GyroRotorError, RuntimeError):
    """A bag cannot be written or read: the message names the path and the problem."""


class AnalysisError(GyroRotorError, RuntimeError):
    """An analysis cannot be carried out on the given data."""


def did_you_mean(key: str, valid) -> str:
    """``"; did you mean 'X'?"`` for the nearest valid name (case and _ ignored first), or ''."""
    import difflib
    valid = list(valid)

    def norm(name: str) -> str:
        return name.lower().replace('_', '').replace('-', '')
    for v in valid:
        if norm(v) == norm(key):
            return f"; did you mean '{v}'?"
    near = difflib.get_close_matches(key, valid, n=1, cutoff=0.6)
    return f"; did you mean '{near[0]}'?" if near else ''
