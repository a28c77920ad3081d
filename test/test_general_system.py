"""General rotor systems (issue 15): system files, generated equations, scenes, claims, CLI."""

import math
import random
import re

from gyro_rotor.cli.main import main
from gyro_rotor.core.linearize import linearize
from gyro_rotor.core.model import FullModel
from gyro_rotor.core.params import RotorParams
from gyro_rotor.core.scene import list_scenes, load_scene
from gyro_rotor.core.steady import steady_motion
from gyro_rotor.core.system.codegen import compile_system
from gyro_rotor.core.system.expression import parse_expression
from gyro_rotor.core.system.model import GeneralModel
from gyro_rotor.core.system.system_file import list_systems, load_system, system_from_mapping
from gyro_rotor.errors import NotSteadyError, ParameterError, SystemFileError
from gyro_rotor.linear.stability import ModeKind
from gyro_rotor.linear.system import (assess, check_claims, from_analytic, linearize_scene,
                                      modes)
from gyro_rotor.numerics.ensemble import run_ensemble
from gyro_rotor.numerics.integrators.methods import integrate
from gyro_rotor.numerics.simulate import integrate as integrate_general
from hypothesis import example, given, HealthCheck, settings, strategies as st
import numpy as np
import pytest
from random_systems import random_system_file
import sympy
import yaml

SHIPPED = ('centrifuge_euler', 'twin_gimbal', 'elastic_frame')


def _errors(err: str) -> str:
    """Return stderr without the first-use notes of code generation (lines 'gyro_rotor: ').

    A system whose equations are not cached yet says what it generates (adversarial finding
    14); a test's cache may be cold (a fresh machine), so the one ERROR line is what is left.
    """
    return ''.join(x for x in err.splitlines(keepends=True) if not x.startswith('gyro_rotor: '))


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


# where the random text goes: the key, its place in the document, how to read it back
PLACES = {'potential': (lambda t: {'potential': t}, lambda s: s.potential),
          'mass_matrix': (lambda t: {'mass_matrix': [[t]]}, lambda s: s.mass_matrix[0, 0]),
          'guidance': (lambda t: {'guidance': [[t]]}, lambda s: s.guidance[0, 0]),
          'rotor_inertia': (lambda t: {'rotor_inertia': [t]}, lambda s: s.rotor_inertia[0])}


@settings(max_examples=600, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(st.lists(TOKENS, max_size=25).map(''.join), st.text(max_size=40)),
       st.sampled_from(sorted(PLACES)))
def test_random_text_gives_clean_refusal_or_valid_system(text, place):
    put, get = PLACES[place]
    try:
        system = system_from_mapping(_doc(**put(text)), 'random.yaml')
    except SystemFileError as err:
        assert 'random.yaml' in str(err) and place in str(err)
        return
    e = get(system)
    assert e.free_symbols <= set(system.q_symbols()) | set(system.constant_symbols())
    assert not e.has(sympy.zoo, sympy.nan, sympy.oo, sympy.I)


# -- the system file -------------------------------------------------------------------------
# every bad system file: (changes, the fragments the one ERROR line must hold: the key, the
# row/column or index, the offending text)
BAD_SYSTEM_FILES = [
    ({'mass_matrix': [['1', '0']]},
     ['mass_matrix[0] (row 0) must be a list of 1 entries', "['1', '0']"]),
    ({'mass_matrix': [['1'], ['1']]},
     ['mass_matrix must be a list of 1 rows, got 2', "[['1'], ['1']]"]),
    ({'mass_matrix': '1'}, ['mass_matrix must be a list of 1 rows', "'1'"]),
    ({'coordinates': ['x', 'w'], 'mass_matrix': [['1', 'x'], ['0', '1']],
      'guidance': [['1', '0']]},
     ['mass_matrix is not symmetric', "row 0, column 1 is 'x'", "row 1, column 0 is '0'"]),
    ({'mass_matrix': [['1 + q']]},
     ['mass_matrix[0][0] (row 0, column 0)', "unknown name 'q' at column 5", "'1 + q'"]),
    ({'guidance': [['1'], ['0']]}, ['guidance must be a list of 1 rows', "[['1'], ['0']]"]),
    ({'guidance': [['1', '0']]}, ['guidance[0] (row 0) must be a list of 1', "['1', '0']"]),
    ({'guidance': [['foo(x)']]},
     ['guidance[0][0] (row 0, column 0)', "unknown name 'foo' at column 1", "'foo(x)'"]),
    ({'rotor_inertia': ['1', '2']}, ['rotor_inertia must be a list of 1 entries', "['1', '2']"]),
    ({'rotor_inertia': ['x']}, ['rotor_inertia[0]', "unknown name 'x' at column 1"]),
    ({'rotor_inertia': ['-1']}, ["rotor_inertia[0] = '-1'", 'must be a positive number']),
    ({'potential': 'k*x^2'},
     ['potential', "unexpected character '^'", 'at column 4', "'k*x^2'"]),
    ({'potential': "__import__('os')"},
     ['potential', 'unexpected character "\'" at column 12', "__import__('os')"]),
    ({'potential': 'k*x**2/2 + eval(x)'},
     ['potential', "unknown name 'eval' at column 12", "'k*x**2/2 + eval(x)'"]),
    ({'potential': 'x.real'}, ['potential', "unexpected character '.' at column 2"]),
    ({'potential': 'sin(x'}, ['potential', "expected ')'", "'sin(x'"]),
    ({'drives': []}, ['drives must be a list of 1 entries', 'got 0: []']),
    ({'drives': [{'K_S': 1.0, 'K_D': 0.1}]}, ['drives[0]: Omega0 is missing']),
    ({'drives': [{'K_S': 1.0, 'K_D': -0.1, 'Omega0': 1.0}]},
     ['drives[0]', 'must not be negative', 'K_D = -0.1']),
    ({'drives': [{'K_S': 1.0, 'K_D': 0.1, 'Omega0': 1.0, 'pole_pairs': 1.5}]},
     ['drives[0].pole_pairs', 'got 1.5']),
    ({'drives': [{'K_S': 1.0, 'KD': 0.1, 'Omega0': 1.0}]},
     ["drives[0]: unknown key 'KD'", "did you mean 'K_D'"]),
    ({'drives': [{'K_S': 'x', 'K_D': 0.1, 'Omega0': 1.0}]}, ['drives[0].K_S', "'x'"]),
    ({'potentail': 'x'}, ["unknown key 'potentail'", "did you mean 'potential'"]),
    ({'rotors': []}, ['rotors: at least 1 name']),
    ({'coordinates': ['x', 'x']}, ['coordinates[1]', "'x' appears twice"]),
    ({'coordinates': ['sin']}, ['coordinates[0]', "'sin' is reserved"]),
    ({'coordinates': 'x'}, ['coordinates: expected a list of names', "'x'"]),
    ({'constants': {'k': 'two'}}, ['constants.k: expected a number', "'two'"]),
    ({'constants': {'k': 2.0, 'x': 1.0}}, ["the name 'x' is in coordinates and in constants"]),
    ({'rotors': ['x']}, ["the name 'x' is in rotors and in coordinates"]),
    ({'name': 'a b'}, ['name must be a name', "'a b'"]),
]


@pytest.mark.parametrize('changes, fragments', BAD_SYSTEM_FILES)
def test_bad_system_file_is_one_error_line_naming_file_key_and_text(tmp_path, capsys, changes,
                                                                    fragments):
    path = _write_scene(tmp_path, _doc(**changes), {})
    assert main(['eig', path]) == 1
    err = _errors(capsys.readouterr().err)
    assert err.startswith('ERROR: ') and err.count('\n') == 1 and 'Traceback' not in err
    assert f'system file {tmp_path / "sys.yaml"}:' in err, err
    for fragment in fragments:
        assert fragment in err, (fragment, err)


@pytest.mark.parametrize('key', ['name', 'coordinates', 'rotors', 'constants', 'mass_matrix',
                                 'rotor_inertia', 'guidance', 'potential', 'drives'])
def test_missing_key_is_named(tmp_path, capsys, key):
    doc = _doc()
    del doc[key]
    with pytest.raises(SystemFileError, match=f'the key {key} is missing'):
        system_from_mapping(doc, 'bad.yaml')
    path = _write_scene(tmp_path, doc, {})
    assert main(['simulate', path]) == 1
    err = _errors(capsys.readouterr().err)
    assert err.count('\n') == 1 and f'sys.yaml: the key {key} is missing' in err


def test_shipped_systems_and_scenes_load():
    assert set(SHIPPED) <= set(list_systems())
    assert set(SHIPPED) <= set(list_scenes(builtin=False))
    for name in SHIPPED:
        assert load_scene(name).system.name == name


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
    scene = load_scene(name)
    model = scene.make_model()
    te = np.linspace(0.0, 2.0, 201)
    y0 = scene.initial_state(model)
    run = integrate_general(model, y0, te, rtol=1e-11, atol=1e-13)
    E0 = model.energy(y0)
    assert run.y[-1, -1] > 1e-6 * E0                     # the drives did dissipate
    assert np.abs(model.residual(run.y)).max() < 1e-8 * E0
    cons = scene.with_drives(K_D=0.0).make_model()
    run0 = integrate_general(cons, y0, te, rtol=1e-11, atol=1e-13)
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
    run = integrate_general(model, y0, [0.0, 2.0], method='dop853', rtol=1e-13, atol=1e-14)
    ref = integrate(full, full.state_from_euler(**e), (0.0, 2.0), [0.0, 2.0], method='dop853',
                    rtol=1e-13, atol=1e-14)
    y = run.y[-1]
    mapped = full.state_from_euler(theta=y[0], thetadot=y[3], psi=y[1], psidot=y[4],
                                   phi_M=y[2], phi_M_dot=y[5], z=y[6], zdot=y[7])
    assert np.abs(mapped[:9] - ref.y[-1][:9]).max() < 1e-9
    assert abs(y[-1] - ref.y[-1][-1]) < 1e-9


def test_centrifuge_euler_eigenvalues_and_K_D_star_match_quaternion_checker():
    scene = load_scene('centrifuge_euler')
    lin = linearize_scene(scene)
    p = RotorParams()
    ref = linearize(p, steady_motion(p, 0.1, 1))
    lam_ref = np.linalg.eigvals(ref.with_K_D(p.K_D))
    lam = np.array([x.eigenvalue for x in modes(lin)])
    scale = np.abs(lam_ref).max()
    big = lambda v: np.sort_complex(v[np.abs(v) > 1e-6 * scale])  # noqa: E731
    assert len(big(lam)) == len(big(lam_ref)) == 6
    assert np.all(np.abs(big(lam) - big(lam_ref)) <= 1e-9 * np.abs(big(lam_ref)))
    claims = check_claims(lin)
    (star,) = check_claims(from_analytic(ref)).K_D_star
    assert len(claims.meetings) == 1
    # one checker on both paths: K* from the Euler-angle system file and the quaternion model
    assert abs(claims.meetings[0].K_D - star) <= 1e-10 * star


# -- the claims -------------------------------------------------------------------------------
@pytest.mark.parametrize('name', SHIPPED)
def test_claims_hold_on_every_shipped_system(name):
    lin = linearize_scene(load_scene(name))
    claims = check_claims(lin)
    assert claims.all_hold, {k: c.detail for k, c in claims.claims.items()}
    assert claims.claims['d'].data['net_meetings'] == lin.m
    assert all(x.verified and x.lam < 0 for x in claims.meetings)


def test_claims_fail_on_a_statically_unstable_system(tmp_path):
    """A check that can fail: V = -k x^2/2 has a real root pair at K_D = 0."""
    path = _write_scene(tmp_path, _doc(potential='-k*x**2/2'), {})
    claims = check_claims(linearize_scene(load_scene(path)))
    assert not claims.claims['a'].holds and not claims.claims['b'].holds


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
    lin = linearize_scene(load_scene(path))
    un = [x for x in modes(lin) if not x.reached_by_drive]
    assert len(un) == 2 and all('unreached mode (w)' == x.name for x in un)
    assert all(abs(x.eigenvalue.real) < 1e-12
               and abs(abs(x.eigenvalue.imag) - math.sqrt(6.0)) < 1e-9
               for x in un)
    claims = check_claims(lin)
    assert claims.claims['b'].holds and claims.claims['b'].data['unreached'] == 2
    assert np.abs(np.abs(claims.unreached.imag) - math.sqrt(6.0)).max() < 1e-9
    out = tmp_path / 'eig.json'
    assert main(['eig', path, '--json', str(out)]) == 0
    assert 'unreached mode (w)' in capsys.readouterr().out


def test_locked_scene_is_the_rotor_on_its_drive(tmp_path):
    path = _write_scene(tmp_path, _doc(), {'locked': ['x']})
    scene = load_scene(path)
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
    # one CSV format for every system (the centrifuge's: name [unit], a rate is NAME_dot)
    assert head[0] == ('t [s],alpha [SI],beta1 [SI],beta2 [SI],alpha_dot [SI/s],'
                       'beta1_dot [SI/s],beta2_dot [SI/s],z_R1 [rad],z_R2 [rad],'
                       'z_R1_dot [rad/s],z_R2_dot [rad/s],E_star [J],dE_dt [W],residual [J]')
    assert len(head) == 12
    assert 'max |residual|' in capsys.readouterr().out


def test_locus_json_has_K_D_star_and_claims(tmp_path):
    import json
    out = tmp_path / 'l.json'
    assert main(['locus', 'twin_gimbal', '--json', str(out), '--points', '20']) == 0
    doc = json.loads(out.read_text())
    assert len(doc['K_D_star']) == 2
    assert {k: c['holds'] for k, c in doc['claims'].items()} == dict.fromkeys('abcd', True)


@pytest.mark.parametrize('params, match', [
    ({'initial': {'q': [0.1, 0.2]}}, r'initial.q must have 1 entries \(one per coordinate: x\)'),
    ({'initial': {'zdot': [0.1, 0.2]}}, 'initial.zdot must have 1 entries'),
    ({'initial': {'qdot': []}}, r'initial.qdot must have 1 entries \(one per coordinate: x\), '
                                'got 0'),
    ({'initial': {'z': [0.0, 0.0]}}, r'initial.z must have 1 entries \(one per rotor: R\)'),
    ({'steady': {'q': [0.0, 0.0]}}, 'steady.q must have 1 entries'),
    ({'steady': {'qdot': [0.0, 1.0]}}, 'steady.qdot must have 1 entries'),
    ({'initial': {'q': ['a']}}, 'initial.q must be a list of numbers'),
    ({'locked': 'x'}, 'locked must be a list of coordinate names'),
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
    err = _errors(capsys.readouterr().err)
    assert err.startswith('ERROR: ') and err.count('\n') == 1 and 'Traceback' not in err
    assert __import__('re').search(match, err), err


def test_bad_system_file_via_cli_is_one_error_line(tmp_path, capsys):
    path = _write_scene(tmp_path, _doc(potential='k*x^2'), {})
    assert main(['eig', path]) == 1
    err = _errors(capsys.readouterr().err)
    assert err.count('\n') == 1 and "potential: unexpected character '^'" in err
    assert 'sys.yaml' in err


def test_steady_command_solves_from_a_guess(tmp_path, capsys):
    doc = _doc(potential='k*(x - 0.25)**2/2')
    path = _write_scene(tmp_path, doc, {})
    assert main(['eig', path]) == 1     # the default steady motion (zeros) is checked too
    err = _errors(capsys.readouterr().err)
    assert 'x_ddot = 0.5' in err and f'`gyro-rotor steady {path}`' in err, err
    assert main(['steady', path]) == 0
    assert 'q = [0.25' in capsys.readouterr().out


def test_campbell_marks_critical_speeds(tmp_path, capsys):
    import json
    out = tmp_path / 'c.json'
    assert main(['campbell', 'twin_gimbal', '--points', '60', '--json', str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc['critical_speeds'] and len(doc['frequencies_hz']) == 60
    assert main(['campbell', 'precession', '--points', '20']) == 0   # centrifuge scenes too


def test_expression_undefined_at_the_state_is_one_error_line(tmp_path, capsys):
    path = _write_scene(tmp_path, _doc(mass_matrix=[['1 + sqrt(x)']]),
                        {'initial': {'q': [-1.0]}})
    assert main(['simulate', path]) == 1
    err = _errors(capsys.readouterr().err)
    assert err.count('\n') == 1 and 'not defined at q = [-1.0]' in err


def test_singular_coordinates_are_refused(capsys):
    assert main(['simulate', 'centrifuge_euler', '--set', 'initial.q=[0.0, 0.0, 0.0]']) == 1
    err = _errors(capsys.readouterr().err)
    assert err.count('\n') == 1 and 'numerically singular' in err
    assert 'at the initial state' in err


ONE = """name: one
coordinates: [x]
rotors: [R]
constants: {J: 0.1, C: 0.01, k: 10.0}
mass_matrix: [["J"]]
rotor_inertia: ["C"]
guidance: [["1"]]
potential: "k*x**2/2"
drives:
  - {K_S: 5.0, K_D: 0.01, Omega0: 100.0, pole_pairs: 0}
"""


@pytest.mark.parametrize('scale', [1e-15, 1.0, 1e6])
def test_the_mass_check_has_no_unit_scale(tmp_path, capsys, scale):
    # review finding: the check was absolute below 1 kg m^2 (1e-12 * max(1, |w|)): a
    # micro-rotor with J = 1e-16 was refused, and C = 1e-30 beside J = 0.1 was called
    # 'not positive definite' with both eigenvalues printed positive
    (tmp_path / 'one.yaml').write_text(ONE)
    scene = tmp_path / 's.yaml'
    scene.write_text('/**:\n  ros__parameters:\n    system: one.yaml\n    t_end: 0.1\n'
                     '    initial: {q: [0.01], qdot: [0.0], z: [0.0], zdot: [0.1]}\n')

    def run(C, out):
        argv = ['simulate', str(scene), '--out', str(tmp_path / out)]
        for c, v in (('J', 0.1 * scale), ('C', C), ('k', 10.0 * scale)):
            argv += ['--set', f'constants.{c}={v!r}']
        return main(argv)

    assert run(0.01 * scale, 'a.csv') == 0, capsys.readouterr().err
    capsys.readouterr()
    assert run(1e-14 * scale, 'b.csv') == 1
    err = _errors(capsys.readouterr().err)
    assert err.count('\n') == 1 and 'is numerically singular' in err, err


# -- scene keys ----------------------------------------------------------------------------------
def test_scene_overrides_reach_the_system(tmp_path):
    params = {'K_S': 3.0, 'Omega0': 200.0, 'pole_pairs': 2,
              'drive': {'R2': {'K_D': 0.7, 'Omega0': 150.0}},
              'constants': {'c_a': 55.0}, 't_end': 1.5}
    path = tmp_path / 'scene.yaml'
    path.write_text(yaml.safe_dump({'rotor_sim': {'ros__parameters': {
        'system': 'twin_gimbal', **params}}}))
    scene = load_scene(str(path), overrides={'drive.R1.K_D': 0.4})
    d1, d2 = scene.system.drives
    assert (d1.K_S, d1.K_D, d1.Omega0, d1.pole_pairs) == (3.0, 0.4, 200.0, 2)
    assert (d2.K_S, d2.K_D, d2.Omega0, d2.pole_pairs) == (3.0, 0.7, 150.0, 2)
    assert scene.system.constants['c_a'] == 55.0 and scene.t_end == 1.5
    assert scene.system.constants['J_g'] == load_system('twin_gimbal').constants['J_g']
    # the numbers reach the equations: alpha'' = -c_a alpha / J_alpha at rest with z = 0
    model = scene.make_model()
    f0 = model.rhs(0.0, model.state([0.1, 0, 0], [0, 0, 0], [0, 0], [0, 0]))
    ref = GeneralModel(load_system('twin_gimbal'))
    f1 = ref.rhs(0.0, ref.state([0.1, 0, 0], [0, 0, 0], [0, 0], [0, 0]))
    assert f0[3] / f1[3] == pytest.approx(55.0 / 40.0, rel=1e-12)


def test_initial_state_is_taken_from_the_scene():
    scene = load_scene('twin_gimbal')
    y0 = scene.initial_state()
    assert y0.tolist() == [0.006, 0.015, -0.009, 0.0, 0.06, 0.0, 0.003, 0.0, 0.15, -0.09, 0.0]


def test_non_steady_motion_names_its_size_and_the_steady_command(tmp_path, capsys):
    path = _write_scene(tmp_path, _doc(), {'steady': {'q': [0.3]}})
    for command in (['eig', path], ['locus', path], ['simulate', path, '--t-end', '0.1']):
        assert main(command) == 1
        err = _errors(capsys.readouterr().err)
        assert err.count('\n') == 1 and 'x_ddot = -0.6' in err, err
        assert f'`gyro-rotor steady {path}` solves for one from this guess' in err
    assert main(['steady', path]) == 0
    out = capsys.readouterr().out
    assert 'x_ddot = -0.6' in out and 'steady motion (Newton' in out
    # the steady motion is x = 0 (V = k x^2/2): to round-off, not necessarily printed 0.0
    q = re.search(r'steady motion \(Newton[^:]*: q = \[([^\]]*)\]', out).group(1)
    assert abs(float(q)) < 1e-12, out


def test_core_says_what_is_not_steady_and_the_command_line_names_the_command(tmp_path):
    """Core's NotSteadyError names no command; the CLI adds ``gyro-rotor steady`` (issue #25)."""
    path = _write_scene(tmp_path, _doc(), {'steady': {'q': [0.3]}})
    with pytest.raises(NotSteadyError, match=r'\(x_ddot = -0.6, largest of 0.6 > 1e-08\)$') \
            as info:
        load_scene(path)
    assert 'gyro-rotor' not in str(info.value) and info.value.scene == path


def test_steady_command_without_equilibrium_exits_1(tmp_path, capsys):
    path = _write_scene(tmp_path, _doc(potential='k*x'), {})
    assert main(['steady', path]) == 1
    assert 'no steady motion found' in capsys.readouterr().out


# -- eig, locus, tune, campbell ----------------------------------------------------------------
def test_eig_json_has_eigenvalues_and_reached(tmp_path):
    import json
    out = tmp_path / 'e.json'
    assert main(['eig', 'twin_gimbal', '--json', str(out)]) == 0
    doc = json.loads(out.read_text())
    lam = np.array([complex(*x) for x in doc['eigenvalues']])
    ref = np.linalg.eigvals(linearize_scene(load_scene('twin_gimbal')).A_scene())
    assert len(lam) == 10 and np.abs(np.sort_complex(lam) - np.sort_complex(ref)).max() < 1e-9
    assert len(doc['modes']) == 10 and all(isinstance(x['reached'], bool) for x in doc['modes'])
    assert all(x['reached'] for x in doc['modes'])   # twin_gimbal: every mode damped


def test_zero_roots_of_cyclic_coordinates_are_named():
    """Name both zero roots of centrifuge_euler's one cyclic direction after psi.

    Its potential holds psi and phi_M only as phi_M + psi: one cyclic direction (psi at
    fixed phi_M + psi), whose two zero roots are one Jordan block (its shift and its
    neighbouring steady motions; the quaternion model drops psi and keeps the second,
    'zero root (cyclic psi)'). Both are named by it, as the kernel of A0 holds it.
    """
    lin = linearize_scene(load_scene('centrifuge_euler'))
    ms = modes(lin)
    zeros = [x.name for x in ms if x.kind == ModeKind.ZERO]
    assert zeros == ['zero root (cyclic psi)'] * 2
    assert not any(x.reached_by_drive for x in ms if x.kind == ModeKind.ZERO)
    shift = np.zeros(len(lin.names))
    shift[[lin.names.index('psi'), lin.names.index('phi_M')]] = (1.0, -1.0)
    assert np.abs(lin.A0 @ shift).max() < 1e-12 * np.abs(lin.A0).max()
    assert [x.name for x in modes(linearize_scene(load_scene('precession')))
            if x.kind == ModeKind.ZERO] == ['zero root (cyclic psi)']


def _pair_is_complex(lin, K, point, scale):
    lam = lin.eig(K)
    near = lam[np.abs(lam - point) < 1e-2 * scale]
    return bool(np.any(np.abs(near.imag) > 1e-6 * abs(point)))


@pytest.mark.parametrize('drive', [None, 'R1', 'R2'])
def test_locus_K_D_star_is_a_double_root_to_1e_8(tmp_path, drive):
    """Check each K* as a double root: the pair is complex just before, real just after.

    Both sides at 1e-7 relative (ten times the claimed precision of 1e-8).
    """
    import json
    out = tmp_path / 'l.json'
    args = ['locus', 'twin_gimbal', '--json', str(out), '--points', '10']
    assert main(args + (['--drive', drive] if drive else [])) == 0
    doc = json.loads(out.read_text())
    lin = linearize_scene(load_scene('twin_gimbal'), drive=drive)
    assert doc['drive'] == drive
    assert {k: c['holds'] for k, c in doc['claims'].items()} == dict.fromkeys('abcd', True)
    assert len(doc['K_D_star']) == (2 if drive is None else 1)
    # (a) is about every drive at K_D = 0; the locus of one drive starts with the other
    # damped, off the axis: the statement says which K_D = 0 it means
    assert ('also those the locus does not vary' in doc['claims']['a']['statement']) == (
        drive is not None)
    scale = float(np.abs(lin.eig(0.0)).max())
    for K, point in zip(doc['K_D_star'], doc['meeting_points']):
        assert point < 0
        assert _pair_is_complex(lin, K * (1 - 1e-7), point, scale)
        assert not _pair_is_complex(lin, K * (1 + 1e-7), point, scale)


def test_locus_unknown_drive_is_one_error_line(capsys):
    assert main(['locus', 'twin_gimbal', '--drive', 'R3']) == 1
    err = _errors(capsys.readouterr().err)
    assert err.count('\n') == 1 and "unknown rotor 'R3'" in err and 'R1, R2' in err


def test_tune_finds_a_better_common_K_D(capsys):
    assert main(['tune', 'twin_gimbal']) == 0
    out = capsys.readouterr().out
    best = float(out.split('slowest decay rate ')[1].split()[0])
    at_scene = float(out.split('scene K_D = 0.02, 0.02: rate ')[1].split()[0])
    assert best > at_scene > 0
    # the flatness of the optimum: the rates printed at 0.5 and 2 x over the best, in %
    half = float(out.split('0.5 x best: ')[1].split(',')[0])
    twice = float(out.split('2 x best: ')[1].split()[0])
    pct = out.split('the rate at half the best K_D is ')[1]
    assert float(pct.split()[0]) == pytest.approx(100 * half / best, rel=1e-2)
    at_twice = float(pct.split('at twice it ')[1].split()[0])
    assert at_twice == pytest.approx(100 * twice / best, rel=1e-2)
    assert 'd ln(rate)' not in out


def test_tune_names_a_repeated_root_once_with_its_multiplicity(capsys):
    """centrifuge_euler's cyclic psi gives a double zero root: one name, '(2 roots)'."""
    assert main(['tune', 'centrifuge_euler']) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if 'not judged' in x)
    assert line.endswith(': zero root (cyclic psi) (2 roots)'), line


def test_tune_refuses_a_system_unstable_for_every_K_D(capsys):
    """An indefinite potential (c_b2 < 0): one ERROR line naming the growing root, exit 1."""
    lam = np.linalg.eigvals(linearize_scene(load_scene(
        'twin_gimbal', overrides={'constants.c_b2': -2.0}, check=False)).A_scene())
    assert main(['tune', 'twin_gimbal', '--set', 'constants.c_b2=-2.0']) == 1
    cap = capsys.readouterr()
    err = _errors(cap.err)
    assert err.count('\n') == 1 and err.startswith('ERROR: unstable for every K_D: ')
    assert 'Traceback' not in cap.err and not cap.out
    grows = float(err.split('the root lambda = ')[1].split()[0])
    assert grows > 0 and abs(grows - lam.real.max()) < 1e-3 * lam.real.max()


def test_campbell_critical_speeds_are_crossings(tmp_path):
    import json
    out = tmp_path / 'c.json'
    assert main(['campbell', 'twin_gimbal', '--points', '80', '--json', str(out)]) == 0
    doc = json.loads(out.read_text())
    F = np.array(doc['frequencies_hz'])
    assert F.shape == np.array(doc['decay_rates']).shape == (80, 5)
    assert doc['critical_speeds']
    scene = load_scene('twin_gimbal')
    ref = scene.system.drives[0].Omega0
    for c in doc['critical_speeds']:
        f = c['Omega0'] / ref
        drives = [d.replace(Omega0=d.Omega0 * f) for d in scene.system.drives]
        import dataclasses
        sc = dataclasses.replace(scene, system=scene.system.with_drives(drives))
        lam = np.linalg.eigvals(linearize_scene(sc).A_scene())
        target = c['order'] * c['Omega0'] / (2 * math.pi)
        assert np.min(np.abs(lam.imag / (2 * math.pi) - target)) < 1e-2 * target, c


def test_campbell_names_the_modes_at_the_scene_speed(tmp_path, capsys):
    """A range from 0: the gimbals are out of the drives' reach at rest, not at 300 rad/s.

    Each label is the name eig gives the mode's root at the scene's speed (all reached
    there), whatever the speed of the mode's largest frequency; the critical-speed lines
    carry the same labels.
    """
    import json
    out = tmp_path / 'c.json'
    assert main(['campbell', 'twin_gimbal', '--omega-min', '0', '--omega-max', '600',
                 '--points', '21', '--json', str(out)]) == 0
    text = capsys.readouterr().out
    doc = json.loads(out.read_text())
    i = doc['Omega0'].index(300.0)
    assert doc['modes_named_at_Omega0'] == 300.0
    ms = modes(linearize_scene(load_scene('twin_gimbal')))
    for k, (label, cols) in enumerate(zip(doc['modes'], doc['mode_roots'])):
        z = max((complex(*doc['roots'][i][c]) for c in cols), key=lambda x: x.imag)
        mode = min(ms, key=lambda m: abs(m.eigenvalue - z))
        assert abs(mode.eigenvalue - z) < 1e-6 * abs(z), (label, z)
        assert mode.reached_by_drive and label.startswith(f'{mode.name}, '), (label, mode)
        assert f'mode {k}: {label} ' in text
    assert doc['critical_speeds'] and 'unreached' not in text
    assert all(c['label'] == doc['modes'][c['mode']] for c in doc['critical_speeds'])


@pytest.mark.parametrize('c_b2, grows', [(-2.0, True), (None, False)])
def test_campbell_flags_growing_roots(tmp_path, capsys, c_b2, grows):
    """A growing root (Re above its resolution) is flagged UNSTABLE in the text and JSON."""
    import json
    out = tmp_path / 'c.json'
    sets = [] if c_b2 is None else ['--set', f'constants.c_b2={c_b2}']
    assert main(['campbell', 'twin_gimbal', '--points', '40', '--json', str(out)] + sets) == 0
    text = capsys.readouterr().out
    doc = json.loads(out.read_text())
    lam = np.linalg.eigvals(linearize_scene(load_scene(
        'twin_gimbal', overrides={} if c_b2 is None else {'constants.c_b2': c_b2},
        check=False)).A_scene())
    assert (lam.real.max() > 1.0) == grows
    unstable = np.array(doc['unstable'])
    assert unstable.shape == (40, len(doc['modes']))
    assert np.array_equal(unstable, np.array(doc['decay_rates']) < 0)
    assert bool(doc['unstable_modes']) == grows == ('UNSTABLE' in text)
    for k in doc['unstable_modes']:
        assert f'UNSTABLE: mode {k} ({doc["modes"][k]}) has a growing root' in text
        assert 'growing' in doc['modes'][k]
        i = doc['Omega0'].index(300.0)
        assert -np.array(doc['decay_rates'])[i, k] == pytest.approx(lam.real.max(), rel=1e-6)


def test_campbell_and_eig_judge_a_roots_sign_by_one_rule(tmp_path, capsys, monkeypatch):
    """Damping destroys gyroscopic stabilisation (Kelvin-Tait-Chetaev): both commands say so.

    s_gyro: an unstable potential (ka, kb < 0) held by the rotor's spin; with K_D > 0 the slow
    mode (beta, 0.079 Hz) grows at +1.1e-10 1/s at 300 rad/s, below the double-precision
    resolution of its root: the one rule (claims.damped, 40 digits) decides it, in eig and in
    campbell at every speed (campbell judged it by double precision only: undamped above
    about 200 rad/s).
    """
    import json
    import pathlib
    import shutil
    for name in ('s_gyro.yaml', 'sc_gyro.yaml'):
        shutil.copy(pathlib.Path(__file__).parent / 'data' / name, tmp_path / name)
    monkeypatch.chdir(tmp_path)
    assert main(['campbell', 'sc_gyro.yaml', '--omega-min', '300', '--omega-max', '600',
                 '--points', '7', '--json', 'c.json']) == 0
    assert main(['eig', 'sc_gyro.yaml', '--json', 'e.json']) == 0
    text = capsys.readouterr().out
    doc, eig = (json.loads((tmp_path / f).read_text()) for f in ('c.json', 'e.json'))
    i = doc['Omega0'].index(300.0)
    roots = [complex(*z) for z in doc['roots'][i]]
    reached = [m for m in eig['modes'] if m['reached']]
    assert reached and any(not m['damped'] for m in reached)
    for m in reached:
        z = complex(*m['eigenvalue'])
        j = min(range(len(roots)), key=lambda c: abs(roots[c] - z))
        k = next(k for k, cols in enumerate(doc['mode_roots']) if j in cols)
        # the same decision: damped in eig exactly where campbell's decay rate is positive
        assert (doc['decay_rates'][i][k] > 0) == m['damped'], (m['name'], z)
    grows = [k for k in doc['unstable_modes'] if all(u[k] for u in doc['unstable'])]
    assert grows and 'growing root (Re above its resolution) at 7 of the 7 speeds' in text


def test_campbell_counts_unreached_nilpotent_zero_roots_exactly():
    """The exact nilpotent invariant subspace in ker C (campbell's _zeros_exact, integers).

    A chain e2 -> 3e6 e1 -> 3e-3 e0 -> 0 beside a root 0.1 (entries of very different
    sizes and not exact in binary: the doubles are scaled to integers by one power of 2):
    all three chain states unreached with C = 0 or with C seeing only the fourth state,
    two if C sees e2, none if C sees e0; ``enough`` stops at the first step that has as many.
    """
    from gyro_rotor.linear.campbell import _zeros_exact
    A0 = np.zeros((4, 4))
    A0[0, 1], A0[1, 2], A0[3, 3] = 1e-9 * 3e6, 3e6, 0.1
    for c, dim in ((None, 3), (3, 3), (2, 2), (0, 0)):
        C = np.zeros((1, 4))
        if c is not None:
            C[0, c] = 0.7
        assert _zeros_exact(A0, C) == dim, c
    assert _zeros_exact(A0, np.zeros((1, 4)), enough=1) == 1
    # the same chain seen in other coordinates (an exact binary change of basis)
    T = np.eye(4) + np.triu(np.full((4, 4), 0.5), 1)
    Ti = np.linalg.inv(T)
    assert np.array_equal(T @ Ti, np.eye(4))
    assert _zeros_exact(T @ A0 @ Ti, np.array([[0.0, 0.0, 0.0, 1.0]]) @ Ti) == 3


# -- the project's integrators and the ensemble run general systems ----------------------------
# method: (keyword arguments, largest state difference to dop853 at rtol 1e-13 after 0.5 s)
GENERAL_RUNS = {'dop853': ({'rtol': 1e-10, 'atol': 1e-12}, 1e-8),
                'vern7': ({'rtol': 1e-10, 'atol': 1e-12}, 1e-8),
                'vern8': ({'rtol': 1e-10, 'atol': 1e-12}, 1e-8),
                'vern9': ({'rtol': 1e-10, 'atol': 1e-12}, 1e-8),
                'rodas4': ({'rtol': 1e-10, 'atol': 1e-12}, 1e-8),
                'radau9': ({'rtol': 1e-10, 'atol': 1e-12}, 1e-8),
                'rk4': ({'step': 2e-4}, 1e-5), 'rk8': ({'step': 2e-4}, 1e-10),
                'gauss6': ({'step': 2e-4}, 1e-10)}


@pytest.mark.parametrize('name', SHIPPED)
def test_every_general_method_runs_every_shipped_system(name):
    from gyro_rotor.numerics.kernel_system import SYSTEM_METHODS
    assert set(SYSTEM_METHODS) == set(GENERAL_RUNS)
    scene = load_scene(name)
    model = scene.make_model()
    y0 = scene.initial_state(model)
    te = np.linspace(0.0, 0.5, 6)
    ref = integrate_general(model, y0, te, method='dop853', rtol=1e-13, atol=1e-15).y
    for method, (kwargs, tol) in GENERAL_RUNS.items():
        run = integrate_general(model, y0, te, method=method, **kwargs)
        assert run.method == method and run.y.shape == ref.shape
        assert np.abs(run.y - ref).max() < tol, method
        assert np.abs(model.residual(run.y)).max() < 1e-8 * model.energy(y0), method


def test_general_kernels_are_compiled_for_the_function_type_only():
    """Check that one compiled loop serves every system (numba caches it on disk).

    The kernels never see a system's own dispatcher type, only the first-class function
    type RHS_TYPE; the generated module holds no integrator.
    """
    from gyro_rotor.core.system.codegen import RHS_TYPE
    from gyro_rotor.numerics.integrators import kernels
    for name in SHIPPED:
        scene = load_scene(name)
        model = scene.make_model()
        assert not hasattr(model.compiled.module, 'run')    # no integrator is generated
        integrate_general(model, scene.initial_state(model), [0.0, 0.01], method='dop853')
    from numba.core import types
    kinds = {sig[0] for sig in kernels.dop853_run.signatures}
    model_kinds = (types.Integer, types.IntEnumMember)    # the hand-written models' kinds
    assert {k for k in kinds if not isinstance(k, model_kinds)} == \
        {types.FunctionType(RHS_TYPE)}, kinds


def test_ensemble_runs_a_general_system_with_its_own_numbers_per_trajectory():
    scene = load_scene('twin_gimbal')
    model = scene.make_model()
    y0 = scene.initial_state(model)
    systems = [scene.system.reduced, scene.with_drives(K_D=0.3).system.reduced,
               scene.system.reduced.with_constants({'c_a': 60.0})]
    Y0 = np.array([y0, 0.5 * y0, y0])
    te = np.linspace(0.0, 0.5, 11)
    res = run_ensemble(model, Y0, te, params=systems, step=1e-4)
    assert res.y.shape == (11, 3, model.size) and res.backend == 'numba'
    for r, (system, y) in enumerate(zip(systems, Y0)):
        single = integrate_general(GeneralModel(system), y, te, method='rk4', step=1e-4)
        assert np.abs(res.y[:, r] - single.y).max() < 1e-12, r
    assert np.abs(res.y[-1, 0] - res.y[-1, 1]).max() > 1e-3     # other numbers, other runs
    assert np.abs(res.y[-1, 0] - res.y[-1, 2]).max() > 1e-3
    with pytest.raises(ParameterError, match='the same system with other numbers'):
        run_ensemble(model, Y0[:1], te, params=[load_system('elastic_frame')])


def test_simulate_system_file_scene_with_each_method(tmp_path, capsys):
    for method in ('rk4', 'rodas4'):
        assert main(['simulate', 'twin_gimbal', '--t-end', '0.2', '--method', method]) == 0
        assert f'{method}: steps' in capsys.readouterr().out
    assert main(['simulate', 'twin_gimbal', '--t-end', '0.2', '--method', 'split8']) == 1
    err = _errors(capsys.readouterr().err)
    assert err.count('\n') == 1 and "unknown integrator 'split8' for system twin_gimbal" in err


def test_auto_picks_radau9_for_a_stiff_drive():
    from gyro_rotor.numerics.integrators import choose_method
    scene = load_scene('twin_gimbal')
    model = scene.make_model()
    y0 = scene.initial_state(model)
    from gyro_rotor.numerics.integrators import COST_METHODS
    assert choose_method(model, y0=y0)[0] in COST_METHODS     # non-stiff: an explicit pair
    stiff = scene.with_drives(K_D=1e3).make_model()
    method, reason = choose_method(stiff, y0=y0)
    assert method == 'radau9' and 'stiff' in reason
    run = integrate_general(stiff, y0, np.linspace(0.0, 0.2, 5))
    assert run.method == 'radau9' and run.nsteps < 5000
    assert np.abs(stiff.residual(run.y)).max() < 1e-7 * stiff.energy(y0)


@pytest.mark.parametrize('scene', ['twin_gimbal', 'precession', 'centrifuge_euler'])
def test_no_drive_stiffness_is_marginal_on_every_system(scene):
    # K_S = 0: the rotor angle z has no restoring torque; its zero root is not excused
    # like a cyclic carrier coordinate (the theorem needs self-stable drives)
    from gyro_rotor.cli.util import load_scene_with_sets
    from gyro_rotor.linear.system import assess
    sc = load_scene_with_sets(scene, ['K_S=0'])
    ms, v = assess(linearize_scene(sc))
    assert v.verdict == 'marginal', v.reason
    assert 'rotor angle neutral (K_S = 0' in v.reason
    assert any(m.rotor_angle and m.kind == ModeKind.ZERO for m in ms)
    # the prediction marks the same modes marginal as the verdict names
    from gyro_rotor.analysis.prediction import predict
    pred = predict(sc)
    assert pred.verdict == 'marginal'
    assert {m.name for m in pred.marginal_modes} == set(v.marginal_modes)
    # with the drives stiff again, no rotor angle is neutral
    ms, v = assess(linearize_scene(load_scene(scene)))
    assert not any(m.rotor_angle for m in ms) and 'rotor angle' not in v.reason


def _fd_slopes(A0, BC, hs=(1e-10, 1e-11)):
    """Roots of A0 and (lambda(h) - lambda(0))/h of A0 - h BC for each h, at 40 digits.

    Written here independently of the code under test: mpmath's eigenvalues (so that a
    Jordan block's round-off split, ~sqrt(1e-40), stays far below h), each root at h paired
    with its root at 0 by distance.
    """
    import mpmath as mp
    from scipy.optimize import linear_sum_assignment
    with mp.workdps(40):
        def ev(h):
            return mp.eig(mp.matrix(A0.tolist()) - mp.mpf(h) * mp.matrix(BC.tolist()))[0]
        l0 = ev(0)
        c0 = np.array([complex(x) for x in l0])
        out = []
        for h in hs:
            lh = ev(h)
            ch = np.array([complex(x) for x in lh])
            rows, cols = linear_sum_assignment(np.abs(c0[:, None] - ch[None, :]))
            s = np.empty(len(c0), dtype=complex)
            s[rows] = [complex((lh[j] - l0[i]) / mp.mpf(h)) for i, j in zip(rows, cols)]
            out.append(s)
    return c0, out


#: printed dRe/dK_D against the finite-difference slope: |d - fd| <= TOL_FD (1 + |fd|)
#: (measured: <= 2.4e-9 absolute on twin_gimbal, <= 2.2e-10 on random systems)
TOL_FD = 1e-6


def _check_sensitivities_against_fd(lin):
    """Per cluster of K = 0 roots: the printed d (sorted) equal the converged FD slopes."""
    A0, BC = lin.A_cons, lin.b_all @ lin.c_all.T
    l0, (s1, s2) = _fd_slopes(A0, BC)
    ms = modes(lin)
    start = np.array([m.eigenvalue_K_D0 for m in ms])
    d = np.array([m.dRe_dKD for m in ms])
    scale = max(1.0, float(np.abs(l0).max()))
    seen = np.zeros(len(l0), dtype=bool)
    for i in range(len(l0)):
        if seen[i]:
            continue
        g = np.abs(l0 - l0[i]) <= 1e-6 * scale
        seen |= g
        fd, fd1 = np.sort(s2[g].real), np.sort(s1[g].real)
        printed = np.sort(d[np.abs(start - l0[i]) <= 1e-6 * scale])
        assert len(printed) == len(fd), (l0[i], printed, fd)
        converged = np.all(np.abs(fd - fd1) <= TOL_FD * (1 + np.abs(fd)))
        # "not defined" exactly where the slope does not converge (a sqrt-type split)
        assert np.all(np.isnan(printed)) == (not converged), (l0[i], printed, fd, fd1)
        if converged:
            assert np.all(np.abs(printed - fd) <= TOL_FD * (1 + np.abs(fd))), (printed, fd)
    return ms


def test_sensitivity_at_a_jordan_zero_root_is_the_finite_difference_slope(capsys):
    # twin_gimbal at K_S = 0: each rotor's (z, zdot) is a Jordan block at 0; e_z stays a
    # null vector for every K (its root stays at 0, d = 0), the slip root moves linearly
    # (-K c^T b: -500 and -666.67 1/(N m s)); printed, not "not defined"
    assert main(['eig', 'twin_gimbal', '--set', 'K_S=0']) == 0
    out = capsys.readouterr().out
    rows = [x for x in out.splitlines() if 'z_R' in x and ('mode' in x or 'zero' in x)
            and 'verdict' not in x]
    assert len(rows) == 4 and not any('not defined' in x for x in rows), rows
    assert {x.split()[-2] for x in rows} == {'-5.0000e+02', '-6.6667e+02', '+0.0000e+00'}
    _check_sensitivities_against_fd(
        linearize_scene(load_scene_with_sets('twin_gimbal', ['K_S=0'])))
    # the simple roots keep their sensitivity
    ms = modes(linearize_scene(load_scene('twin_gimbal')))
    assert all(math.isfinite(m.dRe_dKD) and m.dRe_dKD < 0 for m in ms)


def load_scene_with_sets(name, sets):
    """Return the scene ``name`` with ``--set`` overrides (the CLI's loader)."""
    from gyro_rotor.cli.util import load_scene_with_sets as load
    return load(name, sets)


@settings(max_examples=5, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 3), m=st.integers(1, 2))
def test_sensitivity_with_no_drive_stiffness_is_the_finite_difference_slope(seed, n, m,
                                                                            tmp_path_factory):
    """Random valid systems, K_S = 0 on some drives: printed d = FD slope, every root."""
    folder = tmp_path_factory.mktemp('jordan')
    (folder / 'sys.yaml').write_text(yaml.safe_dump(random_system_file(seed, n, m, zero_K_S=True)))
    (folder / 'scene.yaml').write_text(yaml.safe_dump(
        {'/**': {'ros__parameters': {'system': 'sys.yaml', 't_end': 1.0}}}))
    ms = _check_sensitivities_against_fd(linearize_scene(load_scene(str(folder / 'scene.yaml'))))
    assert any(m.kind == ModeKind.ZERO for m in ms)


def test_centrifuge_euler_sensitivities_are_the_finite_difference_slopes():
    # the Euler twin at K_S = 0: a cyclic direction (psi - phi_M), its Jordan chain with the
    # precession family, and z's; the slip root -50.0072 as on the centrifuge's own path
    _check_sensitivities_against_fd(
        linearize_scene(load_scene_with_sets('centrifuge_euler', ['K_S=0'])))


@pytest.mark.parametrize('K_S', ['1e-7', '1e-8'])
def test_a_tiny_drive_stiffness_keeps_two_simple_roots_on_both_paths(K_S):
    """Review finding: K_S = 1e-7 / 1e-8 (> 0: inside the theorem) on the centrifuge.

    The rotor-field pair +-i sqrt(K_S/C) is two simple roots, d = -25.004 each (the FD
    slope at 40 digits). A cluster tolerance of 1e-6 of the spectral scale merged them with
    the cyclic root (0 and -50.007, the K_S = 0 answer) at 1e-8 on the centrifuge and at
    1e-7 on centrifuge_euler, and resting_space's rank cutoff 1e-10 counted z at rest.
    """
    ms = _check_sensitivities_against_fd(
        linearize_scene(load_scene_with_sets('centrifuge_euler', [f'K_S={K_S}'])))
    ref = modes(linearize_scene(load_scene_with_sets('precession', [f'K_S={K_S}'])))
    for paths in (ms, ref):
        slip = sorted(m.dRe_dKD for m in paths if 'z_R' in m.name or 'rotor-field' in m.name)
        assert len(slip) == 2 and all(abs(d + 25.0036) < 1e-3 for d in slip), slip


@pytest.mark.parametrize('scene', ['precession', 'conservative'])
def test_a_repeated_zero_root_is_reached_where_it_moves_with_K(scene):
    """K_S = K_D = 0: three roots at 0; the one that moves with K (d = -50.007) is reached.

    Found by the one-path helper: classify matched modes to roots by eigenvalue alone, so
    in the cluster at 0 the reach labels followed list order (the moving root 'not
    reached', the cyclic psi root 'reached'). A root on the fixed subspace has d = 0.
    """
    ms = modes(linearize_scene(load_scene_with_sets(scene, ['K_S=0', 'K_D=0'])))
    at0 = [m for m in ms if abs(m.eigenvalue) <= 1e-9]
    assert len(at0) == 3
    for m in at0:
        assert m.reached_by_drive == (abs(m.dRe_dKD) > 1.0), m


def test_centrifuge_and_its_euler_twin_agree_without_drive_stiffness():
    # issue 25, one path: at K_S = 0 the roots (1e-9) and every root's dRe/dK_D agree, the
    # slip root's -50.0072 on both (the built-in prints it, the system file did not)
    ref = {complex(m.eigenvalue): m.dRe_dKD
           for m in modes(linearize_scene(load_scene_with_sets('precession', ['K_S=0'])))}
    ms = modes(linearize_scene(load_scene_with_sets('centrifuge_euler', ['K_S=0'])))
    for m in ms:
        if m.kind == ModeKind.ZERO:      # a zero root (Jordan round-off ~1e-8 here): rests
            assert m.dRe_dKD == 0.0 or abs(m.dRe_dKD) <= 1e-12, m
            continue
        if m.eigenvalue.imag < 0:
            continue                     # the built-in names a pair once
        lam = min(ref, key=lambda x: abs(x - m.eigenvalue))
        assert abs(lam - m.eigenvalue) <= 1e-9 * max(abs(lam), 1.0), (lam, m.eigenvalue)
        assert math.isfinite(m.dRe_dKD)
        assert abs(ref[lam] - m.dRe_dKD) <= 1e-9 * max(abs(ref[lam]), 1.0), (m, ref[lam])
    assert sum(m.kind == ModeKind.ZERO for m in ms) == 3
    assert all(abs(d) <= 1e-12 for x, d in ref.items() if abs(x) < 1e-9)
    slip = [m for m in ms if m.name == 'mode (z_R)']
    assert len(slip) == 1 and abs(slip[0].dRe_dKD + 50.0072) < 1e-4


def test_not_defined_only_where_the_split_is_like_sqrt_K():
    # a cluster still defective once the resting space is out: lambda^2 = -K, the FD slope
    # grows like K^-1/2 (does not converge), and the one rule says "not defined" (nan)
    from gyro_rotor.linear.spectrum import zero_K_sensitivities
    A0 = np.array([[0.0, 1.0], [0.0, 0.0]])
    BC = np.array([[0.0, 0.0], [1.0, 0.0]])
    _, d, _, _, r = zero_K_sensitivities(A0, BC)
    assert r == 2 and np.all(np.isnan(d))
    _, (s1, s2) = _fd_slopes(A0, BC)
    assert np.all(np.abs(s2) > 3 * np.abs(s1))           # sqrt(10) per decade
    # the same block with the perturbation on the chain's end (c^T picks the head's rate):
    # e_1 rests for every K, the other root moves linearly: d = (0, -1), both finite
    _, d, _, _, r = zero_K_sensitivities(A0, np.array([[0.0, 0.0], [0.0, 1.0]]))
    assert r == 1 and sorted(d.real) == [-1.0, 0.0]


def test_slow_roots_at_a_huge_K_D_are_reached_not_zero_roots():
    # K_D = 1e7: the slow roots -K_S/K_D (-1e-6, -8e-7 1/s) are smaller than any size
    # threshold for "zero", but they move with K: reached, damped, never a neutral rotor angle
    from gyro_rotor.cli.util import load_scene_with_sets
    from gyro_rotor.linear.system import assess
    ms, v = assess(linearize_scene(load_scene_with_sets('twin_gimbal', ['K_D=1e7'])))
    assert v.verdict == 'asymptotically stable', v.reason
    slow = [m for m in ms if abs(m.eigenvalue) < 1e-5]
    assert len(slow) == 2
    assert all(m.kind == ModeKind.REAL and m.reached_by_drive and m.is_damped
               and not m.rotor_angle for m in slow)


def test_a_singular_potential_gives_one_error_line_and_no_warnings(tmp_path):
    # review finding: numpy's RuntimeWarnings from the generated code came before the ERROR
    import subprocess
    import sys
    (tmp_path / 'one.yaml').write_text(ONE.replace('k*x**2/2', 'k*sqrt(x)'))
    scene = tmp_path / 's.yaml'
    scene.write_text('/**:\n  ros__parameters:\n    system: one.yaml\n    t_end: 0.1\n'
                     '    initial: {q: [0.0], qdot: [0.0], z: [0.0], zdot: [0.1]}\n')
    r = subprocess.run([sys.executable, '-m', 'gyro_rotor', 'simulate', str(scene)],
                       capture_output=True, text=True)
    err = _errors(r.stderr)          # a cold cache first says what it generates
    assert r.returncode == 1 and err.count('\n') == 1, r.stderr
    assert err.startswith('ERROR: ') and 'not finite' in err, r.stderr


@settings(max_examples=8, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 3), m=st.integers(1, 3))
@example(seed=0, n=1, m=3)          # more modes than coordinates: names must collide first
def test_every_mode_has_its_own_name(seed, n, m, tmp_path_factory):
    """eig, the report and the live table tell modes apart by name: one name a mode.

    A name is the dominant coordinate; two modes dominated by one coordinate (twin_gimbal's
    beta1 at 2.52 and 6.11 Hz) carry their frequency (a real root its rate) as well. The
    two roots of a pair are one mode: one name.
    """
    folder = tmp_path_factory.mktemp('names')
    (folder / 'sys.yaml').write_text(yaml.safe_dump(random_system_file(seed, n, m)))
    (folder / 'scene.yaml').write_text(yaml.safe_dump(
        {'/**': {'ros__parameters': {'system': 'sys.yaml', 't_end': 1.0}}}))
    for scene in (load_scene(str(folder / 'scene.yaml')), load_scene('twin_gimbal')):
        ms, verdict = assess(linearize_scene(scene))
        ms = [x for x in ms if x.kind != ModeKind.ZERO]
        one = [x for x in ms if x.kind == ModeKind.REAL or x.eigenvalue.imag > 0]
        assert len({x.name for x in one}) == len(one), [x.name for x in one]
        for x in ms:        # a pair's lower root is named as its upper one
            if x.kind == ModeKind.OSCILLATORY and x.eigenvalue.imag < 0:
                twin = min(one, key=lambda u: abs(u.eigenvalue - x.eigenvalue.conjugate()))
                assert x.name == twin.name
        assert not verdict.slowest_mode or verdict.slowest_mode in {x.name for x in ms}
