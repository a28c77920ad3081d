"""Fuzz of the live analysis (issue 24): foreign messages interleaved with a real run.

rotor_analysis records and analyses a real run of rotor_sim (real_time_factor 0, 10 s of
the scene precession with its kick) while this test publishes random and malformed messages
on every topic the analysis subscribes to (``energy``, ``joint_states``,
``/rotor_sim/scene``): random bytes, cut messages, foreign layouts, non-finite and absurd
times, other joints, arrays of the wrong length, text that is no scene document, deep
nesting, alias bombs. Then:

* the bag is complete: every sample of the run (seq 0..2500 without a gap) and every
  foreign message, byte for byte;
* every foreign message was counted by the live analysis (``gyro_rotor.live_result``);
* the live verdict equals that of the run without them (the bag with the foreign messages
  taken out, analysed offline), and so does the offline analysis of the bag as recorded.

Forged messages that are valid in every respect (a plausible energy sample of the scene at
an unused time) are not part of the fuzz: nothing in a message tells who sent it.
"""

from __future__ import annotations

from collections import Counter
import json
import os
from pathlib import Path
import random
import signal
import struct
import subprocess
import sys
import threading
import warnings

from gyro_rotor.analysis.offline import analyze_bag
from gyro_rotor.bag.bagio import BagWriter, open_bag
from gyro_rotor.ros.messages import ENERGY_FIELDS
from node_helpers import bag_on_disk, wait_for_log, wait_until
import pytest

pytestmark = pytest.mark.ros

RATE = 250.0
T_END = 10.0
N_SAMPLES = int(T_END * RATE) + 1


def _cdr_string(text: bytes) -> bytes:
    raw = text + b'\x00'
    return struct.pack('<I', len(raw)) + raw + b'\x00' * ((-len(raw)) % 4)


def _energy(label: str, values) -> bytes:
    body = struct.pack('<I', 1) + _cdr_string(label.encode()) + struct.pack('<III', len(
        values), len(values), 0)
    body += struct.pack('<I', len(values))
    pad = (-len(body)) % 8
    return (b'\x00\x01\x00\x00' + body + b'\x00' * pad
            + struct.pack(f'<{len(values)}d', *values))


def _joints(names: list[str], pos, vel, sec: int = 1, nsec: int = 0) -> bytes:
    body = struct.pack('<iI', sec, nsec) + _cdr_string(b'world')
    body += struct.pack('<I', len(names)) + b''.join(_cdr_string(n.encode()) for n in names)

    def f64s(vals, body):
        body += struct.pack('<I', len(vals))
        if vals:
            body += b'\x00' * ((-len(body)) % 8)
        return body + struct.pack(f'<{len(vals)}d', *vals)
    body = f64s(list(pos), body)
    body = f64s(list(vel), body)
    body = f64s([], body)
    return b'\x00\x01\x00\x00' + body


class Fuzz:
    """Random and malformed messages for the three topics (seeded)."""

    def __init__(self, seed: int):
        self.rng = random.Random(seed)
        self.label = ','.join(ENERGY_FIELDS)

    def energy(self) -> bytes:
        r, n = self.rng, len(ENERGY_FIELDS)
        vals = [r.uniform(-10, 10) for _ in range(n)]
        t = ENERGY_FIELDS.index('t_sim')
        kind = r.randrange(8)
        if kind == 0:
            return r.randbytes(r.randrange(1, 200))
        if kind == 1:
            vals[t] = r.choice([float('nan'), float('inf'), -1.0, 1e300, 1e200])
        elif kind == 2:
            vals = vals[:r.randrange(n)]                    # too few values
        elif kind == 3:
            return _energy('a,b,c', [1.0, 2.0, 3.0])       # a foreign layout
        elif kind == 4:
            vals[ENERGY_FIELDS.index('seq')] = r.choice([0.5, -3.0, float('nan')])
        elif kind == 5:
            data = _energy(self.label, vals)
            return data[:r.randrange(4, len(data) - 16)]    # cut short (by whole values)
        elif kind == 6:
            return b'\x00\x01\x00\x00' + struct.pack('<I', 0xFFFFFFF0)   # absurd length
        else:
            vals = [float('nan')] * n
        return _energy(self.label, vals)

    def joints(self) -> bytes:
        r = self.rng
        names = ['theta', 'psi', 'phi_R', 'phi_M']
        kind = r.randrange(5)
        if kind == 0:
            return r.randbytes(r.randrange(1, 120))
        if kind == 1:
            return _joints(['a', 'b'], [1.0, 2.0], [0.0, 0.0], r.randrange(10), 0)
        if kind == 2:
            return _joints(names, [0.1] * 3, [0.0] * 4, r.randrange(10), 0)  # lengths
        if kind == 3:
            data = _joints(names, [0.1] * 4, [0.0] * 4)
            return data[:r.randrange(4, len(data) - 16)]    # cut short (by whole values)
        return _joints(names[::-1], [0.0] * 4, [0.0] * 4, 3, 0)             # other order

    def scene(self) -> bytes:
        r = self.rng
        kind = r.randrange(6)
        texts = [r.randbytes(r.randrange(1, 80)).decode('latin-1').encode(),
                 b'[' * 5000 + b']' * 5000,
                 b'{garbage: [',
                 b'42',
                 ('a: &a [1,1,1,1,1,1,1,1,1]\n' + ''.join(
                     f'{k}: &{k} [' + ','.join([f'*{p}'] * 9) + ']\n'
                     for p, k in zip('abcdefgh', 'bcdefghi'))).encode(),
                 b'params: {K_D: [1, 2]}\nscene: x']
        if kind == 0:
            return r.randbytes(r.randrange(1, 60))
        return b'\x00\x01\x00\x00' + _cdr_string(texts[kind - 1].replace(b'\x00', b' '))


def _start(args: list[str], log: Path) -> subprocess.Popen:
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    return subprocess.Popen([sys.executable, '-m', *args], stdout=open(log, 'w'),
                            stderr=subprocess.STDOUT, env=env)


def _stop(proc: subprocess.Popen) -> int:
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
    try:
        return proc.wait(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        raise


def _without(bag: Path, dst: Path, foreign: set) -> None:
    """Copy ``bag`` without the messages whose bytes are in ``foreign``."""
    reader = open_bag(bag)
    with BagWriter(dst, metadata={k: v for k, v in reader.metadata.items()
                                  if k not in ('rosbag2', 'gyro_rotor.live_result')}) as w:
        for topic, info in reader.topics.items():
            w.add_topic(topic, info.type)
        for topic, t, data in reader.messages():
            if (topic, data) not in foreign:
                w.write(topic, data, t)


def test_fuzzed_live_analysis_keeps_its_verdict(tmp_path):
    import rclpy
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray, String
    bag = tmp_path / 'bag'
    an = _start(['gyro_rotor.ros.analysis_node', '--ros-args', '-p', f'output:={bag}',
                 '-p', 'scene:=precession'], tmp_path / 'an.log')
    sim = None
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node('fuzzer', context=ctx)
    sent: list[tuple[str, bytes]] = []
    stop = threading.Event()
    try:
        wait_for_log(tmp_path / 'an.log', 'recording to', an, timeout=60)
        deep = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5000,
                          reliability=ReliabilityPolicy.RELIABLE)
        latched = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5000,
                             reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        fuzz = Fuzz(24)
        pubs = {'/energy': (node.create_publisher(Float64MultiArray, '/energy', deep),
                            fuzz.energy),
                '/joint_states': (node.create_publisher(JointState, '/joint_states', deep),
                                  fuzz.joints),
                '/rotor_sim/scene': (node.create_publisher(String, '/rotor_sim/scene',
                                                           latched), fuzz.scene)}
        wait_until(lambda: all(p.get_subscription_count() for p, _ in pubs.values()),
                   'the recorder to match the fuzz publishers', an, timeout=60)
        sim = _start(['gyro_rotor.ros.sim_node', '--ros-args', '-p', 'scene:=precession',
                      '-p', 'real_time_factor:=0.0', '-p', f't_end:={T_END}',
                      '-p', f'publish_rate:={RATE}', '-p', 'stop_at_t_end:=true',
                      '-p', 'wait_for_subscribers:=1', '-p', 'wait_for_node:=rotor_analysis'],
                     tmp_path / 'sim.log')

        failed: list = []

        def publish() -> None:
            names = list(pubs)
            try:
                while not stop.is_set():
                    topic = fuzz.rng.choice(names)
                    pub, make = pubs[topic]
                    data = make()
                    # DDS pads a payload to whole 4-byte words (and notes it in the
                    # encapsulation options): whole words arrive byte for byte
                    data += b'\x00' * ((-len(data)) % 4)
                    pub.publish(data)
                    sent.append((topic, data))
                    stop.wait(0.002)
            except Exception as err:    # noqa: B902 -- reported by the test below
                failed.append(err)
                raise
        thread = threading.Thread(target=publish, daemon=True)
        thread.start()

        def run_recorded() -> bool:
            mine = set(sent)
            return sum(1 for _, d in bag_on_disk(bag, '/energy')
                       if ('/energy', d) not in mine) >= N_SAMPLES
        wait_until(run_recorded, 'every sample of the run in the bag', sim, timeout=240,
                   step=0.5)
        stop.set()
        thread.join()
        assert not failed, failed
    finally:
        stop.set()
        if sim is not None:
            _stop(sim)
        rc = _stop(an)
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)
    assert rc == 0, (tmp_path / 'an.log').read_text()[-3000:]
    foreign = set(sent)
    assert len(sent) > 300, len(sent)

    with warnings.catch_warnings():
        warnings.simplefilter('error')          # the bag must read without any problem
        reader = open_bag(bag)
    assert not reader.damaged
    recorded = [(t, d) for t, _, d in reader.messages(['/energy', '/joint_states',
                                                       '/rotor_sim/scene'])]
    mine = [(t, d) for t, d in recorded if (t, d) in foreign]
    assert Counter(mine) == Counter(sent)        # every foreign message, byte for byte
    seqs = [int(struct.unpack_from(f'<{len(ENERGY_FIELDS)}d', d, len(d) - 8 * len(
        ENERGY_FIELDS))[ENERGY_FIELDS.index('seq')])
            for t, d in recorded if t == '/energy' and (t, d) not in foreign]
    assert seqs == list(range(N_SAMPLES))        # every sample of the run, no gap
    joints = [1 for t, d in recorded if t == '/joint_states' and (t, d) not in foreign]
    assert len(joints) == N_SAMPLES

    live = reader.metadata['gyro_rotor.live_result']
    rejected = json.loads(live['rejected'])
    counted = {t: sum(per.values()) for t, per in rejected.items()}
    by_topic = {t: sum(1 for s, _ in sent if s == t) for t in pubs}
    assert counted == {t: n for t, n in by_topic.items() if n}, (counted, by_topic)

    clean = tmp_path / 'clean'
    _without(bag, clean, foreign)
    truth = analyze_bag(clean).result
    offline = analyze_bag(bag).result
    live_res = json.loads(live['json'])
    assert live_res['verdict'] == str(truth.verdict) == str(offline.verdict)
    assert truth.confirmed and live_res['samples'] == truth.samples == N_SAMPLES
    assert [c.line() for c in offline.criteria] == [c.line() for c in truth.criteria]
    ignored = next(e for e in offline.evidence if 'messages ignored' in e)
    assert ignored.startswith(f'{len(sent)} messages ignored'), ignored
