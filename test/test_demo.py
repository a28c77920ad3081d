"""The main job: ``gyro-rotor demo`` end to end on a short run (both nodes as processes)."""

import json
import subprocess
import sys

from gyro_rotor.bag.bagio import open_bag
import pytest


@pytest.mark.ros
@pytest.mark.slow
def test_demo_confirms_the_default_scene(tmp_path):
    out = tmp_path / 'demo'
    r = subprocess.run([sys.executable, '-m', 'gyro_rotor', 'demo', '--duration', '8',
                        '--out', str(out)], capture_output=True, text=True, timeout=240)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert 'RESULT: CONFIRMED: asymptotically stable' in r.stdout
    assert 'kick at t =' in r.stdout
    # the checks name the verdicts as text, never an enum's repr
    assert ("verdict 'asymptotically stable', expected by the linear theory "
            "'asymptotically stable'") in r.stdout
    assert 'Traceback' not in r.stderr
    bag = open_bag(out / 'bag')
    assert bag.topics['/joint_states'].count >= 8 * 250 - 1
    assert bag.topics['/energy'].count == bag.topics['/joint_states'].count
    assert not bag.truncated
    report = json.loads((out / 'report' / 'report.json').read_text())
    assert report['verdict'] == 'asymptotically stable' and report['confirmed']
    assert report['dropped'] == 0 and report['unpaired'] == 0 and report['kicks'] == 1
    assert {c['name']: c['status'] for c in report['criteria']} == {
        'Lyapunov': 'PASS', 'energy balance': 'PASS', 'decay': 'PASS', 'modes': 'PASS',
        'data': 'PASS', 'scene': 'PASS'}
    # the live table: no NaN anywhere, and once the first window is fitted (the decay
    # column filled) it stays filled
    rows = [ln for ln in r.stdout.splitlines() if ln[:9].strip().replace('.', '').isdigit()]
    assert rows and not any('nan' in ln for ln in rows), rows
    decay = [ln.split()[3] for ln in rows]
    first = next(i for i, d in enumerate(decay) if d != '-')
    assert all(d != '-' for d in decay[first:]), rows
    for png in ('energy.png', 'eigenvalues.png', 'state.png'):
        assert (out / 'report' / png).stat().st_size > 1000


def test_demo_refuses_bad_arguments(tmp_path, capsys):
    from gyro_rotor.cli.main import main
    assert main(['demo', 'nosuch']) == 1
    assert "unknown scene 'nosuch'" in capsys.readouterr().err
    assert main(['demo', '--duration', '-1']) == 1
    assert '--duration' in capsys.readouterr().err
    busy = tmp_path / 'busy'
    busy.mkdir()
    (busy / 'x').write_text('keep me')
    assert main(['demo', '--out', str(busy)]) == 1
    assert 'not empty' in capsys.readouterr().err
    assert (busy / 'x').read_text() == 'keep me'


@pytest.mark.ros
@pytest.mark.slow
def test_demo_exit_status_follows_the_verdict(tmp_path):
    # 2 s with the kick at 0.5 s: the segment after the kick is shorter than the 2 s a fit
    # needs, so decay and modes stay NOT YET: insufficient data, NOT CONFIRMED, status 1
    out = tmp_path / 'short'
    r = subprocess.run([sys.executable, '-m', 'gyro_rotor', 'demo', '--duration', '2',
                        '--out', str(out), '--quiet'], capture_output=True, text=True,
                       timeout=240)
    assert r.returncode == 1, r.stdout[-3000:] + r.stderr[-3000:]
    assert 'RESULT: NOT CONFIRMED: insufficient data' in r.stdout
    assert '[NOT YET] decay' in r.stdout and 'Traceback' not in r.stderr


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.parametrize('scene,verdict', [('elastic_frame', 'marginal'),
                                           ('twin_gimbal', 'insufficient data')])
def test_demo_of_a_general_system_at_its_default_duration(tmp_path, scene, verdict):
    """The README's two general demos at their default 20 s: the same verdict live and offline.

    elastic_frame CONFIRMED; twin_gimbal 'insufficient data' (exit 1): its decay is not
    decided in 8 s windows (docs/manual/analysis.md: the rate of E* - E*_inf held against
    the slowest term that shows, the 6.11 Hz gimbal mode's), every other criterion passes.

    elastic_frame said NOT CONFIRMED at 20 s (its 22.15 Hz = 8.734 + 13.419 Hz combination
    tone judged as a mode that disagrees); twin_gimbal's live verdict said 'not confirmed:
    failed: modes' from t = 2.99 to 8.04 s (a root given to the wrong one of two near
    modes). Every live verdict the analysis node published, as recorded in the bag, is the
    linear theory's or 'insufficient data'.
    """
    out = tmp_path / 'demo'
    r = subprocess.run([sys.executable, '-m', 'gyro_rotor', 'demo', scene, '--rtf', '0',
                        '--quiet', '--out', str(out)], capture_output=True, text=True,
                       timeout=300)
    assert 'Traceback' not in r.stderr, r.stderr[-3000:]
    confirmed = verdict != 'insufficient data'
    assert r.returncode == (0 if confirmed else 1), r.stdout[-3000:] + r.stderr[-3000:]
    assert f'RESULT: {"CONFIRMED" if confirmed else "NOT CONFIRMED"}: {verdict}' in r.stdout
    if not confirmed:
        assert '[NOT YET] decay' in r.stdout and r.stdout.count('[PASS]') >= 5
    bag = open_bag(out / 'bag')
    assert bag.topics['/energy'].count == 5001
    live = [msg.data for _, _, msg in bag.decoded(['/analysis_verdict'])]
    assert live, 'the analysis node published verdicts'
    assert all(v.split(':')[0] in (verdict, 'insufficient data') for v in live), live
    assert live[-1].startswith(verdict)
    final = json.loads(bag.metadata['gyro_rotor.live_result']['json'])
    assert final['verdict'] == verdict
    assert 'not confirmed' not in r.stdout


def test_demo_stops_watching_when_the_simulation_diverged(tmp_path, capsys):
    """Review finding 7: rotor_sim stopped at t = 2.19 s; the demo waited ~2 min for 5 s.

    The view (a stand-in for the demo's rclpy node) has the simulation's diagnostics say
    'diverged: ...' while its time stays short of the duration: the watch returns at once
    (the analysis of the bag then says what the data show), never waits for its deadline.
    """
    import argparse
    from gyro_rotor.cli.commands import demo

    class View:
        energy = {'t_sim': 2.192}
        diverged = 'diverged: energy-balance residual -1.09 J at t = 2.192 s'
        spins = 0

        def spin(self, _timeout):
            self.spins += 1
            assert self.spins < 100, 'the demo kept waiting after the divergence'

    class Proc:
        module = 'gyro_rotor.ros.sim_node'

        def poll(self):
            return None

    args = argparse.Namespace(quiet=True, duration=5.0, rtf=0.0, rate=250.0)
    assert demo._watch(args, View(), [Proc()], tmp_path, -1.0).startswith('diverged:')
    assert 'the simulation stopped at t = 2.192 s: diverged:' in capsys.readouterr().out
