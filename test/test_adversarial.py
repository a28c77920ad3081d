"""Issue 24: nothing lost, nothing frozen, nothing silently wrong (the adversarial findings).

One regression test per numbered finding of the issue (each failed before the fix); the
bag-damage matrix is in test_bag_damage.py.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import warnings

from gyro_rotor.analysis.offline import analyze_bag
from gyro_rotor.bag.bagio import BagWriter, open_bag
import gyro_rotor.cli.main as cli
from mcap.reader import SeekingReader
import pytest

REPO = Path(__file__).resolve().parent.parent
BAGS = REPO / 'bags'


# -- helpers ------------------------------------------------------------------------------------
def string_cdr(text: str) -> bytes:
    raw = text.encode() + b'\x00'
    return b'\x00\x01\x00\x00' + len(raw).to_bytes(4, 'little') + raw + b'\x00' * (
        (-len(raw)) % 4)


def energy_cdr(label: str, values) -> bytes:
    from rclpy.serialization import serialize_message
    from std_msgs.msg import Float64MultiArray, MultiArrayDimension
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label=label, size=len(values), stride=len(values))]
    msg.data = [float(v) for v in values]
    return serialize_message(msg)


def energy_label(bag: Path = BAGS / 'precession') -> str:
    for _, _, msg in open_bag(bag).decoded('/energy'):
        return msg.layout.dim[0].label


def malformed_messages(label: str) -> list[tuple[str, bytes]]:
    """Return the messages of finding 1 and their kin: each broke or froze the analysis."""
    n = len(label.split(','))
    t_at = label.split(',').index('t_sim')

    def with_t(t):
        v = [1.0] * n
        v[t_at] = t
        return v
    return [
        ('/rotor_sim/scene', string_cdr('[' * 10000 + ']' * 10000)),   # RecursionError
        ('/energy', energy_cdr(label, with_t(1e300))),                 # OverflowError
        ('/energy', energy_cdr(label, [math.nan] * n)),                 # ValueError
        ('/energy', energy_cdr(label, with_t(1e200))),                 # a time out of range
        ('/energy', energy_cdr(label, [1.0, 2.0])),                     # wrong length
        ('/energy', energy_cdr('a,b', [1.0, 2.0])),                     # a foreign layout
        ('/energy', b'\x00\x01\x00\x00\xff\xff\xff\xff'),               # CDR overrun
        ('/joint_states', b'\x00\x01\x00\x00' + os.urandom(40)),        # random bytes
        ('/joint_states', b''),                                         # empty
        ('/rotor_sim/scene', string_cdr('{garbage: [')),                # finding 4
        ('/rotor_sim/scene', string_cdr('42')),                         # finding 4
        ('/rotor_sim/scene', b'\x00\x01\x00\x00\x05\x00\x00\x00ab'),    # cut string
    ]


def copy_with(src: Path, dst: Path, extra: list[tuple[str, bytes]], every: int = 97) -> int:
    """Copy a bag, slipping ``extra`` messages in between the recorded ones; return count."""
    reader = open_bag(src)
    meta = {k: v for k, v in reader.metadata.items() if k != 'rosbag2'}
    pending = list(extra)
    with BagWriter(dst, metadata=meta) as w:
        for topic, info in reader.topics.items():
            w.add_topic(topic, info.type)
        for i, (topic, t, data) in enumerate(reader.messages()):
            w.write(topic, data, t)
            if pending and i % every == 50:
                w.write(*pending.pop(0)[:2], t)
    assert not pending
    return len(extra)


# -- finding 1: one malformed message froze the live analysis ----------------------------------
def test_live_analysis_counts_malformed_messages_and_goes_on():
    """Finding 1 (live): a malformed message froze the analysis.

    _feed let any exception but two through, and the message stayed at the head of the
    pending list, so every later message failed on it (the verdict froze).
    """
    import rclpy
    from gyro_rotor.ros.analysis_node import RotorAnalysisNode
    from rclpy.parameter import Parameter
    label = energy_label()
    bad = malformed_messages(label)
    real = list(open_bag(BAGS / 'precession').messages(
        ['/energy', '/joint_states', '/rotor_sim/scene']))
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    try:
        def run(extra):
            node = RotorAnalysisNode(context=ctx, parameter_overrides=[
                Parameter('record', value=False), Parameter('window_s', value=8.0)])
            try:
                node.energy_topic, node.joints_topic = '/energy', '/joint_states'
                node.scene_topic = '/rotor_sim/scene'
                queue = list(extra)
                for i, (topic, _, data) in enumerate(real):
                    node._on_bytes(topic, data)
                    if queue and i % 300 == 150:
                        node._on_bytes(*queue.pop(0))
                assert not queue and node._pending == []
                node.session.finish()
                return node.session.result(), node.session
            finally:
                node.destroy_node()
        clean, _ = run([])
        dirty, session = run(bad)
    finally:
        rclpy.try_shutdown(context=ctx)
    assert clean.confirmed
    assert dirty.verdict == clean.verdict and dirty.samples == clean.samples == 3001
    assert [c.line() for c in dirty.criteria] == [c.line() for c in clean.criteria]
    assert session.rejected_count == len(bad)
    reasons = ' | '.join(r for per in session.rejected.values() for r in per)
    for reason in ('nested more than 64', 't_sim = 1e+300', 't_sim = nan', 'CdrError',
                   'has 2 values', 'not a scene document'):
        assert reason in reasons, reasons
    assert session.rejected_text().startswith(f'{len(bad)} messages ignored')


def test_live_verdict_goes_stale_when_no_data_is_usable():
    """Finding 1: the live verdict goes stale, never stays at the last good value.

    It stayed 'asymptotically stable' while data stopped being used; now it says stale (and
    error when the analysis itself fails).
    """
    import rclpy
    from gyro_rotor.ros.analysis_node import RotorAnalysisNode
    from rclpy.parameter import Parameter
    real = list(open_bag(BAGS / 'precession').messages(['/energy', '/joint_states']))
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    try:
        node = RotorAnalysisNode(context=ctx, parameter_overrides=[
            Parameter('record', value=False), Parameter('scene', value='precession')])
        sent = []
        node.pub_verdict.publish = sent.append
        try:
            node.energy_topic, node.joints_topic = '/energy', '/joint_states'
            for topic, _, data in real[:2000]:
                node._on_bytes(topic, data)
            node.publish_results()
            assert sent[-1].data.startswith('asymptotically stable'), sent[-1].data
            for _ in range(50):                     # data arrives, none of it usable
                node._on_bytes('/energy', b'\x00\x01\x00\x00')
            node.publish_results()
            assert sent[-1].data.startswith('stale: 50 energy/joint_states messages'), \
                sent[-1].data
            for topic, _, data in real[2000:2100]:  # usable again
                node._on_bytes(topic, data)
            node.publish_results()
            assert sent[-1].data.startswith('asymptotically stable'), sent[-1].data

            def broken():
                raise OverflowError('int too large to convert to float')
            node.session.result = broken
            node.publish_results()
            assert sent[-1].data.startswith('error: the analysis failed (OverflowError'), \
                sent[-1].data
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)


def test_offline_analysis_of_a_bag_with_malformed_messages(tmp_path):
    """Findings 1 and 4 (offline): malformed messages are counted, the rest analysed.

    analyze ended in the same traceback; one bad scene document made the whole bag
    unanalysable.
    """
    bag = tmp_path / 'dirty'
    n = copy_with(BAGS / 'precession', bag, malformed_messages(energy_label()))
    clean = analyze_bag(BAGS / 'precession').result
    ana = analyze_bag(bag)
    res = ana.result
    assert res.verdict == clean.verdict and res.confirmed
    assert res.samples == clean.samples == 3001
    line = next(e for e in res.evidence if 'messages ignored' in e)
    assert line.startswith(f'{n} messages ignored'), line
    # through the command line: rc 0, no traceback
    assert cli.main(['analyze', str(bag), '--no-plots']) == 0


# -- finding 2: the reader stopped at the first damaged chunk ----------------------------------
def _flip_in_chunk(bag: Path, k: int) -> None:
    mcap = next(bag.glob('*.mcap'))
    with open(mcap, 'rb') as f:
        chunks = sorted(SeekingReader(f).get_summary().chunk_indexes,
                        key=lambda c: c.chunk_start_offset)
    b = bytearray(mcap.read_bytes())
    c = chunks[k]
    b[c.chunk_start_offset + c.chunk_length // 2] ^= 0x01
    mcap.write_bytes(bytes(b))


def test_damaged_bag_is_never_a_plain_confirmed(tmp_path, capsys):
    """Finding 2: one bit flipped in chunk 11 of a recorded bag.

    It gave '[PASS] data: 738 samples, 0 messages lost', CONFIRMED, rc 0; after recover the
    note was gone too.
    """
    bag = tmp_path / 'flipped'
    shutil.copytree(BAGS / 'precession', bag)
    _flip_in_chunk(bag, 11)
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        reader = open_bag(bag)
        ana = analyze_bag(bag)
    lost_energy = reader.lost['/energy']
    assert reader.topics['/energy'].count + lost_energy == 3001 and lost_energy > 0
    assert ana.result.samples == 3001 - lost_energy
    data = next(c for c in ana.result.criteria if str(c.name) == 'data')
    assert str(data.status) == 'FAIL' and f'/energy {lost_energy}' in data.line()
    assert not ana.result.confirmed
    assert cli.main(['analyze', str(bag), '--no-plots']) == 2
    out = capsys.readouterr().out
    assert 'RESULT: NOT CONFIRMED' in out and 'recorded messages lost' in out
    assert cli.main(['recover', str(bag)]) == 0
    assert 'lost' in capsys.readouterr().out
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        again = analyze_bag(bag)
    assert not again.result.confirmed and again.result.samples == ana.result.samples
    assert cli.main(['analyze', str(bag), '--no-plots']) == 2


@pytest.mark.parametrize('fraction', [0.5, 0.9])
def test_truncated_bag_counts_its_loss_against_metadata_yaml(tmp_path, fraction):
    """Finding 2: a bag cut at 50 % / 90 %: '0 messages lost', CONFIRMED."""
    bag = tmp_path / 'cut'
    shutil.copytree(BAGS / 'precession', bag)
    mcap = next(bag.glob('*.mcap'))
    data = mcap.read_bytes()
    mcap.write_bytes(data[:int(len(data) * fraction)])
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        reader = open_bag(bag)
        ana = analyze_bag(bag)
    n = reader.topics['/energy'].count
    assert 0 < n < 3001 and reader.lost['/energy'] == 3001 - n
    assert reader.unknown_loss == [] and reader.truncated
    assert not ana.result.confirmed and ana.result.samples == n


# -- finding 5: the demo's nodes outlived a SIGTERM --------------------------------------------
def _children(pid: int) -> list[int]:
    """Return the processes whose parent is ``pid``."""
    out = []
    for entry in os.listdir('/proc'):
        if entry.isdigit():
            try:
                stat = Path(f'/proc/{entry}/stat').read_text()
            except OSError:
                continue
            if int(stat.rsplit(')', 1)[1].split()[1]) == pid:
                out.append(int(entry))
    return out


def _alive(pid: int) -> bool:
    try:
        stat = Path(f'/proc/{pid}/stat').read_text()
    except OSError:
        return False
    return stat.rsplit(')', 1)[1].split()[0] != 'Z'


@pytest.mark.ros
@pytest.mark.parametrize('sig', [signal.SIGTERM, signal.SIGKILL])
def test_demo_ends_its_nodes_however_it_ends(tmp_path, sig):
    """Finding 5: demo killed by SIGTERM (or timeout) left both nodes running, PPID 1."""
    from node_helpers import wait_until
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    log = tmp_path / 'demo.log'
    proc = subprocess.Popen([sys.executable, '-m', 'gyro_rotor.cli.main', 'demo',
                             '--duration', '60', '--quiet', '--out', str(tmp_path / 'run')],
                            stdout=open(log, 'w'), stderr=subprocess.STDOUT, env=env)
    nodes: list[int] = []
    try:
        nodes = wait_until(lambda: len(_children(proc.pid)) == 2 and _children(proc.pid),
                           'both nodes started', proc, timeout=120)
        wait_until(lambda: (tmp_path / 'run' / 'bag').exists(), 'the bag', proc,
                   timeout=60)
        proc.send_signal(sig)
        rc = proc.wait(timeout=60)
        assert rc == (128 + sig if sig != signal.SIGKILL else -sig), log.read_text()
        wait_until(lambda: not any(_alive(p) for p in nodes), 'the nodes to end',
                   timeout=40)
    finally:
        if proc.poll() is None:
            proc.kill()
        for p in nodes:
            if _alive(p):
                os.kill(p, signal.SIGKILL)
    if sig == signal.SIGTERM:
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')
            assert not open_bag(tmp_path / 'run' / 'bag').truncated   # finalized
