"""The gyro-rotor command line: exit codes and messages (called as a function)."""

from pathlib import Path
import subprocess
import sys

from gyro_rotor.cli.main import main
import numpy as np
import pytest
from random_systems import unstable_scene

_REPO = Path(__file__).resolve().parent.parent
_BAG = str(_REPO / 'bags' / 'precession')
_README = str(_REPO / 'README.md')


def test_simulate_prints_summary_and_writes_csv(tmp_path, capsys):
    out = tmp_path / 'traj.csv'
    assert main(['simulate', 'precession', '--t-end', '0.5', '--rate', '50',
                 '--out', str(out), '--set', 'K_D=0.1']) == 0
    text = capsys.readouterr().out
    for word in ('final state', 'E*', 'residual', 'RHS evaluations', 'wall time', '||q|-1|'):
        assert word in text
    header = out.read_text().splitlines()[0].split(',')
    assert header[:6] == ['t [s]', 'theta [rad]', 'psi [rad]', 'phi_R [rad]', 'phi_M [rad]',
                          'theta_dot [rad/s]']
    from gyro_rotor.core.model import Model
    assert [h.split(' [')[0] for h in header] == [c[0] for c in Model.CSV_COLUMNS]
    assert all(h.endswith(']') for h in header)


def test_set_errors_name_the_option_not_the_scene_file(capsys):
    assert main(['simulate', 'precession', '--set', 'A_R=-0.05']) == 1
    err = capsys.readouterr().err
    assert err.startswith('ERROR: --set A_R=-0.05 (scene precession): inertia A_R')
    assert 'scene file' not in err


def test_fixed_step_method_reports_no_tolerances(capsys):
    assert main(['simulate', 'precession', '--t-end', '0.1', '--method', 'rk4']) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert 'rtol 1e' not in first and 'fixed step' in first
    assert main(['simulate', 'precession', '--t-end', '0.1', '--method', 'dop853']) == 0
    assert 'rtol 1e-' in capsys.readouterr().out.splitlines()[0]


def test_simulate_pole_slip_reports_the_slip_count(capsys):
    assert main(['simulate', 'pole_slip', '--t-end', '3']) == 0
    line = next(ln for ln in capsys.readouterr().out.splitlines() if 'pole slips' in ln)
    assert int(line.split(':')[1].split()[0]) > 0
    assert main(['simulate', 'precession', '--t-end', '0.1']) == 0
    assert 'pole slips' not in capsys.readouterr().out


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
    (['simulate', 'precession', '--rtol', '-1'], '--rtol must be finite and > 0'),
    (['simulate', 'precession', '--t-end', '0.1', '--out', 'x.txt'], '.csv or .npz'),
    (['locus', 'precession', '--points', '3', '--out', 'x.txt'], 'must end in .png'),
    (['eig', 'precession', '--json', ''], '--json is empty'),
    (['simulate', 'precession', '--set', 'initial.dzdot=1e300'], 'not a finite number'),
    (['simulate', 'precession', '--out', ''], '--out is empty'),
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


@pytest.mark.parametrize('argv, match', [
    (['locus', 'precession', '--points', 'abc'], "argument --points: invalid int value: 'abc'"),
    (['locus', 'precession', '--points', '2.5'], "argument --points: invalid int value: '2.5'"),
    (['tune', 'precession', '--K-S', 'abc'], "argument --K-S: invalid float value: 'abc'"),
    (['steady', 'precession', '--theta0', 'abc'],
     "argument --theta0: invalid float value: 'abc'"),
    (['eig', 'precession', '--bogus'], 'unrecognized arguments: --bogus (see gyro-rotor eig'),
    (['nosuch'], "invalid choice: 'nosuch'"),
    ([], 'the following arguments are required: COMMAND'),
])
def test_bad_arguments_are_one_error_line_exit_1(argv, match, capsys):
    assert main(argv) == 1
    cap = capsys.readouterr()
    assert cap.err.startswith('ERROR: ') and cap.err.count('\n') == 1, cap.err
    assert match in cap.err and 'usage:' not in cap.err and not cap.out


def test_help_still_exits_0(capsys):
    with pytest.raises(SystemExit) as exc:
        main(['locus', '--help'])
    assert exc.value.code == 0 and 'usage: gyro-rotor locus' in capsys.readouterr().out


def test_bad_input_message_names_problem(capsys):
    main(['simulate', 'precession', '--set', 'K_D=-1'])
    assert 'K_D' in capsys.readouterr().err


def test_usage_error_and_module_entry_point():
    # a bad argument is bad input like any other: one ERROR line, exit 1 (not argparse's
    # usage text and exit 2, which locus uses for "a claim failed")
    r = subprocess.run([sys.executable, '-m', 'gyro_rotor', 'simulate', 'precession',
                        '--t-end', 'abc'], capture_output=True, text=True)
    assert r.returncode == 1 and r.stderr.count('\n') == 1
    assert r.stderr.startswith("ERROR: argument --t-end: invalid float value: 'abc'")
    r = subprocess.run([sys.executable, '-m', 'gyro_rotor', 'simulate', 'nosuch'],
                       capture_output=True, text=True)
    assert r.returncode == 1 and "unknown scene 'nosuch'" in r.stderr


@pytest.mark.parametrize('argv, match', [
    (['simulate', 'precession', '--out', '/nonexistent/dir/x.csv'], 'does not exist'),
    (['simulate', 'precession', '--rate', '1e12'], 'samples is more than'),
    (['steady', 'precession', '--set', 'Omega0=1e200'], 'supported range'),
    (['analyze', _BAG, '--json', '/nonexistent/dir/a.json'], 'does not exist'),
    (['analyze', _BAG, '--out', _README], 'exists and is not a directory'),
    (['demo', 'precession', '--out', _README], 'exists and is not a directory'),
])
def test_bad_output_and_sizes_are_refused_before_work(argv, match, capsys):
    assert main(argv) == 1
    assert match in capsys.readouterr().err


def test_a_directory_given_as_scene_or_system_file_is_named_so(tmp_path, capsys):
    # review finding: '... does not exist' for a path that exists as a directory
    (tmp_path / 'sys.yaml').mkdir()
    scene = tmp_path / 'scene.yaml'
    scene.write_text('/**:\n  ros__parameters:\n    system: sys.yaml\n')
    for argv, what in ((['simulate', str(tmp_path)], 'scene file'),
                       (['eig', str(scene)], 'system file')):
        assert main(argv) == 1
        err = capsys.readouterr().err
        assert err.startswith('ERROR: ') and err.count('\n') == 1, err
        assert f'{what} ' in err and 'is a directory, not a file' in err, err


@pytest.mark.parametrize('argv, match', [
    (['locus', 'precession', '--csv', '/proc/x.csv'], 'cannot write /proc/x.csv'),
    (['locus', 'precession', '--json', '/proc/x.json'], 'cannot write /proc/x.json'),
    (['campbell', 'precession', '--json', '/proc/x.json'], 'cannot write /proc/x.json'),
    (['campbell', 'precession', '--omega-min', '10', '--omega-max', '5'],
     '--omega-max (5) must exceed --omega-min (10)'),
    (['campbell', 'precession', '--omega-min', '-10'], '--omega-min must be >= 0 rad/s'),
    (['campbell', 'precession', '--set', 'Omega0=-314.16', '--omega-max', '10'],
     '--omega-max must be <= 0 rad/s'),
    (['steady', 'twin_gimbal', '--theta0', '0.1'], '--theta0 applies to the centrifuge'),
])
def test_bad_outputs_and_ranges_are_one_error_line_before_work(argv, match, capsys):
    assert main(argv) == 1
    cap = capsys.readouterr()
    err = ''.join(x for x in cap.err.splitlines(True) if not x.startswith('gyro_rotor: '))
    assert err.startswith('ERROR: ') and err.count('\n') == 1 and match in err, err
    assert not cap.out


def test_set_reads_exponent_notation(capsys):
    assert main(['steady', 'precession', '--set', 'K_D=1e-3']) == 0


def test_a_closed_stdout_pipe_is_not_an_error_message():
    """`gyro-rotor scenes | head -0`: the reader is gone before anything is written."""
    proc = subprocess.Popen([sys.executable, '-m', 'gyro_rotor', 'scenes'],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    proc.stdout.close()
    err = proc.stderr.read()
    assert proc.wait(timeout=60) == 1
    assert 'Broken pipe' not in err and 'Errno 32' not in err and 'Traceback' not in err, err


def test_module_entry_point_from_the_folder_that_holds_the_checkout(tmp_path):
    """A folder named gyro_rotor in the working directory must not shadow the package."""
    from pathlib import Path
    import gyro_rotor
    (tmp_path / 'gyro_rotor').symlink_to(Path(gyro_rotor.__file__).resolve().parents[1])
    r = subprocess.run([sys.executable, '-m', 'gyro_rotor', 'recover', 'no_such_bag'],
                       cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert r.returncode == 1 and 'Traceback' not in r.stderr, r.stderr
    assert r.stderr.startswith('ERROR: no_such_bag: no such bag'), r.stderr


def test_soak_load_starts_busy_processes_and_stops_them(capsys):
    import time
    from gyro_rotor.tools.soak import CpuLoad, read_cpu_s
    with CpuLoad(2) as load:
        pids = [p.pid for p in load.procs]
        assert len(pids) == 2
        deadline = time.monotonic() + 30
        while not all((read_cpu_s(pid) or 0) > 0.05 for pid in pids):
            assert time.monotonic() < deadline, 'the busy processes use no CPU'
            time.sleep(0.05)
    assert all(read_cpu_s(pid) is None for pid in pids)        # stopped and reaped
    assert main(['soak', '--load', '-1', '--duration', '1']) == 1
    assert '--load must be >= 0' in capsys.readouterr().err


@pytest.mark.parametrize('argv', [['bench'], ['bench', '--quick']])
def test_bench_writes_to_a_new_directory_unless_told_bench(argv):
    """Issue 12: --quick overwrote the committed bench/ results (resolved without running)."""
    import re
    from gyro_rotor.cli.commands.bench import resolve_settings
    from gyro_rotor.cli.main import build_parser
    args = build_parser().parse_args(argv)
    assert resolve_settings(args) is None
    assert re.fullmatch(r'bench_out/bench-\d{8}-\d{6}', args.out), args.out   # git ignores it
    args = build_parser().parse_args(argv + ['--out', 'bench'])
    assert resolve_settings(args) is None and args.out == 'bench'
    args = build_parser().parse_args(argv + ['--scenes', 'no_such_scene'])
    assert resolve_settings(args).startswith('--scenes:')


#: a statically unstable one-coordinate system (V = k x^2 / 2, k < 0) on a self-stable drive
def test_simulate_of_an_unstable_system_says_it_grew(tmp_path, capsys):
    """Review finding: x grew to 1e39 and simulate exited 0 saying nothing.

    The energy identity holds (the residual is 1e-11 of |E*|): growth, not a divergence;
    the last line says so, the exit status is 2 and every sample is written.
    """
    out = tmp_path / 'neg.csv'
    assert main(['simulate', unstable_scene(tmp_path), '--out', str(out)]) == 2
    last = capsys.readouterr().out.splitlines()[-1]
    assert last.startswith('UNSTABLE: the motion grows, the energy identity sound'), last
    assert 'not a numerical divergence' in last
    assert len(out.read_text().splitlines()) == 1 + 1001


def test_simulate_of_an_unstable_system_too_short_to_fit_says_it_grows(tmp_path, capsys):
    """Review finding: simulate of the unstable system exited 0 saying nothing.

    With t_end below the analysis' shortest fit (2 s) no window measured the growth, so
    no line was printed and the exit status was 0, though E* went from -0.00045 J to
    -109128 J in 1.5 s. The linear theory's growing mode is named, exit 2.
    """
    assert main(['simulate', unstable_scene(tmp_path), '--t-end', '1.5']) == 2
    last = capsys.readouterr().out.splitlines()[-1]
    assert last.startswith('UNSTABLE: the linear theory predicts growing modes: mode (x) '), last
    assert '(Re lambda = +9.602 1/s); this 1.5 s run is too short for the analysis' in last
    assert last.endswith('(its fits need 2 s): E* went from -0.00045 J to -109128 J'), last


def test_simulate_of_an_unstable_system_grown_beyond_floats_is_unstable(tmp_path, capsys):
    """Review finding: growth until the state overflowed was called DIVERGED.

    k < 0 grows like exp(9.6 t): at t = 37.6 s the state leaves floating point's range and
    the integrator stops, with the energy identity sound in every sample before (1e-11 of
    |E*|). That is the unstable steady motion, not a failed integration: UNSTABLE, naming
    where the integration stopped; exit 2.
    """
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter('error')          # numpy's overflow warnings: none
        assert main(['simulate', unstable_scene(tmp_path), '--t-end', '100']) == 2
    last = capsys.readouterr().out.splitlines()[-1]
    assert last.startswith('UNSTABLE: the motion grows, the energy identity sound'), last
    assert 'then the integration stopped after the last finite sample (t = 37.37 s' in last
    assert 'DIVERGED' not in last


def test_simulate_of_a_diverging_integration_says_so_and_keeps_the_samples(tmp_path, capsys):
    """dop853 at rtol 0.9 blows up: the last line names the guard's numbers, exit 2.

    The samples before the first one the live guard rejects are written (the integrator
    went on to a non-finite state at t = 1.51 s; that used to be one ERROR line, exit 1 and
    no file).
    """
    out = tmp_path / 'div.csv'
    argv = ['simulate', 'precession', '--method', 'dop853', '--rtol', '0.9', '--atol', '1',
            '--out', str(out)]
    assert main(argv) == 2
    text = capsys.readouterr().out
    last = text.splitlines()[-1]
    assert last.startswith('DIVERGED: the integration diverged: energy-balance residual '), last
    assert 'exceeds max(max_residual 1 J, 1e-06 x max(|E*|, |E_ref|)) = 1 J' in last
    rows = np.loadtxt(out, delimiter=',', skiprows=1)
    t_break = float(last.split(' at t = ')[1].split(' s ')[0])
    assert rows[-1, 0] < t_break and len(rows) == round(t_break * 100)
    assert f'wrote {out} ({len(rows)} rows)' in text
    head = out.read_text().splitlines()[0].split(',')
    E, r = rows[:, head.index('E_star [J]')], rows[:, head.index('residual [J]')]
    assert np.all(np.abs(r) <= np.maximum(np.maximum(np.abs(E), abs(E[0])), 1.0))


def _strict_json(path):
    """Parse ``path`` as strict JSON: the bare Infinity / NaN of Python's json is refused."""
    import json

    def refuse(name):
        raise ValueError(f'{path.name}: {name} is not JSON')
    return json.loads(path.read_text(), parse_constant=refuse)


def test_every_json_file_is_strict_json_with_null_for_non_finite(tmp_path, capsys):
    """Review finding: eig's "tau": Infinity, locus's "K_D_to": Infinity (jq refuses them)."""
    eig, loc, camp = (tmp_path / f'{n}.json' for n in ('eig', 'locus', 'campbell'))
    assert main(['eig', 'precession', '--json', str(eig)]) == 0
    assert main(['locus', 'precession', '--points', '20', '--json', str(loc)]) == 0
    assert main(['campbell', 'precession', '--points', '5', '--json', str(camp)]) == 0
    modes = _strict_json(eig)['modes']
    assert any(m['tau'] is None for m in modes)          # the undamped zero root
    assert _strict_json(loc)['regimes'][-1]['K_D_to'] is None     # runs on to infinity
    _strict_json(camp)


def test_analyze_json_to_stdout_is_the_json_alone(capsys):
    """Adversarial finding: '--json -' mixed the text report into stdout (not pipeable)."""
    import json
    bag = Path(__file__).resolve().parent.parent / 'bags' / 'precession'
    assert main(['analyze', str(bag), '--no-plots', '--json', '-']) == 0
    cap = capsys.readouterr()
    assert json.loads(cap.out)['verdict'] and 'RESULT: CONFIRMED' in cap.err


def test_campbell_critical_speeds_are_exact_whatever_the_grid(tmp_path, capsys):
    """Review finding: --points 2 gave nutation x 1 at 39.95 rad/s, the default 37.69.

    A crossing is solved (brentq on the tracked mode's frequency minus order x speed) to
    CROSSING_RTOL, not interpolated between grid points; eig at the reported speed has the
    crossing's frequency.
    """
    import json
    from gyro_rotor.linear.campbell import CROSSING_RTOL
    crit = {}
    for n in (2, 7, 200):
        out = tmp_path / f'c{n}.json'
        assert main(['campbell', 'precession', '--points', str(n), '--json', str(out)]) == 0
        crit[n] = {(c['mode'], c['order']): c for c in json.loads(out.read_text())[
            'critical_speeds']}
    capsys.readouterr()
    assert crit[2].keys() == crit[200].keys() == crit[7].keys() and len(crit[200]) >= 3
    for key, c in crit[200].items():
        for n in (2, 7):
            assert abs(crit[n][key]['Omega0'] - c['Omega0']) <= 10 * CROSSING_RTOL * 628.32, (
                n, key, crit[n][key]['Omega0'], c['Omega0'])
    nut = next(c for c in crit[200].values() if c['label'].startswith('nutation')
               and c['order'] == 1)
    eig = tmp_path / 'eig.json'
    assert main(['eig', 'precession', '--set', f'Omega0={nut["Omega0"]!r}',
                 '--json', str(eig)]) == 0
    f = [abs(m['im']) / (2 * np.pi) for m in json.loads(eig.read_text())['modes']
         if m['name'].startswith('nutation')]
    assert min(abs(x - nut['frequency_hz']) for x in f) <= 1e-7 * nut['frequency_hz'], (
        f, nut)


_NUMBERS = ('0', '-1', 'inf', '-inf', 'nan', '1e300')
#: (command and its fixed arguments, option, the values refused, the message they get); a
#: value left out of a row is valid there (0 = until Ctrl-C, K_S = 0, ...). Every numeric
#: option of every command, with 0, negative, inf, -inf, nan, huge and the empty string.
_REFUSED = [
    (['demo', 'precession'], '--duration', _NUMBERS,
     '--duration must be finite and > 0 and <= 1e+09 s, got'),
    (['demo', 'precession'], '--rtf', ('-1', 'inf', '-inf', 'nan', '1e300'),
     '--rtf must be finite and >= 0 and <= 1000 (0 = as fast as possible), got'),
    (['demo', 'precession'], '--rate', _NUMBERS,
     '--rate must be finite and >= 10 and <= 10000 Hz, got'),
    (['demo', 'precession'], '--kick-at', ('inf', '-inf', 'nan'),
     '--kick-at must be finite (a time in s; any finite negative value: no kick), got'),
    (['demo', 'precession'], '--kick-at', ('0', '1e300'),
     '--kick-at must be at least one sample (1/250 s) and before --duration (20 s)'),
    (['simulate', 'precession'], '--t-end', _NUMBERS[:5], 't_end must be positive and finite'),
    (['simulate', 'precession'], '--t-end', ('1e300',), 'samples is more than 5e+07'),
    (['simulate', 'precession'], '--rate', _NUMBERS[:5], 'rate must be positive and finite'),
    (['simulate', 'precession'], '--rate', ('1e300',), 'samples is more than 5e+07'),
    (['simulate', 'precession'], '--rtol', _NUMBERS, '--rtol must be finite and > 0 and <= 1,'),
    (['simulate', 'precession'], '--atol', _NUMBERS, '--atol must be finite and > 0 and <= 1,'),
    (['steady', 'precession'], '--theta0', ('0', '-1', '1e300'),
     'solution II needs 0 < theta0 < pi'),
    (['steady', 'precession'], '--theta0', ('inf', '-inf', 'nan'), 'theta0 must be finite'),
    (['steady', 'precession'], '--theta0', ('3.14159',),
     'scene precession (--theta0 3.14159): no steady motion II at theta0 = 3.14159 rad: the '
     'discriminant'),
    (['locus', 'precession'], '--kd-min', _NUMBERS[:5],
     '--kd-min must be finite and > 0 N m s/rad (the log grid; K_D = 0 is always included)'),
    (['locus', 'precession'], '--kd-min', ('1e300',), '--kd-max (4502.89) must exceed'),
    (['locus', 'precession'], '--kd-max', _NUMBERS[:5], '--kd-max must be finite and > 0 N m'),
    (['locus', 'precession'], '--kd-max', ('1e300',), 'too large for the linear analysis'),
    (['locus', 'precession'], '--points', ('0', '-1'), '--points must be from 2 to 100000'),
    (['tune', 'precession'], '--K-S', ('-1',), 'K_S must not be negative'),
    (['tune', 'precession'], '--K-S', ('inf', '-inf', 'nan'), 'K_S must be finite'),
    (['tune', 'precession'], '--K-S', ('1e300',), 'outside the supported range'),
    (['bench'], '--repeats', ('0', '-1'), '--repeats must be >= 1'),
    (['bench'], '--drift-t-end', ('-1', 'inf', '-inf', 'nan', '1e300'),
     '--drift-t-end must be finite and >= 0 and <= 10000 s (0 = no drift run), got'),
    (['bench'], '--t-end', _NUMBERS, '--t-end must be finite and > 0 and <= 10000 s, got'),
    (['bench'], '--level', _NUMBERS,
     '--level must be finite and > 0 and <= 1 (a relative error), got'),
    (['analyze', 'bags/precession'], '--window', ('-1', '-inf', 'nan'),
     '--window must be >= 0 s (0 = whole segments)'),
    (['monitor'], '--duration', ('-1', 'inf', '-inf', 'nan'),
     '--duration must be finite and >= 0 [s] (0 = until Ctrl-C)'),
    (['monitor'], '--period', _NUMBERS[:5], '--period must be finite and > 0 [s]'),
    (['monitor'], '--domain-id', ('-1',), '--domain-id must be in 0..232'),
    (['soak'], '--rate', _NUMBERS, '--rate must be finite and >= 1 and <= 10000 Hz, got'),
    (['soak'], '--duration', _NUMBERS, '--duration must be finite and > 0 and <= 1e+09 s, got'),
    (['soak'], '--rtf', ('-1', 'inf', '-inf', 'nan', '1e300'),
     '--rtf must be finite and >= 0 and <= 1000 (0 = as fast as possible), got'),
    (['soak'], '--run-seconds', _NUMBERS,
     '--run-seconds must be finite and > 0 and <= 1e+09 s, got'),
    (['soak'], '--load', ('-1',), '--load must be >= 0 busy processes'),
    (['soak', '--find-max-rate'], '--rates', ('250,inf', '250,nan', '0', '250,-1', '1e300'),
     '--rates must be finite and >= 1 and <= 10000 Hz (each of them), got'),
    (['soak', '--find-max-rate'], '--rates', ('', ','), '--rates is empty'),
    (['rt-bench'], '--rtf', ('-1', 'inf', '-inf', 'nan', '1e300'),
     '--rtf must be finite and >= 0 and <= 1000'),
    (['rt-bench'], '--duration', _NUMBERS[:5], '--duration must be finite and > 0 [s]'),
    (['rt-bench'], '--publish-rate', _NUMBERS,
     '--publish-rate must be finite and >= 1 and <= 10000 [Hz]'),
    (['campbell', 'precession'], '--omega-min', _NUMBERS[1:5], '--omega-min must be >= 0 rad/s '
     '(finite,'),
    (['campbell', 'precession'], '--omega-min', ('1e300',), '--omega-max (628.32) must exceed'),
    (['campbell', 'precession'], '--omega-max', ('0',), '--omega-max (0) must exceed'),
    (['campbell', 'precession'], '--omega-max', _NUMBERS[1:5], '--omega-max must be >= 0 rad/s '
     '(finite,'),
    (['campbell', 'precession'], '--omega-max', ('1e300',), 'outside the supported range'),
    (['campbell', 'precession'], '--points', ('0', '-1'), '--points must be 2..20000'),
    (['sweep', 'precession', '--grid', 'K_D=0.05:0.1:2', '--out', 'sw', '--yes'], '--t-end',
     _NUMBERS[:5], '--t-end must be positive and finite'),
    (['sweep', 'precession', '--grid', 'K_D=0.05:0.1:2', '--out', 'sw', '--yes'], '--t-end',
     ('1e300',), 'samples per trajectory is more than 5e+07'),
    (['sweep', 'precession', '--grid', 'K_D=0.05:0.1:2', '--out', 'sw', '--yes'], '--rate',
     _NUMBERS[:5], '--rate must be positive and finite'),
    (['sweep', 'precession', '--grid', 'K_D=0.05:0.1:2', '--out', 'sw', '--yes'], '--rate',
     ('1e300',), 'samples per trajectory is more than 5e+07'),
    (['sweep', 'precession', '--grid', 'K_D=0.05:0.1:2', '--out', 'sw', '--yes'], '--tol',
     _NUMBERS[:5], '--tol must be positive and finite'),
    (['sweep', 'precession', '--grid', 'K_D=0.05:0.1:2', '--out', 'sw', '--yes'], '--step',
     _NUMBERS[:5], '--step must be positive and finite'),
    (['sweep', 'precession', '--grid', 'K_D=0.05:0.1:2', '--out', 'sw', '--yes'], '--workers',
     ('0', '-1'), '--workers must be positive'),
    (['sweep', 'precession', '--grid', 'K_D=0.05:0.1:2', '--out', 'sw', '--yes'], '--block',
     ('0', '-1'), '--block must be a positive number of points'),
    (['sweep-bench', '--out', 'sb'], '--t-end', _NUMBERS[:5], '--t-end must be positive and '
     'finite'),
    (['sweep-bench', '--out', 'sb'], '--t-end', ('1e300',), 'samples per trajectory is more'),
    (['sweep-bench', '--out', 'sb'], '--workers', ('0', '-1'), '--workers must be positive'),
]
_INTS = {'--points', '--repeats', '--domain-id', '--load', '--workers', '--block',
         '--realtime-priority'}
_CASES = [(cmd, opt, v, match) for cmd, opt, values, match in _REFUSED for v in values]
# every option once more: not a number at all (inf, nan, 1e300 of an integer option too)
_CASES += [(cmd, opt, v, f'argument {opt}: invalid {"int" if opt in _INTS else "float"} '
            f'value: {v!r}')
           for cmd, opt in dict.fromkeys((tuple(c), o) for c, o, _, _ in _REFUSED
                                         if o != '--rates')      # a list in one string
           for v in ([''] + (['inf', 'nan', '1e300'] if opt in _INTS else []))]


@pytest.mark.parametrize('cmd, opt, value, match', _CASES,
                         ids=[f'{c[0]}{o}={v}' for c, o, v, _ in _CASES])
def test_every_numeric_argument_refused_with_one_clear_error_line(cmd, opt, value, match,
                                                                  tmp_path, monkeypatch,
                                                                  capsys):
    """Refuse every bad number with one ERROR line that is right about the value.

    Review finding: "must be positive (K_D >= 0)" for 0, "must be positive, got inf",
    "must be finite ... or < 0" for -inf, no ERROR line (steady), tracebacks (sweep).
    """
    from pathlib import Path
    argv = [str(Path(__file__).resolve().parents[1] / a) if a.startswith('bags/') else a
            for a in cmd]
    monkeypatch.chdir(tmp_path)
    assert main([*argv, f'{opt}={value}']) == 1
    cap = capsys.readouterr()
    err = ''.join(x for x in cap.err.splitlines(True) if not x.startswith('gyro_rotor: '))
    assert err.startswith('ERROR: ') and err.count('\n') == 1, err
    assert match in err and 'Traceback' not in err, err


def test_campbell_keeps_a_crossing_whose_bracket_loses_the_steady_motion(monkeypatch, capsys):
    """No steady motion inside a bracket (a system file's Newton): the grid's speed, no crash."""
    import gyro_rotor.linear.campbell as cb
    from gyro_rotor.errors import NoSteadyMotionError

    def fails(*args):
        raise NoSteadyMotionError('none in the bracket')
    monkeypatch.setattr(cb, '_crossing', fails)
    assert main(['campbell', 'precession', '--points', '200']) == 0
    out = capsys.readouterr().out
    assert 'nutation, 9.71 Hz) crosses 1 x rotor speed at Omega0 = 37.694' in out, out


def test_a_run_out_of_steps_is_stopped_not_diverged(monkeypatch, capsys):
    """Adversarial finding: Omega0 = 1e12 ran 93 s, then said 'DIVERGED: ... budget'."""
    import gyro_rotor.numerics.simulate as sim
    make = sim.make_integrator
    monkeypatch.setattr(sim, 'make_integrator',
                        lambda *a, **k: make(*a, **k, max_steps=50))   # the budget, small
    assert main(['simulate', 'precession', '--t-end', '1']) == 2
    out = capsys.readouterr().out
    assert 'STOPPED: ' in out and 'budget' in out and 'DIVERGED' not in out


#: what ``gyro-rotor --help``, a command's ``--help`` and a bad argument must not wait for
_HEAVY = ('sympy', 'numba', 'scipy', 'dask', 'distributed', 'mcap', 'matplotlib', 'rclpy')


@pytest.mark.parametrize('argv', [['--help'], ['eig', '--help'], ['sweep', '--help'],
                                  ['eig', '--bogus'], ['nosuch']])
def test_help_and_usage_errors_import_no_heavy_package(argv):
    """The parser of every command is built without sympy, numba, scipy, dask, ... (issue 21).

    Each command imports what its work needs when it runs: ``--help`` and a usage error
    (one ``ERROR:`` line, exit 1) start in a fraction of a second.
    """
    code = ('import sys\nfrom gyro_rotor.cli.main import main\ntry:\n'
            f'    sys.exit(main({argv!r}))\nfinally:\n'     # --help exits inside argparse
            f'    print(sorted(m for m in {_HEAVY!r} if m in sys.modules), file=sys.stderr)\n')
    r = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                       timeout=120)
    *lines, loaded = r.stderr.splitlines()
    assert loaded == '[]', f'{argv}: {loaded}'
    if argv[-1] == '--help':
        assert r.returncode == 0 and r.stdout.startswith('usage: gyro-rotor')
    else:
        assert r.returncode == 1 and len(lines) == 1 and lines[0].startswith('ERROR: ')
