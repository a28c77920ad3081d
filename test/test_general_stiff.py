"""Stiff drives on generated systems (issue 25, item 4): the exact Jacobian and its method."""

from gyro_rotor.core.system.scene import load_general_scene
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
    scene = load_general_scene(name)
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
    model = load_general_scene('twin_gimbal').make_model()
    y = np.linspace(0.1, 0.9, model.size)
    J = np.empty((model.size, model.size))
    model.compiled.jac(y, model.P, J)
    Jfd = _fd_jacobian(model, y)
    n = model.n
    J[n + 1, 1] *= 1.0 + 1e-5                           # d(beta1_ddot)/d beta1
    assert J[n + 1, 1] != 0.0 and _relative_error(J, Jfd) > 1e-7
