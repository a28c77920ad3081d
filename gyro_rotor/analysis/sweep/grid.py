"""Grid axes of a sweep: ``KEY=START:STOP:COUNT[:lin|log]`` over scene keys, and their product.

A centrifuge scene sweeps any numeric key that changes the motion: every
:class:`~gyro_rotor.core.params.RotorParams` field (``K_D``, ``K_S``, ``Omega0``,
``pole_pairs``, ...) and the initial condition (``initial.dzdot``, ``initial.dz``,
``initial.theta0``, ``initial.branch``, ...). The points are the Cartesian product of the
axes in the order given, the first axis varying slowest (C order); point ``i`` has the
multi-index ``numpy.unravel_index(i, shape)``. Every value of every axis is checked
against the scene (with the other keys at the scene's values) before any work starts, so
a value the scene refuses is an error up front, not a column of failed points.

A system file's scene sweeps ``constants.NAME`` (a constant of the system), ``K_S``,
``K_D``, ``Omega0`` (every rotor's drive) and ``drive.ROTOR.KEY`` (one rotor's). Which keys
a scene sweeps is asked of its system (``check_sweep_key`` of
:class:`~gyro_rotor.core.centrifuge.Centrifuge` and
:class:`~gyro_rotor.core.system.generated.GeneratedSystem`); :meth:`SweepGrid.check` does
the rest the same way for every scene.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from typing import Any, Mapping, Sequence

from gyro_rotor.core.params import PARAM_UNITS
from gyro_rotor.core.scene import INITIAL_UNITS, Scene, SCENE_KEYS
from gyro_rotor.errors import GyroRotorError, ParameterError
import numpy as np

__all__ = ['Spacing', 'GridAxis', 'SweepGrid', 'parse_axis', 'key_unit', 'MAX_POINTS']

#: most points of one sweep (the grid product)
MAX_POINTS = 100_000_000


def key_unit(key: str) -> str:
    """SI unit of a sweepable key ('-' for counts)."""
    last = key.rsplit('.', 1)[-1]
    if key in PARAM_UNITS or (key.startswith('drive.') and last in PARAM_UNITS):
        return PARAM_UNITS[last] or '-'
    if key.startswith('constants.'):
        return '-'                    # a constant of a system file carries no unit
    return INITIAL_UNITS.get(key.split('.', 1)[-1], '-')


class Spacing(enum.StrEnum):
    """Spacing of the values of an axis."""

    LIN = 'lin'
    LOG = 'log'


@dataclasses.dataclass(frozen=True)
class GridAxis:
    """One axis: ``count`` values of ``key`` from ``start`` to ``stop`` (both included)."""

    key: str
    start: float
    stop: float
    count: int
    spacing: Spacing = Spacing.LIN

    @property
    def values(self) -> np.ndarray:
        """Return the values, shape (count,); integers for integer keys."""
        if self.count == 1:
            v = np.array([self.start])
        elif self.spacing is Spacing.LOG:
            v = np.geomspace(self.start, self.stop, self.count)
        else:
            v = np.linspace(self.start, self.stop, self.count)
        return v

    @property
    def is_int(self) -> bool:
        """Whether the key is an integer scene key (pole_pairs, initial.branch)."""
        return SCENE_KEYS.get(self.key) is int

    def scene_value(self, v: float) -> Any:
        """Return a value as the scene wants it (int for integer keys)."""
        return int(round(v)) if self.is_int else float(v)

    @property
    def spec(self) -> str:
        """Return the axis written back as a ``--grid`` argument."""
        return f'{self.key}={self.start!r}:{self.stop!r}:{self.count}:{self.spacing.value}'


def _number(text: str, what: str, spec: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ParameterError(f"--grid {spec}: {what} '{text}' is not a number") from None
    if not math.isfinite(v):
        raise ParameterError(f'--grid {spec}: {what} must be finite, got {text}')
    return v


def parse_axis(spec: str) -> GridAxis:
    """Parse ``KEY=START:STOP:COUNT[:lin|log]`` (syntax; :meth:`SweepGrid.check` does the rest).

    Raises
    ------
    ParameterError
        Missing ``=``, wrong number of fields, a non-number, a count that is not a
        positive integer, an empty range (START = STOP with COUNT > 1), a log axis that
        does not stay positive.
    """
    key, sep, rng = spec.partition('=')
    key = key.strip()
    if not sep or not key:
        raise ParameterError(f"--grid needs KEY=START:STOP:COUNT[:lin|log], got '{spec}'")
    parts = [p.strip() for p in rng.split(':')]
    if len(parts) not in (3, 4):
        raise ParameterError(f'--grid {spec}: expected START:STOP:COUNT[:lin|log] after '
                             f"'{key}=', got {len(parts)} field(s)")
    start = _number(parts[0], 'START', spec)
    stop = _number(parts[1], 'STOP', spec)
    try:
        count = int(parts[2])
    except ValueError:
        raise ParameterError(f"--grid {spec}: COUNT '{parts[2]}' is not an integer") from None
    if count < 0:
        raise ParameterError(f'--grid {spec}: COUNT must be positive, got {count}')
    if count == 0:
        raise ParameterError(f'--grid {spec}: COUNT 0 is an empty range')
    try:
        spacing = Spacing(parts[3] if len(parts) == 4 else 'lin')
    except ValueError:
        raise ParameterError(f"--grid {spec}: spacing must be 'lin' or 'log', got "
                             f"'{parts[3]}'") from None
    if count > 1 and start == stop:
        raise ParameterError(f'--grid {spec}: empty range (START = STOP = {start:g} with '
                             f'COUNT {count})')
    if spacing is Spacing.LOG and not (start > 0 and stop > 0):
        raise ParameterError(f'--grid {spec}: a log axis needs START and STOP > 0')
    return GridAxis(key, start, stop, count, spacing)


@dataclasses.dataclass(frozen=True)
class SweepGrid:
    """The Cartesian product of the axes (first axis slowest)."""

    axes: tuple

    @classmethod
    def parse(cls, specs: Sequence[str]) -> 'SweepGrid':
        """Parse the ``--grid`` arguments (at least one)."""
        if not specs:
            raise ParameterError('a sweep needs at least one --grid KEY=START:STOP:COUNT')
        axes = tuple(parse_axis(s) for s in specs)
        keys = [a.key for a in axes]
        dup = sorted({k for k in keys if keys.count(k) > 1})
        if dup:
            raise ParameterError(f"--grid: key '{dup[0]}' is given more than once")
        grid = cls(axes)
        if grid.n_points > MAX_POINTS:
            raise ParameterError(f'--grid: {grid.n_points:.3g} points is more than '
                                 f'{MAX_POINTS:.0e}')
        return grid

    @property
    def keys(self) -> tuple:
        """Return the swept keys, in axis order."""
        return tuple(a.key for a in self.axes)

    @property
    def shape(self) -> tuple:
        """Return number of values per axis."""
        return tuple(a.count for a in self.axes)

    @property
    def n_points(self) -> int:
        """Return number of points (the product of the counts)."""
        return int(math.prod(self.shape))

    def coordinates(self, index: np.ndarray) -> dict:
        """Key -> values (float64) of the points with flat indices ``index``."""
        multi = np.unravel_index(np.asarray(index, dtype=np.int64), self.shape)
        return {a.key: a.values[m].astype(float) for a, m in zip(self.axes, multi)}

    def overrides(self, coords: Mapping[str, np.ndarray], j: int) -> dict:
        """Scene overrides of the ``j``-th of the points in ``coords``."""
        return {a.key: a.scene_value(coords[a.key][j]) for a in self.axes}

    def check(self, scene: Scene) -> list:
        """Refuse a key the scene's system cannot sweep and any value the scene refuses.

        Each key is asked of the scene's system (``check_sweep_key``); each value of each
        axis is tried with the other keys at the scene's values (:meth:`Scene.with_changes`,
        the scene's own checks). Return those scenes, one per distinct value of each axis.
        """
        for a in self.axes:
            try:
                scene.system.check_sweep_key(a)
            except ParameterError as err:
                hint = ' (use --t-end for the duration)' if a.key == 't_end' else ''
                raise ParameterError(f'--grid {a.spec}: {err}{hint}') from None
        scenes = []
        for a in self.axes:
            for v in np.unique(a.values):
                try:
                    scenes.append(scene.with_changes({a.key: a.scene_value(v)}))
                except GyroRotorError as err:
                    raise ParameterError(f'--grid {a.spec}: the value {a.key} = {v:g} is '
                                         f'refused: {err}') from err
        return scenes
