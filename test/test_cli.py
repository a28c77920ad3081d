"""The gyro-rotor command line: exit codes and messages (called as a function)."""

import subprocess
import sys

from gyro_rotor.cli.main import main
import pytest


def test_simulate_prints_summary_and_writes_csv(tmp_path, capsys):
    out = tmp_path / 'traj.csv'
    assert main(['simulate', 'precession', '--t-end', '0.5', '--rate', '50',
                 '--out', str(out), '--set', 'K_D=0.1']) == 0
    text = capsys.readouterr().out
    for word in ('final state', 'E*', 'residual', 'RHS evaluations', 'wall time', '||q|-1|'):
        assert word in text
    assert out.read_text().startswith('t,theta,psi,phi_R,phi_M,')


def test_steady_prints_both_branches(capsys):
    assert main(['steady', 'precession']) == 0
    text = capsys.readouterr().out
    assert 'branch 1' in text and 'branch 2' in text and 'eq. (22)' in text


@pytest.mark.parametrize('argv, match', [
    (['simulate', 'precesion'], "did you mean 'precession'"),
    (['simulate', 'precession', '--set', 'K_D=-1'], 'K_D must not be negative'),
    (['simulate', 'precession', '--set', 'A_R=0'], 'inertia A_R must be positive'),
    (['simulate', 'precession', '--set', 'pole_pairs=1.5'], 'pole_pairs'),
    (['simulate', 'precession', '--set', 'Kd=1'], "did you mean 'K_D'"),
    (['simulate', 'precession', '--set', 'oops'], 'NAME=VALUE'),
    (['simulate', 'precession', '--rtol', '-1'], 'rtol must be positive'),
    (['simulate', 'precession', '--t-end', '0.1', '--out', 'x.txt'], '.csv or .npz'),
    (['steady', 'precession', '--set', 'c_theta=1.0', '--set', 'Omega0=10.0',
      '--theta0', '0.5'], 'discriminant'),
])
@pytest.mark.filterwarnings('ignore::gyro_rotor.core.params.StaticallyUnstableWarning')
def test_bad_input_exits_non_zero_with_message(argv, match, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 1
    cap = capsys.readouterr()
    assert match in cap.err + cap.out
    assert 'Traceback' not in cap.err


def test_bad_input_message_names_problem(capsys):
    main(['simulate', 'precession', '--set', 'K_D=-1'])
    assert 'K_D' in capsys.readouterr().err


def test_usage_error_and_module_entry_point():
    r = subprocess.run([sys.executable, '-m', 'gyro_rotor', 'simulate', 'precession',
                        '--t-end', 'abc'], capture_output=True, text=True)
    assert r.returncode == 2 and 'invalid float value' in r.stderr
    r = subprocess.run([sys.executable, '-m', 'gyro_rotor', 'simulate', 'nosuch'],
                       capture_output=True, text=True)
    assert r.returncode == 1 and "unknown scene 'nosuch'" in r.stderr


@pytest.mark.parametrize('argv, match', [
    (['simulate', 'precession', '--out', '/nonexistent/dir/x.csv'], 'does not exist'),
    (['simulate', 'precession', '--rate', '1e12'], 'samples is more than'),
    (['steady', 'precession', '--set', 'Omega0=1e200'], 'supported range'),
])
def test_bad_output_and_sizes_are_refused_before_work(argv, match, capsys):
    assert main(argv) == 1
    assert match in capsys.readouterr().err


def test_set_reads_exponent_notation(capsys):
    assert main(['steady', 'precession', '--set', 'K_D=1e-3']) == 0
