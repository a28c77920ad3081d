"""One MCAP file read as far as it is intact, with its losses counted (issue 24).

:func:`read_mcap` never stops at the first damaged record. It uses the summary section
(chunk and metadata indexes, statistics) when the footer is there and the summary's CRC
holds; otherwise it walks the records from the start and, after a damaged record,
resynchronises on the next record boundary (the declared length if a valid record follows
there, else the next chunk whose CRC holds or the next record followed by two valid ones).
Every chunk is checked (record layout, decompression, CRC of the uncompressed data): the
messages of every intact chunk are kept, those of a damaged chunk are all given up, never
half read. What was lost is counted per channel, exactly where the file says how many
messages it held (the statistics record, the message index records that follow a chunk),
and flagged as of unknown size where it does not (a file cut short without a summary).

:func:`iter_messages` yields the messages of the intact chunks (and of messages outside
chunks) in log-time order, reading one chunk at a time.
"""

from __future__ import annotations

from collections.abc import Iterator
import dataclasses
import heapq
import io
import mmap
from pathlib import Path
import struct
from typing import Any, NamedTuple
import zlib

from gyro_rotor.errors import BagError
from mcap.data_stream import ReadDataStream
from mcap.records import (Channel, Chunk, ChunkIndex, DataEnd, Footer, Header, Message,
                          MessageIndex, Metadata, MetadataIndex, Schema, Statistics)

__all__ = ['McapContents', 'read_mcap', 'iter_messages', 'MAGIC']

MAGIC = b'\x89MCAP0\r\n'
#: largest uncompressed chunk accepted [bytes] (a damaged size field must not allocate more)
MAX_CHUNK_BYTES = 1 << 31
_FOOTER_LEN = 1 + 8 + 20
_RECORD = struct.Struct('<BQ')
#: record types with a fixed layout that must fill their length exactly
_PARSERS = {0x01: Header.read, 0x02: Footer.read, 0x03: Schema.read, 0x04: Channel.read,
            0x06: Chunk.read, 0x07: MessageIndex.read, 0x08: ChunkIndex.read,
            0x0B: Statistics.read, 0x0C: Metadata.read, 0x0D: MetadataIndex.read,
            0x0F: DataEnd.read}
#: opcodes a resynchronisation may land on (never those that also occur inside chunks)
_RESYNC = frozenset({0x02, 0x06, 0x07, 0x08, 0x0B, 0x0C, 0x0D, 0x0E, 0x0F})
_KNOWN = frozenset(range(0x01, 0x10))


class ChunkRef(NamedTuple):
    """An intact chunk: where its record starts, its length and its message time range."""

    offset: int
    length: int
    start: int
    end: int


@dataclasses.dataclass
class McapContents:
    """What :func:`read_mcap` found in one MCAP file."""

    path: Path
    size: int = 0
    profile: str = ''
    library: str = ''
    schemas: dict[int, Schema] = dataclasses.field(default_factory=dict)
    channels: dict[int, Channel] = dataclasses.field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = dataclasses.field(default_factory=dict)
    chunks: list[ChunkRef] = dataclasses.field(default_factory=list)
    #: messages outside chunks (an unchunked file)
    loose: list[Message] = dataclasses.field(default_factory=list)
    #: readable messages per channel id
    counts: dict[int, int] = dataclasses.field(default_factory=dict)
    #: messages per channel id the file says it holds (statistics); None if unknown
    recorded: dict[int, int] | None = None
    #: messages known lost per channel id (damaged chunks; recorded minus readable)
    lost: dict[int, int] = dataclasses.field(default_factory=dict)
    #: messages of channels whose channel record was lost: channel id -> count
    orphans: dict[int, int] = dataclasses.field(default_factory=dict)
    #: losses whose size the file does not tell (a cut without summary)
    unknown_loss: list[str] = dataclasses.field(default_factory=list)
    #: metadata records the summary indexes but that do not read (damaged): their names
    lost_records: list[str] = dataclasses.field(default_factory=list)
    #: what was wrong, one line each
    problems: list[str] = dataclasses.field(default_factory=list)
    start: int | None = None
    end: int | None = None
    indexed: bool = False
    #: the file ends with a footer and the magic
    complete: bool = False

    @property
    def damaged(self) -> bool:
        """Whether anything in the file could not be read."""
        return bool(self.problems)


def _parse(opcode: int, body: bytes | memoryview) -> Any:
    """Parse one record body; raise ValueError unless it fills its length exactly."""
    parser = _PARSERS.get(opcode)
    if parser is None:
        if opcode == 0x05:
            return Message.read(ReadDataStream(io.BytesIO(body)), len(body))
        return None
    stream = ReadDataStream(io.BytesIO(body))
    record = parser(stream)
    if stream.count != len(body):
        raise ValueError(f'record fills {stream.count} of its {len(body)} bytes')
    return record


def _chunk_records(chunk: Chunk) -> list:
    """Decompress a chunk, check its CRC and return its records; raise if damaged."""
    if chunk.uncompressed_size > MAX_CHUNK_BYTES:
        raise ValueError(f'uncompressed size {chunk.uncompressed_size} out of range')
    if chunk.compression == 'zstd':
        import zstandard
        data = zstandard.ZstdDecompressor().decompress(
            chunk.data, max_output_size=chunk.uncompressed_size)
    elif chunk.compression == 'lz4':
        import lz4.frame
        data = lz4.frame.decompress(chunk.data)
    elif chunk.compression == '':
        data = chunk.data
    else:
        raise ValueError(f'unknown compression {chunk.compression!r}')
    if len(data) != chunk.uncompressed_size:
        raise ValueError(f'{len(data)} bytes uncompressed, the chunk says '
                         f'{chunk.uncompressed_size}')
    if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        raise ValueError('CRC mismatch')
    records, pos, n = [], 0, len(data)
    view = memoryview(data)
    while pos < n:
        if n - pos < 9:
            raise ValueError(f'{n - pos} stray bytes at the end of the chunk')
        opcode, length = _RECORD.unpack_from(view, pos)
        if length > n - pos - 9:
            raise ValueError(f'inner record of {length} bytes overruns the chunk')
        if opcode in (0x03, 0x04, 0x05):
            records.append(_parse(opcode, view[pos + 9:pos + 9 + length]))
        pos += 9 + length
    return records


class _Reader:
    """Read one file held in memory (a memory map)."""

    def __init__(self, buf, out: McapContents):
        self.buf = buf
        self.size = len(buf)
        self.out = out

    # -- helpers ------------------------------------------------------------------------------
    def head(self, pos: int) -> tuple[int, int] | None:
        """Return (opcode, length) of a plausible record at ``pos``, else None."""
        if pos < 0 or pos + 9 > self.size:
            return None
        opcode, length = _RECORD.unpack_from(self.buf, pos)
        if opcode not in _KNOWN or length > self.size - pos - 9:
            return None
        return opcode, length

    def record(self, pos: int) -> tuple[int, int, Any]:
        """Return (opcode, length, parsed record) at ``pos``; raise ValueError if damaged."""
        head = self.head(pos)
        if head is None:
            raise ValueError('no valid record header')
        opcode, length = head
        try:
            record = _parse(opcode, memoryview(self.buf)[pos + 9:pos + 9 + length])
        except (ValueError, struct.error, UnicodeDecodeError, EOFError) as err:
            raise ValueError(f'{type(err).__name__}: {err}') from err
        except Exception as err:        # mcap's EndOfFile and others: all mean damage
            raise ValueError(f'{type(err).__name__}: {err}') from err
        return opcode, length, record

    def valid_at(self, pos: int, depth: int) -> bool:
        """Whether ``depth`` valid records follow each other from ``pos`` (or end the file)."""
        for _ in range(depth):
            if pos == self.size:
                return True
            try:
                opcode, length, record = self.record(pos)
                if isinstance(record, Chunk):
                    _chunk_records(record)
            except ValueError:
                return False
            pos += 9 + length
        return True

    def take_chunk(self, pos: int, length: int, chunk: Chunk) -> bool:
        """Check a chunk and count its messages; return False if it is damaged."""
        out = self.out
        try:
            records = _chunk_records(chunk)
        except Exception as err:    # noqa: B902 -- any failure to decode means damage
            out.problems.append(f'chunk at byte {pos} ({length + 9} bytes) is damaged '
                                f'({type(err).__name__}: {err}): its messages are lost')
            return False
        for rec in records:
            if isinstance(rec, Message):
                out.counts[rec.channel_id] = out.counts.get(rec.channel_id, 0) + 1
            elif isinstance(rec, Channel):
                out.channels.setdefault(rec.id, rec)
            elif isinstance(rec, Schema):
                out.schemas.setdefault(rec.id, rec)
        if any(isinstance(r, Message) for r in records):
            out.start = chunk.message_start_time if out.start is None else min(
                out.start, chunk.message_start_time)
            out.end = chunk.message_end_time if out.end is None else max(
                out.end, chunk.message_end_time)
        out.chunks.append(ChunkRef(pos, 9 + length, chunk.message_start_time,
                                   chunk.message_end_time))
        return True

    # -- the summary ----------------------------------------------------------------------
    def summary(self) -> tuple[dict[int, Any], str]:
        """Return the summary records by kind, or ({}, why not)."""
        size, buf = self.size, self.buf
        if size < 2 * len(MAGIC) + _FOOTER_LEN or buf[size - len(MAGIC):] != MAGIC:
            return {}, 'no MCAP magic at the end'
        fpos = size - len(MAGIC) - _FOOTER_LEN
        try:
            _, _, footer = self.record(fpos)
        except ValueError:
            footer = None
        if not isinstance(footer, Footer):
            return {}, 'no footer before the closing magic'
        self.out.complete = True
        start = footer.summary_start
        if start == 0:
            return {}, 'no summary section'
        if not len(MAGIC) <= start <= fpos:
            return {}, f'the footer points to a summary at byte {start}, outside the file'
        if footer.summary_crc and zlib.crc32(buf[start:size - len(MAGIC) - 4]) != \
                footer.summary_crc:
            return {}, 'the summary section fails its CRC'
        kinds: dict[int, Any] = {0x03: {}, 0x04: {}, 0x08: [], 0x0D: [], 0x0B: None}
        pos = start
        while pos < fpos:
            try:
                opcode, length, record = self.record(pos)
            except ValueError as err:
                return {}, f'summary record at byte {pos} is damaged ({err})'
            if opcode in (0x03, 0x04):
                kinds[opcode][record.id] = record
            elif opcode in (0x08, 0x0D):
                kinds[opcode].append(record)
            elif opcode == 0x0B:
                kinds[opcode] = record
            pos += 9 + length
        return kinds, ''

    def header(self) -> None:
        try:
            opcode, _, record = self.record(len(MAGIC))
        except ValueError as err:
            self.out.problems.append(f'the header record is damaged ({err})')
            return
        if opcode == 0x01:
            self.out.profile, self.out.library = record.profile, record.library

    # -- indexed reading ------------------------------------------------------------------
    def indexed(self, kinds: dict[int, Any]) -> None:
        out = self.out
        out.indexed = True
        self.header()
        out.schemas = dict(kinds[0x03])
        out.channels = dict(kinds[0x04])
        stats: Statistics | None = kinds[0x0B]
        if stats is not None:
            out.recorded = dict(stats.channel_message_counts)
        for index in kinds[0x0D]:
            try:
                if index.length < 9:
                    raise ValueError(f'index gives a length of {index.length}')
                opcode, length, record = self.record(index.offset)
                if opcode != 0x0C or length + 9 != index.length:
                    raise ValueError(f'no metadata record of {index.length} bytes there')
                if record.name != index.name:
                    raise ValueError(f'its name reads {record.name!r}')
            except ValueError as err:
                out.problems.append(f'metadata record {index.name!r} at byte {index.offset} '
                                    f'is damaged ({err}): skipped')
                out.lost_records.append(f'the metadata record {index.name!r} (damaged)')
                continue
            out.metadata[record.name] = dict(record.metadata)
        mismatch = ''
        for index in sorted(kinds[0x08], key=lambda c: c.chunk_start_offset):
            pos = index.chunk_start_offset
            try:
                opcode, length, record = self.record(pos)
                if opcode != 0x06 or length + 9 != index.chunk_length:
                    raise ValueError(f'no chunk record of {index.chunk_length} bytes there')
                _chunk_records(record)
            except Exception as err:    # noqa: B902 -- any failure to decode means damage
                mismatch = f'the chunk indexed at byte {pos} does not read ({err})'
                break
            self.take_chunk(pos, length, record)
        if mismatch or not kinds[0x08] and out.recorded and sum(out.recorded.values()):
            # a damaged chunk, or data moved by inserted or missing bytes, or an unchunked
            # file: read the data section record by record; the summary's channels and
            # counts stay (its CRC held)
            if mismatch:
                out.problems.append(f'{mismatch}: the data section is read record by record')
            out.chunks.clear()
            out.counts.clear()
            out.start = out.end = None
            self.scan()

    # -- sequential reading ---------------------------------------------------------------
    def scan(self) -> None:
        """Walk the records from the start; resynchronise after damage."""
        out = self.out
        pos = len(MAGIC)
        lost_chunk = ''     # a damaged chunk whose message indexes may follow
        while pos < self.size:
            try:
                opcode, length, record = self.record(pos)
            except ValueError as err:
                head = self.head(pos)
                nxt = None
                if head is not None and self.valid_at(pos + 9 + head[1], 2):
                    nxt = pos + 9 + head[1]         # the declared length holds
                if nxt is None:
                    nxt = self._resync(pos + 1)
                self._settle(lost_chunk)
                lost_chunk = ''
                if nxt is None:
                    out.problems.append(f'truncated: no valid record from byte {pos} to the '
                                        f'end of the file at byte {self.size} ({err}): cut '
                                        'or damaged to its end')
                    out.unknown_loss.append(f'what followed byte {pos}')
                    return
                out.problems.append(f'record at byte {pos} is damaged ({err}); reading on at '
                                    f'byte {nxt}')
                if self.buf[pos] == 0x06 and (head is not None and nxt == pos + 9 + head[1]
                                              or self.buf[nxt] == 0x07):
                    # the damaged record is one chunk: its message indexes (if they follow)
                    # count its loss exactly
                    lost_chunk = f'the damaged chunk at byte {pos}'
                else:
                    out.unknown_loss.append(f'bytes {pos}..{nxt}')
                pos = nxt
                continue
            if opcode == 0x07:
                if lost_chunk:        # the index of a damaged chunk: its loss, exactly
                    cid = record.channel_id
                    out.lost[cid] = out.lost.get(cid, 0) + len(record.records)
                    lost_chunk = 'indexed'
                pos += 9 + length
                continue
            self._settle(lost_chunk)
            lost_chunk = ''
            if opcode == 0x06:
                if not self.take_chunk(pos, length, record):
                    lost_chunk = f'the damaged chunk at byte {pos}'
            elif opcode == 0x05:
                out.loose.append(record)
                out.counts[record.channel_id] = out.counts.get(record.channel_id, 0) + 1
                t = record.log_time
                out.start = t if out.start is None else min(out.start, t)
                out.end = t if out.end is None else max(out.end, t)
            elif opcode == 0x04:
                out.channels.setdefault(record.id, record)
            elif opcode == 0x03:
                out.schemas.setdefault(record.id, record)
            elif opcode == 0x0C:
                out.metadata[record.name] = dict(record.metadata)
            elif opcode == 0x01:
                out.profile, out.library = record.profile, record.library
            elif opcode == 0x0B and out.recorded is None:
                out.recorded = dict(record.channel_message_counts)
            elif opcode == 0x02:
                out.complete = self.buf[pos + 9 + length:] == MAGIC
                if not out.complete:
                    out.problems.append('the footer is not followed by the MCAP magic')
                return
            pos += 9 + length
        self._settle(lost_chunk)
        out.problems.append(f'truncated: no footer, the file ends at byte {self.size}')
        out.unknown_loss.append(f'what followed byte {self.size}')

    def _settle(self, lost_chunk: str) -> None:
        """Flag a damaged chunk without message indexes after it: a loss of unknown size."""
        if lost_chunk and lost_chunk != 'indexed':
            self.out.unknown_loss.append(f'{lost_chunk} (no message index after it)')

    def _resync(self, pos: int) -> int | None:
        """Return the next offset >= pos where the records read on, or None."""
        buf, size = self.buf, self.size
        while pos + 9 <= size:
            candidates = [p for p in (buf.find(bytes([op]), pos) for op in _RESYNC) if p >= 0]
            if not candidates:
                return None
            q = min(candidates)
            head = self.head(q)
            if head is not None:
                opcode, length = head
                if opcode == 0x06:
                    try:
                        _, _, chunk = self.record(q)
                        if chunk.uncompressed_crc:
                            _chunk_records(chunk)
                            return q
                    except Exception:   # noqa: B902 -- not a chunk after all
                        pass
                if self.valid_at(q, 3):
                    return q
            pos = q + 1
        return None


def read_mcap(path: str | Path) -> McapContents:
    """Read what is intact in one MCAP file (see module doc).

    Raises
    ------
    BagError
        If the file cannot be opened, is empty, or does not start with the MCAP magic.
    """
    path = Path(path)
    out = McapContents(path)
    try:
        with open(path, 'rb') as stream:
            size = stream.seek(0, io.SEEK_END)
            out.size = size
            if size == 0:
                raise BagError(f'{path}: empty file, not an MCAP file')
            stream.seek(0)
            head = stream.read(len(MAGIC))
            if head != MAGIC[:len(head)]:
                raise BagError(f'{path}: not an MCAP file (magic {head[:8]!r})')
            if len(head) < len(MAGIC):
                raise BagError(f'{path}: truncated inside the MCAP magic, nothing to read')
            with mmap.mmap(stream.fileno(), 0, access=mmap.ACCESS_READ) as buf:
                reader = _Reader(buf, out)
                kinds, why = reader.summary()
                if kinds:
                    reader.indexed(kinds)
                else:
                    if out.complete:
                        out.problems.append(f'{why}: the file is read record by record')
                        out.complete = False
                    reader.scan()
    except OSError as err:
        raise BagError(f'cannot read {path}: {err.strerror or err}') from err
    _count_losses(out)
    return out


def _count_losses(out: McapContents) -> None:
    """Count the losses per channel: recorded minus readable, where the file has counts."""
    for cid in list(out.counts):
        if cid not in out.channels:
            out.orphans[cid] = out.counts.pop(cid)
    if out.recorded is not None:
        if all(out.recorded.get(c, 0) >= n for c, n in out.counts.items()):
            out.lost = {c: n - out.counts.get(c, 0) for c, n in out.recorded.items()
                        if n > out.counts.get(c, 0)}
            for c, n in out.orphans.items():
                if c in out.lost:
                    out.lost[c] = max(0, out.lost[c] - n)
            out.lost = {c: n for c, n in out.lost.items() if n}
            # the recorded counts account for everything: no unknown loss left
            out.unknown_loss.clear()
        else:
            out.problems.append('the statistics record counts fewer messages than were '
                                'read: ignored')
            out.recorded = None
    if out.orphans:
        out.problems.append(
            f'{sum(out.orphans.values())} messages on channels whose channel record was '
            f'lost (ids {sorted(out.orphans)}): not readable')


def iter_messages(contents: McapContents, channel_ids: set[int] | None = None
                  ) -> Iterator[Message]:
    """Yield the readable messages of ``channel_ids`` (all if None) in log-time order.

    Raises
    ------
    BagError
        If the file cannot be read again or changed since :func:`read_mcap`.
    """
    def wanted(msg: Message) -> bool:
        return msg.channel_id in contents.channels and (
            channel_ids is None or msg.channel_id in channel_ids)

    chunks = sorted(contents.chunks, key=lambda c: (c.start, c.offset))
    loose = sorted((m for m in contents.loose if wanted(m)), key=lambda m: m.log_time)
    if not chunks:
        yield from loose
        return
    try:
        with open(contents.path, 'rb') as stream, \
                mmap.mmap(stream.fileno(), 0, access=mmap.ACCESS_READ) as buf:
            heap: list = [(m.log_time, -1, i, m) for i, m in enumerate(loose)]
            heapq.heapify(heap)
            i = 0
            while heap or i < len(chunks):
                if i < len(chunks) and (not heap or chunks[i].start <= heap[0][0]):
                    ref = chunks[i]
                    try:
                        opcode, length, chunk = _Reader(buf, contents).record(ref.offset)
                        records = _chunk_records(chunk)
                    except Exception as err:    # noqa: B902 -- the file changed under us
                        raise BagError(f'{contents.path}: the chunk at byte {ref.offset} '
                                       f'no longer reads ({err}): the file changed') from err
                    for j, rec in enumerate(records):
                        if isinstance(rec, Message) and wanted(rec):
                            heapq.heappush(heap, (rec.log_time, i, j, rec))
                    i += 1
                    continue
                yield heapq.heappop(heap)[3]
    except OSError as err:
        raise BagError(f'cannot read {contents.path}: {err.strerror or err}') from err
