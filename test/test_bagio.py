"""Tests of gyro_rotor.bagio: rosbag2 MCAP bags read back by three independent readers.

Readers: (a) ``mcap`` + ``mcap_ros2.decoder.DecoderFactory``, (b) ``rosbags.highlevel.AnyReader``
with the Jazzy typestore (it also checks the QoS pairing of metadata.yaml and channels and
the RIHS01 hashes), (c) a structural check of the records that ``ros2 bag info`` needs.
Tests that serialize real messages import rclpy inside and skip without it.
"""

from __future__ import annotations

import os
from pathlib import Path
import shutil
import signal
import struct
import subprocess
import sys
import textwrap
import time
import warnings

from gyro_rotor.bag.bagio import (BagError, BagWarning, BagWriter, message_definition,
                                  normalize_qos, open_bag, qos_profile_dict, recover_bag,
                                  type_hash)
from gyro_rotor.bag.msgdefs import DELIMITER
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]
FLOAT64 = 'std_msgs/msg/Float64'


def f64(value: float) -> bytes:
    """Return the CDR (little endian) of std_msgs/Float64, without rclpy."""
    return b'\x00\x01\x00\x00' + struct.pack('<d', value)


def anyreader_read(path: Path) -> tuple[dict[str, int], list[tuple[str, int, object]]]:
    """Read a bag with rosbags AnyReader: counts per topic and decoded messages."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import get_typestore, Stores

    with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        msgs = [(c.topic, t, reader.deserialize(raw, c.msgtype))
                for c, t, raw in reader.messages()]
    return counts, msgs


def mcap_read(path: Path) -> list[tuple[str, int, object]]:
    """Read an .mcap file with the mcap reader and the mcap_ros2 decoder."""
    with open(path, 'rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        return [(ch.topic, m.log_time, dec)
                for _, ch, m, dec in reader.iter_decoded_messages(log_time_order=True)]


def check_structure(bag: Path) -> dict[str, int]:
    """Check the records rosbag2 and Foxglove need; return the Statistics counts per topic."""
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['version'] == 9 and info['storage_identifier'] == 'mcap'
    assert info['ros_distro'] == 'jazzy' and info['custom_data'] == {}
    assert info['compression_format'] == '' and info['compression_mode'] == ''
    mcap_path = bag / info['relative_file_paths'][0]
    assert [f['path'] for f in info['files']] == info['relative_file_paths']
    by_topic = {t['topic_metadata']['name']: t for t in info['topics_with_message_count']}
    with open(mcap_path, 'rb') as stream:
        reader = make_reader(stream)
        assert reader.get_header().profile == 'ros2'
        assert 'gyro_rotor' in reader.get_header().library
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        records = {m.name: m.metadata for m in reader.iter_metadata()}
    counts = {}
    for cid, channel in summary.channels.items():
        schema = summary.schemas[channel.schema_id]
        assert channel.message_encoding == 'cdr'
        assert schema.encoding == 'ros2msg' and schema.data
        assert schema.data.decode() == message_definition(schema.name)
        meta = by_topic[channel.topic]['topic_metadata']
        assert meta['type'] == schema.name and meta['serialization_format'] == 'cdr'
        qos = yaml.safe_load(channel.metadata['offered_qos_profiles'])
        assert qos == meta['offered_qos_profiles'] and qos
        assert channel.metadata['topic_type_hash'] == meta['type_description_hash']
        assert meta['type_description_hash'] == type_hash(schema.name)
        counts[channel.topic] = summary.statistics.channel_message_counts.get(cid, 0)
        assert counts[channel.topic] == by_topic[channel.topic]['message_count']
    assert sum(counts.values()) == info['message_count'] == summary.statistics.message_count
    serialized = yaml.safe_load(records['rosbag2']['serialized_metadata'])
    assert serialized['version'] == 9 and serialized['message_count'] == info['message_count']
    return counts


def values(msg: object) -> tuple:
    """Return comparable field values of the test messages, whatever reader decoded them."""
    def floats(seq: object) -> list[float]:
        return [float(x) for x in seq]

    def byte(value: object) -> int:
        return value[0] if isinstance(value, bytes) else int(value)

    if hasattr(msg, 'effort'):
        return ('js', msg.header.stamp.sec, msg.header.frame_id, list(msg.name),
                floats(msg.position), floats(msg.velocity), floats(msg.effort))
    if hasattr(msg, 'layout'):
        return ('arr', [(d.label, d.size, d.stride) for d in msg.layout.dim],
                floats(msg.data))
    if hasattr(msg, 'status'):
        return ('diag', [(byte(s.level), s.name, s.message,
                          [(kv.key, kv.value) for kv in s.values]) for s in msg.status])
    if hasattr(msg, 'mesh_file'):
        return ('marker', msg.ns, msg.id, msg.type, msg.pose.orientation.w, msg.scale.x,
                msg.color.g, msg.lifetime.sec, [(p.x, p.y, p.z) for p in msg.points],
                msg.text)
    if hasattr(msg, 'clock'):
        return ('clock', msg.clock.sec, msg.clock.nanosec)
    return ('f64', msg.data)


def ros_messages() -> list[tuple[str, str, object]]:
    """Real messages of several types (rclpy); skip if rclpy is missing."""
    pytest.importorskip('rclpy')
    from builtin_interfaces.msg import Duration
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from geometry_msgs.msg import Point
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray, MultiArrayDimension
    from visualization_msgs.msg import Marker

    out = []
    for i in range(30):
        js = JointState(name=['rotor_spin', 'gimbal_inner', 'gimbal_outer'],
                        position=[0.1 * i, -0.2, 3.0], velocity=[100.0 + i, 0.5, -0.5],
                        effort=[1.5, 0.0, 2.5 * i])
        js.header.stamp.sec = i
        js.header.frame_id = 'base'
        out.append(('/joint_states', 'sensor_msgs/msg/JointState', js))
        clock = Clock()
        clock.clock.sec, clock.clock.nanosec = i, 500_000_000
        out.append(('/clock', 'rosgraph_msgs/msg/Clock', clock))
        if i % 3 == 0:
            arr = Float64MultiArray(data=[float(i), 2.0, 1e-9])
            arr.layout.dim = [MultiArrayDimension(label='state', size=3, stride=3)]
            out.append(('/energy', 'std_msgs/msg/Float64MultiArray', arr))
        if i % 10 == 0:
            status = DiagnosticStatus(level=DiagnosticStatus.WARN, name='sim: energy',
                                      message=f'drift {i}', hardware_id='rotor',
                                      values=[KeyValue(key='drift', value=str(1e-6 * i))])
            out.append(('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray',
                        DiagnosticArray(status=[status])))
            marker = Marker(ns='rotor', id=i, type=Marker.ARROW, text='axis',
                            lifetime=Duration(sec=2),
                            points=[Point(x=0.0, y=0.0, z=0.0), Point(x=1.0, y=2.0, z=3.0)])
            marker.scale.x, marker.color.g, marker.color.a = 0.05, 1.0, 1.0
            out.append(('/marker', 'visualization_msgs/msg/Marker', marker))
    return out


def write_ros_bag(bag: Path, **kwargs: object) -> list[tuple[str, int, object, bytes]]:
    """Write ros_messages() to a bag; return the (topic, log_time, msg, data) written.

    The data is kept: rclpy's serialize_message leaves alignment padding bytes
    uninitialized, so serializing the same message twice can give different bytes.
    """
    from rclpy.serialization import serialize_message

    written = []
    with BagWriter(bag, **kwargs) as writer:
        for k, (topic, type_name, msg) in enumerate(ros_messages()):
            qos = (qos_profile_dict(reliability='best_effort', depth=1) if topic == '/clock'
                   else qos_profile_dict(durability='transient_local', depth=1)
                   if topic == '/diagnostics' else qos_profile_dict(depth=50))
            writer.add_topic(topic, type_name, qos)
            t = 1_700_000_000_000_000_000 + 10_000_000 * k
            data = serialize_message(msg)
            writer.write(topic, data, t, publish_time_ns=t - 1000)
            written.append((topic, t, msg, data))
    return written


# --------------------------------------------------------------------------------------------


def test_import_does_not_import_rclpy():
    code = ('import sys, gyro_rotor.bag.bagio, gyro_rotor.bag.msgdefs; '
            'bad = [m for m in sys.modules if m == "rclpy" or m.endswith("_msgs")]; '
            'assert not bad, bad')
    env = dict(os.environ, PYTHONPATH=str(REPO))
    subprocess.run([sys.executable, '-c', code], check=True, env=env, timeout=60)


def test_message_definition_like_rosbag2():
    text = message_definition('sensor_msgs/msg/JointState')
    share = Path(sys.prefix) / 'share'
    assert text.startswith((share / 'sensor_msgs/msg/JointState.msg').read_text())
    blocks = text.split(f'\n{DELIMITER}\n')
    assert [b.splitlines()[0] for b in blocks[1:]] == [
        'MSG: std_msgs/Header', 'MSG: builtin_interfaces/Time']
    assert blocks[2] == 'MSG: builtin_interfaces/Time\n' + (
        share / 'builtin_interfaces/msg/Time.msg').read_text()
    assert message_definition('sensor_msgs/JointState') == text

    marker = message_definition('visualization_msgs/msg/Marker')
    deps = [line[5:] for line in marker.splitlines() if line.startswith('MSG: ')]
    assert len(deps) == len(set(deps))
    assert {'visualization_msgs/UVCoordinate', 'visualization_msgs/MeshFile',
            'sensor_msgs/CompressedImage', 'std_msgs/ColorRGBA', 'std_msgs/Header',
            'builtin_interfaces/Duration', 'builtin_interfaces/Time', 'geometry_msgs/Pose',
            'geometry_msgs/Point', 'geometry_msgs/Quaternion',
            'geometry_msgs/Vector3'} == set(deps)
    assert all(len(line) == 80 for line in marker.splitlines() if line.startswith('='))
    assert message_definition('std_msgs/msg/Empty').count(DELIMITER) == 0

    with pytest.raises(BagError, match='no_such_msgs/msg/Nope'):
        message_definition('no_such_msgs/msg/Nope')
    with pytest.raises(BagError, match='not a ROS 2 message type'):
        message_definition('JointState')
    assert type_hash('sensor_msgs/msg/JointState').startswith('RIHS01_a13ee3a3')
    assert type_hash('no_such_msgs/msg/Nope') == ''


@pytest.mark.parametrize('type_name', [
    'sensor_msgs/msg/JointState', 'visualization_msgs/msg/Marker', 'rosgraph_msgs/msg/Clock',
    'diagnostic_msgs/msg/DiagnosticArray', 'std_msgs/msg/Float64MultiArray', FLOAT64])
def test_definition_hashes_match_rosbags(type_name):
    """The RIHS01 hash that rosbags computes from our text equals the installed hash."""
    from rosbags.typesys import get_types_from_msg, get_typestore, Stores

    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg(message_definition(type_name), type_name))
    assert store.hash_rihs01(type_name) == type_hash(type_name) != ''
    assert get_typestore(Stores.ROS2_JAZZY).hash_rihs01(type_name) == type_hash(type_name)


def test_qos_normalization_parses_equal_in_rosbags():
    from rosbags.rosbag2.metadata import parse_qos

    profile = qos_profile_dict(reliability='best_effort', depth=5, deadline=1_500_000_000)
    assert profile['deadline'] == {'sec': 1, 'nsec': 500_000_000}
    assert profile['lifespan'] == {'sec': 9223372036, 'nsec': 854775807}
    ints = normalize_qos({'history': 1, 'depth': 5, 'reliability': 2, 'durability': 2,
                          'deadline': {'sec': 1, 'nsec': 500_000_000}})
    assert ints == [profile]
    as_string = yaml.safe_dump([profile], sort_keys=False)
    assert parse_qos(as_string) == parse_qos([profile])
    assert parse_qos([profile])[0].reliability.name == 'BEST_EFFORT'
    for bad in ({'reliability': 'sometimes'}, {'depth': -1}, {'color': 'red'},
                {'deadline': 1.5}, {'history': 7}):
        with pytest.raises(BagError):
            normalize_qos(bad)


def test_qos_from_rclpy_profile():
    qos_mod = pytest.importorskip('rclpy.qos')
    profile = qos_mod.QoSProfile(depth=7, reliability=qos_mod.ReliabilityPolicy.BEST_EFFORT)
    (out,) = normalize_qos(profile)
    assert (out['history'], out['depth'], out['reliability']) == ('keep_last', 7, 'best_effort')


def test_roundtrip_with_three_readers(tmp_path):
    bag = tmp_path / 'run1'
    written = write_ros_bag(bag, chunk_size=4096)
    expected = [(topic, t, values(msg)) for topic, t, msg, _ in written]
    expected_counts = {}
    for topic, _, _, _ in written:
        expected_counts[topic] = expected_counts.get(topic, 0) + 1
    assert sorted(os.listdir(bag)) == ['metadata.yaml', 'run1_0.mcap']

    # (a) mcap reader + mcap_ros2 decoder
    assert [(tp, t, values(m)) for tp, t, m in mcap_read(bag / 'run1_0.mcap')] == expected
    # (b) rosbags AnyReader on the directory (pairs metadata.yaml with channels, checks
    #     hashes) and on the bare file
    counts, msgs = anyreader_read(bag)
    assert counts == expected_counts
    assert [(tp, t, values(m)) for tp, t, m in msgs] == expected
    counts, msgs = anyreader_read(bag / 'run1_0.mcap')
    assert [(tp, t, values(m)) for tp, t, m in msgs] == expected
    # (c) structure
    assert check_structure(bag) == expected_counts

    # our own reader, directory and bare file
    for path in (bag, bag / 'run1_0.mcap'):
        reader = open_bag(path)
        assert not reader.truncated and reader.problems == []
        assert {k: v.count for k, v in reader.topics.items()} == expected_counts
        assert reader.topics['/marker'].type == 'visualization_msgs/msg/Marker'
        assert 'rosbag2' in reader.metadata
        raw = list(reader.messages())
        assert raw == [(tp, t, data) for tp, t, _, data in written]    # bytes unchanged
        assert [(tp, t, values(m)) for tp, t, m in reader.decoded()] == expected
        assert [t for _, t, _ in reader.messages(topics='/clock')] == [
            t for tp, t, _, _ in written if tp == '/clock']
        assert list(reader.messages(topics=['/nope'])) == []


def test_metadata_records_sequence_and_publish_time(tmp_path):
    bag = tmp_path / 'meta'
    with BagWriter(bag, metadata={'gyro_rotor': {'scene': 'demo'}}) as writer:
        writer.add_topic('/x', FLOAT64)
        writer.add_topic('/y', 'std_msgs/Float64')
        assert writer.add_topic('/x', FLOAT64) == 1
        writer.add_metadata('run', {'seed': '3'})
        for i in range(3):
            writer.write('/x', f64(i), 10 + i, publish_time_ns=5 + i)
        writer.write('/y', f64(9.0), 20)
        assert writer.message_counts == {'/x': 3, '/y': 1}
    reader = open_bag(bag)
    assert reader.metadata['gyro_rotor'] == {'scene': 'demo'}
    assert reader.metadata['run'] == {'seed': '3'}
    with open(bag / 'meta_0.mcap', 'rb') as stream:
        msgs = list(make_reader(stream).iter_messages())
    assert [(c.topic, m.sequence, m.publish_time) for _, c, m in msgs] == [
        ('/x', 1, 5), ('/x', 2, 6), ('/x', 3, 7), ('/y', 1, 20)]
    assert [v.data for _, _, v in reader.decoded('/x')] == [0.0, 1.0, 2.0]
    assert check_structure(bag) == {'/x': 3, '/y': 1}
    assert anyreader_read(bag)[0] == {'/x': 3, '/y': 1}


def test_refuses_to_overwrite(tmp_path):
    (tmp_path / 'taken').mkdir()
    (tmp_path / 'file').write_text('keep me')
    for name in ('taken', 'file'):
        with pytest.raises(BagError, match='exists already, not overwriting'):
            BagWriter(tmp_path / name)
    assert (tmp_path / 'file').read_text() == 'keep me'
    with BagWriter(tmp_path / 'new'):
        pass
    with pytest.raises(BagError, match='exists already'):
        BagWriter(tmp_path / 'new')


def test_unwritable_target(tmp_path):
    (tmp_path / 'plain').write_text('x')
    with pytest.raises(BagError, match='plain'):
        BagWriter(tmp_path / 'plain' / 'bag')
    readonly = tmp_path / 'ro'
    readonly.mkdir()
    readonly.chmod(0o500)
    try:
        if os.access(readonly, os.W_OK):
            pytest.skip('running as root: permissions are not enforced')
        with pytest.raises(BagError, match='ro'):
            BagWriter(readonly / 'bag')
    finally:
        readonly.chmod(0o700)


def test_strict_lifecycle(tmp_path):
    writer = BagWriter(tmp_path / 'b')
    writer.add_topic('/x', FLOAT64)
    with pytest.raises(BagError, match='unknown topic'):
        writer.write('/nope', f64(1.0), 1)
    with pytest.raises(BagError, match='already'):
        writer.add_topic('/x', 'std_msgs/msg/String')
    with pytest.raises(BagError, match='nanoseconds'):
        writer.write('/x', f64(1.0), 1.5)
    with pytest.raises(BagError, match='bytes'):
        writer.write('/x', 'text', 1)
    with pytest.raises(BagError, match='not found'):
        writer.add_topic('/y', 'no_such_msgs/msg/Nope')
    writer.write('/x', f64(1.0), 1)
    writer.close()
    writer.close()
    writer.finish()
    assert writer.closed
    for call in (lambda: writer.write('/x', f64(1.0), 2), lambda: writer.add_topic('/z', FLOAT64),
                 lambda: writer.add_metadata('m', {}), writer.flush):
        with pytest.raises(BagError, match='closed'):
            call()
    assert open_bag(tmp_path / 'b').topics['/x'].count == 1


def test_reader_errors(tmp_path):
    with pytest.raises(BagError, match='no such bag'):
        open_bag(tmp_path / 'missing')
    (tmp_path / 'empty').mkdir()
    with pytest.raises(BagError, match='no .mcap file'):
        open_bag(tmp_path / 'empty')
    (tmp_path / 'text.mcap').write_bytes(b'hello, this is not an MCAP file at all')
    with pytest.raises(BagError, match='not an MCAP file'):
        open_bag(tmp_path / 'text.mcap')
    (tmp_path / 'zero.mcap').write_bytes(b'')
    with pytest.raises(BagError, match='empty file'):
        open_bag(tmp_path / 'zero.mcap')
    garbage = tmp_path / 'garbage.mcap'
    garbage.write_bytes(b'\x89MCAP0\r\n' + bytes(range(256)) * 4)
    with pytest.warns(BagWarning, match='truncated'):
        reader = open_bag(garbage)
    assert reader.truncated and list(reader.messages()) == []

    bag = tmp_path / 'nometa'
    with BagWriter(bag) as writer:
        writer.add_topic('/x', FLOAT64)
        writer.write('/x', f64(2.5), 7)
    (bag / 'metadata.yaml').unlink()
    with pytest.warns(BagWarning, match='metadata.yaml is missing'):
        reader = open_bag(bag)
    assert [(t, m.data) for _, t, m in reader.decoded()] == [(7, 2.5)]
    (bag / 'metadata.yaml').write_text(': not yaml : [')
    with pytest.warns(BagWarning, match='unreadable'):
        assert open_bag(bag).topics['/x'].count == 1


def write_float_bag(bag: Path, n: int = 40, **kwargs: object) -> list[tuple[str, int, bytes]]:
    """Write n Float64 messages on two topics; return them as (topic, t, data)."""
    out = []
    with BagWriter(bag, **kwargs) as writer:
        writer.add_topic('/a', FLOAT64, qos_profile_dict(depth=3))
        writer.add_topic('/b', FLOAT64, qos_profile_dict(reliability='best_effort'))
        for i in range(n):
            topic = '/a' if i % 3 else '/b'
            writer.write(topic, f64(float(i)), 1_000 + i)
            out.append((topic, 1_000 + i, f64(float(i))))
    return out


def test_truncated_file_gives_readable_prefix(tmp_path):
    bag = tmp_path / 'full'
    full = write_float_bag(bag, chunk_size=300)
    data = (bag / 'full_0.mcap').read_bytes()
    offsets = sorted({0, 1, 7, 8, 9, 16, 17, 40, 100, 200, len(data) - 1, len(data) - 8,
                      len(data) - 9, len(data) - 40, len(data) - 200}
                     | set(range(300, len(data), 97)))
    readable = []
    for cut in offsets:
        path = tmp_path / f'cut{cut}.mcap'
        path.write_bytes(data[:cut])
        try:
            with warnings.catch_warnings():
                warnings.simplefilter('ignore', BagWarning)
                reader = open_bag(path)
                got = list(reader.messages())
                decoded = list(reader.decoded())
        except BagError as err:
            assert str(path) in str(err)
            assert cut < 8, f'cut at {cut}: {err}'
            continue
        assert got == full[:len(got)], f'cut at {cut}: not a prefix'
        assert [d.data for _, _, d in decoded] == [struct.unpack('<d', x[4:])[0]
                                                   for _, _, x in got]
        assert reader.truncated == (cut < len(data))
        readable.append(len(got))
    assert readable == sorted(readable) and readable[-1] == len(full)
    assert 0 < readable[len(readable) // 2] < len(full)


def test_flush_interval_bounds_what_is_only_in_memory(tmp_path):
    writer = BagWriter(tmp_path / 'live', chunk_size=1 << 20, flush_interval_s=0.05)
    writer.add_topic('/a', FLOAT64)
    for i in range(5):
        writer.write('/a', f64(i), 100 + i)
    with pytest.warns(BagWarning, match='truncated'):
        assert open_bag(tmp_path / 'live').topics == {}    # all in the chunk in memory
    time.sleep(0.06)
    writer.write('/a', f64(5), 105)                          # chunk is old: flushed
    with pytest.warns(BagWarning, match='truncated'):
        reader = open_bag(tmp_path / 'live' / 'live_0.mcap')
    assert [t for _, t, _ in reader.messages()] == [100, 101, 102, 103, 104, 105]
    writer.write('/a', f64(6), 106)
    writer.flush()                                           # explicit flush for idle writers
    with pytest.warns(BagWarning):
        assert open_bag(tmp_path / 'live').topics['/a'].count == 7
    writer.close()
    assert open_bag(tmp_path / 'live').topics['/a'].count == 7


def test_recover_cut_bag(tmp_path):
    bag = tmp_path / 'cut'
    full = write_float_bag(bag, chunk_size=300)
    mcap_path = bag / 'cut_0.mcap'
    data = mcap_path.read_bytes()
    mcap_path.write_bytes(data[:len(data) // 2])
    with pytest.warns(BagWarning):
        before = list(open_bag(bag).messages())
    assert 0 < len(before) < len(full)

    report = recover_bag(bag)
    assert report.rewritten == (mcap_path,) and report.metadata_rewritten
    assert (bag / 'cut_0.mcap.orig').read_bytes() == data[:len(data) // 2]
    assert report.message_count == len(before)
    reader = open_bag(bag)
    assert not reader.truncated and list(reader.messages()) == before
    assert check_structure(bag) == report.messages_per_topic
    counts, msgs = anyreader_read(bag)
    assert counts == report.messages_per_topic
    assert [(tp, t, m.data) for tp, t, m in msgs] == [
        (tp, t, struct.unpack('<d', d[4:])[0]) for tp, t, d in before]
    assert len(mcap_read(mcap_path)) == len(before)

    again = recover_bag(bag)
    assert again.rewritten == () and not again.metadata_rewritten
    assert again.messages_per_topic == report.messages_per_topic

    (bag / 'cut_0.mcap').write_bytes(data[:len(data) // 3])
    with pytest.raises(BagError, match='exists already'):
        recover_bag(bag)


SIGKILL_WRITER = textwrap.dedent("""
    import sys, time
    from rclpy.serialization import serialize_message
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState
    from gyro_rotor.bag.bagio import BagWriter, qos_profile_dict

    writer = BagWriter(sys.argv[1], flush_interval_s=1.0)
    writer.add_topic('/joint_states', 'sensor_msgs/msg/JointState', qos_profile_dict(depth=10))
    writer.add_topic('/clock', 'rosgraph_msgs/msg/Clock',
                     qos_profile_dict(reliability='best_effort', depth=1))
    print('READY', flush=True)
    i = 0
    while True:
        now = time.time_ns()
        js = JointState(name=['rotor_spin'], position=[float(i)], velocity=[1.0], effort=[0.0])
        writer.write('/joint_states', serialize_message(js), now)
        clock = Clock()
        clock.clock.sec, clock.clock.nanosec = divmod(now, 10**9)
        writer.write('/clock', serialize_message(clock), now)
        i += 1
        time.sleep(0.01)
""")


def test_sigkill_then_recover(tmp_path):
    pytest.importorskip('rclpy')
    bag = tmp_path / 'killed'
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.Popen([sys.executable, '-c', SIGKILL_WRITER, str(bag)], env=env,
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == 'READY'
        t_start = time.time_ns()
        time.sleep(3.0)
        t_kill = time.time_ns()
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert [t['message_count'] for t in info['topics_with_message_count']] == [0, 0]

    with pytest.warns(BagWarning, match='truncated'):
        reader = open_bag(bag)
    assert reader.truncated
    js = [(t, m.position[0]) for _, t, m in reader.decoded('/joint_states')]
    assert [p for _, p in js] == [float(i) for i in range(len(js))]    # no gap
    assert js[0][0] <= t_start + 200_000_000
    lost_s = (t_kill - js[-1][0]) / 1e9
    assert lost_s < 1.3, f'{lost_s:.2f} s of messages lost (flush interval 1 s)'
    readable = {k: v.count for k, v in reader.topics.items()}

    report = recover_bag(bag)
    assert report.messages_per_topic == readable
    assert (bag / 'killed_0.mcap.orig').exists()
    assert check_structure(bag) == readable
    counts, msgs = anyreader_read(bag)
    assert counts == readable
    assert [m.position[0] for tp, _, m in msgs if tp == '/joint_states'] == [p for _, p in js]
    assert len(mcap_read(bag / 'killed_0.mcap')) == sum(readable.values())
    assert not open_bag(bag).truncated


def test_copy_of_bag_is_readable_by_directory(tmp_path):
    """A bag directory can be moved or renamed: paths in metadata.yaml are relative."""
    write_float_bag(tmp_path / 'orig', n=5)
    shutil.copytree(tmp_path / 'orig', tmp_path / 'moved')
    assert anyreader_read(tmp_path / 'moved')[0] == {'/a': 3, '/b': 2}
