"""Every shipped scene, default method and tolerances: axis direction accurate to 1e-8.

Compared with a run at 100 times tighter tolerances over the scene's whole duration; the
error is the largest angle between the two symmetry axes over the samples (and |z|).
"""

from gyro_rotor.core.scene import list_scenes
from gyro_rotor.numerics.integrators import METHODS
from gyro_rotor.numerics.simulate import DEFAULT_ATOL, DEFAULT_RTOL, simulate
import numpy as np
import pytest


@pytest.mark.parametrize('name', list_scenes(builtin=True))
def test_default_run_accurate_to_1e_8_in_axis_direction(name):
    tr = simulate(name, rate=20.0)
    assert METHODS[tr.method].adaptive     # else tighter tolerances would change nothing
    tight = simulate(name, rate=20.0, method=tr.method, rtol=DEFAULT_RTOL / 100,
                     atol=DEFAULT_ATOL / 100)
    a, b = tr.axis, tight.axis
    angle = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.sum(a * b, axis=1))
    assert np.max(angle) < 1e-8
    assert np.max(np.abs(tr.z - tight.z)) < 1e-8
