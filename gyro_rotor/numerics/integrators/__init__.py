"""Integrators for the gyrostat: one interface, ten methods, compiled inner loops.

See :mod:`gyro_rotor.numerics.integrators.base` for the contract (scipy's OdeSolver shape),
:mod:`gyro_rotor.numerics.integrators.methods` for the methods and :func:`integrate`,
:mod:`gyro_rotor.numerics.integrators.tableaux` for their coefficients and
:mod:`gyro_rotor.numerics.integrators.kernels` for the compiled loops (numba if installed).
"""

from gyro_rotor.numerics.integrators.base import (IntegrationResult, Integrator, model_rate,
                                                  STATUS_MESSAGES)
from gyro_rotor.numerics.integrators.kernels import HAVE_NUMBA, rk_generated
from gyro_rotor.numerics.integrators.methods import (cheapest_explicit, choose_method,
                                                     COST_METHODS, DOP853, Gauss6, integrate,
                                                     make_integrator, method_cost, METHODS,
                                                     Radau9, RK4, RK8, Rodas4, Split8, Vern7,
                                                     Vern8, Vern9)

__all__ = ['Integrator', 'IntegrationResult', 'STATUS_MESSAGES', 'METHODS', 'RK4', 'RK8',
           'DOP853', 'Vern7', 'Vern8', 'Vern9', 'Gauss6', 'Rodas4', 'Radau9', 'Split8',
           'integrate', 'choose_method', 'cheapest_explicit', 'method_cost', 'COST_METHODS',
           'make_integrator', 'model_rate', 'HAVE_NUMBA', 'rk_generated']
