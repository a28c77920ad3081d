"""The system file: a rotor system of the paper's general theory (Magnus 1980, eqs. 1-17).

A system file (YAML; shipped ones in ``config/systems/``) states a conservative carrier
with n coordinates q and m symmetric rotors on synchronous drives, the way the paper does::

    name: twin_gimbal
    description: ...                        # optional
    coordinates: [alpha, beta1, beta2]      # q, n >= 0 names
    rotors: [R1, R2]                        # m >= 1 names
    constants: {J_p: 0.5, C1: 0.002}        # numbers, usable in every expression
    mass_matrix: [["J_p", "0"], ["0", "1"]] # M(q), n x n, symmetric, eq. (1), without the
                                            # rotors' axial inertias
    rotor_inertia: ["C1", "C2"]             # the diagonal of A, eq. (1) (constants only)
    guidance: [["cos(beta1)", "0", "0"]]    # B(q), m x n, eq. (2): omega = phidot + B qdot
    potential: "0.5*c_a*alpha**2"           # V(q), eq. (12)
    drives:                                 # one per rotor, eq. (8)
      - {K_S: 10.0, K_D: 0.05, Omega0: 314.159, pole_pairs: 0}

Expressions are parsed by :mod:`gyro_rotor.core.system.expression` (never evaluated as
Python). Every error names the file, the key, the row and column and the offending text.
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import math
import os
from pathlib import Path
import random
from typing import Any, Mapping

from gyro_rotor.core.params import MAX_MAGNITUDE
from gyro_rotor.core.system.expression import FUNCTIONS, parse_expression
from gyro_rotor.core.yamlio import IDENTIFIER as _NAME, load_yaml, short
from gyro_rotor.errors import did_you_mean, SystemFileError
import sympy

__all__ = ['RotorSystem', 'Drive', 'load_system', 'system_from_mapping', 'system_path',
           'list_systems', 'SYSTEM_KEYS', 'DRIVE_KEYS', 'config_dirs', 'systems_dirs']

#: the keys of a system file (all required but ``description``)
SYSTEM_KEYS = ('name', 'description', 'coordinates', 'rotors', 'constants', 'mass_matrix',
               'rotor_inertia', 'guidance', 'potential', 'drives')
#: the keys of one drive (eq. 8 or its sine law); pole_pairs 0 = linear law
DRIVE_KEYS = ('K_S', 'K_D', 'Omega0', 'pole_pairs')
_RESERVED = set(FUNCTIONS) | {'t', 'pi'}
_SYMMETRY_RTOL = 1e-12


@dataclasses.dataclass(frozen=True)
class Drive:
    """One synchronous drive (eq. 8): Q = -K_S z - K_D zdot, or the sine law with p > 0.

    Sine law: Q = -(K_S/p) sin(p z) - K_D zdot, U(z) = (K_S/p^2)(1 - cos p z).
    """

    K_S: float
    K_D: float
    Omega0: float
    pole_pairs: int = 0

    def replace(self, **changes: Any) -> 'Drive':
        """Return a copy with some values changed (checked as in a file)."""
        values = {**dataclasses.asdict(self), **changes}
        return _drive(values, 'drive override')


@dataclasses.dataclass(frozen=True)
class RotorSystem:
    """A loaded, validated rotor system (see module doc); expressions are sympy objects."""

    name: str
    coordinates: tuple
    rotors: tuple
    constants: Mapping[str, float]
    mass_matrix: sympy.ImmutableMatrix
    rotor_inertia: tuple
    guidance: sympy.ImmutableMatrix
    potential: sympy.Expr
    drives: tuple
    description: str = ''
    path: str | None = None
    #: the parsed system file this was built from (what a scene document or a bag carries,
    #: so that a reader needs no file: :func:`system_from_mapping` rebuilds it)
    document: Mapping | None = dataclasses.field(default=None, compare=False, repr=False)

    @property
    def n(self) -> int:
        """Return the number of carrier coordinates q."""
        return len(self.coordinates)

    @property
    def m(self) -> int:
        """Return the number of rotors."""
        return len(self.rotors)

    def q_symbols(self) -> tuple:
        """Return the sympy symbols of the coordinates q (in order)."""
        return tuple(sympy.Symbol(c, real=True) for c in self.coordinates)

    def constant_symbols(self) -> tuple:
        """Return the sympy symbols of the constants (in the order of ``constants``)."""
        return tuple(sympy.Symbol(c, real=True) for c in self.constants)

    def structure_key(self) -> str:
        """Hash of everything but the numbers: the key of the generated code's cache."""
        text = repr((self.coordinates, self.rotors, tuple(self.constants),
                     sympy.srepr(self.mass_matrix), tuple(map(sympy.srepr, self.rotor_inertia)),
                     sympy.srepr(self.guidance), sympy.srepr(self.potential)))
        return hashlib.sha256(text.encode()).hexdigest()[:20]

    def with_constants(self, overrides: Mapping[str, float], where: str = 'constants') -> \
            'RotorSystem':
        """Return a copy with some constants changed (names must exist)."""
        values = dict(self.constants)
        for key, value in overrides.items():
            if key not in values:
                hint = did_you_mean(key, values)
                raise SystemFileError(f"{where}: unknown constant '{key}' of system "
                                      f'{self.name}{hint}')
            values[key] = _number(value, f'{where}.{key}')
        out = dataclasses.replace(self, constants=values)
        _check_numbers(out, f'system {self.name} with {where}')
        return out

    def with_drives(self, drives) -> 'RotorSystem':
        """Return a copy with new drives (one per rotor)."""
        return dataclasses.replace(self, drives=tuple(drives))


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SystemFileError(f'{where}: expected a number, got {short(value)}')
    v = float(value)
    if not math.isfinite(v) or abs(v) > MAX_MAGNITUDE:
        raise SystemFileError(f'{where}: {short(value)} is not a finite number of magnitude '
                              f'<= {MAX_MAGNITUDE:g}')
    return v


def _names(value: Any, where: str, minimum: int) -> tuple:
    if value is None:
        value = []
    if not isinstance(value, list):
        raise SystemFileError(f'{where}: expected a list of names, got {short(value)}')
    for i, name in enumerate(value):
        if not isinstance(name, str) or not _NAME.match(name):
            raise SystemFileError(f'{where}[{i}]: {short(name)} is not a name (ASCII '
                                  'letters, digits, _; at most 100)')
        if name in _RESERVED:
            raise SystemFileError(f'{where}[{i}]: {name!r} is reserved (a function or t, pi)')
        if value.index(name) != i:
            raise SystemFileError(f'{where}[{i}]: the name {name!r} appears twice')
    if len(value) < minimum:
        raise SystemFileError(f'{where}: at least {minimum} name(s) needed, got {len(value)}')
    return tuple(value)


def _check_mapping(doc: Any, keys, where: str, expected: str) -> None:
    """Refuse a ``doc`` that is not a mapping, or that has a key not in ``keys`` (did you mean)."""
    if not isinstance(doc, dict):
        raise SystemFileError(f'{where}: expected a mapping with {expected}')
    for key in doc:
        if key not in keys:
            raise SystemFileError(f"{where}: unknown key '{key}'{did_you_mean(str(key), keys)}")


def _drive(entry: Any, where: str) -> Drive:
    _check_mapping(entry, DRIVE_KEYS, where, f'{", ".join(DRIVE_KEYS)}, got {short(entry)}')
    for key in ('K_S', 'K_D', 'Omega0'):
        if key not in entry:
            raise SystemFileError(f'{where}: {key} is missing')
    K_S = _number(entry['K_S'], f'{where}.K_S')
    K_D = _number(entry['K_D'], f'{where}.K_D')
    if K_S < 0 or K_D < 0:
        raise SystemFileError(f'{where}: K_S and K_D must not be negative, got K_S = {K_S}, '
                              f'K_D = {K_D}')
    p = entry.get('pole_pairs', 0)
    if isinstance(p, bool) or not isinstance(p, (int, float)) or not float(p).is_integer() \
            or not 0 <= p <= 10000:
        raise SystemFileError(f'{where}.pole_pairs: expected an integer 0..10000, got {short(p)}')
    return Drive(K_S=K_S, K_D=K_D, Omega0=_number(entry['Omega0'], f'{where}.Omega0'),
                 pole_pairs=int(p))


def _matrix(value: Any, rows: int, cols: int, key: str, where: str, names) -> list:
    if not isinstance(value, list) or len(value) != rows:
        got = f'{len(value)}: {short(value)}' if isinstance(value, list) else repr(value)
        raise SystemFileError(f'{where}: {key} must be a list of {rows} rows, got {got}')
    out = []
    for i, row in enumerate(value):
        if not isinstance(row, list) or len(row) != cols:
            got = f'{len(row)} entries: {short(row)}' if isinstance(row, list) else repr(row)
            raise SystemFileError(f'{where}: {key}[{i}] (row {i}) must be a list of {cols} '
                                  f'entries, got {got}')
        out.append([parse_expression(
            e, names, where=f'{where}: {key}[{i}][{j}] (row {i}, column {j})')
            for j, e in enumerate(row)])
    return out


#: random points at which the mass matrix' symmetry is checked numerically
_SYMMETRY_POINTS = 8
#: largest difference (in sympy operations) expanded symbolically when the numbers differ
_SYMBOLIC_BUDGET = 200


def _cheap(expr) -> bool:
    """Whether ``sympy.expand(expr)`` is cheap: few operations, small integer powers."""
    if sympy.count_ops(expr) > _SYMBOLIC_BUDGET:
        return False
    return all(not (p.exp.is_Integer and abs(int(p.exp)) > 8) for p in expr.atoms(sympy.Pow))


def _check_symmetric(M: list, coords, constants, qsyms, csyms, where: str) -> None:
    """Refuse a mass matrix that is not symmetric (issue 24: with a budget).

    Numerically first, at random points q with the file's constants: entries equal there
    (relative 1e-12) are taken as equal. Only where the numbers differ, and the difference
    is small enough (:data:`_SYMBOLIC_BUDGET` operations, powers up to 8), sympy may still
    prove it zero (a cancellation in floating point); ``(a+...+h)**16*(1+x)`` against its
    expanded twin no longer expands 245157 terms.
    """
    rng = random.Random(0)
    points = [{**dict(zip(csyms, constants.values())),
               **{s: rng.uniform(-1.0, 1.0) for s in qsyms}} for _ in range(_SYMMETRY_POINTS)]
    for i in range(len(M)):
        for j in range(i + 1, len(M)):
            diff = M[i][j] - M[j][i]
            if diff == 0:
                continue
            for pt in points:
                a, b = complex(M[i][j].evalf(subs=pt)), complex(M[j][i].evalf(subs=pt))
                if abs(a - b) <= _SYMMETRY_RTOL * max(1.0, abs(a), abs(b)):
                    continue
                if _cheap(diff) and sympy.expand(diff) == 0:
                    break
                raise SystemFileError(
                    f'{where}: mass_matrix is not symmetric: row {i}, column {j} is '
                    f'{short(str(M[i][j]))} but row {j}, column {i} is {short(str(M[j][i]))} '
                    f'(at q = {[round(pt[s], 3) for s in qsyms]}: {a.real:.12g} against '
                    f'{b.real:.12g})')


def _check_numbers(system: RotorSystem, where: str) -> None:
    subs = dict(zip(system.constant_symbols(), system.constants.values()))
    for i, a in enumerate(system.rotor_inertia):
        v = complex(a.evalf(subs=subs))
        if not (math.isfinite(v.real) and v.imag == 0 and v.real > 0):
            raise SystemFileError(f'{where}: rotor_inertia[{i}] = {str(a)!r} = {v.real!r} '
                                  f'must be a positive number')


def system_from_mapping(doc: Any, path: str | None = None) -> RotorSystem:
    """Build a RotorSystem from the parsed YAML document (see module doc)."""
    where = f'system file {path}' if path else 'system'
    _check_mapping(doc, SYSTEM_KEYS, where, f'the keys {", ".join(SYSTEM_KEYS)}')
    for key in SYSTEM_KEYS:
        if key not in doc and key != 'description':
            raise SystemFileError(f'{where}: the key {key} is missing')
    name = doc['name']
    if not isinstance(name, str) or not _NAME.match(name):
        raise SystemFileError(f'{where}: name must be a name (ASCII letters, digits, _), got '
                              f'{short(name)}')
    coords = _names(doc['coordinates'], f'{where}: coordinates', 0)
    rotors = _names(doc['rotors'], f'{where}: rotors', 1)
    consts = doc['constants'] if doc['constants'] is not None else {}
    if not isinstance(consts, dict):
        raise SystemFileError(f'{where}: constants must be a mapping name: number')
    _names(list(consts), f'{where}: constants', 0)
    constants = {k: _number(v, f'{where}: constants.{k}') for k, v in consts.items()}
    for key_a, key_b, a, b in (('coordinates', 'constants', coords, constants),
                               ('rotors', 'coordinates', rotors, coords),
                               ('rotors', 'constants', rotors, constants)):
        clash = sorted(set(a) & set(b))
        if clash:
            raise SystemFileError(f'{where}: the name {clash[0]!r} is in {key_a} and in '
                                  f'{key_b} (a coordinate, rotor and constant need distinct '
                                  f'names)')
    qsyms = tuple(sympy.Symbol(c, real=True) for c in coords)
    csyms = tuple(sympy.Symbol(c, real=True) for c in constants)
    names = {**dict(zip(constants, csyms)), **dict(zip(coords, qsyms))}
    n, m = len(coords), len(rotors)
    M = _matrix(doc['mass_matrix'] if doc['mass_matrix'] is not None else [], n, n,
                'mass_matrix', where, names)
    _check_symmetric(M, coords, constants, qsyms, csyms, where)
    inertia = doc['rotor_inertia']
    if not isinstance(inertia, list) or len(inertia) != m:
        got = f'{len(inertia)}: {short(inertia)}' if isinstance(inertia, list) else repr(inertia)
        raise SystemFileError(f'{where}: rotor_inertia must be a list of {m} entries (one per '
                              f'rotor), got {got}')
    A = tuple(parse_expression(a, dict(zip(constants, csyms)),
                               where=f'{where}: rotor_inertia[{i}]') for i, a in
              enumerate(inertia))
    B = _matrix(doc['guidance'], m, n, 'guidance', where, names)
    V = parse_expression(doc['potential'], names, where=f'{where}: potential')
    drives = doc['drives']
    if not isinstance(drives, list) or len(drives) != m:
        got = f'{len(drives)}: {short(drives)}' if isinstance(drives, list) else repr(drives)
        raise SystemFileError(f'{where}: drives must be a list of {m} entries (one per rotor), '
                              f'got {got}')
    description = doc.get('description', '')
    if not isinstance(description, str):
        raise SystemFileError(f'{where}: description must be text')
    system = RotorSystem(
        name=name, coordinates=coords, rotors=rotors, constants=constants,
        mass_matrix=sympy.ImmutableMatrix(n, n, [e for row in M for e in row]),
        rotor_inertia=A, guidance=sympy.ImmutableMatrix(m, n, [e for row in B for e in row]),
        potential=V, drives=tuple(_drive(d, f'{where}: drives[{i}]')
                                  for i, d in enumerate(drives)),
        description=description, path=path, document=copy.deepcopy(doc))
    _check_numbers(system, where)
    return system


def config_dirs() -> list[Path]:
    """Where scene and system files are searched: the source tree, then installed shares."""
    import sys
    dirs = [Path(__file__).resolve().parents[3] / 'config']
    prefixes = [sys.prefix] + [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)
                               if p]
    dirs += [Path(p) / 'share' / 'gyro_rotor' / 'config' for p in prefixes]
    return [d for d in dirs if d.is_dir()]


def systems_dirs() -> list[Path]:
    """Where system files are searched: config/systems of the source tree and installs."""
    return [d / 'systems' for d in config_dirs() if (d / 'systems').is_dir()]


def list_systems() -> list[str]:
    """Names of the shipped systems."""
    return sorted({f.stem for d in systems_dirs() for f in d.glob('*.yaml')})


def system_path(name_or_path: str | os.PathLike, relative_to: str | None = None) -> Path:
    """Resolve a system name (``twin_gimbal``) or a path (relative to a scene file's folder)."""
    s = str(name_or_path)
    if s.endswith(('.yaml', '.yml')) or os.sep in s:
        p = Path(s)
        if not p.is_absolute() and relative_to is not None and not p.is_file():
            p = Path(relative_to).parent / p
        if not p.is_file():
            raise SystemFileError(f'system file {s} is a directory, not a file'
                                  if p.is_dir() else f'system file {s} does not exist')
        return p
    for d in systems_dirs():
        f = d / f'{s}.yaml'
        if f.is_file():
            return f
    names = list_systems()
    raise SystemFileError(f"unknown system '{s}'{did_you_mean(s, names)} (systems: "
                          f"{', '.join(names)})")


def load_system(name_or_path: str | os.PathLike, relative_to: str | None = None) -> RotorSystem:
    """Load and validate a system file by name or path."""
    path = system_path(name_or_path, relative_to)
    try:
        text = path.read_text(encoding='utf-8')
    except (OSError, UnicodeDecodeError) as err:
        raise SystemFileError(f'cannot read system file {path}: {err}') from err
    doc = load_yaml(text, f'system file {path}', SystemFileError)
    return system_from_mapping(doc, str(path))
