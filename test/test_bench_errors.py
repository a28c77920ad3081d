"""The benchmark's error measure on every model a scene can run (numerics/bench.errors)."""

from gyro_rotor.core.model import make_model
from gyro_rotor.core.scene import load_scene
from gyro_rotor.numerics.bench import errors
from gyro_rotor.numerics.integrators import integrate
import numpy as np
import pytest


@pytest.mark.parametrize('name', ['full', 'upright_axis', 'locked_housing'])
def test_errors_measure_the_axis_and_z_of_every_centrifuge_model(name):
    """A run against itself: 0; z moved by 1e-7: z_err 1e-7, axis_err 0.

    The reduced models' states hold no quaternion: the locked housing's 3 states were
    unpacked as a quaternion's 4 (a traceback in ``bench --scenes locked_housing``) and the
    upright axis's chi, chidot, z, zdot were read as one.
    """
    model = make_model(name, load_scene('precession').system.params)
    y0 = model.state_from_euler(theta=0.1 if name == 'full' else 0.0, psidot=1.0)
    R = integrate(model, y0, (0.0, 0.5), np.linspace(0.0, 0.5, 11), method='dop853',
                  rtol=1e-10).y
    assert errors(model, R.copy(), R)['err'] == 0.0
    Y = R.copy()
    Y[:, model.iz] += 1e-7
    e = errors(model, Y, R)
    assert e['axis_err'] == 0.0 and e['z_err'] == pytest.approx(1e-7, rel=1e-6)
