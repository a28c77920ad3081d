"""Sweeps on Dask (gyro_rotor.analysis.sweep, ``gyro-rotor sweep``): same numbers everywhere.

Serial in-process and a LocalCluster of 2 worker processes give identical results; a
worker killed mid-sweep costs nothing (every point exactly once, the same numbers);
``--resume`` computes only the missing blocks; bad grids are refused before any work.
"""

import os
import signal

from gyro_rotor.analysis.sweep.metrics import PointStatus, well_passages
from gyro_rotor.analysis.sweep.runner import Executor, run_sweep
from gyro_rotor.analysis.sweep.store import SweepStore
from gyro_rotor.analysis.sweep.task import make_spec, run_block
from gyro_rotor.cli.main import main
import numpy as np
import pytest

GRID = ['initial.dzdot=-150:150:12', 'K_D=0.02:0.2:2:log']
METRIC_COLS = ('final_well', 'pole_slips', 'settling_time', 'peak_deviation', 'decay_rate',
               'final_E_star', 'spectral_abscissa')


def _spec(block=4):
    return make_spec('pole_slip', GRID, t_end=0.4, rate=100.0, block_size=block)


def _columns(out):
    t = SweepStore(out).read()
    return {c: t.column(c).to_numpy(zero_copy_only=False) for c in t.column_names}


def _assert_same(a, b):
    assert set(a) == set(b)
    for c in METRIC_COLS + ('initial.dzdot', 'K_D'):
        x, y = np.asarray(a[c], dtype=float), np.asarray(b[c], dtype=float)
        np.testing.assert_allclose(x, y, rtol=1e-12, atol=0.0, equal_nan=True, err_msg=c)
    np.testing.assert_array_equal(a['status'], b['status'])


@pytest.fixture(scope='module')
def serial_result(tmp_path_factory):
    out = tmp_path_factory.mktemp('serial') / 'sweep'
    r = run_sweep(_spec(), out, executor=Executor.SERIAL)
    assert r.blocks_run == list(range(6)) and r.points_run == 24
    return _columns(out)


@pytest.fixture(scope='module')
def cluster2():
    distributed = pytest.importorskip('distributed')
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=':0') as cluster:
        with distributed.Client(cluster) as client:
            yield client


def test_serial_result_is_a_pull_in_map(serial_result):
    """Every point once, all OK; slow initial slips stay in well 0, fast ones slip poles."""
    np.testing.assert_array_equal(serial_result['point'], np.arange(24))
    assert np.all(serial_result['status'] == PointStatus.OK)
    slow = np.abs(serial_result['initial.dzdot']) < 20
    fast = np.abs(serial_result['initial.dzdot']) > 100
    assert np.all(serial_result['final_well'][slow] == 0)
    assert np.all(serial_result['pole_slips'][fast] >= 3)
    # the sign of the initial slip decides the direction of the slips
    dz = serial_result['initial.dzdot'][fast]
    assert np.all(np.sign(serial_result['final_well'][fast]) == np.sign(dz))


def test_serial_and_local_cluster_agree(serial_result, cluster2, tmp_path):
    """2 worker processes, by client or by address, give the serial numbers (to 1e-12)."""
    r = run_sweep(_spec(), tmp_path / 'dask', executor=Executor.LOCAL, client=cluster2)
    assert r.workers == 2 and sorted(r.blocks_run) == list(range(6))
    _assert_same(serial_result, _columns(tmp_path / 'dask'))
    # the same cluster reached by its address, as --scheduler ADDRESS does
    r = run_sweep(_spec(), tmp_path / 'addr', executor=Executor.ADDRESS,
                  scheduler=cluster2.scheduler.address)
    assert r.workers == 2 and sorted(r.blocks_run) == list(range(6))
    _assert_same(serial_result, _columns(tmp_path / 'addr'))


def test_cli_scheduler_address(serial_result, cluster2, tmp_path, capsys):
    """``gyro-rotor sweep --scheduler ADDRESS`` runs on that cluster, with the serial numbers."""
    out = tmp_path / 'cli-addr'
    args = ['sweep', 'pole_slip', '--t-end', '0.4', '--rate', '100', '--block', '4',
            '--out', str(out), '--quiet', '--no-maps', '--scheduler', cluster2.scheduler.address]
    for g in GRID:
        args += ['--grid', g]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert 'address' in text and 'on 2 worker(s)' in text and '24/24 points' in text, text
    _assert_same(serial_result, _columns(out))


def test_cli_scheduler_unreachable(tmp_path, capsys):
    """No scheduler at the address: one ERROR line naming it, exit 1."""
    import socket
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        port = s.getsockname()[1]            # a port nobody listens on
    address = f'tcp://127.0.0.1:{port}'
    assert main(['sweep', 'pole_slip', '--grid', 'initial.dzdot=-100:100:4', '--t-end', '0.2',
                 '--out', str(tmp_path / 'x'), '--quiet', '--scheduler', address]) == 1
    err = capsys.readouterr().err
    assert err.startswith('ERROR: --scheduler ' + address) and err.count('\n') == 1, err


def test_worker_killed_mid_sweep(serial_result, tmp_path):
    """SIGKILL a worker that is running a block: the scheduler reruns it; each point once."""
    distributed = pytest.importorskip('distributed')
    killed = []
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=':0') as cluster, \
            distributed.Client(cluster) as client:
        def kill_one(res):
            if killed:
                return
            busy = [w for w, keys in client.processing().items() if keys]
            assert busy, 'no block in flight to kill'
            pid = client.run(os.getpid, workers=[busy[0]])[busy[0]]
            os.kill(pid, signal.SIGKILL)
            killed.append((busy[0], pid, list(client.processing()[busy[0]])))
        r = run_sweep(_spec(block=2), tmp_path / 'killed', executor=Executor.LOCAL,
                      client=client, on_block=kill_one)
    assert killed and killed[0][2], 'the killed worker had no task'
    with pytest.raises(ProcessLookupError):
        os.kill(killed[0][1], 0)
    assert sorted(r.blocks_run) == list(range(12))       # each block written once
    got = _columns(tmp_path / 'killed')
    np.testing.assert_array_equal(got['point'], np.arange(24))
    _assert_same(serial_result, got)


def test_resume_computes_only_missing_blocks(serial_result, tmp_path):
    """Interrupt after 2 blocks; --resume runs exactly the other 4; the result is complete."""
    out = tmp_path / 'resume'

    class Stop(Exception):
        pass

    first = []

    def stop_after_two(res):
        first.append(res.block)
        if len(first) == 2:
            raise Stop
    with pytest.raises(Stop):
        run_sweep(_spec(), out, executor=Executor.SERIAL, on_block=stop_after_two)
    assert SweepStore(out).done_blocks(_spec()) == set(first)
    r = run_sweep(_spec(), out, executor=Executor.SERIAL, resume=True)
    assert r.blocks_skipped == 2
    assert sorted(r.blocks_run) == sorted(set(range(6)) - set(first))
    _assert_same(serial_result, _columns(out))
    # a complete sweep resumed computes nothing
    assert run_sweep(_spec(), out, executor=Executor.SERIAL, resume=True).blocks_run == []


def _as_older_version(out, general):
    """Rewrite a sweep's directory as a version with the ``general`` key wrote it.

    Its sweep.json gets the key and its blocks the hash of that text (as that version put
    its own sweep.json's hash into each block).
    """
    import hashlib
    import json

    import pyarrow.parquet as pq
    from gyro_rotor.analysis.sweep.store import BLOCK_KEY
    manifest = out / 'sweep.json'
    d = json.loads(manifest.read_text(encoding='utf-8'))
    d['general'] = general
    text = json.dumps(d, indent=1, sort_keys=True)
    manifest.write_text(text, encoding='utf-8')
    for f in (out / 'blocks').glob('block-*.parquet'):
        table = pq.read_table(f)
        info = json.loads(table.schema.metadata[BLOCK_KEY])
        info['spec_sha256'] = hashlib.sha256(text.encode()).hexdigest()
        pq.write_table(table.replace_schema_metadata({BLOCK_KEY: json.dumps(info).encode()}), f)


def test_resume_of_an_older_sweep_json(tmp_path, capsys):
    """A sweep.json with the dropped ``general`` key: resumed with its blocks kept.

    A centrifuge's (``general: false``) reads as before the key was dropped (issue 25) and
    its blocks count; a system file's (``general: true``, its base held only t_end) is
    refused with one line.
    """
    for scene, general in (('pole_slip', False), ('twin_gimbal', True)):
        out = tmp_path / scene
        args = ['sweep', scene, '--grid', 'K_D=0.05:0.2:2', '--t-end', '0.1', '--out',
                str(out), '--serial', '--metrics', 'peak', '--quiet', '--no-maps']
        assert main(args) == 0
        before = _columns(out)
        _as_older_version(out, general)
        capsys.readouterr()
        if general:
            assert main(args + ['--resume']) == 1
            err = capsys.readouterr().err
            assert 'older version' in err and err.count('\n') == 1, err
            continue
        assert SweepStore(out).read().num_rows == 2
        assert main(args + ['--resume']) == 0
        assert '0 blocks run, 1 already there' in capsys.readouterr().out
        got = _columns(out)
        np.testing.assert_array_equal(got['peak_deviation'], before['peak_deviation'])
        assert 'general' not in make_spec(scene, ['K_D=0.05:0.2:2']).to_json()


def test_cli_resume_and_refusals(tmp_path, capsys):
    """The command: a sweep, the refusal to overwrite it, --resume with nothing to do."""
    out = str(tmp_path / 'cli')
    args = ['sweep', 'pole_slip', '--grid', 'initial.dzdot=-100:100:4', '--t-end', '0.2',
            '--out', out, '--serial', '--metrics', 'well,peak', '--quiet']
    assert main(args) == 0
    text = capsys.readouterr().out
    assert '4/4 points' in text and (tmp_path / 'cli' / 'maps' / 'final_well.png').is_file()
    assert main(args) == 1
    assert 'already holds a sweep' in capsys.readouterr().err
    assert main(args + ['--resume']) == 0
    assert '0 blocks run, 1 already there' in capsys.readouterr().out
    maps = tmp_path / 'elsewhere'
    assert main(args + ['--resume', '--maps', str(maps)]) == 0
    assert (maps / 'final_well.png').is_file() and (maps / 'peak_deviation.png').is_file()
    capsys.readouterr()
    changed = [a if a != '0.2' else '0.3' for a in args]
    assert main(changed + ['--resume']) == 1
    assert 'differs in t_end' in capsys.readouterr().err


@pytest.mark.parametrize('grid, message', [
    ('K_D=0.1:0.1:5', 'empty range'),
    ('K_D=0.1:1:0', 'empty range'),
    ('K_X=0:1:3', "unknown key 'K_X'"),
    ('K_D=0:1:-3', 'COUNT must be positive'),
    ('K_D=-1:1:3', 'K_D = -1 is refused'),
    ('A_R=0:0.1:3', 'A_R = 0 is refused'),
    ('t_end=1:2:3', 'cannot be swept'),
    ('pole_pairs=1:2:3', 'takes integers'),
    ('K_D=1e-3:1:3:log2', "spacing must be 'lin' or 'log'"),
    ('K_D=0:1:3:log', 'log axis'),
    ('K_D=a:1:3', 'is not a number'),
    ('K_D', 'KEY=START:STOP:COUNT'),
])
def test_bad_grid_is_an_error_before_any_work(grid, message, tmp_path, capsys):
    """One ERROR line naming the problem, exit status 1, nothing written."""
    out = tmp_path / 'never'
    assert main(['sweep', 'pole_slip', '--grid', grid, '--out', str(out), '--serial']) == 1
    err = capsys.readouterr().err
    assert err.startswith('ERROR: ') and message in err and err.count('\n') == 1, err
    assert not out.exists()


@pytest.mark.parametrize('extra, message', [
    (['--metrics', 'well,speed'], "unknown metric 'speed'"),
    (['--workers', '0'], '--workers must be positive'),
    (['--t-end', '-1'], '--t-end must be positive'),
])
def test_bad_options_are_errors_before_any_work(extra, message, tmp_path, capsys):
    """Bad --metrics, --workers, --t-end: one ERROR line, exit 1, nothing written."""
    out = tmp_path / 'never'
    assert main(['sweep', 'pole_slip', '--grid', 'K_D=0.1:1:3', '--out', str(out)]
                + extra) == 1
    err = capsys.readouterr().err
    assert err.startswith('ERROR: ') and message in err and err.count('\n') == 1, err
    assert not out.exists()


def test_scene_initial_condition_matches_simulate(capsys):
    """The sweep point at the pole_slip scene's own initial slip slips as ``simulate`` says.

    The scene's initial slip speed is read from its file; the slip count is the one
    ``gyro-rotor simulate pole_slip`` prints (RotorAnalyzer over its trajectory).
    """
    import re

    from gyro_rotor.analysis.sweep.task import scene_flat
    from gyro_rotor.numerics.simulate import simulate
    dzdot = scene_flat('pole_slip')[0]['initial.dzdot']
    spec = make_spec('pole_slip', [f'initial.dzdot={dzdot}:{dzdot}:1'], metrics=['well'])
    res = run_block(spec, 0).columns
    assert main(['simulate', 'pole_slip']) == 0
    printed = re.search(r'pole slips: +(\d+)', capsys.readouterr().out)
    assert printed, 'simulate printed no pole-slip count'
    assert res['status'][0] == PointStatus.OK
    assert res['pole_slips'][0] == int(printed.group(1)) == 3     # the README's reference
    tr = simulate('pole_slip')
    p = tr.scene.system.params.pole_pairs
    assert res['final_well'][0] == int(round(tr.z[-1] * p / (2 * np.pi))) == -3


def test_sweep_bench_writes_to_a_new_directory_by_default():
    """``sweep-bench`` never overwrites the committed bench/ unless --out bench is given."""
    from gyro_rotor.cli.commands.sweep_bench import default_out_dir
    from gyro_rotor.cli.main import build_parser
    args = build_parser().parse_args(['sweep-bench'])
    assert args.out is None
    name = default_out_dir()
    assert name.startswith('sweep-bench-') and len(name) == len('sweep-bench-YYYYmmdd-HHMMSS')
    assert build_parser().parse_args(['sweep-bench', '--out', 'bench']).out == 'bench'


GENERAL_GRID = ['constants.c_a=20:40:2', 'K_D=0.02:0.2:2:log']


def _general_spec():
    return make_spec('twin_gimbal', GENERAL_GRID, t_end=0.5, rate=100.0, block_size=3)


def test_general_sweep_matches_a_direct_integration(tmp_path):
    """A sweep point of a system file's scene equals the scene loaded with its values, run alone.

    Reference: the project's dop853 at rtol 1e-11 (not the sweep's RK4 ensemble) on
    ``load_scene(twin_gimbal, {constants.c_a: 40, K_D: 0.2})``.
    """
    from gyro_rotor.core.scene import load_scene
    from gyro_rotor.numerics.simulate import integrate
    spec = _general_spec()
    assert spec.n_points == 4 and spec.n_blocks == 2
    r = run_sweep(spec, tmp_path / 'g', executor=Executor.SERIAL)
    assert sorted(r.blocks_run) == [0, 1]
    got = _columns(tmp_path / 'g')
    np.testing.assert_array_equal(got['point'], np.arange(4))
    assert np.all(got['status'] == PointStatus.OK)
    j = int(np.nonzero((got['constants.c_a'] == 40.0) & np.isclose(got['K_D'], 0.2))[0][0])
    scene = load_scene('twin_gimbal', {'constants.c_a': 40.0, 'K_D': 0.2})
    model = scene.make_model()
    run = integrate(model, scene.initial_state(model), spec.t_eval, method='dop853',
                    rtol=1e-11, atol=1e-13)
    q = run.y[:, :model.n] - np.asarray(scene.system.steady_q)
    assert got['peak_deviation'][j] == pytest.approx(np.abs(q).max(), rel=1e-7)
    assert got['final_E_star'][j] == pytest.approx(model.energy(run.y[-1:])[0], rel=1e-7)
    # the values reach the points: a stiffer turntable spring changes the motion
    assert len(set(np.round(got['final_E_star'], 9))) == 4
    # every system offers every metric: the linear drives of twin_gimbal have no wells,
    # and the abscissa is the prediction's (the one linearization of every scene)
    from gyro_rotor.analysis.prediction import predict
    assert got['final_well'][j] == 0 and got['pole_slips'][j] == 0
    assert got['spectral_abscissa'][j] == predict(scene).spectral_abscissa < 0


def test_general_sweep_same_on_a_local_cluster(cluster2, tmp_path):
    """Serial and 2 worker processes give the same numbers for a system file's scene (to 1e-12)."""
    run_sweep(_general_spec(), tmp_path / 's', executor=Executor.SERIAL)
    r = run_sweep(_general_spec(), tmp_path / 'd', executor=Executor.LOCAL, client=cluster2)
    assert r.workers == 2 and sorted(r.blocks_run) == [0, 1]
    a, b = _columns(tmp_path / 's'), _columns(tmp_path / 'd')
    for c in ('peak_deviation', 'settling_time', 'decay_rate', 'final_E_star'):
        np.testing.assert_allclose(a[c], b[c], rtol=1e-12, atol=0.0, equal_nan=True, err_msg=c)


@pytest.mark.parametrize('extra, message', [
    (['--grid', 'constants.c_x=1:2:3'], "unknown constant 'c_x'"),
    (['--grid', 'drive.R9.K_D=0.1:0.2:2'], "unknown key 'drive.R9.K_D'"),
    (['--grid', 'constants.J_g=-1:1:3'], 'not positive definite'),
    (['--grid', 'K_D=-1:1:3'], 'must not be negative'),
    (['--grid', 'initial.q=0:1:2'], "cannot be swept in a system file's scene"),
    (['--grid', 'K_D=0.1:0.2:2', '--metrics', 'wells'], "unknown metric 'wells'"),
])
def test_bad_general_grid_is_an_error_before_any_work(extra, message, tmp_path, capsys):
    """Scenes of system files: one ERROR line naming the problem, exit 1, nothing written."""
    out = tmp_path / 'never'
    assert main(['sweep', 'twin_gimbal', '--out', str(out), '--serial'] + extra) == 1
    err = capsys.readouterr().err
    assert err.startswith('ERROR: ') and message in err and err.count('\n') == 1, err
    assert not out.exists()


def test_well_passages_counts_with_hysteresis():
    """Jitter on a maximum counts nothing; a jump over two wells between samples counts 2."""
    u = np.array([0.0, 0.3, 0.5, 0.45, 0.55, 0.49, 0.2, 0.0, 0.9, 1.1, 3.05, 2.5, 2.1])
    assert well_passages(u) == 1 + 2 + 1


def test_progress_bar_counts_points():
    """The text progress bar: a line per tenth off a terminal, ending at all points, 100 %."""
    import io

    from gyro_rotor.analysis.sweep.runner import TextProgress
    stream = io.StringIO()
    bar = TextProgress(40, stream=stream, width=10)
    for _ in range(8):
        bar.update(5)
    lines = stream.getvalue().splitlines()
    assert len(lines) == 8, lines                     # 5, 10, ..., 40 of 40: each a new tenth
    assert lines[0].startswith('[#.........] 5/40 points  12.5%'), lines[0]
    assert lines[-1].startswith('[##########] 40/40 points 100.0%'), lines[-1]


@pytest.mark.parametrize('scene, grid, target', [
    ('pole_slip', ['K_D=0.5:2:3'], 'gyro_rotor.analysis.sweep.task.run_ensemble'),
    ('twin_gimbal', ['K_D=0.01:0.1:3'], 'gyro_rotor.analysis.sweep.task.run_ensemble'),
])
def test_a_block_that_fails_falls_back_to_its_points(scene, grid, target, monkeypatch):
    """Every kind of scene: the block's ensemble raises, its points are run one by one.

    The fake ensemble refuses the block and the third point, and returns the second's
    samples non-finite from the fourth on: rows OK, DIVERGED, FAILED, with their messages;
    the first point's numbers are those of the whole block run at once.
    """
    import importlib
    spec = make_spec(scene, grid, t_end=0.2, rate=100.0, metrics=['peak', 'energy'])
    ref = run_block(spec, 0).columns
    module, _, name = target.rpartition('.')
    real = getattr(importlib.import_module(module), name)
    calls = []

    def fake(model, Y, t_eval, **kw):
        calls.append(len(Y))
        if len(Y) > 1 or len(calls) == 4:
            raise ArithmeticError('refused by the test')
        res = real(model, Y, t_eval, **kw)
        if len(calls) == 3:
            res.y[3:] = np.nan
        return res
    monkeypatch.setattr(target, fake)
    got = run_block(spec, 0).columns
    assert calls == [3, 1, 1, 1]
    assert list(got['status']) == [PointStatus.OK, PointStatus.DIVERGED, PointStatus.FAILED]
    assert list(got['message']) == ['', 'non-finite state at t = 0.03 s',
                                    'integration: ArithmeticError: refused by the test']
    for c in ('peak_deviation', 'final_E_star'):
        assert got[c][0] == ref[c][0] and np.all(np.isnan(got[c][1:])), c
        assert np.all(np.isfinite(ref[c])), c


def test_a_step_longer_than_a_sample_interval_is_shown_as_the_one_taken(capsys, tmp_path):
    """Adversarial finding: --step 10 on a 1-s run printed 'RK4 step 10 s (100 steps)'."""
    from gyro_rotor.cli.main import main
    spec = make_spec('precession', ['K_D=0:1:2'], t_end=1.0, rate=100.0, step=10.0)
    assert spec.step_used == pytest.approx(0.01) and spec.steps_per_trajectory == 100
    assert make_spec('precession', ['K_D=0:1:2'], t_end=1.0, step=1e-3).step_used == \
        pytest.approx(1e-3)
    assert main(['sweep', 'precession', '--grid', 'K_D=0:1:2', '--serial', '--out',
                 str(tmp_path / 'sw'), '--t-end', '1', '--step', '10', '--no-maps',
                 '--quiet', '--yes']) == 0
    assert 'RK4 step 0.01 s (--step 10 s is longer than a sample interval' in \
        capsys.readouterr().out
