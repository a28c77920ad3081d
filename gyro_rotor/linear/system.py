"""The one linearization of every scene, and the paper's claims (a) to (d), checked by meaning.

About a steady motion (q0, qdot0, z0, zdot = 0) the state x = (q, z, qdot, zdot) obeys

    x' = A(K) x,   A(K) = [[0, I], [Mbar^-1 G_x, Mbar^-1 G_v]] = A_0 - K b c',

K the common drive damping of the drives varied (all, or one); c' picks their zdot, b =
[0; Mbar^-1 e_z]. Every system offers these pieces itself, as
:class:`~gyro_rotor.core.linearize.LinearParts` (``linear_parts`` of the scene's system):
a system file's are the exact (symbolic) derivatives of its generated equations
(:mod:`gyro_rotor.core.system.codegen`), Mbar, G_x = [dF/dq | dQ/dz], G_v = dF/dv +
[0; dQ/dzdot], about its checked steady motion
(:meth:`~gyro_rotor.core.system.generated.GeneratedSystem.linear_parts`: the coordinates
that move must enter the equations only through combinations that stay constant, so that
A does not change along the motion); the built-in centrifuge's come from its analytic
linearization (:mod:`gyro_rotor.core.linearize`: Magnus 1980, eqs. 18, 19, 23 in the
coordinates of solution II or I, and its reduced models), one drive: b, c its torque
direction and zdot. :func:`linearize_scene` builds one :class:`Linearization` of them for
any scene; the centrifuge's carries its
:class:`~gyro_rotor.core.linearize.LinearSystem` as ``analytic`` (its modes are named by
modal energy and tracked from K_D = 0, :mod:`gyro_rotor.linear.stability`).

The claims (Magnus 1980, eqs. 13-17 and the footnote; docs MODEL.md section 8):

(a) K = 0: every root on the imaginary axis; zero roots are structural (a cyclic
    coordinate) and named by their eigenvector.
(b) K > 0: the roots of every mode the drives reach (its root at K = 0 is not on the
    unobservable subspace of (C, A0), :func:`gyro_rotor.linear.claims.fixed_subspace`: the
    one rule of reach, :func:`gyro_rotor.linear.stability.classify`) lie in the open left
    half plane, and exactly the unreached ones
    stay on the axis, at their K = 0 values (Hagedorn's exclusion).
(c) K -> infinity: the roots tend to the spectrum of the locked system (z = 0 held,
    computed separately), plus m real roots to -infinity and m to 0.
(d) every K* where a pair meets on the real axis or leaves it, with its kind and meeting
    point; net, m pairs meet.

The claims are decided by the one checker of every system, :mod:`gyro_rotor.linear.claims`,
on :meth:`Linearization.drive_system` (:func:`check_claims`).
"""

from __future__ import annotations

import dataclasses
import math

from gyro_rotor.core.linearize import analytic_parts, Coords, LinearParts, LinearSystem
from gyro_rotor.core.scene import Scene
from gyro_rotor.core.system.model import GeneralModel
from gyro_rotor.linear.stability import judge, Mode, ModeKind, named_modes
import numpy as np

__all__ = ['Linearization', 'linearize_scene', 'from_analytic', 'modes', 'distinct_names',
           'assess', 'check_claims', 'dominant', 'name_roots']


@dataclasses.dataclass(frozen=True)
class Linearization:
    """A(K) = A0 - K b c' about a scene's steady motion (module doc), with the states' names.

    ``A0``, ``b``, ``c``: the drives varied (``vary``) undamped, the others at their K_D;
    ``A_cons``, ``b_all``, ``c_all``, ``K_all``: every drive (A_cons: all undamped);
    ``names`` the states, ``coordinate`` the coordinate each state belongs to (a rate
    belongs to its angle); ``fast_rates`` the eigenvalues of c' b (the roots that escape
    like -K c' b); ``A_locked`` the locked system (the varied drives' z held at 0).
    ``analytic``: the built-in centrifuge's analytic linearization, else None (its modes
    are named by modal energy, a system file's by coordinate: :func:`modes`); ``coords``
    the coordinates it is written in; ``about`` the steady motion in words.
    """

    A0: np.ndarray
    b: np.ndarray
    c: np.ndarray
    K_D: float
    A_locked: np.ndarray
    names: tuple
    coordinate: tuple
    fast_rates: np.ndarray
    A_cons: np.ndarray
    b_all: np.ndarray
    c_all: np.ndarray
    K_all: np.ndarray
    vary: tuple
    analytic: LinearSystem | None = None
    coords: Coords = Coords.GENERAL
    about: str = ''
    #: the modes already classified, by K (:func:`modes`: once per K and command)
    classified: dict = dataclasses.field(default_factory=dict, init=False, repr=False,
                                         compare=False)

    @property
    def m(self) -> int:
        """Return the number of drives."""
        return self.b_all.shape[1]

    @property
    def n(self) -> int:
        """Return the number of coordinates q (those that are not a drive's lag z)."""
        return len(set(self.coordinate)) - self.m

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


def _locked(A0: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Return the locked system: the varied drives' z held at 0 by their torques (module doc).

    The torques u that keep zdot' = c'(A0 x + b u) = 0 give x' = P A0 x, P = I - b (c'b)^-1
    c'; the states z (whose rate is zdot: the rows of A0 equal to c') and zdot are dropped.
    """
    N = A0.shape[0]
    P = np.eye(N) - b @ np.linalg.solve(c.T @ b, c.T)
    z = [int(np.flatnonzero(np.all(A0 == c[:, j], axis=1))[0]) for j in range(c.shape[1])]
    zdot = [int(np.argmax(c[:, j])) for j in range(c.shape[1])]
    keep = [i for i in range(N) if i not in z and i not in zdot]
    return (P @ A0)[np.ix_(keep, keep)]


def linearize_scene(scene: Scene, *, drive: str | None = None,
                    model: GeneralModel | None = None) -> Linearization:
    """Linearize any scene about its steady motion: the linear pieces its system offers.

    ``linear_parts`` of the scene's system (the centrifuge's analytic linearization, a
    system file's exact derivatives of its generated equations about its checked steady
    motion); ``drive``: vary only that rotor's K_D (default: all drives together).
    """
    return _linearization(scene.system.linear_parts(scene, drive, model))


def from_analytic(ls: LinearSystem) -> Linearization:
    """Return the centrifuge's analytic linearization ``ls`` as a :class:`Linearization`."""
    return _linearization(analytic_parts(ls))


def _linearization(parts: LinearParts) -> Linearization:
    """Return the :class:`Linearization` of a system's linear pieces (module doc).

    K_D the largest of the varied drives', the locked system (:func:`_locked`) and the
    fast rates (eigenvalues of c' b) from A0, b, c.
    """
    p = parts
    return Linearization(A0=p.A0, b=p.b, c=p.c, K_D=float(p.K_all[list(p.vary)].max()),
                         A_locked=_locked(p.A0, p.b, p.c), names=p.names,
                         coordinate=p.coordinate, fast_rates=np.linalg.eigvalsh(p.c.T @ p.b),
                         A_cons=p.A_cons, b_all=p.b_all, c_all=p.c_all, K_all=p.K_all,
                         vary=p.vary, analytic=p.analytic, coords=p.coords, about=p.about)


def dominant(lin: Linearization, v: np.ndarray) -> str:
    """Return the coordinate that holds most of eigenvector ``v`` (its angle and rate).

    Of coordinates that hold equal shares within 1e-9 (a cyclic direction such as
    centrifuge_euler's psi at fixed phi_M + psi), the first in the system's order.
    """
    order = list(dict.fromkeys(lin.coordinate))
    w = np.zeros(len(order))
    for i, name in enumerate(lin.coordinate):
        w[order.index(name)] += abs(v[i])
    return order[int(np.flatnonzero(w >= (1.0 - 1e-9) * w.max())[0])]


def _kernel(A: np.ndarray) -> np.ndarray:
    """Return an orthonormal basis of the kernel of ``A`` (numerical rank, numpy's rule)."""
    _, s, vh = np.linalg.svd(A)
    return vh[s <= s.max(initial=0.0) * max(A.shape) * np.finfo(float).eps].conj().T


def _on_kernel(null: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Return zero root eigenvector ``v`` projected on the kernel ``null`` (if it lies there).

    A cyclic coordinate's two zero roots are one Jordan block (its shift, and the
    neighbouring steady motions of its family): the computed pair splits by about
    sqrt(eps) ||A|| (centrifuge_euler: +-1.2e-7j) and its two vectors carry that much of
    the generalized vector. The kernel (:func:`_kernel`) is exact to round-off: both roots
    are named by the cyclic direction it holds.
    """
    w = null @ (null.conj().T @ v)
    return w if np.linalg.norm(w) >= 0.5 * np.linalg.norm(v) else v


def modes(lin: Linearization, K: float | None = None) -> list[Mode]:
    """Return the modes of A(K) (default: every drive at its own K_D) the linearization offers.

    The centrifuge: its named modes, one per complex pair, from the analytic linearization
    it carries (:func:`gyro_rotor.linear.stability.named_modes`); a system file: every root
    (:func:`_modes_by_coordinate`). Classified once per K (``lin.classified``).
    """
    key = None if K is None else float(K)
    if key not in lin.classified:
        lin.classified[key] = tuple(
            _modes_by_coordinate(lin, K) if lin.analytic is None else
            named_modes(lin.analytic, K, lin.drive_system()))
    return list(lin.classified[key])


def assess(lin: Linearization, K: float | None = None) -> tuple:
    """Return the modes of A(K) (:func:`modes`, :func:`distinct_names`) and their verdict.

    One rule (:class:`Verdict`) for ``eig``, the analysis' prediction and the sweeps.
    """
    ms = distinct_names(modes(lin, K))
    Ks = lin.K_all if K is None else np.array([float(K)])
    return ms, judge(ms, not np.any(Ks > 0))


def _modes_by_coordinate(lin: Linearization, K: float | None) -> list[Mode]:
    """Return every root of A(K), named by its dominant coordinate, with its reach.

    Reach and damping: :func:`~gyro_rotor.linear.stability.classify` (one rule for every
    system: a root on the fixed subspace of A(0) is unreached and stays where it is for
    every K). ``eigenvalue_K_D0`` is the root at K = 0 the root is followed from
    (eigenvector continuity), ``dRe_dKD`` its sensitivity there to a common K (nan, not
    defined, for a root of a cluster still defective once the resting space is out:
    :func:`gyro_rotor.linear.spectrum.zero_K_sensitivities`), ``resolution`` its round-off
    (:func:`gyro_rotor.linear.roundoff.resolutions`). A zero root whose
    eigenvector is mostly a rotor angle z is ``rotor_angle`` (no drive stiffness).
    """
    from gyro_rotor.linear.roundoff import floor, nearest, resolution
    from gyro_rotor.linear.spectrum import unit_eig
    from gyro_rotor.linear.stability import classify
    Ks = lin.K_all if K is None else np.full(len(lin.K_all), float(K))
    A = lin.A_scene() if K is None else lin.A_common(K)
    scale = max(1.0, float(np.abs(np.linalg.eigvals(lin.A_cons)).max(initial=0.0)))
    lam, V = unit_eig(A)
    lam0, dre = _followed(lin, Ks, lam)
    # one eigen-decomposition, two scales: the imaginary parts' round-off at that of A_cons
    # (below), the real parts' at that of A with the floor of A_cons (roundoff.resolutions)
    s_cons = max(np.linalg.norm(lin.A_cons), 1.0)
    lam_r, res_i = resolution(A, scale=s_cons)
    res_r = np.maximum(res_i * (np.linalg.norm(A) / s_cons), floor(lin.A_cons))
    angles = {lin.coordinate[i] for i in np.flatnonzero(np.any(lin.c_all != 0, axis=1))}
    zeros = np.abs(lam) <= 1e-7 * scale
    null = _kernel(A) if zeros.any() else None          # one SVD for every zero root
    out = []
    for i, value in enumerate(lam):
        v = V[:, i]
        zero = bool(zeros[i])
        coord = dominant(lin, _on_kernel(null, v) if zero else v)
        value = complex(value)
        re = value.real
        near = int(nearest(lam_r, value)[0])
        res = float(res_r[near])
        # complex beyond the root's own round-off at the scale of A_cons (as the centrifuge's
        # pencil: not of the escaping roots of a large K), not beyond a scale of the whole
        # matrix (a stiff drive's K_S)
        im_res = float(res_i[near])
        kind = (ModeKind.ZERO if zero else ModeKind.OSCILLATORY if abs(value.imag) > im_res
                else ModeKind.REAL)
        on_axis = abs(re) <= res
        out.append(Mode(name=coord, eigenvalue=value, freq_hz=abs(value.imag) / (2 * math.pi),
                        zeta=0.0 if zero or on_axis else -re / abs(value),
                        tau=-1.0 / re if re < 0 and not on_axis else math.inf,
                        reached_by_drive=not zero, dRe_dKD=float(dre[i]),
                        kind=kind, eigenvalue_K_D0=complex(lam0[i]), resolution=res,
                        rotor_angle=zero and coord in angles))
    out = classify(out, lin.drive_system(), Ks)
    return [dataclasses.replace(m, name=(
        f'zero root (cyclic {m.name})' if m.kind == ModeKind.ZERO else
        f'{"mode" if m.reached_by_drive else "unreached mode"} ({m.name})')) for m in out]


def distinct_names(out: list[Mode]) -> list[Mode]:
    """Give modes that share a name (the dominant coordinate of two modes) their frequency.

    The name labels a mode in ``eig``, the report, the ``analysis_modes`` topic and the
    live table; two modes called 'mode (beta1)' could not be told apart there. A pair's
    two roots keep one name (the same frequency); a real root gets its rate instead. (The
    Campbell diagram and the root locus name their tracked branches their own way.)
    """
    def label(m: Mode) -> str:
        return (f'{m.freq_hz:.3g} Hz' if m.kind == ModeKind.OSCILLATORY
                else f'{m.eigenvalue.real:.3g} 1/s')
    labels: dict = {}
    for m in out:
        if m.kind != ModeKind.ZERO:
            labels.setdefault(m.name, set()).add(label(m))
    return [dataclasses.replace(m, name=f'{m.name} {label(m)}')
            if len(labels.get(m.name, ())) > 1 else m for m in out]


def _followed(lin: Linearization, Ks: np.ndarray, lam: np.ndarray) -> tuple:
    """Return, for each root ``lam`` of A at dampings ``Ks``, its K = 0 root and d Re/d K there.

    The sensitivity to a common K, and the roots that stay at 0 for every K (the resting
    space), by the one rule :func:`gyro_rotor.linear.spectrum.zero_K_sensitivities`; the
    other roots are followed from K = 0 (every drive's K scaled by s in [0, 1], a log path)
    by eigenvector continuity (:func:`gyro_rotor.linear.spectrum.track`) on the reduced
    matrix.
    """
    from scipy.optimize import linear_sum_assignment
    from gyro_rotor.linear.spectrum import track, unit, unit_eig, zero_K_sensitivities
    BC = lin.b_all @ lin.c_all.T
    # the one rule (also the centrifuge's): the resting space out, the rest on Q^H A Q;
    # its roots are followed there (their vectors stay apart where the full ones merge
    # into a rotor angle's Jordan block)
    lam0, d0, V0, Q, r = zero_K_sensitivities(lin.A_cons, BC)
    d0 = d0.real
    Qh = Q.conj().T
    Vr = unit(Qh @ V0[:, :r])

    def fn(s):
        if s == 0:
            return lam0[:r], Vr
        return unit_eig(Qh @ (lin.A_cons - lin.b_all @ np.diag(s * Ks) @ lin.c_all.T) @ Q)
    path = [0.0] + list(np.geomspace(1e-6, 1.0, 49)) if np.any(Ks > 0) else [0.0]
    end = np.concatenate([track(fn, path, [''] * r, log=True)[-1], lam0[r:]])
    rows, cols = linear_sum_assignment(np.abs(end[:, None] - lam[None, :]))
    start = np.empty(len(lam), dtype=complex)
    d = np.empty(len(lam))
    start[cols], d[cols] = lam0[rows], d0[rows]
    return start, d


def name_roots(lin: Linearization, lam, K: float | None = None) -> list:
    """Name each root in ``lam`` by the mode of :func:`modes` at K it is (or its conjugate)."""
    ms = modes(lin, K)
    return [min(ms, key=lambda m: min(abs(m.eigenvalue - z), abs(m.eigenvalue.conjugate() - z)))
            .name for z in lam]


def check_claims(lin: Linearization):
    """Check claims (a) to (d) (module doc): :func:`gyro_rotor.linear.claims.check`.

    Claim (b)'s exception names the modes the drives do not reach (:func:`name_roots`).
    """
    from gyro_rotor.linear.claims import check
    res = check(lin.drive_system())
    if not res.unreached.size:
        return res
    b = res.claims['b']
    names = ', '.join(sorted(set(name_roots(lin, res.unreached, 0.0))))
    b = dataclasses.replace(b, exception=b.exception.replace(
        'roots not reached by the drive', f'roots not reached by the drive ({names})'))
    return dataclasses.replace(res, claims={**res.claims, 'b': b})
