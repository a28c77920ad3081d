"""RotorParams: every bad value is refused with a message naming field and value."""

import math
import warnings

from gyro_rotor.core.params import PARAM_FIELDS, RotorParams, StaticallyUnstableWarning
from gyro_rotor.errors import ParameterError
import pytest


def test_defaults_are_valid_and_statically_stable():
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        p = RotorParams()
    assert p.c_theta > p.G * p.s
    assert p.I == pytest.approx(p.A_R + p.A_M)


@pytest.mark.parametrize('name', [n for n in PARAM_FIELDS if n != 'pole_pairs'])
@pytest.mark.parametrize('value', [math.nan, math.inf, -math.inf])
def test_non_finite_refused(name, value):
    with pytest.raises(ParameterError, match=name):
        RotorParams(**{name: value})


@pytest.mark.parametrize('name', ['A_R', 'A_M', 'C_R', 'C_M'])
@pytest.mark.parametrize('value', [0.0, -0.1])
def test_non_positive_inertia_refused(name, value):
    with pytest.raises(ParameterError, match=f'{name}.*{value}'):
        RotorParams(**{name: value})


@pytest.mark.parametrize('name', ['G', 'c_theta', 'c_psi', 'K_S', 'K_D'])
def test_negative_stiffness_or_damping_refused(name):
    with pytest.raises(ParameterError, match=f'{name}.*-1.5'):
        RotorParams(**{name: -1.5})


@pytest.mark.parametrize('value', [-1, 1.5, 'two', True, math.nan])
def test_bad_pole_pairs_refused(value):
    with pytest.raises(ParameterError, match='pole_pairs'):
        RotorParams(pole_pairs=value)


def test_wrong_type_refused():
    with pytest.raises(ParameterError, match="K_S.*'20'"):
        RotorParams(K_S='20')


def test_integral_float_pole_pairs_accepted():
    assert RotorParams(pole_pairs=2.0).pole_pairs == 2


def test_weak_restraint_warns():
    with pytest.warns(StaticallyUnstableWarning, match='c_theta'):
        RotorParams(c_theta=1.0)


def test_immutable_and_replace_validates():
    p = RotorParams()
    with pytest.raises(Exception):
        p.K_D = 1.0
    assert p.replace(K_D=1.0).K_D == 1.0
    with pytest.raises(ParameterError, match='K_D'):
        p.replace(K_D=-1.0)
    with pytest.raises(ParameterError, match="did you mean 'K_D'"):
        p.replace(K_d=1.0)


def test_mapping_roundtrip():
    p = RotorParams(K_D=0.3, pole_pairs=2)
    assert RotorParams(**p.to_mapping()) == p
