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
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from gyro_rotor.analysis.sweep.metrics import INT_COLUMNS
from gyro_rotor.analysis.sweep.task import BlockResult, SweepSpec
from gyro_rotor.errors import ParameterError
import numpy as np

__all__ = ['SweepStore', 'MANIFEST', 'to_table']

MANIFEST = 'sweep.json'


def to_table(res: BlockResult):
    """Return a block's columns as a pyarrow Table (integer metrics nullable)."""
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
    return pa.table(arrays)


class SweepStore:
    """The output directory of one sweep."""

    def __init__(self, out: str | os.PathLike):
        self.root = Path(out)
        self.blocks_dir = self.root / 'blocks'

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
            stored = SweepSpec.from_json(self.manifest.read_text(encoding='utf-8'))
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
        self.root.mkdir(parents=True, exist_ok=True)
        self.blocks_dir.mkdir(exist_ok=True)
        tmp = self.manifest.with_suffix('.json.tmp')
        tmp.write_text(spec.to_json(), encoding='utf-8')
        os.replace(tmp, self.manifest)
        return spec

    def block_path(self, b: int) -> Path:
        """File of block ``b``."""
        return self.blocks_dir / f'block-{b:06d}.parquet'

    def done_blocks(self, spec: SweepSpec) -> set:
        """Blocks whose file is there with one row per point."""
        import pyarrow.parquet as pq
        done = set()
        if not self.blocks_dir.is_dir():
            return done
        for f in self.blocks_dir.glob('block-*.parquet'):
            try:
                b = int(f.stem.split('-')[1])
                if pq.read_metadata(f).num_rows == spec.block_points(b).size:
                    done.add(b)
            except (ValueError, OSError, ParameterError):
                continue
        return done

    def write(self, res: BlockResult) -> None:
        """Write one block atomically (temporary file, then rename)."""
        import pyarrow.parquet as pq
        self.blocks_dir.mkdir(parents=True, exist_ok=True)
        path = self.block_path(res.block)
        tmp = path.with_name(path.name + f'.tmp{os.getpid()}')
        pq.write_table(to_table(res), tmp)
        os.replace(tmp, path)

    def read(self):
        """All finished blocks as one pyarrow Table sorted by point."""
        import pyarrow as pa
        import pyarrow.parquet as pq
        files = sorted(self.blocks_dir.glob('block-*.parquet'))
        if not files:
            raise ParameterError(f'{self.root}: no finished block')
        table = pa.concat_tables([pq.read_table(f) for f in files])
        return table.sort_by('point')
