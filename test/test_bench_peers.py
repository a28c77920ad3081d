"""The benchmark's compiled peers (CyRK, numbalsoda) run the package's equations.

Their right-hand side is the benchmark's own copy of the full model (a user's numba code,
constants folded in): it must agree with core.model.full_rhs at random states to 1e-14
(relative to the size of the derivative), or the benchmark would compare different
problems. Skipped, with the reason, where the benchmark extras are not installed.
"""

from gyro_rotor.core.model import FullModel
from gyro_rotor.core.scene import load_scene
import numpy as np
import pytest

pytest.importorskip('numba', reason='numba not installed: the peers need it')
bench_peers = pytest.importorskip('gyro_rotor.numerics.bench_peers')


@pytest.mark.parametrize('scene', ['precession', 'pole_slip', 'stiff_drive', 'conservative'])
def test_peer_rhs_equals_the_model_at_random_states(scene):
    params = load_scene(scene).system.params
    model = FullModel(params)
    f = bench_peers.peer_rhs_python(params)
    rng = np.random.default_rng(26)
    for _ in range(200):
        y = rng.uniform(-2.0, 2.0, size=10)
        y[0] += 2.5          # keep the axis away from theta = pi (the model's one singularity)
        want = model.rhs(0.0, y)[:9]
        got = f(y[:9].copy())
        assert np.max(np.abs(got - want)) <= 1e-14 * max(1.0, np.max(np.abs(want))), y


@pytest.mark.parametrize('package', ['cyrk', 'numbalsoda'])
def test_each_peer_runs_the_model(package):
    if package not in bench_peers.available():
        pytest.skip(bench_peers.missing_reason())
    from gyro_rotor.numerics.integrators import integrate
    scene = load_scene('precession')
    model = scene.make_model()
    y0 = scene.initial_state(model)
    te = np.linspace(0.0, 0.5, 51)
    peer = bench_peers.make_peer_rhs(scene.system.params)
    ref = integrate(model, y0, (0.0, 0.5), te, 'dop853', rtol=1e-12, atol=1e-14).y
    for method in bench_peers.PEER_METHODS[package]:
        Y, _ = bench_peers.peer_run(peer, package, method, y0, te, 1e-10, 1e-12)
        assert Y is not None and Y.shape == (51, 9), method
        assert np.max(np.abs(Y - ref[:, :9])) < 1e-6, method


@pytest.mark.parametrize('name', ['centrifuge_euler', 'twin_gimbal', 'elastic_frame'])
def test_general_peer_rhs_equals_the_generated_model_at_random_states(name):
    """The general systems' peer (numba on sympy lambdify, a linear solve per call)."""
    pytest.importorskip('sympy')
    from gyro_rotor.core.system.codegen import pack
    from gyro_rotor.core.scene import load_scene
    scene = load_scene(name)
    model = scene.make_model()
    y0 = scene.initial_state(model)
    f = bench_peers.general_peer_rhs_python(scene)
    P = pack(model.system)
    rng = np.random.default_rng(26)
    for _ in range(100):
        y = y0 + rng.normal(scale=0.3, size=y0.shape)
        if name == 'centrifuge_euler':
            # Euler angles: the mass matrix is singular at theta = 0, ill-conditioned near it
            y[0] = rng.uniform(0.2, 1.2)
        want = np.empty(y.size)
        model.compiled.rhs(y, P, want)
        got = f(y)
        # the two evaluate M^-1 F in different orders: equal to the solve's round-off
        assert np.max(np.abs(got - want)) <= 1e-12 * max(1.0, np.max(np.abs(want))), y


def test_the_bench_repeats_in_rounds_and_keeps_each_run_s_fastest():
    """The repeats of one run are spread over the sweep, not back to back (stop 37).

    The machine's speed drifts over minutes: back-to-back repeats put a slow spell on one
    method. Here a setting of method A is slow on its first pass and one of B on its later
    ones; each keeps its fastest timed pass. Round 1 runs the jobs in their order; each
    later round runs every job once, a method's settings together and in their order (a
    block), the blocks in a shuffled order (``random.Random(k)``), and each block's first
    job once untimed before its timed run (a run after another package's code is slower).
    """
    import dataclasses
    import random
    from gyro_rotor.numerics.bench import timed_in_rounds

    @dataclasses.dataclass
    class Row:
        name: str
        wall_per_sim: float

    now, calls = [0.0], []
    jobs = [('A', 1), ('A', 2), ('A', 3), ('B', 1), ('B', 2), ('B', 3), ('C', 1), ('C', 2)]
    slow = {('A', 1): 3.0e-3, ('B', 1): 1.0e-3}      # their first pass; later ones below
    later = {('A', 1): [1.0e-3, 2.0e-3], ('B', 1): [5.0e-3, 4.0e-3]}
    reads = [0]                 # clock reads: odd while a timed run is under way

    def clock():
        reads[0] += 1
        return now[0]

    def job(name, n):
        def fn():
            calls.append(f'{name}{n}')
            if len(calls) <= len(jobs):
                dt = slow.get((name, n), 1.0e-3)
            elif reads[0] % 2:
                dt = later[(name, n)].pop(0) if (name, n) in later else 1.0e-3
            else:
                dt = 9.0e-3             # an untimed run: were it timed, rows would show it
            now[0] += dt
            return None, 1, 1, 0, 0.5          # Y, nfev, nsteps, status, t_done
        return ('gyro_rotor', name, f'rtol=1e-0{n}', fn)

    rows = timed_in_rounds([job(*j) for j in jobs],
                           lambda family, name, setting, out, wall: Row(name, wall / out[4]),
                           3, clock=clock)
    assert calls[:8] == ['A1', 'A2', 'A3', 'B1', 'B2', 'B3', 'C1', 'C2']
    block = {'A': ['A1', 'A1', 'A2', 'A3'], 'B': ['B1', 'B1', 'B2', 'B3'], 'C': ['C1', 'C1', 'C2']}
    rest = calls[8:]
    for k in (2, 3):
        order = list('ABC')
        random.Random(k).shuffle(order)
        want = [c for m in order for c in block[m]]
        assert rest[:len(want)] == want, (k, rest)
        rest = rest[len(want):]
    assert rest == []
    assert [r.name for r in rows] == list('AAABBBCC')
    assert [r.wall_per_sim for r in rows] == pytest.approx([2.0e-3] * 8, rel=1e-12)


def test_no_block_of_the_bench_always_follows_the_same_one():
    """Over the rounds of a sweep of 20 methods, the first is not always after the last.

    With a rotation of the jobs the last block (a peer's) came before the first (auto's)
    in every round; auto's first settings then ran slower than the same computations.
    """
    from gyro_rotor.numerics.bench import REPEATS, timed_in_rounds
    calls = []

    def job(m):
        def fn():
            calls.append(m)
            return None, 1, 1, 0, 1.0
        return ('gyro_rotor', f'm{m}', 'rtol=1e-03', fn)
    timed_in_rounds([job(m) for m in range(20)], lambda *a: type('R', (), {
        'wall_per_sim': 0.0})(), REPEATS, clock=lambda: 0.0)
    rounds = [calls[20:][k * 40:(k + 1) * 40:2] for k in range(REPEATS - 1)]
    assert all(sorted(r) == list(range(20)) for r in rounds)
    before_first = [r[r.index(0) - 1] if r.index(0) else None for r in rounds]
    assert before_first.count(19) < len(rounds), before_first


@pytest.mark.parametrize('quick', [True, False])
def test_the_bench_picks_peers_by_the_equations_the_system_says_they_copy(monkeypatch, quick):
    """The peers are those of the system's ``peer_equations``, not of ``builtin`` (issue #25).

    The centrifuge's full model: CyRK and numbalsoda; its other models: none; a system
    file's: CyRK on its generated equations.
    """
    from gyro_rotor.numerics import bench
    monkeypatch.setattr(bench_peers, 'available', lambda: ('cyrk', 'numbalsoda'))
    monkeypatch.setattr(bench_peers, 'make_peer_rhs', lambda params, have: ('full', have))
    monkeypatch.setattr(bench_peers, 'make_general_peer', lambda scene: ('generated', scene))
    full = bench.QUICK_PEERS if quick else bench_peers.PEER_METHODS
    general = bench.QUICK_PEERS['cyrk'] if quick else bench_peers.GENERAL_PEER_METHODS
    prec, twin = load_scene('precession'), load_scene('twin_gimbal')
    assert bench._peers(prec, quick) == (('full', list(full)), dict(full))
    assert bench._peers(load_scene('locked_housing'), quick) == (None, {})
    assert bench._peers(twin, quick) == (('generated', twin), {'cyrk': general})


def test_the_stiff_table_puts_ours_against_the_best_of_scipy_and_of_cyrk(monkeypatch):
    """`bench --table stiff`: auto's row carries scipy best / ours and CyRK best / ours.

    Each is the fastest run of that family with error <= level; a run above the level
    (here CyRK's faster LSODA at 2e-6) is not a peer's best.
    """
    import argparse
    from gyro_rotor.cli.commands import bench as bench_cmd
    from gyro_rotor.numerics import bench
    S = bench.StiffRow
    rows = [S(100.0, 'auto (radau9)', 1e-4, 5e-7, 0.001, 2.0, 10, 0.5),
            S(100.0, 'lambdify+LSODA', 1e-6, 6e-7, 0.040, 2.0, 10, 0.5),
            S(100.0, 'lambdify+Radau', 1e-4, 4e-7, 0.050, 2.0, 10, 0.5),
            S(100.0, bench.PEER_PREFIX + 'Radau', 1e-6, 3e-7, 0.004, 2.0, -1, 0.5),
            S(100.0, bench.PEER_PREFIX + 'LSODA', 1e-5, 2e-6, 0.002, 2.0, -1, 0.5),
            S(100.0, bench.PEER_PREFIX + 'LSODA', 1e-6, 8e-7, 0.003, 2.0, -1, 0.5)]
    monkeypatch.setattr(bench, 'stiff_table', lambda **kw: (rows, {100.0: 1e-12}))
    args = argparse.Namespace(table=bench_cmd.BenchTable.STIFF, scenes='twin_gimbal',
                              out='bench', t_end=2.0, level=1e-6, repeats=1)
    lines = bench_cmd.stiff_lines(args, 'twin_gimbal')
    head = next(x for x in lines if x.startswith('| K_D | method |'))
    assert head.rstrip(' |').endswith('scipy best / ours | CyRK best / ours'), head
    ours = next(x for x in lines if x.startswith('| 100 | auto (radau9) |'))
    assert ours.rstrip(' |').endswith('| 40.0x | 3.0x'), ours
