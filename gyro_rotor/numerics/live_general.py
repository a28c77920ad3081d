"""The live simulation of any rotor system (a general scene): pure Python, no rclpy.

:class:`GeneralLiveSimulation` is :class:`~gyro_rotor.numerics.live.LiveSimulation` (the
pacer, the work budget, the divergence guard, the services' actions, the diagnostics) on a
:class:`~gyro_rotor.core.system.scene.GeneralScene`. What differs:

* **outputs** (:class:`~gyro_rotor.numerics.live.SampleBlock`): the joint columns are the
  system's coordinates q and the rotor lags z_ROTOR = phi - Omega0 t (eq. 7, the
  coordinates in which the paper states the theorem), positions and rates as integrated
  (not wrapped: a lag or a coordinate may pass pi); no efforts and no 3-D pose. (The
  field angle advances at Omega0; after a live Omega0 change z is phi minus that angle,
  continuous, no longer phi - Omega0 t.) The
  ``energy`` fields are :data:`GENERAL_ENERGY_FIELDS`: E* (eq. 13), dE*/dt = -sum K_D
  zdot^2 (eq. 17), the dissipation, the residual, the sample counter, D and the grid index;
  z and zdot are in ``joint_states``;
* **parameters**: ``constants.NAME``, ``drive.ROTOR.KEY`` and the keys K_S, K_D, Omega0,
  pole_pairs for every drive, validated by rebuilding the scene
  (:meth:`GeneralScene.with_changes`: positive definite mass matrix, steady motion still
  steady) and the integrator at the current state; applied, the state is kept (an Omega0
  change keeps each rotor's absolute spin: zdot jumps by -delta Omega0) and E*'s baseline
  moves by the jump of E*;
* **kicks** (``~/perturb``): ``perturbation.q``, ``.qdot``, ``.z``, ``.zdot`` are added to
  the state (lists of n, n, m, m numbers, n the system file's coordinates as for
  ``initial.q``: a locked coordinate's entry must be 0);
* **methods**: those of :mod:`gyro_rotor.numerics.general` (``auto``: rodas4 for a stiff
  drive, dop853 otherwise, from the linearization at the current state).
"""

from __future__ import annotations

import math
from typing import Any, Mapping

from gyro_rotor.core.scene import Scene
from gyro_rotor.core.system.model import GeneralModel
from gyro_rotor.core.system.system_file import DRIVE_KEYS
from gyro_rotor.errors import ParameterError, SceneError
from gyro_rotor.numerics.general import choose_method, KernelSystem, METHODS
from gyro_rotor.numerics.live import LiveSimulation, SampleBlock
from gyro_rotor.numerics.realtime import make_stepper
import numpy as np

__all__ = ['GeneralLiveSimulation', 'GENERAL_ENERGY_FIELDS', 'general_joint_names',
           'GENERAL_PERTURBATION_KEYS', 'is_physical_key']

#: the ``energy`` fields of a general system (z and zdot of each rotor are joints)
GENERAL_ENERGY_FIELDS = ('t_sim', 'E_star', 'dE_dt', 'dissipation', 'residual', 'seq', 'D',
                         'k')
#: the parts of the state a kick (``perturbation.KEY``) adds to: lengths n, n, m, m
GENERAL_PERTURBATION_KEYS = ('q', 'qdot', 'z', 'zdot')


def general_joint_names(coordinates, rotors) -> tuple:
    """Joint names of a general system: its coordinates, then z_ROTOR for each rotor."""
    return tuple(coordinates) + tuple(f'z_{r}' for r in rotors)


def is_physical_key(key: str) -> bool:
    """Return True for a key that changes the system's numbers (constants, drives)."""
    return key in DRIVE_KEYS or key.startswith(('constants.', 'drive.'))


class GeneralLiveSimulation(LiveSimulation):
    """A general scene integrated in real time (module doc; the API of LiveSimulation)."""

    energy_fields = GENERAL_ENERGY_FIELDS

    def __init__(self, scene: Scene, cfg: Mapping[str, Any],
                 perturbation: Mapping[str, Any] | None = None, **kwargs: Any):
        # kicks of q and qdot name every coordinate of the system file, as initial.q does;
        # a locked coordinate's entry must be 0
        n, m = scene.full_system.n, scene.system.m
        self._sizes = dict(zip(GENERAL_PERTURBATION_KEYS, (n, n, m, m)))
        self._free = [i for i, c in enumerate(scene.full_system.coordinates)
                      if c not in scene.locked]
        self.scene_coordinates = scene.full_system.coordinates
        self.joint_names = general_joint_names(scene.system.coordinates, scene.system.rotors)
        kick = {k: [0.0] * self._sizes[k] for k in GENERAL_PERTURBATION_KEYS}
        self._kick_values = kick
        for k, v in (perturbation or {}).items():
            self._set_perturbation(k, v)
        super().__init__(scene, cfg, {}, **kwargs)
        self.perturbation = self._kick_values

    # -- hooks of LiveSimulation -------------------------------------------------------------
    def _resolve(self, method: str, model: GeneralModel, y: np.ndarray, t_end: float) -> tuple:
        if method != 'auto':
            return method, 'requested'
        return choose_method(model, y)

    def _make_stepper(self, method: str, model: GeneralModel, t: float, y: np.ndarray,
                      cfg: Mapping):
        if method not in METHODS:
            raise ParameterError(f"integrator '{method}': general systems integrate with "
                                 f"auto, {', '.join(METHODS)}")
        return make_stepper(method, model.rhs, t, y, rtol=cfg['rtol'], atol=cfg['atol'],
                            step_size=cfg['step_size'], model=KernelSystem(model))

    def _changed_scene(self, changes: Mapping[str, Any]) -> Scene | None:
        phys = {k: v for k, v in changes.items() if is_physical_key(k)}
        if not phys:
            return None
        try:
            return self.scene.with_changes(phys)
        except SceneError as err:
            raise ParameterError(str(err)) from None

    def _model_of(self, scene: Scene) -> GeneralModel:
        return scene.make_model()

    def _jump(self, model: GeneralModel, t: float, y: np.ndarray) -> np.ndarray:
        """Keep each rotor's absolute spin: zdot_k jumps by -(Omega0_k new - old)."""
        old = np.array([d.Omega0 for d in self.model.system.drives])
        new = np.array([d.Omega0 for d in model.system.drives])
        y = y.copy()
        y[model.slices()[3]] -= new - old
        return y

    def _set_perturbation(self, key: str, value: Any) -> None:
        if key not in self._sizes:
            raise ParameterError(f"unknown key 'perturbation.{key}': a general scene kicks "
                                 f"perturbation.{', perturbation.'.join(self._sizes)}")
        try:      # a list, a tuple, or the array.array('d') of a ROS double-array parameter
            v = [float(x) for x in np.atleast_1d(np.asarray(value, dtype=float))]
        except (TypeError, ValueError):
            v = []
        size = self._sizes[key]
        if len(v) != size or not all(math.isfinite(x) for x in v):
            raise ParameterError(f'perturbation.{key} must be {size} finite numbers, got '
                                 f'{list(value) if hasattr(value, "__len__") else value!r}')
        if key in ('q', 'qdot'):
            held = [c for i, c in enumerate(self.scene_coordinates) if i not in self._free
                    and v[i] != 0.0]
            if held:
                raise ParameterError(f'perturbation.{key}: the locked coordinate '
                                     f'{held[0]} cannot be kicked (its entry must be 0)')
        self._kick_values[key] = v

    def check(self, changes: Mapping[str, Any]) -> None:
        """Raise a GyroRotorError if the changes cannot be applied (see LiveSimulation)."""
        for k, v in changes.items():
            if k.startswith('perturbation.'):
                keep = dict(self._kick_values)
                try:
                    self._set_perturbation(k.split('.', 1)[1], v)
                finally:
                    self._kick_values.clear()
                    self._kick_values.update(keep)
        super().check(changes)

    def _kicked(self, y: np.ndarray) -> np.ndarray:
        y = np.array(y, dtype=float)
        for k, sl in zip(GENERAL_PERTURBATION_KEYS, self.model.slices()):
            kick = np.asarray(self._kick_values[k])
            y[sl] += kick[self._free] if k in ('q', 'qdot') else kick
        return y

    def _with_t_end(self, scene: Scene, t_end: float) -> Scene:
        return scene.with_t_end(t_end)

    def _norm_error(self, y: np.ndarray) -> float:
        return 0.0

    def _outputs(self, samples, t, Y, E, resid, p) -> SampleBlock:
        m = self.model
        sq, sqd, sz, szd = m.slices()
        zdot = Y[:, szd]
        diss = m.dissipation(Y)
        n = len(t)
        energy = {'t_sim': t, 'E_star': E, 'dE_dt': -diss, 'dissipation': diss,
                  'residual': resid,
                  'seq': np.arange(self.seq, self.seq + n, dtype=float), 'D': Y[:, m.iD],
                  'k': np.fromiter((s.k for s in samples), float, n)}
        self.seq += n
        self.last = (samples[-1].t, samples[-1].y)
        return SampleBlock(t=t, position=np.column_stack([Y[:, sq], Y[:, sz]]),
                           velocity=np.column_stack([Y[:, sqd], zdot]),
                           effort=np.zeros((n, 0)), energy=energy, quaternion=None,
                           axis=None)

    def _initial_doc(self) -> dict[str, Any]:
        sc = self.scene
        return {'q': list(sc.q0), 'qdot': list(sc.qdot0), 'z': list(sc.z0),
                'zdot': list(sc.zdot0)}

    def scene_doc(self) -> dict[str, Any]:
        """Return the current scene as a document (the node's ``~/scene``).

        ``flat`` holds the scene's keys with the system file's document embedded
        (:func:`~gyro_rotor.core.scene.Scene.to_flat`): a reader rebuilds
        the scene without the file.
        """
        sc = self.scene
        return {'scene': sc.name, 'system': sc.system.name, 't_end': sc.t_end,
                'constants': dict(sc.full_system.constants),
                'drives': {r: {k: getattr(d, k) for k in DRIVE_KEYS}
                           for r, d in zip(sc.system.rotors, sc.system.drives)},
                'joint_names': list(self.joint_names), 'initial': self._initial_doc(),
                'perturbation': self._kick_values, 'node': self.cfg,
                'integrator': self.stepper.method, 't_sim': self.stepper.t,
                'path': sc.path, 'flat': sc.to_flat()}
