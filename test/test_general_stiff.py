"""Stiff drives on generated systems (issue 25, item 4): the exact Jacobian and its method."""

from gyro_rotor.core.scene import load_scene
from gyro_rotor.numerics.integrators import radau_jac
from gyro_rotor.numerics.simulate import integrate
import numpy as np
import pytest

SHIPPED = ('centrifuge_euler', 'twin_gimbal', 'elastic_frame')


def _fd_jacobian(model, y):
    """d(rhs)/dy by central differences with one Richardson step (error ~ h^4, h = 1e-3)."""
    ny = y.size
    J = np.empty((ny, ny))
    for c in range(ny):
        h = 1e-3 * max(1.0, abs(y[c]))

        def f(d, c=c):
            yy = y.copy()
            yy[c] += d
            return model.rhs(0.0, yy)
        J[:, c] = (8.0 * (f(h / 2) - f(-h / 2)) - (f(h) - f(-h))) / (6.0 * h)
    return J


def _relative_error(J, Jfd):
    """Entry-wise |J - Jfd| in units of the larger of its row's and its column's scale."""
    d = np.abs(J - Jfd)
    row = np.abs(Jfd).max(axis=1, keepdims=True)
    col = np.abs(Jfd).max(axis=0, keepdims=True)
    return float((d / np.maximum(np.maximum(row, col), 1e-300)).max())


@pytest.mark.parametrize('name', SHIPPED)
@pytest.mark.parametrize('drive', [{}, {'K_D': 50.0}, {'pole_pairs': 2, 'K_D': 0.3}])
def test_generated_jacobian_matches_finite_differences(name, drive):
    """jac(y, P, J) is d(rhs)/dy to 1e-7 at random states, for both drive laws."""
    scene = load_scene(name)
    if drive:
        scene = scene.with_drives(**drive)
    model = scene.make_model()
    rng = np.random.default_rng(7)
    ny = model.size
    for _ in range(4):
        y = rng.uniform(-1.0, 1.0, ny)
        y[:model.n] = rng.uniform(0.2, 0.8, model.n)     # away from singular coordinates
        y[-1] = rng.uniform(0.0, 3.0)
        J = np.full((ny, ny), np.nan)
        model.compiled.jac(y, model.P, J)
        Jfd = _fd_jacobian(model, y)
        assert np.all(np.isfinite(J))
        assert _relative_error(J, Jfd) < 1e-7, (name, drive)
        assert np.all(J[:, -1] == 0.0)                  # D enters no equation


def test_jacobian_check_detects_a_wrong_entry():
    """The comparison above fails for a Jacobian wrong in one coupling entry by 1e-5."""
    model = load_scene('twin_gimbal').make_model()
    y = np.linspace(0.1, 0.9, model.size)
    J = np.empty((model.size, model.size))
    model.compiled.jac(y, model.P, J)
    Jfd = _fd_jacobian(model, y)
    n = model.n
    J[n + 1, 1] *= 1.0 + 1e-5                           # d(beta1_ddot)/d beta1
    assert J[n + 1, 1] != 0.0 and _relative_error(J, Jfd) > 1e-7


# -- radau9 with the exact Jacobian ------------------------------------------------------------
def test_transformation_block_diagonalizes_A_inverse_and_matches_scipy_for_3_stages():
    """TI A^-1 T is diag(mu_r, [[a, -b], [b, a]], ...); for s = 3 scipy's Radau numbers."""
    from scipy.integrate._ivp import radau as sr
    for s in (3, 5):
        A, C, T, TI, mu_r, mu_c, E = radau_jac.tableau(s)
        L = TI @ np.linalg.inv(A) @ T
        expect = np.zeros((s, s))
        expect[0, 0] = mu_r
        for p, mu in enumerate(mu_c):
            i = 1 + 2 * p
            expect[i:i + 2, i:i + 2] = [[mu.real, -mu.imag], [mu.imag, mu.real]]
        assert np.abs(L - expect).max() < 1e-12 * np.abs(expect).max()
    A, C, T, TI, mu_r, mu_c, E = radau_jac.tableau(3)
    assert mu_r == pytest.approx(sr.MU_REAL, rel=1e-14)
    assert mu_c[0] == pytest.approx(sr.MU_COMPLEX, rel=1e-14)
    assert np.allclose(E, sr.E, rtol=1e-12, atol=0.0)


def _twin(K_D=None):
    scene = load_scene('twin_gimbal')
    if K_D is not None:
        scene = scene.with_drives(K_D=K_D)
    model = scene.make_model()
    return model, scene.initial_state(model)


def test_radau9_agrees_with_dop853_on_the_non_stiff_system():
    model, y0 = _twin()
    te = np.linspace(0.0, 1.0, 101)
    ref = integrate(model, y0, te, method='dop853', rtol=1e-13, atol=1e-15).y
    errs = []
    for rtol in (1e-6, 1e-8, 1e-10):
        run = integrate(model, y0, te, method='radau9', rtol=rtol, atol=rtol * 1e-3)
        assert run.method == 'radau9'
        errs.append(np.abs(run.y - ref).max())
    assert errs[2] < 1e-8
    assert errs[0] > errs[1] > errs[2]                  # converges as the tolerance shrinks


@pytest.mark.parametrize('K_D, method, rtol', [(1e2, 'dop853', 1e-12),
                                               (1e6, 'rodas4', 1e-11)])
def test_radau9_on_a_stiff_drive_against_a_tight_reference(K_D, method, rtol):
    """Stiff twin_gimbal: radau9 at rtol 1e-8 within 1e-7 of an independent tight run."""
    model, y0 = _twin(K_D)
    te = np.linspace(0.0, 0.5, 51)
    ref = integrate(model, y0, te, method=method, rtol=rtol, atol=rtol * 1e-3).y
    run = integrate(model, y0, te, method='radau9', rtol=1e-8, atol=1e-11)
    pos = np.r_[0:model.n, 2 * model.n:2 * model.n + model.m]
    assert np.abs(run.y[:, pos] - ref[:, pos]).max() < 1e-7
    assert np.abs(model.residual(run.y)).max() < 1e-8 * model.energy(y0)


def test_radau9_cost_does_not_grow_with_K_D():
    """A cost budget, not a timing: evaluations at K_D = 1e6 within 1.5 x those at 1e2."""
    te = np.linspace(0.0, 1.0, 101)
    nfev = {}
    for K_D in (1e2, 1e4, 1e6):
        model, y0 = _twin(K_D)
        nfev[K_D] = integrate(model, y0, te, method='radau9', rtol=1e-8, atol=1e-11).nfev
    assert max(nfev.values()) < 1.5 * min(nfev.values()), nfev


def test_auto_and_the_stepper_use_radau9_with_the_generated_jacobian():
    from gyro_rotor.numerics.kernel_system import KernelSystem
    from gyro_rotor.numerics.integrators import choose_method
    from gyro_rotor.numerics.integrators.methods import make_integrator
    model, y0 = _twin(1e4)
    assert choose_method(model, y0=y0)[0] == 'radau9'
    stepper = make_integrator('radau9', KernelSystem(model), y0, 0.0, 1.0, rtol=1e-8,
                              atol=1e-11)
    assert isinstance(stepper, radau_jac.Radau9Jac)
    assert stepper.advance_to(0.1) == 'running' and stepper.t == 0.1
    run = integrate(model, y0, [0.0, 0.1], method='radau9', rtol=1e-8, atol=1e-11)
    assert np.abs(stepper.y - run.y[-1]).max() < 1e-7


def test_the_live_simulation_runs_a_stiff_drive_of_a_system_file_with_radau9():
    """The live path (rotor_sim's stepper): auto is radau9 at K_D = 1e4, the residual small."""
    from gyro_rotor.node_settings import NODE_KEYS
    from gyro_rotor.numerics.live import LiveSimulation
    cfg = {k: v[1] for k, v in NODE_KEYS.items()}
    cfg['real_time_factor'] = 0.0
    scene = load_scene('twin_gimbal', {'K_D': 1e4})
    sim = LiveSimulation(scene, cfg, {}, budget=None)
    assert sim.stepper.method == 'radau9'
    blocks = []
    while sim.stepper.t < 0.3 and not sim.diverged:
        b = sim.tick()
        if b is not None:
            blocks.append(b)
    assert not sim.diverged and blocks
    resid = np.concatenate([b.energy['residual'] for b in blocks])
    assert np.abs(resid).max() < 1e-6 * sim.model.energy(scene.initial_state(sim.model))
