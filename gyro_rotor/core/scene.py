"""Scenes: a YAML file that is at once a ROS 2 parameter file for ``rotor_sim``.

Every scene names its system (Magnus 1980: the theorem of sections 2-3 holds for any of
them): ``system: centrifuge`` is the built-in elastically restrained centrifuge of section 4
(hand-written quaternion model, regular at theta = 0, with its reduced models), any other
name or path is a system file (:mod:`gyro_rotor.core.system.system_file`). A scene without
a ``system`` key is a centrifuge scene, so older files keep working. One type
(:class:`Scene`), one reader, one validator of keys (unknown keys are refused with the
nearest valid name), one name-or-path resolver (:func:`scene_path`: config/ first, then
config/systems/scenes/). A scene holds its system with the scene's numbers and motion
(:attr:`Scene.system`): a :class:`~gyro_rotor.core.centrifuge.Centrifuge` or a system
file's :class:`~gyro_rotor.core.system.generated.GeneratedSystem`, one interface; the scene
asks it and never which one it is.

The shipped scenes are keyed ``/**`` (any node name, so that a renamed or namespaced
rotor_sim reads them too); ``rotor_sim`` and ``/rotor_sim`` are read as well.

The centrifuge::

    /**:
      ros__parameters:
        scene: precession
        system: centrifuge
        model: full                 # full | locked_housing | upright_axis
        t_end: 10.0                 # s
        A_R: 0.05                   # ... every RotorParams field (floats written as floats)
        initial:
          mode: steady              # steady | body
          theta0: 0.1
          branch: 1                 # 0 = solution I, 1 = precession, 2 = nutation branch
          dtheta: 0.005             # dthetadot dpsidot dchi dz dzdot as well
        perturbation:               # the kick of the node's ~/perturb service
          dthetadot: 0.05

With ``initial.mode: steady`` the state at t = 0 is theta = theta0 + dtheta,
thetadot = dthetadot, psi = 0, psidot = psidot0 + dpsidot, phi_M = dchi,
phi_M_dot = -psidot0, z = dz, zdot = dzdot (field angle Omega0 t). With ``body``:
``initial.quaternion`` [w, x, y, z] (stator, body to space), ``initial.omega_body`` [3],
``initial.z``, ``initial.zdot`` and ``initial.chi`` (the twist for the upright_axis model;
for the full model it must agree with the quaternion's).

A system file's scene::

    /**:
      ros__parameters:
        scene: twin_gimbal
        system: twin_gimbal          # a shipped system name or a path (relative to the scene)
        t_end: 10.0
        initial: {q: [...], qdot: [...], z: [...], zdot: [...]}   # lengths n, n, m, m
        steady: {q: [...], qdot: [...], z: [...]}    # the steady motion (zeros by default)
        locked: [beta2]              # coordinates held at their steady.q value
        constants: {c_a: 40.0}       # overrides of the system's constants
        K_D: 0.1                     # a drive value for every rotor (K_S, K_D, Omega0, pole_pairs)
        drive: {R1: {K_D: 0.2}}      # or for one rotor
        perturbation: {qdot: [...]}  # the kick of rotor_sim's ~/perturb (q, qdot, z, zdot)

A steady motion is one where the accelerations vanish (z = steady.z, zdot = 0); the
coordinates that move (steady.qdot != 0) must be cyclic up to that motion, so that the
linearization does not change along it.
:meth:`~gyro_rotor.core.system.generated.GeneratedSystem.check_steady` says by how much a
guess misses; ``gyro-rotor steady SCENE`` solves for one from the guess.

ROS 2 parameter files are typed: a float parameter written as ``98`` is an integer there
and the node could not take it, so the loader refuses it with a hint to write ``98.0``.
"""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path
import re
from typing import Any, Mapping

from gyro_rotor.core.centrifuge import (CENTRIFUGE, Centrifuge, INITIAL_UNITS,
                                        InitialCondition, SCENE_KEYS)
from gyro_rotor.core.model import Model, perturb_state, PERTURBATION_KEYS
from gyro_rotor.core.system.generated import (GeneratedSystem, key_sizes, lock, SYSTEM_DOC,
                                              vector)
from gyro_rotor.core.system.model import GeneralModel
from gyro_rotor.core.system.system_file import (config_dirs, DRIVE_KEYS, load_system,
                                                RotorSystem, system_from_mapping, systems_dirs)
from gyro_rotor.core.yamlio import SCENE_NAME, short
from gyro_rotor.errors import did_you_mean, SceneError, SystemFileError
from gyro_rotor.node_settings import NODE_KEYS, NODE_NAMES, NODE_RANGES
import numpy as np

__all__ = ['Scene', 'InitialCondition', 'load_scene', 'scene_from_mapping', 'scene_from_flat',
           'list_scenes', 'scene_path', 'perturb_state', 'PERTURBATION_KEYS',
           'SCENE_KEYS', 'SYSTEM_SCENE_KEYS', 'DEFAULT_SCENE', 'CENTRIFUGE', 'INITIAL_UNITS',
           'lock', 'SYSTEM_DOC', 'config_dirs', 'Centrifuge',
           'GeneratedSystem']

DEFAULT_SCENE = 'precession'
#: fixed keys of a system file's scene (constants.NAME and drive.ROTOR.KEY come on top)
SYSTEM_SCENE_KEYS: dict[str, type] = {
    'scene': str, 'description': str, 'system': str, 't_end': float,
    'initial.q': list, 'initial.qdot': list, 'initial.z': list, 'initial.zdot': list,
    'steady.q': list, 'steady.qdot': list, 'steady.z': list, 'locked': list,
    'perturbation.q': list, 'perturbation.qdot': list, 'perturbation.z': list,
    'perturbation.zdot': list,
    'K_S': float, 'K_D': float, 'Omega0': float, 'pole_pairs': int,
    **{name: spec[0] for name, spec in NODE_KEYS.items()},
}


@dataclasses.dataclass(frozen=True)
class Scene:
    """A loaded, validated scene of any system (module doc).

    Its name, ``t_end``, the description, the file, the node's keys (``node``), the kick
    (``perturbation``), the typed flat keys it was built from (``flat``) and its system
    with the scene's numbers and motion (``system``): the built-in
    :class:`~gyro_rotor.core.centrifuge.Centrifuge` or a system file's
    :class:`~gyro_rotor.core.system.generated.GeneratedSystem`. The two present one
    interface: what differs by the system is asked of it, never of its kind.
    """

    name: str
    system: Centrifuge | GeneratedSystem
    t_end: float = 10.0
    perturbation: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    node: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    description: str = ''
    path: str | None = None
    #: the typed flat keys the scene was built from (overrides included)
    flat: dict = dataclasses.field(default_factory=dict, compare=False, repr=False)

    @property
    def builtin(self) -> bool:
        """Return True for the built-in centrifuge (its hand-written models)."""
        return self.system.builtin

    @property
    def system_name(self) -> str:
        """Return the name of the scene's system (``centrifuge`` for the built-in one)."""
        return self.system.name

    @property
    def pole_pairs(self) -> tuple:
        """Pole pairs of each rotor's drive (0: linear law)."""
        return self.system.pole_pairs

    @property
    def Omega0(self) -> float:
        """Return the field speed Omega0 of the first rotor's drive [rad/s] (eq. 23)."""
        return self.system.Omega0

    @property
    def joint_names(self) -> tuple:
        """Return the joint_states names rotor_sim publishes for this scene (its model's)."""
        return self.system.joint_names

    def physics(self) -> tuple:
        """Return (name, value) of everything a run's analysis depends on.

        The system's name first, then what its system holds: the centrifuge's parameters,
        model and initial condition; a system file's coordinates, rotors, constants (by
        name), drives, equations, steady motion and initial state. Names, descriptions,
        t_end and the kick do not count.
        """
        return (('system', self.system_name), *self.system.physics())

    @property
    def kicked(self) -> bool:
        """Return True if the scene's perturbation moves the state."""
        return any(v for vals in self.perturbation.values()
                   for v in (vals if isinstance(vals, (list, tuple)) else [vals]))

    def make_model(self) -> Model | GeneralModel:
        """Return the model this scene needs."""
        return self.system.make_model()

    def initial_state(self, model=None) -> np.ndarray:
        """State vector at t = 0 for this scene's model."""
        return self.system.initial_state(model or self.make_model(), self.name)

    def steady_state(self, model: Model | GeneralModel | None = None) -> np.ndarray:
        """State on the scene's steady motion at t = 0 (z = zdot = 0, D = 0).

        The centrifuge: its steady motion (I or II, eqs. 20-23; the resting state for a
        body-mode scene); a system file: its checked steady motion (q_s, qdot_s, z_s).
        """
        return self.system.steady_state(model or self.make_model())

    def with_params(self, **changes: Any) -> 'Scene':
        """Copy with some centrifuge parameters changed (validated)."""
        return dataclasses.replace(self, system=self.system.with_params(**changes))

    def with_drives(self, **values: float) -> 'Scene':
        """Copy with a drive value (K_S, K_D, Omega0, pole_pairs) set for every rotor."""
        drives = [d.replace(**values) for d in self.system.drives]
        return dataclasses.replace(self, system=self.system.with_drives(drives))

    def with_changes(self, changes: Mapping[str, Any]) -> 'Scene':
        """Copy with flat keys changed (constants.NAME, drive.ROTOR.KEY, K_D, ..., t_end).

        Validated as in a scene file (SceneError, or ParameterError for a parameter,
        ``scene NAME: ...``); a system file's steady motion is checked again, since
        constants move it. Another ``initial.mode`` drops the scene's ``initial.*`` keys
        (those of the other mode).
        """
        flat = {**self.to_flat(), **self.node}
        flat.pop(SYSTEM_DOC, None)
        for key in changes:      # a common drive key sets every drive: per-rotor ones go
            if key in DRIVE_KEYS:
                flat = {k: v for k, v in flat.items()
                        if not (k.startswith('drive.') and k.endswith(f'.{key}'))}
        if changes.get('initial.mode', flat.get('initial.mode')) != flat.get('initial.mode'):
            flat = {k: v for k, v in flat.items() if not k.startswith('initial.')}
        flat.update(changes)
        return scene_from_mapping(flat, path=self.path, strict_float=False,
                                  system=self.system.base, where=f'scene {self.name}')

    def with_t_end(self, t_end: float) -> 'Scene':
        """Copy with another duration."""
        return dataclasses.replace(self, t_end=t_end, flat={**self.flat, 't_end': t_end})

    # -- the live simulation's interface (gyro_rotor.numerics.live) ------------------------
    def with_live_changes(self, changes: Mapping[str, Any]) -> 'Scene | None':
        """Return the scene with the physical keys of ``changes`` (None if there are none).

        The centrifuge's are RotorParams fields (validated by RotorParams); a system
        file's ``constants.NAME``, ``drive.ROTOR.KEY`` and the drive keys of every rotor
        (validated as in a scene file, :meth:`with_changes`: positive definite mass matrix,
        steady motion still steady). Raises ParameterError.
        """
        return self.system.live_scene(self, changes)

    def kick_values(self, values: Mapping[str, Any]) -> dict[str, Any]:
        """Return the kick of rotor_sim's ~/perturb: ``values`` checked, the other keys 0.

        The centrifuge's keys are :data:`PERTURBATION_KEYS` (numbers; finite and fit for
        the model when applied, :func:`perturb_state`); a system file's scene kicks q,
        qdot, z, zdot, lists of n, n, m, m finite numbers, n the system file's coordinates
        as for ``initial.q`` (a locked coordinate's entry must be 0). Raises
        ParameterError.
        """
        return self.system.kick_values(values)

    def model_kick(self, kick: Mapping[str, Any]) -> Mapping[str, Any]:
        """Return a kick of :meth:`kick_values` in the terms of the scene's model.

        (A system file's scene drops the entries of its locked coordinates.)
        """
        return self.system.model_kick(kick)

    def initial_doc(self) -> dict[str, Any]:
        """Return the initial condition as ``initial.*`` keys without the prefix."""
        return self.system.initial_doc()

    def document_parts(self) -> tuple[dict[str, Any], dict[str, Any]]:
        """Return the scene's keys of rotor_sim's ``~/scene`` document: (head, tail).

        The node's keys (perturbation, node, integrator, t_sim) go between them. A system
        file's ``flat`` holds the scene's keys with the system file's document embedded
        (:meth:`to_flat`): a reader rebuilds the scene without the file.
        """
        return self.system.document_parts(self)

    def to_flat(self) -> dict[str, Any]:
        """Return the flat dotted keys that :func:`scene_from_flat` rebuilds the scene from.

        A system file's scene carries the system's document (``system_doc``), so that a
        reader rebuilds it on a machine without the file.
        """
        return self.system.to_flat(self)


# -- loading ---------------------------------------------------------------------------------
def _scene_dirs() -> list[Path]:
    """Where shipped scenes are: config/ (the centrifuge's), then config/systems/scenes."""
    return config_dirs() + [d / 'scenes' for d in systems_dirs() if (d / 'scenes').is_dir()]


def _names_centrifuge(flat: Mapping[str, Any]) -> bool:
    """Return True if flat scene keys name the built-in centrifuge (or no system at all)."""
    return flat.get('system', CENTRIFUGE) == CENTRIFUGE


def list_scenes(builtin: bool | None = None) -> list[str]:
    """Names of the shipped scenes: of every system, or the centrifuge's (``builtin``) or not."""
    names = sorted({f.stem for d in _scene_dirs() for f in d.glob('*.yaml')} - {'analysis'})
    if builtin is None:
        return names
    return [n for n in names
            if _names_centrifuge(_read(scene_path(n))) == builtin]


def scene_path(name_or_path: str | os.PathLike) -> Path:
    """Resolve a scene name ('precession', 'twin_gimbal') or a path to a scene file."""
    s = str(name_or_path)
    p = Path(s)
    if s.endswith(('.yaml', '.yml')) or os.sep in s or p.is_file():
        if not p.is_file():
            raise SceneError(f'scene file {s} is a directory, not a file' if p.is_dir()
                             else f'scene file {s} does not exist')
        return p
    for d in _scene_dirs():
        f = d / f'{s}.yaml'
        if f.is_file() and s != 'analysis':
            return f
    raise SceneError(unknown_scene_message(s))


def unknown_scene_message(name: str) -> str:
    """``unknown scene 'X'; did you mean 'Y'? (scenes: ...)``: every shipped scene listed."""
    names = list_scenes()
    return f"unknown scene '{name}'{did_you_mean(name, names)} (scenes: {', '.join(names)})"


def _read(path: Path) -> dict[str, Any]:
    """Return the flat keys of a scene file's ``ros__parameters`` (the one reader)."""
    from gyro_rotor.core.yamlio import load_yaml
    try:
        text = path.read_text(encoding='utf-8')
    except (OSError, UnicodeDecodeError) as err:
        raise SceneError(f'cannot read scene file {path}: {err}') from err
    doc = load_yaml(text, f'scene file {path}', SceneError)
    if not isinstance(doc, dict):
        raise SceneError(f'scene file {path}: expected a mapping with a /** (or rotor_sim): '
                         f'ros__parameters: section')
    section = None
    for key in NODE_NAMES:
        if key in doc:
            section = doc[key]
            break
    if section is None and {'coordinates', 'rotors', 'mass_matrix'} & set(map(str, doc)):
        name = doc.get('name', path.stem)
        raise SceneError(f'{path} is a system file, not a scene file: give its name '
                         f'({name}) as the scene, or a scene file whose parameters name it '
                         f'(system: {name})')
    if section is None:
        raise SceneError(f'scene file {path}: no rotor_sim (or /**) section; found '
                         f'{", ".join(map(str, doc)) or "nothing"}')
    if not isinstance(section, dict) or not isinstance(section.get('ros__parameters'), dict):
        raise SceneError(f'scene file {path}: its /** (rotor_sim) section needs a '
                         'ros__parameters mapping')
    for key in section:
        if key != 'ros__parameters':
            raise SceneError(f"scene file {path}: unexpected key '{key}' beside "
                             'ros__parameters')
    return flatten(section['ros__parameters'])


def _key_type(key: str, centrifuge: bool) -> type | None:
    """Return the type of a scene key (None: unknown)."""
    if centrifuge:
        return SCENE_KEYS.get(key)
    if key.startswith(('constants.', 'drive.')):
        return int if key.endswith('.pole_pairs') and key.startswith('drive.') else float
    return SYSTEM_SCENE_KEYS.get(key)


def load_scene(name_or_path: str | os.PathLike = DEFAULT_SCENE,
               overrides: Mapping[str, Any] | None = None, *, check: bool = True) -> Scene:
    """Load and validate a scene of any system by name or path (module doc).

    ``overrides`` use the flat dotted keys (an integer is taken for a float: overrides are
    not typed ROS files). ``check=False`` skips the steadiness check of a system file's
    steady motion (for the command that solves for one).
    """
    path = scene_path(name_or_path)
    flat = _read(path)
    centrifuge = _names_centrifuge(flat)
    for key, value in (overrides or {}).items():
        if _key_type(key, centrifuge) is float and isinstance(value, int) \
                and not isinstance(value, bool):
            value = float(value)
        flat[key] = value
    flat.setdefault('scene', re.sub(r'[^A-Za-z0-9_.-]', '_', path.stem, flags=re.ASCII))
    return scene_from_mapping(flat, path=str(path), check=check)


def flatten(d: Mapping[str, Any], prefix: str = '') -> dict[str, Any]:
    """Nested dict to ROS 2 dotted parameter names."""
    out: dict[str, Any] = {}
    for k, v in d.items():
        name = f'{prefix}{k}'
        if isinstance(v, dict):
            out.update(flatten(v, name + '.'))
        else:
            out[name] = v
    return out


def _unknown(key: str, valid) -> str:
    inside = sorted(v for v in valid if v.startswith(key + '.'))
    if inside:       # a value where a group of keys belongs ('initial: 5')
        more = ', ...' if len(inside) > 6 else ''
        return (f"'{key}' is a group of keys, not a value: give its keys "
                f"({', '.join(inside[:6])}{more})")
    return f"unknown key '{key}'{did_you_mean(key, valid)}"


def _typed(key: str, want: type, value: Any, where: str, *, strict_float: bool) -> Any:
    """Check one key's value against its type ``want`` (ROS 2 parameter files are typed)."""
    if key == 'scene' and not (isinstance(value, str) and SCENE_NAME.match(value)):
        raise SceneError(f'{where}: scene must be a name of ASCII letters, digits, _ . - '
                         f'(at most 100), got {short(value)}')
    if want is str and isinstance(value, str) and len(value) > 10000:
        raise SceneError(f'{where}: {key} is longer than 10000 characters')
    if want is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SceneError(f'{where}: {key} must be a number, got {short(value)}')
        if strict_float and isinstance(value, int):
            raise SceneError(f'{where}: {key} must be written as a float ({value}.0): ROS 2 '
                             f'parameter files are typed')
        return float(value)
    if want is int:
        if strict_float and isinstance(value, float):
            raise SceneError(f'{where}: {key} must be written as an integer, got '
                             f'{short(value)}: ROS 2 parameter files are typed')
        if isinstance(value, bool) or not isinstance(value, (int, float)) or (
                isinstance(value, float) and not value.is_integer()):
            raise SceneError(f'{where}: {key} must be an integer, got {short(value)}')
        return int(value)
    if want is bool:
        if not isinstance(value, bool):
            raise SceneError(f'{where}: {key} must be true or false, got {short(value)}')
        return value
    if want is str:
        if not isinstance(value, str):
            raise SceneError(f'{where}: {key} must be a string, got {short(value)}')
        return value
    if key == 'locked':
        if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
            raise SceneError(f'{where}: locked must be a list of coordinate names, got '
                             f'{short(value)}')
        return tuple(value)
    if want is list:
        if not isinstance(value, (list, tuple)) or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            raise SceneError(f'{where}: {key} must be a list of numbers, got {short(value)}')
        return tuple(float(v) for v in value)
    raise AssertionError(want)  # pragma: no cover


def check_node_ranges(vals: Mapping[str, Any], where: str) -> None:
    """Refuse a node key outside :data:`NODE_RANGES` (as rotor_sim would, but before a run)."""
    for key, (low, high) in NODE_RANGES.items():
        v = vals.get(key)
        if v is not None and not (isinstance(v, (int, float)) and low <= v <= high):
            raise SceneError(f'{where}: {key} must be in [{low:g}, {high:g}], got {v!r}')


def scene_from_mapping(flat: Mapping[str, Any], path: str | None = None,
                       strict_float: bool | None = None, *, check: bool = True,
                       system: RotorSystem | None = None, where: str | None = None) -> Scene:
    """Build a Scene of any system from flat dotted keys (a parameter file's, a document's).

    The ``system`` key picks the system: ``centrifuge`` (or none) the built-in one, any
    other name or path (relative to ``path``) a system file; ``system`` (a RotorSystem)
    gives that file's system already loaded. ``strict_float`` (default: for a file) refuses
    an integer for a float, as ROS 2 does; a system file's scene is always strict.
    """
    if system is None and _names_centrifuge(flat):
        return _centrifuge_scene(flat, path, path is not None if strict_float is None
                                 else strict_float, where)
    return _system_scene(flat, path=path, system=system, check=check, where=where)


def scene_from_flat(flat: Mapping[str, Any], *, check: bool = True) -> Scene:
    """Rebuild a scene from :meth:`Scene.to_flat`'s keys (a bag's record, a document).

    A system file's scene is rebuilt from its embedded document (the file is not needed).
    """
    flat = dict(flat)
    doc = flat.pop(SYSTEM_DOC, None)
    system = None
    if doc is not None:
        try:
            system = system_from_mapping(doc)
        except SystemFileError as err:
            raise SceneError(f'the embedded system document: {err}') from None
    return scene_from_mapping(flat, strict_float=False, system=system, check=check,
                              where=f"scene '{flat.get('scene', '?')}'")


def _centrifuge_scene(flat: Mapping[str, Any], path: str | None, strict: bool,
                      where: str | None = None) -> Scene:
    """Build a centrifuge scene from its flat keys (module doc); ``where``: for messages."""
    where = where or (f'scene file {path}' if path else 'scene')
    vals: dict[str, Any] = {}
    for key, value in flat.items():
        if key not in SCENE_KEYS:
            raise SceneError(f'{where}: ' + _unknown(key, SCENE_KEYS))
        vals[key] = _typed(key, SCENE_KEYS[key], value, where, strict_float=strict)
    t_end = vals.get('t_end', 10.0)
    if not (math.isfinite(t_end) and t_end > 0):
        raise SceneError(f'{where}: t_end must be positive and finite, got {t_end!r}')
    system = Centrifuge.from_keys(vals, where)
    pert = {k.split('.', 1)[1]: v for k, v in vals.items() if k.startswith('perturbation.')}
    for k, v in pert.items():
        if not math.isfinite(v):
            raise SceneError(f'{where}: perturbation.{k} must be finite, got {v!r}')
    check_node_ranges(vals, where)
    scene = Scene(name=vals.get('scene', Path(path).stem if path else 'custom'), system=system,
                  t_end=t_end, perturbation=pert, node=_node(vals),
                  description=vals.get('description', ''), path=path, flat=dict(vals))
    # validate the initial condition now (steady motion exists, model fits)
    scene.initial_state()
    return scene


def _node(vals: Mapping[str, Any]) -> dict[str, Any]:
    """Return the node's keys of a scene's typed keys."""
    return {k: v for k, v in vals.items() if k in NODE_KEYS}


def _drives(system: RotorSystem, vals: dict, where: str) -> RotorSystem:
    common = {k: vals[k] for k in DRIVE_KEYS if k in vals}
    drives = [d.replace(**common) for d in system.drives] if common else list(system.drives)
    for key, value in vals.items():
        if not key.startswith('drive.'):
            continue
        parts = key.split('.')
        if len(parts) != 3 or parts[1] not in system.rotors or parts[2] not in DRIVE_KEYS:
            valid = [f'drive.{r}.{k}' for r in system.rotors for k in DRIVE_KEYS]
            raise SceneError(f"{where}: unknown key '{key}'{did_you_mean(key, valid)}")
        k = system.rotors.index(parts[1])
        drives[k] = drives[k].replace(**{parts[2]: value})
    return system.with_drives(drives)


def _system_scene(flat: Mapping[str, Any], *, path: str | None = None,
                  system: RotorSystem | None = None, check: bool = True,
                  where: str | None = None) -> Scene:
    """Build a system file's scene from its flat dotted keys (a scene file's, a document's).

    ``system``: the system as its file defines it (before the scene's constants and
    drives); default: loaded from the ``system`` key (a name, or a path relative to
    ``path``). The scene keeps the typed keys as :attr:`Scene.flat`.
    """
    where = where or (f'scene file {path}' if path else 'scene')
    if system is None:      # the system first: the other keys are read as its keys
        if 'system' not in flat:
            raise SceneError(f'{where}: the key system is missing')
        try:
            system = load_system(_typed('system', str, flat['system'], where,
                                        strict_float=True), relative_to=path)
        except SystemFileError as err:
            raise SceneError(f'{where}: {err}') from None
    vals = {}
    for key, value in flat.items():
        want = _key_type(key, False)
        if want is None:
            raise SceneError(f'{where}: ' + _unknown(key, SYSTEM_SCENE_KEYS))
        vals[key] = _typed(key, want, value, where, strict_float=True)
        v = vals[key]
        if not all(math.isfinite(x) for x in (v if isinstance(v, tuple) and key != 'locked'
                                              else [v] if isinstance(v, float) else [])):
            raise SceneError(f'{where}: {key} must be finite, got {short(value)}')
    check_node_ranges(vals, where)
    try:
        base = system
        system = system.with_constants({k.split('.', 1)[1]: v for k, v in vals.items()
                                        if k.startswith('constants.')},
                                       where=f'{where}: constants')
        system = _drives(system, vals, where)
    except SystemFileError as err:
        raise SceneError(f'{where}: {err}') from None
    scene = _build(vals, system, base, where, path)
    model = scene.make_model()
    # the checks test the values for finiteness and say so in one line: numpy's warnings
    # on the way (a singular point of the generated code) would only add lines
    with np.errstate(all='ignore'):
        _check_mass(scene, model, scene.initial_state(model), 'initial', where)
        _check_energy(scene, model, where)
        if any(k.startswith('steady.') for k in vals):
            _check_mass(scene, model, scene.steady_state(model), 'steady', where)
            if check:
                scene.system.check_steady(model, where, scene.path or scene.name)
    return scene


def _build(vals: dict, system: RotorSystem, base: RotorSystem, where: str,
           path: str | None) -> Scene:
    """Return the scene of typed keys ``vals`` on ``system`` (constants, drives applied)."""
    generated = dataclasses.replace(GeneratedSystem.from_keys(vals, system, where), base=base)
    t_end = vals.get('t_end', 10.0)
    if not t_end > 0:
        raise SceneError(f'{where}: t_end must be positive, got {t_end!r}')
    sizes = key_sizes(system)
    kick = {k: vector(vals, f'perturbation.{k}', *sizes[k], where) for k in sizes
            if f'perturbation.{k}' in vals}
    return Scene(name=vals.get('scene', Path(path).stem if path else system.name),
                 system=generated, t_end=t_end, description=vals.get('description', ''),
                 path=path, node=_node(vals), perturbation=kick,
                 flat={k: list(v) if isinstance(v, tuple) else v for k, v in vals.items()})


#: smallest mass-matrix eigenvalue over the largest below which a scene is refused
MASS_CONDITION = 1e-12


def _check_mass(scene: Scene, model: GeneralModel, y: np.ndarray, what: str,
                where: str) -> None:
    Mbar = model.lin(y)[0]
    w = np.linalg.eigvalsh(Mbar) if Mbar.size else np.ones(1)
    # relative to the largest eigenvalue: the system's own scale, whatever its units
    if not (np.all(np.isfinite(w)) and w.min() > MASS_CONDITION * abs(w).max()):
        state = ('is not positive definite' if not w.min() > 0 else
                 f'is numerically singular (smallest eigenvalue below {MASS_CONDITION:g} '
                 f'times the largest)')
        raise SceneError(f'{where}: the mass matrix of system {scene.system.name} (with the '
                         f'rotors) {state} at the {what} state q = {y[:model.n].tolist()} '
                         f'(eigenvalues {w.tolist()}): a singular point of the coordinates or '
                         f'a bad constant')


def _check_energy(scene: Scene, model: GeneralModel, where: str) -> None:
    """Refuse a scene whose E* (eq. 13) or accelerations are not finite where it starts.

    Checked on the steady motion and the initial state before anything runs (issue 24: a
    potential infinite everywhere, ``1/(sin(x)**2 + cos(x)**2 - 1)``, gave E*(0) = inf and
    a residual of nan, exit 0).
    """
    for what, y in (('steady', scene.steady_state(model)),
                    ('initial', scene.initial_state(model))):
        with np.errstate(all='ignore'):
            E = float(model.energy(y))
            f = model.rhs(0.0, y)
        if not math.isfinite(E):
            raise SceneError(f'{where}: E* of system {scene.system.name} is {E} at the {what} '
                             f'state q = {y[:model.n].tolist()}: the potential or a constant '
                             'is not finite there')
        if not np.all(np.isfinite(f)):
            raise SceneError(f'{where}: the equations of motion of system '
                             f'{scene.system.name} are not finite at the {what} state q = '
                             f'{y[:model.n].tolist()}')
