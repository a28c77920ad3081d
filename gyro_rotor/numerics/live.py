"""The live simulation behind ``rotor_sim``: pure Python, no rclpy (tested without ROS).

:class:`LiveSimulation` owns everything the simulation node computes for a scene of any
rotor system (the built-in centrifuge or a system file's); the node only declares
parameters, services and timers and copies the arrays of a :class:`SampleBlock` into
messages. It holds the scene, its model, a stepper driven by a
:class:`~gyro_rotor.numerics.realtime.Pacer` and the energy baseline, and does:

* **parameter changes** (:meth:`LiveSimulation.check`, :meth:`LiveSimulation.apply`): the
  scene applies the physical ones (:meth:`Scene.with_live_changes
  <gyro_rotor.core.scene.Scene.with_live_changes>`); they are validated by building the
  new model and stepper at the current state; applied, the state is kept (an Omega0 change
  keeps each rotor's absolute spin: zdot jumps by -delta Omega0, the model's
  ``carried_state``; the field angle stays continuous) and the baseline of the residual
  moves by the jump of E* (eq. 13);
* **ticks** (:meth:`LiveSimulation.tick`) with a work budget: a tick stops after
  ``budget`` seconds of work (see the pacer's module doc); when that happens in
  ``CUTS_TO_SWITCH`` consecutive ticks of one stepper, the method that ``auto`` would
  choose for the current parameters (:func:`~gyro_rotor.numerics.realtime.resolve_method`)
  takes over, if it is not the one running already, and the diagnostics say so;
* **the divergence guard**: an energy-balance residual |r| = |E* + D - E_ref| above
  max(``max_residual``, 1e-6 x max(|E*|, |E_ref|)) (:mod:`~gyro_rotor.numerics.guard`:
  in joules, relative only where a statically unstable system's motion has grown far
  beyond them), a non-finite E*, or *any* exception raised by the model or the
  integrator (a diverging solution can make the right-hand side divide by zero) stops the
  integration; the last good state is kept, the diagnostics turn ERROR, and
  :meth:`LiveSimulation.reset` starts again;
* **the sample block** (:class:`SampleBlock`): for every grid sample of a tick the
  joint outputs the model names (``joint_names``, ``joints``: for the centrifuge the 3-1-3
  angles theta, psi, the rotor angle phi_R = field + z + phi_M, phi_M, wrapped to
  (-pi, pi], their rates and the generalized forces of eqs. (19, 23); for a system file
  its coordinates q and the rotor lags z_ROTOR = phi - Omega0 t (eq. 7) as integrated,
  their rates, no efforts and no 3-D pose), and the model's ``energy_fields`` (t_sim, E*,
  dE*/dt = -sum K_D zdot^2 (eq. 17), the dissipation, the residual, the centrifuge's z
  and zdot, the sample counter seq, D and the grid index k), all as arrays;
* the services' actions (:meth:`reset`, :meth:`perturb`: the scene's ``perturbation``
  kick, :meth:`Scene.kick_values <gyro_rotor.core.scene.Scene.kick_values>`, applied by
  the model's ``kick``; :meth:`pause`), the diagnostics (:meth:`diagnostics`) and the
  scene document (:meth:`scene_doc`).

Auto's choice is :func:`~gyro_rotor.numerics.realtime.resolve_method` (one rule for every
system, on what the model gives: its drive damping root and fastest oscillation at the
current state); a system file integrates with the methods of
:mod:`gyro_rotor.numerics.kernel_system` through its kernel handle (``kernel_model``).
"""

from __future__ import annotations

import dataclasses
import enum
import math
import time
from typing import Any, Callable, Mapping

from gyro_rotor.core.model import Model
from gyro_rotor.core.rotations import axis_from_quaternion, wrap_angles
from gyro_rotor.core.scene import Scene
from gyro_rotor.core.system.model import GeneralModel
from gyro_rotor.errors import GyroRotorError, IntegrationError, ParameterError
from gyro_rotor.numerics.guard import describe_break, first_break
from gyro_rotor.numerics.kernel_system import kernel_model, SYSTEM_METHODS
from gyro_rotor.numerics.realtime import (EnergyBaseline, make_stepper, Pacer, resolve_method,
                                          Stepper)
import numpy as np

__all__ = ['LiveSimulation', 'SampleBlock', 'Level', 'TICK_BUDGET', 'CUTS_TO_SWITCH', 'FAST_CHUNK',
           'STEPPER_KEYS', 'ENERGY_COLUMNS', 'wrap_angles']

#: most wall seconds of integration work in one tick; a tick that needs more is cut
#: (services are answered between ticks, so this bounds their latency)
TICK_BUDGET = 0.025
#: a stepper counts as too slow after this many consecutive cut ticks (the first tick of a
#: method may include loading or compiling its kernels)
CUTS_TO_SWITCH = 2
#: with real_time_factor 0, each tick advances this much simulated time [s] (whole samples)
FAST_CHUNK = 0.04
#: node keys whose change rebuilds the integrator at the current state
STEPPER_KEYS = ('integrator', 'rtol', 'atol', 'step_size')
#: the columns of the centrifuge's :attr:`SampleBlock.energy` (the ``energy`` topic's layout)
ENERGY_COLUMNS = Model.energy_fields


class Level(enum.StrEnum):
    """Level of the simulation's diagnostic status (diagnostic_msgs/DiagnosticStatus)."""

    OK = 'OK'
    WARN = 'WARN'
    ERROR = 'ERROR'


@dataclasses.dataclass(frozen=True)
class SampleBlock:
    """The grid samples of one tick with every derived output (m samples).

    ``position``, ``velocity`` and ``effort`` are (m, j) in the model's joint order
    (``joint_names``; no efforts: (m, 0)); ``energy`` maps each of the model's
    ``energy_fields`` to an (m,) array; ``quaternion`` (4,) and ``axis`` (3,) (the symmetry
    axis in space axes) belong to the last sample, ``quaternions`` (m, 4) to every sample
    (all None for a system without a 3-D pose).
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray
    energy: dict[str, np.ndarray]
    quaternion: np.ndarray | None
    axis: np.ndarray | None
    quaternions: np.ndarray | None = None

    def __len__(self) -> int:
        """Return the number of samples."""
        return len(self.t)


def _describe(err: BaseException) -> str:
    """Return a one-line account of an exception for the diagnostics."""
    if isinstance(err, GyroRotorError):
        return str(err)
    return f'{type(err).__name__} in the model or integrator: {err}'


class LiveSimulation:
    """A scene of any rotor system integrated in real time (see the module doc).

    Parameters
    ----------
    scene : Scene
        The scene (its system, parameters and initial condition; ``t_end``).
    cfg : mapping
        The node keys of :data:`~gyro_rotor.node_settings.NODE_KEYS` (publish_rate,
        real_time_factor, integrator, rtol, atol, step_size, max_catch_up, stop_at_t_end,
        max_residual, ...); kept as :attr:`cfg` and updated by :meth:`apply`.
    perturbation : mapping
        The kick of :meth:`perturb` (the scene's keys, :meth:`Scene.kick_values`).
    budget : float or None
        Work budget of a tick [s] (None: unbounded).
    clock : callable
        The steady clock [s]; must be ``time.monotonic`` (or agree with it) when a budget
        is set, since the steppers check their deadline against it.
    log : callable, optional
        ``log(level, text)`` for events worth a log line (a :class:`Level`).
    """

    def __init__(self, scene: Scene, cfg: Mapping[str, Any],
                 perturbation: Mapping[str, Any] | None = None,
                 *, budget: float | None = TICK_BUDGET,
                 clock: Callable[[], float] = time.monotonic,
                 log: Callable[[Level, str], None] | None = None):
        self.scene = scene
        self.cfg = dict(cfg)
        self.perturbation = scene.kick_values(perturbation or {})
        self.budget = budget
        self.clock = clock
        self._log = log or (lambda level, text: None)
        self.model: Model | GeneralModel = scene.make_model()
        #: samples produced over the simulation's life (never reset)
        self.seq = 0
        #: the last work-budget event (a method switch), for the diagnostics
        self.switch = ''
        self._auto = False          # after a budget switch: 'auto' instead of cfg['integrator']
        self._switched: Stepper | None = None      # the stepper a budget switch made
        self.start(scene.initial_state(self.model))

    @property
    def joint_names(self) -> tuple:
        """Return the names of the joint_states columns (the model's)."""
        return tuple(self.model.joint_names)

    @property
    def energy_fields(self) -> tuple:
        """Return the fields of the energy array (the model's)."""
        return self.model.energy_fields

    # -- state -------------------------------------------------------------------------------
    def start(self, y0: np.ndarray) -> None:
        """(Re)start at t = 0 from y0."""
        self.stepper = self._new_stepper(self.model, 0.0, y0, self.cfg)
        self._cuts = 0              # consecutive ticks of this stepper cut by the budget
        self.baseline = EnergyBaseline(self.model.energy, self.model.idiss, y0)
        # (t_c, field angles at t_c) of the rotors, for phi_R
        self._field = (0.0, np.zeros(len(self.model.field_speeds())))
        self.pacer = Pacer(self.stepper, self.cfg['publish_rate'],
                           rtf=self.cfg['real_time_factor'],
                           max_catch_up=self.cfg['max_catch_up'],
                           chunk_samples=max(1, math.ceil(self.cfg['publish_rate'] * FAST_CHUNK)),
                           t_end=self._t_end())
        #: (t, y) of the last good sample
        self.last = (0.0, np.array(y0, dtype=float))
        #: why the integration stopped (None while it runs)
        self.diverged: str | None = None

    def _t_end(self) -> float | None:
        return self.scene.t_end if self.cfg['stop_at_t_end'] else None

    def _new_stepper(self, model, t: float, y: np.ndarray, cfg: Mapping) -> Stepper:
        t_end = self.scene.t_end if cfg['stop_at_t_end'] else math.inf
        method = 'auto' if self._auto else cfg['integrator']
        method, self.method_reason = resolve_method(method, model, t_end, y)
        if self._auto:
            self.method_reason = f'work budget: {self.method_reason}'
        if isinstance(model, GeneralModel) and method not in SYSTEM_METHODS:
            raise ParameterError(f"integrator '{method}': general systems integrate with "
                                 f"auto, {', '.join(SYSTEM_METHODS)}")
        return make_stepper(method, model.rhs, t, y, rtol=cfg['rtol'], atol=cfg['atol'],
                            step_size=cfg['step_size'], model=kernel_model(model))

    def _restart_stepper(self, y: np.ndarray) -> None:
        self._use(self._new_stepper(self.model, self.stepper.t, y, self.cfg))

    def _use(self, stepper: Stepper) -> None:
        """Continue with a new stepper at its t (its budget cuts are counted afresh)."""
        self.stepper = stepper
        self._cuts = 0
        self.pacer.restart(stepper, self.clock())

    def _field_angle(self, t: float) -> np.ndarray:
        t_c, a_c = self._field
        return a_c + self.model.field_speeds() * (t - t_c)

    def _diverge(self, reason: str) -> None:
        self.diverged = reason
        self._log(Level.ERROR, f'integration stopped, last good state at t = '
                               f'{self.last[0]:.6f} s kept: {reason}')

    # -- parameter changes -------------------------------------------------------------------
    def check(self, changes: Mapping[str, Any]) -> None:
        """Raise a GyroRotorError if the changes cannot be applied (nothing changes here).

        A kick is checked by the scene (:meth:`Scene.kick_values`); new physical constants
        by the scene (:meth:`Scene.with_live_changes`) and, with the integrator settings,
        by building the new model and stepper at the current (or, after a divergence, the
        last good) state.
        """
        try:
            kick = {k.split('.', 1)[1]: v for k, v in changes.items()
                    if k.startswith('perturbation.')}
            if kick:
                self.scene.kick_values({**self.perturbation, **kick})
            new = self.scene.with_live_changes(changes)
            if new is not None or any(k in changes for k in STEPPER_KEYS):
                cfg = {**self.cfg, **{k: v for k, v in changes.items() if k in self.cfg}}
                t, y = self.last if self.diverged else (self.stepper.t, self.stepper.y)
                auto, self._auto = self._auto, self._auto and 'integrator' not in changes
                model = self.model if new is None else new.make_model()
                try:
                    self._new_stepper(model, t, y, cfg)
                finally:
                    self._auto = auto
        except GyroRotorError:
            raise
        except Exception as err:  # noqa: B902 -- a change the model cannot evaluate
            raise ParameterError(f'{", ".join(changes)}: {_describe(err)}') from err

    def apply(self, changes: Mapping[str, Any]) -> None:
        """Apply checked changes without restart (the guard catches what still fails)."""
        try:
            self._apply(changes)
        except Exception as err:  # noqa: B902 -- the divergence guard
            self._diverge(_describe(err))

    def _apply(self, changes: Mapping[str, Any]) -> None:
        kick = {}
        for k, v in changes.items():
            if k in self.cfg:
                self.cfg[k] = v
            elif k.startswith('perturbation.'):
                kick[k.split('.', 1)[1]] = v
        if kick:
            self.perturbation = self.scene.kick_values({**self.perturbation, **kick})
        if 'integrator' in changes:
            self._auto = False
        new = self.scene.with_live_changes(changes)
        if 't_end' in changes:
            if new is None:
                self.scene = self.scene.with_t_end(changes['t_end'])
            else:
                new = new.with_t_end(changes['t_end'])
        if new is not None and self.diverged:
            # stopped: take the parameters for the next reset, integrate nothing
            self.scene = new
            self.model = new.make_model()
        elif new is not None:
            self._apply_params(new)
        elif not self.diverged and any(k in changes for k in STEPPER_KEYS):
            self._restart_stepper(self.stepper.y.copy())
        now = self.clock()
        if 'real_time_factor' in changes:
            self.pacer.set_rtf(self.cfg['real_time_factor'], now)
        self.pacer.max_catch_up = self.cfg['max_catch_up']
        self.pacer.t_end = self._t_end()

    def _apply_params(self, new: Scene) -> None:
        """Switch to the scene's new parameters at the current state (module doc)."""
        y_old = self.stepper.y.copy()
        model = new.make_model()
        t = self.stepper.t
        if np.any(model.field_speeds() != self.model.field_speeds()):
            self._field = (t, self._field_angle(t))
        y = model.carried_state(self.model, y_old)
        self.scene = new
        self.model = model
        jump = self.baseline.rebase(self.model.energy, y, y_old)
        self._restart_stepper(y)
        self._log(Level.OK, f'parameters changed; E* jumped by {jump:.6g} J (residual '
                            f'baseline moved with it); integrator {self.stepper.method}')

    # -- ticks -------------------------------------------------------------------------------
    def tick(self, now: float | None = None, woke: float | None = None) -> SampleBlock | None:
        """Advance to the pacer's target now; return the new good samples (None if none).

        ``now``: the steady-clock time to advance to (default: the clock now); a loop that
        sleeps to absolute deadlines passes the deadline, and when it ``woke`` (the work
        budget and the tick figures count from then). Never raises for a failure of the
        model or the integrator: that is a divergence.
        """
        if self.diverged:
            return None
        if woke is None:
            woke = self.clock()
        if now is None:
            now = woke
        deadline = None if self.budget is None else woke + self.budget
        block = None
        try:
            samples = self.pacer.tick(now, deadline, woke=woke)
            if samples:
                block = self._block(samples)
        except Exception as err:  # noqa: B902 -- the divergence guard
            self._diverge(_describe(err))
        self.pacer.end_tick(self.clock())
        self._cuts = self._cuts + 1 if self.pacer.cut else 0
        if self._cuts >= CUTS_TO_SWITCH and not self.diverged:
            self._over_budget()
        return block

    def _over_budget(self) -> None:
        """Switch to auto's method for the current parameters, or say that none is better."""
        cur = self.stepper.method
        t_end = self.scene.t_end if self.cfg['stop_at_t_end'] else math.inf
        method, reason = resolve_method('auto', self.model, t_end, self.stepper.y)
        what = (f'tick work budget {1e3 * self.budget:g} ms exceeded with {cur} at '
                f't = {self.stepper.t:.6f} s')
        if method.lower() != cur.lower():
            self._auto = True
            try:
                self._restart_stepper(self.stepper.y.copy())
            except Exception as err:  # noqa: B902 -- the divergence guard
                return self._diverge(_describe(err))
            self.switch = f'{what}: switched to {self.stepper.method} ({reason})'
            self._switched = self.stepper
            self._log(Level.WARN, self.switch)
        elif self.stepper is not self._switched and \
                not self.switch.startswith(what.split(' at t = ')[0]):
            # (the method a switch chose keeps that message: its first ticks may be slow too)
            self.switch = f"{what}: {cur} is auto's choice already; simulation time falls " \
                          'behind real time'
            self._log(Level.WARN, self.switch)

    def _block(self, samples) -> SampleBlock | None:
        """Derive every output of the samples; stop before the first one the guard rejects."""
        m = self.model
        n = len(samples)
        t = np.fromiter((s.t for s in samples), float, n)
        Y = np.array([s.y for s in samples])
        with np.errstate(all='ignore'):
            E = np.asarray(m.energy(Y), dtype=float)
        D = Y[:, m.idiss]
        E_ref, limit = self.baseline.E_ref, self.cfg['max_residual']
        resid = E + D - E_ref
        n_good = first_break(E, resid, E_ref, limit)
        n_good = n if n_good is None else n_good
        block = self._outputs(samples[:n_good], t[:n_good], Y[:n_good], E[:n_good],
                              resid[:n_good]) if n_good else None
        if n_good < n:
            self._diverge(describe_break(t[n_good], E[n_good], resid[n_good], E_ref, limit))
        return block

    def _outputs(self, samples, t, Y, E, resid) -> SampleBlock:
        m = self.model
        n = len(t)
        t_c, a_c = self._field
        field = a_c + m.field_speeds() * (t - t_c)[:, None]
        position, velocity, effort, q = m.joints(Y, field)
        diss = m.dissipation(Y)
        columns = {'t_sim': t, 'E_star': E, 'dE_dt': -diss, 'dissipation': diss,
                   'residual': resid, **m.state_fields(Y),
                   'seq': np.arange(self.seq, self.seq + n, dtype=float), 'D': Y[:, m.idiss],
                   'k': np.fromiter((s.k for s in samples), float, n)}
        self.seq += n
        self.last = (samples[-1].t, samples[-1].y)
        return SampleBlock(
            t=t, position=position, velocity=velocity, effort=effort,
            energy={f: columns[f] for f in m.energy_fields},
            quaternion=None if q is None else q[-1],
            axis=None if q is None else axis_from_quaternion(q[-1]), quaternions=q)

    # -- services ----------------------------------------------------------------------------
    def reset(self) -> str:
        """Start the scene again at t = 0 (also after a divergence); return a message."""
        y0 = self.scene.initial_state(self.model)
        self.start(y0)
        self.pacer.set_rtf(self.cfg['real_time_factor'], self.clock())
        # the previous run's "cannot keep up" is not this run's (issue 24, finding 15)
        self.switch = ''
        return f"reset to scene '{self.scene.name}' at t = 0"

    def perturb(self) -> str:
        """Kick the state by :attr:`perturbation`; move E*'s baseline by the jump."""
        if self.diverged:
            raise ParameterError('diverged: reset first')
        y_old = self.stepper.y.copy()
        y = self.model.kick(y_old, self.scene.model_kick(self.perturbation))
        why = self.model.singular_at(y)     # the centrifuge's axis at theta = pi
        if why:
            raise ParameterError(f'kick refused: {why}')
        try:       # the new stepper first: a state the model cannot evaluate changes nothing
            stepper = self._new_stepper(self.model, self.stepper.t, y, self.cfg)
        except GyroRotorError as err:
            if not isinstance(err, IntegrationError):
                raise
            raise ParameterError(f'kick refused: {err}') from err
        except Exception as err:  # noqa: B902 -- e.g. the model's singularity at theta = pi
            raise ParameterError(f'kick refused: {_describe(err)}') from err
        jump = self.baseline.rebase(self.model.energy, y, y_old)
        self._use(stepper)
        return (f'kicked at t = {self.stepper.t:.6f} s with {self.perturbation}; E* changed '
                f'by {jump:.6g} J')

    def pause(self, paused: bool) -> str:
        """Hold (True) or continue (False) simulation time."""
        if paused:
            self.pacer.pause(self.clock())
        else:
            self.pacer.resume(self.clock())
        return 'paused' if paused else 'running'

    # -- reports -----------------------------------------------------------------------------
    def _norm_error(self, y: np.ndarray) -> float:
        """Drift of the quaternion's norm (the model's: 0 for a model without one)."""
        return float(self.model.quaternion_norm_error(y))

    def _status(self, w) -> tuple[Level, str]:
        rtf = self.pacer.rtf
        qn = self._norm_error(self.last[1])
        if self.diverged:
            return Level.ERROR, f'diverged: {self.diverged}'
        if self.pacer.paused:
            return Level.OK, 'paused'
        if self.pacer.finished:
            return Level.OK, f'stopped at t_end = {self.scene.t_end:g} s'
        if w.budget_cuts:
            return Level.WARN, (f'cannot keep up: {w.budget_cuts} ticks cut by the work '
                                f'budget, {w.lost_sim_time:.3f} s of simulation time lost; '
                                f'{self.switch}')
        if w.capped:
            return Level.WARN, (f'cannot keep up: {w.capped} ticks capped, '
                                f'{w.lost_sim_time:.3f} s of simulation time lost')
        if rtf > 0 and w.ticks > 2 and w.achieved_rtf < 0.9 * rtf:
            return Level.WARN, f'achieved real-time factor {w.achieved_rtf:.3f} < {rtf:g}'
        if abs(qn) > 1e-6:
            return Level.WARN, f'quaternion norm drift {qn:.3e}'
        return Level.OK, 'running'

    def diagnostics(self) -> tuple[Level, str, dict[str, Any]]:
        """Return (level, message, values) over the window since the last call."""
        w = self.pacer.take_window(self.clock())
        y = self.last[1]
        st = self.stepper
        level, msg = self._status(w)
        values = {
            'scene': self.scene.name, 'model': self.model.name, 'integrator': st.method,
            'rtol': getattr(st, 'rtol', ''), 'atol': getattr(st, 'atol', ''),
            'step_size': getattr(st, 'h', ''), 't_sim': st.t,
            'real_time_factor': self.pacer.rtf, 'achieved_rtf': w.achieved_rtf,
            'overruns': w.overruns, 'overruns_total': self.pacer.overruns,
            'capped_ticks': w.capped, 'capped_total': self.pacer.capped,
            'budget_cuts': w.budget_cuts, 'budget_cuts_total': self.pacer.budget_cuts,
            'tick_budget': '' if self.budget is None else self.budget,
            'method_switch': self.switch,
            'lost_sim_time_total': self.pacer.lost_sim_time,
            'tick_interval_mean': w.interval_mean, 'tick_jitter_std': w.interval_std,
            'tick_interval_max': w.interval_max, 'tick_busy_max': w.busy_max,
            'integrator_reason': self.method_reason, 'nfev': st.nfev,
            'quaternion_norm_error': self._norm_error(y),
            'residual': self.baseline.residual(y), 'E_star': float(self.model.energy(y)),
            'samples': self.seq, 'publish_rate': self.cfg['publish_rate'],
            'paused': self.pacer.paused}
        return level, msg, values

    def scene_doc(self) -> dict[str, Any]:
        """Return the current scene as a document (the node's ``~/scene``).

        The scene's keys (:meth:`Scene.document_parts`) around the node's: the kick, the
        node keys, the integrator and the simulation time.
        """
        head, tail = self.scene.document_parts()
        return {**head, 'perturbation': self.perturbation, 'node': self.cfg,
                'integrator': self.stepper.method, 't_sim': self.stepper.t, **tail}
