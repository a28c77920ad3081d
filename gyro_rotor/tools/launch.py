"""Starting the nodes as processes, without ROS 2 launch (not installable from PyPI).

:func:`claim_domain_id` takes a free ROS_DOMAIN_ID (a lock file per id, held while the
claim lives), so that a demo, a soak run or a test cannot hear another one;
:class:`NodeProcess` starts ``python -m gyro_rotor.<node> --ros-args -p name:=value ...``
with that domain and localhost-only discovery, and stops it with SIGINT (then SIGTERM,
then SIGKILL) so that the nodes finish cleanly: the recorder finalizes its bag.

Where the upstream ``ros2 launch`` is at hand (``../shared/rostools`` builds it for the
venv; ``GYRO_ROTOR_ROSTOOLS`` names the build), :class:`LaunchRun` runs a launch file in a
process group of its own and stops it as a terminal's Ctrl-C does, and
:func:`check_bag` says whether the recording survived whole. ``python -m
gyro_rotor.tools.launch --runs 20`` does that 20 times and counts the clean stops.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
from pathlib import Path
import signal
import struct
import subprocess
import sys
import tempfile
import time
from typing import Any, IO, Mapping

from gyro_rotor.errors import GyroRotorError, ParameterError
from gyro_rotor.signals import StopSignals

__all__ = ['claim_domain_id', 'DomainClaim', 'NodeProcess', 'SideNode', 'tear_down',
           'ros_param', 'energy_seq_from_cdr', 'make_output_dir']


class DomainClaim:
    """A claimed ROS_DOMAIN_ID; ``release()`` (or the context exit) frees it."""

    def __init__(self, domain_id: int, lock: IO):
        self.domain_id = domain_id
        self._lock = lock

    def release(self) -> None:
        """Free the domain id."""
        if self._lock is not None:
            self._lock.close()
            self._lock = None

    def __enter__(self) -> 'DomainClaim':
        return self

    def __exit__(self, *exc: Any) -> None:
        self.release()


def claim_domain_id(first: int = 101, last: int = 232) -> DomainClaim:
    """Claim a ROS_DOMAIN_ID in [first, last] that no other gyro_rotor process holds."""
    start = first + os.getpid() % (last - first + 1)
    for i in range(last - first + 1):
        domain = first + (start - first + i) % (last - first + 1)
        path = os.path.join(tempfile.gettempdir(), f'gyro_rotor_domain_{domain}.lock')
        f = open(path, 'w')
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.close()
            continue
        return DomainClaim(domain, f)
    raise RuntimeError(f'no free ROS_DOMAIN_ID in {first}..{last}')


def make_output_dir(out: Path) -> Path:
    """Create the output directory ``out`` of a node run (its parents too) and return it.

    Raises ParameterError if it cannot be created (the demo and the soak run's bad --out).
    """
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ParameterError(f'cannot create output directory {out}: {err}') from err
    return out


def ros_param(name: str, value: Any) -> str:
    """``name:=value`` for ``--ros-args -p`` (floats keep their point, bools lower case)."""
    if isinstance(value, bool):
        text = 'true' if value else 'false'
    elif isinstance(value, float):
        text = repr(value)
    else:
        text = str(value)
    return f'{name}:={text}'


class NodeProcess:
    """One node as a child process (stdout/stderr to files or pipes)."""

    def __init__(self, module: str, params: Mapping[str, Any] | None = None, *,
                 domain_id: int | None = None, stdout=None, stderr=None,
                 extra_args: list[str] | None = None, env: Mapping[str, str] | None = None,
                 die_with_parent: bool = False):
        self.module = module
        cmd = [sys.executable, '-m', module, '--ros-args']
        for k, v in (params or {}).items():
            cmd += ['-p', ros_param(k, v)]
        cmd += list(extra_args or [])
        e = dict(os.environ if env is None else env)
        e['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
        if domain_id is not None:
            e['ROS_DOMAIN_ID'] = str(domain_id)
        self.cmd = cmd
        preexec = None
        if die_with_parent:     # in the child: SIGTERM from Linux when this process dies
            from gyro_rotor.ros.runner import exit_with_parent as preexec
        self.proc = subprocess.Popen(cmd, env=e, stdout=stdout, stderr=stderr,
                                     stdin=subprocess.DEVNULL, start_new_session=True,
                                     preexec_fn=preexec)

    @property
    def pid(self) -> int:
        """Process id."""
        return self.proc.pid

    def poll(self) -> int | None:
        """Exit code, or None while it runs."""
        return self.proc.poll()

    def stop(self, timeout: float = 20.0) -> int:
        """SIGINT, then SIGTERM, then SIGKILL, each after ``timeout``/2 s; the exit code."""
        for sig, wait in ((signal.SIGINT, timeout), (signal.SIGTERM, timeout / 2),
                          (signal.SIGKILL, timeout / 2)):
            if self.proc.poll() is not None:
                break
            try:
                self.proc.send_signal(sig)
            except ProcessLookupError:
                break
            try:
                self.proc.wait(wait)
            except subprocess.TimeoutExpired:
                continue
        return self.proc.wait()

    def kill(self) -> int:
        """SIGKILL (for fault tests)."""
        if self.proc.poll() is None:
            self.proc.kill()
        return self.proc.wait()


# -- the launch files' helpers ---------------------------------------------------------------
_TRUE = ('true', '1', 'yes', 'on')


#: the arguments of the launch files: name -> (default, description), each written once
LAUNCH_ARGUMENTS = {
    'scene': ('precession', 'scene of rotor_sim: a name (config/<scene>.yaml, '
                            'config/systems/scenes/<scene>.yaml) or a path'),
    'output': ('', "rosbag2 (MCAP) directory to record to, which must not exist yet ('': a "
                   'fresh bags_out/rotor_<time>)'),
    'rviz': ('false', 'start RViz2'),
    'robot_description': ('true', "start robot_state_publisher with the URDF of the scene's "
                                  'system (urdf/NAME.urdf, or NAME.urdf beside its system '
                                  'file)'),
    'use_sim_time': ('true', "the nodes but rotor_sim follow rotor_sim's /clock (simulation "
                             'time; rotor_sim is the clock source); false: the system clock'),
    'namespace': ('', 'ROS namespace of every node and of their topics'),
    'window_s': ('8.0', 'analysis window [s]'),
    'wait_for_subscribers': ('0', 'hold t = 0 until joint_states and energy have this many '
                                  'subscribers (0: start at once)'),
    'wait_for_node': ('', '... and until this node subscribes to both'),
}


class SideNode:
    """A node of this process in a context of its own on ``domain_id`` (demo, soak)."""

    #: longest wait of one spin in :meth:`spin` [s]
    SPIN_STEP = 0.05

    def __init__(self, name: str, domain_id: int, signals: StopSignals | None = None,
                 **options: Any):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        self.ctx = rclpy.context.Context()
        rclpy.init(context=self.ctx, domain_id=domain_id)
        self.node = rclpy.create_node(name, context=self.ctx, **options)
        self.ex = SingleThreadedExecutor(context=self.ctx)
        self.ex.add_node(self.node)
        #: the process's stop request, checked between two spins (None: not checked)
        self.signals = signals

    def spin(self, seconds: float) -> None:
        """Process callbacks for about ``seconds``; raise ``Stopped`` once a signal came.

        The stop request (:attr:`signals`) is checked between two spins of the executor
        (:func:`gyro_rotor.ros.runner.spin_for`), within :attr:`SPIN_STEP`.
        """
        from gyro_rotor.ros.runner import spin_for
        spin_for(self.ex, seconds, self.signals, self.SPIN_STEP)

    def close(self) -> None:
        """Shut the node down."""
        import rclpy
        self.ex.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.ctx)


def tear_down(procs: list, side: SideNode | None, claim: DomainClaim, logs: dict,
              signals: StopSignals) -> dict:
    """Stop ``procs`` (the last started first), close ``side``, release ``claim`` and ``logs``.

    The end of a run of the nodes from this process (demo, soak), however it ends: until
    it is done a signal is counted by ``signals``, not acted on, so the stopping (SIGINT,
    then SIGTERM, then SIGKILL; the bag finalized) is not cut short; then ``signals`` are
    restored. Return each process's exit code by module.
    """
    try:
        codes = {p.module: p.stop() for p in reversed(procs)}
        if side is not None:
            side.close()
        claim.release()
        for f in logs.values():
            f.close()
        return codes
    finally:
        signals.restore()


def launch_arguments(*names: str, **own: tuple[str, str]) -> list:
    """Return a DeclareLaunchArgument for each of ``names`` (:data:`LAUNCH_ARGUMENTS`).

    ``own``: name -> (default, description) of an argument that a launch file declares its
    own way.
    """
    from launch.actions import DeclareLaunchArgument
    return [DeclareLaunchArgument(name, default_value=default, description=description)
            for name in names
            for default, description in [own.get(name, LAUNCH_ARGUMENTS[name])]]


def scene_urdf(scene: str, share: str) -> str | None:
    """Return the URDF of a scene's system, or None if it has none (or is not found).

    A system's URDF sits beside its system file, with the same name: a shipped system
    ``NAME`` (the built-in ``centrifuge`` included; no ``system`` key reads as it) has
    ``share/urdf/NAME.urdf``, a system file given by path ``dir/mine.yaml`` has
    ``dir/mine.urdf`` (a path relative to the scene file's folder, as rotor_sim resolves
    it). Light: reads the YAML file only, for launch files.
    """
    import yaml
    if scene.endswith(('.yaml', '.yml')) or os.sep in scene or os.path.isfile(scene):
        candidates = [scene]
    else:
        candidates = [os.path.join(share, 'config', f'{scene}.yaml'),     # as scene_path
                      os.path.join(share, 'config', 'systems', 'scenes', f'{scene}.yaml')]
    for path in candidates:
        if not os.path.isfile(path):
            continue
        try:
            with open(path, encoding='utf-8') as f:
                doc = yaml.safe_load(f)
        except (OSError, yaml.YAMLError):
            return None
        params = next((v['ros__parameters'] for v in (doc or {}).values()
                       if isinstance(v, dict) and isinstance(v.get('ros__parameters'), dict)),
                      {})
        system = str(params.get('system', 'centrifuge'))
        if system.endswith(('.yaml', '.yml')) or os.sep in system:     # as system_path
            if not os.path.isabs(system) and not os.path.isfile(system):
                system = os.path.join(os.path.dirname(path), system)
            urdf = os.path.splitext(system)[0] + '.urdf'
        else:
            urdf = os.path.join(share, 'urdf', f'{system}.urdf')
        return urdf if os.path.isfile(urdf) else None
    return None


def robot_description(cfg, share: str) -> tuple[str | None, str | None]:
    """Return the URDF for robot_state_publisher, or None and the log line that says why.

    ``cfg``: the launch configurations (``scene``, ``robot_description``). Off: (None,
    None); on, but the scene's system has no URDF (:func:`scene_urdf`): (None, the reason).
    """
    if str(cfg.get('robot_description', 'true')).lower() not in _TRUE:
        return None, None
    scene = str(cfg.get('scene', 'precession'))
    path = scene_urdf(scene, share)
    if path is None:
        return None, (f'scene {scene}: its system has no URDF (NAME.urdf beside its system '
                      'file NAME.yaml): robot_state_publisher is not started')
    with open(path, encoding='utf-8') as f:
        return f.read(), None


# -- ros2 launch, stopped as a terminal's Ctrl-C stops it ---------------------------------------
#: the problems that make a stopped launch unclean, found in its output
UNCLEAN_MARKS = ('process has died', 'Traceback', 'KeyboardInterrupt', '[ERROR]')


def find_rostools() -> str | None:
    """Return the env.sh of a rostools build (``$GYRO_ROTOR_ROSTOOLS/env.sh``), if any.

    rostools (``../shared/rostools/build.sh VENV DEST --package .``) builds the upstream
    ``ros2`` CLI and ``ros2 launch`` for the venv; ``GYRO_ROTOR_ROSTOOLS`` names its DEST.
    """
    dest = os.environ.get('GYRO_ROTOR_ROSTOOLS')
    if dest and os.path.isfile(os.path.join(dest, 'env.sh')):
        return os.path.join(dest, 'env.sh')
    return None


class LaunchRun:
    """One ``ros2 launch`` in a process group of its own, stopped by a signal to the group.

    As a terminal's Ctrl-C: the signal reaches ``ros2 launch`` and every node it started,
    and launch forwards one more SIGINT to each node (or, on SIGTERM, a SIGINT). ``log``
    gets the whole output; :meth:`problems` lists what made the stop unclean.
    """

    def __init__(self, env_sh: str, launch_args: list[str], log: str, *,
                 domain_id: int | None = None):
        import shlex
        self.log_path = log
        cmd = f'source {shlex.quote(env_sh)} && exec ros2 launch ' + ' '.join(
            shlex.quote(a) for a in launch_args)
        e = dict(os.environ, PYTHONUNBUFFERED='1', ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
        if domain_id is not None:
            e['ROS_DOMAIN_ID'] = str(domain_id)
        self._log = open(log, 'w')
        # a session (and process group) of its own, SIGINT not ignored: a terminal's job
        self.proc = subprocess.Popen(['bash', '-c', cmd], env=e, stdout=self._log,
                                     stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                     start_new_session=True)
        self.status: int | None = None

    def text(self) -> str:
        """Return the output so far."""
        with open(self.log_path, errors='replace') as f:
            return f.read()

    def wait_for(self, text: str, timeout: float) -> bool:
        """Wait until ``text`` is in the output (False: timeout or launch ended)."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if text in self.text():
                return True
            if self.proc.poll() is not None:
                return False
            time.sleep(0.2)
        return False

    def interrupt(self, sig: int = signal.SIGINT, timeout: float = 40.0) -> int:
        """Send ``sig`` to the process group; return the exit status of ``ros2 launch``.

        SIGKILL to the group after ``timeout`` seconds (then the status is negative).
        """
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self.proc.pid, sig)
        return self._wait(timeout)

    def signal_launch(self, sig: int = signal.SIGTERM, timeout: float = 40.0) -> int:
        """Send ``sig`` to ``ros2 launch`` alone; return its exit status (see interrupt)."""
        with contextlib.suppress(ProcessLookupError):
            self.proc.send_signal(sig)
        return self._wait(timeout)

    def _wait(self, timeout: float) -> int:
        """Wait for launch to exit (SIGKILL to the group after ``timeout`` s); its status."""
        try:
            self.status = self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.kill()
        self._log.close()
        return self.status

    def node_pids(self) -> list[int]:
        """Return the process ids of the nodes launch started (from its output)."""
        import re
        return [int(p) for p in re.findall(r'process started with pid \[(\d+)\]', self.text())]

    def nodes_gone(self, timeout: float = 20.0) -> list[int]:
        """Wait until the nodes' processes are gone; return those still there."""
        end = time.monotonic() + timeout
        alive = self.node_pids()
        while alive and time.monotonic() < end:
            time.sleep(0.1)
            alive = [p for p in alive if _running(p)]
        return alive

    def kill(self) -> None:
        """SIGKILL to the whole group (a launch that does not stop)."""
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self.proc.pid, signal.SIGKILL)
        self.status = self.proc.wait()

    def problems(self, nodes: tuple = ('rotor_analysis', 'rotor_sim')) -> list[str]:
        """Return what made the stop unclean (empty: clean): exit status, output, exits."""
        text = self.text()
        found = [] if self.status == 0 else [f'ros2 launch exit status {self.status}']
        for mark in UNCLEAN_MARKS:
            lines = [ln for ln in text.splitlines() if mark in ln]
            if lines:
                found.append(f'{len(lines)} line(s) with {mark!r}, first: {lines[0][:200]}')
        for n in nodes:
            if f'[{n}-' in text and not any('process has finished cleanly' in ln and
                                            f'[{n}-' in ln for ln in text.splitlines()):
                found.append(f'{n} did not finish cleanly')
        return found


def _running(pid: int) -> bool:
    """Return whether process ``pid`` exists and is not a zombie."""
    try:
        with open(f'/proc/{pid}/stat') as f:
            return f.read().rsplit(')', 1)[1].split()[0] != 'Z'
    except OSError:
        return False


def energy_seq_from_cdr(data: bytes) -> int:
    """Return the ``seq`` of a serialized ``energy`` message (its data array ends the CDR)."""
    from gyro_rotor.bag.wire import ENERGY_FIELDS
    n = len(ENERGY_FIELDS)
    off = len(data) - 8 * n + 8 * ENERGY_FIELDS.index('seq')
    if off < 4:
        raise GyroRotorError(f'energy message of {len(data)} bytes is too short')
    return int(struct.unpack_from('<d', data, off)[0])


def check_bag(path: str, sim_log_text: str = '') -> list[str]:
    """Return what is wrong with a bag recorded under launch (empty: finalized, whole).

    Finalized: a footer and summary (not truncated), metadata.yaml; complete: the energy
    sequence numbers run from 0 without a gap, and every joint_states and energy message
    that rotor_sim says it published (``published counts`` in ``sim_log_text``) is in it.
    """
    import re
    import warnings
    from gyro_rotor.bag.bagio import open_bag
    found = []
    if not os.path.isfile(os.path.join(path, 'metadata.yaml')):
        found.append(f'{path}: no metadata.yaml')
    try:
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')
            reader = open_bag(path)
            seq = [energy_seq_from_cdr(d) for _, _, d in reader.messages('/energy')]
            counts = {t: reader.topics[t].count for t in reader.topics}
    except GyroRotorError as err:
        return found + [f'{path}: {err}']
    if reader.truncated:
        found.append(f'{path}: not finalized (no summary: truncated)')
    if not seq:
        found.append(f'{path}: no /energy messages')
    elif seq != list(range(len(seq))):
        gaps = sum(1 for a, b in zip(seq, seq[1:]) if b != a + 1)
        found.append(f'{path}: energy sequence numbers have {gaps} gap(s) (first {seq[0]})')
    published = re.findall(r'published counts: (\{.*\})', sim_log_text)
    if published:
        import json
        pub = json.loads(published[-1])
        for topic in ('joint_states', 'energy'):
            got = counts.get(f'/{topic}', 0)
            if got != pub[topic]:
                found.append(f'{path}: {got} {topic} recorded, {pub[topic]} published')
    return found


def _main(argv: list[str] | None = None) -> int:
    """Ctrl-C ``ros2 launch gyro_rotor gyro_rotor.launch.py`` N times; count the clean stops."""
    import argparse
    p = argparse.ArgumentParser(prog='python -m gyro_rotor.tools.launch',
                                description=_main.__doc__)
    p.add_argument('--env', default=find_rostools(), help='env.sh of a rostools build '
                   '(default: $GYRO_ROTOR_ROSTOOLS/env.sh)')
    p.add_argument('--runs', type=int, default=20)
    p.add_argument('--out', default='ctrl_c_runs', help='folder for the logs and bags')
    p.add_argument('--run-s', type=float, default=5.0,
                   help='seconds of simulation time running before the signal')
    p.add_argument('--signal', default='INT', choices=('INT', 'TERM'))
    p.add_argument('launch_args', nargs='*', default=['robot_description:=false'],
                   help='arguments of gyro_rotor.launch.py (output:= is added)')
    a = p.parse_args(argv)
    if not a.env:
        p.error('no rostools build: give --env or set GYRO_ROTOR_ROSTOOLS')
    os.makedirs(a.out, exist_ok=True)
    sig = getattr(signal, f'SIG{a.signal}')
    clean = 0
    with claim_domain_id() as claim:
        for i in range(1, a.runs + 1):
            out = os.path.abspath(os.path.join(a.out, f'run{i:02d}'))
            log = f'{out}.log'
            run = LaunchRun(a.env, ['gyro_rotor', 'gyro_rotor.launch.py', *a.launch_args,
                                    f'output:={out}'], log, domain_id=claim.domain_id)
            started = run.wait_for('simulation time starts', 120.0)
            time.sleep(a.run_s if started else 0.0)
            run.interrupt(sig)
            problems = ([] if started else ['simulation time never started'])
            left = run.nodes_gone()
            problems += [f'node processes left: {left}'] if left else []
            if sig == signal.SIGINT:
                problems += run.problems() + check_bag(out, run.text())
            else:       # the Jazzy ros2 launch dies on SIGTERM (ros2/launch#666), exit -15,
                # and the nodes' output dies with it: the nodes and the bag are what is left
                problems += [p for p in run.problems() if f'status {-sig}' not in p
                             and 'finish cleanly' not in p] + check_bag(out)
            clean += not problems
            print(f'run {i:2d}: ' + ('clean' if not problems else '; '.join(problems)),
                  flush=True)
    print(f'{clean} of {a.runs} clean (SIG{a.signal} to the process group of ros2 launch'
          + (': launch itself exits -15, ros2/launch#666' if sig == signal.SIGTERM else '')
          + ')')
    return 0 if clean == a.runs else 1


if __name__ == '__main__':
    sys.exit(_main())
