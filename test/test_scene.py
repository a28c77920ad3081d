"""Scenes: every shipped scene loads; bad scene files give clear errors."""

from gyro_rotor.core.scene import list_scenes, load_scene, perturb_state
from gyro_rotor.errors import ParameterError, SceneError
import pytest

SHIPPED = ['precession', 'nutation', 'upright', 'stiff_drive', 'fast_spin', 'conservative',
           'pole_slip', 'locked_housing']


def test_all_required_scenes_ship():
    assert set(SHIPPED) <= set(list_scenes())


@pytest.mark.parametrize('name', SHIPPED)
def test_scene_loads_and_is_statically_stable(name):
    s = load_scene(name)
    assert s.system.params.c_theta > s.system.params.G * s.system.params.s
    assert s.initial_state().shape == (s.make_model().n,)


def test_scene_specifics():
    assert load_scene('fast_spin').system.params.Omega0 == 3141.6
    assert load_scene('conservative').system.params.K_D == 0.0
    assert load_scene('pole_slip').system.params.pole_pairs > 0
    assert load_scene('locked_housing').system.model == 'locked_housing'
    assert load_scene('nutation').system.initial.branch == 2
    assert load_scene('upright').system.initial.branch == 0


def write(tmp_path, body, name='s.yaml'):
    f = tmp_path / name
    f.write_text(body)
    return f


HEAD = 'rotor_sim:\n  ros__parameters:\n'


@pytest.mark.parametrize('body, match', [
    (HEAD + '    K_d: 0.1\n', "unknown key 'K_d'; did you mean 'K_D'"),
    (HEAD + '    initial:\n      brnch: 1\n', "did you mean 'initial.branch'"),
    (HEAD + '    G: 98\n', 'written as a float'),
    (HEAD + '    K_S: fast\n', 'K_S must be a number'),
    (HEAD + '    model: rigid\n', "unknown model 'rigid'"),
    (HEAD + '    t_end: -1.0\n', 't_end must be positive'),
    (HEAD + '    initial:\n      mode: wobble\n', 'initial.mode'),
    (HEAD + '    initial:\n      mode: body\n      quaternion: [1.0, 0.0]\n', '4 numbers'),
    (HEAD + '    initial:\n      mode: body\n      theta0: 0.1\n', 'belongs to initial.mode'),
    (HEAD + '    pole_pairs: 1.5\n', 'pole_pairs must be written as an integer'),
    ('rotor_sim: [1, 2\n', 'not valid YAML'),
    ('other_node:\n  ros__parameters: {}\n', 'no rotor_sim'),
    ('- 1\n- 2\n', 'expected a mapping'),
])
def test_bad_scene_files(tmp_path, body, match):
    with pytest.raises(SceneError, match=match):
        load_scene(write(tmp_path, body))


def test_bad_parameter_in_file_names_field_and_file(tmp_path):
    f = write(tmp_path, HEAD + '    C_M: -0.01\n')
    with pytest.raises(ParameterError, match=r's\.yaml.*C_M.*-0\.01'):
        load_scene(f)


def test_missing_scene_and_typo():
    with pytest.raises(SceneError, match="did you mean 'precession'"):
        load_scene('precesion')
    with pytest.raises(SceneError, match='does not exist'):
        load_scene('/nonexistent/scene.yaml')


def test_body_mode_scene(tmp_path):
    f = write(tmp_path, HEAD + '    initial:\n      mode: body\n'
              '      quaternion: [2.0, 0.0, 0.0, 0.0]\n      omega_body: [0.1, 0.0, 0.0]\n'
              '      zdot: 0.5\n')
    s = load_scene(f)
    y = s.initial_state()
    assert y[0] == pytest.approx(1.0) and y[4] == 0.1 and y[8] == 0.5


def test_perturbation_kick():
    s = load_scene('upright')
    m = s.make_model()
    y = s.initial_state(m)
    y2 = perturb_state(m, y, {'dzdot': 1.0})
    assert y2[8] == pytest.approx(y[8] + 1.0)
    with pytest.raises(SceneError, match='perturbation.dzdott'):
        perturb_state(m, y, {'dzdott': 1.0})


def test_twist_kick_beyond_pi_moves_chi_by_exactly_dchi():
    """Regression (review): a hemisphere flip of q used to shift chi by 2 pi."""
    s = load_scene('precession')
    m = s.make_model()
    y = s.initial_state(m)
    chi0 = m.chi(y[None])[0]
    y2 = perturb_state(m, y, {'dchi': 4.0})
    assert m.chi(y2[None])[0] == pytest.approx(chi0 + 4.0)


def test_kick_at_theta_zero_keeps_the_transverse_spin():
    """Regression (review): at sin(theta) = 0 the Euler rates lose W_1, W_2."""
    import numpy as np
    s = load_scene('upright')
    m = s.make_model()
    y = np.array([1, 0, 0, 0, 0.3, 0.4, 1.0, 0, 0, 0], dtype=float)
    assert np.array_equal(perturb_state(m, y, {})[4:7], y[4:7])
    y2 = perturb_state(m, y, {'dthetadot': 0.05, 'dzdot': 1.0})
    assert np.allclose(y2[4:7], [0.35, 0.4, 1.0]) and y2[8] == 1.0


def test_body_quaternion_sign_is_the_smaller_twist(tmp_path):
    f = write(tmp_path, HEAD + '    initial:\n      mode: body\n'
              '      quaternion: [-1.0, 0.0, 0.0, 0.0]\n')
    s = load_scene(f)
    y = s.initial_state()
    assert y[0] == 1.0
    assert s.make_model().energy(y) == pytest.approx(s.system.params.G * s.system.params.s)
    f = write(tmp_path, HEAD + '    initial:\n      mode: body\n'
              '      quaternion: [-1.0, 0.0, 0.0, 0.0]\n      chi: 6.283185307179586\n', 'c.yaml')
    assert load_scene(f).initial_state()[0] == -1.0


def test_typed_file_refusals(tmp_path):
    with pytest.raises(SceneError, match='pole_pairs must be written as an integer'):
        load_scene(write(tmp_path, HEAD + '    pole_pairs: 2.0\n'))
    f = tmp_path / 'latin1.yaml'
    f.write_bytes(HEAD.encode() + b'    description: "K\xf6nig"\n')
    with pytest.raises(SceneError, match='cannot read scene file'):
        load_scene(f)
    with pytest.raises(ParameterError, match='supported range'):
        load_scene('precession', overrides={'Omega0': 1e200})


def test_both_kinds_of_system_offer_what_a_scene_asks_of_its_system():
    """Scene asks its system (issue 25): the centrifuge and a system file's answer alike.

    Every ``self.system.NAME`` in Scene's source must exist on both classes, except the
    copies that only make sense for one kind (parameters of the centrifuge, drives of a
    system file).
    """
    import inspect
    import re
    from gyro_rotor.core.scene import Centrifuge, GeneratedSystem, Scene
    asked = set(re.findall(r'self\.system\.(\w+)', inspect.getsource(Scene)))
    assert {'make_model', 'initial_state', 'document_parts', 'live_scene'} <= asked
    one_kind = {'with_params', 'with_drives', 'drives'}
    for cls in (Centrifuge, GeneratedSystem):
        missing = sorted(asked - one_kind - set(dir(cls)))
        assert not missing, f'{cls.__name__} lacks {missing}'
    for name in ('precession', 'twin_gimbal'):
        scene = load_scene(name)
        assert scene.physics()[0] == ('system', scene.system_name)
        assert scene.with_changes({'t_end': 3.0}).t_end == 3.0


def test_with_changes_takes_what_rotor_sim_may_override_at_start():
    """Issue 25: rotor_sim builds every scene with with_changes, the centrifuge's as well.

    The same scene as its file with those values; another initial.mode drops the keys of the
    old one; a refusal names the scene, not its file.
    """
    base = load_scene('precession')
    changed = base.with_changes({'K_D': 0.2, 'initial.theta0': 0.3, 'perturbation.dz': 0.1})
    assert changed == load_scene('precession', {'K_D': 0.2, 'initial.theta0': 0.3,
                                                'perturbation.dz': 0.1})
    body = base.with_changes({'initial.mode': 'body'})
    assert body.system.initial.mode == 'body' and body.system.initial.theta0 == 0.0
    with pytest.raises(ParameterError, match='^scene precession: parameter K_D must not'):
        base.with_changes({'K_D': -1.0})
    twin = load_scene('twin_gimbal')
    assert twin.with_changes({'drive.R1.K_D': 0.2}) == load_scene('twin_gimbal',
                                                                  {'drive.R1.K_D': 0.2})


def test_parameter_specs_are_scene_keys_of_their_system():
    """Every parameter a system gives rotor_sim is a key of its scene, of the key's type."""
    from gyro_rotor.core.scene import SCENE_KEYS, SYSTEM_SCENE_KEYS
    for name in list_scenes():
        scene = load_scene(name)
        given = {}
        for spec in scene.system.parameter_specs(scene, given):
            given[spec.key] = spec.default
            assert isinstance(spec.default, spec.typ), spec
            assert spec.kick == spec.key.startswith('perturbation.'), spec
            if scene.builtin:
                assert SCENE_KEYS[spec.key] is spec.typ, spec
            elif not spec.key.startswith(('constants.', 'drive.')):
                assert SYSTEM_SCENE_KEYS[spec.key] is spec.typ, spec
        assert [k for k in given if k == 'system'] == ['system']


def test_a_system_file_given_as_a_scene_is_named_as_such():
    """Adversarial finding: it said 'no rotor_sim (or /**) section; found name, ...'."""
    from pathlib import Path
    path = Path(__file__).resolve().parent.parent / 'config' / 'systems' / 'twin_gimbal.yaml'
    with pytest.raises(SceneError, match='is a system file, not a scene file: give its name'):
        load_scene(str(path))


@pytest.mark.parametrize('system', ['', 'system: twin_gimbal\n    '])
def test_a_value_where_a_group_of_keys_belongs_is_named(tmp_path, system):
    """Adversarial finding: 'initial: 5' gave "unknown key 'initial'; did you mean ...?"."""
    path = tmp_path / 'scene.yaml'
    path.write_text(f'/**:\n  ros__parameters:\n    {system}initial: 5\n')
    with pytest.raises(SceneError, match="'initial' is a group of keys, not a value"):
        load_scene(str(path))
