"""rotor_sim and rotor_analysis as separate processes: record, read back, count, crash.

The simulation runs at real time (250 Hz) and stops at t_end (``stop_at_t_end``), so it
publishes exactly t_end * 250 + 1 samples with ``seq`` 0, 1, 2, ...; the recorder starts
first. Counts are proved by the sequence numbers, read with three independent readers:
``mcap`` + ``mcap_ros2``, rosbags ``AnyReader`` and bagio's structural reader.
(At real_time_factor 0 the simulator outruns any Python subscriber on two cores, so that
rate is not one the recorder is configured for.)
"""

from __future__ import annotations

import os
from pathlib import Path
import signal
import subprocess
import sys

from gyro_rotor.analysis.checks import analyze_bag
from gyro_rotor.bag.bagio import open_bag
from gyro_rotor.ros.messages import ENERGY_FIELDS
from node_helpers import bag_on_disk, wait_for_log, wait_until
import pytest

pytestmark = pytest.mark.ros

RATE = 250.0
T_END = 3.0


def _start(args: list[str], log: Path) -> subprocess.Popen:
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    return subprocess.Popen([sys.executable, '-m', *args], stdout=open(log, 'w'),
                            stderr=subprocess.STDOUT, env=env)


def _stop(proc: subprocess.Popen, sig=signal.SIGINT, timeout: float = 30.0) -> int:
    if proc.poll() is None:
        proc.send_signal(sig)
    try:
        return proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        raise


def _record(tmp_path: Path, scene: str = 'precession', t_end: float = T_END):
    """Start the recorder, then the simulator (stopping at ``t_end``); return both.

    The simulator holds its time at 0 until the recorder's subscriptions matched
    (``wait_for_subscribers``), then logs 'simulation time starts'.
    """
    bag = tmp_path / 'bag'
    an = _start(['gyro_rotor.ros.analysis_node', '--ros-args', '-p', f'output:={bag}',
                 '-p', 'window_s:=2.0', '-p', 'min_fit_s:=1.0'], tmp_path / 'an.log')
    wait_for_log(tmp_path / 'an.log', 'recording to', an, timeout=40.0)
    sim = _start(['gyro_rotor.ros.sim_node', '--ros-args', '-p', f'scene:={scene}',
                  '-p', 'real_time_factor:=1.0', '-p', f't_end:={t_end}',
                  '-p', 'stop_at_t_end:=true', '-p', 'wait_for_subscribers:=1'],
                 tmp_path / 'sim.log')
    return bag, an, sim


def _energy_k(data: bytes) -> tuple[int, int]:
    """(seq, k) of a serialized energy message: its float64 array ends the CDR."""
    import struct
    n = len(ENERGY_FIELDS)
    row = struct.unpack_from(f'<{n}d', data, len(data) - 8 * n)
    return int(row[ENERGY_FIELDS.index('seq')]), int(row[ENERGY_FIELDS.index('k')])


def _published(log: Path) -> dict:
    import json
    import re
    found = re.findall(r'published counts: (\{.*\})', log.read_text())
    return json.loads(found[-1]) if found else {}


def _reset_sim(timeout: float = 20.0) -> None:
    """Call /rotor_sim/reset (std_srvs/Trigger) from this process."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from std_srvs.srv import Trigger
    context = rclpy.context.Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node('test_reset_client', context=context)
        client = node.create_client(Trigger, '/rotor_sim/reset')
        assert client.wait_for_service(timeout_sec=timeout)
        future = client.call_async(Trigger.Request())
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        executor.spin_until_future_complete(future, timeout_sec=timeout)
        assert future.done() and future.result().success
        executor.shutdown()
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)


def _parameters(node: str, wanted: list[str], timeout: float = 30.0):
    """Names (list_parameters) and values (get_parameters) of ``node``, by its services."""
    import rclpy
    from rcl_interfaces.srv import GetParameters, ListParameters
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import parameter_value_to_python
    context = rclpy.context.Context()
    rclpy.init(context=context)
    try:
        client_node = rclpy.create_node('test_param_client', context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(client_node)
        answers = []
        for srv, name, req in ((ListParameters, 'list_parameters', ListParameters.Request()),
                               (GetParameters, 'get_parameters',
                                GetParameters.Request(names=wanted))):
            client = client_node.create_client(srv, f'{node}/{name}')
            assert client.wait_for_service(timeout_sec=timeout), name
            future = client.call_async(req)
            executor.spin_until_future_complete(future, timeout_sec=timeout)
            assert future.done(), name
            answers.append(future.result())
        executor.shutdown()
        client_node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
    return (list(answers[0].result.names),
            [parameter_value_to_python(v) for v in answers[1].values])


def _energy_seq_three_readers(bag: Path) -> tuple[list, list, list]:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import get_typestore, Stores

    mcap_file = next(bag.glob('*.mcap'))
    with open(mcap_file, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == 'ros2'
        a = [(int(dec.data[7]), int(dec.data[9])) for _, _, _, dec in
             reader.iter_decoded_messages(topics=['/energy'], log_time_order=True)]
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as r:
        conns = [c for c in r.connections if c.topic == '/energy']
        b = [(int(m.data[7]), int(m.data[9])) for m in
             (r.deserialize(raw, c.msgtype) for c, _, raw in r.messages(connections=conns))]
    c = [(int(m.data[7]), int(m.data[9])) for _, _, m in open_bag(bag).decoded('/energy')]
    return a, b, c


def test_record_read_back_counts_and_sigint_finalizes(tmp_path):
    bag, an, sim = _record(tmp_path)
    try:
        wait_for_log(tmp_path / 'sim.log', 'simulation time starts', sim, timeout=40.0)
        # restart the run (the node's ~/reset) once the first run is longer than the window
        # in which the analysis pairs energy with joint_states by stamp (PAIRER_KEEP): a
        # shorter run's unpaired samples would meet the new run's samples of the same stamps.
        # The run after the reset must be recorded completely, and the analysis must count
        # it as one reset.
        from gyro_rotor.tools.soak import PAIRER_KEEP
        wait_until(lambda: len(bag_on_disk(bag, '/energy')) > 2 * PAIRER_KEEP,
                   'the first run on disk beyond the pairing window', an, timeout=60.0)
        _reset_sim()
        n = int(T_END * RATE) + 1

        def run_complete():
            ks = [_energy_k(d)[1] for _, d in bag_on_disk(bag, '/energy')]
            return any(ks[i] < ks[i - 1] for i in range(1, len(ks))) and ks[-1] == n - 1
        wait_until(run_complete, 'the run after the reset on disk', an, timeout=60.0)
        assert _stop(sim) == 0
        published = _published(tmp_path / 'sim.log')
        # the recorder took every published message (all on disk) before it is stopped
        for topic in ('energy', 'joint_states'):
            wait_until(lambda: len(bag_on_disk(bag, f'/{topic}')) == published[topic],
                       f'all {published[topic]} {topic} messages on disk', an)
    finally:
        _stop(sim)
        rc = _stop(an)
    log = (tmp_path / 'an.log').read_text()
    assert rc == 0 and 'Traceback' not in log, log
    n = int(T_END * RATE) + 1
    reader = open_bag(bag)
    assert not reader.truncated                      # SIGINT finalized it (footer, summary)
    a, b, c = _energy_seq_three_readers(bag)
    assert a == b == c
    seq = [s for s, _ in a]
    # no gap anywhere: every message published after the recorder matched is in the bag
    assert seq == list(range(seq[0], seq[0] + len(seq))), seq
    # the run after the reset (grid index k back to 0) is complete: k = 0 .. n - 1
    start = max(i for i in range(1, len(a)) if a[i][1] < a[i - 1][1])
    assert [k for _, k in a[start:]] == list(range(n))
    # joint_states: the run after the reset is complete too (k = 0 .. n - 1 by its stamps).
    # Before the reset the two topics may start one sample apart: their subscriptions are
    # matched by discovery independently, while the simulator is already publishing.
    js_k = [round((m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec) * RATE)
            for _, _, m in reader.decoded('/joint_states')]
    js_start = max(i for i in range(1, len(js_k)) if js_k[i] < js_k[i - 1])
    assert js_k[js_start:] == list(range(n))
    assert abs(reader.topics['/joint_states'].count - len(seq)) <= 1
    # metadata.yaml carries the same QoS as the channels and the final counts
    import yaml
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    by_name = {t['topic_metadata']['name']: t for t in info['topics_with_message_count']}
    assert by_name['/energy']['message_count'] == len(seq)
    assert yaml.safe_load(reader.channel_metadata['/energy']['offered_qos_profiles']) == \
        by_name['/energy']['topic_metadata']['offered_qos_profiles']
    assert by_name['/energy']['topic_metadata']['offered_qos_profiles'][0]['reliability'] \
        == 'reliable'
    # the type hash the publisher announced in the graph (the same RIHS01 as the share files)
    from gyro_rotor.bag.msgdefs import type_hash
    want = type_hash('std_msgs/msg/Float64MultiArray')
    assert want.startswith('RIHS01_')
    assert reader.channel_metadata['/energy']['topic_type_hash'] == want
    assert by_name['/energy']['topic_metadata']['type_description_hash'] == want
    # no directory of the recording machine in the metadata: the scene is named relative
    # to the package's share directory
    doc = yaml.safe_load(reader.metadata['gyro_rotor.scene']['document'])
    assert doc['path'] == 'config/precession.yaml'
    # the live result is in the bag, and the offline analysis reproduces it
    off = analyze_bag(bag)
    assert off.live is not None and off.live['samples'] == len(seq)
    assert off.live['dropped'] == 0 and off.live['resets'] == 1
    assert off.result.verdict == off.live['verdict'] == 'asymptotically stable'
    assert reader.topics['/analysis'].count >= 1


def test_sigkill_leaves_a_readable_bag_that_recover_fixes(tmp_path, capsys):
    import gyro_rotor.cli.main as cli
    bag, an, sim = _record(tmp_path, t_end=60.0)
    try:
        # killed while the simulation is running (it would run for a minute), as soon as
        # the recorder has written a chunk with some energy messages
        wait_for_log(tmp_path / 'sim.log', 'simulation time starts', sim, timeout=40.0)
        wait_until(lambda: len(bag_on_disk(bag, '/energy')) >= 25,
                   'a flushed chunk with energy messages', an, timeout=60.0)
        on_disk = bag_on_disk(bag, '/energy')         # what the recorder had flushed
        an.send_signal(signal.SIGKILL)
        an.wait(timeout=10)
    finally:
        _stop(sim)
        _stop(an)
    with pytest.warns(Warning, match='truncated'):
        reader = open_bag(bag)
    assert reader.truncated
    # every message flushed before the kill is readable after it (a bound in wall-clock
    # seconds on the open chunk's loss is a timing, not an event: the spool's idle flush is
    # tested in test_spool without a clock)
    after = [(t, d) for _, t, d in reader.messages('/energy')]
    assert len(on_disk) >= 25 and after[:len(on_disk)] == on_disk
    seq = [int(m.data[7]) for _, _, m in reader.decoded('/energy')]
    assert seq == list(range(seq[0], seq[0] + len(seq)))
    assert cli.main(['recover', str(bag)]) == 0
    assert 'rewrote' in capsys.readouterr().out
    a, b, c = _energy_seq_three_readers(bag)
    assert a == b == c and [s for s, _ in a] == seq
    assert not open_bag(bag).truncated


def test_unwritable_output_is_a_clear_error_at_start(tmp_path):
    blocker = tmp_path / 'a_file'
    blocker.write_text('not a directory')
    proc = subprocess.run([sys.executable, '-m', 'gyro_rotor.ros.analysis_node', '--ros-args',
                           '-p', f'output:={blocker / "bag"}'], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 1
    assert 'ERROR:' in proc.stderr and 'not writable' in proc.stderr, proc.stderr
    assert 'Traceback' not in proc.stderr


def test_sigterm_finalizes_the_bag(tmp_path):
    bag = tmp_path / 'bag'
    an = _start(['gyro_rotor.ros.analysis_node', '--ros-args', '-p', f'output:={bag}'],
                tmp_path / 'an.log')
    try:
        wait_for_log(tmp_path / 'an.log', 'recording to', an, timeout=40.0)
        # the node spins (its parameter services answer) before it gets SIGTERM
        names, values = _parameters('/rotor_analysis', ['window_s', 'output'])
    finally:
        rc = _stop(an, signal.SIGTERM)
    # ros2 param list/get see the node's parameters (issue 16)
    assert {'output', 'window_s', 'min_fit_s', 'scene', 'record'} <= set(names)
    assert values == [8.0, str(bag)]
    assert rc == 0, (tmp_path / 'an.log').read_text()
    reader = open_bag(bag)
    assert not reader.truncated
    # no simulator ran: the final record says why there is no verdict
    assert 'scene is unknown' in reader.metadata['gyro_rotor.live_result']['error']
