"""The root-locus figure of any scene, in the style of the paper's figure 2 (matplotlib, lazily).

:func:`locus_figure`: zoomed to where the roots meet, each K_D* marked and
annotated, a legend for the branches and the markers, short tick labels, and a magnified
view of the branches that barely leave the imaginary axis. The figure functions return the
figure (tests read its limits and legend); only the command line saves them. Everything
else works without matplotlib.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ['plot_root_locus', 'locus_figure', 'MEETING_COLOR', 'SCENE_K_D_COLOR',
           'BRANCH_COLORS']

#: the colour of the K_D* markers (a pair meets on the real axis) and of the scene's K_D
MEETING_COLOR = 'tab:red'
SCENE_K_D_COLOR = 'tab:purple'
#: the branches' colours, one a mode: matplotlib's tab10 without the markers' colours and
#: 'tab:gray' (the colour of a branch with no label of its own), so that no branch takes a
#: marker's colour (with tab10 itself the fourth and fifth modes were drawn in the K_D* red
#: and the scene's K_D purple)
BRANCH_COLORS = ('tab:blue', 'tab:orange', 'tab:green', 'tab:brown', 'tab:pink', 'tab:olive',
                 'tab:cyan')


def _frame(ax, scale: float, top: float) -> None:
    """Draw the axes through 0 and frame the upper half plane to ``scale`` (``top`` x above)."""
    ax.axvline(0.0, color='0.4', lw=0.8)
    ax.axhline(0.0, color='0.4', lw=0.8)
    ax.set_xlim(-1.15 * scale, 0.08 * scale)
    ax.set_ylim(-0.04 * scale, top * scale)
    ax.set_xlabel('Re lambda [1/s]')
    ax.set_ylabel('Im lambda [rad/s]')


def plot_root_locus(lin, claims, path: str, *, K_lo: float, K_hi: float,
                    title: str = '') -> None:
    """Draw the root locus over K_D of any scene (:func:`locus_figure`), save it to ``path``."""
    import matplotlib.pyplot as plt
    fig = locus_figure(lin, claims, K_lo=K_lo, K_hi=K_hi, title=title)
    fig.savefig(path)
    plt.close(fig)


def _retrack(roots: np.ndarray) -> np.ndarray:
    """Columns that follow each root: nearest to the linear prediction from row to row."""
    from scipy.optimize import linear_sum_assignment
    out = roots.copy()
    for i in range(1, len(out)):
        prev = out[i - 1]
        pred = 2 * prev - out[i - 2] if i > 1 else prev
        r, c = linear_sum_assignment(np.abs(pred[:, None] - out[i][None, :])
                                     + 0.5 * np.abs(prev[:, None] - out[i][None, :]))
        row = np.empty_like(out[i])
        row[r] = out[i][c]
        out[i] = row
    return out


def _densify(Ks: np.ndarray, R: np.ndarray, eig_at, sub: int = 4) -> tuple:
    """Add ``sub - 1`` K values (geometric) in every step of the continuation.

    For smooth arcs: the roots there are matched to the tracked columns (interpolated
    prediction).
    """
    from scipy.optimize import linear_sum_assignment
    out_K, out_R = [Ks[0]], [R[0]]
    for i in range(len(Ks) - 1):
        a, b = math.log(Ks[i]), math.log(Ks[i + 1])
        for t in np.arange(1, sub) / sub:
            lam = eig_at(math.exp(a + t * (b - a)))
            pred = (1 - t) * R[i] + t * R[i + 1]
            r, c = linear_sum_assignment(np.abs(pred[:, None] - lam[None, :]))
            row = np.empty(R.shape[1], dtype=complex)
            row[r] = lam[c]
            out_K.append(math.exp(a + t * (b - a)))
            out_R.append(row)
        out_K.append(Ks[i + 1])
        out_R.append(R[i + 1])
    return np.array(out_K), np.array(out_R)


def _ticks(ax) -> None:
    """Few, short tick labels (never run together): at most 7 per axis, '%g' text."""
    from matplotlib.ticker import FuncFormatter, MaxNLocator
    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_locator(MaxNLocator(nbins=6))
        axis.set_major_formatter(FuncFormatter(lambda v, _: f'{v:.4g}'))


class _Locus:
    """What the root-locus figure draws (:func:`locus_figure`)."""

    def __init__(self, lin, claims, K_lo: float, K_hi: float):
        """Collect the branches (tracked, densified), names, fixed and limit roots, scale."""
        from gyro_rotor.linear.claims import locked_spectrum
        from gyro_rotor.linear.locus import name_roots
        loc = claims.locus
        sel = (loc.K >= K_lo * (1 - 1e-12)) & (loc.K <= K_hi * (1 + 1e-12))
        if np.sum(sel) < 2:
            sel = np.ones(len(loc.K), bool)
        self.ds = ds = lin.drive_system()
        A0l, Bl, Cl = ds.locus_pieces()
        self.K, R = _densify(loc.K[sel], _retrack(loc.roots)[sel],
                             lambda K: np.linalg.eigvals(A0l - K * (Bl @ Cl)))
        self.R = R
        # names at the start of the locus: the linearization's modes there; the roots of
        # A(K) on no branch do not move (not reached by the drives)
        lam_s = np.linalg.eigvals(ds.A(float(self.K[0])))
        used = set()
        for z in R[0]:
            d = np.abs(lam_s - z)
            d[list(used)] = np.inf
            used.add(int(np.argmin(d)))
        self.names = name_roots(lin, R[0], float(self.K[0]))
        self.fixed = np.array([lam_s[i] for i in range(len(lam_s)) if i not in used],
                              dtype=complex)
        try:
            self.locked = locked_spectrum(A0l, Bl, Cl)
        except np.linalg.LinAlgError:
            self.locked = np.zeros(0, complex)
        self.meetings = sorted(claims.meetings, key=lambda mt: mt.lam)
        meet = np.array([mt.lam for mt in self.meetings], dtype=float)
        self.S = S = max(float(np.abs(R[0]).max(initial=0.0)),
                         float(np.abs(self.fixed).max(initial=0.0)),
                         float(np.abs(self.locked).max(initial=0.0)),
                         float(np.abs(meet).max(initial=0.0)), 1e-9)
        self.z_up = np.where(R.imag < 0, R.conj(), R)
        self.upper = ~np.all(R.imag < -1e-9 * S, axis=0)
        self.excursion = np.abs(R.real).max(axis=0)
        # the slow branches: reached, but their real parts stay below 2 % of the picture
        slow = [j for j in range(R.shape[1]) if self.upper[j]
                and 0 < self.excursion[j] < 0.02 * S and np.all(np.abs(self.z_up[:, j]) < 2 * S)]
        self.slow = sorted(slow, key=lambda j: -abs(R[0, j].imag))[:4]
        K_scene = np.asarray(ds.K_scene)[list(ds.vary)]
        self.mark = float(K_scene[0]) if K_scene.size and np.all(K_scene == K_scene[0]) \
            and K_scene[0] > 0 else None
        self.fast = np.sort(lin.fast_rates)
        # the start of the range is 'K_D = 0' when no root has moved visibly from there yet
        lam0 = np.linalg.eigvals(A0l)
        moved = max((float(np.min(np.abs(lam0 - z))) for z in R[0]), default=0.0)
        self.start = 'K_D = 0' if moved <= 1e-3 * S else f'K_D = {self.K[0]:.3g}'

    def label(self, j: int) -> str:
        """Return the legend entry of branch ``j``."""
        return f'{self.names[j]} ({abs(self.R[0, j].imag):.4g} rad/s at {self.start})'


def locus_figure(lin, claims, *, K_lo: float, K_hi: float, title: str = ''):
    """Return the root-locus figure of any scene (matplotlib).

    ``lin``: :class:`~gyro_rotor.linear.system.Linearization`; ``claims``: its
    :class:`~gyro_rotor.linear.claims.ClaimsResult` (the continuation's locus, the
    meetings). The upper half plane is drawn (the lower is its mirror image), zoomed to
    where the roots meet: every K_D* meeting point, the K_D = 0 roots and the locked
    system's lie inside; the m fast roots that leave to -infinity leave the picture
    (a note gives their rate). Branches are coloured by mode (named as
    :func:`gyro_rotor.linear.system.modes` names them); x marks K_D = 0, o the
    K_D -> infinity limits, a diamond each meeting K_D* (annotated with its value and
    kind), a dot the scene's K_D, + the roots the drives do not reach. Branches that
    barely leave the imaginary axis get a panel each beside it (Re scaled by a power of
    ten, Im about its K_D = 0 value).
    """
    try:
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.pyplot as plt
    except ImportError as err:   # pragma: no cover -- optional dependency
        from gyro_rotor.errors import AnalysisError
        raise AnalysisError('plotting needs matplotlib (pip install matplotlib)') from err
    d = _Locus(lin, claims, K_lo, K_hi)
    if d.slow:
        fig = plt.figure(figsize=(12.5, 6.0), dpi=110)
        gs = fig.add_gridspec(len(d.slow), 2, width_ratios=(2.2, 1))
        ax = fig.add_subplot(gs[:, 0])
        side = [fig.add_subplot(gs[k, 1]) for k in range(len(d.slow))]
    else:
        fig, ax = plt.subplots(figsize=(8.5, 5.8), dpi=110)
        side = []
    labels = sorted({d.label(j) for j in range(d.R.shape[1]) if d.upper[j]},
                    key=lambda t: -float(t.split('(')[-1].split()[0]))
    color = {t: BRANCH_COLORS[i % len(BRANCH_COLORS)] for i, t in enumerate(labels)}
    _draw_main(ax, d, color, title)
    for ax2, j in zip(side, d.slow):
        _draw_slow_branch(ax2, d, j, color.get(d.label(j), 'tab:gray'))
    if side:
        side[-1].set_xlabel('Re lambda x 10^p [1/s] (p in each title)', fontsize=8)
    fast = ', '.join(f'{g:.4g}' for g in d.fast)
    fig.text(0.01, 0.005, f'K_D from {d.K[0]:.3g} to {d.K[-1]:.3g} N m s/rad (log); the '
             f'{len(d.fast)} fast root(s) leave to the left like -K_D x ({fast}) '
             '1/(N m s/rad) and leave the picture', fontsize=7.5, color='0.3')
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    return fig


def _draw_main(ax, d: _Locus, color: dict, title: str) -> None:
    """Draw the branches, markers, annotations, limits and legend of the main panel."""
    from matplotlib.lines import Line2D
    S, seen = d.S, set()
    for j in range(d.R.shape[1]):
        if not d.upper[j]:
            continue                                   # lower half plane: the mirror image
        t = d.label(j)
        col = color.get(t, 'tab:gray')
        ax.plot(d.z_up[:, j].real, d.z_up[:, j].imag, '-', color=col, lw=1.6,
                label=None if t in seen else t)
        seen.add(t)
        ax.plot(d.z_up[0, j].real, d.z_up[0, j].imag, 'x', color=col, ms=9, mew=2)
    for zs, kw in ((d.locked, {'marker': 'o', 'mfc': 'none', 'color': '0.2', 'ms': 9,
                               'mew': 1.5}),
                   (d.fixed, {'marker': '+', 'color': 'k', 'ms': 11, 'mew': 2})):
        for z in zs:
            if z.imag >= -1e-9 * S:
                ax.plot(z.real, abs(z.imag), ls='', **kw)
    if d.mark is not None:
        for z in np.linalg.eigvals(d.ds.A(d.mark)):
            if z.imag >= -1e-9 * S and abs(z) < 2 * S:
                ax.plot(z.real, abs(z.imag), '.', color=SCENE_K_D_COLOR, ms=9)
    for i, mt in enumerate(d.meetings):
        ax.plot(mt.lam, 0.0, 'D', color=MEETING_COLOR, ms=7)
        ax.annotate(f'K_D* = {mt.K_D:.4g} ({mt.kind})', (mt.lam, 0.0),
                    textcoords='offset points', xytext=(8, 12 + 20 * i), color=MEETING_COLOR,
                    fontsize=8, arrowprops={'arrowstyle': '-', 'color': MEETING_COLOR, 'lw': 0.6})
    _frame(ax, S, 1.15)
    ax.set_title(title or 'root locus over K_D', fontsize=10)
    _ticks(ax)
    ax.grid(True, alpha=0.3)
    marks = [Line2D([], [], ls='', marker='x', color='0.3', ms=8, mew=2, label=d.start),
             Line2D([], [], ls='', marker='o', mfc='none', color='0.2', ms=8,
                    label='K_D -> infinity (locked system)'),
             Line2D([], [], ls='', marker='D', color=MEETING_COLOR, ms=6,
                    label='K_D*: a pair meets on the real axis')]
    if d.mark is not None:
        marks.append(Line2D([], [], ls='', marker='.', color=SCENE_K_D_COLOR, ms=9,
                            label=f"scene's K_D = {d.mark:.4g}"))
    if d.fixed.size:
        marks.append(Line2D([], [], ls='', marker='+', color='k', ms=9, mew=2,
                            label='not reached by the drives (fixed)'))
    h, t = ax.get_legend_handles_labels()
    ax.legend(h + marks, t + [m.get_label() for m in marks], loc='upper left', fontsize=7.5,
              framealpha=0.9)


def _draw_slow_branch(ax2, d: _Locus, j: int, col) -> None:
    """Draw one slow branch, Re magnified by a power of ten to fill the panel."""
    top = max(float(d.excursion[j]), 1e-300)
    p = int(math.floor(math.log10(d.S / top) / 3) * 3) or 3
    f = 10.0 ** p
    w0 = float(abs(d.R[0, j].imag))      # Im about its K_D = 0 value (no digits lost)
    z = d.z_up[:, j]
    y = z.imag - w0
    ax2.plot(z.real * f, y, '-', color=col, lw=1.6)
    ax2.plot(z[0].real * f, y[0], 'x', color=col, ms=9, mew=2)
    if d.mark is not None and d.K[0] <= d.mark <= d.K[-1]:
        i = int(np.argmin(np.abs(np.log(d.K) - math.log(d.mark))))
        ax2.plot(z[i].real * f, y[i], '.', color=SCENE_K_D_COLOR, ms=9)
    im_lo, im_hi = float(y.min()), float(y.max())
    pad = max(0.15 * (im_hi - im_lo), 1e-9 * max(w0, 1.0))
    for x in d.locked:
        if x.imag >= 0 and im_lo - pad <= x.imag - w0 <= im_hi + pad:
            ax2.plot(x.real * f, x.imag - w0, 'o', mfc='none', color='0.2', ms=9, mew=1.5)
    ax2.axvline(0.0, color='0.4', lw=0.8)
    ax2.set_xlim(-1.15 * top * f, 0.1 * top * f)
    ax2.set_ylim(im_lo - pad, im_hi + pad)
    ax2.set_title(f'{d.names[j]} near {w0:.6g} rad/s: Re x 1e{p}', fontsize=8)
    ax2.set_ylabel(f'Im - {w0:.6g} [rad/s]', fontsize=8)
    ax2.tick_params(labelsize=7)
    _ticks(ax2)
    ax2.grid(True, alpha=0.3)
