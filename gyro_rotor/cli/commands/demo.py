"""``gyro-rotor demo [SCENE]``: the paper's theorem, live, in one command.

Starts ``rotor_sim`` and ``rotor_analysis`` as separate processes in a ROS domain of
their own (DDS on loopback), kicks the rotor through ``~/perturb``, shows a live table
(simulation time, E*, residual, the decay rate of E* against its predicted bound, and
identified against predicted frequencies of each mode), records an MCAP bag under a fresh
directory, then analyses the bag offline and ends with the verdict, the report and the
plot paths.

Exit status 0 (CONFIRMED) only if the offline verdict of the bag is confirmed (every
applicable criterion of :mod:`gyro_rotor.analysis.verdict` passed: Lyapunov, energy
balance, decay, modes, data, synchronism), it is the verdict the linear theory expects
(:func:`gyro_rotor.linear.system.assess`: asymptotically stable for the
default scene, marginal tilt modes for ``upright``), for a sine drive law the pole-slip
count equals that of an offline reference simulation, and both nodes exited cleanly;
else 1 (NOT CONFIRMED, naming why), 130 after Ctrl-C (the bag is finalized and
analysed), 128 + N after SIGTERM or SIGHUP (the nodes stopped and the bag finalized, no
analysis). However the demo ends -- done, Ctrl-C, SIGTERM (``timeout``), SIGHUP, an error --
both nodes are stopped first; if the demo itself is killed (SIGKILL), Linux sends them
SIGTERM (``PR_SET_PDEATHSIG``).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
import signal
import sys
import time

from gyro_rotor.cli.util import check_number
from gyro_rotor.errors import GyroRotorError, ParameterError
from gyro_rotor.signals import StopSignals
from gyro_rotor.tools.launch import (claim_domain_id, make_output_dir, NodeProcess, SideNode,
                                     tear_down)
from gyro_rotor.tools.monitor import message_values

HELP = ('live demo: simulation + analysis nodes, a kick, a live table, an MCAP bag, the '
        'verdict with report and plots')


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``demo``."""
    p.add_argument('scene', nargs='?', default='precession', help='scene name or path')
    p.add_argument('--duration', type=float, default=20.0,
                   help='simulated seconds to run (default 20)')
    p.add_argument('--rtf', type=float, default=1.0,
                   help='real-time factor (default 1; 0 = as fast as possible)')
    p.add_argument('--rate', type=float, default=250.0, help='publish rate [Hz]')
    p.add_argument('--kick-at', type=float, default=None,
                   help='simulation time of the kick [s] (default 2; none for pole_slip, '
                        'whose start far off synchronism is the kick; <0 = no kick)')
    p.add_argument('--out', default=None,
                   help='output directory (default: demo_runs/<scene>_<time>)')
    p.add_argument('--quiet', action='store_true', help='no live table')


def _check(args: argparse.Namespace) -> None:
    from gyro_rotor.node_settings import NODE_RANGES       # rotor_sim's own limits
    check_number('--duration', args.duration, low=0.0, low_open=True,
                 high=NODE_RANGES['t_end'][1], what='s')
    check_number('--rtf', args.rtf, low=0.0, high=NODE_RANGES['real_time_factor'][1],
                 what='(0 = as fast as possible)')
    check_number('--rate', args.rate, low=10.0, high=10000.0, what='Hz')
    if args.kick_at is not None:
        if not math.isfinite(args.kick_at):
            raise ParameterError(f'--kick-at must be finite (a time in s; any finite negative '
                                 f'value: no kick), got {args.kick_at}')
        if args.kick_at >= 0 and not 1.0 / args.rate <= args.kick_at < args.duration:
            raise ParameterError(f'--kick-at must be at least one sample (1/{args.rate:g} s) '
                                 f'and before --duration ({args.duration:g} s), or negative '
                                 f'for no kick; got {args.kick_at}')
    # rotor_sim publishes on the grid k / rate and stops at t_end: a time off the grid is
    # never reached (--duration 5 kicked at 1.25 s waited at 1.248 s until the deadline)
    if round(args.duration * args.rate) < 1:
        raise ParameterError(f'--duration {args.duration:g} s is shorter than one sample '
                             f'(1/{args.rate:g} s)')
    args.duration = _on_grid(args.duration, args.rate)


def _on_grid(t: float, rate: float) -> float:
    """Return the sample time k / rate nearest to ``t`` (rotor_sim's publication grid)."""
    return round(t * rate) / rate


#: subscribers rotor_sim waits for on joint_states and on energy before its time starts:
#: the recorder of rotor_analysis and the demo's own view (which subscribes to both)
SUBSCRIBERS = 2


#: the signals that stop the demo: Ctrl-C, ``kill``, and the terminal closing
SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class _LiveView(SideNode):
    """An rclpy node in the demo process: listens to energy and analysis, kicks."""

    def __init__(self, domain_id: int, signals: StopSignals | None = None):
        from gyro_rotor.ros.qos import profile
        from std_msgs.msg import Float64MultiArray, String
        from std_srvs.srv import Trigger
        super().__init__('gyro_rotor_demo', domain_id, signals)
        self.energy: dict = {}
        self.analysis: dict = {}
        self.modes: list = []
        self.verdict = ''
        # reliable, keep last 10: the view may skip samples but always gets the newest (it
        # ends when t_sim reaches the duration; best effort lost the last 0.7 s of a burst
        # at --rtf 0, and the demo then waited for its deadline)
        qos, latched = 10, profile('latched')
        self.node.create_subscription(Float64MultiArray, 'energy', self._on_energy, qos)
        # joint_states too, though the table does not show it: rotor_sim then waits for
        # this view *and* the recorder on both state topics (SUBSCRIBERS); with energy
        # alone, this view could stand in for a recorder not yet matched on energy, whose
        # first sample was then never recorded (1 unpaired in 1 of 6 suite runs)
        from sensor_msgs.msg import JointState
        self.node.create_subscription(JointState, 'joint_states', lambda _msg: None, qos)
        self.node.create_subscription(Float64MultiArray, 'analysis', self._on_analysis, 10)
        self.node.create_subscription(Float64MultiArray, 'analysis_modes', self._on_modes, 10)
        self.node.create_subscription(String, 'analysis_verdict', self._on_verdict, latched)
        #: why rotor_sim stopped integrating (its diagnostics: 'diverged: ...'), '' if not
        self.diverged = ''
        from diagnostic_msgs.msg import DiagnosticArray
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics,
                                      10)
        self.perturb = self.node.create_client(Trigger, '/rotor_sim/perturb')
        self._trigger = Trigger
        from rcl_interfaces.srv import SetParameters
        self.set_params = self.node.create_client(SetParameters, '/rotor_sim/set_parameters')

    def _on_energy(self, msg) -> None:
        self.energy = message_values(msg)

    def _on_analysis(self, msg) -> None:
        self.analysis = message_values(msg)

    def _on_modes(self, msg) -> None:
        if len(msg.layout.dim) == 2:
            self.modes = list(message_values(msg).items())

    def _on_verdict(self, msg) -> None:
        self.verdict = msg.data

    def _on_diagnostics(self, msg) -> None:
        for st in msg.status:
            if st.name.startswith('rotor_sim') and st.message.startswith('diverged:'):
                self.diverged = st.message

    def _call(self, client, request, timeout: float):
        """Call a service and spin until it answers; return the response (None: none).

        A signal during the wait for the service is acted on after it (up to ``timeout``);
        the wait for the answer spins, so a stop request ends it at once.
        """
        if not client.wait_for_service(timeout_sec=timeout):
            return None
        fut = client.call_async(request)
        end = time.monotonic() + timeout
        while not fut.done() and time.monotonic() < end:
            self.spin(0.05)
        return fut.result() if fut.done() else None

    def kick(self, timeout: float = 5.0) -> str:
        """Call /rotor_sim/perturb; return its message."""
        res = self._call(self.perturb, self._trigger.Request(), timeout)
        return res.message if res is not None else 'perturb service: no answer'

    def set_t_end(self, t_end: float, timeout: float = 5.0) -> None:
        """Set rotor_sim's t_end (a live parameter); raise GyroRotorError if refused."""
        from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
        req = self.set_params.srv_type.Request(parameters=[Parameter(
            name='t_end', value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE,
                                               double_value=float(t_end)))])
        res = self._call(self.set_params, req, timeout)
        if res is None or not res.results[0].successful:
            raise GyroRotorError(f'rotor_sim did not take t_end = {t_end} s: '
                                 f'{res.results[0].reason if res else "no answer"}')


def _short(name: str) -> str:
    """Return a mode's name for the live table: 'nutation', 'z_R2', 'beta1 6.11'.

    Whole words, never cut inside one ('rotor-field', not 'rotor-fie'): the first word of
    a centrifuge mode, the dominant coordinate (and the frequency that tells two such
    modes apart) of a general system's.
    """
    if name.startswith(('mode (', 'unreached mode (')):
        inner, _, rest = name.split('(', 1)[1].partition(')')
        return inner + (' ' + rest.split()[0] if rest.strip() else '')
    return name.split(' ')[0]


def _mode_cell(row: dict) -> str:
    pred = row.get('pred_im', math.nan) / (2 * math.pi)
    meas = row.get('meas_im', math.nan) / (2 * math.pi)
    m = '-' if not math.isfinite(meas) else f'{abs(meas):.3f}'
    return f'{abs(pred):.3f}/{m}'


#: the criteria columns of the live table: field of the ``analysis`` topic, header letter
_CRITERIA = (('lyapunov_status', 'L'), ('energy_balance_status', 'E'), ('decay_status', 'D'),
             ('modes_status', 'M'), ('data_status', 'd'), ('sync_status', 'S'),
             ('scene_status', 'F'))
_STATUS_MARK = {0: '+', 1: 'X', 2: '.'}


def _num(x: float, spec: str) -> str:
    return format(x, spec) if math.isfinite(x) else '-'.rjust(int(spec.split('.')[0]))


def _rate_cell(a: dict) -> str:
    """Return the rate of E* - E*_inf; in parentheses while criterion D has not decided.

    Undecided (D NOT YET), the rate is that of the terms the window shows, not one the
    bound applies to (the slowest term may be merged into E*_inf): the parentheses keep it
    from reading as a rate that clears the bound beside it.
    """
    rate = a.get('energy_decay_rate', math.nan)
    status = a.get('decay_status', math.nan)
    decided = math.isfinite(status) and _STATUS_MARK.get(int(status)) in ('+', 'X')
    if decided or not math.isfinite(rate):
        return _num(rate, '9.4f')
    return f'({rate:.4f})'.rjust(9)


def _line(view: _LiveView) -> str:
    e, a = view.energy, view.analysis
    nan = math.nan
    t = e.get('t_sim', nan)
    marks = ''.join(_STATUS_MARK.get(int(a[f]), '?') if math.isfinite(a.get(f, nan)) else ' '
                    for f, _ in _CRITERIA)
    cells = [_num(t, '7.2f'), _num(e.get('E_star', nan), '11.7f'),
             _num(e.get('residual', nan), '9.1e'),
             _rate_cell(a),
             _num(a.get('decay_rate_bound', nan), '9.4f'),
             f'{int(a["pole_slips"]) if "pole_slips" in a else "-":>5}', f'{marks:7s}']
    modes = '  '.join(f'{_short(name)} {_mode_cell(row)}'
                      for name, row in view.modes
                      if 'zero' not in name and math.isfinite(row.get('pred_im', math.nan)))
    return '  '.join(cells) + '  ' + modes + f'  {view.verdict.split(":")[0]}'


HEADER = ('  t [s]       E* [J]  residual  E* decay   >= bound  slips  LEDMdSF  modes: '
          'predicted/identified frequency [Hz]  live verdict\n'
          '  (criteria L Lyapunov, E energy balance, D decay, M modes, d data, S synchronism,'
          ' F the data fit the scene: + PASS, X FAIL, . NOT YET; E* decay in parentheses:'
          ' D has not decided, the rate is not yet held against the bound)')


def expected_outcome(scene, duration: float) -> dict:
    """Return what linear theory (and, for a sine law, a reference simulation) expects.

    The verdict of the scene's linearization (:func:`gyro_rotor.analysis.prediction.predict`);
    with a sine-law drive, the pole slips of a reference simulation of the same run.
    """
    from gyro_rotor.analysis.prediction import predict
    exp = {'verdict': predict(scene).verdict, 'pole_slips': None}
    if any(scene.pole_pairs):
        from gyro_rotor.analysis.analyzer import RotorAnalyzer
        from gyro_rotor.analysis.samples import iter_samples
        from gyro_rotor.numerics.simulate import simulate
        tr = simulate(scene, t_end=duration, rate=250.0)
        ref = RotorAnalyzer(scene, window_s=0, checkpoint_s=0)     # the slip count alone
        ref.add_many(iter_samples(tr))
        exp['pole_slips'] = ref.result().pole_slips
    return exp


def _out_dir(args: argparse.Namespace, scene) -> Path:
    """Return the output directory: --out (new or empty), else a new one for this run.

    The default demo_runs/<scene>_<time>[-k] is created here, atomically: two demos started
    in the same second get two folders (the second one the suffix -2), never one shared.
    """
    if not args.out:
        from gyro_rotor.cli.util import make_unique_dir
        stamp = time.strftime('%Y%m%d-%H%M%S')
        return make_unique_dir(Path('demo_runs') / f'{scene.name}_{stamp}')
    from gyro_rotor.cli.util import check_output_dir
    check_output_dir(args.out)
    out = Path(args.out)
    if out.exists() and any(out.iterdir()):
        raise ParameterError(f'output directory {out} exists and is not empty')
    return make_output_dir(out)


def _start_nodes(args, scene_arg: str, out: Path, domain_id: int, logs: dict) -> list:
    procs = [NodeProcess('gyro_rotor.ros.analysis_node', {
        'output': str(out / 'bag'), 'scene': str(scene_arg), 'use_sim_time': True},
        domain_id=domain_id, die_with_parent=True,
        stdout=logs['rotor_analysis'], stderr=logs['rotor_analysis'])]
    return procs


def default_kick_at(scene, duration: float) -> float:
    """Return the demo's kick time: 2 s (a quarter of a shorter run); -1 for none.

    None for a scene without a ``perturbation`` (its initial condition is the kick) and for
    a sine-law drive (pole_slip: its start far off synchronism is the kick).
    """
    kicked = scene.kicked and not any(scene.pole_pairs)
    return min(2.0, duration / 4) if kicked else -1.0


def _first_stop(args, kick_at: float) -> float:
    """Return the simulation time where rotor_sim first stops: the kick's, else the end.

    The simulation holds at the kick's time (stop_at_t_end) until the kick is done, so the
    kick lands exactly there however late the demo process sees that time (a loaded
    machine); then t_end moves on to the duration.
    """
    return kick_at if 0.0 <= kick_at < args.duration else float(args.duration)


def _start_sim(args, scene_arg: str, domain_id: int, logs: dict, t_stop: float):
    return NodeProcess('gyro_rotor.ros.sim_node', {
        'scene': str(scene_arg), 'real_time_factor': float(args.rtf),
        'publish_rate': float(args.rate), 't_end': float(t_stop),
        'stop_at_t_end': True, 'wait_for_subscribers': SUBSCRIBERS,
        'wait_for_node': 'rotor_analysis'}, domain_id=domain_id, die_with_parent=True,
        stdout=logs['rotor_sim'], stderr=logs['rotor_sim'])


def _watch(args, view: _LiveView, procs: list, out: Path, kick_at: float) -> str:
    """Show the live table and kick once, until the simulation reaches the duration.

    Return why rotor_sim stopped integrating before the duration ('' if it did not).
    """
    if not args.quiet:
        print(HEADER)
    kicked = kick_at < 0
    next_print = time.monotonic()
    deadline = time.monotonic() + 120.0 + (args.duration / args.rtf if args.rtf else 0)
    last_t = -1.0
    while True:
        view.spin(0.1)
        t = view.energy.get('t_sim', -1.0)
        if not kicked and t >= kick_at - 0.25 / args.rate:
            print(f'  kick at t = {t:.2f} s: {view.kick()}')
            kicked = True
            if _first_stop(args, kick_at) < args.duration:
                view.set_t_end(args.duration)
        if not args.quiet and time.monotonic() >= next_print and t > last_t:
            print(_line(view), flush=True)
            next_print = time.monotonic() + 1.0
            last_t = t
        if t >= args.duration - 0.5 / args.rate:
            break
        if view.diverged:
            # the simulation stopped short of the duration: the bag holds the run up to
            # there, and the analysis says what it shows (no wait for the deadline)
            print(f'  the simulation stopped at t = {t:.3f} s: {view.diverged}', flush=True)
            break
        for p in procs:
            if p.poll() is not None:
                raise GyroRotorError(f'{p.module} exited early with status {p.poll()}; '
                                     f'see {out}')
        if time.monotonic() > deadline:
            raise GyroRotorError(f'the simulation did not reach t = {args.duration} s in '
                                 f'time (last t = {t:.3f} s); see {out}/rotor_sim.log')
    view.spin(1.5)     # let the analysis take the last samples
    if not args.quiet:
        print(_line(view))
    return view.diverged


def _run_live(args, scene, out: Path, kick_at: float) -> tuple[dict, int, str]:
    """Run both nodes with the live table; return (exit codes, signal or 0, divergence).

    The divergence: why rotor_sim stopped integrating before the duration ('' if not).

    The nodes are stopped (SIGINT, then SIGTERM, then SIGKILL) however this ends; a
    signal while they stop is counted, not acted on, so the stopping is not cut short. A
    signal only asks for the stop (:class:`~gyro_rotor.signals.StopSignals`): the live
    view's loops leave at their next boundary.
    """
    scene_arg = scene.path or args.scene
    signals = StopSignals(SIGNALS)
    claim = claim_domain_id()
    logs: dict = {}
    procs: list = []
    view = None
    stopped_by = 0
    diverged = ''
    try:
        signals.install()
        logs.update((n, open(out / f'{n}.log', 'w')) for n in ('rotor_sim', 'rotor_analysis'))
        print(f'ROS_DOMAIN_ID {claim.domain_id} (localhost only); recording to {out / "bag"}\n'
              f'watch it from another terminal: gyro-rotor monitor --domain-id '
              f'{claim.domain_id}', flush=True)
        procs += _start_nodes(args, scene_arg, out, claim.domain_id, logs)
        view = _LiveView(claim.domain_id, signals)
        view.spin(1.0)
        procs.append(_start_sim(args, scene_arg, claim.domain_id, logs,
                                _first_stop(args, kick_at)))
        diverged = _watch(args, view, procs, out, kick_at)
        signals.check()
    except KeyboardInterrupt as err:
        stopped_by = getattr(err, 'signum', signal.SIGINT)
        print(f'\n{"interrupted" if stopped_by == signal.SIGINT else "terminated"}: '
              'stopping the nodes, finalizing the bag', file=sys.stderr, flush=True)
    finally:
        codes = tear_down(procs, view, claim, logs, signals)
    return codes, int(stopped_by), diverged


def _conclude(out: Path, exp: dict, codes: dict, interrupted: bool = False,
              diverged: str = '') -> bool:
    """Analyse the bag offline, print the report and the checks; return CONFIRMED.

    ``interrupted``: the run was stopped (Ctrl-C) before its duration; the verdict is
    that of the data up to the cut, and says so. ``diverged``: why rotor_sim stopped
    integrating before the duration (a check that fails).
    """
    from gyro_rotor.analysis.offline import analyze_bag
    from gyro_rotor.analysis.report import text_report, write_report
    bag = out / 'bag'
    if not bag.exists():
        raise GyroRotorError(f'no bag was recorded; see {out}/rotor_analysis.log')
    ana = analyze_bag(str(bag), cut_note='interrupted (Ctrl-C)' if interrupted else '')
    files = write_report(ana, out / 'report', None, plots=True)
    res = ana.result
    print()
    print(text_report(res, ana))
    bad_exit = {m: c for m, c in codes.items() if c not in (0, -2)}
    checks = [(res.confirmed, f'verdict {res.verdict}: {res.reason}'),
              (res.verdict == exp['verdict'],
               f'verdict {str(res.verdict)!r}, expected by the linear theory '
               f'{str(exp["verdict"])!r}')]
    if exp['pole_slips'] is not None:
        checks.append((res.pole_slips == exp['pole_slips'],
                       f'pole slips {res.pole_slips}, reference {exp["pole_slips"]}'))
    checks.append((not bad_exit, f'node exit codes {codes}'))
    if diverged:
        checks.append((False, f'rotor_sim stopped integrating: {diverged}'))
    print('checks:')
    for ok, text in checks:
        print(f'  [{"ok" if ok else "FAILED"}] {text}')
    print(f'bag:    {bag}')
    print(f'report: {out / "report" / "report.txt"}')
    for f in files:
        if str(f).endswith('.png'):
            print(f'plot:   {f}')
    ok = all(c for c, _ in checks)
    why = [t for c, t in checks if not c] + ([ana.cut_note] if ana.cut_note else [])
    print(f'RESULT: {"CONFIRMED" if ok else "NOT CONFIRMED"}: {res.verdict}'
          + (f' ({"; ".join(why)})' if why else ''))
    return ok


def run(args: argparse.Namespace) -> int:
    """Run the demo; 0 if confirmed, 1 if not, 130 if interrupted (module doc)."""
    # imported here, not at the top: ``gyro-rotor --help`` loads every command's module
    from gyro_rotor.core.scene import load_scene
    _check(args)
    scene = load_scene(args.scene)
    kick_at = args.kick_at
    if kick_at is None:
        kick_at = default_kick_at(scene, args.duration)
    if kick_at >= 0:
        kick_at = _on_grid(kick_at, args.rate)
    out = _out_dir(args, scene)
    print(f'gyro_rotor demo: scene {scene.name} ({scene.description})')
    exp = expected_outcome(scene, args.duration)
    print(f'expected (linear stability): {exp["verdict"]}'
          + (f'; pole slips {exp["pole_slips"]} (reference simulation)'
             if exp['pole_slips'] is not None else ''))
    codes, stopped_by, diverged = _run_live(args, scene, out, kick_at)
    if stopped_by and stopped_by != signal.SIGINT:
        print(f'stopped by {signal.Signals(stopped_by).name}: nodes ended {codes}; bag '
              f'{out / "bag"}', file=sys.stderr)
        return 128 + stopped_by
    ok = _conclude(out, exp, codes, bool(stopped_by), diverged)
    if stopped_by:
        return 130
    return 0 if ok else 1
