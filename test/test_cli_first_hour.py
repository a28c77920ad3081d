"""A user's first hour (issue 28): plots that explain every system, a CLI with no surprises.

Campbell diagrams with tracked modes on every shipped scene, root-locus plots zoomed to
where the roots meet, one resolution rule for eigenvalues, "did you mean" for every scene
name, benchmark and demo outputs where they belong, a monitor that prints what changed.
The plots are checked through the figures the commands build (data limits, legend
entries), not through PNG files.
"""

import json
import math

from gyro_rotor.cli.main import main
from gyro_rotor.core.scene import list_scenes, load_scene
import numpy as np
import pytest

plt = pytest.importorskip('matplotlib.pyplot')

ALL_SCENES = tuple(list_scenes())


def _load(name, **sets):
    return load_scene(name, overrides=sets)


def _W0(scene):
    return scene.system.params.Omega0 if scene.builtin else scene.system.drives[0].Omega0


def _legend(ax):
    leg = ax.get_legend()
    assert leg is not None, 'no legend'
    return [t.get_text() for t in leg.get_texts()]


# -- Campbell diagrams: tracked modes, every scene ------------------------------------------
def test_campbell_twin_gimbal_where_the_root_count_changes(tmp_path, capsys):
    """The crash of the issue: K_D = 0.28 makes a pair real over part of the range."""
    out = tmp_path / 'c.json'
    assert main(['campbell', 'twin_gimbal', '--set', 'K_D=0.28', '--points', '200',
                 '--json', str(out)]) == 0
    text = capsys.readouterr().out
    assert 'the number of real roots changes over the range' in text
    doc = json.loads(out.read_text())
    F = np.array(doc['frequencies_hz'])
    assert F.shape == np.array(doc['decay_rates']).shape == (200, len(doc['modes']))
    roots = np.array(doc['roots'])
    upper = np.sum(roots[:, :, 1] >= 0, axis=1)
    assert upper.min() < upper.max()        # the count of roots with Im >= 0 changes
    # the mode that is real at the scene's speed oscillates at the top of the range
    k = [i for i, t in enumerate(doc['modes']) if 'real at the scene speed' in t]
    assert len(k) == 1 and F[-1, k[0]] > 0 and F[100, k[0]] == 0


@pytest.mark.parametrize('name', ALL_SCENES)
def test_campbell_exits_0_on_every_shipped_scene(name, tmp_path):
    out = tmp_path / 'c.json'
    assert main(['campbell', name, '--points', '40', '--json', str(out)]) == 0
    doc = json.loads(out.read_text())
    F = np.array(doc['frequencies_hz'])
    assert F.ndim == 2 and F.shape[1] == len(doc['modes']) == len(set(doc['modes']))
    assert np.all(np.isfinite(F)) and np.all(np.isfinite(np.array(doc['decay_rates'])))


@pytest.mark.parametrize('name', ALL_SCENES)
def test_campbell_tracks_roots_continuously(name):
    """Each column follows one root: no jump from speed to speed (sorting would jump)."""
    from gyro_rotor.linear.campbell import campbell
    scene = _load(name)
    W0 = _W0(scene)
    cb = campbell(scene, np.linspace(0.05 * W0, 2 * W0, 120))
    R = cb.roots
    scale = max(float(np.sort(np.abs(R).max(axis=0))[-2]), 1.0)
    step = np.abs(np.diff(R, axis=0))
    assert step.max() < 0.1 * scale, (name, step.max(), scale)


def test_campbell_modes_cross_instead_of_swapping():
    """Nutation and rotor-field coupling frequencies cross (precession).

    The j-th lowest frequency would swap them; the tracked modes keep their names on both
    sides.
    """
    from gyro_rotor.linear.campbell import campbell
    scene = load_scene('precession')
    cb = campbell(scene, np.linspace(0.05, 2.0, 150) * scene.system.params.Omega0)
    nut = [k for k, t in enumerate(cb.labels) if t.startswith('nutation')]
    rfc = [k for k, t in enumerate(cb.labels) if t.startswith('rotor-field')]
    assert len(nut) == len(rfc) == 1
    d = cb.frequencies[:, nut[0]] - cb.frequencies[:, rfc[0]]
    assert d[0] < 0 < d[-1]


def test_campbell_pairs_split_and_join_by_continuity():
    """Two modes throughout: a pair that lands on the real axis, an undamped pair.

    Synthetic: lambda^2 + 2 zeta lambda + 1 with zeta from 0.5 to 1.5 (the pair lands on
    the real axis at zeta = 1) and an undamped pair at 3j.
    """
    from gyro_rotor.linear.campbell import _assemble
    zeta = np.linspace(0.5, 1.5, 41)
    rows = []
    for z in zeta:
        s = np.sqrt(complex(z * z - 1))
        rows.append([-z + s, -z - s, 3j, -3j])
    R = np.array(rows)
    # the tracks as continuity gives them: columns 0/1 swap their roles at the meeting
    res = np.full(R.shape, 1e-12)
    cb = _assemble(zeta, R, res, lambda i, cols: [['d', 'd', 'u', 'u'][j] for j in cols],
                   orders=(1,), nominal=1.0)
    assert len(cb.labels) == 2 and cb.frequencies.shape == (41, 2)
    k_u = [k for k, t in enumerate(cb.labels) if t.startswith('u')][0]
    k_d = 1 - k_u
    assert np.all(cb.decay[:, k_u] == 0)              # undamped: exactly 0, not 1e-12
    assert np.all(cb.undamped[:, k_u])
    assert np.allclose(cb.frequencies[:, k_u], 3 / (2 * math.pi))
    over = zeta >= 1
    assert np.all(cb.frequencies[over, k_d] == 0) and np.all(cb.frequencies[~over, k_d] > 0)
    assert np.allclose(cb.decay[over, k_d], zeta[over] - np.sqrt(zeta[over] ** 2 - 1))


def _campbell_fig(name, **sets):
    from gyro_rotor.cli.commands.campbell import campbell_figure
    from gyro_rotor.linear.campbell import campbell
    scene = _load(name, **sets)
    W0 = _W0(scene)
    cb = campbell(scene, np.linspace(0.05 * W0, 2 * W0, 120))
    return cb, campbell_figure(cb, name)


def test_campbell_plot_zoomed_to_the_modes_with_a_legend():
    cb, fig = _campbell_fig('twin_gimbal')
    try:
        a1, a2 = fig.axes[:2]
        lo, hi = a1.get_ylim()
        fmax = float(cb.frequencies.max())
        assert fmax < 12 and lo == 0 and fmax <= hi <= 1.2 * fmax   # not a 0-200 Hz axis
        texts = _legend(a1)
        assert '1x rotor speed' in texts and '2x rotor speed' in texts
        assert any(t.startswith('critical speed') for t in texts)
        for label in cb.labels:       # every oscillating mode named
            assert any(t.startswith(label) for t in texts), label
        # every critical speed marked inside the axes
        x0, x1 = a1.get_xlim()
        for c in cb.critical:
            rpm = c['Omega0'] * 30 / math.pi
            assert x0 <= rpm <= x1 and lo <= c['frequency_hz'] <= hi
        assert 'rpm' in a2.get_xlabel() and '[Hz]' in a1.get_ylabel()
        assert '[1/s]' in a2.get_ylabel()
    finally:
        plt.close(fig)


def test_campbell_plot_draws_undamped_modes_at_zero():
    """Draw the modes the drive does not reach (elastic_frame) as undamped.

    Decay 0, dashed, named so in the legend (never a decay of 1e-12 on a log axis).
    """
    cb, fig = _campbell_fig('elastic_frame')
    try:
        a1, a2 = fig.axes[:2]
        und = [t for t in _legend(a1) if t.endswith('(undamped)')]
        assert len(und) == int(np.sum(np.all(cb.undamped, axis=0))) == 3
        assert a2.get_yscale() == 'symlog' and a2.get_ylim()[0] < 0 < a2.get_ylim()[1]
        zero_lines = [ln for ln in a2.get_lines()
                      if len(ln.get_ydata()) > 2 and np.all(ln.get_ydata() == 0)
                      and ln.get_linestyle() == '--']
        assert len(zero_lines) >= 3
    finally:
        plt.close(fig)


def test_campbell_command_writes_the_plot(tmp_path, capsys):
    out = tmp_path / 'c.png'
    assert main(['campbell', 'twin_gimbal', '--set', 'K_D=0.28', '--points', '60',
                 '--out', str(out)]) == 0
    assert out.stat().st_size > 10000


# -- root-locus plots: zoomed to where the roots meet --------------------------------------
def _locus_fig(name):
    from gyro_rotor.linear.locus import check_claims, K_ref
    from gyro_rotor.linear.locus_plot import locus_figure
    from gyro_rotor.linear.system import linearize_scene
    lin = linearize_scene(load_scene(name))
    claims = check_claims(lin)
    K = K_ref(lin)
    return claims, locus_figure(lin, claims, K_lo=1e-4 * K, K_hi=1e4 * K, title=name)


@pytest.mark.parametrize('name', list_scenes(builtin=False))
def test_general_locus_plot_shows_every_meeting(name):
    claims, fig = _locus_fig(name)
    try:
        ax = fig.axes[0]
        x0, x1 = ax.get_xlim()
        y0, y1 = ax.get_ylim()
        assert claims.meetings
        lam = [mt.lam for mt in claims.meetings]
        for x in lam:
            assert x0 < x < x1 and y0 < 0 < y1
        # zoomed: the meetings take a good part of the axis, not one pixel column at Re = 0
        assert -x0 < 5 * max(abs(x) for x in lam) and x1 < 0.2 * -x0
        texts = _legend(ax)
        assert any(t.startswith('K_D*') for t in texts) and 'K_D = 0' in texts
        notes = [t.get_text() for t in ax.texts]
        for mt in claims.meetings:
            assert any(f'K_D* = {mt.K_D:.4g}' in t and str(mt.kind) in t for t in notes)
        # readable ticks: a handful of short labels on each axis
        fig.canvas.draw()
        for axis in (ax.xaxis, ax.yaxis):
            labels = [t.get_text() for t in axis.get_ticklabels() if t.get_text()]
            assert 2 <= len(labels) <= 8 and max(len(t) for t in labels) <= 7, labels
    finally:
        plt.close(fig)


def test_general_locus_plot_magnifies_the_slow_branches():
    """Give each slow branch its own magnified panel (twin_gimbal).

    The gimbal branches leave the axis by 1e-4 .. 0.1 1/s while the drive branches reach
    -74 1/s.
    """
    claims, fig = _locus_fig('twin_gimbal')
    try:
        side = fig.axes[1:]
        assert len(side) == 3
        for a in side:
            assert 'Re x 1e' in a.get_title()
            x0, x1 = a.get_xlim()
            data = np.concatenate([ln.get_xdata() for ln in a.get_lines()
                                   if len(ln.get_xdata()) > 2])
            assert data.min() < 0.5 * x0      # the branch fills its panel
    finally:
        plt.close(fig)


def test_no_branch_of_the_locus_takes_a_markers_colour():
    """twin_gimbal's five modes: tab10 drew the fourth in the K_D* red, the fifth in purple."""
    from matplotlib.colors import same_color
    from gyro_rotor.linear.locus_plot import MEETING_COLOR, SCENE_K_D_COLOR
    claims, fig = _locus_fig('twin_gimbal')
    try:
        branches = [ln for a in fig.axes for ln in a.get_lines() if len(ln.get_xdata()) > 2]
        assert len({ln.get_color() for ln in branches}) == 5
        for ln in branches:
            for marker in (MEETING_COLOR, SCENE_K_D_COLOR):
                assert not same_color(ln.get_color(), marker), (ln.get_label(), marker)
        marks = [ln for ln in fig.axes[0].get_lines() if ln.get_marker() in ('D', '.')]
        assert marks and all(same_color(ln.get_color(), MEETING_COLOR if ln.get_marker() == 'D'
                                        else SCENE_K_D_COLOR) for ln in marks)
    finally:
        plt.close(fig)


def test_general_locus_plot_of_a_part_of_the_range_says_where_it_starts():
    from gyro_rotor.linear.system import check_claims, linearize_scene
    from gyro_rotor.linear.locus_plot import locus_figure
    lin = linearize_scene(load_scene('twin_gimbal'))
    fig = locus_figure(lin, check_claims(lin), K_lo=0.1, K_hi=0.5)
    try:
        texts = _legend(fig.axes[0])
        start = [t for t in texts if t.startswith('K_D = ')]
        assert len(start) == 1 and 0.1 <= float(start[0][6:]) < 0.11      # not 'K_D = 0'
        assert all(t.endswith(f'at {start[0]})') for t in texts if 'rad/s at' in t)
    finally:
        plt.close(fig)


@pytest.mark.parametrize('name', ['precession', 'stiff_drive', 'nutation'])
def test_centrifuge_locus_plot_marks_every_meeting(name):
    cr, fig = _locus_fig(name)
    try:
        ax = fig.axes[0]
        x0, x1 = ax.get_xlim()
        assert cr.meetings
        for mt in cr.meetings:
            assert x0 < mt.lam < x1
        texts = _legend(ax)
        assert any(t.startswith('K_D*') for t in texts) and 'K_D = 0' in texts
    finally:
        plt.close(fig)


@pytest.mark.parametrize('name', list_scenes(builtin=False))
def test_locus_command_writes_the_plot(name, tmp_path, capsys):
    out = tmp_path / 'l.png'
    assert main(['locus', name, '--points', '40', '--out', str(out)]) == 0
    assert out.stat().st_size > 10000
    assert f'wrote {out}' in capsys.readouterr().out


# -- eig: one resolution rule for every system ---------------------------------------------
def _eig_rows(out):
    rows = []
    for line in out.splitlines():
        parts = line.split()
        if len(parts) >= 6 and parts[-1] in ('yes', 'no'):
            rows.append(line)
    return rows


@pytest.mark.parametrize('name,sets', [('twin_gimbal', ['K_D=0']), ('elastic_frame', []),
                                       ('centrifuge_euler', ['K_D=0']), ('twin_gimbal', [])])
def test_general_eig_shows_round_off_as_zero(name, sets, capsys, tmp_path):
    args = ['eig', name] + [x for s in sets for x in ('--set', s)]
    out_json = tmp_path / 'e.json'
    assert main(args + ['--json', str(out_json)]) == 0
    out = capsys.readouterr().out
    rows = _eig_rows(out)
    assert rows
    for line in rows:
        re_text = line[43:56].strip()      # the Re column (2 + 40 + 1 characters in)
        if re_text != '0':
            assert abs(float(re_text)) > 1e-9, line           # never a round-off real part
        if re_text == '0' and 'zero root' not in line:
            assert 'undamped' in line, line                   # no decay time from round-off
    sa = out.split('spectral abscissa ')[1].split()[0]
    assert sa == '0' or abs(float(sa)) > 1e-9
    doc = json.loads(out_json.read_text())
    n_und = sum(1 for m in doc['modes'] if m['undamped'] and not m['structural_zero']
                and m['im'] > 0)
    assert n_und == sum(1 for line in rows if 'undamped' in line)
    if sets == ['K_D=0']:
        assert sa == '0' and all(('undamped' in r) or ('zero root' in r) for r in rows)
        assert 'e+12 s' not in out and 'e+13 s' not in out


def test_centrifuge_eig_same_rule_and_consistent_with_its_verdict(capsys):
    """Print Re = 1.8e-102 as 0, undamped (pole_slip), and Re = -4.3e-8 as a result.

    stiff_drive: the nutation's -4.3e-8 1/s is resolved (the pencil keeps it), printed with
    its time constant, as the verdict says.
    """
    assert main(['eig', 'pole_slip']) == 0
    out = capsys.readouterr().out
    assert 'e-102' not in out and 'spectral abscissa 0 1/s' in out
    assert [ln for ln in out.splitlines() if ln.strip().startswith('nutation')][0].count(
        'undamped') == 1
    assert main(['eig', 'stiff_drive']) == 0
    out = capsys.readouterr().out
    nut = [ln for ln in out.splitlines() if ln.strip().startswith('nutation')][0]
    assert '-4.28' in nut and 'undamped' not in nut
    assert 'spectral abscissa -4.28' in out


# -- scene names: did you mean, and the full list -------------------------------------------
TYPO_COMMANDS = [['eig', 'twin_gimbel'], ['simulate', 'twin_gimbel'], ['steady', 'twin_gimbel'],
                 ['locus', 'twin_gimbel'], ['tune', 'twin_gimbel'],
                 ['campbell', 'twin_gimbel'], ['demo', 'twin_gimbel'],
                 ['sweep', 'twin_gimbel', '--grid', 'K_D=0.1:0.2:2', '--out', '{tmp}/s'],
                 ['soak', '--scene', 'twin_gimbel'], ['rt-bench', '--scenes', 'twin_gimbel'],
                 ['bench', '--quick', '--scenes', 'twin_gimbel', '--out', '{tmp}/b']]


@pytest.mark.parametrize('argv', TYPO_COMMANDS, ids=lambda a: a[0])
def test_every_scene_name_error_says_did_you_mean(argv, tmp_path, capsys):
    argv = [a.replace('{tmp}', str(tmp_path)) for a in argv]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert "did you mean 'twin_gimbal'?" in err, err
    for name in ALL_SCENES:          # the full list, the general systems' scenes included
        assert name in err.split('(scenes:')[1], (name, err)
    assert err.count('\n') == 1      # one line, no traceback


def test_did_you_mean_ignores_case_and_underscores(capsys):
    assert main(['eig', 'TwinGimbal']) == 1
    assert "did you mean 'twin_gimbal'?" in capsys.readouterr().err
    assert main(['eig', 'precesion']) == 1
    assert "did you mean 'precession'?" in capsys.readouterr().err


# -- run outputs: never the tracked tree by default, one folder per run ---------------------
def test_unique_dirs_for_runs_started_in_the_same_second(tmp_path):
    from gyro_rotor.cli.util import make_unique_dir
    base = tmp_path / 'runs' / 'x_20260101-000000'
    made = [make_unique_dir(base) for _ in range(3)]
    assert [p.name for p in made] == ['x_20260101-000000', 'x_20260101-000000-2',
                                      'x_20260101-000000-3']
    assert all(p.is_dir() for p in made)


def test_unique_dirs_under_concurrency(tmp_path):
    """Eight threads asking for the same name at once get eight folders."""
    import concurrent.futures
    from gyro_rotor.cli.util import make_unique_dir
    base = tmp_path / 'same'
    with concurrent.futures.ThreadPoolExecutor(8) as ex:
        made = list(ex.map(lambda _: make_unique_dir(base), range(8)))
    assert len(set(made)) == 8


def test_two_demos_in_the_same_second_get_two_folders(tmp_path, monkeypatch):
    import argparse
    from gyro_rotor.cli.commands import demo
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(demo.time, 'strftime', lambda fmt, *a: '20260101-120000')
    scene = load_scene('precession')
    args = argparse.Namespace(out=None)
    a, b = demo._out_dir(args, scene), demo._out_dir(args, scene)
    assert a != b and a.is_dir() and b.is_dir()
    assert a.parent.name == b.parent.name == 'demo_runs'
    (a / 'bag').mkdir()
    with pytest.raises(Exception, match='exists and is not empty'):
        demo._out_dir(argparse.Namespace(out=str(a)), scene)


def test_bench_default_output_is_untracked_and_new(tmp_path, monkeypatch):
    from gyro_rotor.cli.commands import bench as bench_cmd
    from gyro_rotor.cli.main import build_parser
    monkeypatch.chdir(tmp_path)
    args = build_parser().parse_args(['bench', '--quick'])
    assert bench_cmd.resolve_settings(args) is None
    assert args.out.startswith('bench_out/bench-') and args.out_is_default
    explicit = build_parser().parse_args(['bench', '--quick', '--out', 'bench'])
    assert bench_cmd.resolve_settings(explicit) is None and explicit.out == 'bench'
    assert not getattr(explicit, 'out_is_default', False)


def test_bench_table_general_writes_bench_general_md_only_when_asked(tmp_path, monkeypatch,
                                                                     capsys):
    """One command for every table: ``bench --table general`` writes to a new directory."""
    from gyro_rotor.numerics import bench
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(bench, 'rhs_cost', lambda: {'hand_ns': 1.0, 'generated_ns': 2.0,
                                                    'ratio': 2.0})
    times = {'imports': 0.1, 'load_system': 0.1, 'compile_system': 0.1, 'first_run': 0.1}
    monkeypatch.setattr(bench, 'compile_times', lambda: {'first': times, 'cached': times})
    monkeypatch.setattr(bench, 'system_work_precision', lambda *a, **kw: [])
    monkeypatch.setattr(bench, 'best_at', lambda rows, level: {})
    assert main(['bench', '--table', 'general']) == 0
    assert not (tmp_path / 'bench').exists()
    written = list((tmp_path / 'bench_out').glob('bench-*/general.md'))
    assert len(written) == 1 and 'wrote bench_out/bench-' in capsys.readouterr().out
    assert 'Command: `gyro-rotor bench --table general --scenes centrifuge_euler,twin_gimbal,' \
        'elastic_frame --out bench_out/bench-' in written[0].read_text()
    assert main(['bench', '--table', 'general']) == 0          # a second run: a second file
    assert len(list((tmp_path / 'bench_out').glob('bench-*/general.md'))) == 2
    (tmp_path / 'bench').mkdir()
    assert main(['bench', '--table', 'general', '--out', 'bench']) == 0
    assert (tmp_path / 'bench' / 'general.md').is_file()


@pytest.mark.parametrize('argv, message', [
    (['--table', 'general', '--scenes', 'precession'], 'scene precession is the built-in'),
    (['--table', 'stiff', '--scenes', 'twin_gimbal,elastic_frame'], 'takes one scene, got 2'),
    (['--table', 'stiff', '--level', '0'], '--level must be finite and > 0'),
    (['--table', 'general', '--t-end', 'nan'], '--t-end must be finite and > 0'),
    (['--scenes', 'no_such_scene'], '--scenes: '),
])
def test_bench_refuses_bad_settings_with_one_error_line(argv, message, tmp_path, monkeypatch,
                                                        capsys):
    monkeypatch.chdir(tmp_path)
    assert main(['bench', *argv]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('ERROR: ') and message in err[0], err
    assert not (tmp_path / 'bench_out').exists()


def test_gitignore_covers_the_run_outputs():
    import shutil
    import subprocess
    from pathlib import Path
    root = Path(__file__).resolve().parent.parent
    if not (root / '.git').exists() or shutil.which('git') is None:
        pytest.skip('not a git checkout')
    for path in ('bench_out/bench-20260101-000000/work_precision.md',
                 'bench-20260101-000000/work_precision.md',
                 'demo_runs/precession_20260101-000000/report.txt',
                 'sweep-bench-20260101-000000/sweep_bench.md'):
        r = subprocess.run(['git', 'check-ignore', '-q', '--no-index', path], cwd=root)
        assert r.returncode == 0, path
    r = subprocess.run(['git', 'check-ignore', '-q', '--no-index', 'bench/general.md'],
                       cwd=root)
    assert r.returncode == 1          # the committed results stay tracked


def test_bench_quick_plot_has_a_legend_and_every_point():
    """The work-precision figure of a quick run: a legend per panel, every point inside."""
    from gyro_rotor.cli.commands.bench import work_precision_figure
    from gyro_rotor.numerics import bench
    rows = bench.run_sweep('precession', quick=True, repeats=1, scipy=True, peers=False)
    fig = work_precision_figure(rows)
    try:
        ax = fig.axes[0]
        assert ax.get_title() == 'precession'
        texts = _legend(ax)
        ok = [r for r in rows if r.status == 0 and math.isfinite(r.err) and r.err > 0]
        assert set(texts) == {r.method for r in ok}
        x0, x1 = ax.get_xlim()
        y0, y1 = ax.get_ylim()
        for r in ok:
            assert x0 <= r.wall_per_sim <= x1 and y0 <= r.err <= y1
        assert '[s/s]' in ax.get_xlabel() and '[rad]' in ax.get_ylabel()
    finally:
        plt.close(fig)


def test_bench_sweeps_a_system_file_scene_through_the_same_path():
    """One benchmark path for every scene: a system file's, its error that of q and z."""
    from gyro_rotor.numerics import bench
    rows = bench.run_sweep('twin_gimbal@t_end=1', quick=True, repeats=1, scipy=True,
                           peers=False, methods=('auto', 'dop853', 'rk4', 'split8'))
    assert {r.method for r in rows} == {'auto', 'dop853', 'rk4', 'LSODA'}   # split8: none
    dop = {r.setting: r for r in rows if r.method == 'dop853'}
    assert all(r.status == 0 and 0 < r.err < 1e-3 for r in dop.values()), dop
    assert dop['rtol=1e-08'].err < dop['rtol=1e-05'].err
    scene, _ = bench.parse_scene_spec('twin_gimbal@t_end=1')
    model = scene.make_model()
    R = bench.reference(scene, np.linspace(0.0, 1.0, 11))
    q, _, z, _ = model.slices()
    Y = R.copy()
    Y[5, q.start + 1] += 3e-7
    Y[7, z.start] -= 2e-7
    e = bench.errors(model, Y, R)
    assert e['axis_err'] == pytest.approx(3e-7, rel=1e-6)
    assert e['z_err'] == pytest.approx(2e-7, rel=1e-6) and e['err'] == e['axis_err']
    assert math.isnan(bench.errors(model, None, R)['err'])


# -- the monitor: only what changed, no NaN, the topics the system publishes ----------------
def _feed(mon, topic, msg):
    from rclpy.serialization import serialize_message
    from gyro_rotor.tools.monitor import TopicStats
    mon.stats.setdefault(topic, TopicStats(topic, type(msg).__name__))
    mon._callback(topic, type(msg))(serialize_message(msg))


def _system_file_scene_doc():
    import yaml
    return yaml.safe_dump({'scene': 'twin_gimbal', 'system': 'twin_gimbal', 't_end': 20.0,
                           'joint_names': ['alpha', 'beta1', 'beta2', 'z_R1', 'z_R2'],
                           'node': {'publish_rate': 250.0, 'real_time_factor': 0.0}},
                          sort_keys=False)


@pytest.mark.ros
def test_monitor_prints_no_nan_before_the_first_result():
    from gyro_rotor.cli.commands.monitor import Monitor
    from std_msgs.msg import Float64MultiArray, MultiArrayDimension
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label='t_sim,E_star,decay', size=3, stride=3)]
    msg.data = [math.nan, math.nan, math.nan]
    mon = Monitor(node=None)
    _feed(mon, '/analysis', msg)
    text = mon.render()
    assert 'nan' not in text.lower() and '/analysis: no result yet' in text
    msg.data = [1.5, 0.001, math.nan]
    _feed(mon, '/analysis', msg)
    line = [ln for ln in mon.render().splitlines() if ln.startswith('/analysis:')][0]
    assert line == '/analysis: t_sim 1.5, E_star 0.001'


@pytest.mark.ros
def test_monitor_log_prints_only_what_changed_and_the_scene_once():
    from gyro_rotor.cli.commands.monitor import Monitor
    from gyro_rotor.tools.monitor import TopicStats
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String
    mon = Monitor(node=None)
    for t in ('/axis', '/stator_pose', '/axis_marker'):       # in the graph, never published
        mon.stats[t] = TopicStats(t, 'x')
    doc = _system_file_scene_doc()
    _feed(mon, '/rotor_sim/scene', String(data=doc))
    js = JointState(name=['alpha', 'beta1', 'beta2', 'z_R1', 'z_R2'],
                    position=[0.1, 0.2, 0.3, 0.4, 0.5])
    _feed(mon, '/joint_states', js)
    first = mon.render(changed_only=True, full_docs=True)
    assert first.count('scene: twin_gimbal') == 1 and '/rotor_sim/scene (' in first
    assert not [ln for ln in first.splitlines() if ln.startswith(('/axis', '/stator_pose'))]
    assert 'no message yet' not in first
    assert 'twin_gimbal publishes no 3-D pose: /axis, /axis_marker, /stator_pose' in first
    assert '/joint_states: alpha 0.1' in first
    second = mon.render(changed_only=True, full_docs=True)
    assert second.splitlines()[1:] == ['(nothing changed)']
    js.position = [0.1, 0.2, 0.3, 0.4, 0.6]
    _feed(mon, '/joint_states', js)
    third = mon.render(changed_only=True, full_docs=True)
    assert 'z_R2 0.6' in third and 'scene: twin_gimbal' not in third
    assert '/joint_states ' in third and 'publishes no 3-D pose' not in third
    # the terminal view: everything, the document in one line
    screen = mon.render()
    assert '/rotor_sim/scene: a ' in screen and 'scene: twin_gimbal\n' not in screen
    assert len(screen.splitlines()) < 12


@pytest.mark.ros
def test_monitor_knows_the_system_from_the_joints_before_the_scene():
    from gyro_rotor.cli.commands.monitor import Monitor
    from gyro_rotor.tools.monitor import TopicStats
    from sensor_msgs.msg import JointState
    mon = Monitor(node=None)
    mon.stats['/axis'] = TopicStats('/axis', 'x')
    _feed(mon, '/joint_states', JointState(name=['theta', 'psi', 'phi_R', 'phi_M'],
                                           position=[0.1, 0.0, 0.0, 0.0]))
    assert not mon.hidden('/axis') and 'no message yet on /axis' in mon.render()
    mon2 = Monitor(node=None)
    mon2.stats['/axis'] = TopicStats('/axis', 'x')
    _feed(mon2, '/joint_states', JointState(name=['a', 'b', 'z_R'], position=[0.0] * 3))
    assert mon2.hidden('/axis') and 'no message yet' not in mon2.render()
    assert 'a general system publishes no 3-D pose: /axis not listed' in mon2.render()


def test_monitor_names_missed_messages_as_the_monitor_s_own():
    from gyro_rotor.tools.monitor import Changes, system_topics, TopicStats
    s = TopicStats('/energy')
    s.add(0.0, seq=0)
    s.add(0.1, seq=74)
    assert s.gaps == 73
    assert system_topics('scene: precession\nt_end: 10\n')['absent'] == ()
    absent = system_topics(_system_file_scene_doc())['absent']
    assert absent == ('axis', 'stator_pose', 'axis_marker')
    assert system_topics('just a verdict') is None
    c = Changes()
    assert c.changed('k', 'a') and not c.changed('k', 'a') and c.changed('k', 'b')


def test_live_table_mode_names_are_whole_words():
    """Issue 28: the live table cut 'rotor-field coupling' to 'rotor-fie'."""
    from gyro_rotor.cli.commands.demo import _short
    assert _short('rotor-field coupling') == 'rotor-field'
    assert _short('housing twist') == 'housing'
    assert _short('mode (beta1) 6.11 Hz') == 'beta1 6.11'
    assert _short('unreached mode (a)') == 'a'


def test_state_plot_names_the_first_coordinate():
    """Issue 28: the state plot's axis said 'first coordinate q_1' with no name."""
    from gyro_rotor.analysis.report import _first_coordinate
    assert _first_coordinate('twin_gimbal').startswith('alpha = q_1')
    assert _first_coordinate('elastic_frame').startswith('y = q_1')
