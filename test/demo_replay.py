"""The demo without ROS: a scene run as ``rotor_sim`` runs it, analysed as ``rotor_analysis`` does.

:func:`run_like_demo` integrates a scene with the simulation node's own code
(:class:`~gyro_rotor.numerics.live.LiveSimulation`, as fast as possible) on the node's
sample grid, kicks it through the same ``~/perturb`` action at the demo's time, and
returns the samples as the node publishes them (angles wrapped, the energy fields, ``seq``
and ``k``). :func:`stream` feeds them to a RotorAnalyzer and evaluates it every ``period``
of simulation time, as the analysis node evaluates every second: the live verdicts over
the run and the final result (the verdict matrix of test_verdict). Pure Python, no rclpy.
"""

from __future__ import annotations

import dataclasses
import math

from gyro_rotor.analysis.samples import make_sample
from gyro_rotor.cli.commands.demo import default_kick_at


@dataclasses.dataclass
class DemoRun:
    """Samples of one run as rotor_sim publishes them, and what happened."""

    scene: object
    samples: list
    kick_at: float
    kick: str


def _live(scene, rate: float):
    from gyro_rotor.node_settings import NODE_KEYS
    cfg = {k: spec[1] for k, spec in NODE_KEYS.items() if k != 'use_sim_time'}
    node = getattr(scene, 'node', None) or {}
    cfg.update({k: v for k, v in node.items() if k in cfg})
    cfg.update({'publish_rate': float(rate), 'real_time_factor': 0.0,
                'stop_at_t_end': False})
    from gyro_rotor.numerics.live import LiveSimulation
    return LiveSimulation(scene, cfg, scene.perturbation, budget=None)


def _samples(block) -> list:
    cols = {k: v.tolist() for k, v in block.energy.items()}
    pos, vel = block.position.tolist(), block.velocity.tolist()
    return [make_sample({k: v[i] for k, v in cols.items()}, (tuple(pos[i]), tuple(vel[i])))
            for i in range(len(block))]


def run_like_demo(scene, duration: float, *, rate: float = 250.0,
                  kick_at: float | None = None) -> DemoRun:
    """Run ``scene`` (a name, path or loaded scene) for ``duration`` s as the demo does.

    The kick (``~/perturb`` with the scene's ``perturbation``) lands on the first grid
    sample at or after ``kick_at`` (default: the demo's ``default_kick_at``; < 0: none), as
    the demo's simulation holds at that time until it is kicked. Samples at t = k / rate for
    k = 0 .. round(duration * rate).
    """
    from gyro_rotor.core.scene import load_scene
    if isinstance(scene, str):
        scene = load_scene(scene)
    if kick_at is None:
        kick_at = default_kick_at(scene, duration)
    sim = _live(scene, rate)
    n_end = int(round(duration * rate))
    samples: list = []
    kick = ''
    stops = ([kick_at] if 0.0 <= kick_at < duration else []) + [duration]
    for stop in stops:
        target = int(math.ceil(stop * rate - 1e-9))
        sim.pacer.t_end = target / rate
        while (not samples or samples[-1].k < target) and not sim.diverged:
            block = sim.tick()
            if block is not None:
                samples += [s for s in _samples(block) if s.k <= n_end]
        if stop < duration:
            kick = sim.perturb()
    return DemoRun(scene=scene, samples=samples, kick_at=kick_at, kick=kick)


@dataclasses.dataclass(frozen=True)
class LiveVerdict:
    """One evaluation of the streaming analysis: simulation time, verdict and reason."""

    t: float
    verdict: str
    reason: str
    statuses: dict


def stream(analyzer, samples, *, period: float = 1.0, until: float = math.inf) -> list:
    """Feed ``samples`` (up to time ``until``) and evaluate every ``period`` of sim time.

    Returns the :class:`LiveVerdict` of each evaluation (the last at the last sample), as
    the analysis node publishes them.
    """
    out = []
    next_t = None
    for s in samples:
        if s.t > until + 1e-9:
            break
        analyzer.add(s)
        if next_t is None:
            next_t = s.t + period
        if s.t >= next_t - 1e-9:
            out.append(_verdict(analyzer))
            next_t += period
    if not out or analyzer._last is not None and out[-1].t < analyzer._last.t:
        out.append(_verdict(analyzer))
    return out


def _verdict(analyzer) -> LiveVerdict:
    res = analyzer.result()
    return LiveVerdict(t=res.t_sim, verdict=str(res.verdict), reason=res.reason,
                       statuses={str(c.name): str(c.status) for c in res.criteria})
