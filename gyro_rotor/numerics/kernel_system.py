"""The compiled kernels' view of any model: a hand-written one as it is, a system file's wrapped.

The generated equations of a system (:mod:`gyro_rotor.core.system.codegen`) provide only
the right-hand side; the integration loops are the project's own compiled kernels
(:mod:`gyro_rotor.numerics.integrators.kernels`), which take the generated ``rhs`` as a
numba first-class function in place of a model number. :class:`KernelSystem` presents a
:class:`~gyro_rotor.core.system.model.GeneralModel` to them (state size, parameter array,
fastest rate); :func:`kernel_model` gives the view of any model, the one
:func:`gyro_rotor.numerics.simulate.integrate`, :func:`gyro_rotor.numerics.ensemble.run_ensemble`
and the live simulation hand to the integrators.

Methods of every model (:data:`SYSTEM_METHODS`): those whose kernels need nothing but the
right-hand side, and radau9, which for a generated system is Radau IIA with the generated
exact Jacobian (:mod:`~gyro_rotor.numerics.integrators.radau_jac`; ``kernel_jac``); a
model adds its own symplectic method (:func:`methods_for`).
"""

from __future__ import annotations

from gyro_rotor.core.model import Model
from gyro_rotor.core.system.codegen import pack
from gyro_rotor.core.system.model import GeneralModel, system_rate
from gyro_rotor.core.system.system_file import RotorSystem
from gyro_rotor.errors import ParameterError
from gyro_rotor.numerics.integrators import METHODS
import numpy as np

__all__ = ['KernelSystem', 'SYSTEM_METHODS', 'kernel_model', 'methods_for']

#: the project's integrators that need nothing but the right-hand side, and radau9 with the
#: generated exact Jacobian (:mod:`~gyro_rotor.numerics.integrators.radau_jac`)
SYSTEM_METHODS = ('dop853', 'vern7', 'vern8', 'vern9', 'radau9', 'rodas4', 'rk4', 'rk8',
                  'gauss6')


class KernelSystem:
    """A general model as the kernels see it: ``kernel_rhs``, ``kernel_jac``, ``pack``, ...

    (and ``rate``, ``n``).
    """

    def __init__(self, model: GeneralModel):
        """Wrap ``model``; its system is the default parameter set (``params``)."""
        self.model = model
        self.params = model.system
        self.n = model.size
        self.name = f'system {model.system.name}'
        self.kernel_rhs = model.compiled.first_class

    @property
    def kernel_jac(self):
        """Return the generated exact Jacobian, a first-class function (compiled at first use)."""
        return self.model.compiled.jac_first_class

    def pack(self, system: RotorSystem) -> np.ndarray:
        """Parameter array of ``system`` (same structure as the model's, other numbers)."""
        if system is self.params:
            return self.model.P
        if not isinstance(system, RotorSystem) or \
                system.structure_key() != self.params.structure_key():
            raise ParameterError(f'{self.name}: every parameter set must be the same system '
                                 f'with other numbers (constants, drives), got {system!r:.80}')
        return pack(system)

    def rate(self, system: RotorSystem) -> float:
        """Fastest rate [1/s] for the default step sizes."""
        return system_rate(system)


def kernel_model(model: Model | GeneralModel | KernelSystem):
    """Return what the kernels take for ``model``: a hand-written model or a KernelSystem."""
    return KernelSystem(model) if isinstance(model, GeneralModel) else model


def methods_for(model) -> tuple:
    """Return the project's integration methods ``model`` offers (in the integrators' order).

    Those of :data:`SYSTEM_METHODS`, which need nothing but the right-hand side (and a
    generated system's exact Jacobian), and the model's own symplectic method
    (``symplectic_method``: split8, the exact sub-flows of the centrifuge's full model).
    """
    return tuple(n for n in METHODS if n in SYSTEM_METHODS or n == model.symplectic_method)
