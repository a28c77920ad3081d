"""Samples: one ``energy`` and one ``joint_states`` message of the same grid point, paired.

Nothing here imports rclpy or message types.
"""

from __future__ import annotations

import collections
import dataclasses
import math
from typing import Iterator, Mapping, Sequence

from gyro_rotor.errors import AnalysisError
import numpy as np

__all__ = ['Sample', 'SamplePairer', 'energy_sample_fields', 'make_sample',
           'samples_from_trajectory', 'iter_samples']

_TWO_PI = 2.0 * math.pi


@dataclasses.dataclass(frozen=True)
class Sample:
    """One paired sample of ``energy`` and ``joint_states`` at simulation time ``t``.

    ``positions``/``velocities`` are (theta, psi, phi_R, phi_M) and their rates as
    published (angles wrapped), for a general system its coordinates q and rotor lags z;
    the rest are the ``energy`` fields of :mod:`gyro_rotor.ros.messages` (t_sim, E_star,
    dE_dt, residual, z, zdot, seq, D, k; a general system's energy has no z, zdot: NaN).
    """

    t: float
    seq: int
    k: int
    E_star: float
    dE_dt: float
    residual: float
    z: float
    zdot: float
    D: float
    positions: tuple = (0.0, 0.0, 0.0, 0.0)
    velocities: tuple = (0.0, 0.0, 0.0, 0.0)
    #: False for an energy message whose joint state never came (positions NaN placeholders)
    joints: bool = True
    #: the ``dissipation`` field K_D zdot^2 [W] as recorded (None: the source has none);
    #: the simulation writes it as -dE_dt exactly
    dissipation: float | None = None
    #: ``energy`` fields the message did not carry (NaN here, but not recorded as NaN)
    absent: tuple = ()


def energy_sample_fields(values: Sequence[float], fields: Sequence[str]) -> dict:
    """Map an ``energy`` array to a dict by the field names of its layout label."""
    if len(values) != len(fields):
        raise AnalysisError(f'energy message has {len(values)} values but its layout names '
                            f'{len(fields)} fields ({",".join(fields)})')
    return dict(zip(fields, (float(v) for v in values)))


class SamplePairer:
    """Pair ``energy`` and ``joint_states`` messages by their simulation time stamp.

    The simulation node publishes both for every grid point with the same stamp, each
    topic in order; the recorder and DDS may interleave the two topics arbitrarily (in a
    bag, messages of the same stamp sit up to thousands of records apart). Energy
    messages are released in their arrival order (publication order, ``seq``), each as
    soon as its joint state is there, so nothing is lost however far apart the topics are.

    Data loss is counted, never silent: an energy message whose joint state has not come
    while more than ``keep`` joint states wait (each topic arrives in publication order, so
    those came later: its own was lost) is released with NaN joints and counted in
    :attr:`unpaired_energy`; a joint state that arrived before the one just paired was
    left without its energy message and counts in :attr:`unpaired_joints`. Only arrival
    order is used, never the order of the stamps (a reset starts t_sim again at 0).
    ``max_pending`` bounds the memory: beyond it the oldest waiting message is given up.
    """

    def __init__(self, keep: int = 64, max_pending: int = 1_000_000):
        self.keep = int(keep)
        self.max_pending = int(max_pending)
        self._energy: collections.deque = collections.deque()     # (stamp, fields)
        self._joints: dict[int, tuple] = {}                        # in arrival order
        self.unpaired_energy = 0
        self.unpaired_joints = 0
        #: messages left at the end of the recording past the other topic's last message:
        #: the cut took their partner (a Ctrl-C or a truncated bag), not a loss the data show
        self.cut = 0
        self._last_energy: int | None = None       # stamp of the newest arrival of each topic
        self._last_joints: int | None = None

    @property
    def unpaired(self) -> int:
        """Messages of either topic left without their partner so far."""
        return self.unpaired_energy + self.unpaired_joints

    @property
    def pending(self) -> int:
        """Messages waiting for their partner."""
        return len(self._energy) + len(self._joints)

    def add_energy(self, stamp_ns: int, fields: Mapping[str, float]) -> list[Sample]:
        """Add an energy message; return the samples completed (in order)."""
        self._energy.append((int(stamp_ns), dict(fields)))
        self._last_energy = int(stamp_ns)
        return self._release()

    def add_joints(self, stamp_ns: int, positions, velocities) -> list[Sample]:
        """Add a joint state; return the samples completed."""
        stamp = int(stamp_ns)
        self._last_joints = stamp
        if stamp in self._joints:            # a stamp again (a restarted run): the old is lost
            del self._joints[stamp]
            self.unpaired_joints += 1
        self._joints[stamp] = (tuple(float(v) for v in positions),
                               tuple(float(v) for v in velocities))
        if len(self._joints) > self.max_pending:
            del self._joints[next(iter(self._joints))]
            self.unpaired_joints += 1
        return self._release()

    def _release(self) -> list[Sample]:
        out = []
        while self._energy:
            stamp, fields = self._energy[0]
            joints = None
            if stamp in self._joints:
                # joint states that arrived before this one lost their energy message
                while (first := next(iter(self._joints))) != stamp:
                    del self._joints[first]
                    self.unpaired_joints += 1
                joints = self._joints.pop(stamp)
            elif len(self._joints) <= self.keep and len(self._energy) <= self.max_pending:
                break
            else:
                self.unpaired_energy += 1
            self._energy.popleft()
            out.append(make_sample(fields, joints))
        return out

    def flush(self) -> list[Sample]:
        """Return every waiting energy sample (NaN joints where missing).

        A message whose partner is missing counts as unpaired, unless it is past the end
        of the other topic (its stamp after the other topic's newest one): the recording
        was cut there (Ctrl-C, a truncated file), which took the partner; those count in
        :attr:`cut`.
        """
        out = []
        while self._energy:
            stamp, fields = self._energy.popleft()
            joints = self._joints.pop(stamp, None)
            if joints is None:
                if self._last_joints is None or stamp > self._last_joints:
                    self.cut += 1
                else:
                    self.unpaired_energy += 1
            out.append(make_sample(fields, joints))
        for stamp in self._joints:
            if self._last_energy is None or stamp > self._last_energy:
                self.cut += 1
            else:
                self.unpaired_joints += 1
        self._joints.clear()
        return out


def make_sample(e: Mapping[str, float], joints: tuple | None) -> Sample:
    """Return the sample of one energy message's fields ``e`` and its joint state.

    ``joints``: (positions, velocities), None if it never came (NaN placeholders).
    """
    pos, vel = joints if joints is not None else (None, None)
    nan4 = (math.nan,) * 4
    return Sample(t=e['t_sim'], seq=int(e['seq']), k=int(e.get('k', -1)),
                  E_star=e['E_star'], dE_dt=e.get('dE_dt', math.nan),
                  residual=e.get('residual', math.nan), z=e.get('z', math.nan),
                  zdot=e.get('zdot', math.nan),
                  D=e.get('D', math.nan), positions=pos or nan4, velocities=vel or nan4,
                  joints=joints is not None, dissipation=e.get('dissipation'),
                  absent=tuple(f for f in ('dE_dt', 'residual', 'z', 'zdot', 'D')
                               if f not in e))


def samples_from_trajectory(tr, seq0: int = 0) -> list[Sample]:
    """Return samples as rotor_sim publishes them, from a simulate() Trajectory of any system.

    The model's joints (at the field angle Omega0 t), E*, dE*/dt = -dissipation (eq. 17),
    the residual against the first sample, the dissipated work D and the ``energy``
    message's own fields (:meth:`state_fields`: the centrifuge's z, zdot).
    """
    return list(iter_samples(tr, seq0))


#: rows turned into samples at a time by :func:`iter_samples`
SAMPLE_CHUNK = 65536


def iter_samples(tr, seq0: int = 0) -> Iterator[Sample]:
    """Yield the samples of :func:`samples_from_trajectory`, SAMPLE_CHUNK rows at a time.

    The memory stays that of one chunk however long the run (a list of 1e7 samples took
    11.5 GB).
    """
    model, t_all = tr.model, np.asarray(tr.t, dtype=float)
    Y_all = np.atleast_2d(np.asarray(tr.y, dtype=float))
    speeds = model.field_speeds()[None, :]
    # the residual against the run's first sample, in every chunk
    E0 = float(model.energy(Y_all[:1])[0] + Y_all[0, model.idiss]) if len(t_all) else 0.0
    for a in range(0, len(t_all), SAMPLE_CHUNK):
        t, Y = t_all[a:a + SAMPLE_CHUNK], Y_all[a:a + SAMPLE_CHUNK]
        pos, vel, _, _ = model.joints(Y, t[:, None] * speeds)
        E, dE, r = model.energy(Y), -model.dissipation(Y), model.residual(Y, E0)
        fields = model.state_fields(Y)
        nan = np.full(len(t), math.nan)
        z, zdot = fields.get('z', nan), fields.get('zdot', nan)
        D = Y[:, model.idiss]
        for i in range(len(t)):
            yield Sample(t=float(t[i]), seq=seq0 + a + i, k=a + i, E_star=float(E[i]),
                         dE_dt=float(dE[i]), residual=float(r[i]), z=float(z[i]),
                         zdot=float(zdot[i]), D=float(D[i]),
                         positions=tuple(pos[i].tolist()), velocities=tuple(vel[i].tolist()))
