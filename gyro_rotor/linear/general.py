"""Linearization of any rotor system and the paper's claims (a) to (d), checked by meaning.

About a steady motion (q0, qdot0, z0, zdot = 0) the state x = (q, z, qdot, zdot) obeys

    x' = A(K) x,   A(K) = [[0, I], [Mbar^-1 G_x, Mbar^-1 G_v]] = A_0 - K b c',

with Mbar, G_x = [dF/dq | dQ/dz], G_v = dF/dv + [0; dQ/dzdot] from the generated
equations (:mod:`gyro_rotor.core.system.codegen`), exact (symbolic) derivatives. K is the
common drive damping of the drives varied (all, or one); c' picks their zdot, b =
[0; Mbar^-1 e_z]. The coordinates that move on the steady motion must enter the
equations only through combinations that stay constant, so that A does not change along
the motion; :func:`linearize` checks this.

The claims (Magnus 1980, eqs. 13-17 and the footnote; docs MODEL.md section 8):

(a) K = 0: every root on the imaginary axis; zero roots are structural (a cyclic
    coordinate) and named by their eigenvector.
(b) K > 0: the roots of every mode the drives reach (PBH: its eigenvector at K = 0 has
    a non-zero zdot part) lie in the open left half plane, and exactly the unreached ones
    stay on the axis, at their K = 0 values (Hagedorn's exclusion).
(c) K -> infinity: the roots tend to the spectrum of the locked system (z = 0 held,
    computed separately), plus m real roots to -infinity and m to 0.
(d) every K* where a pair meets on the real axis or leaves it, with its kind and meeting
    point; net, m pairs meet.

The claims are decided by the one checker of every system, :mod:`gyro_rotor.linear.claims`,
on :meth:`GeneralLinear.drive_system`.
"""

from __future__ import annotations

import dataclasses
import math

from gyro_rotor.core.scene import check_steady, Scene
from gyro_rotor.core.system.model import GeneralModel
from gyro_rotor.errors import ParameterError, SceneError
import numpy as np

__all__ = ['GeneralLinear', 'linearize_scene', 'modes', 'Mode', 'check_claims', 'damped_newton',
           'solve_steady', 'REL_AXIS']

#: roots with |Re| <= REL_AXIS * spectral radius count as on the imaginary axis (mode
#: labels and the predicted verdict; the claims use each root's own resolution)
REL_AXIS = 1e-9
#: a mode is reached when the zdot part of its unit eigenvector exceeds this
REACH_TOL = 1e-7


@dataclasses.dataclass(frozen=True)
class GeneralLinear:
    """A(K) = A0 - K b c' about a steady motion (module doc), with names of the states."""

    A0: np.ndarray
    b: np.ndarray
    c: np.ndarray
    K_D: float
    A_locked: np.ndarray
    names: tuple
    n: int
    m: int
    fast_rates: np.ndarray
    K_each: np.ndarray
    A_cons: np.ndarray
    b_all: np.ndarray
    c_all: np.ndarray
    K_all: np.ndarray
    vary: tuple

    def drive_system(self):
        """Return the :class:`~gyro_rotor.linear.claims.DriveSystem` of every drive."""
        from gyro_rotor.linear.claims import DriveSystem
        return DriveSystem(A0=self.A_cons, B=self.b_all, C=self.c_all.T, K_scene=self.K_all,
                           vary=self.vary)

    def A_scene(self) -> np.ndarray:
        """Return A with every drive at its own K_D (the scene's spectrum)."""
        return self.A_cons - self.b_all @ np.diag(self.K_all) @ self.c_all.T

    def A_common(self, K: float) -> np.ndarray:
        """Return A with every drive at the same K_D = K."""
        return self.A_cons - K * (self.b_all @ self.c_all.T)

    def A(self, K: float) -> np.ndarray:
        """Return the matrix for drive damping K of the drives varied."""
        return self.A0 - K * (self.b @ self.c.T)

    def eig(self, K: float) -> np.ndarray:
        """Return the eigenvalues of A(K)."""
        return np.linalg.eigvals(self.A(K))


def _parts(model: GeneralModel, y: np.ndarray):
    return model.lin(y)


def _A0(model: GeneralModel, y: np.ndarray, drives, which) -> tuple:
    """A0 (varied drives undamped), b, c of the varied drives, A_locked, fast rates, A_cons."""
    n, m, N = model.n, model.m, model.N
    Mbar, Fq, Fv = _parts(model, y)
    Gx = np.zeros((N, N))
    Gx[:, :n] = Fq
    Gv = Fv.copy()
    z = y[2 * n:2 * n + m]
    for k, d in enumerate(drives):
        p = d.pole_pairs
        Gx[n + k, n + k] = -d.K_S * (math.cos(p * z[k]) if p else 1.0)
    Minv = np.linalg.inv(Mbar)
    A_cons = np.block([[np.zeros((N, N)), np.eye(N)], [Minv @ Gx, Minv @ Gv]])
    for k, d in enumerate(drives):
        if k not in which:
            Gv[n + k, n + k] -= d.K_D
    A0 = np.block([[np.zeros((N, N)), np.eye(N)], [Minv @ Gx, Minv @ Gv]])
    E = np.zeros((N, len(which)))
    for j, k in enumerate(which):
        E[n + k, j] = 1.0
    b = np.vstack([np.zeros((N, len(which))), Minv @ E])
    c = np.vstack([np.zeros((N, len(which))), E])
    # the locked system: z of the varied drives held at 0 (their rows and columns removed)
    keep = [i for i in range(N) if i - n not in which]
    Mi = np.linalg.inv(Mbar[np.ix_(keep, keep)]) if keep else np.zeros((0, 0))
    r = len(keep)
    A_locked = np.block([[np.zeros((r, r)), np.eye(r)],
                         [Mi @ Gx[np.ix_(keep, keep)], Mi @ Gv[np.ix_(keep, keep)]]])
    fast = np.linalg.eigvalsh(Minv[np.ix_([n + k for k in which], [n + k for k in which])])
    return A0, b, c, A_locked, fast, A_cons


def linearize_scene(scene: Scene, *, drive: str | None = None,
                    model: GeneralModel | None = None) -> GeneralLinear:
    """Linearize a general scene about its steady motion (checked steady and stationary).

    ``drive``: vary only that rotor's K_D (default: all drives together).
    """
    model = model or scene.make_model()
    check_steady(scene, model)
    system = scene.system
    if drive is None:
        which = list(range(system.m))
    elif drive in system.rotors:
        which = [system.rotors.index(drive)]
    else:
        raise ParameterError(f"unknown rotor '{drive}'; rotors of {system.name}: "
                             f"{', '.join(system.rotors)}")
    y0 = scene.steady_state(model)
    A0, b, c, A_locked, fast, A_cons = _A0(model, y0, system.drives, which)
    everyone = list(range(system.m))
    _, b_all, c_all, *_ = _A0(model, y0, system.drives, everyone)
    if np.any(np.asarray(scene.steady_qdot) != 0):
        y1 = y0.copy()
        y1[:model.n] += 0.37 * np.asarray(scene.steady_qdot)
        A1 = _A0(model, y1, system.drives, which)[0]
        if not np.allclose(A0, A1, rtol=1e-8, atol=1e-10 * np.abs(A0).max()):
            raise SceneError(f'scene {scene.name}: the linearization changes along the steady '
                             'motion (the moving coordinates are not cyclic): no constant '
                             'A matrix to analyse')
    if not np.all(np.isfinite(A0)):
        raise SceneError(f'scene {scene.name}: the linearization is not finite')
    Ks = np.array([system.drives[k].K_D for k in which])
    coords = system.coordinates
    names = tuple(coords) + tuple(f'z_{r}' for r in system.rotors) + tuple(
        f'{q}_dot' for q in coords) + tuple(f'zdot_{r}' for r in system.rotors)
    return GeneralLinear(A0=A0, b=b, c=c, K_D=float(Ks.max()), A_locked=A_locked, names=names,
                         n=model.n, m=model.m, fast_rates=fast, K_each=Ks, A_cons=A_cons,
                         b_all=b_all, c_all=c_all,
                         K_all=np.array([d.K_D for d in system.drives]), vary=tuple(which))


@dataclasses.dataclass(frozen=True)
class Mode:
    """One root: value, whether the drives reach its mode (PBH at K = 0) and its name."""

    value: complex
    reached: bool
    name: str
    structural_zero: bool = False


def _scale(lam: np.ndarray) -> float:
    return max(1.0, float(np.abs(lam).max())) if lam.size else 1.0


def _dominant(lin: GeneralLinear, v: np.ndarray) -> str:
    N = lin.n + lin.m
    w = np.abs(v[:N]) + np.abs(v[N:])
    return lin.names[int(np.argmax(w))]


def modes(lin: GeneralLinear, K: float | None = None) -> list[Mode]:
    """Roots of A(K) (default: the scene's own K_D), each with its PBH reach and a name.

    A root is unreached when it is one of the K = 0 roots whose eigenvector has no zdot
    part (the PBH test); those stay where they are for every K.
    """
    A = lin.A_scene() if K is None else lin.A_common(K)
    un, zeros, scale = _unreached(lin)
    lam, V = np.linalg.eig(A)
    out = []
    for i, value in enumerate(lam):
        v = V[:, i] / np.linalg.norm(V[:, i])
        zero = abs(value) <= 1e-7 * scale
        unreached = bool(un.size) and float(np.min(np.abs(un - value))) <= 1e-7 * scale and \
            float(np.abs(lin.c_all.T @ v).max()) <= REACH_TOL
        if zero:
            label = f'zero root (cyclic {_dominant(lin, v)})'
        else:
            label = f'{"unreached mode" if unreached else "mode"} ({_dominant(lin, v)})'
        out.append(Mode(complex(value), not (zero or unreached), label, bool(zero)))
    return out


def _unreached(lin: GeneralLinear) -> tuple[np.ndarray, np.ndarray, float]:
    """Non-zero roots at K = 0 whose eigenvectors have no zdot part, zero roots, scale."""
    lam0, V0 = np.linalg.eig(lin.A_cons)
    scale = _scale(lam0)
    zero = np.abs(lam0) <= 1e-7 * scale
    un = []
    for i in np.flatnonzero(~zero):
        v = V0[:, i] / np.linalg.norm(V0[:, i])
        if float(np.abs(lin.c_all.T @ v).max()) <= REACH_TOL:
            un.append(lam0[i])
    return np.array(un, dtype=complex), lam0[zero], scale


def check_claims(lin: GeneralLinear):
    """Check claims (a) to (d) (module doc): :func:`gyro_rotor.linear.claims.check`."""
    from gyro_rotor.linear.claims import check
    return check(lin.drive_system())


def damped_newton(acc, u, tol: float, *, max_iter: int = 60,
                  min_step: float = 1e-6) -> tuple:
    """Solve acc(u) = 0 for u by damped Newton; return (u, acc(u)).

    The Jacobian by central differences (steps 1e-7 max(1, |u_j|)), the Newton step by
    least squares (a rank-deficient Jacobian: a cyclic coordinate), halved down to
    ``min_step`` until |acc| falls; stops at |acc| <= tol, at a non-finite acc or after
    ``max_iter`` steps. The steady motions of a system file (:func:`solve_steady`) and of
    a Campbell diagram's family (:mod:`gyro_rotor.linear.campbell`) are solved by it.
    """
    u = np.array(u, dtype=float)
    r = acc(u)
    for _ in range(max_iter):
        if not np.all(np.isfinite(r)) or np.abs(r).max() <= tol:
            break
        J = np.empty((len(r), len(u)))
        for j in range(len(u)):
            h = 1e-7 * max(1.0, abs(u[j]))
            e = np.zeros(len(u))
            e[j] = h
            J[:, j] = (acc(u + e) - acc(u - e)) / (2 * h)
        du = np.linalg.lstsq(J, -r, rcond=None)[0]
        step = 1.0
        while step > min_step:
            r_new = acc(u + step * du)
            if np.all(np.isfinite(r_new)) and np.abs(r_new).max() < np.abs(r).max():
                break
            step *= 0.5
        u = u + step * du
        r = acc(u)
    return u, r


def solve_steady(scene: Scene, *, max_iter: int = 50) -> tuple:
    """Newton for (q, z) with qdot = steady.qdot held: the accelerations vanish.

    Returns (q, z, largest |acceleration|) from the scene's steady guess.
    """
    model = scene.make_model()
    n, m = model.n, model.m
    x = np.concatenate([scene.steady_q, scene.steady_z]).astype(float)

    def acc(x):
        y = model.state(x[:n], scene.steady_qdot, x[n:], np.zeros(m))
        f = model.rhs(0.0, y)
        return np.concatenate([f[n:2 * n], f[2 * n + m:2 * n + 2 * m]])
    x, r = damped_newton(acc, x, 1e-13 * max(1.0, model.rate()), max_iter=max_iter,
                         min_step=1e-4)
    return x[:n], x[n:], float(np.abs(r).max())
