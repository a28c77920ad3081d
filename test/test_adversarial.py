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


# -- findings 7-12: the loaders ----------------------------------------------------------------
def _scene_text(extra: str = '', **changes: str) -> str:
    text = (REPO / 'config' / 'precession.yaml').read_text()
    for old, new in changes.items():
        text = text.replace(old, new)
    return text + extra


def _system(tmp_path: Path, name: str = 'sys', **changes: str) -> Path:
    text = (REPO / 'config' / 'systems' / 'twin_gimbal.yaml').read_text()
    for old, new in changes.items():
        assert old in text, old
        text = text.replace(old, new)
    path = tmp_path / f'{name}.yaml'
    path.write_text(text)
    return path


def _system_file_scene(tmp_path: Path, system: Path) -> Path:
    path = tmp_path / 'gscene.yaml'
    path.write_text('rotor_sim:\n  ros__parameters:\n    scene: g\n'
                    f'    system: {system}\n    t_end: 1.0\n')
    return path


def test_duplicate_keys_are_refused(tmp_path):
    """Finding 7: the last of two equal keys won silently (K_D: 50.0 appended to a scene)."""
    from gyro_rotor.core.scene import load_scene
    from gyro_rotor.core.system.system_file import load_system
    from gyro_rotor.errors import SceneError, SystemFileError
    scene = tmp_path / 'dup.yaml'
    scene.write_text(_scene_text('    K_D: 50.0\n'))
    with pytest.raises(SceneError, match="key 'K_D' a second time"):
        load_scene(scene)
    with pytest.raises(SystemFileError, match="key 'potential' a second time"):
        load_system(_system(tmp_path, **{'\ndrives:': '\npotential: "0"\ndrives:'}))
    with pytest.raises(SystemFileError, match="key 'c_a' a second time"):
        load_system(_system(tmp_path, **{'c_a: 40.0': 'c_a: 40.0, c_a: 4.0'}))


def test_names_are_whole_ascii_names(tmp_path):
    """Finding 8: 'R1' and a newline was a rotor name (the CSV header broke); x**２ was x**2."""
    from gyro_rotor.core.system.system_file import load_system
    from gyro_rotor.errors import SystemFileError
    with pytest.raises(SystemFileError, match=r"rotors\[0\]: 'R1\\n' is not a name"):
        load_system(_system(tmp_path, **{'rotors: [R1, R2]': 'rotors: ["R1\\n", R2]'}))
    with pytest.raises(SystemFileError, match="unexpected character '２'"):
        load_system(_system(tmp_path, **{'c_a*alpha**2/2': 'c_a*alpha**２/2'}))
    with pytest.raises(SystemFileError, match='name must be a name'):
        load_system(_system(tmp_path, **{'name: twin_gimbal': 'name: "tw\u0131n"'}))


def test_infinite_potential_is_refused_before_anything_runs(tmp_path):
    """Finding 9: a potential infinite everywhere: E*(0) = inf, residual nan, exit 0."""
    system = _system(tmp_path, **{'c_a*alpha**2/2 +': 'c_a*alpha**2/2 + 1/(sin(alpha)**2 + '
                                  'cos(alpha)**2 - 1) +'})
    scene = _system_file_scene(tmp_path, system)
    for cmd in (['simulate', str(scene), '--t-end', '0.1', '--out',
                 str(tmp_path / 'o.csv')], ['eig', str(scene)]):
        assert cli.main(cmd) == 1
    from gyro_rotor.core.scene import load_scene
    from gyro_rotor.errors import SceneError
    with pytest.raises(SceneError, match='E\\* of system twin_gimbal is inf at the steady'):
        load_scene(scene)


#: a flow sequence of 10 anchored lists, each holding the one before 9 times: 9**9 leaves
ALIAS_BOMB = ('[&a0 [x, x, x, x, x, x, x, x, x], ' + ', '.join(
    f'&a{i} [' + ', '.join([f'*a{i - 1}'] * 9) + ']' for i in range(1, 10)) + ']')


@pytest.mark.parametrize('where', ['mass_matrix', 'description', 'initial', 'set'])
def test_alias_bomb_is_refused_at_once(tmp_path, where, capsys):
    """Finding 10: 9 levels of aliases took 2 min 18 s, 15.6 GB and a 2.1 GB error line."""
    import time as _time
    from gyro_rotor.core.scene import load_scene
    from gyro_rotor.core.system.system_file import load_system
    from gyro_rotor.errors import GyroRotorError
    t0 = _time.monotonic()
    if where == 'set':
        assert cli.main(['simulate', 'precession', '--set', f'A_R={ALIAS_BOMB}', '--out',
                         str(tmp_path / 'x.csv')]) == 1
        text = capsys.readouterr().err
        assert 'alias' in text and len(text) < 400, text[:400]
        return
    if where == 'mass_matrix':
        text = (REPO / 'config' / 'systems' / 'twin_gimbal.yaml').read_text()
        a = text.index('mass_matrix:')
        b = text.index('rotor_inertia:')
        path = tmp_path / 'bomb.yaml'
        path.write_text(text[:a] + f'mass_matrix: {ALIAS_BOMB}\n' + text[b:])
        load = load_system
    else:
        old = ('    description: "' if where == 'description' else '      theta0: 0.1\n')
        new = (f'    description: {ALIAS_BOMB}\n    old: "' if where == 'description'
               else f'      theta0: {ALIAS_BOMB}\n')
        path = tmp_path / 'bomb.yaml'
        path.write_text(_scene_text(**{old: new}))
        load = load_scene
    with pytest.raises(GyroRotorError, match='alias') as err:
        load(path)
    assert _time.monotonic() - t0 < 5.0
    assert len(str(err.value)) < 400


@pytest.mark.parametrize('where', ['potential', 'description', 'set'])
def test_deep_nesting_is_one_line(tmp_path, where, capsys):
    """Finding 11: 10^4-deep nesting ended in a 2999-line RecursionError traceback."""
    from gyro_rotor.core.scene import load_scene
    from gyro_rotor.core.system.system_file import load_system
    from gyro_rotor.errors import GyroRotorError
    deep = '[' * 10000 + ']' * 10000
    if where == 'potential':
        with pytest.raises(GyroRotorError, match='nested more than') as err:
            load_system(_system(tmp_path, **{'potential: "': f'potential: {deep}\nold: "'}))
        err2 = None
        with pytest.raises(GyroRotorError, match='nested more than 60') as err2:
            load_system(_system(tmp_path, **{'potential: "': 'potential: "' + '(' * 1000
                                             + 'alpha' + ')' * 1000 + ' + '}))
        assert len(str(err2.value)) < 400
    elif where == 'description':
        path = tmp_path / 'deep.yaml'
        path.write_text(_scene_text(**{'    description: "': f'    description: {deep}\n'
                                                             '    old: "'}))
        with pytest.raises(GyroRotorError, match='nested more than') as err:
            load_scene(path)
    else:
        assert cli.main(['simulate', 'precession', '--set', f'A_R={deep}', '--out',
                         str(tmp_path / 'x.csv')]) == 1
        text = capsys.readouterr().err
        assert 'nested more than' in text and 'Traceback' not in text
        return
    assert len(str(err.value)) < 400


def test_symmetry_check_does_not_expand_big_powers(tmp_path):
    """Finding 12: (a+...+h)**16*(1+x) against its expanded twin hung past 120 s."""
    import time as _time
    from gyro_rotor.core.system.system_file import load_system
    from gyro_rotor.errors import SystemFileError
    s = '(J_p+c_a+J_g+J_t+J_h+c_b1+c_b2+gam1)**16'
    row = (f'  - ["J_p", "{s}*(1 + beta1)", "0"]\n  - ["{s} + beta1*{s}", "J_g", "0"]\n'
           '  - ["0", "0", "J_g"]\n')
    text = (REPO / 'config' / 'systems' / 'twin_gimbal.yaml').read_text()
    a = text.index('mass_matrix:\n') + len('mass_matrix:\n')
    b = text.index('rotor_inertia:')
    path = tmp_path / 'big.yaml'
    path.write_text(text[:a] + row + text[b:])
    t0 = _time.monotonic()
    load_system(path)
    path.write_text(text[:a] + row.replace('+ beta1*', '+ beta2*') + text[b:])
    with pytest.raises(SystemFileError, match='not symmetric: row 0, column 1'):
        load_system(path)
    assert _time.monotonic() - t0 < 10.0


def test_yaml_1_2_numbers_the_same_everywhere(tmp_path):
    """Finding 15: K_D: 1.0e5 was refused by the scene loader, taken by --params-file."""
    from gyro_rotor.cli.util import parse_sets
    from gyro_rotor.core.scene import load_scene
    path = tmp_path / 's.yaml'
    path.write_text(_scene_text(**{'K_D: 0.05 ': 'K_D: 1.0e5 '}))
    assert load_scene(path).system.params.K_D == 1.0e5
    path.write_text(_scene_text(**{'K_D: 0.05 ': 'K_D: 1e5 '}))
    assert load_scene(path).system.params.K_D == 1.0e5
    assert parse_sets(['K_D=1.0e5', 'x=1e-3', 'y=012', 'z=nan'])['y'] == 12
    assert parse_sets(['K_D=1.0e5'])['K_D'] == 1.0e5
    assert isinstance(parse_sets(['y=yes'])['y'], str)      # YAML 1.1's bool is text


# -- finding 6: --resume trusted any Parquet file; sweep.json unchecked -------------------------
def _sweep_args(out: Path, t_end: str = '0.2') -> list[str]:
    return ['sweep', 'pole_slip', '--grid', 'initial.dzdot=-100:100:8', '--t-end', t_end,
            '--out', str(out), '--serial', '--metrics', 'well,peak', '--quiet', '--no-maps',
            '--block', '2']


def test_sweep_resume_verifies_every_block(tmp_path, capsys):
    """Finding 6: block 1 copied as block 3 and a foreign block-000999 were taken as done."""
    import pyarrow.parquet as pq
    from gyro_rotor.analysis.sweep.store import SweepStore
    out = tmp_path / 'sw'
    assert cli.main(_sweep_args(out)) == 0
    capsys.readouterr()
    blocks = out / 'blocks'
    good = pq.read_table(blocks / 'block-000003.parquet')
    shutil.copy(blocks / 'block-000001.parquet', blocks / 'block-000003.parquet')
    shutil.copy(blocks / 'block-000000.parquet', blocks / 'block-000999.parquet')
    assert cli.main(_sweep_args(out) + ['--resume']) == 0
    text = capsys.readouterr().out
    assert '1 blocks run, 3 already there' in text, text
    assert 'block-000003.parquet: it is block 1' in text
    assert 'block-000999.parquet: this sweep has blocks 0..3' in text
    assert '8/8 points' in text
    table = SweepStore(out).read()
    assert table.column('point').to_pylist() == list(range(8))
    again = pq.read_table(blocks / 'block-000003.parquet')
    assert again.column('point').to_pylist() == good.column('point').to_pylist()
    assert again.column('peak_deviation').to_pylist() == \
        good.column('peak_deviation').to_pylist()


def test_sweep_without_or_with_a_bad_manifest_is_refused(tmp_path, capsys):
    """Finding 6: a missing or corrupt sweep.json is refused with one line.

    Without sweep.json, --resume --t-end 5 took blocks of t_end 10; a corrupt sweep.json
    gave a JSONDecodeError traceback.
    """
    out = tmp_path / 'sw'
    assert cli.main(_sweep_args(out)) == 0
    manifest = out / 'sweep.json'
    text = manifest.read_text()
    manifest.write_text(text[:len(text) // 2])
    capsys.readouterr()
    assert cli.main(_sweep_args(out) + ['--resume']) == 1
    err = capsys.readouterr().err
    assert err.startswith('ERROR: ') and 'is not a sweep specification' in err
    assert len(err.strip().splitlines()) == 1
    manifest.unlink()
    assert cli.main(_sweep_args(out, t_end='0.3') + ['--resume']) == 1
    err = capsys.readouterr().err
    assert 'holds blocks/ but no sweep.json' in err and len(err.strip().splitlines()) == 1


def test_huge_sweep_asks_first(tmp_path, capsys):
    """Finding 14: a 10^7-point sweep started at once ('eta 13683.5 s')."""
    args = ['sweep', 'pole_slip', '--grid', 'initial.dzdot=-100:100:10000', '--grid',
            'initial.dz=-3:3:1000', '--out', str(tmp_path / 'huge'), '--serial']
    assert cli.main(args) == 1
    err = capsys.readouterr().err
    assert 'pass --yes to run it' in err and '10,000,000 points' in err
    assert not (tmp_path / 'huge').exists()


# -- findings 13 and 15: the demo's grid, the command-line checks -------------------------------
@pytest.mark.ros
def test_demo_with_a_duration_whose_kick_is_off_the_grid(tmp_path, capsys):
    """Finding 13: the kick time is put on the sample grid.

    demo --duration 5 kicked at 1.25 s, off the 250 Hz grid, and failed after 2 minutes
    ('did not reach t = 5.0 s in time (last t = 1.248 s)').
    """
    assert cli.main(['demo', '--duration', '3', '--rtf', '0', '--quiet', '--out',
                     str(tmp_path / 'run')]) == 0
    out = capsys.readouterr().out
    assert 'kick at t = 0.75 s' in out and 'RESULT: CONFIRMED' in out


@pytest.mark.parametrize('argv, message', [
    (['monitor', '--duration', 'nan'], '--duration must be finite'),
    (['monitor', '--duration', '-1'], '--duration must be finite and >= 0'),
    (['monitor', '--namespace', 'bad name!'], "--namespace 'bad name!' is not a ROS namespace"),
    (['rt-bench', '--duration', '0'], '--duration must be finite and > 0'),
    (['rt-bench', '--rtf', 'nan'], '--rtf must be finite'),
    (['demo', '--kick-at', 'nan'], '--kick-at must be finite'),
    (['demo', '--kick-at', '30', '--duration', '20'], 'before --duration'),
    (['simulate', 'precession', '--set', 'publish_rate=0.0'], 'publish_rate must be in'),
    (['simulate', 'precession', '--set', 'step_size=-0.001'], 'step_size must be in'),
    (['eig', '--json', '{tmp}/missing/x.json'], 'does not exist'),
    (['eig', '--json', '{tmp}'], 'is a directory'),
    (['locus', '--csv', '{tmp}/missing/x.csv'], 'does not exist'),
    (['locus', '--json', '{tmp}'], 'is a directory'),
    (['locus', '--points', '100000000'], '--points must be from 2 to 100000'),
])
def test_command_line_values_are_checked_before_any_work(argv, message, tmp_path, capsys,
                                                         monkeypatch):
    """Finding 15: these ran forever, exited 0 with nothing, printed nan or skipped a kick.

    eig and locus refuse an unwritable output and a huge grid before they compute anything.
    """
    # the commands import these when they run (not at import: --help starts fast)
    import gyro_rotor.linear.locus as locus
    import gyro_rotor.linear.system as system
    called = []
    monkeypatch.setattr(system, 'linearize_scene', lambda *a, **k: called.append(1))
    monkeypatch.setattr(locus, 'check_claims', lambda *a, **k: called.append(1))
    assert cli.main([a.replace('{tmp}', str(tmp_path)) for a in argv]) == 1
    err = capsys.readouterr().err
    assert message in err and err.startswith('ERROR: ') and 'Traceback' not in err, err
    assert not called, 'refused before any computation'


def test_simulate_out_never_overwrites_nor_leaves_a_partial_file(tmp_path, capsys):
    """Finding 15: simulate --out refuses an existing file and writes all or nothing.

    --out existing.csv was overwritten silently; a full disk left a partial CSV and an
    error that did not name the file.
    """
    out = tmp_path / 'x.csv'
    out.write_text('precious\n')
    args = ['simulate', 'precession', '--t-end', '0.05', '--out', str(out)]
    assert cli.main(args) == 1
    assert 'exists already; pass --force' in capsys.readouterr().err
    assert out.read_text() == 'precious\n'
    assert cli.main(args + ['--force']) == 0 and out.read_text().startswith('t [s]')
    if Path('/dev/full').exists():
        from gyro_rotor.cli.util import write_output

        def to_full(tmp):
            with open('/dev/full', 'w') as f:
                f.write('x' * 100000)
        with pytest.raises(Exception, match=f'cannot write {out}: No space left'):
            write_output(str(out), to_full)
        assert out.read_text().startswith('t [s]')
        assert not [p for p in tmp_path.iterdir() if '.tmp' in p.name]


def test_code_generation_says_what_it_does(tmp_path, monkeypatch):
    """Finding 14: a 50-rotor system took 219 s to generate on first use, with no output."""
    from gyro_rotor.core.system import codegen
    from gyro_rotor.core.system.system_file import load_system
    monkeypatch.setattr(codegen, 'cache_dir', lambda: tmp_path)
    # an earlier test of this process may have loaded twin_gimbal already (in memory)
    monkeypatch.setattr(codegen, '_LOADED', {})
    lines: list[str] = []
    codegen.compile_system(load_system('twin_gimbal'), warm=False, progress=lines.append)
    assert lines[0].startswith('generating the equations of system twin_gimbal (n = 3, m = 2)')
    assert any('derived in' in x for x in lines) and lines[-1].startswith('  ready in')
    lines.clear()
    codegen._LOADED.clear()
    codegen.compile_system(load_system('twin_gimbal'), warm=False, progress=lines.append)
    assert lines == []                          # from the cache: nothing to say
