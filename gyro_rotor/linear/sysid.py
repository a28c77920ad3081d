"""Eigenvalues from data: the matrix-pencil method for sums of damped exponentials.

A signal y_c(t_i) = sum_r a_rc exp(lambda_r t_i) (channel c, samples t_i = i dt) is fitted
by stacking the channels' Hankel matrices, keeping the ``order`` dominant right singular
vectors (noise and nonlinear remainder are cut off there), and solving the shift
invariance V_2 = V_1 Z for the discrete poles z_r = exp(lambda_r dt). The amplitudes
follow from least squares on the Vandermonde matrix. Noise-free sums of exponentials are
recovered to rounding error; for the gyrostat the remainder is the nonlinear part of the
response, of the order of the perturbation amplitude squared.

References
----------
Y. Hua and T. K. Sarkar, "Matrix pencil method for estimating parameters of exponentially
damped/undamped sinusoids in noise", IEEE Trans. ASSP 38 (1990) 814-824.
"""

from __future__ import annotations

import dataclasses

from gyro_rotor.errors import AnalysisError
import numpy as np

__all__ = ['ModalFit', 'matrix_pencil', 'match_eigenvalues']


@dataclasses.dataclass(frozen=True)
class ModalFit:
    """Result of :func:`matrix_pencil`.

    ``eigenvalues`` (order,) in 1/s, sorted by decreasing imaginary part;
    ``amplitudes`` (order, k) complex, channel by channel (y ~ Re of nothing: the
    conjugate terms are fitted separately); ``rms_residual`` per channel relative to the
    channel's rms; ``singular_values`` of the stacked Hankel matrix (normalized).
    """

    eigenvalues: np.ndarray
    amplitudes: np.ndarray
    rms_residual: np.ndarray
    singular_values: np.ndarray

    @property
    def freq_hz(self) -> np.ndarray:
        """|Im lambda|/(2 pi)."""
        return np.abs(self.eigenvalues.imag) / (2 * np.pi)

    @property
    def decay_rate(self) -> np.ndarray:
        """-Re lambda [1/s]."""
        return -self.eigenvalues.real


def matrix_pencil(signals, dt: float, order: int, *, pencil: int | None = None,
                  normalize: bool = True) -> ModalFit:
    """Fit ``order`` complex exponentials to sampled signals.

    Parameters
    ----------
    signals : array_like, shape (m,) or (m, k)
        m equally spaced samples of k channels (real or complex).
    dt : float
        Sample interval [s].
    order : int
        Number of exponentials (2 per oscillation, 1 per real root or constant offset).
    pencil : int, optional
        Pencil parameter L (columns of the Hankel matrices minus one); default
        min(m // 3, 400), at least order + 1.
    normalize : bool
        Scale each channel to unit rms before stacking (channels in different units).
    """
    Y = np.asarray(signals)
    if Y.ndim == 1:
        Y = Y[:, None]
    if Y.ndim != 2:
        raise AnalysisError(f'signals must be (m,) or (m, k), got shape {Y.shape}')
    m, k = Y.shape
    if not np.all(np.isfinite(Y)):
        raise AnalysisError('signals must be finite')
    if not (np.isfinite(dt) and dt > 0):
        raise AnalysisError(f'dt must be positive, got {dt!r}')
    order = int(order)
    if order < 1:
        raise AnalysisError(f'order must be at least 1, got {order}')
    L = min(m // 3, 400) if pencil is None else int(pencil)
    L = max(L, order + 1)
    if m - L < order + 1:
        raise AnalysisError(f'{m} samples are too few for order {order} (pencil {L})')
    scale = np.sqrt(np.mean(np.abs(Y) ** 2, axis=0)) if normalize else np.ones(k)
    scale = np.where(scale > 0, scale, 1.0)
    Yn = Y / scale
    rows = m - L
    idx = np.arange(rows)[:, None] + np.arange(L + 1)[None, :]
    H = np.concatenate([Yn[:, c][idx] for c in range(k)], axis=0)     # (k rows, L+1)
    _, sv, Vh = np.linalg.svd(H, full_matrices=False)
    if order > len(sv):
        raise AnalysisError(f'order {order} exceeds the Hankel rank bound {len(sv)}')
    Vr = Vh[:order].conj().T                                          # (L+1, order)
    V1, V2 = Vr[:-1], Vr[1:]
    z = np.linalg.eigvals(np.linalg.lstsq(V1, V2, rcond=None)[0])
    lam = np.log(z.astype(complex)) / dt
    order_idx = np.argsort(-lam.imag, kind='stable')
    lam, z = lam[order_idx], z[order_idx]
    Phi = z[None, :] ** np.arange(m)[:, None]
    amp, *_ = np.linalg.lstsq(Phi, Y.astype(complex), rcond=None)
    res = Y - (Phi @ amp)
    rms_y = np.sqrt(np.mean(np.abs(Y) ** 2, axis=0))
    rel = np.sqrt(np.mean(np.abs(res) ** 2, axis=0)) / np.where(rms_y > 0, rms_y, 1.0)
    return ModalFit(eigenvalues=lam, amplitudes=amp, rms_residual=rel,
                    singular_values=sv / sv[0])


def match_eigenvalues(fitted, predicted) -> np.ndarray:
    """Return, for each predicted eigenvalue, the index of the nearest one in ``fitted``.

    A one-to-one assignment by distance.
    """
    from scipy.optimize import linear_sum_assignment
    f = np.asarray(fitted, dtype=complex)
    p = np.asarray(predicted, dtype=complex)
    D = np.abs(p[:, None] - f[None, :])
    r, c = linear_sum_assignment(D)
    out = np.empty(len(p), dtype=int)
    out[r] = c
    return out
