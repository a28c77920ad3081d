"""``rotor_sim``: the full nonlinear gyrostat in real time on ROS 2 (a thin adapter).

The node declares every scene key as a parameter (with descriptors), loads the scene named
by ``scene``, integrates the scene's model with a :class:`~gyro_rotor.realtime.Pacer` from
a steady-clock timer, and publishes samples on the output grid t_k = k / publish_rate:

* ``joint_states`` (sensor_msgs/JointState): theta, psi, phi_R, phi_M; effort = the
  generalized forces (Q_theta, Q_psi, Q, -c_psi chi - Q) of eqs. (19, 23);
* ``energy`` (std_msgs/Float64MultiArray, layout in :mod:`gyro_rotor.ros_msgs`);
* ``axis`` (Vector3Stamped), ``stator_pose`` (PoseStamped), ``axis_marker`` (Marker);
* ``/diagnostics`` about once a second, ``/clock`` when ``publish_clock`` is true;
* ``~/scene`` (std_msgs/String, transient local): the current scene as YAML.

Services ``~/reset``, ``~/perturb`` (std_srvs/Trigger) and ``~/pause`` (std_srvs/SetBool).
Run: ``rotor_sim --ros-args -p scene:=nutation`` or ``python -m gyro_rotor.sim_node``.
"""

from __future__ import annotations

import dataclasses
import json
import math
import signal
import sys
import threading
import time
import warnings

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, Vector3Stamped
from gyro_rotor.core.model import make_model
from gyro_rotor.core.params import PARAM_DESCRIPTIONS, PARAM_FIELDS, PARAM_UNITS, RotorParams
from gyro_rotor.core.rotations import (axis_from_quaternion, euler_from_quaternion,
                                       euler_rates_from_body)
from gyro_rotor.core.scene import (DEFAULT_SCENE, load_scene, NODE_KEYS, perturb_state,
                                   PERTURBATION_KEYS, Scene, scene_from_mapping)
from gyro_rotor.errors import GyroRotorError, IntegrationError
from gyro_rotor.numerics.realtime import EnergyBaseline, make_stepper, Pacer, resolve_method
import gyro_rotor.ros.messages as ros_msgs
import numpy as np
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String
from std_srvs.srv import SetBool, Trigger
from visualization_msgs.msg import Marker

__all__ = ['RotorSimNode', 'main', 'STATE_QOS']

#: QoS of the state topics: reliable, deep enough for a recorder to keep up
STATE_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
_LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)
_BIG = 1e9
#: with real_time_factor 0, each tick advances this much simulated time [s] (whole samples)
FAST_CHUNK = 0.04
#: flow control at real_time_factor 0: longest block per tick waiting for acknowledgements
ACK_WAIT = Duration(seconds=0.05)
#: at real_time_factor 0, sleep per tick while waiting, paused, finished or diverged [s]
IDLE_SLEEP = 0.005
#: at shutdown, longest wait for the last messages to be acknowledged [s]
SHUTDOWN_ACK_WAIT = 2.0
#: ... and the most samples per state topic that may be in flight unacknowledged
ACK_WINDOW = STATE_QOS.depth // 2
#: ... and how long a subscriber may stay silent before the simulator goes on without it [s]
ACK_GIVE_UP = 5.0

# ranges of the RotorParams fields (the on-set callback still validates via RotorParams)
_PARAM_RANGES = {
    'A_R': (0.0, 1e6), 'A_M': (0.0, 1e6), 'C_R': (0.0, 1e6), 'C_M': (0.0, 1e6),
    'G': (0.0, 1e7), 's': (-100.0, 100.0), 'c_theta': (0.0, _BIG), 'c_psi': (0.0, _BIG),
    'K_S': (0.0, _BIG), 'K_D': (0.0, _BIG), 'Omega0': (-1e5, 1e5),
}
_NODE_RANGES = {
    'publish_rate': (1.0, 10000.0), 'real_time_factor': (0.0, 1000.0), 'rtol': (0.0, 1.0),
    'atol': (0.0, 1.0), 'step_size': (0.0, 1.0), 'diagnostics_period': (0.05, 3600.0),
    'max_catch_up': (0.001, 10.0), 'max_residual': (0.0, _BIG),
}
_READ_ONLY = {'scene', 'model', 'publish_rate', 'description', 'wait_for_subscribers'}
#: node keys whose change rebuilds the integrator at the current state
_STEPPER_KEYS = ('integrator', 'rtol', 'atol', 'step_size')
_INITIAL_DOC = {
    'mode': 'initial condition: steady (on a steady motion) or body (quaternion, rates)',
    'theta0': 'tilt of the steady motion [rad]', 'branch': 'steady motion: 0 = solution I, '
    '1 = precession, 2 = nutation branch', 'dtheta': 'offset of theta [rad]',
    'dthetadot': 'offset of thetadot [rad/s]', 'dpsidot': 'offset of psidot [rad/s]',
    'dchi': 'offset of the twist chi [rad]', 'dz': 'offset of z [rad]',
    'dzdot': 'offset of zdot [rad/s]', 'quaternion': 'stator quaternion [w, x, y, z]',
    'omega_body': 'stator body rates [rad/s]', 'z': 'rotor lag z [rad]',
    'zdot': 'rate of z [rad/s]', 'chi': 'twist chi [rad]',
}
_PERTURB_UNITS = {'dtheta': 'rad', 'dthetadot': 'rad/s', 'dpsidot': 'rad/s', 'dchi': 'rad',
                  'dz': 'rad', 'dzdot': 'rad/s'}


def _descriptor(name: str, description: str, read_only: bool = False,
                frange: tuple | None = None, irange: tuple | None = None) -> ParameterDescriptor:
    d = ParameterDescriptor(name=name, description=description, read_only=read_only)
    if frange:
        d.floating_point_range = [FloatingPointRange(from_value=float(frange[0]),
                                                     to_value=float(frange[1]), step=0.0)]
    if irange:
        d.integer_range = [IntegerRange(from_value=int(irange[0]), to_value=int(irange[1]),
                                        step=1)]
    return d


class RotorSimNode(Node):
    """The simulation node (see module doc); importable so that tests can compose it."""

    def __init__(self, node_name: str = 'rotor_sim', **kwargs):
        super().__init__(node_name, **kwargs)
        self._lock = threading.RLock()
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.scene = self._declare_parameters()
        self.cfg = {k: self.get_parameter(k).value for k in NODE_KEYS if k != 'use_sim_time'}
        self.perturbation = {k: self.get_parameter(f'perturbation.{k}').value
                             for k in PERTURBATION_KEYS}
        if self.get_parameter('use_sim_time').value:
            self.get_logger().warn('use_sim_time is true: the simulator keeps its own time '
                                   'and publishes /clock; set it on the other nodes instead')
        self.model = self.scene.make_model()
        self.seq = 0
        self.diverged: str | None = None
        self.last_window = None
        self._last = None          # (t, y) of the last published (good) sample
        self._start(self.scene.initial_state(self.model))

        self.pub_joints = self.create_publisher(JointState, 'joint_states', STATE_QOS)
        self.pub_energy = self.create_publisher(Float64MultiArray, 'energy', STATE_QOS)
        # one message per tick: as deep as the state topics, so that a recorder busy with
        # those does not lose them (depth 10 lost 0.2 % in a 10-minute soak at 1000 Hz)
        self.pub_axis = self.create_publisher(Vector3Stamped, 'axis', STATE_QOS)
        self.pub_pose = self.create_publisher(PoseStamped, 'stator_pose', STATE_QOS)
        self.pub_marker = self.create_publisher(Marker, 'axis_marker', STATE_QOS)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.pub_clock = self.create_publisher(ClockMsg, '/clock', STATE_QOS)
        self.pub_scene = self.create_publisher(String, '~/scene', _LATCHED)
        # reused for every sample (see _publish_samples)
        self._msg_joints = ros_msgs.joint_state(ros_msgs.stamp(0), (0.0,) * 4, (0.0,) * 4,
                                                (0.0,) * 4)
        self._msg_energy = ros_msgs.energy_array(dict.fromkeys(ros_msgs.ENERGY_FIELDS, 0.0))
        #: messages published per topic over the node's life (in the diagnostics)
        self.published = dict.fromkeys(('joint_states', 'energy', 'axis', 'stator_pose',
                                        'axis_marker', 'clock', 'diagnostics'), 0)
        #: flow control at real_time_factor 0: wall time spent waiting for acknowledgements
        self.ack_wait_s = 0.0
        self.ack_timeouts = 0
        self._ack_since: float | None = None
        self._t_clock: float | None = None
        self._unacked = 0
        self.create_service(Trigger, '~/reset', self._srv_reset)
        self.create_service(Trigger, '~/perturb', self._srv_perturb)
        self.create_service(SetBool, '~/pause', self._srv_pause)
        self._waiting = self.cfg['wait_for_subscribers'] > 0
        self._timer = None
        self._diag_timer = None
        self._make_timer()
        self._make_diag_timer()
        self.add_on_set_parameters_callback(self._on_set)
        self.add_post_set_parameters_callback(self._post_set)
        self._publish_scene()
        self.get_logger().info(
            f"scene '{self.scene.name}' (model {self.model.name}), integrator "
            f'{self.stepper.method}, publish_rate {self.cfg["publish_rate"]:g} Hz, '
            f'real_time_factor {self.cfg["real_time_factor"]:g}')

    # -- parameters --------------------------------------------------------------------------
    def _declare_parameters(self) -> Scene:
        name = self.declare_parameter('scene', DEFAULT_SCENE, _descriptor(
            'scene', 'scene name (config/<name>.yaml) or path to a scene file; loaded at '
            'start, the other parameters override it', read_only=True)).value
        base = load_scene(name)
        flat: dict = {'scene': base.name}
        d = self.declare_parameter('description', base.description, _descriptor(
            'description', 'what the scene shows', read_only=True))
        flat['description'] = d.value
        flat['model'] = self.declare_parameter('model', base.model, _descriptor(
            'model', 'full | locked_housing | upright_axis', read_only=True)).value
        flat['t_end'] = self.declare_parameter('t_end', base.t_end, _descriptor(
            't_end', 'scene duration [s] (the node stops there if stop_at_t_end)',
            frange=(1e-6, _BIG))).value
        for f in PARAM_FIELDS:
            desc = f'{PARAM_DESCRIPTIONS[f]} [{PARAM_UNITS[f]}]; live'
            value = getattr(base.params, f)
            if f == 'pole_pairs':
                d = _descriptor(f, desc, irange=(0, 64))
            else:
                d = _descriptor(f, desc, frange=_PARAM_RANGES[f])
            flat[f] = self.declare_parameter(f, value, d).value
        ic = base.initial
        mode = self.declare_parameter('initial.mode', ic.mode, _descriptor(
            'initial.mode', _INITIAL_DOC['mode'], read_only=True)).value
        keys = (('theta0', 'branch', *PERTURBATION_KEYS) if mode == 'steady'
                else ('quaternion', 'omega_body', 'z', 'zdot'))
        flat['initial.mode'] = mode
        for k in keys:
            v = getattr(ic, k)
            v = [float(x) for x in v] if isinstance(v, tuple) else v
            flat[f'initial.{k}'] = self.declare_parameter(f'initial.{k}', v, _descriptor(
                f'initial.{k}', _INITIAL_DOC[k] + '; read at start and by ~/reset',
                read_only=True)).value
        if mode == 'body' and ic.chi is not None:
            flat['initial.chi'] = self.declare_parameter('initial.chi', ic.chi, _descriptor(
                'initial.chi', _INITIAL_DOC['chi'], read_only=True)).value
        for k in PERTURBATION_KEYS:
            flat[f'perturbation.{k}'] = self.declare_parameter(
                f'perturbation.{k}', float(base.perturbation.get(k, 0.0)), _descriptor(
                    f'perturbation.{k}', f'kick of ~/perturb [{_PERTURB_UNITS[k]}]; live')).value
        for k, (typ, default, doc) in NODE_KEYS.items():
            if k == 'use_sim_time':
                continue
            value = base.node.get(k, default)
            flat[k] = self.declare_parameter(k, value, _descriptor(
                k, doc + ('' if k in _READ_ONLY else '; live'), read_only=k in _READ_ONLY,
                frange=_NODE_RANGES.get(k))).value
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')
            return scene_from_mapping(flat, path=base.path, strict_float=False)

    def _on_set(self, params) -> SetParametersResult:
        """Validate a change before it is accepted (RotorParams, integrator settings)."""
        changes = {p.name: p.value for p in params}
        phys = {k: v for k, v in changes.items() if k in PARAM_FIELDS}
        try:
            with warnings.catch_warnings():
                warnings.simplefilter('ignore')
                new = self.scene.params.replace(**phys) if phys else self.scene.params
            if any(k in changes for k in _STEPPER_KEYS) or phys:
                cfg = {**self.cfg, **{k: v for k, v in changes.items() if k in self.cfg}}
                scene = dataclasses.replace(self.scene, params=new)
                # after a divergence the stepper's state may be garbage: check the last good
                t, y = self._last if self.diverged else (self.stepper.t, self.stepper.y)
                self._new_stepper(make_model(scene.model, new), t, y, cfg, scene)
        except GyroRotorError as err:
            return SetParametersResult(successful=False, reason=str(err))
        return SetParametersResult(successful=True)

    def _post_set(self, params) -> None:
        """Apply accepted changes without restart."""
        changes = {p.name: p.value for p in params}
        now = self._now()
        with self._lock:
            for k, v in changes.items():
                if k in self.cfg:
                    self.cfg[k] = v
                elif k.startswith('perturbation.'):
                    self.perturbation[k.split('.', 1)[1]] = v
            phys = {k: v for k, v in changes.items() if k in PARAM_FIELDS}
            if 't_end' in changes:
                self.scene = dataclasses.replace(self.scene, t_end=changes['t_end'])
            if phys and self.diverged:
                # stopped: take the parameters for the next ~/reset, integrate nothing
                with warnings.catch_warnings():
                    warnings.simplefilter('ignore')
                    self.scene = dataclasses.replace(
                        self.scene, params=self.scene.params.replace(**phys))
                self.model = make_model(self.scene.model, self.scene.params)
            elif phys:
                self._apply_params(self.scene.params.replace(**phys), now)
            elif self.diverged:
                pass
            elif any(k in changes for k in _STEPPER_KEYS):
                self._restart_stepper(self.stepper.y.copy(), now)
            if 'real_time_factor' in changes:
                was_fast = self.pacer.rtf == 0
                self.pacer.set_rtf(self.cfg['real_time_factor'], now)
                if was_fast != (self.pacer.rtf == 0):
                    self._make_timer()
            self.pacer.max_catch_up = self.cfg['max_catch_up']
            self.pacer.t_end = self.scene.t_end if self.cfg['stop_at_t_end'] else None
            if 'diagnostics_period' in changes:
                self._make_diag_timer()
        self._publish_scene()

    def _apply_params(self, new: RotorParams, now: float) -> None:
        """Switch to new parameters at the current state.

        The state (q, W, z) is kept; an Omega0 change keeps the rotor's absolute spin
        (zdot jumps by -delta Omega0, the field angle is continuous). E* jumps (e.g. by
        (K_S' - K_S) z^2 / 2 for a K_S change); the residual baseline is moved by the jump.
        """
        old_model = self.model
        y_old = self.stepper.y.copy()
        t = self.stepper.t
        y = y_old.copy()
        dOmega = new.Omega0 - old_model.params.Omega0
        if dOmega:
            self._field = (t, self._field_angle(t))
            y[old_model.izd] -= dOmega
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')
            self.scene = dataclasses.replace(self.scene, params=new)
        self.model = make_model(self.scene.model, new)
        jump = self.baseline.rebase(self.model.energy, y, y_old)
        self._restart_stepper(y, now)
        self.get_logger().info(f'parameters changed; E* jumped by {jump:.6g} J '
                               f'(residual baseline moved with it)')

    # -- simulation state --------------------------------------------------------------------
    def _now(self) -> float:
        return self._steady.now().nanoseconds * 1e-9

    def _new_stepper(self, model, t, y, cfg, scene):
        t_end = scene.t_end if cfg['stop_at_t_end'] else math.inf
        method, self.method_reason = resolve_method(cfg['integrator'], model.params, t_end)
        return make_stepper(method, model.rhs, t, y, rtol=cfg['rtol'], atol=cfg['atol'],
                            step_size=cfg['step_size'], model=model)

    def _start(self, y0: np.ndarray) -> None:
        """(Re)start at t = 0 from y0."""
        self.stepper = self._new_stepper(self.model, 0.0, y0, self.cfg, self.scene)
        self.baseline = EnergyBaseline(self.model.energy, self.model.idiss, y0)
        self._field = (0.0, 0.0)     # (t_c, field angle at t_c) for phi_R
        self.pacer = Pacer(self.stepper, self.cfg['publish_rate'],
                           rtf=self.cfg['real_time_factor'],
                           max_catch_up=self.cfg['max_catch_up'],
                           chunk_samples=max(1, math.ceil(self.cfg['publish_rate'] * FAST_CHUNK)),
                           t_end=self.scene.t_end if self.cfg['stop_at_t_end'] else None)
        self._last = (0.0, np.array(y0, dtype=float))
        self.diverged = None

    def _restart_stepper(self, y: np.ndarray, now: float) -> None:
        self.stepper = self._new_stepper(self.model, self.stepper.t, y, self.cfg, self.scene)
        self.pacer.restart(self.stepper, now)

    def _field_angle(self, t: float) -> float:
        t_c, a_c = self._field
        return a_c + self.model.params.Omega0 * (t - t_c)

    # -- timers ------------------------------------------------------------------------------
    def _make_timer(self) -> None:
        if self._timer is not None:
            self.destroy_timer(self._timer)
        rtf = self.cfg['real_time_factor']
        period = 1.0 / self.cfg['publish_rate'] if rtf > 0 else 0.0
        self._timer = self.create_timer(period, self._tick, clock=self._steady)

    def _make_diag_timer(self) -> None:
        if self._diag_timer is not None:
            self.destroy_timer(self._diag_timer)
        self._diag_timer = self.create_timer(self.cfg['diagnostics_period'],
                                             self._publish_diagnostics, clock=self._steady)

    def _tick(self) -> None:
        with self._lock:
            if self.diverged:
                return self._idle()
            if self._waiting:
                n = self.cfg['wait_for_subscribers']
                if min(self.pub_joints.get_subscription_count(),
                       self.pub_energy.get_subscription_count()) < n:
                    return self._idle()   # the pacer anchors its clock at the first real tick
                self._waiting = False
                self.get_logger().info(f'{n} subscriber(s) matched: simulation time starts')
            now = self._now()
            if self.pacer.rtf == 0 and not self._acked(now):
                return
            try:
                samples = self.pacer.tick(now)
            except IntegrationError as err:
                samples = []
                self._diverge(str(err))
            if samples:
                self._publish_samples(samples)
            t = self.stepper.t
            if self.cfg['publish_clock'] and not self.diverged and t != self._t_clock:
                # only when time moved: a paused or finished simulator sends nothing new
                self.pub_clock.publish(ros_msgs.clock(ros_msgs.stamp(t)))
                self._t_clock = t
                self.published['clock'] += 1
            self.pacer.end_tick(self._now())
            if not samples and (self.pacer.paused or self.pacer.finished or self.diverged):
                self._idle()

    def _idle(self) -> None:
        """At real_time_factor 0 the timer has period 0: do not spin hot with nothing to do."""
        if self.pacer.rtf == 0:
            time.sleep(IDLE_SLEEP)

    def _acked(self, now: float) -> bool:
        """Flow control at real_time_factor 0: whether the next chunk may be computed.

        As fast as possible is meant for batch recording, so it must not outrun a reliable
        subscriber. At most ``ACK_WINDOW`` samples of ``joint_states`` and ``energy`` may
        be unacknowledged by their reliable subscriptions (less than the publisher's
        history, so that DDS never overwrites an unacknowledged sample); a KEEP_ALL
        subscription that cannot store more does not acknowledge, which holds the
        simulator back. A full window blocks each call for at most ``ACK_WAIT``, so that
        services are still served; a subscriber silent for ``ACK_GIVE_UP`` s (killed) is
        given up on for that window (counted in ``ack_timeouts``).
        """
        if self._unacked + self.pacer.chunk_samples <= ACK_WINDOW:
            return True
        start = time.monotonic()
        ok = all(pub.wait_for_all_acked(ACK_WAIT) for pub in (self.pub_joints,
                                                              self.pub_energy))
        self.ack_wait_s += time.monotonic() - start
        if not ok:
            if self._ack_since is None:
                self._ack_since = now
            if now - self._ack_since < ACK_GIVE_UP:
                return False
            self.ack_timeouts += 1
            self.get_logger().warn(f'a subscriber did not acknowledge for {ACK_GIVE_UP:g} s: '
                                   'continuing without it')
        self._ack_since = None
        self._unacked = 0
        return True

    def _diverge(self, reason: str) -> None:
        self.diverged = reason
        self.get_logger().error(f'integration stopped, last good state at t = '
                                f'{self._last[0]:.6f} s kept: {reason}')
        self._publish_diagnostics()

    def _publish_samples(self, samples) -> None:
        """Publish joint_states and energy for every sample, the 3-D topics for the last.

        Everything is computed once per tick on arrays (states, angles, forces, E*, the
        residuals and their check), converted to Python floats in one ``tolist`` each, and
        written into two message objects reused for every sample (``publish`` serializes
        synchronously, so reusing them is safe). If a residual fails the check, the
        samples before it are published and the node stops (:meth:`_diverge`).
        """
        m = self.model
        p = m.params
        n = len(samples)
        t = np.fromiter((s.t for s in samples), float, n)
        Y = np.array([s.y for s in samples])
        q = m.quaternion(Y)
        W = m.body_rates(Y)
        psi, theta, phi_M = euler_from_quaternion(q)
        psidot, thetadot, phi_M_dot = euler_rates_from_body(theta, phi_M, W)
        z, zdot = Y[:, m.iz], Y[:, m.izd]
        t_c, a_c = self._field
        field = a_c + p.Omega0 * (t - t_c)
        E = np.asarray(m.energy(Y), dtype=float)
        D = Y[:, m.idiss]
        resid = E + D - self.baseline.E_ref
        bad = ~(np.isfinite(E) & (np.abs(resid) <= self.cfg['max_residual']))
        n_good = int(np.argmax(bad)) if bad.any() else n
        if n_good:
            forces = m.generalized_forces(Y[:n_good])
            pos = np.column_stack([theta, psi, field + z + phi_M, phi_M])[:n_good].tolist()
            vel = np.column_stack([thetadot, psidot, p.Omega0 + zdot + phi_M_dot,
                                   phi_M_dot])[:n_good].tolist()
            eff = forces.tolist()
            diss = p.K_D * zdot * zdot
            seq = np.arange(self.seq, self.seq + n, dtype=float)
            k = np.fromiter((s.k for s in samples), float, n)
            rows = np.column_stack([t, E, -diss, diss, resid, z, zdot, seq, D, k])
            rows = rows[:n_good].tolist()
            js, en = self._msg_joints, self._msg_energy
            stamp = js.header.stamp
            pub_j, pub_e = self.pub_joints.publish, self.pub_energy.publish
            rem, two_pi = math.remainder, 2 * math.pi
            for i in range(n_good):
                ns = int(round(t[i] * 1e9))
                stamp.sec, stamp.nanosec = divmod(ns, 1_000_000_000)
                a = [rem(x, two_pi) for x in pos[i]]
                js.position = [math.pi if x == -math.pi else x for x in a]
                js.velocity = vel[i]
                js.effort = eff[i]
                pub_j(js)
                en.data = rows[i]
                pub_e(en)
            self.seq += n_good
            self._unacked += n_good
            self.published['joint_states'] += n_good
            self.published['energy'] += n_good
            last = samples[n_good - 1]
            self._last = (last.t, last.y)
            st = ros_msgs.stamp(last.t)
            frame = self.cfg['frame_id']
            axis = axis_from_quaternion(q[n_good - 1])
            self.pub_axis.publish(ros_msgs.axis_vector(st, frame, axis))
            self.pub_pose.publish(ros_msgs.stator_pose(st, frame, q[n_good - 1]))
            self.pub_marker.publish(ros_msgs.axis_marker(st, frame, axis))
            for topic in ('axis', 'stator_pose', 'axis_marker'):
                self.published[topic] += 1
        if n_good < n:
            s = samples[n_good]
            self._diverge(f'energy-balance residual {resid[n_good]:.6g} J at t = {s.t:.6f} s '
                          f'exceeds max_residual {self.cfg["max_residual"]:g} J (or E* is not '
                          f'finite)')

    # -- diagnostics -------------------------------------------------------------------------
    def _publish_diagnostics(self) -> None:
        with self._lock:
            now = self._now()
            w = self.pacer.take_window(now)
            self.last_window = w
            t, y = self._last
            m = self.model
            rtf = self.pacer.rtf
            qn = float(m.quaternion_norm_error(y))
            res = self.baseline.residual(y)
            level, msg = 'OK', 'running'
            if self.diverged:
                level, msg = 'ERROR', f'diverged: {self.diverged}'
            elif self.pacer.paused:
                msg = 'paused'
            elif self.pacer.finished:
                msg = f'stopped at t_end = {self.scene.t_end:g} s'
            elif w.capped:
                level, msg = 'WARN', (f'cannot keep up: {w.capped} ticks capped, '
                                      f'{w.lost_sim_time:.3f} s of simulation time lost')
            elif rtf > 0 and w.ticks > 2 and w.achieved_rtf < 0.9 * rtf:
                level, msg = 'WARN', f'achieved real-time factor {w.achieved_rtf:.3f} < {rtf:g}'
            elif abs(qn) > 1e-6:
                level, msg = 'WARN', f'quaternion norm drift {qn:.3e}'
            values = {
                'scene': self.scene.name, 'model': m.name, 'integrator': self.stepper.method,
                'rtol': getattr(self.stepper, 'rtol', ''),
                'atol': getattr(self.stepper, 'atol', ''),
                'step_size': getattr(self.stepper, 'h', ''), 't_sim': self.stepper.t,
                'real_time_factor': rtf, 'achieved_rtf': w.achieved_rtf,
                'overruns': w.overruns, 'overruns_total': self.pacer.overruns,
                'capped_ticks': w.capped, 'capped_total': self.pacer.capped,
                'lost_sim_time_total': self.pacer.lost_sim_time,
                'tick_interval_mean': w.interval_mean, 'tick_jitter_std': w.interval_std,
                'tick_interval_max': w.interval_max, 'tick_busy_max': w.busy_max,
                'integrator_reason': self.method_reason, 'nfev': self.stepper.nfev,
                'quaternion_norm_error': qn, 'residual': res,
                'E_star': float(m.energy(y)), 'samples': self.seq,
                'publish_rate': self.cfg['publish_rate'], 'paused': self.pacer.paused,
                'ack_wait_s': self.ack_wait_s, 'ack_timeouts': self.ack_timeouts,
                **{f'published_{k}': v for k, v in self.published.items()},
            }
            self.published['diagnostics'] += 1
            self.pub_diag.publish(ros_msgs.diagnostic_array(
                ros_msgs.stamp(self.stepper.t), f'{self.get_name()}: simulation', level, msg,
                values, hardware_id=f'scene:{self.scene.name}'))

    def _publish_scene(self) -> None:
        import yaml
        doc = {'scene': self.scene.name, 'model': self.scene.model, 't_end': self.scene.t_end,
               'params': self.scene.params.to_mapping(), 'initial': self._initial_doc(),
               'perturbation': self.perturbation,
               'node': self.cfg, 'integrator': self.stepper.method, 't_sim': self.stepper.t,
               'path': self.scene.path}
        self.pub_scene.publish(ros_msgs.text(yaml.safe_dump(doc, sort_keys=False)))

    def _initial_doc(self) -> dict:
        """Return the initial condition as ``initial.*`` keys without the prefix."""
        ic = self.scene.initial
        keys = (('mode', 'theta0', 'branch', *PERTURBATION_KEYS) if ic.mode == 'steady'
                else ('mode', 'quaternion', 'omega_body', 'z', 'zdot', 'chi'))
        out = {}
        for k in keys:
            v = getattr(ic, k)
            if v is None:
                continue
            if isinstance(v, (tuple, list, np.ndarray)):
                v = [float(x) for x in v]
            elif not isinstance(v, (bool, int, str)):
                v = float(v)
            out[k] = v
        return out

    # -- services ----------------------------------------------------------------------------
    def _srv_reset(self, request, response):
        with self._lock:
            try:
                y0 = self.scene.initial_state(self.model)
            except GyroRotorError as err:
                response.success, response.message = False, str(err)
                return response
            rtf_anchor = self._now()
            self._start(y0)
            self.pacer.set_rtf(self.cfg['real_time_factor'], rtf_anchor)
        self._publish_scene()
        response.success, response.message = True, f"reset to scene '{self.scene.name}' at t = 0"
        return response

    def _srv_perturb(self, request, response):
        with self._lock:
            if self.diverged:
                response.success = False
                response.message = 'diverged: reset first'
                return response
            y_old = self.stepper.y.copy()
            try:
                y = perturb_state(self.model, y_old, self.perturbation)
            except GyroRotorError as err:
                response.success, response.message = False, str(err)
                return response
            jump = self.baseline.rebase(self.model.energy, y, y_old)
            self._restart_stepper(y, self._now())
        response.success = True
        response.message = (f'kicked at t = {self.stepper.t:.6f} s with '
                            f'{self.perturbation}; E* changed by {jump:.6g} J')
        return response

    def _srv_pause(self, request, response):
        with self._lock:
            now = self._now()
            if request.data:
                self.pacer.pause(now)
            else:
                self.pacer.resume(now)
        response.success = True
        response.message = 'paused' if request.data else 'running'
        return response


#: Fast DDS profile of the simulator's writers: a reliable writer asks its readers for
#: acknowledgements every heartbeat period (default 3 s); the flow control at
#: real_time_factor 0 waits for them, so the period bounds its throughput
FASTDDS_PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <data_writer profile_name="gyro_rotor_sim_writer" is_default_profile="true">
    <times>
      <heartbeatPeriod><sec>0</sec><nanosec>{ns}</nanosec></heartbeatPeriod>
    </times>
  </data_writer>
</profiles>
"""
#: heartbeat period of the simulator's writers [ns]: with 5 ms (suspected: repair traffic) the
#: recorder stalled in a 150-s soak under load; 50 ms allows ACK_WINDOW / 50 ms = 10k samples/s
HEARTBEAT_NS = 50_000_000


def use_fastdds_profile() -> str | None:
    """Point Fast DDS at :data:`FASTDDS_PROFILE` unless a profile file is configured.

    Must run before ``rclpy.init``; returns the file used (None if the user's is kept).
    """
    import os
    import tempfile
    if os.environ.get('FASTRTPS_DEFAULT_PROFILES_FILE') or \
            os.environ.get('FASTDDS_DEFAULT_PROFILES_FILE'):
        return None
    path = os.path.join(tempfile.gettempdir(), f'gyro_rotor_sim_fastdds_{HEARTBEAT_NS}.xml')
    if not os.path.exists(path):
        tmp = f'{path}.{os.getpid()}'
        with open(tmp, 'w') as f:
            f.write(FASTDDS_PROFILE.format(ns=HEARTBEAT_NS))
        os.replace(tmp, path)
    os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = path
    return path


def _raise_interrupt(signum, frame):
    raise KeyboardInterrupt


def main(args: list[str] | None = None) -> int:
    """Run the node until SIGINT/SIGTERM; return the exit status.

    rclpy's own signal handlers would shut the context down under a running timer
    callback (its next publish then fails); instead both signals raise KeyboardInterrupt
    in the main thread, between callbacks or inside one, and the node is torn down here.
    """
    use_fastdds_profile()
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    previous = {sig: signal.signal(sig, _raise_interrupt)
                for sig in (signal.SIGINT, signal.SIGTERM)}
    node = None
    status = 0
    try:
        node = RotorSimNode()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except GyroRotorError as err:
        print(f'ERROR: {err}', file=sys.stderr)
        status = 1
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, signal.SIG_IGN if handler is None else handler)
        if node is not None:
            # the soak benchmark compares these with the messages recorded
            print(f'published counts: {json.dumps(node.published)}', file=sys.stderr,
                  flush=True)
            # a reliable writer's unacknowledged messages die with it: give them a moment
            for pub in (node.pub_joints, node.pub_energy):
                pub.wait_for_all_acked(Duration(seconds=SHUTDOWN_ACK_WAIT))
            node.destroy_node()
        rclpy.try_shutdown()
    return status


if __name__ == '__main__':
    sys.exit(main())
