"""Damaged bags (issue 24, findings 2 and 3): every intact chunk read, every loss counted.

A bag is written with small chunks (uncompressed and zstd), then damaged in 14 ways at
three places (the first, a middle and the last chunk). Whatever the damage, the reader and
``recover`` must give exactly the messages of every chunk the damage did not touch (in
log-time order), every metadata record it did not touch, and count the loss per topic
exactly against the counts the bag recorded. The expected sets are computed from the
undamaged file's own chunk index, independently of the reader.

Before issue 24 the reader stopped at the first damaged record: a bit flipped in one chunk
lost every chunk after it and reported ``0 messages lost``.
"""

from __future__ import annotations

import random
import shutil
import struct
import warnings

from gyro_rotor.bag.bagio import BagWarning, BagWriter, open_bag, recover_bag
from mcap.reader import SeekingReader
from mcap.records import Message
from mcap.stream_reader import breakup_chunk
import pytest

TOPICS = {'/energy': 'std_msgs/msg/Float64', '/joint_states': 'std_msgs/msg/Float64',
          '/rotor_sim/scene': 'std_msgs/msg/String'}


def f64(x: float) -> bytes:
    return b'\x00\x01\x00\x00' + struct.pack('<d', x)


def string(text: str) -> bytes:
    raw = text.encode() + b'\x00'
    return b'\x00\x01\x00\x00' + struct.pack('<I', len(raw)) + raw


def write_bag(path, compression: str) -> None:
    with BagWriter(path, chunk_size=3000, compression=compression,
                   metadata={'gyro_rotor.first': {'k': 'v' * 50}}) as w:
        for topic, type_name in TOPICS.items():
            w.add_topic(topic, type_name)
        for i in range(1200):
            t = 1_000_000_000 + i * 1000
            if i % 3 == 0:
                w.write('/energy', f64(i * 0.5), t)
            elif i % 3 == 1:
                w.write('/joint_states', f64(-i * 0.25), t)
            elif i % 60 == 2:
                w.write('/rotor_sim/scene', string(f'doc {i} ' + 'x' * (i % 97)), t)
            if i == 600:
                w.add_metadata('gyro_rotor.middle', {'n': str(i)})


class Layout:
    """The undamaged file: chunks (offset, length, messages), metadata records, totals."""

    def __init__(self, path):
        with open(path, 'rb') as f:
            reader = SeekingReader(f)
            summary = reader.get_summary()
            names = {c.id: c.topic for c in summary.channels.values()}
            self.chunks = []
            for ci in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
                f.seek(ci.chunk_start_offset + 9)
                from mcap.data_stream import ReadDataStream
                from mcap.records import Chunk
                chunk = Chunk.read(ReadDataStream(f))
                msgs = [(names[m.channel_id], m.log_time, m.data)
                        for m in breakup_chunk(chunk) if isinstance(m, Message)]
                self.chunks.append((ci.chunk_start_offset, ci.chunk_length, msgs))
            self.meta = [(m.offset, m.length, m.name) for m in summary.metadata_indexes]
            self.summary_start = f.seek(0, 2) - 8 - 29
        self.total: dict[str, int] = {}
        for _, _, msgs in self.chunks:
            for topic, _, _ in msgs:
                self.total[topic] = self.total.get(topic, 0) + 1

    def expected(self, touched) -> tuple[list, set]:
        """Return the messages of the chunks and the metadata records ``touched`` spares."""
        def hit(off, length):
            return any(touches(off, length) for touches in touched)
        msgs = sorted((m for off, n, ms in self.chunks if not hit(off, n) for m in ms),
                      key=lambda m: m[1])
        meta = {name for off, n, name in self.meta if not hit(off, n)}
        return msgs, meta


def overlap(a: int, b: int):
    """Damage bytes [a, b) of the original file."""
    return lambda off, n: off < b and a < off + n


def inside(p: int):
    """Insert or remove bytes at p: a record is hit if p lies strictly inside it."""
    return lambda off, n: off < p < off + n


def after(p: int):
    """Cut the file at p: every record not wholly before p is lost."""
    return lambda off, n: off + n > p


def damage(kind: str, data: bytes, lay: Layout, k: int, rng: random.Random):
    """Return (damaged bytes, touched predicates, whether counts stay known)."""
    off, n, _ = lay.chunks[k]
    mid = off + n // 2
    b = bytearray(data)
    if kind == 'flip_data':
        b[mid] ^= 0x10
        return bytes(b), [overlap(mid, mid + 1)]
    if kind == 'flip_length':
        b[off + 6] ^= 0x01               # a high byte of the 8-byte length: far too long
        return bytes(b), [overlap(off + 6, off + 7)]
    if kind == 'opcode':
        b[off] = 0x00
        return bytes(b), [overlap(off, off + 1)]
    if kind == 'zero_block':
        b[mid:mid + 512] = bytes(len(b[mid:mid + 512]))
        return bytes(b), [overlap(mid, mid + 512)]
    if kind == 'random_block':
        b[off:off + n] = rng.randbytes(n)
        return bytes(b), [overlap(off, off + n)]
    if kind == 'delete':
        del b[mid:mid + 37]
        return bytes(b), [overlap(mid, mid + 37)]
    if kind == 'insert':
        b[mid:mid] = rng.randbytes(53)
        return bytes(b), [inside(mid)]
    if kind == 'insert_between':
        b[off:off] = rng.randbytes(64)
        return bytes(b), [inside(off)]
    if kind == 'cut':
        return bytes(b[:mid]), [after(mid)]
    if kind == 'two_chunks':
        j = (k + 2) % len(lay.chunks)
        o2, n2, _ = lay.chunks[j]
        b[mid] ^= 0x01
        b[o2 + n2 // 2] ^= 0x80
        return bytes(b), [overlap(mid, mid + 1), overlap(o2 + n2 // 2, o2 + n2 // 2 + 1)]
    if kind == 'summary':
        p = lay.summary_start - 200 + 17 * k     # inside the summary section
        b[p] ^= 0xFF
        return bytes(b), [overlap(p, p + 1)]
    if kind == 'footer':
        b[-40:] = bytes(40)
        return bytes(b), [overlap(len(b) - 40, len(b))]
    if kind == 'metadata':
        moff, mlen, _ = lay.meta[1]      # the record added mid-way
        b[moff + 9 + 2] ^= 0x7F          # its name length
        return bytes(b), [overlap(moff, moff + mlen)]
    if kind == 'message_index':
        p = off + n + 9 + 3              # inside the message index after the chunk
        b[p] ^= 0x55
        return bytes(b), [overlap(p, p + 1)]
    raise AssertionError(kind)


KINDS = ['flip_data', 'flip_length', 'opcode', 'zero_block', 'random_block', 'delete',
         'insert', 'insert_between', 'cut', 'two_chunks', 'summary', 'footer', 'metadata',
         'message_index']


@pytest.fixture(scope='module')
def pristine(tmp_path_factory):
    out = {}
    for compression in ('none', 'zstd'):
        path = tmp_path_factory.mktemp('bags') / f'b_{compression}'
        write_bag(path, compression)
        mcap = path / f'b_{compression}_0.mcap'
        lay = Layout(mcap)
        assert len(lay.chunks) >= 8, len(lay.chunks)
        out[compression] = (path, mcap.read_bytes(), lay)
    return out


def read_all(path):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always', BagWarning)
        reader = open_bag(path)
        msgs = list(reader.messages())
    return reader, msgs, [str(w.message) for w in caught]


@pytest.mark.parametrize('compression', ['none', 'zstd'])
@pytest.mark.parametrize('place', ['first', 'middle', 'last'])
@pytest.mark.parametrize('kind', KINDS)
def test_damage_keeps_every_intact_chunk_and_counts_the_loss(
        pristine, tmp_path, kind, place, compression):
    src, data, lay = pristine[compression]
    k = {'first': 0, 'middle': len(lay.chunks) // 2, 'last': len(lay.chunks) - 1}[place]
    rng = random.Random(f'{kind}{place}{compression}')
    bad, touched = damage(kind, data, lay, k, rng)
    bag = tmp_path / 'bag'
    shutil.copytree(src, bag)
    mcap = bag / f'b_{compression}_0.mcap'
    mcap.write_bytes(bad)
    want, want_meta = lay.expected(touched)

    reader, got, warned = read_all(bag)
    assert got == want, (f'{kind}/{place}: {len(got)} messages read, {len(want)} in the '
                         f'intact chunks')
    assert want_meta <= set(reader.metadata), sorted(reader.metadata)
    # a lost metadata record is named: those written when the file was closed when they
    # went with its end, a damaged one by its name (the summary still indexes it)
    missing = {name for _, _, name in lay.meta} - want_meta
    assert bool(reader.lost_records) == bool(missing), reader.lost_records
    if kind == 'metadata':
        assert any("the metadata record 'gyro_rotor.middle' (damaged)" in r
                   for r in reader.lost_records)
    readable = {t: sum(1 for m in want if m[0] == t) for t in lay.total}
    lost = {t: n - readable[t] for t, n in lay.total.items() if n > readable[t]}
    assert reader.lost == lost, reader.problems
    assert reader.unknown_loss == []            # the bag recorded its counts: loss is exact
    if kind == 'message_index':
        # the chunk index is what the reader uses; a damaged message index loses nothing
        assert got == [m for _, _, ms in lay.chunks for m in ms] and not lost
        return
    assert reader.damaged and warned
    if lost:
        assert f'{sum(lost.values())} recorded messages lost' in reader.loss_text()

    # recover keeps the same messages and carries the loss on into the repaired bag
    report = recover_bag(bag)
    assert report.was_damaged and report.lost == lost
    again, got2, warned2 = read_all(bag)
    assert got2 == want and again.lost == lost and not again.truncated
    # nothing lost: the repaired bag is whole; lost records stay on record like messages
    assert again.damaged == bool(lost or reader.lost_records)
    assert again.lost_records == [f'before the recovery: {r}' for r in reader.lost_records]
    assert want_meta <= set(again.metadata)
    assert recover_bag(bag).rewritten == ()     # complete now: nothing more to do


def test_undamaged_bag_reads_whole_and_clean(pristine):
    for src, data, lay in pristine.values():
        reader, got, warned = read_all(src)
        assert len(got) == sum(lay.total.values()) and warned == []
        assert reader.lost == {} and not reader.damaged and reader.unknown_loss == []


def test_cut_bare_file_says_the_loss_is_of_unknown_size(pristine, tmp_path):
    """A cut .mcap without metadata.yaml records no counts: the loss is flagged, not guessed."""
    src, data, lay = pristine['none']
    off, n, _ = lay.chunks[len(lay.chunks) // 2]
    path = tmp_path / 'cut.mcap'
    path.write_bytes(data[:off + n // 2])
    reader, got, _ = read_all(path)
    want, _ = lay.expected([after(off + n // 2)])
    assert got == want
    assert reader.truncated and reader.damaged and reader.unknown_loss
    assert 'loss of unknown size' in reader.loss_text()
    report = recover_bag(path)
    again, got2, _ = read_all(path)
    assert got2 == want and again.unknown_loss and not again.truncated
    assert report.unknown_loss


def test_damaged_scene_record_loses_no_message(tmp_path):
    """Finding 3: four bytes flipped inside the gyro_rotor.scene record of a recorded bag."""
    from pathlib import Path
    src = Path(__file__).resolve().parent.parent / 'bags' / 'precession'
    bag = tmp_path / 'precession'
    shutil.copytree(src, bag)
    mcap = bag / 'precession_0.mcap'
    with open(mcap, 'rb') as f:
        index = next(m for m in SeekingReader(f).get_summary().metadata_indexes
                     if m.name == 'gyro_rotor.scene')
    b = bytearray(mcap.read_bytes())
    for i in range(4):
        b[index.offset + 9 + 30 + i] ^= 0xFF
    mcap.write_bytes(bytes(b))
    reader, got, _ = read_all(bag)
    assert reader.topics['/energy'].count == 3001 and reader.lost == {}
    # no message is lost, the record is: said so, not 'nothing lost' (adversarial finding)
    lost = "the metadata record 'gyro_rotor.scene' (damaged)"
    assert 'gyro_rotor.scene' not in reader.metadata and lost in reader.loss_text()
    report = recover_bag(bag)
    assert report.messages_per_topic['/energy'] == 3001
    assert any(lost in r for r in report.lost_records)
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', BagWarning)
        again = open_bag(bag)
    assert again.topics['/energy'].count == 3001
    assert any(lost in r for r in again.lost_records)       # kept on record by the recovery


def test_cut_after_the_last_chunk_names_the_lost_live_verdict(tmp_path, capsys):
    """Review finding: a recorded bag cut after its last chunk, before the metadata records.

    Every message is there and metadata.yaml accounts for them, but the live verdict
    (``gyro_rotor.live_result``) and the ``rosbag2`` record went with the file's end. The
    loss line said 'nothing lost'; it must name them, in analyze's line and after a recovery.
    """
    from pathlib import Path
    from gyro_rotor.cli.main import main
    src = Path(__file__).resolve().parent.parent / 'bags' / 'precession'
    bag = tmp_path / 'precession'
    shutil.copytree(src, bag)
    mcap = bag / 'precession_0.mcap'
    with open(mcap, 'rb') as f:
        summary = SeekingReader(f).get_summary()
    live = next(m for m in summary.metadata_indexes if m.name == 'gyro_rotor.live_result')
    last_chunk = max(c.chunk_start_offset + c.chunk_length for c in summary.chunk_indexes)
    assert last_chunk <= live.offset
    mcap.write_bytes(mcap.read_bytes()[:live.offset])
    reader, got, _ = read_all(bag)
    assert reader.lost == {} and reader.unknown_loss == [] and len(got) == sum(
        t.count for t in open_bag(src).topics.values())
    assert 'gyro_rotor.live_result' not in reader.metadata
    assert reader.lost_records and 'nothing lost' not in reader.loss_text()
    assert main(['analyze', str(bag), '--no-plots']) == 0
    result = capsys.readouterr().out.strip().splitlines()[-1]
    assert result.startswith('RESULT: CONFIRMED') and 'records lost' in result, result
    recover_bag(bag)
    assert main(['analyze', str(bag), '--no-plots']) == 0
    result = capsys.readouterr().out.strip().splitlines()[-1]
    assert 'records lost: before the recovery' in result, result


def test_a_bag_missing_samples_the_live_analysis_saw_is_not_confirmed(tmp_path, capsys):
    """Review finding: half a split bag, its other file and metadata.yaml gone.

    The remaining file is complete and its own counts match what it holds, so the reader
    sees no loss; the live verdict recorded in it says how many samples the live analysis
    saw (3001), and the bag holds fewer: the data criterion must count them as lost.
    """
    from pathlib import Path
    from gyro_rotor.cli.main import main
    src = Path(__file__).resolve().parent.parent / 'bags' / 'precession'
    reader = open_bag(src)
    assert reader.metadata['gyro_rotor.live_result']['samples'] == '3001'
    bag = tmp_path / 'half'
    with BagWriter(bag, metadata={k: v for k, v in reader.metadata.items()
                                  if k != 'rosbag2'}) as w:
        for topic, info in reader.topics.items():
            w.add_topic(topic, info.type)
        messages = list(reader.messages())
        cut = [t for topic, t, _ in messages if topic == '/energy'][1500]
        for topic, t, data in messages:
            if t < cut:
                w.write(topic, data, t)
    (bag / 'metadata.yaml').unlink()
    half = open_bag(bag)
    assert half.lost == {} and half.unknown_loss == [] and not half.lost_records
    assert main(['analyze', str(bag), '--no-plots']) != 0
    out = capsys.readouterr().out
    result = out.strip().splitlines()[-1]
    assert 'NOT CONFIRMED' in result and 'data' in result, result
    import re
    n = int(re.search(r'^samples (\d+),', out, re.M).group(1))
    assert n < 1600
    assert f'{3001 - n} of the 3001 samples the live analysis saw are not in the bag' in out
