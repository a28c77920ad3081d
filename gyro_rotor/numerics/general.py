"""General rotor systems on the project's integrators and ensemble (issue 15).

The generated equations of a system (:mod:`gyro_rotor.core.system.codegen`) provide only
the right-hand side; the integration loops are the project's own compiled kernels
(:mod:`gyro_rotor.numerics.integrators.kernels`), which take the generated ``rhs`` as a
numba first-class function in place of a model number. :class:`KernelSystem` presents a
:class:`~gyro_rotor.core.system.model.GeneralModel` to them (state size, parameter array,
fastest rate); :func:`integrate` and :func:`run_ensemble` are the entry points.

Methods (:data:`METHODS`): those whose kernels need nothing but the right-hand side, and
radau9, which for a generated system is Radau IIA with the generated exact Jacobian
(:mod:`~gyro_rotor.numerics.integrators.radau_jac`; ``kernel_jac`` of :class:`KernelSystem`).
``auto`` is the one rule of every system
(:func:`gyro_rotor.numerics.integrators.methods.choose_method`): radau9 when the drive
damping root K_D lambda_max(Mbar^-1 on z) exceeds the fastest oscillation of the
conservative linearization at the initial state by
:data:`~gyro_rotor.numerics.integrators.methods.STIFF_RATIO` (its cost then does not
depend on K_D: ``gyro-rotor bench-general``, stiff table), else the cheapest explicit pair
by the measured cost model.
"""

from __future__ import annotations

import dataclasses
import math

from gyro_rotor.core.system.codegen import pack
from gyro_rotor.core.system.model import GeneralModel, system_rate
from gyro_rotor.core.system.system_file import RotorSystem
from gyro_rotor.errors import IntegrationError, ParameterError
from gyro_rotor.numerics import ensemble
from gyro_rotor.numerics.integrators import methods
import numpy as np

__all__ = ['KernelSystem', 'GeneralRun', 'integrate', 'run_ensemble', 'METHODS']

#: the project's integrators that need nothing but the right-hand side, and radau9 with the
#: generated exact Jacobian (:mod:`~gyro_rotor.numerics.integrators.radau_jac`)
METHODS = ('dop853', 'vern7', 'vern8', 'vern9', 'radau9', 'rodas4', 'rk4', 'rk8', 'gauss6')


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


@dataclasses.dataclass
class GeneralRun:
    """Samples of one run: times ``t`` (k,), states ``y`` (k, 2 N + 1) and the counters."""

    t: np.ndarray
    y: np.ndarray
    method: str
    nfev: int
    nsteps: int
    nrejected: int


def integrate(model: GeneralModel, y0, t_eval, *, method: str = 'auto', rtol: float = 1e-9,
              atol: float = 1e-12, step: float | None = None,
              max_steps: int = 50_000_000) -> GeneralRun:
    """Integrate from ``y0`` at ``t_eval[0]``, sampled at ``t_eval`` (2 or more times).

    Raises :class:`IntegrationError` if the run stops early (the message says why).
    """
    y0 = np.asarray(y0, dtype=float).reshape(-1)
    te = np.asarray(t_eval, dtype=float).reshape(-1)
    if y0.size != model.size or not np.all(np.isfinite(y0)):
        raise ParameterError(f'the initial state must be {model.size} finite numbers, got '
                             f'{y0.tolist()}')
    if te.size < 2 or not np.all(np.isfinite(te)) or np.any(np.diff(te) <= 0):
        raise ParameterError('t_eval must be a finite, increasing array of 2 or more times')
    if method == 'auto':
        method = methods.choose_method(model, te[-1] - te[0], rtol, 0.0, y0)[0]
    if method not in METHODS:
        raise ParameterError(f"general systems integrate with auto, {', '.join(METHODS)}; "
                             f'got {method!r}')
    res = methods.integrate(KernelSystem(model), y0, (te[0], te[-1]), te, method=method,
                            rtol=rtol, atol=atol, step=step, max_steps=max_steps)
    if not res.success:
        last = res.t[-1] if res.t.size else te[0]
        raise IntegrationError(f'system {model.system.name} ({method}): the integration '
                               f'stopped after t = {last:.6g} s: {res.message}')
    return GeneralRun(t=res.t, y=res.y, method=method, nfev=res.nfev, nsteps=res.nsteps,
                      nrejected=res.nrejected)


def run_ensemble(model: GeneralModel, Y0, t_eval, *, systems: list | None = None,
                 method: str = 'rk4', step: float | None = None) -> ensemble.EnsembleResult:
    """Run N trajectories of a general system in lockstep (the project's ensemble).

    ``systems``: one :class:`RotorSystem` per trajectory (the model's system with other
    constants or drives), or None for the model's own numbers.
    """
    if step is not None and not (math.isfinite(step) and step > 0):
        raise ParameterError(f'step must be positive and finite, got {step!r}')
    return ensemble.run_ensemble(KernelSystem(model), Y0, t_eval, method=method, step=step,
                                 params=systems, backend='numba', renormalize=False)
