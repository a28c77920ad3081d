"""Scenes for any rotor system: a ROS 2 parameter file with a ``system`` key.

::

    /**:                             # any node name (rotor_sim, renamed, namespaced)
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
linearization does not change along it. :func:`check_steady` says by how much a guess
misses; ``gyro-rotor steady SCENE`` solves for one from the guess.

A scene without a ``system`` key is a centrifuge scene (:mod:`gyro_rotor.core.scene`).
"""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path
from typing import Any, Mapping

from gyro_rotor.core.scene import check_node_ranges, flatten, NODE_KEYS, NODE_NAMES, scene_path
from gyro_rotor.core.system.model import GeneralModel
from gyro_rotor.core.system.system_file import (
    DRIVE_KEYS, load_system, RotorSystem, system_from_mapping)
from gyro_rotor.errors import did_you_mean, SceneError, SystemFileError
import numpy as np
import sympy

__all__ = ['GeneralScene', 'load_general_scene', 'is_general_scene', 'lock',
           'general_scene_path', 'list_general_scenes', 'check_steady',
           'steady_residual', 'GENERAL_KEYS', 'general_scene_from_mapping',
           'general_scene_to_flat', 'general_scene_from_flat', 'is_general_flat', 'SYSTEM_DOC',
           'load_any_scene']

#: fixed keys of a general scene (constants.NAME and drive.ROTOR.KEY come on top)
GENERAL_KEYS: dict[str, type] = {
    'scene': str, 'description': str, 'system': str, 't_end': float,
    'initial.q': list, 'initial.qdot': list, 'initial.z': list, 'initial.zdot': list,
    'steady.q': list, 'steady.qdot': list, 'steady.z': list, 'locked': list,
    'perturbation.q': list, 'perturbation.qdot': list, 'perturbation.z': list,
    'perturbation.zdot': list,
    'K_S': float, 'K_D': float, 'Omega0': float, 'pole_pairs': int,
    **{name: spec[0] for name, spec in NODE_KEYS.items()},
}


#: key of the embedded system document in :func:`general_scene_to_flat`
SYSTEM_DOC = 'system_doc'


@dataclasses.dataclass(frozen=True)
class GeneralScene:
    """A loaded general scene: the system (overrides applied, locked coordinates removed)."""

    name: str
    system: RotorSystem
    full_system: RotorSystem
    t_end: float
    q0: tuple
    qdot0: tuple
    z0: tuple
    zdot0: tuple
    steady_q: tuple
    steady_qdot: tuple
    steady_z: tuple
    locked: tuple = ()
    description: str = ''
    path: str | None = None
    node: dict = dataclasses.field(default_factory=dict)
    #: the typed flat keys the scene was built from (overrides included)
    flat: dict = dataclasses.field(default_factory=dict, compare=False, repr=False)
    #: the system as its file defines it (before the scene's constants and drives)
    base_system: RotorSystem | None = dataclasses.field(default=None, compare=False,
                                                        repr=False)

    @property
    def pole_pairs(self) -> tuple:
        """Pole pairs of each rotor's drive (0: linear law)."""
        return tuple(int(d.pole_pairs) for d in self.system.drives)

    def with_changes(self, changes: Mapping[str, Any]) -> 'GeneralScene':
        """Copy with flat keys changed (constants.NAME, drive.ROTOR.KEY, K_D, ..., t_end).

        Validated as in a scene file (SceneError names the problem); the steady motion
        is checked again, since constants move it.
        """
        flat = dict(self.flat)
        for key in changes:      # a common drive key sets every drive: per-rotor ones go
            if key in DRIVE_KEYS:
                flat = {k: v for k, v in flat.items()
                        if not (k.startswith('drive.') and k.endswith(f'.{key}'))}
        flat.update(changes)
        return general_scene_from_mapping(flat, path=self.path, system=self.base_system,
                                          where=f'scene {self.name}')

    def make_model(self) -> GeneralModel:
        """Return the compiled model of the (reduced) system."""
        return GeneralModel(self.system)

    def initial_state(self, model: GeneralModel | None = None) -> np.ndarray:
        """State (q, qdot, z, zdot, D = 0) at t = 0."""
        model = model or self.make_model()
        return model.state(self.q0, self.qdot0, self.z0, self.zdot0)

    def steady_state(self, model: GeneralModel | None = None) -> np.ndarray:
        """State on the steady motion at t = 0 (zdot = 0, D = 0)."""
        model = model or self.make_model()
        return model.state(self.steady_q, self.steady_qdot, self.steady_z,
                           np.zeros(self.system.m))

    def with_drives(self, **values: float) -> 'GeneralScene':
        """Copy with a drive value (K_S, K_D, Omega0, pole_pairs) set for every rotor."""
        drives = [d.replace(**values) for d in self.system.drives]
        return dataclasses.replace(self, system=self.system.with_drives(drives))


def general_scene_path(name_or_path) -> Path:
    """Resolve a scene name: shipped general scenes (config/systems/scenes) first."""
    from gyro_rotor.core.system.system_file import systems_dirs
    s = str(name_or_path)
    if not (s.endswith(('.yaml', '.yml')) or os.sep in s):
        for d in systems_dirs():
            f = d / 'scenes' / f'{s}.yaml'
            if f.is_file():
                return f
    return scene_path(name_or_path)


def list_general_scenes() -> list[str]:
    """Names of the shipped general scenes (config/systems/scenes)."""
    from gyro_rotor.core.system.system_file import systems_dirs
    return sorted({f.stem for d in systems_dirs() for f in (d / 'scenes').glob('*.yaml')})


def is_general_scene(name_or_path) -> bool:
    """Return True if the scene file has a ``system`` key (a general scene)."""
    import yaml
    try:
        path = general_scene_path(name_or_path)
        doc = yaml.safe_load(path.read_text(encoding='utf-8'))
    except Exception:   # noqa: B902 - any problem: let the centrifuge loader report it
        return False
    if not isinstance(doc, dict):
        return False
    for key in NODE_NAMES:
        sec = doc.get(key)
        if isinstance(sec, dict) and isinstance(sec.get('ros__parameters'), dict):
            return 'system' in sec['ros__parameters']
    return False


def lock(system: RotorSystem, names, values) -> RotorSystem:
    """Hold the coordinates ``names`` at ``values``: the reduced system (rows/columns dropped)."""
    if not names:
        return system
    keep = [i for i, c in enumerate(system.coordinates) if c not in names]
    syms = system.q_symbols()
    subs = {syms[i]: sympy.Float(values[i]) for i, c in enumerate(system.coordinates)
            if c in names}
    M = sympy.ImmutableMatrix([[system.mass_matrix[i, j].xreplace(subs) for j in keep]
                               for i in keep]) if keep else sympy.ImmutableMatrix(0, 0, [])
    B = sympy.ImmutableMatrix(system.m, len(keep), [system.guidance[k, j].xreplace(subs)
                                                    for k in range(system.m) for j in keep])
    return dataclasses.replace(
        system, name=f'{system.name}_locked', coordinates=tuple(system.coordinates[i]
                                                                for i in keep),
        mass_matrix=M, guidance=B, potential=system.potential.xreplace(subs))


def _typed(key: str, value: Any, where: str) -> Any:
    from gyro_rotor.core.yamlio import SCENE_NAME, short
    if key == 'scene' and not (isinstance(value, str) and SCENE_NAME.match(value)):
        raise SceneError(f'{where}: scene must be a name of ASCII letters, digits, _ . - '
                         f'(at most 100), got {short(value)}')
    want = float if key.startswith(('constants.', 'drive.')) and not key.endswith(
        'pole_pairs') else int if key.startswith('drive.') else GENERAL_KEYS[key]
    if want is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SceneError(f'{where}: {key} must be a number, got {short(value)}')
        if isinstance(value, int):
            raise SceneError(f'{where}: {key} must be written as a float ({value}.0): ROS 2 '
                             f'parameter files are typed')
        if not math.isfinite(value):
            raise SceneError(f'{where}: {key} must be finite, got {short(value)}')
        return float(value)
    if want is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise SceneError(f'{where}: {key} must be an integer, got {short(value)}')
        return value
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
    if not isinstance(value, (list, tuple)) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        raise SceneError(f'{where}: {key} must be a list of numbers, got {short(value)}')
    if not all(math.isfinite(v) for v in value):
        raise SceneError(f'{where}: {key} must be finite, got {short(value)}')
    return tuple(float(v) for v in value)


def _vector(vals: dict, key: str, size: int, what: str, where: str) -> tuple:
    v = vals.get(key, (0.0,) * size)
    if len(v) != size:
        raise SceneError(f'{where}: {key} must have {size} entries ({what}), got {len(v)}')
    return v


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


def _read(path: Path) -> dict:
    from gyro_rotor.core.yamlio import load_yaml
    try:
        text = path.read_text(encoding='utf-8')
    except (OSError, UnicodeDecodeError) as err:
        raise SceneError(f'cannot read scene file {path}: {err}') from err
    doc = load_yaml(text, f'scene file {path}', SceneError)
    section = None
    if isinstance(doc, dict):
        section = next((doc[k] for k in NODE_NAMES if k in doc), None)
    if not isinstance(section, dict) or not isinstance(section.get('ros__parameters'), dict):
        raise SceneError(f'scene file {path}: needs a /** (or rotor_sim): ros__parameters: '
                         'mapping')
    return flatten(section['ros__parameters'])


def load_general_scene(name_or_path: str | os.PathLike, overrides: dict | None = None, *,
                       check: bool = True) -> GeneralScene:
    """Load a general scene (module doc); ``overrides`` use the flat dotted keys.

    ``check=False`` skips the steadiness check (for the command that solves for one).
    """
    path = general_scene_path(name_or_path)
    flat = _read(path)
    for key, value in (overrides or {}).items():
        flat[key] = float(value) if isinstance(value, int) and not isinstance(value, bool) \
            and key != 'pole_pairs' and not key.endswith('.pole_pairs') else value
    return general_scene_from_mapping(flat, path=str(path), check=check)


def general_scene_from_mapping(flat: Mapping[str, Any], *, path: str | None = None,
                               system: RotorSystem | None = None, check: bool = True,
                               where: str | None = None) -> GeneralScene:
    """Build a general scene from its flat dotted keys (a scene file's, or a document's).

    ``system``: the system as its file defines it (before the scene's constants and
    drives); default: loaded from the ``system`` key (a name, or a path relative to
    ``path``). The scene keeps the typed keys as :attr:`GeneralScene.flat`.
    """
    where = where or (f'scene file {path}' if path else 'general scene')
    vals = {}
    for key, value in flat.items():
        if key not in GENERAL_KEYS and not key.startswith(('constants.', 'drive.')):
            raise SceneError(f"{where}: unknown key '{key}'{did_you_mean(key, GENERAL_KEYS)}")
        vals[key] = _typed(key, value, where)
    if 'system' not in vals:
        raise SceneError(f'{where}: the key system is missing')
    check_node_ranges(vals, where)
    try:
        if system is None:
            system = load_system(vals['system'], relative_to=path)
        base = system
        system = system.with_constants({k.split('.', 1)[1]: v for k, v in vals.items()
                                        if k.startswith('constants.')},
                                       where=f'{where}: constants')
        system = _drives(system, vals, where)
    except SystemFileError as err:
        raise SceneError(f'{where}: {err}') from None
    scene = _build(vals, system, where, path)
    scene = dataclasses.replace(scene, base_system=base, flat={
        k: list(v) if isinstance(v, tuple) else v for k, v in vals.items()})
    model = scene.make_model()
    _check_mass(scene, model, scene.initial_state(model), 'initial', where)
    _check_energy(scene, model, where)
    if any(k.startswith('steady.') for k in vals):
        _check_mass(scene, model, scene.steady_state(model), 'steady', where)
        if check:
            check_steady(scene, model, where)
    return scene


def _build(vals: dict, system: RotorSystem, where: str, path: str | None) -> GeneralScene:
    """Return the scene of typed keys ``vals`` on ``system`` (constants, drives applied)."""
    n, m = system.n, system.m
    coords = ', '.join(system.coordinates) or 'none'
    per_q, per_r = f'one per coordinate: {coords}', f'one per rotor: {", ".join(system.rotors)}'
    q0 = _vector(vals, 'initial.q', n, per_q, where)
    qd0 = _vector(vals, 'initial.qdot', n, per_q, where)
    z0 = _vector(vals, 'initial.z', m, per_r, where)
    zd0 = _vector(vals, 'initial.zdot', m, per_r, where)
    sq = _vector(vals, 'steady.q', n, per_q, where)
    sqd = _vector(vals, 'steady.qdot', n, per_q, where)
    sz = _vector(vals, 'steady.z', m, per_r, where)
    locked = vals.get('locked', ())
    for i, name in enumerate(locked):
        if name not in system.coordinates:
            raise SceneError(f"{where}: locked[{i}] = '{name}' is not a coordinate of system "
                             f'{system.name}{did_you_mean(name, system.coordinates)} '
                             f'(coordinates: {coords})')
    keep = [i for i, c in enumerate(system.coordinates) if c not in locked]
    for i, c in enumerate(system.coordinates):
        if c in locked and (q0[i] != sq[i] or qd0[i] != 0.0 or sqd[i] != 0.0):
            raise SceneError(f'{where}: the locked coordinate {c} is held at steady.q = '
                             f'{sq[i]}: initial.q must equal it and initial.qdot, steady.qdot '
                             f'be 0 there')
    t_end = vals.get('t_end', 10.0)
    if not t_end > 0:
        raise SceneError(f'{where}: t_end must be positive, got {t_end!r}')
    for k, size, what in (('q', n, per_q), ('qdot', n, per_q), ('z', m, per_r),
                          ('zdot', m, per_r)):
        _vector(vals, f'perturbation.{k}', size, what, where)

    def pick(v):
        return tuple(v[i] for i in keep)
    return GeneralScene(
        name=vals.get('scene', Path(path).stem if path else system.name),
        system=lock(system, locked, sq), full_system=system, t_end=t_end, q0=pick(q0),
        qdot0=pick(qd0), z0=z0, zdot0=zd0, steady_q=pick(sq), steady_qdot=pick(sqd),
        steady_z=sz, locked=tuple(locked), description=vals.get('description', ''),
        path=path, node={k: v for k, v in vals.items() if k in NODE_KEYS})


def general_scene_to_flat(scene: GeneralScene) -> dict[str, Any]:
    """Return the flat keys of a scene with the system's document embedded (``system_doc``).

    What a bag or a scene document carries: :func:`general_scene_from_flat` rebuilds the
    scene from it on a machine without the system file.
    """
    flat = dict(scene.flat)
    doc = scene.base_system.document if scene.base_system is not None else None
    if doc is not None:
        flat[SYSTEM_DOC] = doc
    return flat


def general_scene_from_flat(flat: Mapping[str, Any], *, check: bool = True) -> GeneralScene:
    """Rebuild a scene from :func:`general_scene_to_flat`'s keys (system file not needed)."""
    flat = dict(flat)
    doc = flat.pop(SYSTEM_DOC, None)
    system = None
    if doc is not None:
        try:
            system = system_from_mapping(doc)
        except SystemFileError as err:
            raise SceneError(f'the embedded system document: {err}') from None
    return general_scene_from_mapping(flat, system=system, check=check,
                                      where=f"general scene '{flat.get('scene', '?')}'")


def load_any_scene(name_or_path, overrides: dict | None = None):
    """Load a general scene (a file with a ``system`` key) or else a centrifuge scene."""
    if is_general_scene(name_or_path):
        return load_general_scene(name_or_path, overrides)
    from gyro_rotor.core.scene import load_scene
    return load_scene(name_or_path, overrides=overrides)


def is_general_flat(flat: Mapping[str, Any]) -> bool:
    """Return True if flat scene keys (a bag's record, a document) are a general scene's."""
    return 'system' in flat


def _check_mass(scene: GeneralScene, model: GeneralModel, y: np.ndarray, what: str,
                where: str) -> None:
    Mbar = model.lin(y)[0]
    w = np.linalg.eigvalsh(Mbar) if Mbar.size else np.ones(1)
    if not (np.all(np.isfinite(w)) and w.min() > 1e-12 * max(1.0, abs(w).max())):
        raise SceneError(f'{where}: the mass matrix of system {scene.system.name} (with the '
                         f'rotors) is not positive definite at the {what} state q = '
                         f'{y[:model.n].tolist()} (eigenvalues {w.tolist()}): a singular point '
                         f'of the coordinates or a bad constant')


def _check_energy(scene: GeneralScene, model: GeneralModel, where: str) -> None:
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


def steady_residual(scene: GeneralScene, model: GeneralModel | None = None) -> np.ndarray:
    """Accelerations (qddot, zddot) on the steady motion (zero if it is steady)."""
    model = model or scene.make_model()
    f = model.rhs(0.0, scene.steady_state(model))
    n, m = model.n, model.m
    return np.concatenate([f[n:2 * n], f[2 * n + m:2 * n + 2 * m]])


def check_steady(scene: GeneralScene, model: GeneralModel | None = None,
                 where: str | None = None) -> None:
    """Raise SceneError if the accelerations on the steady motion do not vanish."""
    model = model or scene.make_model()
    acc = steady_residual(scene, model)
    v = np.abs(np.concatenate([scene.steady_qdot, [1.0]])).max()
    tol = 1e-9 * max(1.0, v * v, model.rate())
    worst = int(np.argmax(np.abs(acc))) if acc.size else 0
    if acc.size and abs(acc[worst]) > tol:
        names = [f'{c}_ddot' for c in scene.system.coordinates] + [
            f'zddot_{r}' for r in scene.system.rotors]
        raise SceneError(
            f'{where or "scene " + scene.name}: steady.q/steady.qdot is not a steady motion: '
            f'the accelerations do not vanish there ({names[worst]} = {acc[worst]:.6g}, '
            f'largest of {np.abs(acc).max():.3g} > {tol:.3g}); `gyro-rotor steady '
            f'{scene.path or scene.name}` solves for one from this guess')
