"""Incremental Parquet output of a sweep and ``--resume``.

Layout of the output directory::

    DIR/sweep.json                  the specification (:class:`~.task.SweepSpec`)
    DIR/blocks/block-000000.parquet one file per finished block, written atomically
    DIR/maps/*.png                  the heatmaps (:mod:`.maps`)

A block file appears only when its block is complete (written to a temporary name, then
renamed), so an interrupted sweep leaves whole blocks only, and ``--resume`` computes the
blocks without a file. Each file holds a row per point of its block: ``point`` (flat
index), ``block``, the grid coordinates (one column per swept key), ``status``
(:class:`~.metrics.PointStatus`), ``message`` and the metric columns.

Each file also carries, in its Parquet key-value metadata :data:`BLOCK_KEY`, the SHA-256 of
the specification it was computed for and its block index and point range (issue 24).
``--resume`` and :meth:`SweepStore.read` take a block only if all of these match the
sweep's and its ``point`` column is exactly the block's range; any other file (a copy
under another name, one of another sweep, an older one without the key, a foreign
``block-000999``) is named and left out, and its block computed again. A ``sweep.json``
that does not read is refused with one line, and so is a ``blocks/`` directory without it
(nothing would say what its blocks were computed with). A ``sweep.json`` of an older version,
with a ``general`` key (issue 25), reads and keeps its blocks; one of a system file's scene
is refused (its ``base`` held none of the scene's keys).
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
import re

from gyro_rotor.analysis.sweep.metrics import INT_COLUMNS
from gyro_rotor.analysis.sweep.task import BlockResult, SweepSpec
from gyro_rotor.errors import ParameterError
import numpy as np

__all__ = ['SweepStore', 'MANIFEST', 'BLOCK_KEY', 'to_table', 'spec_hash']

MANIFEST = 'sweep.json'
#: the Parquet metadata key of a block file: spec hash, block index, point range
BLOCK_KEY = b'gyro_rotor.sweep_block'
_BLOCK_FILE = re.compile(r'\Ablock-([0-9]{6})\.parquet\Z', re.ASCII)


def spec_hash(spec: SweepSpec) -> str:
    """Return the SHA-256 of a specification's JSON text (what fixes its numbers)."""
    return hashlib.sha256(spec.to_json().encode()).hexdigest()


def to_table(res: BlockResult, spec: SweepSpec | None = None):
    """Return a block's columns as a pyarrow Table (integer metrics nullable).

    With ``spec``, the table's metadata carries :data:`BLOCK_KEY` (hash, block, points).
    """
    import pyarrow as pa
    arrays = {}
    for k, v in res.columns.items():
        if k in INT_COLUMNS:
            v = np.asarray(v, dtype=float)
            mask = ~np.isfinite(v)
            arrays[k] = pa.array(np.where(mask, 0, v).astype(np.int64), mask=mask)
        elif k == 'message':
            arrays[k] = pa.array([str(x) for x in v], type=pa.string())
        else:
            arrays[k] = pa.array(np.asarray(v))
    table = pa.table(arrays)
    if spec is not None:
        pts = spec.block_points(res.block)
        table = table.replace_schema_metadata({BLOCK_KEY: json.dumps(
            {'spec_sha256': spec_hash(spec), 'block': int(res.block),
             'first_point': int(pts[0]), 'points': int(pts.size)}).encode()})
    return table


class SweepStore:
    """The output directory of one sweep."""

    def __init__(self, out: str | os.PathLike):
        self.root = Path(out)
        self.blocks_dir = self.root / 'blocks'
        #: block files left out, each with why (filled by :meth:`done_blocks`, :meth:`read`)
        self.refused: dict[str, str] = {}

    @property
    def manifest(self) -> Path:
        """Path of ``sweep.json``."""
        return self.root / MANIFEST

    def prepare(self, spec: SweepSpec, *, resume: bool) -> SweepSpec:
        """Prepare the directory; with ``resume`` the stored specification must match.

        Returns the specification to run (the stored one on resume).
        """
        if self.root.exists() and not self.root.is_dir():
            raise ParameterError(f'--out {self.root} exists and is not a directory')
        if self.manifest.is_file():
            try:
                stored = SweepSpec.from_json(self.manifest.read_text(encoding='utf-8'))
                stored.block_points(0)
            except (ValueError, TypeError, KeyError, AttributeError, OSError,
                    ParameterError) as err:
                raise ParameterError(f'{self.manifest} is not a sweep specification '
                                     f'({type(err).__name__}: {str(err)[:120]}); remove the '
                                     'directory or give another --out') from None
            if not resume:
                raise ParameterError(f'--out {self.root} already holds a sweep ({MANIFEST}); '
                                     'use --resume to complete it, or another --out')
            mine, theirs = json.loads(spec.to_json()), json.loads(stored.to_json())
            diff = sorted(k for k in mine if k != 'block_size' and mine[k] != theirs.get(k))
            if diff:
                raise ParameterError(f'--resume: the sweep in {self.root} differs in '
                                     f"{', '.join(diff)}; give the same scene, grids and "
                                     'options, or another --out')
            return stored
        if self.blocks_dir.is_dir() and any(self.blocks_dir.iterdir()):
            raise ParameterError(f'--out {self.root} holds {self.blocks_dir.name}/ but no '
                                 f'{MANIFEST}: what its blocks were computed with is unknown; '
                                 'give another --out')
        self.root.mkdir(parents=True, exist_ok=True)
        self.blocks_dir.mkdir(exist_ok=True)
        tmp = self.manifest.with_suffix('.json.tmp')
        tmp.write_text(spec.to_json(), encoding='utf-8')
        os.replace(tmp, self.manifest)
        return spec

    def block_path(self, b: int) -> Path:
        """File of block ``b``."""
        return self.blocks_dir / f'block-{b:06d}.parquet'

    def _digests(self, spec: SweepSpec) -> set:
        """Return the hashes a block of ``spec`` in this directory may carry.

        The specification's own and, if this directory's ``sweep.json`` reads as ``spec``,
        that of its text as written: the blocks of a ``sweep.json`` of an older version
        (its ``general`` key is dropped on reading, :meth:`SweepSpec.from_json`) are kept.
        """
        digests = {spec_hash(spec)}
        try:
            text = self.manifest.read_text(encoding='utf-8')
            if SweepSpec.from_json(text) == spec:
                digests.add(hashlib.sha256(text.encode()).hexdigest())
        except (OSError, ValueError, TypeError, KeyError):
            pass                        # no sweep.json of this spec: its own hash only
        return digests

    def _check_block(self, f: Path, spec: SweepSpec, digests: set) -> int:
        """Return the block index of file ``f`` if it is a finished block of ``spec``.

        Raises ValueError naming why not.
        """
        import pyarrow.parquet as pq
        m = _BLOCK_FILE.match(f.name)
        if m is None:
            raise ValueError('not a block file name')
        b = int(m.group(1))
        if not 0 <= b < spec.n_blocks:
            raise ValueError(f'this sweep has blocks 0..{spec.n_blocks - 1}')
        meta = pq.read_schema(f).metadata or {}
        if BLOCK_KEY not in meta:
            raise ValueError('no block metadata (written by another program or version)')
        info = json.loads(meta[BLOCK_KEY])
        pts = spec.block_points(b)
        if info.get('spec_sha256') not in digests:
            raise ValueError('computed for another specification')
        if (info.get('block'), info.get('first_point'), info.get('points')) != \
                (b, int(pts[0]), int(pts.size)):
            raise ValueError(f"it is block {info.get('block')} (points from "
                             f"{info.get('first_point')}), not block {b}")
        points = pq.read_table(f, columns=['point']).column('point').to_numpy()
        if not np.array_equal(points, pts):
            raise ValueError(f'its points are not {int(pts[0])}..{int(pts[-1])}')
        return b

    def valid_blocks(self, spec: SweepSpec) -> dict[int, Path]:
        """Return the finished blocks of ``spec`` and their files; note the others."""
        self.refused = {}
        found: dict[int, Path] = {}
        if not self.blocks_dir.is_dir():
            return found
        digests = self._digests(spec)
        for f in sorted(self.blocks_dir.iterdir()):
            if f.name.endswith('.parquet') or (f.name.startswith('block-')
                                               and '.tmp' not in f.name):
                try:
                    found[self._check_block(f, spec, digests)] = f
                except (ValueError, OSError, KeyError, TypeError, ParameterError) as err:
                    self.refused[str(f)] = str(err)[:200]
                except Exception as err:    # noqa: B902 -- pyarrow's own errors: a bad file
                    self.refused[str(f)] = f'unreadable: {type(err).__name__}: ' \
                                           f'{str(err)[:150]}'
        return found

    def done_blocks(self, spec: SweepSpec) -> set:
        """Blocks whose file is a verified block of ``spec`` (see :meth:`valid_blocks`)."""
        return set(self.valid_blocks(spec))

    def write(self, res: BlockResult, spec: SweepSpec | None = None) -> None:
        """Write one block atomically (temporary file, then rename), with its metadata."""
        import pyarrow.parquet as pq
        self.blocks_dir.mkdir(parents=True, exist_ok=True)
        path = self.block_path(res.block)
        tmp = path.with_name(path.name + f'.tmp{os.getpid()}')
        pq.write_table(to_table(res, spec), tmp)
        os.replace(tmp, path)

    def read(self, spec: SweepSpec | None = None):
        """Return the verified blocks as one pyarrow Table sorted by point.

        ``spec`` defaults to the stored ``sweep.json``; files that are not blocks of it are
        left out (:attr:`refused`), so no point is ever counted twice or taken from another
        sweep.
        """
        import pyarrow as pa
        import pyarrow.parquet as pq
        if spec is None:
            spec = self.prepare_read()
        blocks = self.valid_blocks(spec)
        if not blocks:
            raise ParameterError(f'{self.root}: no finished block')
        table = pa.concat_tables([pq.read_table(f) for _, f in sorted(blocks.items())])
        return table.replace_schema_metadata(None).sort_by('point')

    def prepare_read(self) -> SweepSpec:
        """Return the stored specification (ParameterError if it does not read)."""
        try:
            return SweepSpec.from_json(self.manifest.read_text(encoding='utf-8'))
        except (ValueError, TypeError, KeyError, OSError) as err:
            raise ParameterError(f'{self.manifest}: not a readable sweep specification '
                                 f'({type(err).__name__}: {str(err)[:120]})') from None
