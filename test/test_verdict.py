"""The verdict right on every scene, every duration and every system (issue 23).

**The verdict matrix.** Every shipped scene and system is run once for 60 s as the demo
runs it: rotor_sim's own LiveSimulation as fast as possible (real_time_factor 0), kicked
through ``~/perturb`` at t = 2 s where the demo kicks (``demo_replay``). Then

* *live*: the samples are streamed into the analyzer as rotor_analysis receives them, with
  a result every second of simulation time (as the node publishes at real_time_factor 1);
  every live verdict must be the linear theory's or 'insufficient data', never 'not
  confirmed', 'unstable' or 'diverged';
* *offline*: the run is written to a rosbag2 bag (the recorder's metadata records) and
  ``analyze_bag`` analyses its first 10, 20 and 60 s (``until``).

In both, every criterion is PASS or NOT YET with its reason (never FAIL on a correct run),
every PASS holds by the rule (its interval wholly on the passing side), and the verdict is
the linear theory's where the run can show it: at 10, 20 and 60 s on every scene but
``stiff_drive`` (K_D = 1e4: the modes the drive reaches decay at 0.004 1/s and slower, which
no 8 s window resolves: an honest 'insufficient data'). The simulation runs once per scene
(11 x 60 s); since the decay's rate is fitted free the analysis costs about 33 ms per
window judged (every second of simulation time) on one BLAS thread, as run_tests.sh runs
it (8 ms before; 300-450 ms with a threaded BLAS at load 4).

**Mutations**, each must NOT confirm: the prediction from a wrong K_D (0.5x, 2x), from
another scene, from other constants; an E* rise injected; 1 % of the messages dropped; the
combination-tone rule turned off (elastic_frame's 22.15 Hz = 8.734 + 13.419 Hz counts as an
unexplained mode).

**The decay criterion's own property**: a run simulated with the drive damping at f x the
scene's (f in 0.3 .. 0.8: its slowest shown terms decay at about f x the predicted rate,
clearly below the bound 0.9 x) and analysed against the scene never passes decay, on every
scene whose decay is resolvable; at f = 1 the same runs pass (``test_decay_never_passes_a_
slower_run``).
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
import random
import re

from demo_replay import run_like_demo, stream
from gyro_rotor.analysis.analyzer import RotorAnalyzer
from gyro_rotor.analysis.modes import mode_tolerances
from gyro_rotor.analysis.offline import analyze_bag
from gyro_rotor.analysis.samples import SamplePairer
from gyro_rotor.analysis.sweep.metrics import decay_interval, fit_decay
from gyro_rotor.analysis.verdict import (conjoin, Criterion, CriterionName, decide,
                                         fmt_against, fmt_interval, Measured, over_run, Status)
import gyro_rotor.cli.main as cli
from gyro_rotor.core.scene import list_scenes, load_scene
from hypothesis import example, given, settings, strategies as st
import numpy as np
import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]
SCENES = tuple(list_scenes())
DURATIONS = (10.0, 20.0, 60.0)
#: scenes whose decay the 8 s windows resolve late or never, and the run's duration from
#: which they do (inf: never): before it 'insufficient data' is their honest verdict.
#: stiff_drive: the modes the drive reaches decay at 0.004 1/s and slower. twin_gimbal: the
#: slowest term of E* that shows is a cross term of the 6.11 Hz gimbal mode and the weakly
#: damped 2.52 Hz one (0.0312 1/s), nearly collinear with E*_inf and the trend over 8 s:
#: at 10 s its own part is below the noise floor, at 20 s its interval 0.0257 .. 0.0355
#: straddles the bound 0.0281 ('needs about 30.7 s'), at 60 s 0.0307 (0.0290 .. 0.0324)
#: passes. (Before E*'s fit went to round-off, test_decay_third_order, its 60 s verdict
#: was 'insufficient data' too.)
LATE = {'stiff_drive': math.inf, 'twin_gimbal': 60.0}
_RUNS: dict = {}


def demo_run(name: str):
    """Return the scene run once for 60 s as the demo runs it (cached for the module)."""
    if name not in _RUNS:
        _RUNS[name] = run_like_demo(name, 60.0)
    return _RUNS[name]


def expected(scene) -> str:
    return RotorAnalyzer(scene, checkpoint_s=0).prediction.verdict


# -- the rule ----------------------------------------------------------------------------------
@pytest.mark.parametrize('lo,hi,status', [(0.42, 0.43, 'PASS'), (0.41, 0.43, 'NOT YET'),
                                          (0.39, 0.40, 'FAIL'), (0.415, 0.43, 'PASS')])
def test_the_rule_pass_fail_not_yet(lo, hi, status):
    m = Measured(0.5 * (lo + hi), lo, hi)
    assert str(decide(m, 0.415, 'above')) == status
    # the same rule the other way round (a bound from above)
    flip = {'PASS': 'FAIL', 'FAIL': 'PASS', 'NOT YET': 'NOT YET'}[status]
    if lo != 0.415:
        assert str(decide(m, 0.415, 'below')) == flip
    assert decide(Measured(math.nan, math.nan, math.nan), 1.0, 'above') is Status.NOT_YET


def test_conjoin_and_over_run():
    p, f, n = Status.PASS, Status.FAIL, Status.NOT_YET
    assert conjoin([p, p]) is p and conjoin([p, n]) is n and conjoin([n, f]) is f
    assert conjoin([]) is n
    c = {s: Criterion(CriterionName.DECAY, s, str(s)) for s in (p, f, n)}
    assert over_run([(1.0, c[n]), (2.0, c[p]), (3.0, c[n])]).status is p
    assert 'newest window NOT YET' in over_run([(2.0, c[p]), (3.0, c[n])]).detail
    assert over_run([(1.0, c[p]), (2.0, c[f]), (3.0, c[p])]).status is f
    assert 't = 2.00 s' in over_run([(1.0, c[p]), (2.0, c[f])]).detail
    assert over_run([(1.0, c[n])]).status is n


def test_intervals_are_printed_with_the_digits_their_width_needs():
    assert fmt_interval(Measured(0.41496, 0.41493, 0.41499)) == \
        '0.414960 (interval 0.414930 .. 0.414990)'
    text = fmt_interval(Measured(0.415, 0.4149, 0.4151))
    lo, hi = text.split('interval ')[1].rstrip(')').split(' .. ')
    assert lo != hi


@pytest.mark.parametrize('bag', ['pole_slip', 'upright', 'precession'])
def test_no_pass_with_an_interval_across_its_bound_on_the_sample_bags(bag):
    # bags/pole_slip and bags/upright passed decay with 0.3969 .. 0.4265 and 0.4146 ..
    # 0.4153 against 2|alpha| = 0.4149: a PASS now holds by the rule against the bound it
    # prints, (1 - 0.1) 2|alpha|
    res = analyze_bag(REPO / 'bags' / bag).result
    check_no_false_pass(res)
    decay = res.criterion(CriterionName.DECAY)
    assert 'bound (1 - 0.1) x 2|alpha| = 0.3734 1/s' in decay.detail or bag == 'precession'
    assert ' .. ' in decay.detail and '0.415 .. 0.415' not in decay.detail


def check_no_false_pass(res) -> None:
    """Every PASS of the decay and modes criteria holds by the rule, number by number."""
    decay = res.criterion(CriterionName.DECAY)
    if decay is not None and decay.status is Status.PASS and 'rate_lo' in decay.numbers:
        n = decay.numbers
        if math.isfinite(n.get('rate_bound', math.nan)) and math.isfinite(n['rate_lo']):
            assert n['rate_lo'] >= n['rate_bound'], decay.detail
    seg = res.judged
    for m in (seg.modes if seg is not None else []):
        tol_im, tol_re = mode_tolerances(m.predicted, m.window_s)
        if m.freq_status is Status.PASS:
            d = m.freq.abs_deviation(m.predicted.imag)
            assert d.hi <= tol_im, (m.name, d, tol_im)
        if m.rate_status is Status.PASS:
            target = 0.0 if (m.structural or not m.reached_by_drive) else m.predicted.real
            assert m.rate.abs_deviation(target).hi <= tol_re, (m.name, m.rate, tol_re)
        if m.freq is not None:
            assert m.freq.hi > m.freq.lo, m.name             # never a zero-width interval
            if m.tau is not None:
                assert m.tau.lo < m.tau.value < m.tau.hi, m.name


def check_honest(res, exp: str, name: str, when: str) -> None:
    """Check: the verdict is the expected one or an honest 'insufficient data'."""
    statuses = {str(c.name): str(c.status) for c in res.criteria}
    assert 'FAIL' not in statuses.values(), (name, when, res.evidence)
    assert str(res.verdict) in (exp, 'insufficient data'), (name, when, res.evidence)
    if str(res.verdict) == 'insufficient data':
        assert all(c.detail for c in res.criteria if c.status is Status.NOT_YET)
    check_no_false_pass(res)


# -- the verdict matrix: live ------------------------------------------------------------------
_LIVE: dict = {}


def live_run(name: str) -> tuple:
    """Return the live verdicts every second and the final result of the 60 s run."""
    if name not in _LIVE:
        a = RotorAnalyzer(demo_run(name).scene, window_s=8.0)
        live = stream(a, demo_run(name).samples, period=1.0)
        _LIVE[name] = live, a.result()
    return _LIVE[name]


@pytest.mark.parametrize('name', SCENES)
def test_verdict_matrix_live(name):
    run = demo_run(name)
    exp = expected(run.scene)
    live, final = live_run(name)
    bad = [(v.t, v.verdict, v.reason) for v in live
           if v.verdict not in (exp, 'insufficient data')]
    assert not bad, (name, bad[:3])
    at = {round(v.t): v for v in live}
    for T in DURATIONS:
        v = at[round(T)]
        assert 'FAIL' not in v.statuses.values(), (name, T, v.reason)
        if T >= LATE.get(name, 0.0):
            assert v.verdict == exp, (name, T, v.reason)
    check_honest(final, exp, name, 'live at 60 s')
    # once the linear theory's verdict is reached it stays
    first = next((i for i, v in enumerate(live) if v.verdict == exp), len(live))
    assert all(v.verdict == exp for v in live[first:]), name


# -- the verdict matrix: offline ---------------------------------------------------------------
def write_bag(run, path: Path) -> None:
    """Write the run as rotor_analysis records it: energy, joint_states, the scene."""
    pytest.importorskip('rclpy')
    from gyro_rotor.analysis.fit import joint_names
    from gyro_rotor.bag.bagio import BagWriter
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray, MultiArrayDimension
    fields = run.scene.make_model().energy_fields     # the layout rotor_sim publishes
    names = list(joint_names(run.scene))
    meta = {'gyro_rotor.scene': {'name': run.scene.name,
                                 'flat': yaml.safe_dump(run.scene.to_flat(),
                                                        sort_keys=False)},
            'gyro_rotor.analysis': {'options': json.dumps({'window_s': 8.0,
                                                           'min_fit_s': 2.0})}}
    with BagWriter(path, metadata=meta) as w:
        w.add_topic('/joint_states', 'sensor_msgs/msg/JointState')
        w.add_topic('/energy', 'std_msgs/msg/Float64MultiArray')
        for s in run.samples:
            ns = int(round(s.t * 1e9))
            js = JointState(name=names, position=list(s.positions),
                            velocity=list(s.velocities))
            js.header.stamp.sec, js.header.stamp.nanosec = divmod(ns, 10 ** 9)
            e = Float64MultiArray()
            e.layout.dim = [MultiArrayDimension(label=','.join(fields), size=len(fields),
                                                stride=len(fields))]
            e.data = [float(getattr(s, f) if f not in ('t_sim', 'dissipation')
                            else (s.t if f == 't_sim' else -s.dE_dt)) for f in fields]
            w.write('/joint_states', serialize_message(js), 10 ** 9 + ns)
            w.write('/energy', serialize_message(e), 10 ** 9 + ns + 1)


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    root = tmp_path_factory.mktemp('matrix')
    out = {}
    for name in SCENES:
        out[name] = root / name
        write_bag(demo_run(name), out[name])
    return out


@pytest.mark.parametrize('name', SCENES)
def test_verdict_matrix_offline(bags, name):
    exp = expected(demo_run(name).scene)
    for T in DURATIONS:
        ana = analyze_bag(bags[name], until=T)
        res = ana.result
        assert res.samples == int(round(T * 250)) + 1 and res.unpaired == 0, (name, T)
        check_honest(res, exp, name, f'offline at {T:g} s')
        if T >= LATE.get(name, 0.0):
            assert str(res.verdict) == exp and res.confirmed, (name, T, res.evidence)
        else:
            assert str(res.verdict) == 'insufficient data'
            detail = res.criterion(CriterionName.DECAY).detail
            assert 'not measurable in this window, ' in detail or 'straddles' in detail
        # offline up to T = the live result at T (the same windows judged)
        live = {round(v.t): v for v in live_run(name)[0]}[round(T)]
        assert (live.verdict, live.statuses) == \
            (str(res.verdict), {str(c.name): str(c.status) for c in res.criteria}), (name, T)


# -- mutations: each must NOT confirm ----------------------------------------------------------
def _first(name: str, T: float = 20.0) -> tuple:
    run = demo_run(name)
    return run.scene, [s for s in run.samples if s.t <= T + 1e-9]


def _verdict(scene, samples, **kw):
    a = RotorAnalyzer(scene, window_s=8.0, **kw)
    a.add_many(samples)
    return a.result()


def _mutations(scene) -> dict:
    if scene.builtin:
        p = scene.system.params
        return {'K_D x0.5': scene.with_params(K_D=0.5 * p.K_D),
                'K_D x2': scene.with_params(K_D=2.0 * p.K_D),
                'c_psi x1.2': scene.with_params(c_psi=1.2 * p.c_psi),
                'G x1.2': scene.with_params(G=1.2 * p.G),
                'scene nutation': load_scene('nutation'),
                'scene upright': load_scene('upright')}
    kd = scene.system.drives[0].K_D
    first = next(iter(scene.system.constants))
    return {'K_D x0.5': scene.with_changes({'K_D': 0.5 * kd}),
            'K_D x2': scene.with_changes({'K_D': 2.0 * kd}),
            f'{first} x1.2': scene.with_changes(
                {f'constants.{first}': 1.2 * scene.system.constants[first]})}


@pytest.mark.parametrize('name', ['precession', 'twin_gimbal', 'elastic_frame'])
def test_mutations_of_the_prediction_never_confirm(name):
    scene, samples = _first(name)
    res = _verdict(scene, samples)
    if name in LATE:                # every criterion but the undecided decay passes (20 s)
        assert [str(c.name) for c in res.criteria if c.status is not Status.PASS] == \
            ['decay'] and str(res.verdict) == 'insufficient data', res.evidence
    else:
        assert res.confirmed
    for what, wrong in _mutations(scene).items():
        res = _verdict(wrong, samples)
        assert not res.confirmed, (name, what, res.evidence)
        assert str(res.verdict) == 'not confirmed', (name, what, res.reason)


# -- the decay criterion's own property ---------------------------------------------------------
#: scenes where the decay criterion decides: a decaying mode predicted, not LATE
DECAYING = tuple(n for n in SCENES if n not in LATE and math.isfinite(
    RotorAnalyzer(load_scene(n), checkpoint_s=0).prediction.decaying_abscissa))
#: the slower runs last this long: the kick at 2 s, then 8 s windows up to 12 s
SLOW_RUN_S = 12.0
_SLOW: dict = {}


def _with_K_D(scene, f: float):
    """Return the scene with its drive damping K_D (every drive's) times ``f``."""
    if scene.builtin:
        return scene.with_params(K_D=f * scene.system.params.K_D)
    return scene.with_changes({'K_D': f * scene.system.drives[0].K_D})


def _decay_of_slower_run(name: str, f: float) -> Criterion:
    """Decay of a run simulated with f x K_D, analysed against the scene (cached)."""
    key = (name, round(f, 2))
    if key not in _SLOW:
        scene = load_scene(name)
        run = run_like_demo(_with_K_D(scene, key[1]), SLOW_RUN_S)
        _SLOW[key] = _verdict(scene, run.samples).criterion(CriterionName.DECAY)
    return _SLOW[key]


@settings(max_examples=10, deadline=None, derandomize=True)
@given(name=st.sampled_from(DECAYING), f=st.floats(0.3, 0.88))
@example(name='precession', f=0.75)
@example(name='elastic_frame', f=0.8)
@example(name='elastic_frame', f=0.88)
def test_decay_never_passes_a_slower_run(name, f):
    """Decay never passes a run whose drive damping is f x the scene's (0.3 <= f <= 0.88).

    The bound is 0.9 x the predicted rate, and the rates of E*'s terms scale about like
    K_D: up to f = 0.88 the true rate is under the bound (elastic_frame at 0.88: 0.403
    against 0.412).

    Found: precession at 0.75 K_D passed decay with 0.420 (interval 0.377 .. 0.475) 1/s
    against the bound 0.3735: the rate was measured with E*_inf and the amplitudes fitted
    with the predicted exponents, which absorb a wrong rate; the true rate is 0.311 1/s.
    With the slowest shown terms' rate fitted free it measures 0.3113 (0.3112 .. 0.3114)
    1/s in the windows ending 11 .. 20 s: FAIL. elastic_frame at 0.8 K_D (true 0.367
    1/s) passed with the free rate alone, 0.531 (0.476 .. 0.587): the faster terms fixed
    at the scene's rates leaked into it; with their rates scaled by a fitted factor it
    measures 0.405 (0.399 .. 0.410): FAIL. elastic_frame at 0.88 K_D (true 0.403 1/s)
    still passed with that factor, 0.419 (0.416 .. 0.422) in the window ending at 6 s: one
    factor is not the truth, and the faster terms' misfit leaks into the rate most at the
    window's start; measured again over the window's last three quarters, 0.406
    (0.4055 .. 0.4062): FAIL. The same runs at f = 1 pass (the scene's own data; the
    verdict matrix judges them over 60 s).
    """
    decay = _decay_of_slower_run(name, f)
    assert decay.status is not Status.PASS, (name, f, decay.detail)
    assert _decay_of_slower_run(name, 1.0).status is Status.PASS, name


def test_decay_fails_the_slower_precession_with_the_true_rate():
    """The finding itself: precession at 0.75 K_D, its true slowest shown rate 0.311 1/s."""
    decay = _decay_of_slower_run('precession', 0.75)
    assert decay.status is Status.FAIL, decay.detail
    bound = decay.numbers['rate_bound']
    assert decay.numbers['rate_hi'] < bound and bound == pytest.approx(0.3735, abs=1e-4)
    assert 0.30 < decay.numbers['rate'] < 0.36, decay.detail


def test_decay_fails_elastic_frame_at_0_88_K_D_by_the_window_s_last_part():
    """One fitted factor for the faster terms left elastic_frame at 0.88 K_D passing.

    Its true rate 0.403 1/s is under the bound 0.412; over the window's last three quarters
    the rate comes out near it, below the bound.
    """
    decay = _decay_of_slower_run('elastic_frame', 0.88)
    assert decay.status is Status.FAIL, decay.detail
    n = decay.numbers
    assert n['tail_rate_hi'] < n['rate_bound'] == pytest.approx(0.4124, abs=1e-4)
    assert 0.395 < n['tail_rate'] < 0.41, decay.detail
    assert 'over its last 75 %' in decay.detail and 'slower than predicted' in decay.detail


def test_a_wrong_K_D_is_seen_by_the_modes_alone():
    # K_D does not enter E* or the initial state: the drive's decay rates must show it
    scene, samples = _first('precession')
    for k in (0.5, 2.0):
        wrong = scene.with_params(K_D=k * 0.05)
        res = _verdict(wrong, samples)
        assert str(res.criterion(CriterionName.MODES).status) == 'FAIL', (k, res.evidence)
        assert str(res.criterion(CriterionName.SCENE).status) == 'PASS'


@pytest.mark.parametrize('name', ['precession', 'elastic_frame'])
def test_injected_E_star_rise_and_dropped_messages_never_confirm(name):
    scene, samples = _first(name)
    rise = [dataclasses.replace(s, E_star=s.E_star + 1e-4, residual=s.residual + 1e-4)
            if 1500 <= i < 1600 else s for i, s in enumerate(samples)]
    res = _verdict(scene, rise)
    assert not res.confirmed and 'Lyapunov' in res.reason
    rng = random.Random(23)
    kept = [s for s in samples if rng.random() >= 0.01]
    res = _verdict(scene, kept)
    assert not res.confirmed and 'data' in res.reason and res.dropped > 0
    # a window with lost samples is not fitted (no invented data), so no false growth
    assert str(res.verdict) == 'not confirmed'


def test_combination_rule_off_counts_the_sum_tone_as_a_new_mode():
    scene, samples = _first('elastic_frame')
    res = _verdict(scene, samples)
    assert res.confirmed
    # the tone's frequency with its uncertainty, then the tone and its tolerance
    assert any(re.match(r'22\.15\d* \+- [0-9.e-]+ Hz is a combination tone .*within the '
                        r'tolerance', line)
               for line in res.criterion(CriterionName.MODES).detail.split('; '))
    off = _verdict(scene, samples, combination_tones=False)
    assert not off.confirmed and 'modes' in off.reason
    assert 'unexplained' in off.criterion(CriterionName.MODES).detail


def test_near_modes_are_matched_as_an_assignment():
    # twin_gimbal: the root near -5.29 + 71.39i belongs to mode (z_R1), not to the
    # mode (z_R2) at -6.63 + 74.15i it was greedily given to
    scene, samples = _first('twin_gimbal', 8.0)
    a = RotorAnalyzer(scene, window_s=8.0, checkpoint_s=0)
    a.add_many(samples)
    modes = {m.name: m for m in a.result().judged.modes}
    z1 = modes['mode (z_R1)']
    assert str(z1.status) == 'decaying as predicted'
    assert abs(z1.measured - z1.predicted) < 0.05 * abs(z1.predicted)


def test_mode_status_says_what_the_run_saw():
    scene, samples = _first('precession')
    res = _verdict(scene, samples)
    rf = {m.name: m for m in res.judged.modes}['rotor-field coupling']
    assert str(rf.status) == 'decaying as predicted'
    assert 'decayed below the noise floor by t = ' in rf.run_status
    assert rf.freq is not None and abs(rf.freq.value / (2 * math.pi) - 10.731) < 0.01


# -- the scene must fit the recording ----------------------------------------------------------
def test_analyze_refuses_a_scene_that_is_not_the_recording(capsys, tmp_path):
    assert cli.main(['analyze', str(REPO / 'bags' / 'precession'), '--scene', 'nutation',
                     '--no-plots']) == 1
    err = capsys.readouterr().err
    assert err.startswith('ERROR: ') and err.count('\n') == 1
    assert "scene 'nutation' does not fit the recording of scene 'precession'" in err
    assert 'initial.branch 2 (recorded 1)' in err
    # the same scene under another name and path is no other scene
    doc = yaml.safe_load((REPO / 'config' / 'precession.yaml').read_text())
    copy = tmp_path / 'lab.yaml'
    copy.write_text(yaml.safe_dump(doc))
    assert cli.main(['analyze', str(REPO / 'bags' / 'precession'), '--scene', str(copy),
                     '--no-plots']) == 0
    capsys.readouterr()
    # other constants are named
    doc[next(iter(doc))]['ros__parameters']['K_D'] = 0.1
    copy.write_text(yaml.safe_dump(doc))
    assert cli.main(['analyze', str(REPO / 'bags' / 'precession'), '--scene', str(copy),
                     '--no-plots']) == 1
    assert 'K_D 0.1 (recorded 0.05)' in capsys.readouterr().err


def test_a_truncated_bag_says_so_in_its_verdict(tmp_path, capsys):
    import shutil
    bag = tmp_path / 'precession'
    shutil.copytree(REPO / 'bags' / 'precession', bag)
    mcap = bag / 'precession_0.mcap'
    data = mcap.read_bytes()
    mcap.write_bytes(data[:int(0.6 * len(data))])
    code = cli.main(['analyze', str(bag), '--no-plots'])
    out = capsys.readouterr().out
    verdict = next(ln for ln in out.splitlines() if ln.startswith('verdict: '))
    result = next(ln for ln in out.splitlines() if ln.startswith('RESULT: '))
    for line in (verdict, result):
        assert 'the recording is truncated: analysed up to the cut at t = ' in line, line
    assert code == 2
    # the messages past the cut are counted against the bag's recorded counts (issue 24: a
    # truncated bag is never a plain CONFIRMED); the one sample at the cut without its
    # partner is not counted as unpaired
    data = next(ln for ln in out.splitlines() if '] data: ' in ln)
    assert data.lstrip().startswith('[FAIL] data') and '0 unpaired' in data
    assert 'recorded messages lost' in data and '[damaged bag: ' in result


def test_the_unpaired_sample_at_the_cut_does_not_fail_data():
    p = SamplePairer()
    e = {'t_sim': 0.0, 'E_star': 1.0, 'seq': 0, 'k': 0}
    for k in range(5):
        p.add_joints(k, [0.1] * 4, [0.0] * 4)
        p.add_energy(k, {**e, 't_sim': k * 1e-9, 'seq': k, 'k': k})
    p.add_energy(5, {**e, 't_sim': 5e-9, 'seq': 5, 'k': 5})     # its joint state: cut off
    out = p.flush()
    assert len(out) == 1 and p.unpaired == 0 and p.cut == 1
    # a joint state lost in the middle still counts
    q = SamplePairer(keep=2)
    for k in range(8):
        if k != 3:
            q.add_joints(k, [0.1] * 4, [0.0] * 4)
        q.add_energy(k, {**e, 't_sim': k * 1e-9, 'seq': k, 'k': k})
    q.flush()
    assert q.unpaired_energy == 1 and q.cut == 0


# -- sweeps -----------------------------------------------------------------------------------
def test_sweep_decay_rate_is_a_decay_or_not_resolved():
    t = np.linspace(0.0, 10.0, 2501)
    decaying = np.abs(np.exp(-0.3 * t) * np.cos(20.0 * t))
    assert fit_decay(t, decaying) == pytest.approx(0.3, rel=0.05)
    m = decay_interval(t, decaying)
    assert m.lo < 0.3 < m.hi and m.hi - m.lo > 0
    # two undamped modes beating: no decay, and no growth either
    beating = np.abs(np.cos(20.0 * t) + 0.8 * np.cos(21.3 * t))
    assert math.isnan(fit_decay(t, beating))
    # a decay too slow for the run: not resolved within t_end
    assert math.isnan(fit_decay(t, np.exp(-1e-4 * t)))


def test_sweep_of_twin_gimbal_gives_no_growth_at_stable_points():
    from gyro_rotor.analysis.sweep.metrics import Metric, system_metrics
    from gyro_rotor.numerics.simulate import integrate
    for k_d in (0.01, 0.0316):
        scene = load_scene('twin_gimbal').with_changes({'K_D': k_d})
        model = scene.make_model()
        t = np.linspace(0.0, 10.0, 1001)
        run = integrate(model, scene.initial_state(model), t)
        rate = system_metrics(model, np.asarray(scene.system.steady_q), t, run.y, {Metric.DECAY},
                              tol=1e-3)['decay_rate']
        # every root is stable (eig): a rate is positive or not resolved, never negative
        assert math.isnan(rate) or rate > 0, (k_d, rate)


def test_codes_on_the_topics_are_the_positions():
    """The numbers the analysis sends for its closed choices (the topics' contract)."""
    from gyro_rotor.analysis.verdict import ModeStatus, SyncState, Verdict
    assert [s.code for s in Status] == [0, 1, 2] and Status.NOT_YET.code == 2
    assert Verdict.INSUFFICIENT_DATA.code == 0 and Verdict.NOT_CONFIRMED.code == 5
    assert ModeStatus.NOT_IDENTIFIED.code == 0 and ModeStatus.UNOBSERVABLE.code == 8
    assert (SyncState.SYNCHRONOUS.code, SyncState.RESYNCHRONIZED.code) == (0, 2)
    assert not hasattr(CriterionName.DECAY, 'code')


@settings(max_examples=300, deadline=None)
@given(lo=st.floats(1e-3, 1e3), width=st.floats(1e-9, 10.0), rel=st.floats(-0.2, 0.2),
       near=st.floats(-1e-4, 1e-4))
def test_printed_interval_reads_on_the_side_of_the_bound_it_is_decided_on(lo, width, rel,
                                                                          near):
    """The decay line prints each end of the interval on its true side of the bound.

    Found on elastic_frame: 'decays at 0.462 (interval 0.412 .. 0.538), bound 0.4124' beside
    PASS, with the true lower end 0.41246 above the bound 0.41243.
    """
    hi = lo + width
    bound = lo * (1 + near) if rel == 0 else lo * (1 + near) + rel * width
    m = Measured(0.5 * (lo + hi), lo, hi)
    text, b = fmt_against(m, bound, '1/s')
    shown = text.split('(interval ')[1].split(')')[0].split(' .. ')
    for end, x in zip(shown, (lo, hi)):
        if x != bound:
            assert (float(end) > float(b)) == (x > bound) and float(end) != float(b), (text, b)


def test_the_window_a_number_needs_is_never_inf_nor_this_window():
    """Neither "needs about inf s" (an unbounded interval) nor "needs 8 s" in an 8 s window."""
    from gyro_rotor.analysis.verdict import needs_phrase
    assert needs_phrase(8.0, 0.1, 0.2) == 'needs about 32 s'
    assert 'inf' not in needs_phrase(8.0, 0.1, math.inf)
    assert 'unbounded' in needs_phrase(8.0, 0.1, math.inf)
    assert needs_phrase(8.0, 1.0, 0.1) == 'not for want of a longer window'
