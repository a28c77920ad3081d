"""Reports of an analysis: text, JSON and plots (matplotlib optional).

Compute in :mod:`gyro_rotor.analysis`, present here (python-control's ``damp`` vs
``damp(doprint=True)``). Plots: E* - E*_inf on a log scale with the fitted decay of the
last segment; identified against predicted eigenvalues on the complex plane; the state
over time (theta, z, zdot, residual).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from gyro_rotor.analysis.analyzer import windows_text
from gyro_rotor.analysis.modes import tone_line
from gyro_rotor.analysis.offline import BagAnalysis
from gyro_rotor.analysis.results import AnalysisResult
from gyro_rotor.analysis.verdict import (decay_rate_bound, fmt_interval, fmt_pm, fmt_re,
                                         needs_window, RE_RESOLUTION, Status)
import numpy as np

__all__ = ['text_report', 'verdict_line', 'json_report', 'write_report', 'plot_report',
           'strict_json']


def _f(x: Any, spec: str = '.4g') -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return '-'
    return format(x, spec)


def _meas_freq(m) -> str:
    """Return the measured frequency +- its uncertainty [Hz], '-' if not identified."""
    if m.freq is None or not m.freq.bounded:
        return '-'
    return fmt_pm(abs(m.freq.value) / (2 * math.pi), m.freq.u / (2 * math.pi))


def _meas_tau(m) -> str:
    """Return the measured decay time with its interval, or why the window cannot measure it."""
    if m.structural or m.rate is None:
        return '-'
    tau = m.tau
    if tau is not None:
        return fmt_interval(tau).replace(' (interval ', ' (').replace(' .. ', '..')
    if m.marginal_like:
        return 'undamped' if m.rate_status is Status.PASS else '-'
    need = needs_window(m.window_s, m.rate.value if m.rate.value else m.predicted.real,
                        m.rate.u)
    return (f'not measurable in {m.window_s:.2g} s (needs ~{need:.2g} s)'
            if math.isfinite(need) and need > m.window_s else 'not measurable')


def _pred_tau(m) -> str:
    """Return the predicted decay time [s]; '-' for a mode that does not decay (or structural)."""
    re = m.predicted.real
    if m.structural or m.marginal_like or not re < -RE_RESOLUTION * abs(m.predicted):
        return '-'
    return f'{m.pred_tau:.4g}'


def text_report(res: AnalysisResult, bag: BagAnalysis | None = None) -> str:
    """Return a human-readable report (verdict, evidence, modes, data integrity)."""
    p = res.prediction
    lines = []
    if bag is not None:
        lines.append(f'bag: {bag.path}' + (f' (TRUNCATED: {bag.cut_note}; '
                                           '`gyro-rotor recover BAG` repairs it)'
                                           if bag.truncated else ''))
        lines.append(f'scene: {res.scene} (from {bag.scene_source}); options {bag.options}')
    lines.append(verdict_line(res, bag))
    if bag is not None and bag.live is not None:
        lines.append(f"live verdict recorded in the bag: {bag.live.get('verdict')}")
    bound = decay_rate_bound(p.decaying_abscissa)
    lines.append(f'prediction ({p.source}, coordinates {p.coords}): {p.verdict}, spectral '
                 f'abscissa {fmt_re(p.spectral_abscissa)} 1/s, decay bound 2|alpha| = '
                 f'{_f(bound)} 1/s, E*_inf = {p.E_inf:.9g} J (before any kick)')
    lines.append(f'samples {res.samples}, dropped {res.dropped}, unpaired {res.unpaired}, '
                 f'resets {res.resets}, kicks {res.kicks}, time jumps {res.time_jumps}, '
                 f'parameter changes {res.param_changes}, pole slips {res.pole_slips}')
    lines.append('')
    lines.append('criteria:')
    lines += [f'  {c.line()}' for c in res.criteria]
    lines.append('')
    lines.append('evidence:')
    lines += [f'  {e}' for e in res.evidence[1:] if not e.startswith('[')]
    cur = res.judged
    if cur is not None:
        lines += [''] + _mode_table(cur)
        if len(res.segments) > 1:
            lines.append('')
            lines.append('segments:')
            for s in res.segments:
                lines.append(f'  {s.index}: {s.reason}; t {s.t_start:.3f}..{s.t_end:.3f} s, '
                             f'{s.samples} samples: {s.verdict}')
    return '\n'.join(lines) + '\n'


def verdict_line(res: AnalysisResult, bag: BagAnalysis | None = None) -> str:
    """Return the verdict line, with the cut of a truncated recording (analysed up to the cut)."""
    line = f'verdict: {str(res.verdict).upper()}: {res.reason}'
    if res.truncated:
        line += f' -- {res.truncated}'
    return line


def _mode_table(cur) -> list:
    """Return the modes as the segment's windows saw them (numbers with their intervals)."""
    rows = [(m.name, _f(abs(m.predicted.imag) / (2 * math.pi)), _meas_freq(m), _pred_tau(m),
             _meas_tau(m), m.describe()) for m in cur.modes]
    head = ('mode', 'f_pred Hz', 'f_meas Hz', 'tau_pred s', 'tau_meas s', 'status')
    w = [max(len(r[i]) for r in rows + [head]) for i in range(5)]
    out = [f'modes (segment {cur.index}, {windows_text(cur)}):']
    for r in [head] + rows:
        out.append('  ' + f'{r[0]:{w[0]}s}  {r[1]:>{w[1]}s}  {r[2]:>{w[2]}s}  '
                          f'{r[3]:>{w[3]}s}  {r[4]:>{w[4]}s}  {r[5]}')
    for r, text in cur.combinations:
        out.append(f'  also identified: {tone_line(r, text)}')
    for r, text in cur.unexplained:
        out.append(f'  UNEXPLAINED: {text}')
    return out


def json_report(res: AnalysisResult, bag: BagAnalysis | None = None) -> dict:
    """Return the report as a JSON-friendly dict."""
    d = res.as_dict()
    if bag is not None:
        d['bag'] = {'path': bag.path, 'truncated': bag.truncated, 'topics': bag.topics,
                    'scene_source': bag.scene_source, 'options': bag.options,
                    'live': bag.live}
    return d


def strict_json(obj: Any) -> Any:
    """Return ``obj`` with every non-finite float (inf, -inf, nan) replaced by None.

    The one rule of every JSON file the package writes (this report, eig, locus, campbell):
    strict JSON has no Infinity or NaN; ``null`` where a number is not finite (an undamped
    mode's infinite decay time, a regime that runs on to K_D -> infinity).
    """
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        obj = obj.item()
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: strict_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [strict_json(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return strict_json(obj.tolist())
    return obj


def write_report(bag: BagAnalysis, out_dir: str | Path | None = None,
                 json_path: str | Path | None = None, plots: bool = True) -> list[Path]:
    """Write report.txt, report.json and the plots; return the files written."""
    written: list[Path] = []
    if json_path is not None:
        json_path = Path(json_path)
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps(strict_json(json_report(bag.result, bag)), indent=1))
        written.append(json_path)
    if out_dir is not None:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        (out / 'report.txt').write_text(text_report(bag.result, bag))
        (out / 'report.json').write_text(json.dumps(strict_json(json_report(bag.result, bag)),
                                                    indent=1))
        written += [out / 'report.txt', out / 'report.json']
        if plots:
            written += plot_report(bag, out)
    return written


def plot_report(bag: BagAnalysis, out_dir: str | Path) -> list[Path]:
    """energy.png, eigenvalues.png and state.png (nothing if matplotlib is missing)."""
    try:
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.pyplot as plt
    except ImportError:
        return []
    out = Path(out_dir)
    res = bag.result
    S = bag.samples
    t = np.array([s.t for s in S])
    E = np.array([s.E_star for s in S])
    files = []
    # E* - E*_inf (fitted) with the fitted curve over the judged window
    fig, ax = plt.subplots(figsize=(7, 4))
    cur = res.judged
    fit = cur.energy_fit if cur is not None else None
    E_inf = fit.E_inf if fit is not None else res.prediction.E_inf
    dE = E - E_inf
    ax.semilogy(t, np.where(dE > 0, dE, np.nan), lw=0.8, label='E* - E*_inf (data)')
    if fit is not None and len(t):
        sel = (t >= fit.t0) & (t <= cur.t_end)
        curve = fit.curve(t[sel]) - E_inf
        ax.semilogy(t[sel], np.where(curve > 0, curve, np.nan), 'r--', lw=0.8,
                    label=f'fit with the predicted rates: E*_inf = {E_inf:.9g} J, '
                          f'rate {_f(fit.rate, ".3g")} 1/s')
    ax.set_xlabel('simulation time t [s]')
    ax.set_ylabel('E* - E*_inf [J] (E*_inf fitted)')
    ax.set_title(f'{res.scene}: Lyapunov function (eq. 13), verdict {res.verdict}')
    ax.legend(fontsize=8)
    files.append(_save(plt, fig, out / 'energy.png'))
    # eigenvalues
    fig, ax = plt.subplots(figsize=(6, 5))
    for m in res.prediction.modes:
        ax.plot(m.eigenvalue.real, m.eigenvalue.imag, 'kx', ms=9)
        ax.annotate(m.name, (m.eigenvalue.real, m.eigenvalue.imag), fontsize=7,
                    xytext=(4, 4), textcoords='offset points')
    if cur is not None:
        meas = [m.measured for m in cur.modes if m.measured is not None]
        if meas:
            ax.plot([z.real for z in meas], [z.imag for z in meas], 'o', mfc='none', ms=9,
                    color='tab:red', label='identified')
    ax.plot([], [], 'kx', label='predicted')
    ax.axvline(0.0, color='0.6', lw=0.8)
    ax.set_xlabel('Re lambda [1/s]')
    ax.set_ylabel('Im lambda [rad/s]')
    ax.set_title('identified vs predicted eigenvalues')
    ax.legend(fontsize=8)
    files.append(_save(plt, fig, out / 'eigenvalues.png'))
    files.append(_plot_state(plt, res, S, t, out))
    return files


def _state_series(res, S) -> tuple:
    """Return (first coordinate, z, zdot, labels) of the samples.

    theta and the rotor's lag, or a general system's first coordinate and its first
    rotor's lag.
    """
    steady = res.prediction.steady
    if not steady:
        return (np.array([s.positions[0] for s in S]), np.array([s.z for s in S]),
                np.array([s.zdot for s in S]), ('theta [rad]', 'z [rad]', 'zdot [rad/s]'))
    n = len(steady[0])

    def col(attr, i):
        return np.array([getattr(s, attr)[i] if len(getattr(s, attr)) > n else np.nan
                         for s in S])
    return (col('positions', 0), col('positions', n), col('velocities', n),
            (_first_coordinate(res.scene), 'z of rotor 1 [rad]', 'zdot of rotor 1 [rad/s]'))


def _first_coordinate(scene: str) -> str:
    """Return the axis label of a general system's first coordinate: its name (q_1).

    The system file names its coordinates but gives no units (angles in rad, lengths in m,
    as its constants make them); a scene that cannot be found by name keeps 'q_1'.
    """
    from gyro_rotor.core.scene import load_scene
    from gyro_rotor.errors import GyroRotorError
    try:
        name = load_scene(scene, check=False).system.coordinates[0]
    except (GyroRotorError, OSError):
        return 'first coordinate q_1 (SI: rad or m)'
    return f'{name} = q_1 (SI: rad or m)'


def _plot_state(plt, res, S, t, out: Path) -> Path:
    """state.png: the first coordinate, z, zdot and the residual over time."""
    theta, z, zd, labels = _state_series(res, S)
    r = np.array([s.residual for s in S])
    labels = labels + ('residual [J]',)
    fig, axs = plt.subplots(4, 1, figsize=(7, 7), sharex=True)
    for a, y, lab in zip(axs, (theta, z, zd, r), labels):
        a.plot(t, y, lw=0.7)
        a.set_ylabel(lab, fontsize=8)
    axs[-1].set_xlabel('simulation time t [s]')
    axs[0].set_title(f'{res.scene}: state over time')
    return _save(plt, fig, out / 'state.png')


def _save(plt, fig, path: Path) -> Path:
    """Write ``fig`` to ``path`` (100 dpi, tight layout), close it and return the path."""
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
