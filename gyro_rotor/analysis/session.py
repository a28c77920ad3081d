"""Messages in, analysis out: the glue that the analysis node and the offline analysis share.

Also the scene from the simulation node's ``~/scene`` document. Pure Python: messages are
duck-typed.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

from gyro_rotor.analysis.analyzer import RotorAnalyzer
from gyro_rotor.analysis.fit import joint_names
from gyro_rotor.analysis.results import AnalysisResult
from gyro_rotor.analysis.samples import energy_sample_fields, Sample, SamplePairer
from gyro_rotor.core.scene import Scene
from gyro_rotor.errors import AnalysisError

__all__ = ['AnalysisSession', 'scene_from_sim_doc', 'OtherSystemError']


class OtherSystemError(AnalysisError):
    """A joint_states message of another system than the scene's.

    A whole recording of another system, or one foreign message among the right ones.
    """


def scene_from_sim_doc(doc: Mapping[str, Any], base: Scene | Mapping[str, Any] | None = None
                       ) -> Scene:
    """Return the Scene described by the simulation node's ``~/scene`` YAML document.

    The document carries the scene name and path, the model, t_end, the (live) parameters,
    the perturbation and (since issue 8) the initial condition as ``initial``; ``base`` (a
    Scene or a flat mapping, e.g. from the bag's metadata) takes precedence, and older
    documents without ``initial`` fall back to the scene file named.

    Raises
    ------
    SceneError, ParameterError
        For an unknown scene without a base, or invalid values.
    """
    from gyro_rotor.core.scene import load_scene, scene_from_flat, scene_from_mapping
    if isinstance(doc, Mapping) and isinstance(doc.get('flat'), Mapping) and \
            'params' not in doc:
        # a system file's document carries its whole scene (live changes included)
        return scene_from_flat(doc['flat'], check=False)
    if not isinstance(doc, Mapping) or 'params' not in doc:
        raise AnalysisError(f'not a scene document of rotor_sim: {str(doc)[:80]!r}')
    if isinstance(base, Scene):
        flat = base.to_flat()
    elif base is not None:
        flat = dict(base)
    elif isinstance(doc.get('initial'), Mapping):     # documents since issue 8
        flat = {f'initial.{k}': v for k, v in doc['initial'].items()}
    else:
        path = doc.get('path')
        try:
            flat = load_scene(path if path else doc.get('scene', '')).to_flat()
        except AnalysisError:
            raise
        except Exception:
            flat = load_scene(doc.get('scene', '')).to_flat()
    flat['scene'] = str(doc.get('scene', flat.get('scene', 'custom')))
    for key in ('model', 't_end'):
        if key in doc:
            flat[key] = doc[key]
    flat.update(doc['params'])
    for k, v in (doc.get('perturbation') or {}).items():
        flat[f'perturbation.{k}'] = v
    return scene_from_mapping(flat, strict_float=False)


#: largest simulation time an energy message may carry [s] (about 30 years)
MAX_T_SIM = 1e9


def _check_energy(fields: Mapping[str, float]) -> None:
    """Refuse an energy message the analysis cannot place (before it is paired).

    t_sim, seq (and k, if present) must be finite, t_sim within [0, :data:`MAX_T_SIM`],
    seq and k whole numbers >= 0 (k >= -1); E_star must be there (it may be non-finite: a
    diverged simulation's, counted by the data criterion).
    """
    for key in ('t_sim', 'seq', 'E_star'):
        if key not in fields:
            raise AnalysisError(f'energy message without the field {key}')
    t, seq, k = fields['t_sim'], fields['seq'], fields.get('k', -1.0)
    if not (math.isfinite(t) and 0.0 <= t <= MAX_T_SIM):
        raise AnalysisError(f'energy message with t_sim = {t!r} (not in [0, {MAX_T_SIM:g}] s)')
    for key, v, low in (('seq', seq, 0), ('k', k, -1)):
        if not (math.isfinite(v) and v == int(v) and low <= v < 2.0**53):
            raise AnalysisError(f'energy message with {key} = {v!r} (not a whole number '
                                f'>= {low})')


class AnalysisSession:
    """Messages in, analysis out: the glue the node and the offline analysis share.

    Messages are duck-typed: rclpy messages (live) and the ``mcap_ros2`` decoder's objects
    (offline) have the same fields. Samples that arrive before the scene is known are
    kept (up to ``max_pending``) and analysed when it is.

    Parameters
    ----------
    scene : Scene, optional
        A fixed scene (then the sim node's scene documents only switch parameters).
    base : Scene or flat mapping, optional
        Initial-condition source for :func:`scene_from_sim_doc`.
    **options
        Passed to :class:`RotorAnalyzer` (``window_s`` ...).
    """

    def __init__(self, scene: Scene | None = None, base=None, *, max_pending: int = 100000,
                 keep_series: bool = False, **options: Any):
        self.options = options
        self.series: list[Sample] | None = [] if keep_series else None
        self.base = base if base is not None else scene
        self.fixed = scene is not None
        self.analyzer: RotorAnalyzer | None = (RotorAnalyzer(scene, **options)
                                               if scene is not None else None)
        self.pairer = SamplePairer()
        self.pending: list[Sample] = []
        self.max_pending = max_pending
        self.energy_fields: tuple = ()
        self._joint_names: tuple | None = None     # checked against the scene's once
        #: simulation time of the newest paired sample [s]: the time base of the stamps the
        #: analysis node writes (0 before the first sample)
        self.t_sim = 0.0
        #: messages refused (malformed, foreign, not analysable): topic -> reason -> count
        self.rejected: dict[str, dict[str, int]] = {}

    @property
    def scene(self) -> Scene | None:
        """Return the scene being analysed (None until known)."""
        return self.analyzer.scene if self.analyzer is not None else None

    def on_scene_doc(self, text: str) -> Scene:
        """Feed a ``~/scene`` document (YAML text) of the simulation node."""
        from gyro_rotor.core.yamlio import load_yaml
        doc = load_yaml(text, 'scene document', AnalysisError)
        scene = scene_from_sim_doc(doc, self.base)
        if self.base is None:
            self.base = scene
        if self.analyzer is None:
            self.analyzer = RotorAnalyzer(scene, **self.options)
            self.analyzer.add_many(self.pending)
            self.pending.clear()
        else:
            self.analyzer.set_scene(scene)
        return scene

    def on_energy(self, msg: Any) -> None:
        """Feed an ``energy`` message (std_msgs/Float64MultiArray, layout of ros_msgs)."""
        from_label = ''
        if msg.layout.dim:
            from_label = msg.layout.dim[0].label
        if from_label and (not self.energy_fields or
                           ','.join(self.energy_fields) != from_label):
            self.energy_fields = tuple(from_label.split(','))
        if not self.energy_fields:
            raise AnalysisError('energy message without a labelled layout')
        fields = energy_sample_fields(msg.data, self.energy_fields)
        _check_energy(fields)
        stamp = int(round(fields['t_sim'] * 1e9))
        self._take(self.pairer.add_energy(stamp, fields))

    def on_joints(self, msg: Any) -> None:
        """Feed a ``joint_states`` message (sensor_msgs/JointState).

        Raises
        ------
        AnalysisError
            If its joints are not the scene's (a recording of another system).
        """
        names = tuple(msg.name)
        if self.scene is not None and names != self._joint_names:
            want = joint_names(self.scene)
            if names != want:
                raise OtherSystemError(
                    f"joint_states names {', '.join(names) or 'no joints'} but scene "
                    f"'{self.scene.name}' has the joints {', '.join(want)}: a recording "
                    f'of another system')
            self._joint_names = names
        if not len(msg.position) == len(msg.velocity) == len(names):
            raise AnalysisError(f'joint_states with {len(names)} names, {len(msg.position)} '
                                f'positions and {len(msg.velocity)} velocities')
        stamp = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
        self._take(self.pairer.add_joints(stamp, msg.position, msg.velocity))

    def reject(self, topic: str, err: BaseException) -> str:
        """Count a message that could not be used; return the reason (one line)."""
        reason = f'{type(err).__name__}: {str(err)[:160]}'.splitlines()[0] if str(err) \
            else type(err).__name__
        per = self.rejected.setdefault(topic, {})
        per[reason] = per.get(reason, 0) + 1
        return reason

    @property
    def rejected_count(self) -> int:
        """Messages refused so far, all topics."""
        return sum(n for per in self.rejected.values() for n in per.values())

    def rejected_text(self) -> str:
        """One line: the messages refused per topic with their first reason ('' if none)."""
        if not self.rejected:
            return ''
        parts = []
        for topic, per in sorted(self.rejected.items()):
            first = next(iter(per))
            more = f' and {len(per) - 1} other reasons' if len(per) > 1 else ''
            parts.append(f'{topic} {sum(per.values())} ({first}{more})')
        return (f'{self.rejected_count} messages ignored (malformed or not from the '
                'simulation): ' + '; '.join(parts))

    def _take(self, samples: list[Sample]) -> None:
        if not samples:
            return
        self.t_sim = max(self.t_sim, samples[-1].t)
        if self.series is not None:
            self.series.extend(samples)
        if self.analyzer is None:
            self.pending.extend(samples)
            del self.pending[:max(0, len(self.pending) - self.max_pending)]
        else:
            self.analyzer.add_many(samples)

    def finish(self) -> None:
        """Analyse samples still waiting for their pair."""
        self._take(self.pairer.flush())

    def result(self) -> AnalysisResult:
        """Return the analysis so far.

        Raises
        ------
        AnalysisError
            If the scene is still unknown.
        """
        if self.analyzer is None:
            raise AnalysisError(f'the scene is unknown ({len(self.pending)} samples waiting): '
                                'no scene document from rotor_sim and no scene given')
        self.analyzer.unpaired = self.pairer.unpaired
        self.analyzer.cut = self.pairer.cut
        return self.analyzer.result()
