"""Ensemble mode: lockstep runs agree with single-trajectory runs; bad input refused."""

from gyro_rotor.core.scene import load_scene
from gyro_rotor.errors import ParameterError
from gyro_rotor.numerics.ensemble import run_ensemble
from gyro_rotor.numerics.integrators import HAVE_NUMBA, integrate
import numpy as np
import pytest

BACKENDS = ['numpy'] + (['numba'] if HAVE_NUMBA else [])


def _ensemble(n=6):
    sc = load_scene('precession')
    m = sc.make_model()
    y0 = sc.initial_state(m)
    rng = np.random.default_rng(1)
    Y0 = np.repeat(y0[None], n, axis=0)
    Y0[:, 8] += rng.normal(0.0, 1.0, n)            # zdot
    Y0[:, 4:6] += rng.normal(0.0, 0.05, (n, 2))    # transverse rates
    params = [sc.system.params.replace(K_D=kd) for kd in np.linspace(0.0, 0.5, n)]
    return m, Y0, params


@pytest.mark.parametrize('backend', BACKENDS)
@pytest.mark.parametrize('method', ['rk4', 'rk8'])
def test_ensemble_agrees_with_single_runs(backend, method):
    m, Y0, params = _ensemble()
    te = np.linspace(0.0, 0.2, 5)
    ens = run_ensemble(m, Y0, te, method=method, params=params, backend=backend)
    assert ens.y.shape == (5, len(Y0), m.n)
    for i, p in enumerate(params):
        mi = type(m)(p)
        single = integrate(mi, Y0[i], (0.0, 0.2), te, method, step=ens.step)
        np.testing.assert_allclose(ens.y[:, i], single.y, rtol=0, atol=1e-12)
    # the parameters matter: trajectories with different K_D differ
    assert np.max(np.abs(ens.y[-1, 0] - ens.y[-1, -1])) > 1e-6


@pytest.mark.parametrize('kwargs, match', [
    ({'method': 'euler'}, 'method'), ({'backend': 'gpu'}, 'backend'),
    ({'step': -1.0}, 'step'), ({'Y0': np.full((2, 10), np.nan)}, 'finite'),
    ({'Y0': np.zeros((2, 4))}, 'shape'), ({'t_eval': [0.0]}, 't_eval'),
])
def test_ensemble_bad_input(kwargs, match):
    m, Y0, _ = _ensemble(2)
    args = {'Y0': Y0, 't_eval': [0.0, 0.1], **kwargs}
    with pytest.raises(ParameterError, match=match):
        run_ensemble(m, args.pop('Y0'), args.pop('t_eval'), **args)
