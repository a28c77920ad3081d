"""Property-based tests (hypothesis) over parameters and scene files.

Any valid parameter set gives a finite right-hand side and an energy-balance residual at
the tolerance level; any invalid one is refused with a message naming the field; any
scene file, however malformed, gives a GyroRotorError with a message, never a traceback
of another kind.
"""

import math
import warnings

from gyro_rotor.core.model import FullModel
from gyro_rotor.core.params import PARAM_FIELDS, RotorParams
from gyro_rotor.core.scene import load_scene, scene_from_mapping, SCENE_KEYS
from gyro_rotor.errors import GyroRotorError, ParameterError
from gyro_rotor.numerics.simulate import simulate
from hypothesis import given, HealthCheck, settings, strategies as st
import numpy as np
import pytest
import yaml

pytestmark = pytest.mark.filterwarnings(
    'ignore::gyro_rotor.core.params.StaticallyUnstableWarning')

pos = st.floats(1e-3, 10.0)
nonneg = st.floats(0.0, 100.0)
valid_params = st.builds(
    RotorParams, A_R=pos, A_M=pos, C_R=pos, C_M=pos, G=nonneg, s=st.floats(-0.2, 0.2),
    c_theta=nonneg, c_psi=nonneg, K_S=nonneg, K_D=st.floats(0.0, 10.0),
    Omega0=st.floats(-500.0, 500.0), pole_pairs=st.integers(0, 4))

states = st.tuples(st.floats(0.0, 3.0), st.floats(-5, 5), st.floats(-3, 3), st.floats(-5, 5),
                   st.floats(-3, 3), st.floats(-5, 5), st.floats(-3, 3), st.floats(-5, 5))


@settings(max_examples=200, deadline=None)
@given(p=valid_params, s=states)
def test_valid_parameters_give_a_finite_rhs(p, s):
    m = FullModel(p)
    th, thd, ps, psd, ph, phd, z, zd = s
    y = m.state_from_euler(theta=th, thetadot=thd, psi=ps, psidot=psd, phi_M=ph,
                           phi_M_dot=phd, z=z, zdot=zd)
    assert np.all(np.isfinite(m.rhs(0.0, y)))
    assert np.isfinite(m.energy(y))


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(p=valid_params)
def test_valid_parameters_keep_the_energy_balance(p):
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        scene = load_scene('upright', overrides={k: getattr(p, k) for k in PARAM_FIELDS})
    tr = simulate(scene, t_end=0.2, rate=20.0)
    scale = max(1.0, float(np.max(np.abs(tr.E_star))),
                float(np.max(np.abs(tr.out['dissipation']))) * 0.2)
    assert tr.max_abs_residual < 1e3 * tr.rtol * scale


bad_value = st.sampled_from([math.nan, math.inf, -math.inf, -1.0, 0.0, 'x', None, True])


@settings(max_examples=200, deadline=None)
@given(field=st.sampled_from(PARAM_FIELDS), value=bad_value)
def test_invalid_parameters_are_refused_naming_the_field(field, value):
    try:
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')
            RotorParams(**{field: value})
    except ParameterError as err:
        assert field in str(err)
    else:
        # only values that are valid for this field may pass: 0 for the non-negative
        # fields, -1 for signed ones (s, Omega0), 0 for pole_pairs
        assert (value == 0.0 and field in ('G', 's', 'c_theta', 'c_psi', 'K_S', 'K_D',
                                           'Omega0', 'pole_pairs')) or (
            value == -1.0 and field in ('s', 'Omega0'))


yaml_scalars = st.one_of(st.none(), st.booleans(), st.integers(-5, 5), st.floats(
    allow_nan=True, allow_infinity=True), st.text(max_size=8),
    st.lists(st.floats(-2, 2), max_size=5))
keys = st.one_of(st.sampled_from(sorted(SCENE_KEYS)), st.text(min_size=1, max_size=10))


@settings(max_examples=300, deadline=None)
@given(st.dictionaries(keys, yaml_scalars, max_size=6))
def test_any_scene_mapping_is_loaded_or_refused_cleanly(mapping):
    try:
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')
            scene_from_mapping(mapping, path='fuzz.yaml')
    except GyroRotorError as err:
        assert str(err)


@settings(max_examples=200, deadline=None, suppress_health_check=[
    HealthCheck.function_scoped_fixture])
@given(text=st.text(max_size=200))
def test_any_text_as_scene_file_is_refused_cleanly(tmp_path, text):
    f = tmp_path / 'fuzz.yaml'
    f.write_text('rotor_sim:\n  ros__parameters:\n' + text)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')
            load_scene(f)
    except GyroRotorError as err:
        assert str(err)


def test_real_scene_mutations_are_refused_cleanly(tmp_path):
    base = yaml.safe_load(open(load_scene('precession').path))
    body = next(iter(base.values()))['ros__parameters']        # ('/**': any node name)
    for key in list(body):
        for bad in ('text', [1, 2], None, -1e308):
            doc = {'rotor_sim': {'ros__parameters': {**body, key: bad}}}
            f = tmp_path / 'm.yaml'
            f.write_text(yaml.safe_dump(doc))
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter('ignore')
                    load_scene(f)
            except GyroRotorError as err:
                assert key in str(err) or key.split('.')[-1] in str(err) or 'initial' in str(err)


@pytest.fixture(scope='module')
def every_model():
    from gyro_rotor.core.scene import list_scenes
    return [(n, load_scene(n).make_model(), load_scene(n)) for n in list_scenes()]


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 2 ** 32 - 1))
def test_state_from_joints_inverts_joints(every_model, seed):
    """A state published as joints is rebuilt from them: same E* (every shipped model)."""
    rng = np.random.default_rng(seed)
    for name, model, scene in every_model:
        y = np.asarray(scene.initial_state(model), dtype=float).copy()
        y[:-1] += rng.normal(scale=0.05, size=len(y) - 1)
        if isinstance(model, FullModel):
            y[:4] /= np.linalg.norm(y[:4])
        y[model.idiss] = 0.0
        pos, vel, _, _ = model.joints(y[None, :], np.zeros((1, len(model.field_speeds()))))
        iz, izd = getattr(model, 'iz', None), getattr(model, 'izd', None)
        z, zdot = (y[iz], y[izd]) if iz is not None else (math.nan, math.nan)
        back = model.state_from_joints(pos[0], vel[0], z, zdot)
        if model.singular_joints(pos[0]) and model.joint_angles:
            continue
        assert back is not None, name
        E, E_back = (float(np.asarray(model.energy(v[None, :])).reshape(-1)[0]) for v in (y, back))
        assert E_back == pytest.approx(E, rel=1e-9, abs=1e-9), name
        pos2, vel2, _, _ = model.joints(back[None, :], np.zeros((1, len(model.field_speeds()))))
        d = pos2[0] - pos[0]
        if model.joint_angles:
            d = np.remainder(d + np.pi, 2 * np.pi) - np.pi
        assert np.abs(d).max() < 1e-9 and np.allclose(vel2[0], vel[0], rtol=1e-9, atol=1e-9), name
