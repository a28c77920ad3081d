"""Defaults shared by the offline runs (:mod:`~gyro_rotor.numerics.simulate`) and the live pacing.

(:mod:`~gyro_rotor.numerics.realtime`): one place for the tolerances and the scipy baselines.
"""

__all__ = ['DEFAULT_RTOL', 'DEFAULT_ATOL', 'SCIPY_METHODS', 'DEFAULT_RATE']

#: default tolerances of the adaptive methods (every shipped scene accurate to 1e-8 or better,
#: test/test_accuracy.py)
DEFAULT_RTOL = 1e-11
DEFAULT_ATOL = 1e-12
#: scipy ``solve_ivp`` methods (``OdeSolver`` classes), selectable by their names as baselines
SCIPY_METHODS = ('DOP853', 'RK45', 'RK23', 'Radau', 'BDF', 'LSODA')
#: default output sample rate of an offline run [Hz] (``gyro-rotor simulate --rate``)
DEFAULT_RATE = 100.0
