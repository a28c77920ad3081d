"""Topic statistics and output rules for ``gyro-rotor monitor`` (pure Python, no rclpy).

:class:`TopicStats` keeps, per topic, the arrival times of the last messages (a ring of
wall-clock readings), the count, the bytes and, where the message carries a sequence
counter (the ``energy`` array's ``seq``), the number of sequence numbers the monitor did
not receive (it subscribes best effort, so as never to slow the simulation: at a high
rate it may miss what a recorder, subscribed reliably, keeps). Its rate is the one
``ros2 topic hz`` reports: messages in the window over the window's span.
:func:`array_values` names the numbers of a MultiArray by its own dimension labels;
:func:`known_values` drops the numbers that are not results yet (NaN);
:func:`system_topics` says which topics a system publishes (from rotor_sim's ``~/scene``
document); :class:`Changes` remembers what was printed, so that a log shows only what
changed.
"""

from __future__ import annotations

import collections
import dataclasses
import math

__all__ = ['TopicStats', 'array_values', 'message_values', 'known_values', 'system_topics',
           'system_from_joints', 'Changes', 'CENTRIFUGE_ONLY']

#: topics only the centrifuge publishes (a 3-D pose): rotor_sim of a general system has
#: no pose of its own and never publishes them
CENTRIFUGE_ONLY = ('axis', 'stator_pose', 'axis_marker')


def array_values(labels: list[list[str]], data) -> dict:
    """Name the numbers of a Float64MultiArray by its own dimension labels.

    Parameters
    ----------
    labels : list of list of str
        The comma-separated labels of each dimension (:func:`gyro_rotor.bag.wire.array_labels`).
    data : sequence of float
        The array, row major.

    Returns
    -------
    dict
        One dimension: ``{label: value}``. Two dimensions (a row per entry of dim[0], a
        column per entry of dim[1], as ``analysis_modes``): ``{row label: {column label:
        value}}``. Empty when the labels do not fit the data.
    """
    data = list(data)
    if len(labels) == 1 and len(labels[0]) == len(data):
        return dict(zip(labels[0], data))
    if len(labels) == 2:
        rows, cols = labels
        if rows and cols and len(rows) * len(cols) == len(data):
            n = len(cols)
            return {r: dict(zip(cols, data[i * n:(i + 1) * n])) for i, r in enumerate(rows)}
    return {}


def message_values(msg) -> dict:
    """Name the numbers of a Float64MultiArray message by its labels (:func:`array_values`)."""
    # imported here: bag.wire brings the model (numba), which ``gyro-rotor --help`` and the
    # monitor's start need not wait for
    from gyro_rotor.bag.wire import array_labels
    return array_values(array_labels(msg.layout.dim), msg.data)


@dataclasses.dataclass
class TopicStats:
    """Arrival statistics of one topic (see module doc)."""

    name: str
    type_name: str = ''
    window: int = 500
    count: int = 0
    bytes: int = 0  # noqa: A003 (public field name)
    gaps: int = 0
    last_seq: int | None = None
    times: collections.deque = dataclasses.field(default_factory=collections.deque)

    def add(self, t_wall: float, size: int = 0, seq: int | None = None) -> None:
        """Record one message that arrived at wall time ``t_wall`` [s]."""
        self.count += 1
        self.bytes += size
        self.times.append(t_wall)
        while len(self.times) > self.window:
            self.times.popleft()
        if seq is not None:
            if self.last_seq is not None and seq > self.last_seq + 1:
                self.gaps += seq - self.last_seq - 1
            self.last_seq = seq

    def rate(self, now: float | None = None, horizon: float = 5.0) -> float:
        """Messages per second over the last ``horizon`` seconds of the window (NaN if < 2)."""
        ts = [t for t in self.times if now is None or t >= now - horizon]
        if len(ts) < 2 or ts[-1] <= ts[0]:
            return math.nan
        return (len(ts) - 1) / (ts[-1] - ts[0])

    def jitter(self) -> float:
        """Return the standard deviation of the inter-arrival time over the window [s].

        NaN with fewer than 3 arrivals.
        """
        ts = list(self.times)
        if len(ts) < 3:
            return math.nan
        d = [b - a for a, b in zip(ts, ts[1:])]
        mean = sum(d) / len(d)
        return math.sqrt(sum((x - mean) ** 2 for x in d) / (len(d) - 1))


def known_values(values: dict) -> dict:
    """Return ``values`` without the entries that are NaN (not a result yet)."""
    out = {}
    for k, v in values.items():
        if isinstance(v, dict):
            v = known_values(v)
            if v:
                out[k] = v
        elif not (isinstance(v, float) and math.isnan(v)):
            out[k] = v
    return out


def system_topics(scene_text: str) -> dict | None:
    """Return which topics the system of rotor_sim's ``~/scene`` document publishes.

    Returns ``{'system': name, 'general': bool, 'absent': (topic basenames it never
    publishes)}``, or None if the text is not such a document. A general system (the
    document has a ``system`` key) publishes no 3-D pose (:data:`CENTRIFUGE_ONLY`).
    """
    import yaml
    try:
        doc = yaml.safe_load(scene_text)
    except yaml.YAMLError:
        return None
    if not isinstance(doc, dict) or 'scene' not in doc:
        return None
    general = 'system' in doc
    return {'system': str(doc['system']) if general else 'centrifuge', 'general': general,
            'scene': str(doc['scene']), 'absent': CENTRIFUGE_ONLY if general else ()}


def system_from_joints(names) -> dict | None:
    """Tell the system from the joint names of ``joint_states`` (before the scene document).

    The centrifuge's joints are theta, psi, phi_R, phi_M; other names are a general
    system's coordinates and rotor lags (no 3-D pose topics). None for no names.
    """
    from gyro_rotor.bag.wire import JOINT_NAMES
    names = tuple(names)
    if not names:
        return None
    general = names != tuple(JOINT_NAMES)
    return {'system': 'a general system' if general else 'centrifuge', 'general': general,
            'scene': None, 'absent': CENTRIFUGE_ONLY if general else ()}


class Changes:
    """What was printed last under each key: :meth:`changed` is True for new text only."""

    def __init__(self):
        """Start with nothing printed."""
        self.last: dict[str, str] = {}

    def changed(self, key: str, text: str) -> bool:
        """Return True (and remember ``text``) if ``key`` last printed something else."""
        if self.last.get(key) == text:
            return False
        self.last[key] = text
        return True
