"""Soak benchmark: the simulation and analysis nodes under load, as separate processes.

:func:`run_soak` starts ``rotor_analysis`` (recording an MCAP bag) and ``rotor_sim``
(``wait_for_subscribers`` 1, ``stop_at_t_end`` at ``duration`` simulated seconds) in a
ROS domain of their own (:mod:`gyro_rotor.launch`), samples both processes' resident
memory (``VmRSS`` of ``/proc/<pid>/status``) while they run, listens to the simulator's
``/diagnostics`` (achieved real-time factor) and to the analysis' sample count, stops the
simulator when it reached ``t_end`` and the analysis when it has taken every sample, and
compares, per topic, the messages the simulator published (its ``published_*``
counters, logged at exit) with the messages in the bag. The ``energy`` sequence numbers
in the bag prove which messages are missing.

:func:`find_max_rate` runs short soaks at increasing publish rates and reports the
highest one with zero loss (and the achieved real-time factor at each).

Nothing here is a test: figures depend on the machine and its load.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from pathlib import Path
import re
import time
from typing import Callable

from gyro_rotor.errors import GyroRotorError, ParameterError
from gyro_rotor.signals import StopSignals
from gyro_rotor.tools.launch import (claim_domain_id, energy_seq_from_cdr, make_output_dir,
                                     NodeProcess, SideNode, tear_down)
from gyro_rotor.tools.monitor import message_values

__all__ = ['SoakResult', 'run_soak', 'find_max_rate', 'read_rss_kb', 'read_cpu_s', 'CpuLoad',
           'SIM_TOPICS']

#: topics whose published count the simulator reports, and their names in the bag
SIM_TOPICS = {'joint_states': '/joint_states', 'energy': '/energy', 'axis': '/axis',
              'stator_pose': '/stator_pose', 'axis_marker': '/axis_marker',
              'clock': '/clock'}
#: samples the analysis may hold back while pairing (SamplePairer's default keep)
PAIRER_KEEP = 64
_PUBLISHED_RE = re.compile(r'published counts: (\{.*\})')
_RECORDER_RE = re.compile(r'recorder counts: (\{.*\})')
#: share of the run at the start left out of the memory trend (warm-up: imports, histories)
WARMUP_SHARE = 0.25


def read_rss_kb(pid: int) -> int | None:
    """Resident set size of process ``pid`` in kB (``VmRSS``), None if it is gone."""
    try:
        with open(f'/proc/{pid}/status') as f:
            for line in f:
                if line.startswith('VmRSS:'):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


@dataclasses.dataclass
class SoakResult:
    """Figures of one soak run (see :func:`run_soak`)."""

    rate: float
    rtf: float
    duration: float
    scene: str
    wall_s: float = math.nan              # from the first sample to t_end
    achieved_rtf: float = math.nan        # duration / wall_s
    rtf_min: float = math.nan             # lowest achieved_rtf of the sim's 1-s windows
    published: dict = dataclasses.field(default_factory=dict)
    recorded: dict = dataclasses.field(default_factory=dict)
    seq_gaps: int = 0                     # energy messages missing between first and last seq
    rss_kb: list = dataclasses.field(default_factory=list)   # (wall s, sim kB, analysis kB)
    bag_bytes: int = 0
    sim_exit: int | None = None
    analysis_exit: int | None = None
    ack_wait_s: float = math.nan
    capped_total: int = 0
    load: int = 0                         # busy processes run beside the nodes
    loadavg: list = dataclasses.field(default_factory=list)   # 1-min load at start, t_end
    cpu_s: dict = dataclasses.field(default_factory=dict)     # CPU time per node [s]
    cpu_first: dict = dataclasses.field(default_factory=dict)  # ... at the first sample
    rss_t0: float = 0.0
    loadavg_samples: list = dataclasses.field(default_factory=list)  # 1-min load, every 5 s
    recorder: dict = dataclasses.field(default_factory=dict)   # the recorder's exit counts
    notes: list = dataclasses.field(default_factory=list)

    @property
    def lost_in_dds(self) -> dict:
        """Return messages DDS reported lost to the recorder (MESSAGE_LOST), per topic."""
        lost = self.recorder.get('lost_in_dds', {})
        return {k: int(lost.get(t, 0)) for k, t in SIM_TOPICS.items() if t in lost}

    def rss_trend(self, which: int) -> float:
        """Return the RSS trend [MB/min]: least-squares slope after the warm-up; 1 = sim, 2 = ana.

        The first :data:`WARMUP_SHARE` of the run is left out (imports, DDS histories and
        the analysis window filling); a fit over all later samples, not first/last.
        """
        pts = [(t, r[which - 1]) for t, *r in self.rss_kb if r[which - 1] is not None]
        if len(pts) < 3:
            return math.nan
        t_from = WARMUP_SHARE * pts[-1][0]
        late = [p for p in pts if p[0] >= t_from]
        if len(late) < 3:
            return math.nan
        t = [p[0] / 60.0 for p in late]
        y = [p[1] / 1024.0 for p in late]
        tm, ym = sum(t) / len(t), sum(y) / len(y)
        den = sum((a - tm) ** 2 for a in t)
        return sum((a - tm) * (b - ym) for a, b in zip(t, y)) / den if den > 0 else math.nan

    @property
    def lost(self) -> dict:
        """Return published minus recorded, per simulator topic."""
        return {k: self.published.get(k, 0) - self.recorded.get(k, 0) for k in SIM_TOPICS
                if k in self.published}

    @property
    def zero_loss(self) -> bool:
        """Every state message published was recorded (joint_states, energy, no seq gap)."""
        return (bool(self.published) and self.seq_gaps == 0
                and all(self.lost.get(k, 1) == 0 for k in ('joint_states', 'energy')))

    def rss_growth_kb(self, which: int) -> tuple[float, float]:
        """Return RSS growth over the second half of the run (kB, kB/min); 1 = sim, 2 = ana.

        The first half holds the warm-up (imports, DDS histories filling, the analysis
        window filling, allocator high-water marks); a leak shows in the second half.
        """
        pts = [(t, r[which - 1]) for t, *r in self.rss_kb if r[which - 1] is not None]
        if len(pts) < 2:
            return math.nan, math.nan
        half = 0.5 * pts[-1][0]
        late = [p for p in pts if p[0] >= half] or pts
        grow = late[-1][1] - late[0][1]
        span = late[-1][0] - late[0][0]
        return float(grow), float(grow / span * 60.0) if span > 0 else math.nan

    @property
    def bag_mb_per_min(self) -> float:
        """Bag size per minute of wall time [MB/min]."""
        return self.bag_bytes / 1e6 / (self.wall_s / 60.0) if self.wall_s > 0 else math.nan

    def as_dict(self) -> dict:
        """Plain data (JSON)."""
        d = dataclasses.asdict(self)
        d['lost'] = self.lost
        d['zero_loss'] = self.zero_loss
        d['rss_growth_sim_kb'], d['rss_growth_sim_kb_per_min'] = self.rss_growth_kb(1)
        d['rss_growth_analysis_kb'], d['rss_growth_analysis_kb_per_min'] = self.rss_growth_kb(2)
        d['bag_mb_per_min'] = self.bag_mb_per_min
        d['rss_trend_sim_mb_per_min'] = self.rss_trend(1)
        d['rss_trend_analysis_mb_per_min'] = self.rss_trend(2)
        d['lost_in_dds'] = self.lost_in_dds
        return d

    def text(self) -> str:
        """Return a human-readable summary."""
        lines = [f'soak: scene {self.scene}, publish_rate {self.rate:g} Hz, '
                 f'real_time_factor {self.rtf:g}, {self.duration:g} simulated s',
                 f'  wall {self.wall_s:.1f} s, achieved real-time factor '
                 f'{self.achieved_rtf:.4f} (lowest 1-s window {self.rtf_min:.3f}), '
                 f'capped ticks {self.capped_total}',
                 f'  {"topic":14s} {"published":>10s} {"recorded":>10s} {"lost":>7s} '
                 f'{"of it lost in DDS (MESSAGE_LOST)":>33s}']
        dds = self.lost_in_dds
        for k in SIM_TOPICS:
            if k in self.published:
                lines.append(f'  {k:14s} {self.published[k]:10d} '
                             f'{self.recorded.get(k, 0):10d} {self.lost[k]:7d} '
                             f'{dds.get(k, "?"):>33}')
        if self.recorder:
            lines.append(f'  recorder FIFO: high water {self.recorder.get("queue_max", 0)} '
                         f'messages ({self.recorder.get("queue_max_bytes", 0) / 1e6:.1f} MB), '
                         f'receiving thread blocked {self.recorder.get("blocked_s", 0):.1f} s, '
                         f'not written {self.recorder.get("not_written", 0)}')
        lines.append(f'  energy seq gaps in the bag: {self.seq_gaps}')
        for i, name in ((1, 'rotor_sim'), (2, 'rotor_analysis')):
            pts = [r[i - 1] for _, *r in self.rss_kb if r[i - 1] is not None]
            g, gm = self.rss_growth_kb(i)
            if pts:
                lines.append(f'  RSS {name}: {pts[0] / 1024:.1f} -> {pts[-1] / 1024:.1f} MB '
                             f'(max {max(pts) / 1024:.1f}); second half of the run '
                             f'{g / 1024:.2f} MB ({gm:.1f} kB/min); trend (least-squares '
                             f'fit after {WARMUP_SHARE:.0%} of the run) '
                             f'{self.rss_trend(i):+.3f} MB/min')
        n = self.recorded.get('energy', 0)
        for name, cpu in self.cpu_s.items():
            first = self.cpu_first.get(name)
            if cpu is not None and first is not None and n and self.wall_s > 0:
                run = cpu - first
                lines.append(f'  CPU {name}: {cpu:.1f} s, {run:.1f} s from the first sample '
                             f'= {run / n * 1e6:.0f} us per sample ({run / self.wall_s:.2f} of '
                             'a core)')
        lines.append(f'  busy processes: {self.load}; load average (1 min) '
                     + ', '.join(f'{x:.1f}' for x in self.loadavg))
        if self.loadavg_samples:
            la = self.loadavg_samples
            lines.append(f'  load average during the run: min {min(la):.1f}, mean '
                         f'{sum(la) / len(la):.1f}, max {max(la):.1f}')
        lines.append(f'  bag {self.bag_bytes / 1e6:.1f} MB = {self.bag_mb_per_min:.1f} MB per '
                     f'wall minute')
        if self.rtf == 0:
            lines.append(f'  flow control: {self.ack_wait_s:.1f} s spent waiting for '
                         'acknowledgements')
        lines.append(f'  exit codes: rotor_sim {self.sim_exit}, rotor_analysis '
                     f'{self.analysis_exit}')
        lines += [f'  note: {n}' for n in self.notes]
        lines.append(f'  RESULT: {"zero loss" if self.zero_loss else "MESSAGES LOST"}')
        return '\n'.join(lines)


class _Listener(SideNode):
    """A node in this process: the simulator's diagnostics and the analysis' sample count."""

    SPIN_STEP = 0.1

    def __init__(self, domain_id: int, signals: StopSignals | None = None):
        from diagnostic_msgs.msg import DiagnosticArray
        from std_msgs.msg import Float64MultiArray
        super().__init__('gyro_rotor_soak', domain_id, signals,
                         start_parameter_services=False)
        self.sim: dict = {}
        self.sim_message = ''
        self.rtf_windows: list[float] = []
        self.analysis: dict = {}
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, 50)
        self.node.create_subscription(Float64MultiArray, 'analysis', self._on_analysis, 10)

    def _on_diag(self, msg) -> None:
        for st in msg.status:
            if 'rotor_sim' in st.name:
                self.sim = {kv.key: kv.value for kv in st.values}
                self.sim_message = st.message
                try:
                    r = float(self.sim.get('achieved_rtf', 'nan'))
                except ValueError:
                    r = math.nan
                if math.isfinite(r) and not self.sim_message.startswith('stopped'):
                    self.rtf_windows.append(r)

    def _on_analysis(self, msg) -> None:
        self.analysis = message_values(msg)


def _published_from_log(log: Path) -> dict:
    found = _PUBLISHED_RE.findall(log.read_text(errors='replace'))
    return json.loads(found[-1]) if found else {}


def _count_bag(bag: Path, res: SoakResult) -> None:
    from gyro_rotor.bag.bagio import open_bag
    reader = open_bag(bag)
    for k, topic in SIM_TOPICS.items():
        info = reader.topics.get(topic)
        res.recorded[k] = info.count if info else 0
    seqs = [energy_seq_from_cdr(data) for _, _, data in reader.messages('/energy')]
    if seqs:
        seqs.sort()
        # seq is unique per sample over the simulator's life: missing = span - distinct
        res.seq_gaps = (seqs[-1] - seqs[0] + 1) - len(set(seqs))
    res.bag_bytes = sum(f.stat().st_size for f in bag.iterdir() if f.is_file())


class CpuLoad:
    """``n`` busy processes (``yes > /dev/null``), one per core by default; a context."""

    def __init__(self, n: int | None = None):
        self.n = (os.cpu_count() or 1) if n is None else int(n)
        self.procs: list = []

    def __enter__(self) -> 'CpuLoad':
        import subprocess
        for _ in range(self.n):
            self.procs.append(subprocess.Popen(['yes'], stdout=subprocess.DEVNULL,
                                               stdin=subprocess.DEVNULL))
        return self

    def __exit__(self, *exc) -> None:
        for p in self.procs:
            if p.poll() is None:
                p.kill()
            p.wait()
        self.procs.clear()


def read_cpu_s(pid: int) -> float | None:
    """CPU time (user + system) of process ``pid`` so far [s], None if it is gone."""
    try:
        with open(f'/proc/{pid}/stat') as f:
            fields = f.read().rsplit(')', 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def _check_soak_args(rate: float, duration: float, rtf: float, out: Path) -> Path:
    if not (math.isfinite(rate) and 1 <= rate <= 10000):
        raise ParameterError(f'rate must be in 1..10000 Hz, got {rate!r}')
    if not (math.isfinite(duration) and duration > 0):
        raise ParameterError(f'duration must be positive, got {duration!r}')
    if not (math.isfinite(rtf) and rtf >= 0):
        raise ParameterError(f'rtf must be >= 0, got {rtf!r}')
    bag = out / 'bag'
    if bag.exists():
        raise ParameterError(f'{bag} exists already')
    make_output_dir(out)
    return bag


def _start_nodes(res: SoakResult, scene_arg: str, bag: Path, domain_id: int, logs: dict,
                 env: dict):
    """Start rotor_analysis (recording) and rotor_sim; return (sim, analysis)."""
    ana = NodeProcess('gyro_rotor.ros.analysis_node', {
        'output': str(bag), 'scene': scene_arg}, domain_id=domain_id,
        stdout=logs['rotor_analysis'], stderr=logs['rotor_analysis'], env=env)
    sim = NodeProcess('gyro_rotor.ros.sim_node', {
        'scene': scene_arg, 'publish_rate': res.rate, 'real_time_factor': res.rtf,
        't_end': res.duration, 'stop_at_t_end': True, 'wait_for_subscribers': 1,
        'wait_for_node': 'rotor_analysis',
        'diagnostics_period': 1.0},
        domain_id=domain_id, stdout=logs['rotor_sim'], stderr=logs['rotor_sim'], env=env)
    return sim, ana


def _run_to_t_end(res: SoakResult, sim, ana, listener: _Listener, out: Path,
                  rss_period: float, say: Callable[[str], None]) -> None:
    """Sample memory and progress until the simulator reports t_end (or fails)."""
    t0 = time.monotonic()
    t_first = None
    next_rss, next_say = t0, t0 + 30.0
    limit = 120.0 + (res.duration / res.rtf * 3.0 if res.rtf > 0 else res.duration * 5.0)
    while not listener.sim_message.startswith('stopped at t_end'):
        listener.spin(0.2)
        now = time.monotonic()
        t_sim = float(listener.sim.get('t_sim', 'nan') or 'nan')
        if t_first is None and t_sim > 0:
            t_first = now
            res.cpu_first = {'rotor_sim': read_cpu_s(sim.pid),
                             'rotor_analysis': read_cpu_s(ana.pid)}
        if now >= next_rss:
            res.rss_kb.append((round(now - t0, 2), read_rss_kb(sim.pid), read_rss_kb(ana.pid)))
            res.loadavg_samples.append(os.getloadavg()[0])
            next_rss = now + rss_period
        if now >= next_say:
            say(f'  wall {now - t0:6.0f} s  t_sim {t_sim:8.2f} s  achieved rtf '
                f'{listener.sim.get("achieved_rtf", "?")}  recorded samples '
                f'{listener.analysis.get("samples", math.nan):.0f}  load average '
                f'{os.getloadavg()[0]:.1f}')
            next_say = now + 30.0
        for p in (sim, ana):
            if p.poll() is not None:
                raise GyroRotorError(f'{p.module} exited early with status {p.poll()}; '
                                     f'see {out}')
        if now - t0 > limit:
            raise GyroRotorError(f'the simulation did not reach t_end in {limit:.0f} s '
                                 f'(t_sim {t_sim}); see {out}')
    res.wall_s = time.monotonic() - (t_first if t_first is not None else t0)
    res.achieved_rtf = res.duration / res.wall_s if res.wall_s > 0 else math.nan
    res.rtf_min = min(listener.rtf_windows[1:] or listener.rtf_windows or [math.nan])
    res.ack_wait_s = float(listener.sim.get('ack_wait_s', 'nan'))
    res.capped_total = int(listener.sim.get('capped_total', '0'))
    res.rss_t0 = t0


def _drain(res: SoakResult, listener: _Listener, drain_timeout: float) -> None:
    """Wait until the analysis took (nearly) every published sample, or stopped taking."""
    want = int(listener.sim.get('published_energy', '0'))
    deadline = time.monotonic() + drain_timeout
    last, stable = -1.0, 0
    while time.monotonic() < deadline:
        listener.spin(1.0)
        got = listener.analysis.get('samples', -1.0)
        # the analysis pairs energy with joint_states: up to PAIRER_KEEP samples wait
        if got >= want - PAIRER_KEEP:
            return
        stable = stable + 1 if got == last else 0
        last = got
        if stable >= 5:
            res.notes.append(f'the analysis stopped at {got:.0f} of {want} samples')
            return


def _stop_nodes(res: SoakResult, sim, ana, listener: _Listener, out: Path) -> None:
    """Stop the simulator (its counts), then the recorder; CPU time and last memory."""
    res.cpu_s = {'rotor_sim': read_cpu_s(sim.pid), 'rotor_analysis': None}
    res.sim_exit = sim.stop()
    res.published = {k: int(v) for k, v in _published_from_log(out / 'rotor_sim.log').items()}
    listener.spin(1.0)
    res.rss_kb.append((round(time.monotonic() - res.rss_t0, 2), None, read_rss_kb(ana.pid)))
    res.cpu_s['rotor_analysis'] = read_cpu_s(ana.pid)
    res.analysis_exit = ana.stop(timeout=60.0)
    found = _RECORDER_RE.findall((out / 'rotor_analysis.log').read_text(errors='replace'))
    res.recorder = json.loads(found[-1]) if found else {}


def run_soak(rate: float = 1000.0, duration: float = 600.0, scene: str = 'precession',
             out: str | os.PathLike = 'soak_runs', rtf: float = 1.0, rss_period: float = 5.0,
             drain_timeout: float = 120.0, load: int = 0,
             progress: Callable[[str], None] | None = print) -> SoakResult:
    """Run both nodes for ``duration`` simulated seconds and measure (see module doc).

    Parameters
    ----------
    rate : float
        ``publish_rate`` of the simulator [Hz].
    duration : float
        Simulated seconds (``t_end``); at ``rtf`` 1 also the wall time.
    scene : str
        Scene name or path.
    out : path
        Directory for the bag and the node logs (created; must not hold a bag yet).
    rtf : float
        ``real_time_factor`` (0 = as fast as possible, with flow control).
    rss_period : float
        Seconds between memory samples.
    drain_timeout : float
        Longest wait after t_end for the recorder to take the last messages [s].
    load : int
        Busy processes (``yes > /dev/null``) run during the soak (0 = none); started
        before the nodes, stopped after them.
    """
    from gyro_rotor.core.scene import load_scene
    out = Path(out)
    bag = _check_soak_args(rate, duration, rtf, out)
    sc = load_scene(scene)
    say = progress or (lambda s: None)
    res = SoakResult(rate=float(rate), rtf=float(rtf), duration=float(duration),
                     scene=sc.name, load=int(load))
    claim = claim_domain_id()
    logs: dict = {}                 # opened inside the try: tear_down releases the claim
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    sim = ana = listener = None
    res.loadavg.append(os.getloadavg()[0])
    # a signal stops the soak at the listener's next spin (Stopped): the nodes are stopped,
    # the bag finalized, and a signal while they stop is counted, not acted on
    signals = StopSignals()
    try:
        signals.install()
        logs.update((n, open(out / f'{n}.log', 'w')) for n in ('rotor_sim', 'rotor_analysis'))
        with CpuLoad(load):
            listener = _Listener(claim.domain_id, signals)
            sim, ana = _start_nodes(res, str(sc.path or scene), bag, claim.domain_id, logs,
                                    env)
            say(f'soak: ROS_DOMAIN_ID {claim.domain_id}, rotor_sim pid {sim.pid}, '
                f'rotor_analysis pid {ana.pid}, {load} busy processes, bag {bag}')
            _run_to_t_end(res, sim, ana, listener, out, rss_period, say)
            res.loadavg.append(os.getloadavg()[0])
            _drain(res, listener, drain_timeout)
            _stop_nodes(res, sim, ana, listener, out)
    finally:
        tear_down([p for p in (ana, sim) if p is not None], listener, claim, logs, signals)
    _count_bag(bag, res)
    (out / 'soak.json').write_text(json.dumps(res.as_dict(), indent=1, default=str))
    return res


def find_max_rate(rates=(250.0, 500.0, 1000.0, 1500.0, 2000.0, 3000.0), duration: float = 20.0,
                  scene: str = 'precession', out: str | os.PathLike = 'soak_runs/max_rate',
                  min_rtf: float = 0.98, load: int = 0,
                  progress: Callable[[str], None] | None = print
                  ) -> tuple[float | None, list[SoakResult]]:
    """Short soaks at increasing ``rates`` (rtf 1); the highest rate with zero loss.

    A rate passes if nothing was lost and the achieved real-time factor is at least
    ``min_rtf``; the search stops at the first rate that fails. Returns (best rate or
    None, the results).
    """
    say = progress or (lambda s: None)
    results, best = [], None
    for rate in sorted(rates):
        r = run_soak(rate=rate, duration=duration, scene=scene, out=Path(out) / f'{rate:g}Hz',
                     load=load, progress=None)
        results.append(r)
        ok = r.zero_loss and r.achieved_rtf >= min_rtf
        say(f'  {rate:7g} Hz: lost {r.lost.get("energy")} energy / '
            f'{r.lost.get("joint_states")} joint_states, seq gaps {r.seq_gaps}, achieved rtf '
            f'{r.achieved_rtf:.4f} -> {"pass" if ok else "FAIL"}')
        if not ok:
            break
        best = rate
    return best, results
