"""Topic statistics for ``gyro-rotor monitor`` (pure Python, no rclpy).

:class:`TopicStats` keeps, per topic, the arrival times of the last messages (a ring of
wall-clock readings), the count, the bytes and, where the message carries a sequence
counter (the ``energy`` array's ``seq``), the number of missing sequence numbers. Its
rate is the one ``ros2 topic hz`` reports: messages in the window over the window's span.
:func:`array_values` names the numbers of a MultiArray by its own dimension labels.
"""

from __future__ import annotations

import collections
import dataclasses
import math

__all__ = ['TopicStats', 'array_values']


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
