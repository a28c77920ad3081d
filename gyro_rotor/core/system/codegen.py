"""Compiled equations of a rotor system: sympy -> Python source -> numba, cached on disk.

:func:`compile_system` derives the equations (:mod:`~gyro_rotor.core.system.equations`),
writes one Python module per system *structure* (names and expressions; the numbers
travel in a parameter array, so changed constants or drives need no new code) and loads
it. The module lives in the cache directory (``$GYRO_ROTOR_CACHE`` or
``~/.cache/gyro_rotor/systems``) under the hash of the structure; numba caches its machine
code beside it (``cache=True``), so the second run loads instead of compiling.

The generated module holds, with ``y = (q, qdot, z, zdot, D)`` (length 2 (n + m) + 1) and
the parameter array ``P`` of :func:`pack`:

``rhs(y, P, out)``      dy/dt (numba): Mbar vdot = F + [0; Q] solved by an unrolled
                        LDL' factorization, Q the drive law (eq. 8 or the sine law),
                        dD/dt = zdot' K_D zdot
``energy(y, P)``        E* (eq. 13, numba)
``jac(y, P, J)``        the exact Jacobian d(rhs)/dy (numba, :func:`_jac_source`): sympy
                        derivatives of Mbar, F and the drive law, common subexpressions,
                        and Mbar^-1 applied numerically by one LDL' factorization
``lin(y, P)``           (Mbar, dF/dq, dF/dv) at y, plain Python, for the linearization

No integrator is generated: the project's integrators and the ensemble
(:mod:`gyro_rotor.numerics.kernel_system`) call ``rhs`` as a numba first-class function
(:attr:`CompiledSystem.first_class`, and ``jac`` as :attr:`CompiledSystem.jac_first_class`),
so their compiled loops are shared by every system and cached once.
"""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path
import time

from gyro_rotor.core.cache import cache_root, import_file, note, write_atomic
from gyro_rotor.core.system.equations import derive, Equations
from gyro_rotor.core.system.system_file import RotorSystem
import numpy as np
import sympy
from sympy.printing.pycode import PythonCodePrinter

__all__ = ['CompiledSystem', 'compile_system', 'pack', 'cache_dir', 'GENERATOR_VERSION',
           'RHS_TYPE', 'JAC_TYPE']

#: bump when the generated code changes, so that old cache entries are not reused
GENERATOR_VERSION = 6
#: parameters per drive in P: K_S, K_D, Omega0, pole_pairs
DRIVE_SLOTS = 4


class _Printer(PythonCodePrinter):
    """Python printer: math.*, small integer powers as products, floats exact (repr)."""

    def __init__(self):
        super().__init__({'fully_qualified_modules': True, 'standard': 'python3'})

    def _print_Float(self, expr):
        return repr(float(expr))

    def _print_Rational(self, expr):
        return repr(float(expr))

    def _print_Pow(self, expr, rational=False):
        b, e = expr.base, expr.exp
        if e.is_Integer and 1 < abs(int(e)) <= 4:
            body = '*'.join([f'({self._print(b)})'] * abs(int(e)))
            return f'({body})' if int(e) > 0 else f'(1.0/({body}))'
        if e == -1:
            return f'(1.0/({self._print(b)}))'
        if e == sympy.Rational(1, 2):
            return f'math.sqrt({self._print(b)})'
        if e == -sympy.Rational(1, 2):
            return f'(1.0/math.sqrt({self._print(b)}))'
        return f'(({self._print(b)})**({self._print(e)}))'


def cache_dir() -> Path:
    """Directory of the generated modules (folder ``systems`` of the cache root).

    The cache root: :func:`gyro_rotor.core.cache.cache_root`.
    """
    return cache_root() / 'systems'


def pack(system: RotorSystem) -> np.ndarray:
    """Parameter array P: the constants (in file order), then K_S, K_D, Omega0, p per drive."""
    drives = [x for d in system.drives for x in (d.K_S, d.K_D, d.Omega0, float(d.pole_pairs))]
    return np.array(list(system.constants.values()) + drives, dtype=float)


def _unpack_lines(eq: Equations, nc: int, indent: str) -> list[str]:
    n, m = eq.n, eq.m
    lines = [f'{indent}q{i} = y[{i}]' for i in range(n)]
    lines += [f'{indent}v{i} = y[{n + i}]' for i in range(n)]
    lines += [f'{indent}z{k} = y[{2 * n + k}]' for k in range(m)]
    lines += [f'{indent}v{n + k} = y[{2 * n + m + k}]' for k in range(m)]
    lines += [f'{indent}c{k} = P[{k}]' for k in range(nc)]
    lines += [f'{indent}O{k} = P[{nc + DRIVE_SLOTS * k + 2}]' for k in range(m)]
    return lines


def _cse_lines(names: list[str], exprs: list, indent: str, printer: _Printer) -> list[str]:
    subs, reduced = sympy.cse(exprs, symbols=sympy.numbered_symbols('w'))
    lines = [f'{indent}{s} = {printer.doprint(e)}' for s, e in subs]
    lines += [f'{indent}{name} = {printer.doprint(e)}' for name, e in zip(names, reduced)]
    return lines


def _drive_lines(eq: Equations, nc: int, indent: str, *, slope: bool = False) -> list[str]:
    """Return the drive law Q_k(z_k, zdot_k) of each rotor (eq. 8: linear, or sine law).

    One text for the right-hand side and the Jacobian: ``slope`` adds dQ_k/dz_k (``Qz``).
    """
    lines = []
    for k in range(eq.m):
        base = nc + DRIVE_SLOTS * k
        KS, KD, pp, v = f'KS{k}', f'KD{k}', f'pp{k}', f'v{eq.n + k}'
        lines += [f'{indent}{KS} = P[{base}]', f'{indent}{KD} = P[{base + 1}]',
                  f'{indent}{pp} = P[{base + 3}]',
                  f'{indent}if {pp} != 0.0:',
                  f'{indent}    Q{k} = -({KS} / {pp}) * math.sin({pp} * z{k}) - {KD} * {v}']
        lines += [f'{indent}    Qz{k} = -{KS} * math.cos({pp} * z{k})'] if slope else []
        lines += [f'{indent}else:', f'{indent}    Q{k} = -{KS} * z{k} - {KD} * {v}']
        lines += [f'{indent}    Qz{k} = -{KS}'] if slope else []
    return lines


def _ldl_lines(N: int, indent: str) -> list[str]:
    """Solve Mbar a = F by an unrolled LDL' factorization (Mbar symmetric positive definite)."""
    lines = []
    for j in range(N):
        s = ' - '.join([f'M{j}_{j}'] + [f'L{j}_{k} * L{j}_{k} * d{k}' for k in range(j)])
        lines.append(f'{indent}d{j} = {s}')
        for i in range(j + 1, N):
            s = ' - '.join([f'M{i}_{j}'] + [f'L{i}_{k} * L{j}_{k} * d{k}' for k in range(j)])
            lines.append(f'{indent}L{i}_{j} = ({s}) / d{j}')
    for i in range(N):
        s = ' - '.join([f'F{i}'] + [f'L{i}_{k} * b{k}' for k in range(i)])
        lines.append(f'{indent}b{i} = {s}')
    for i in reversed(range(N)):
        s = ' - '.join([f'b{i} / d{i}'] + [f'L{k}_{i} * a{k}' for k in range(i + 1, N)])
        lines.append(f'{indent}a{i} = {s}')
    return lines


_HEADER = '''"""Generated by gyro_rotor.core.system.codegen for the rotor system {name!r}.

Structure key {key}; generator version {version}. Do not edit: delete the file to rebuild.
"""
import math

import numpy as np

try:
    from numba import njit
except ImportError:  # plain Python without numba
    def njit(*args, **kwargs):
        if len(args) == 1 and callable(args[0]):
            return args[0]
        return lambda f: f

N = {N}
NQ = {n}
NR = {m}
NY = {ny}

'''


_LDL_HELPERS = '''

@njit(cache=True, error_model='numpy')
def _ldl_factor(M, d):
    """LDL' factorization of the symmetric M in place (L below the diagonal), D in d."""
    n = M.shape[0]
    for j in range(n):
        s = M[j, j]
        for k in range(j):
            s -= M[j, k] * M[j, k] * d[k]
        d[j] = s
        for i in range(j + 1, n):
            s = M[i, j]
            for k in range(j):
                s -= M[i, k] * M[j, k] * d[k]
            M[i, j] = s / d[j]


@njit(cache=True, error_model='numpy')
def _ldl_solve(M, d, B):
    """Solve M X = B in place on the columns of B (M, d from _ldl_factor)."""
    n = M.shape[0]
    for c in range(B.shape[1]):
        for i in range(n):
            s = B[i, c]
            for k in range(i):
                s -= M[i, k] * B[k, c]
            B[i, c] = s
        for i in range(n - 1, -1, -1):
            s = B[i, c] / d[i]
            for k in range(i + 1, n):
                s -= M[k, i] * B[k, c]
            B[i, c] = s
'''


def _jac_symbols(eq: Equations) -> tuple:
    """Names and sympy expressions of jac's pieces: Mbar, F, dMbar/dq, dF/dq, dF/dv.

    Returns (names, exprs, dM, Fq, Fv); the dicts map the index tuples of the non-zero
    derivatives to their names (dM[k, i, j], i >= j: dMbar_ij / dq_k; Fq[i, j]; Fv[i, j]).
    """
    n, N = eq.n, eq.n + eq.m
    zero = sympy.Integer(0)
    names = [f'M{i}_{j}' for i in range(N) for j in range(i + 1)] + [f'F{i}' for i in range(N)]
    exprs = [eq.Mbar[i, j] for i in range(N) for j in range(i + 1)] + list(eq.F)
    dM = {}
    for k in range(n):
        for i in range(N):
            for j in range(i + 1):
                e = sympy.diff(eq.Mbar[i, j], eq.q[k])
                if e != zero:
                    dM[k, i, j] = f'dM{k}_{i}_{j}'
                    names.append(dM[k, i, j])
                    exprs.append(e)
    Fq = {(i, j): f'Fq{i}_{j}' for i in range(N) for j in range(n) if eq.F_q[i, j] != zero}
    Fv = {(i, j): f'Fv{i}_{j}' for i in range(N) for j in range(N) if eq.F_v[i, j] != zero}
    names += list(Fq.values()) + list(Fv.values())
    exprs += [eq.F_q[i, j] for i, j in Fq] + [eq.F_v[i, j] for i, j in Fv]
    return names, exprs, dM, Fq, Fv


def _jac_columns(eq: Equations, dM: dict, Fq: dict, Fv: dict, ind: str) -> list[str]:
    """Lines filling G (N x 2 N): [dG/dx | dG/dv] with G = F + [0; Q] - Mbar a at fixed a."""
    n, m, N = eq.n, eq.m, eq.n + eq.m
    lines = []
    for j in range(n):                  # columns x_j = q_j: dF/dq_j - (dMbar/dq_j) a
        for i in range(N):
            terms = [Fq[i, j]] if (i, j) in Fq else []
            terms += [f'{dM[j, max(i, c), min(i, c)]} * a[{c}, 0]' for c in range(N)
                      if (j, max(i, c), min(i, c)) in dM]
            if terms:
                first, rest = terms[0], terms[1:]
                line = (first if (i, j) in Fq else f'-{first}') + ''.join(
                    f' - {t}' for t in rest)
                lines.append(f'{ind}G[{i}, {j}] = {line}')
    for k in range(m):                  # columns x_{n+k} = z_k: the drive law only
        lines.append(f'{ind}G[{n + k}, {n + k}] = Qz{k}')
    for (i, j), name in Fv.items():     # columns v_j
        lines.append(f'{ind}G[{i}, {N + j}] = {name}')
    for k in range(m):
        lines.append(f'{ind}G[{n + k}, {N + n + k}] -= KD{k}')
    return lines


def _jac_source(system: RotorSystem, eq: Equations, pr: _Printer) -> str:
    """Source of ``jac(y, P, J)``: the exact Jacobian of ``rhs`` (y = (q, qdot, z, zdot, D)).

    With x = (q, z), v = (qdot, zdot) and a = Mbar^-1 (F + [0; Q]) (eqs. 5, 6, 8):

        da/dx_j = Mbar^-1 (dF/dx_j + [0; dQ/dx_j] - (dMbar/dx_j) a),
        da/dv_j = Mbar^-1 (dF/dv_j + [0; dQ/dv_j]),

    dx/dt = v, and d(dD/dt)/dzdot_k = 2 K_D,k zdot_k. Mbar depends on q only, F on (q, v),
    Q_k on (z_k, zdot_k); the derivatives are sympy's (common subexpressions), the 2 N
    solves share one LDL' factorization of Mbar.
    """
    n, m, N = eq.n, eq.m, eq.n + eq.m
    nc = len(system.constants)
    names, exprs, dM, Fq, Fv = _jac_symbols(eq)
    ind = '    '
    body = _unpack_lines(eq, nc, ind) + _cse_lines(names, exprs, ind, pr)
    body += _drive_lines(eq, nc, ind, slope=True)
    body += [f'{ind}Mb = np.empty(({N}, {N}))', f'{ind}dg = np.empty({N})',
             f'{ind}a = np.empty(({N}, 1))', f'{ind}G = np.zeros(({N}, {2 * N}))']
    body += [f'{ind}Mb[{i}, {j}] = M{i}_{j}' for i in range(N) for j in range(i + 1)]
    body += [f'{ind}a[{i}, 0] = F{i}' + (f' + Q{i - n}' if i >= n else '') for i in range(N)]
    body += [f'{ind}_ldl_factor(Mb, dg)', f'{ind}_ldl_solve(Mb, dg, a)']
    body += _jac_columns(eq, dM, Fq, Fv, ind)
    body += [f'{ind}_ldl_solve(Mb, dg, G)',
             f'{ind}for r in range({2 * N + 1}):',
             f'{ind}    for c in range({2 * N + 1}):',
             f'{ind}        J[r, c] = 0.0',
             f'{ind}for i in range({N}):',
             f'{ind}    J[IX[i], IV[i]] = 1.0',
             f'{ind}    for c in range({N}):',
             f'{ind}        J[IV[i], IX[c]] = G[i, c]',
             f'{ind}        J[IV[i], IV[c]] = G[i, {N} + c]']
    body += [f'{ind}J[{2 * N}, {2 * n + m + k}] = 2.0 * KD{k} * v{n + k}' for k in range(m)]
    ix = list(range(n)) + [2 * n + k for k in range(m)]
    iv = [n + i for i in range(n)] + [2 * n + m + k for k in range(m)]
    head = (f'\n\n#: state indices of x = (q, z) and of v = (qdot, zdot)\n'
            f'IX = np.array({ix}, dtype=np.int64)\nIV = np.array({iv}, dtype=np.int64)\n')
    return (head + _LDL_HELPERS + "\n\n@njit(cache=True, error_model='numpy')\n"
            'def jac(y, P, J):\n    """Exact Jacobian d(rhs)/dy at y into J (NY x NY)."""\n'
            + '\n'.join(body) + '\n')


def _source(system: RotorSystem, eq: Equations) -> str:
    n, m, N = eq.n, eq.m, eq.n + eq.m
    nc = len(system.constants)
    pr = _Printer()
    out = [_HEADER.format(name=system.name, key=system.structure_key(),
                          version=GENERATOR_VERSION, N=N, n=n, m=m, ny=2 * N + 1)]
    # rhs
    names = [f'M{i}_{j}' for i in range(N) for j in range(i + 1)] + [f'F{i}' for i in range(N)]
    exprs = [eq.Mbar[i, j] for i in range(N) for j in range(i + 1)] + list(eq.F)
    body = _unpack_lines(eq, nc, '    ') + _cse_lines(names, exprs, '    ', pr)
    body += _drive_lines(eq, nc, '    ')
    body += ['    diss = 0.0'] + [f'    diss += KD{k} * v{n + k} * v{n + k}' for k in range(m)]
    body += [f'    F{n + k} = F{n + k} + Q{k}' for k in range(m)]
    body += _ldl_lines(N, '    ')
    body += [f'    out[{i}] = v{i}' for i in range(n)]
    body += [f'    out[{n + i}] = a{i}' for i in range(n)]
    body += [f'    out[{2 * n + k}] = v{n + k}' for k in range(m)]
    body += [f'    out[{2 * n + m + k}] = a{n + k}' for k in range(m)]
    body += [f'    out[{2 * N}] = diss']
    out.append("@njit(cache=True, error_model='numpy')\ndef rhs(y, P, out):\n"
               '    """dy/dt of y = (q, qdot, z, zdot, D)."""\n' + '\n'.join(body) + '\n')
    # energy
    body = _unpack_lines(eq, nc, '    ')
    body += _cse_lines(['kin', 'pot'], [eq.kinetic, eq.V], '    ', pr)
    body += ['    U = 0.0']
    for k in range(m):
        base = nc + DRIVE_SLOTS * k
        body += [f'    KS = P[{base}]', f'    pp = P[{base + 3}]', '    if pp != 0.0:',
                 f'        U += (KS / (pp * pp)) * (1.0 - math.cos(pp * z{k}))', '    else:',
                 f'        U += 0.5 * KS * z{k} * z{k}']
    body += ['    return kin + pot + U']
    out.append("\n\n@njit(cache=True, error_model='numpy')\ndef energy(y, P):\n"
               '    """E* (eq. 13) at y."""\n' + '\n'.join(body) + '\n')
    out.append(_jac_source(system, eq, pr))
    # linearization pieces
    Mn = [f'M{i}_{j}' for i in range(N) for j in range(N)]
    Fqn = [f'Fq{i}_{j}' for i in range(N) for j in range(n)]
    Fvn = [f'Fv{i}_{j}' for i in range(N) for j in range(N)]
    exprs = ([eq.Mbar[i, j] for i in range(N) for j in range(N)]
             + [eq.F_q[i, j] for i in range(N) for j in range(n)]
             + [eq.F_v[i, j] for i in range(N) for j in range(N)])
    body = _unpack_lines(eq, nc, '    ') + _cse_lines(Mn + Fqn + Fvn, exprs, '    ', pr)

    def mat(nm, r, c):
        return '[' + ', '.join('[' + ', '.join(f'{nm}{i}_{j}' for j in range(c)) + ']'
                               for i in range(r)) + ']'
    body.append(f'    return ({mat("M", N, N)}, {mat("Fq", N, n)}, {mat("Fv", N, N)})')
    out.append('\n\ndef lin(y, P):\n    """(Mbar, dF/dq, dF/dv) at y, without the drive '
               'terms."""\n' + '\n'.join(body) + '\n')
    return ''.join(out)


@dataclasses.dataclass
class CompiledSystem:
    """The generated module of a system structure and how it was obtained."""

    key: str
    module: object
    path: Path
    from_cache: bool
    seconds: float

    @property
    def rhs(self):
        """Return the compiled right-hand side (arguments y, P, out)."""
        return self.module.rhs

    @property
    def energy(self):
        """Return the compiled E* (arguments y, P)."""
        return self.module.energy

    @functools.cached_property
    def first_class(self):
        """Return ``rhs`` as a numba first-class function of type RHS_TYPE (or ``rhs``).

        A kernel called with it is compiled once for the function *type*, not for this
        function, so numba's on-disk cache serves every system (a jitted function passed
        as is would compile, uncached, a specialization per system and process).
        """
        if not hasattr(self.module.rhs, 'get_compile_result'):   # no numba: plain Python
            return self.module.rhs
        return _FirstClass(self.module.rhs, RHS_TYPE)

    @property
    def jac(self):
        """Return the compiled exact Jacobian (arguments y, P, J)."""
        return self.module.jac

    @functools.cached_property
    def jac_first_class(self):
        """Return ``jac`` as a numba first-class function of type JAC_TYPE (or ``jac``)."""
        if not hasattr(self.module.jac, 'get_compile_result'):   # no numba: plain Python
            return self.module.jac
        return _FirstClass(self.module.jac, JAC_TYPE)


_LOADED: dict[str, CompiledSystem] = {}

try:
    from numba.core import types as _nbtypes
    from numba.core.types import WrapperAddressProtocol
    _ARRAY = _nbtypes.float64[::1]
    #: the type of a generated right-hand side rhs(y, P, out) as a first-class function
    RHS_TYPE = _nbtypes.void(_ARRAY, _ARRAY, _ARRAY)
    #: the type of a generated Jacobian jac(y, P, J) as a first-class function
    JAC_TYPE = _nbtypes.void(_ARRAY, _ARRAY, _nbtypes.float64[:, ::1])
except ImportError:  # pragma: no cover - without numba nothing is compiled
    WrapperAddressProtocol, RHS_TYPE, JAC_TYPE = object, None, None


class _FirstClass(WrapperAddressProtocol):
    """A compiled function as numba's wrapper-address protocol: typed FunctionType(sig)."""

    def __init__(self, dispatcher, sig):
        dispatcher.compile(sig)
        cres = dispatcher.get_compile_result(sig)
        self.dispatcher = dispatcher       # keeps the machine code alive
        self.sig = sig
        self.address = cres.library.get_pointer_to_function(cres.fndesc.llvm_cfunc_wrapper_name)

    def __call__(self, y, P, out):
        """Call the function from Python."""
        self.dispatcher(y, P, out)

    def __wrapper_address__(self):
        """Return the address of the compiled C wrapper of the function."""
        return self.address

    def signature(self):
        """Return the numba type of the function: RHS_TYPE or JAC_TYPE."""
        return self.sig


def compile_system(system: RotorSystem, *, warm: bool = True,
                   progress=note) -> CompiledSystem:
    """Return the compiled equations of ``system``, generating them only if not cached.

    ``warm`` runs ``rhs`` and ``energy`` once, so that numba compiles (or loads from its
    cache) now and not at the first use; ``jac`` compiles at its first use (a stiff run,
    :attr:`CompiledSystem.jac_first_class`), so that other runs do not wait for it. When
    the code is generated (first use of a structure: minutes for tens of rotors),
    ``progress(text)`` gets one line per stage with its time (default: to stderr; None:
    silent).
    """
    key = f'{system.structure_key()}_v{GENERATOR_VERSION}'
    if key in _LOADED:
        return _LOADED[key]
    start = time.perf_counter()
    folder = cache_dir() / key
    path = folder / f'gen_{key}.py'
    from_cache = path.is_file()
    say = progress if (progress is not None and not from_cache) else (lambda _text: None)
    if not from_cache:
        say(f'generating the equations of system {system.name} (n = {system.n}, m = '
            f'{system.m}) on first use; later runs take them from {folder}')
        eq = derive(system)
        say(f'  derived in {time.perf_counter() - start:.1f} s; writing the code')
        source = _source(system, eq)
        say(f'  code written at {time.perf_counter() - start:.1f} s; compiling (numba)')
        write_atomic(path, source)
    module = import_file(path, f'gyro_rotor_generated_{key}')
    if warm:
        ny = 2 * (system.n + system.m) + 1
        y = np.zeros(ny)
        P = pack(system)
        module.rhs(y, P, np.empty(ny))
        module.energy(y, P)      # jac: compiled (or loaded) at its first use, a stiff run
    compiled = CompiledSystem(key=key, module=module, path=path, from_cache=from_cache,
                              seconds=time.perf_counter() - start)
    say(f'  ready in {compiled.seconds:.1f} s')
    _LOADED[key] = compiled
    return compiled
