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

