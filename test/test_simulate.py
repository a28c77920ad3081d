"""simulate(): energy balance, conservation, the passage through theta = 0, reduced models."""

from gyro_rotor.core.model import Model
from gyro_rotor.errors import ParameterError
from gyro_rotor.numerics.simulate import simulate
import numpy as np
import pytest
from scipy.signal import argrelmin

SCENES = ['precession', 'nutation', 'upright', 'stiff_drive', 'fast_spin', 'conservative',
          'pole_slip', 'locked_housing']
SHORT = {'stiff_drive': 0.5, 'fast_spin': 0.5, 'conservative': 5.0}


@pytest.mark.parametrize('name', SCENES)
def test_energy_balance_residual_at_tolerance_level(name):
    """r(t) = E*(t) - E*(0) + int K_D zdot^2 stays at the integrator's tolerance level."""
    tr = simulate(name, t_end=SHORT.get(name), rate=50.0)
    scale = max(1.0, float(np.max(np.abs(tr.E_star))))
    assert tr.max_abs_residual < 1e3 * tr.rtol * scale
    assert tr.max_qnorm_drift < 1e3 * tr.rtol
    if tr.scene.system.params.K_D > 0 and name != 'locked_housing':
        assert tr.E_star[-1] < tr.E_star[0]          # the drive takes energy out


def test_conservative_energy_is_conserved():
    tr = simulate('conservative', rate=20.0)
    E = tr.E_star
    assert np.max(np.abs(E - E[0])) < 1e3 * tr.rtol * E[0]
    assert np.all(tr.out['dissipation'] == 0.0)


def test_upright_passes_theta_zero_many_times_without_loss_of_accuracy():
    tr = simulate('upright', rate=2000.0)
    # distance of the axis tip's horizontal track (piecewise linear between samples) from
    # the vertical: its local minima are the passages
    P = tr.axis[:, :2]
    a, d = P[:-1], P[1:] - P[:-1]
    s = np.clip(-(a * d).sum(1) / np.maximum((d * d).sum(1), 1e-300), 0.0, 1.0)
    dist = np.linalg.norm(a + s[:, None] * d, axis=1)
    amplitude = np.linalg.norm(P, axis=1).max()
    minima = argrelmin(dist)[0]
    passes = minima[dist[minima] < 1e-3 * amplitude]
    assert len(passes) >= 50
    assert tr.max_abs_residual < 1e3 * tr.rtol * tr.E_star[0]
    assert tr.max_qnorm_drift < 1e3 * tr.rtol
    assert np.all(np.isfinite(tr.psi)) and np.all(np.isfinite(tr.phi_M))


def test_locked_housing_is_the_limit_of_a_stiff_twist_restraint():
    """The 1-DOF model agrees with the full one as c_psi -> infinity, error ~ 1/c_psi."""
    ref = simulate('locked_housing', t_end=1.0, rate=200.0)
    errs = []
    for c_psi in (1e3, 1e4):
        tr = simulate('upright', t_end=1.0, rate=200.0, overrides={
            'c_psi': c_psi, 'initial.dz': 0.2, 'initial.dzdot': 0.0,
            'initial.dthetadot': 0.0, 'initial.dchi': 0.0})
        errs.append(np.max(np.abs(tr.z - ref.z)))
    assert errs[1] < errs[0] / 5
    assert errs[1] < 5e-3


def test_upright_axis_is_the_limit_of_a_stiff_tilt_restraint():
    ref = simulate('upright', t_end=1.0, rate=200.0,
                   overrides={'model': 'upright_axis', 'initial.dthetadot': 0.0})
    assert ref.model.name == 'upright_axis'
    errs = []
    for c_theta in (1e3, 1e4):
        tr = simulate('upright', t_end=1.0, rate=200.0,
                      overrides={'c_theta': c_theta, 'initial.dthetadot': 0.05})
        errs.append(max(np.max(np.abs(tr.z - ref.z)), np.max(np.abs(tr.chi - ref.chi))))
    assert errs[1] < errs[0] / 5
    assert errs[1] < 1e-7


def test_trajectory_outputs_and_csv(tmp_path):
    tr = simulate('precession', t_end=0.5, rate=100.0)
    assert len(tr.t) == 51 and tr.t[-1] == pytest.approx(0.5)
    f = tmp_path / 'x.csv'
    tr.save(str(f))
    header = f.read_text().splitlines()[0].split(',')
    assert header == [f'{name} [{unit}]' for name, unit, *_ in Model.CSV_COLUMNS]
    data = np.loadtxt(f, delimiter=',', skiprows=1)
    assert data.shape == (51, len(Model.CSV_COLUMNS))
    assert np.allclose(np.linalg.norm(data[:, 9:12], axis=1), 1.0)
    tr.save(str(tmp_path / 'x.npz'))
    assert 'E_star' in np.load(tmp_path / 'x.npz')
    with pytest.raises(ParameterError, match='.csv or .npz'):
        tr.save(str(tmp_path / 'x.txt'))


@pytest.mark.parametrize('kwargs, match', [
    ({'t_end': -1.0}, 't_end'), ({'rate': 0.0}, 'rate'), ({'rtol': -1e-6}, 'rtol'),
    ({'atol': float('nan')}, 'atol'), ({'overrides': {'K_D': -1.0}}, 'K_D'),
    ({'y0': np.full(10, np.nan)}, 'finite'),
])
def test_bad_simulate_input(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        simulate('precession', **kwargs)


def test_axis_straight_down_is_a_clear_error(tmp_path):
    """The one singular orientation (theta = pi) stops the run with an IntegrationError."""
    from gyro_rotor.errors import IntegrationError
    from gyro_rotor.core.scene import load_scene
    f = tmp_path / 'down.yaml'
    f.write_text('rotor_sim:\n  ros__parameters:\n    initial:\n      mode: body\n'
                 '      quaternion: [0.0, 1.0, 0.0, 0.0]\n')
    with pytest.raises(IntegrationError, match='theta = pi'):
        simulate(load_scene(f), t_end=0.1)
