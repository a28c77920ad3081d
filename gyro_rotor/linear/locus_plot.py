"""Root-locus figure in the style of the paper's figure 2 (matplotlib, imported lazily).

Only the command line calls this; everything else works without matplotlib.
"""

from __future__ import annotations

import math

from gyro_rotor.linear.locus import ClaimsReport, RootLocus
from gyro_rotor.linear.spectrum import ZERO_ROOT
import numpy as np

__all__ = ['plot_root_locus']

COLORS = {'nutation': 'tab:blue', 'precession': 'tab:cyan', 'housing twist': 'tab:green',
          'rotor-field coupling': 'tab:red', ZERO_ROOT: 'black'}


def plot_root_locus(loc: RootLocus, path: str, *, title: str = '',
                    claims: ClaimsReport | None = None, K_D_mark: float | None = None) -> None:
    """Draw the upper half plane of the root locus over K_D and save it to ``path``.

    Branches are coloured by mode; x marks K_D = 0, o the K_D -> infinity asymptotes, a
    diamond the meeting point K_D* on the real axis, a dot the roots at ``K_D_mark``.
    """
    try:
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.pyplot as plt
    except ImportError as err:   # pragma: no cover -- optional dependency
        from gyro_rotor.errors import AnalysisError
        raise AnalysisError('plotting needs matplotlib (pip install matplotlib)') from err
    lam = loc.eigenvalues
    scale = max(np.max(np.abs(lam[0])), np.max(np.abs(loc.zeros)), 1e-9)
    fig, ax = plt.subplots(figsize=(8.0, 5.5), dpi=110)
    seen = set()
    for j, nm in enumerate(loc.labels):
        z = lam[:, j]
        if np.all(z.imag < -1e-9 * scale):
            continue                                   # lower half plane: the mirror image
        z = np.where(z.imag < 0, z.conj(), z)
        col = COLORS.get(nm, 'tab:gray')
        ax.plot(z.real, z.imag, '-', color=col, lw=1.6,
                label=None if nm in seen else nm)
        seen.add(nm)
        ax.plot(z[0].real, abs(z[0].imag), 'x', color=col, ms=9, mew=2)
        if K_D_mark is not None:
            i = int(np.argmin(np.abs(np.log(np.maximum(loc.K_D, 1e-300)) - math.log(K_D_mark))))
            ax.plot(z[i].real, abs(z[i].imag), '.', color=col, ms=9)
    for zz, nm in zip(loc.zeros, loc.zero_labels):
        if zz.imag >= -1e-9 * scale:
            ax.plot(zz.real, zz.imag, 'o', mfc='none', color=COLORS.get(nm, 'tab:gray'), ms=9,
                    mew=1.5)
    if claims is not None and claims.K_D_star is not None:
        ax.plot(claims.breakaway, 0.0, 'D', color='tab:red', ms=7)
        ax.annotate(f'K_D* = {claims.K_D_star:.4g}', (claims.breakaway, 0.0),
                    textcoords='offset points', xytext=(5, 12), color='tab:red')
    ax.axvline(0.0, color='0.4', lw=0.8)
    ax.axhline(0.0, color='0.4', lw=0.8)
    ax.set_xlim(-1.15 * scale, 0.08 * scale)
    ax.set_ylim(-0.04 * scale, 1.12 * scale)
    ax.set_xlabel('Re lambda [1/s]')
    ax.set_ylabel('Im lambda [rad/s]')
    ax.set_title(title or 'root locus over K_D (x: K_D = 0, o: K_D -> infinity)')
    fig.text(0.01, 0.005, f'K_D from 0 to {loc.K_D[-1]:.3g} N m s/rad (log grid); the fast '
             f'{loc.fast_label} root leaves to the left like -{loc.fast_gain:.4g} K_D',
             fontsize=8, color='0.3')
    ax.legend(loc='upper left', fontsize=9)
    ax.grid(True, alpha=0.3)
    _nutation_inset(ax, loc, K_D_mark)
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    fig.savefig(path)
    plt.close(fig)


def _nutation_inset(ax, loc: RootLocus, K_D_mark) -> None:
    """Magnified view of the nutation branch, which barely leaves the imaginary axis."""
    js = [j for j, nm in enumerate(loc.labels) if nm == 'nutation'
          and np.mean(loc.eigenvalues[:, j].imag) > 0]
    if not js:
        return
    z = loc.eigenvalues[:, js[0]]
    re_min = float(np.min(z.real))
    if re_min >= 0:
        return
    ins = ax.inset_axes([0.55, 0.35, 0.3, 0.3])
    ins.plot(z.real * 1e3, z.imag, '-', color=COLORS['nutation'])
    ins.plot(z[0].real * 1e3, z[0].imag, 'x', color=COLORS['nutation'], ms=8, mew=2)
    if K_D_mark is not None:
        i = int(np.argmin(np.abs(np.log(np.maximum(loc.K_D, 1e-300)) - math.log(K_D_mark))))
        ins.plot(z[i].real * 1e3, z[i].imag, '.', color=COLORS['nutation'], ms=9)
    ins.axvline(0.0, color='0.4', lw=0.8)
    ins.set_xlim(1.15 * re_min * 1e3, -0.1 * re_min * 1e3)
    ins.set_title('nutation branch, Re x 1000', fontsize=8)
    ins.tick_params(labelsize=7)
