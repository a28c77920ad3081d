"""The built-in system ``centrifuge`` as a scene sets it up (Magnus 1980, section 4).

The elastically restrained centrifuge of section 4 is the package's one hand-written
system: a quaternion model, regular at theta = 0 (:mod:`gyro_rotor.core.model`), its
reduced models (upright axis, locked housing) and its steady motions in closed form
(:mod:`gyro_rotor.core.steady`). :class:`Centrifuge` holds what a scene gives it: the
parameters (:class:`~gyro_rotor.core.params.RotorParams`), the model that runs it and the
initial condition. A system file's scene holds a
:class:`~gyro_rotor.core.system.generated.GeneratedSystem` instead; the two present the
same interface, so :class:`~gyro_rotor.core.scene.Scene` asks its system and never which
one it is. The scene file's keys are in the module doc of :mod:`gyro_rotor.core.scene`.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, ClassVar, Iterator, Mapping
import warnings

from gyro_rotor.core.linearize import analytic_parts, linearize, LinearParts
from gyro_rotor.core.model import drive_rates, make_model, Model, MODELS, PERTURBATION_KEYS
from gyro_rotor.core.newton import SteadyMotions
from gyro_rotor.core.param_spec import ParamSpec
from gyro_rotor.core.params import PARAM_DESCRIPTIONS, PARAM_FIELDS, PARAM_UNITS, RotorParams
from gyro_rotor.core.peer_equations import PeerEquations
from gyro_rotor.core.steady import steady_motion, SteadyMotion
from gyro_rotor.core.yamlio import short
from gyro_rotor.errors import (did_you_mean, GyroRotorError, NoSteadyMotionError,
                               NotApplicableError, ParameterError, SceneError)
from gyro_rotor.node_settings import NODE_KEYS
import numpy as np

__all__ = ['Centrifuge', 'InitialCondition', 'INITIAL_UNITS', 'CENTRIFUGE', 'SCENE_KEYS',
           'SWEEP_KEYS']

#: the built-in system's name: ``system: centrifuge`` in a scene file
CENTRIFUGE = 'centrifuge'

#: SI units of the centrifuge's numeric initial-condition keys (module doc of core.scene)
INITIAL_UNITS = {'theta0': 'rad', 'dtheta': 'rad', 'dthetadot': 'rad/s', 'dpsidot': 'rad/s',
                 'dchi': 'rad', 'dz': 'rad', 'dzdot': 'rad/s', 'z': 'rad', 'zdot': 'rad/s',
                 'chi': 'rad', 'branch': '-'}

#: keys of a centrifuge scene (module doc of :mod:`gyro_rotor.core.scene`)
SCENE_KEYS: dict[str, type] = {
    'scene': str, 'description': str, 'system': str, 'model': str, 't_end': float,
    **{name: (int if name == 'pole_pairs' else float) for name in PARAM_FIELDS},
    'initial.mode': str, 'initial.branch': int, 'initial.quaternion': list,
    'initial.omega_body': list,
    **{f'initial.{k}': float for k in INITIAL_UNITS if k != 'branch'},
    **{f'perturbation.{k}': float for k in PERTURBATION_KEYS},
    **{name: spec[0] for name, spec in NODE_KEYS.items()},
}
#: the keys a sweep's grid may run over: the parameters and numeric initial conditions
SWEEP_KEYS = tuple(PARAM_FIELDS) + tuple(f'initial.{k}' for k in INITIAL_UNITS)


#: documentation of the initial-condition parameters of rotor_sim
_INITIAL_DOC = {
    'mode': 'initial condition: steady (on a steady motion) or body (quaternion, rates)',
    'theta0': 'tilt of the steady motion [rad]', 'branch': 'steady motion: 0 = solution I, '
    '1 = precession, 2 = nutation branch', 'dtheta': 'offset of theta [rad]',
    'dthetadot': 'offset of thetadot [rad/s]', 'dpsidot': 'offset of psidot [rad/s]',
    'dchi': 'offset of the twist chi [rad]', 'dz': 'offset of z [rad]',
    'dzdot': 'offset of zdot [rad/s]', 'quaternion': 'stator quaternion [w, x, y, z]',
    'omega_body': 'stator body rates [rad/s]', 'z': 'rotor lag z [rad]',
    'zdot': 'rate of z [rad/s]', 'chi': 'twist chi [rad]',
}


@dataclasses.dataclass(frozen=True)
class InitialCondition:
    """Initial condition of a centrifuge scene (module doc of :mod:`gyro_rotor.core.scene`)."""

    mode: str = 'steady'
    theta0: float = 0.0
    branch: int = 0
    dtheta: float = 0.0
    dthetadot: float = 0.0
    dpsidot: float = 0.0
    dchi: float = 0.0
    dz: float = 0.0
    dzdot: float = 0.0
    quaternion: tuple = (1.0, 0.0, 0.0, 0.0)
    omega_body: tuple = (0.0, 0.0, 0.0)
    z: float = 0.0
    zdot: float = 0.0
    chi: float | None = None


@dataclasses.dataclass(frozen=True)
class Centrifuge:
    """The built-in centrifuge with a scene's numbers (module doc).

    ``params``: the parameters; ``model``: the model that runs it (``full``,
    ``upright_axis``, ``locked_housing``); ``initial``: the initial condition.
    """

    params: RotorParams
    model: str = 'full'
    initial: InitialCondition = InitialCondition()

    #: the system's name in a scene file
    name: ClassVar[str] = CENTRIFUGE
    #: the hand-written built-in system (a system file's is generated)
    builtin: ClassVar[bool] = True
    #: the system as its file defines it: none, it is built in
    base: ClassVar[None] = None

    @property
    def peer_equations(self) -> PeerEquations | None:
        """Return which equations the benchmark's compiled peers copy (None: no copy).

        The full model's (:attr:`PeerEquations.CENTRIFUGE_FULL`); its other models have none.
        """
        return PeerEquations.CENTRIFUGE_FULL if self.model == 'full' else None

    @property
    def pole_pairs(self) -> tuple:
        """Pole pairs of the rotor's drive (0: linear law), one per rotor."""
        return (int(self.params.pole_pairs),)

    @property
    def Omega0(self) -> float:
        """Return the drive's field speed Omega0 [rad/s] (eq. 23)."""
        return float(self.params.Omega0)

    @property
    def joint_names(self) -> tuple:
        """Return the joint_states names of its models (theta, psi, phi_R, phi_M)."""
        return Model.joint_names

    def physics(self) -> list:
        """Return (name, value) of its parameters, model and initial condition."""
        return ([(f, getattr(self.params, f)) for f in PARAM_FIELDS] + [('model', self.model)]
                + [(f'initial.{f.name}', getattr(self.initial, f.name))
                   for f in dataclasses.fields(InitialCondition)])

    def make_model(self) -> Model:
        """Return the model that runs it."""
        return make_model(self.model, self.params)

    def with_params(self, **changes: Any) -> 'Centrifuge':
        """Copy with some parameters changed (validated)."""
        return dataclasses.replace(self, params=self.params.replace(**changes))

    def steady(self) -> SteadyMotion:
        """Return the steady motion the initial condition refers to (eqs. 20-22)."""
        ic = self.initial
        if ic.mode != 'steady':
            return steady_motion(self.params, 0.0, 0)
        return steady_motion(self.params, ic.theta0, ic.branch)

    def steady_motions(self, theta0: float | None, scene: str = '') -> SteadyMotions:
        """Return solutions I and II (both branches) in closed form, exact and by eq. (22).

        ``theta0``: the tilt of II (default: the initial condition's, else 0.1).
        """
        p = self.params
        if theta0 is None:
            theta0 = self.initial.theta0 if self.initial.theta0 > 0 else 0.1
        lines = ['I:  theta = 0, psidot = 0, rotor at Omega0 about the vertical, housing at rest']
        found = True
        for branch in (1, 2):
            try:
                sm = steady_motion(p, theta0, branch)
            except NoSteadyMotionError as err:
                lines.append(f'II branch {branch}: {err}')
                found = False
                continue
            eq22 = (f'eq. (22) corrected: {sm.psidot0_eq22:.12g} rad/s; relative difference '
                    f'{sm.relative_difference:+.3e}' if math.isfinite(sm.psidot0_eq22) else
                    'eq. (22) corrected: not defined here (no real root, or cos(theta0) = 0)')
            lines.append(f'{sm.name}: theta0 = {sm.theta0:.6g} rad, psidot0 = '
                         f'{sm.psidot0:.12g} rad/s (exact); {eq22}')
        return SteadyMotions(f'Omega0 = {p.Omega0:g} rad/s, I = {p.I:g} kg m^2, C_R = '
                             f'{p.C_R:g}, G s = {p.Gs:g} N m, c_theta = {p.c_theta:g} N m/rad',
                             lines, found)

    def speed_family(self, scene):
        """Return W -> ``scene`` at field speed Omega0 = W (its steady motion: closed form)."""
        return lambda W: dataclasses.replace(scene, system=self.with_params(Omega0=W))

    def steady_terms(self) -> dict[str, Any]:
        """Return its steady motion in its terms: ``theta0``, ``psidot0`` (eqs. 20-22)."""
        sm = self.steady()
        return {'theta0': sm.theta0, 'psidot0': sm.psidot0, 'steady': ()}

    # -- a sweep's grid (gyro_rotor.analysis.sweep) ----------------------------------------
    def check_sweep_key(self, axis) -> None:
        """Refuse a grid axis (``key``, ``values``, ``is_int``) it cannot sweep.

        Its parameters and numeric initial conditions (:data:`SWEEP_KEYS`), integers for
        an integer key. Raises ParameterError naming the problem (the caller names the axis).
        """
        if axis.key not in SCENE_KEYS:
            raise ParameterError(f"unknown key '{axis.key}'"
                                 f'{did_you_mean(axis.key, SWEEP_KEYS)}')
        if axis.key not in SWEEP_KEYS:
            raise ParameterError(f"key '{axis.key}' cannot be swept; sweepable: the "
                                 f"parameters and initial.{{{', '.join(INITIAL_UNITS)}}}")
        vals = axis.values
        if axis.is_int and not np.all(vals == np.round(vals)):
            raise ParameterError(f'{axis.key} takes integers; the grid gives '
                                 f'{vals[vals != np.round(vals)][0]:g}')

    def sweep_rate(self, axes, scenes) -> float:
        """Return its fastest model rate [1/s] over a sweep's grid (the step's scale).

        Over every combination of the parameter axes (an initial condition does not change
        it; ``scenes``, the scene at each value of each axis alone, are not needed); a
        combination the parameters refuse is left out (its points are recorded as failed).
        """
        param_axes = [a for a in axes if a.key in PARAM_FIELDS]
        fastest = 0.0
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')
            for idx in np.ndindex(*(a.count for a in param_axes)):
                ch = {a.key: a.scene_value(a.values[i]) for a, i in zip(param_axes, idx)}
                try:
                    fastest = max(fastest, *drive_rates(self.params.replace(**ch)))
                except GyroRotorError:
                    continue
        return fastest

    def linear_parts(self, scene, drive: str | None = None, model=None) -> LinearParts:
        """Return its linear pieces: the analytic linearization (eqs. 18, 19, 23), one drive.

        About its steady motion (I or II on its branch; a body-mode scene: solution I), in
        the coordinates of its model (:func:`~gyro_rotor.core.linearize.linearize`).
        ``drive``: refused, NotApplicableError (one drive); ``scene``, ``model``: not needed.
        """
        if drive is not None:
            raise NotApplicableError('drive is for the scenes of system files; the centrifuge '
                                     'has one drive')
        return analytic_parts(linearize(self.params, self.steady(), self.model))

    def steady_state(self, model: Model) -> np.ndarray:
        """State on its steady motion (I or II; the resting state for a body-mode scene)."""
        sm = self.steady()
        return (model.state_from_euler(theta=sm.theta0, psidot=sm.psidot0,
                                       phi_M_dot=-sm.psidot0)
                if self.initial.mode == 'steady' else model.state_from_euler())

    def initial_state(self, model: Model, scene: str) -> np.ndarray:
        """Return the state at t = 0 from the initial condition (``scene``: for messages)."""
        ic = self.initial
        if ic.mode == 'steady':
            sm = self.steady()
            if model.name != 'full' and (ic.dtheta or ic.dthetadot or sm.theta0):
                raise SceneError(f"scene '{scene}': model {model.name} holds the axis "
                                 'vertical; theta0, dtheta and dthetadot must be 0')
            return model.state_from_euler(
                theta=sm.theta0 + ic.dtheta, thetadot=ic.dthetadot, psi=0.0,
                psidot=sm.psidot0 + ic.dpsidot, phi_M=ic.dchi, phi_M_dot=-sm.psidot0,
                z=ic.dz, zdot=ic.dzdot)
        q = np.asarray(ic.quaternion, dtype=float)
        W = np.asarray(ic.omega_body, dtype=float)
        if model.name == 'full':
            return _body_state(model, q, W, ic, scene)
        if model.name == 'upright_axis':
            if abs(W[0]) > 0 or abs(W[1]) > 0 or abs(q[1]) > 0 or abs(q[2]) > 0:
                raise SceneError(f"scene '{scene}': model upright_axis needs the axis "
                                 'vertical: quaternion x, y and omega_body 1, 2 must be 0')
            chi = ic.chi if ic.chi is not None else 2.0 * math.atan2(q[3], q[0])
            return np.array([chi, W[2], ic.z, ic.zdot, 0.0])
        return np.array([ic.z, ic.zdot, 0.0])

    # -- rotor_sim's parameters (gyro_rotor.ros.sim_params) --------------------------------
    def parameter_specs(self, scene, given: Mapping[str, Any]) -> Iterator[ParamSpec]:
        """Yield the parameters of ``scene`` (``system`` to the kick), in declaration order.

        ``system`` (fixed), ``description``, ``model``, ``t_end``, the RotorParams fields
        (live), ``initial.*`` of the mode given at start (``given['initial.mode']``, read
        after that key is yielded) and ``perturbation.*`` (:data:`PERTURBATION_KEYS`, the
        kick, live). The node's keys are not the system's.
        """
        def spec(key, default, doc, read_only=False, kick=False, fixed=False):
            return ParamSpec(key, default, doc, read_only, SCENE_KEYS[key], kick, fixed)
        yield spec('system', CENTRIFUGE, 'the rotor system: the built-in centrifuge (that of '
                   'the scene file)', True, fixed=True)
        yield spec('description', scene.description, 'what the scene shows', True)
        yield spec('model', self.model, 'full | locked_housing | upright_axis', True)
        yield spec('t_end', scene.t_end, 'scene duration [s] (the node stops there if '
                   'stop_at_t_end)')
        for f in PARAM_FIELDS:
            yield spec(f, getattr(self.params, f), f'{PARAM_DESCRIPTIONS[f]} [{PARAM_UNITS[f]}]; '
                       'live')
        ic = self.initial
        yield spec('initial.mode', ic.mode, _INITIAL_DOC['mode'], True)
        keys = (('theta0', 'branch', *PERTURBATION_KEYS) if given['initial.mode'] == 'steady'
                else ('quaternion', 'omega_body', 'z', 'zdot'))
        if given['initial.mode'] == 'body' and ic.chi is not None:
            keys = (*keys, 'chi')
        for k in keys:
            v = getattr(ic, k)
            yield spec(f'initial.{k}', [float(x) for x in v] if isinstance(v, tuple) else v,
                       _INITIAL_DOC[k] + ('' if k == 'chi' else '; read at start and by '
                                          '~/reset'), True)
        for k in PERTURBATION_KEYS:
            yield spec(f'perturbation.{k}', float(scene.perturbation.get(k, 0.0)),
                       f'kick of ~/perturb [{INITIAL_UNITS[k]}]; live', kick=True)

    def kick_values(self, values: Mapping[str, Any]) -> dict[str, Any]:
        """Return the kick ``values`` (keys :data:`PERTURBATION_KEYS`, numbers), the rest 0."""
        out = dict.fromkeys(PERTURBATION_KEYS, 0.0)
        for key, value in values.items():
            if key not in out:
                valid = [f'perturbation.{k}' for k in PERTURBATION_KEYS]
                raise ParameterError(f"unknown key 'perturbation.{key}'"
                                     f'{did_you_mean(f"perturbation.{key}", valid)}')
            try:
                out[key] = float(value)
            except (TypeError, ValueError):
                raise ParameterError(f'perturbation.{key} must be a number, got '
                                     f'{short(value)}') from None
        return out

    def model_kick(self, kick: Mapping[str, Any]) -> Mapping[str, Any]:
        """Return a kick of :meth:`kick_values` in its model's terms (the same)."""
        return kick

    def initial_doc(self) -> dict[str, Any]:
        """Return the initial condition as ``initial.*`` keys without the prefix."""
        ic = self.initial
        keys = (('mode', 'theta0', 'branch', *PERTURBATION_KEYS) if ic.mode == 'steady'
                else ('mode', 'quaternion', 'omega_body', 'z', 'zdot', 'chi'))
        out = {}
        for k in keys:
            v = getattr(ic, k)
            if v is None:
                continue
            if isinstance(v, (tuple, list, np.ndarray)):
                v = [float(x) for x in v]
            elif not isinstance(v, (bool, int, str)):
                v = float(v)
            out[k] = v
        return out

    def document_parts(self, scene) -> tuple[dict[str, Any], dict[str, Any]]:
        """Return the keys of rotor_sim's ``~/scene`` document (:meth:`Scene.document_parts`)."""
        return ({'scene': scene.name, 'model': self.model, 't_end': scene.t_end,
                 'params': self.params.to_mapping(), 'initial': self.initial_doc()},
                {'path': scene.path})

    def to_flat(self, scene) -> dict[str, Any]:
        """Return the flat keys of ``scene`` (:meth:`Scene.to_flat`)."""
        flat: dict[str, Any] = {'scene': scene.name, 'system': CENTRIFUGE, 'model': self.model,
                                't_end': scene.t_end}
        if scene.description:
            flat['description'] = scene.description
        flat.update(self.params.to_mapping())
        flat.update({f'initial.{k}': v for k, v in self.initial_doc().items()})
        for k, v in scene.perturbation.items():
            flat[f'perturbation.{k}'] = v
        return flat

    def live_scene(self, scene, changes: Mapping[str, Any]):
        """Return ``scene`` with the live changes of its parameters (None: there are none).

        The RotorParams fields of ``changes``, validated by RotorParams (ParameterError);
        the live simulation carries its state.
        """
        phys = {k: v for k, v in changes.items() if k in PARAM_FIELDS}
        if not phys:
            return None
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')
            return dataclasses.replace(scene, system=self.with_params(**phys))

    @classmethod
    def from_keys(cls, vals: Mapping[str, Any], where: str) -> 'Centrifuge':
        """Return the centrifuge of a scene's typed keys ``vals`` (module doc of core.scene).

        Checks the model, the parameters (RotorParams) and the initial condition's keys;
        :meth:`initial_state` checks that its steady motion exists and its model fits.
        """
        model = vals.get('model', 'full')
        if model not in MODELS:
            raise SceneError(f"{where}: unknown model '{model}'; valid: {', '.join(MODELS)}")
        try:
            params = RotorParams(**{k: vals[k] for k in PARAM_FIELDS if k in vals})
        except ParameterError as err:
            raise ParameterError(f'{where}: {err}') from None
        ini = {k.split('.', 1)[1]: v for k, v in vals.items() if k.startswith('initial.')}
        _check_initial(ini, where)
        return cls(params=params, model=model, initial=InitialCondition(**ini))


def _check_initial(ini: Mapping[str, Any], where: str) -> None:
    """Refuse initial.* keys of the other mode, wrong sizes and values that are not finite."""
    mode = ini.get('mode', 'steady')
    if mode not in ('steady', 'body'):
        raise SceneError(f"{where}: initial.mode must be 'steady' or 'body', got {mode!r}")
    if mode == 'body':
        bad = [k for k in ini if k in ('theta0', 'branch') or k in PERTURBATION_KEYS]
        if bad:
            raise SceneError(f'{where}: initial.{bad[0]} belongs to initial.mode steady')
        if len(ini.get('quaternion', (1, 0, 0, 0))) != 4:
            raise SceneError(f'{where}: initial.quaternion needs 4 numbers [w, x, y, z]')
        if len(ini.get('omega_body', (0, 0, 0))) != 3:
            raise SceneError(f'{where}: initial.omega_body needs 3 numbers')
        qn = math.hypot(*ini.get('quaternion', (1, 0, 0, 0)))
        if not (math.isfinite(qn) and qn > 0):
            raise SceneError(f'{where}: initial.quaternion must be finite and non-zero')
    else:
        bad = [k for k in ini if k in ('quaternion', 'omega_body', 'z', 'zdot', 'chi')]
        if bad:
            raise SceneError(f'{where}: initial.{bad[0]} belongs to initial.mode body')
    for k, v in ini.items():
        if isinstance(v, float) and not math.isfinite(v):
            raise SceneError(f'{where}: initial.{k} must be finite, got {v!r}')
        if isinstance(v, tuple) and not all(math.isfinite(x) for x in v):
            raise SceneError(f'{where}: initial.{k} must be finite, got {list(v)!r}')


def _body_state(model: Model, q: np.ndarray, W: np.ndarray, ic: InitialCondition,
                scene: str) -> np.ndarray:
    """Return the full model's state of a body-mode initial condition."""
    # q and -q are one orientation, but the sign carries the twist chi (|chi| < 2 pi):
    # without initial.chi take the smaller twist (q_w >= 0); with it, the sign that
    # gives that twist
    if q[0] < 0 or (q[0] == 0 and q[3] < 0):
        q = -q
    if ic.chi is not None and abs(2.0 * math.atan2(-q[3], -q[0]) - ic.chi) < abs(
            2.0 * math.atan2(q[3], q[0]) - ic.chi):
        q = -q
    y = model.state_from_body(q, W, ic.z, ic.zdot)
    if ic.chi is not None:
        chi_q = 2.0 * math.atan2(y[3], y[0])
        if abs(chi_q - ic.chi) > 1e-9:
            raise SceneError(
                f"scene '{scene}': initial.chi = {ic.chi} disagrees with the "
                f"quaternion's twist 2 atan2(q_z, q_w) = {chi_q:.12g}")
    return y
