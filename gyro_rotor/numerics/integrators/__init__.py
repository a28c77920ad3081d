"""Integrators for the gyrostat: one interface, seven methods, compiled inner loops.

See :mod:`gyro_rotor.numerics.integrators.base` for the contract (scipy's OdeSolver shape),
:mod:`gyro_rotor.numerics.integrators.methods` for the methods and :func:`integrate`,
:mod:`gyro_rotor.numerics.integrators.tableaux` for their coefficients and
:mod:`gyro_rotor.numerics.integrators.kernels` for the compiled loops (numba if installed).
"""

from gyro_rotor.numerics.integrators.base import (IntegrationResult, Integrator, model_rate,
                                                  STATUS_MESSAGES)
from gyro_rotor.numerics.integrators.kernels import HAVE_NUMBA
from gyro_rotor.numerics.integrators.methods import (choose_method, DOP853, Gauss6, integrate,
                                                     make_integrator, METHODS, Radau9, RK4, RK8,
                                                     Rodas4, Split8)

__all__ = ['Integrator', 'IntegrationResult', 'STATUS_MESSAGES', 'METHODS', 'RK4', 'RK8',
           'DOP853', 'Gauss6', 'Rodas4', 'Radau9', 'Split8', 'integrate', 'choose_method',
           'make_integrator', 'model_rate', 'HAVE_NUMBA']
