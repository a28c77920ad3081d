"""The offline analysis of a recorded bag: :func:`analyze_bag` (pure Python, no rclpy)."""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Mapping

from gyro_rotor.analysis.analyzer import check_window
from gyro_rotor.analysis.results import AnalysisResult
from gyro_rotor.analysis.session import AnalysisSession
from gyro_rotor.core.scene import Scene
from gyro_rotor.errors import AnalysisError, BagError

__all__ = ['BagAnalysis', 'analyze_bag']


@dataclasses.dataclass
class BagAnalysis:
    """The offline analysis of a bag: the result, the live result recorded, the samples."""

    path: str
    result: AnalysisResult
    live: dict | None
    samples: list
    topics: dict
    truncated: bool
    scene_source: str
    options: dict
    #: the bag was damaged (something in it unreadable, or lost before a recovery)
    damaged: bool = False
    #: the reader's line on what the bag lost ('nothing lost' if nothing)
    loss: str = 'nothing lost'
    #: where the recording ends when it was cut ('' if it was not)
    cut_note: str = ''


def _find_topic(topics: Mapping[str, Any], suffix: str, type_name: str) -> str | None:
    names = [t for t, info in topics.items()
             if t.rsplit('/', 1)[-1] == suffix and info.type == type_name]
    return sorted(names, key=len)[0] if names else None


def analyze_bag(path, *, scene: str | Scene | None = None, window_s: float | None = None,
                cut_note: str = '', until: float | None = None,
                **options: Any) -> BagAnalysis:
    """Run the analysis of the live node over a recorded bag (nothing but the bag needed).

    The scene comes from ``scene`` if given, else from the bag's ``gyro_rotor.scene``
    metadata record, else from the simulation node's ``~/scene`` documents in the bag. The
    window is the one the live node used (metadata ``gyro_rotor.analysis``) unless
    ``window_s`` is given (0 = whole segments). A truncated bag is analysed up to the cut
    and says so in its verdict; so does a run stopped early (``cut_note``: how, e.g.
    'interrupted (Ctrl-C)'). An explicit ``scene`` that is not the one the bag records is
    refused (:func:`gyro_rotor.analysis.fit.scene_differences`). ``until`` [s]: analyse the
    samples up to this simulation time only (the first part of a recording).

    Raises
    ------
    BagError
        Missing or unreadable bag.
    AnalysisError
        The bag lacks the ``energy`` / ``joint_states`` topics, or no scene is known.
    SceneError
        The scene named in the bag is unknown (and the bag carries no parameters).
    """
    import warnings

    from gyro_rotor.bag.bagio import BagWarning, open_bag
    if not str(path).strip():
        raise BagError('the bag path is empty (give a bag directory or an .mcap file)')
    if window_s is not None:
        check_window(window_s)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always', BagWarning)
        reader = open_bag(path)
    problems = [str(w.message) for w in caught]
    energy, joints = _data_topics(path, reader)
    scene_topic = _find_topic(reader.topics, 'scene', 'std_msgs/msg/String')
    meta_opts = _json_record(reader, 'gyro_rotor.analysis', 'options', {})
    opts = {**(meta_opts if isinstance(meta_opts, dict) else {}), **options}
    if window_s is not None:
        opts['window_s'] = window_s
    fixed, base, source = _scene_source(path, reader, scene, scene_topic)
    if fixed is not None and scene is not None:
        _refuse_other_scene(path, reader, fixed, scene_topic)
    session = AnalysisSession(fixed if fixed is not None else base, base=base,
                              keep_series=True, **opts)
    if fixed is None and base is not None:
        session.fixed = False
    wanted = [energy, joints] + ([scene_topic] if scene_topic and fixed is None else [])
    _feed(session, reader, wanted, until)
    if session.analyzer is None:
        if session.rejected:
            raise AnalysisError(f'{path}: no usable scene document in the bag and no scene '
                                f'given; {session.rejected_text()}')
        raise AnalysisError(f'{path}: no scene document in the bag and no scene given')
    if session.analyzer.samples == 0:
        raise AnalysisError(f'{path}: the energy and joint_states topics hold no messages')
    live = _live_record(reader)
    losses = [reader.loss_text()] if reader.lost or reader.unknown_loss else []
    session.analyzer.bag_lost = sum(reader.lost.values())
    unseen = _unseen_live_samples(reader, session.analyzer.samples) if until is None else 0
    if unseen:
        # the files' own counts cannot tell a file of a split bag that is gone with its
        # metadata.yaml: the live analysis recorded how many samples it saw
        losses.append(f'{unseen} of the {session.analyzer.samples + unseen} samples the live '
                      f'analysis saw are not in the bag')
        session.analyzer.bag_lost += unseen
    session.analyzer.bag_loss = '; '.join(losses)
    how = 'the recording is truncated' if reader.truncated else cut_note
    if how:
        cut_note = f'{how}: analysed up to the cut at t = {session.t_sim:.3f} s'
        session.analyzer.truncated = cut_note
    result = session.result()
    if problems:
        result.evidence.extend(problems)
    if session.rejected:
        result.evidence.append(session.rejected_text())
    return BagAnalysis(path=str(path), result=result, live=live, samples=session.series,
                       topics={t: i.count for t, i in reader.topics.items()},
                       truncated=reader.truncated, scene_source=source, options=opts,
                       damaged=reader.damaged, loss=reader.loss_text(), cut_note=cut_note)


def _data_topics(path, reader) -> tuple:
    """Return the bag's energy and joint_states topics (refused if one is missing)."""
    energy = _find_topic(reader.topics, 'energy', 'std_msgs/msg/Float64MultiArray')
    joints = _find_topic(reader.topics, 'joint_states', 'sensor_msgs/msg/JointState')
    if energy is None or joints is None:
        found = ', '.join(f'{t} ({i.type})' for t, i in sorted(reader.topics.items()))
        if reader.damaged and not found:        # cut before its first channel
            raise AnalysisError(f'{path}: the bag is damaged and no topic of it can be read '
                                f'({reader.loss_text()}): no data to analyse')
        raise AnalysisError(f'{path}: not a gyro_rotor recording: needs the topics energy '
                            f'(std_msgs/msg/Float64MultiArray) and joint_states '
                            f'(sensor_msgs/msg/JointState); found {found or "no topics"}')
    return energy, joints


def _live_record(reader) -> dict | None:
    """Return the live node's verdict recorded in the bag, or None."""
    if 'gyro_rotor.live_result' not in reader.metadata:
        return None
    rec = reader.metadata['gyro_rotor.live_result']
    return _json_record(reader, 'gyro_rotor.live_result', 'json', None) or {
        'verdict': rec.get('verdict'), 'error': rec.get('error')}


def _unseen_live_samples(reader, samples: int) -> int:
    """Return how many more samples the live analysis saw than the bag holds (0 if unknown)."""
    try:
        seen = int(reader.metadata['gyro_rotor.live_result']['samples'])
    except (KeyError, TypeError, ValueError):
        return 0
    return max(0, seen - samples)


def _recorded_scene(reader, scene_topic):
    """Return the scene the bag records (metadata, else its first ~/scene document), or None."""
    from gyro_rotor.analysis.session import scene_from_sim_doc
    from gyro_rotor.core.yamlio import load_yaml
    try:
        _, base, _ = _scene_source('', reader, None, None)
        return base
    except AnalysisError:
        pass
    if scene_topic is None:
        return None
    for _, _, msg in reader.decoded([scene_topic]):
        try:
            return scene_from_sim_doc(load_yaml(msg.data, 'a ~/scene document'))
        except Exception:  # noqa: B902 -- an unreadable document: nothing to compare with
            return None
    return None


def _refuse_other_scene(path, reader, given, scene_topic) -> None:
    """Refuse a ``--scene`` that is not the recording's (one error line naming what differs).

    Without a scene in the bag the analysis' own ``scene`` criterion compares the data
    with the scene instead (:mod:`gyro_rotor.analysis.fit`).
    """
    from gyro_rotor.analysis.fit import joint_names, scene_differences
    recorded = _recorded_scene(reader, scene_topic)
    if recorded is None or joint_names(given) != joint_names(recorded):
        return      # another system: the joint names say so (AnalysisSession.on_joints)
    diffs = scene_differences(given, recorded)
    if diffs:
        raise AnalysisError(
            f"{path}: scene '{given.name}' does not fit the recording of scene "
            f"'{recorded.name}': {'; '.join(diffs[:6])}"
            + (f'; and {len(diffs) - 6} more' if len(diffs) > 6 else ''))


def _feed(session: AnalysisSession, reader, wanted: list, until: float | None) -> None:
    """Feed the bag's messages of ``wanted`` (energy, joint_states, scene), each on its own.

    A message that cannot be decoded or used is counted in ``session.rejected`` with its
    reason, and the rest of the bag is analysed (issue 24); messages after ``until`` are
    left out.
    """
    from gyro_rotor.analysis.session import OtherSystemError
    energy, joints = wanted[:2]
    joints_used, other_system = 0, None
    for topic, _, msg in reader.decoded(wanted, on_error=session.reject):
        try:
            if until is not None and topic in (energy, joints) and _stamp(msg) > until + 1e-9:
                continue
            if topic == energy:
                session.on_energy(msg)
            elif topic == joints:
                session.on_joints(msg)
                joints_used += 1
            else:
                session.on_scene_doc(msg.data)
        except Exception as err:    # noqa: B902 -- outside data: anything may go wrong
            if isinstance(err, OtherSystemError) and other_system is None:
                other_system = err
            session.reject(topic, err)
    if other_system is not None and not joints_used:
        raise other_system          # not one joint state of this scene: another system's
    session.finish()


def _stamp(msg) -> float:
    """Return the simulation time [s] of an energy (t_sim) or joint_states message."""
    if hasattr(msg, 'header'):
        return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
    labels = msg.layout.dim[0].label.split(',') if msg.layout.dim else []
    return float(msg.data[labels.index('t_sim')]) if 't_sim' in labels else -math.inf


def _json_record(reader, name: str, key: str, default):
    """Return the JSON value ``key`` of metadata record ``name`` (``default`` if absent)."""
    import json
    text = reader.metadata.get(name, {}).get(key)
    if not text:
        return default
    try:
        return json.loads(text)
    except ValueError:
        return default


def _scene_source(path, reader, scene, scene_topic) -> tuple:
    """Return (fixed scene, base scene, where from) for :func:`analyze_bag`."""
    from gyro_rotor.core.scene import load_scene, scene_from_flat
    from gyro_rotor.core.yamlio import load_yaml
    from gyro_rotor.errors import GyroRotorError
    if isinstance(scene, Scene):
        return scene, None, 'given'
    if scene:
        return load_scene(scene), None, f'given ({scene})'
    problem = ''
    if 'gyro_rotor.scene' in reader.metadata:
        rec = reader.metadata['gyro_rotor.scene']
        try:
            flat = load_yaml(rec.get('flat', ''), 'the gyro_rotor.scene record', AnalysisError)
            if not isinstance(flat, dict):
                raise AnalysisError('the gyro_rotor.scene record holds no parameters')
            base = scene_from_flat(flat, check=False)
            return None, base, f"bag metadata (scene '{base.name}')"
        except GyroRotorError as err:
            if scene_topic is None or not reader.topics[scene_topic].count:
                raise AnalysisError(f'{path}: {err}') from err
            problem = f' (the gyro_rotor.scene record is unusable: {err})'
    if scene_topic is not None:
        return None, None, f'scene documents on {scene_topic}{problem}'
    raise AnalysisError(f'{path}: the bag names no scene (no gyro_rotor.scene metadata, '
                        f'no ~/scene topic); pass one with --scene')
