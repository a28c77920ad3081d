"""One rule for every system: a real part within its eigenvalue's resolution is 0.

An eigenvalue computed in double precision carries round-off; a real part within it is
not a result (never ``decay 2.2e+12 s`` from ``Re = -4.5e-13``, never a spectral abscissa
of ``1.8e-102``). The resolution of each eigenvalue is the larger of

- ``TOL_RE_REL ||A0||_F`` (:data:`gyro_rotor.linear.spectrum.TOL_RE_REL`), A0 the matrix
  without drive damping: the floor of the eigen-solver (the centrifuge's spectrum keeps
  its roots to it at any K_D through the pencil form);
- the eigenvalue's own round-off bound ``100 eps ||A|| kappa`` (condition number kappa,
  :func:`resolution`) where it is computed from A itself (the
  general systems' ``eig`` and ``campbell``).

Every command that prints an eigenvalue (``eig``, ``campbell``, ``locus`` of either kind
of system) shows such a real part as 0 and the mode as undamped.
"""

from __future__ import annotations

import math

from gyro_rotor.linear.spectrum import TOL_RE_REL
import numpy as np
import scipy.linalg as sla

__all__ = ['floor', 'nearest', 'resolution', 'resolutions', 'shown', 'fmt_re', 'decay_text',
           'TOL_RE_REL']


def resolution(A: np.ndarray, scale: float | None = None, balanced: bool = False) -> tuple:
    """Return (eigenvalues, resolution of each): 100 eps ||A|| times its condition number.

    The condition number 1/|y^H x| (unit left and right eigenvectors) bounds how far round-off
    in A moves the eigenvalue: a real part within it is not distinguishable from 0.
    ``scale`` replaces ||A|| where the roots are computed from a better-scaled form (the
    pencil of A0 and the drive, whose round-off is that of A0 at any K_D). ``balanced``:
    the bound of the roots LAPACK's eig computes, of the balanced matrix D^-1 A D (its
    norm and condition numbers): a stiff drive (K_S = 1e12) makes ||A|| 1.8e14 while
    ||D^-1 A D|| is 1.9e7, and the twist's 25.8 rad/s is resolved to 1.7e-5, not 62.
    """
    if len(A) == 0:
        return np.zeros(0, complex), np.zeros(0)
    if balanced:
        A = sla.matrix_balance(A, permute=False)[0]
        scale = None
    lam, yl, xr = sla.eig(A, left=True, right=True)
    yl = yl / np.linalg.norm(yl, axis=0)
    xr = xr / np.linalg.norm(xr, axis=0)
    s = np.abs(np.sum(yl.conj() * xr, axis=0))
    kappa = 1.0 / np.maximum(s, 1e-300)
    norm = np.linalg.norm(A) if scale is None else float(scale)
    return lam, 100 * np.finfo(float).eps * norm * np.minimum(kappa, 1e16)


def nearest(lam_r: np.ndarray, lam) -> np.ndarray:
    """Return the index in ``lam_r`` of the root nearest each of ``lam``.

    ``lam_r`` from :func:`resolution` (with its resolutions), ``lam`` the same roots from
    another computation: the resolution of ``lam[i]`` is ``res_r[nearest(lam_r, lam)[i]]``.
    """
    lam = np.atleast_1d(np.asarray(lam))
    return np.argmin(np.abs(np.asarray(lam_r)[None, :] - lam[:, None]), axis=1)


def floor(A0: np.ndarray) -> float:
    """Return TOL_RE_REL max(||A0||_F, 1): the smallest real part that is a result."""
    return TOL_RE_REL * max(float(np.linalg.norm(A0)), 1.0) if np.size(A0) else TOL_RE_REL


def resolutions(A: np.ndarray, A0: np.ndarray | None = None) -> tuple:
    """Eigenvalues of A and the resolution of each (module doc); A0 defaults to A."""
    lam, res = resolution(np.asarray(A, dtype=float))
    return lam, np.maximum(res, floor(A if A0 is None else A0))


def shown(x: float, res: float) -> float:
    """Return ``x``, or 0.0 if ``|x| <= res`` (round-off)."""
    return 0.0 if abs(x) <= res else float(x)


def fmt_re(x: float, res: float, width: int = 13) -> str:
    """``x`` as ``+1.234560e-03`` right-aligned in ``width``, or ``0`` within resolution."""
    return f'{x:+{width}.6e}' if abs(x) > res else f'{"0":>{width}s}'


def decay_text(re: float, res: float) -> str:
    """``'4.819 s'`` (time constant -1/Re), ``'undamped'`` within resolution, or growth."""
    if abs(re) <= res:
        return 'undamped'
    if re < 0:
        return f'{-1.0 / re:.4g} s'
    return f'grows (x2 in {math.log(2.0) / re:.4g} s)'
