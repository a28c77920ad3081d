"""General rotor systems (issue 15): system files, generated equations, scenes, claims, CLI."""

import math
import random

from gyro_rotor.cli.main import main
from gyro_rotor.core.model import FullModel
from gyro_rotor.core.params import RotorParams
from gyro_rotor.core.steady import steady_motion
from gyro_rotor.core.system.codegen import compile_system
from gyro_rotor.core.system.expression import parse_expression
from gyro_rotor.core.system.model import GeneralModel
from gyro_rotor.core.system.scene import list_general_scenes, load_general_scene
from gyro_rotor.core.system.system_file import list_systems, load_system, system_from_mapping
from gyro_rotor.errors import SystemFileError
from gyro_rotor.linear.general import check_claims, linearize_scene, modes
from gyro_rotor.linear.linearize import linearize
from gyro_rotor.linear.stability import check_claims as centrifuge_claims
from gyro_rotor.numerics.integrators.methods import integrate
from hypothesis import given, HealthCheck, settings, strategies as st
import numpy as np
import pytest
import sympy
import yaml

SHIPPED = ('centrifuge_euler', 'twin_gimbal', 'elastic_frame')
X, Y = sympy.Symbol('x', real=True), sympy.Symbol('k', real=True)
NAMES = {'x': X, 'k': Y}


def _doc(**changes):
    doc = {'name': 'osc', 'coordinates': ['x'], 'rotors': ['R'], 'constants': {'k': 2.0},
           'mass_matrix': [['1.0']], 'rotor_inertia': ['0.01'], 'guidance': [['1']],
           'potential': 'k*x**2/2', 'drives': [{'K_S': 1.0, 'K_D': 0.1, 'Omega0': 10.0}]}
    doc.update(changes)
    return doc


# -- the expression parser ---------------------------------------------------------------------
@pytest.mark.parametrize('text, expected', [
    ('k*x**2/2', Y * X ** 2 / 2), ('pi*x', sympy.pi * X), ('-x**2', -X ** 2),
    ('2**-1', sympy.Rational(1, 2)),
    ('sin(x) + cos(x)*tan(x) - exp(x)/log(k) + sqrt(k)',
     sympy.sin(X) + sympy.cos(X) * sympy.tan(X) - sympy.exp(X) / sympy.log(Y) + sympy.sqrt(Y)),
    ('1.5e-3*(x + 1)', sympy.Float(1.5e-3) * (X + 1)), (3, sympy.Integer(3)),
])
def test_parser_builds_the_expression(text, expected):
    assert sympy.simplify(parse_expression(text, NAMES, where='t') - expected) == 0


@pytest.mark.parametrize('text, match', [
    ("__import__('os').system('x')", 'unexpected character "\'" at column 12'),
    ('__import__(x)', "unknown name '__import__' at column 1"),
    ('x.real', "unexpected character '.'"),
    ('x^2', "powers are written '\\*\\*'"),
    ('y + 1', "unknown name 'y'"),
    ('1/0', 'not a finite real number'),
    ('x/0', 'division by zero'),
    ('log(-1)', 'not a finite real number'),
    ('sqrt(-4)', 'not a finite real number'),
    ('sqrt(pi - 4)', 'not a finite real number'),
    ('9**9**9', 'not a finite real number'),
    ('1e999', 'not finite'),
    ('sin(x', "expected '\\)'"),
    ('x x', "unexpected 'x'"),
    ('', 'empty expression'),
    ('(' * 100 + 'x' + ')' * 100, 'nested more than'),
    ('lambda: 0', "unexpected character ':'"),
    ([1], 'expected an expression'),
])
def test_parser_refuses_with_column_and_text(text, match):
    with pytest.raises(SystemFileError, match=match) as err:
        parse_expression(text, NAMES, where='system file f.yaml: potential')
    assert 'system file f.yaml: potential' in str(err.value)


TOKENS = st.sampled_from(['x', 'k', 'y', '1', '2.5', '1e3', '0', '+', '-', '*', '/', '**', '(',
                          ')', 'sin(', 'cos(', 'tan(', 'exp(', 'log(', 'sqrt(', ' ', '.', '^',
                          '_', 'import', ',', '"', '[', '9**9**9'])


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(st.lists(TOKENS, max_size=25).map(''.join), st.text(max_size=40)))
def test_random_text_gives_clean_refusal_or_valid_system(text):
    try:
        system = system_from_mapping(_doc(potential=text), 'random.yaml')
    except SystemFileError as err:
        assert 'random.yaml' in str(err)
        return
    V = system.potential
    assert V.free_symbols <= set(system.q_symbols()) | set(system.constant_symbols())
    assert not V.has(sympy.zoo, sympy.nan, sympy.oo, sympy.I)


# -- the system file -------------------------------------------------------------------------
@pytest.mark.parametrize('changes, match', [
    ({'mass_matrix': [['1', '0']]}, r'mass_matrix\[0\] \(row 0\) must be a list of 1'),
    ({'mass_matrix': [['1'], ['1']]}, 'mass_matrix must be a list of 1 rows, got 2'),
    ({'coordinates': ['x', 'w'], 'mass_matrix': [['1', 'x'], ['0', '1']],
      'guidance': [['1', '0']]}, "not symmetric: row 0, column 1 is 'x'"),
    ({'mass_matrix': [['1 + q']]}, r'mass_matrix\[0\]\[0\] \(row 0, column 0\): unknown '
                                   r"name 'q' at column 5 of '1 \+ q'"),
    ({'guidance': [['1'], ['0']]}, 'guidance must be a list of 1 rows'),
    ({'guidance': [['1', '0']]}, r'guidance\[0\] \(row 0\) must be a list of 1'),
    ({'rotor_inertia': ['1', '2']}, 'rotor_inertia must be a list of 1 entries'),
    ({'rotor_inertia': ['x']}, "rotor_inertia\\[0\\]: unknown name 'x'"),
    ({'rotor_inertia': ['-1']}, 'must be a positive number'),
    ({'drives': []}, 'drives must be a list of 1 entries'),
    ({'drives': [{'K_S': 1.0, 'K_D': 0.1}]}, r'drives\[0\]: Omega0 is missing'),
    ({'drives': [{'K_S': 1.0, 'K_D': -0.1, 'Omega0': 1.0}]}, 'must not be negative'),
    ({'drives': [{'K_S': 1.0, 'K_D': 0.1, 'Omega0': 1.0, 'pole_pairs': 1.5}]}, 'pole_pairs'),
    ({'drives': [{'K_S': 1.0, 'KD': 0.1, 'Omega0': 1.0}]}, "did you mean 'K_D'"),
    ({'potentail': 'x'}, "unknown key 'potentail'; did you mean 'potential'"),
    ({'rotors': []}, 'at least 1 name'),
    ({'coordinates': ['x', 'x']}, 'appears twice'),
    ({'coordinates': ['sin']}, 'reserved'),
    ({'constants': {'k': 'two'}}, 'constants.k: expected a number'),
    ({'constants': {'x': 1.0}}, "the name 'x' is used twice"),
])
def test_bad_system_file_names_key_and_text(changes, match):
    with pytest.raises(SystemFileError, match=match) as err:
        system_from_mapping(_doc(**changes), 'bad.yaml')
    assert 'system file bad.yaml' in str(err.value)


def test_missing_key_is_named():
    doc = _doc()
    del doc['potential']
    with pytest.raises(SystemFileError, match='the key potential is missing'):
        system_from_mapping(doc, 'bad.yaml')


def test_shipped_systems_and_scenes_load():
    assert set(SHIPPED) <= set(list_systems())
    assert set(SHIPPED) <= set(list_general_scenes())
    for name in SHIPPED:
        assert load_general_scene(name).system.name == name


# -- generated equations vs Lagrange by finite differences (eq. 4) ----------------------------
def _lagrange_fd(system, y):
    """Return vdot from L = T - V by central differences, from M, A, B, V alone (eq. 4)."""
    n, m = system.n, system.m
    q_s, c_s = system.q_symbols(), system.constant_symbols()
    args = list(q_s) + list(c_s)
    Mf = sympy.lambdify(args, system.mass_matrix.tolist(), 'math')
    Bf = sympy.lambdify(args, system.guidance.tolist(), 'math')
    Af = sympy.lambdify(args, list(system.rotor_inertia), 'math')
    Vf = sympy.lambdify(args, system.potential, 'math')
    consts = list(system.constants.values())
    Om = np.array([d.Omega0 for d in system.drives])

    def L(x, v):
        q, qd, zd = x[:n], v[:n], v[n:]
        M = np.array(Mf(*q, *consts), dtype=float).reshape(n, n)
        B = np.array(Bf(*q, *consts), dtype=float).reshape(m, n)
        A = np.array(Af(*q, *consts), dtype=float)
        w = zd + Om + B @ qd
        return 0.5 * qd @ M @ qd + 0.5 * w @ (A * w) - Vf(*q, *consts)
    N = n + m
    x = np.concatenate([y[:n], y[2 * n:2 * n + m]])
    v = np.concatenate([y[n:2 * n], y[2 * n + m:2 * n + 2 * m]])
    h = 2e-3

    def grad(f, z, i):
        e = np.zeros(N)
        e[i] = h
        return (f(z + e) - f(z - e)) / (2 * h)
    dLdx = np.array([grad(lambda s: L(s, v), x, i) for i in range(N)])
    Hvv = np.array([[grad(lambda s: grad(lambda u: L(x, u), s, i), v, j) for j in range(N)]
                    for i in range(N)])
    Hvx = np.array([[grad(lambda s: grad(lambda u: L(s, u), v, i), x, j) for j in range(N)]
                    for i in range(N)])
    Q = np.zeros(N)
    for k, d in enumerate(system.drives):
        Q[n + k] = -d.K_S * x[n + k] - d.K_D * v[n + k]
    return np.linalg.solve(Hvv, dLdx + Q - Hvx @ v)


@pytest.mark.parametrize('name', SHIPPED)
def test_generated_equations_match_finite_difference_lagrange(name):
    system = load_system(name)
    model = GeneralModel(system)
    rng = random.Random(1)
    n, m = system.n, system.m
    for _ in range(3):
        y = np.array([rng.uniform(0.2, 0.8) for _ in range(n)]
                     + [rng.uniform(-1, 1) for _ in range(n)]
                     + [rng.uniform(-0.5, 0.5) for _ in range(m)]
                     + [rng.uniform(-2, 2) for _ in range(m)] + [0.0])
        f = model.rhs(0.0, y)
        gen = np.concatenate([f[n:2 * n], f[2 * n + m:2 * n + 2 * m]])
        fd = _lagrange_fd(system, y)
        assert np.allclose(gen, fd, rtol=1e-5, atol=1e-5 * np.abs(fd).max()), (gen, fd)


@pytest.mark.parametrize('name', SHIPPED)
def test_residual_and_conservation(name):
    scene = load_general_scene(name)
    model = scene.make_model()
    te = np.linspace(0.0, 2.0, 201)
    y0 = scene.initial_state(model)
    run = model.integrate(y0, te, rtol=1e-11, atol=1e-13)
    E0 = model.energy(y0)
    assert run.y[-1, -1] > 1e-6 * E0                     # the drives did dissipate
    assert np.abs(model.residual(run.y)).max() < 1e-8 * E0
    cons = scene.with_drives(K_D=0.0).make_model()
    run0 = cons.integrate(y0, te, rtol=1e-11, atol=1e-13)
    E = cons.energy(run0.y)
    assert np.abs(E - E[0]).max() < 1e-8 * E0
    assert run0.y[-1, -1] == 0.0


# -- centrifuge_euler against the quaternion model ----------------------------------------------
def test_centrifuge_euler_agrees_with_quaternion_model():
    model = GeneralModel(load_system('centrifuge_euler'))
    full = FullModel(RotorParams())
    e = {'theta': 0.4, 'thetadot': 0.3, 'psi': 0.1, 'psidot': 1.5, 'phi_M': 0.2,
         'phi_M_dot': -0.7, 'z': 0.05, 'zdot': 0.4}
    y0 = model.state([e['theta'], e['psi'], e['phi_M']],
                     [e['thetadot'], e['psidot'], e['phi_M_dot']], [e['z']], [e['zdot']])
    run = model.integrate(y0, [0.0, 2.0], rtol=1e-13, atol=1e-14)
    ref = integrate(full, full.state_from_euler(**e), (0.0, 2.0), [0.0, 2.0], method='dop853',
                    rtol=1e-13, atol=1e-14)
    y = run.y[-1]
    mapped = full.state_from_euler(theta=y[0], thetadot=y[3], psi=y[1], psidot=y[4],
                                   phi_M=y[2], phi_M_dot=y[5], z=y[6], zdot=y[7])
    assert np.abs(mapped[:9] - ref.y[-1][:9]).max() < 1e-9
    assert abs(y[-1] - ref.y[-1][-1]) < 1e-9


def test_centrifuge_euler_eigenvalues_and_K_D_star_match_quaternion_checker():
    scene = load_general_scene('centrifuge_euler')
    lin = linearize_scene(scene)
    p = RotorParams()
    ref = linearize(p, steady_motion(p, 0.1, 1))
    lam_ref = np.linalg.eigvals(ref.with_K_D(p.K_D))
    lam = np.array([x.value for x in modes(lin)])
    scale = np.abs(lam_ref).max()
    big = lambda v: np.sort_complex(v[np.abs(v) > 1e-6 * scale])  # noqa: E731
    assert len(big(lam)) == len(big(lam_ref)) == 6
    assert np.abs(big(lam) - big(lam_ref)).max() <= 1e-9 * scale
    claims = check_claims(lin)
    star = centrifuge_claims(ref).K_D_star
    assert len(claims.meetings) == 1
    assert abs(claims.meetings[0].K_star - star) <= 1e-7 * star


# -- the claims -------------------------------------------------------------------------------
@pytest.mark.parametrize('name', SHIPPED)
def test_claims_hold_on_every_shipped_system(name):
    lin = linearize_scene(load_general_scene(name))
    claims = check_claims(lin)
    assert (claims.a, claims.b, claims.c, claims.d) == (True, True, True, True), claims.details
    assert len(claims.meetings) >= lin.m
    assert all(x.bracket <= 1e-8 and x.point < 0 for x in claims.meetings)


def test_claims_fail_on_a_statically_unstable_system(tmp_path):
    """A check that can fail: V = -k x^2/2 has a real root pair at K_D = 0."""
    path = _write_scene(tmp_path, _doc(potential='-k*x**2/2'), {})
    claims = check_claims(linearize_scene(load_general_scene(path)))
    assert not claims.a and not claims.b


def _write_scene(tmp_path, system_doc, params):
    (tmp_path / 'sys.yaml').write_text(yaml.safe_dump(system_doc))
    scene = {'rotor_sim': {'ros__parameters': {'system': 'sys.yaml', **params}}}
    path = tmp_path / 'scene.yaml'
    path.write_text(yaml.safe_dump(scene))
    return str(path)


def test_unreachable_mode_is_reported_marginal_and_named(tmp_path, capsys):
    doc = _doc(coordinates=['x', 'w'], constants={'k': 2.0, 'c_w': 3.0},
               mass_matrix=[['1.0', '0'], ['0', '0.5']], guidance=[['1', '0']],
               potential='k*x**2/2 + c_w*w**2/2')
    path = _write_scene(tmp_path, doc, {})
    lin = linearize_scene(load_general_scene(path))
    un = [x for x in modes(lin) if not x.reached]
    assert len(un) == 2 and all('unreached mode (w)' == x.name for x in un)
    assert all(abs(x.value.real) < 1e-12 and abs(abs(x.value.imag) - math.sqrt(6.0)) < 1e-9
               for x in un)
    claims = check_claims(lin)
    assert claims.b and len(claims.details['unreached']) == 2
    out = tmp_path / 'eig.json'
    assert main(['eig', path, '--json', str(out)]) == 0
    assert 'unreached mode (w)' in capsys.readouterr().out


def test_locked_scene_is_the_rotor_on_its_drive(tmp_path):
    path = _write_scene(tmp_path, _doc(), {'locked': ['x']})
    scene = load_general_scene(path)
    assert scene.system.n == 0
    lam = np.sort_complex(np.linalg.eigvals(linearize_scene(scene).A_scene()))
    C, K_S, K_D = 0.01, 1.0, 0.1
    expected = np.sort_complex(np.roots([C, K_D, K_S]))
    assert np.abs(lam - expected).max() < 1e-12 * abs(expected).max()


def test_compile_cache_is_reused(tmp_path, monkeypatch):
    import gyro_rotor.core.system.codegen as codegen
    monkeypatch.setenv('GYRO_ROTOR_CACHE', str(tmp_path))
    monkeypatch.setattr(codegen, '_LOADED', {})
    system = system_from_mapping(_doc(), 'osc.yaml')
    first = compile_system(system)
    monkeypatch.setattr(codegen, '_LOADED', {})
    second = compile_system(system.with_constants({'k': 5.0}))
    assert (first.from_cache, second.from_cache) == (False, True)
    assert first.path == second.path and str(tmp_path) in str(first.path)


# -- the command line ----------------------------------------------------------------------------
def test_simulate_writes_the_csv_columns(tmp_path, capsys):
    out = tmp_path / 'tg.csv'
    assert main(['simulate', 'twin_gimbal', '--t-end', '0.5', '--rate', '20', '--out',
                 str(out), '--set', 'drive.R1.K_D=0.1']) == 0
    head = out.read_text().splitlines()
    assert head[0] == ('t,alpha,alpha_dot,beta1,beta1_dot,beta2,beta2_dot,z_R1,zdot_R1,'
                       'z_R2,zdot_R2,E_star,residual')
    assert len(head) == 12
    assert 'max |residual|' in capsys.readouterr().out


def test_locus_json_has_K_D_star_and_claims(tmp_path):
    import json
    out = tmp_path / 'l.json'
    assert main(['locus', 'twin_gimbal', '--json', str(out), '--points', '20']) == 0
    doc = json.loads(out.read_text())
    assert len(doc['K_D_star']) == 2 and doc['claims'] == dict.fromkeys('abcd', True)


@pytest.mark.parametrize('params, match', [
    ({'initial': {'q': [0.1, 0.2]}}, r'initial.q must have 1 entries \(one per coordinate: x\)'),
    ({'initial': {'zdot': [0.1, 0.2]}}, 'initial.zdot must have 1 entries'),
    ({'locked': ['y']}, "locked\\[0\\] = 'y' is not a coordinate"),
    ({'steady': {'q': [0.3]}}, 'not a steady motion: the accelerations do not vanish there '
                               r'\(x_ddot = -0.6'),
    ({'constants': {'kk': 1.0}}, "unknown constant 'kk'"),
    ({'drive': {'R9': {'K_D': 1.0}}}, "unknown key 'drive.R9.K_D'"),
    ({'K_D': 1}, 'must be written as a float'),
    ({'bogus': 1.0}, "unknown key 'bogus'"),
])
def test_bad_scene_is_one_error_line(tmp_path, capsys, params, match):
    path = _write_scene(tmp_path, _doc(), params)
    assert main(['simulate', path, '--t-end', '0.1']) == 1
    err = capsys.readouterr().err
    assert err.startswith('ERROR: ') and err.count('\n') == 1 and 'Traceback' not in err
    assert __import__('re').search(match, err), err


def test_bad_system_file_via_cli_is_one_error_line(tmp_path, capsys):
    path = _write_scene(tmp_path, _doc(potential='k*x^2'), {})
    assert main(['eig', path]) == 1
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and "potential: unexpected character '^'" in err
    assert 'sys.yaml' in err


def test_steady_command_solves_from_a_guess(tmp_path, capsys):
    doc = _doc(potential='k*(x - 0.25)**2/2')
    path = _write_scene(tmp_path, doc, {})
    assert main(['steady', path]) == 0
    assert 'q = [0.25' in capsys.readouterr().out


def test_campbell_marks_critical_speeds(tmp_path, capsys):
    import json
    out = tmp_path / 'c.json'
    assert main(['campbell', 'twin_gimbal', '--points', '60', '--json', str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc['critical_speeds'] and len(doc['frequencies_hz']) == 60
    assert main(['campbell', 'precession']) == 1


def test_expression_undefined_at_the_state_is_one_error_line(tmp_path, capsys):
    path = _write_scene(tmp_path, _doc(mass_matrix=[['1 + sqrt(x)']]),
                        {'initial': {'q': [-1.0]}})
    assert main(['simulate', path]) == 1
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and 'not defined at q = [-1.0]' in err


def test_singular_coordinates_are_refused(capsys):
    assert main(['simulate', 'centrifuge_euler', '--set', 'initial.q=[0.0, 0.0, 0.0]']) == 1
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and 'not positive definite at the initial state' in err
