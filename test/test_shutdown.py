"""Clean shutdown however the signals arrive (issue 27): exit status 0, no traceback, bag whole.

A terminal's Ctrl-C on ``ros2 launch`` sends SIGINT to every process of the group, and
launch forwards one more SIGINT to each node: every node gets two, the second while it
tears down. On SIGTERM to the group, launch sends each node a SIGINT after the SIGTERM.
Tested three ways: in-process (``run_node`` in this test's main thread, the signals sent
to this process), with the two nodes as processes (no launch needed), and under the
upstream ``ros2 launch`` when a rostools build is at hand (``../shared/rostools``).
"""

from __future__ import annotations

import os
from pathlib import Path
import signal
import subprocess
import threading
import time

from gyro_rotor.tools.launch import check_bag, LaunchRun, NodeProcess
import node_helpers
import pytest

REPO = Path(__file__).resolve().parents[1]


# -- the handler ------------------------------------------------------------------------------
def test_stop_signals_remember_the_first_count_the_rest_and_restore():
    from gyro_rotor.signals import StopSignals
    before = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    woken = []
    stop = StopSignals().install(wake=lambda: woken.append(1))
    try:
        assert not stop.requested
        os.kill(os.getpid(), signal.SIGINT)
        os.kill(os.getpid(), signal.SIGINT)
        os.kill(os.getpid(), signal.SIGTERM)
        node_helpers.wait_until(lambda: len(woken) >= 1 and stop.repeats == 2,
                                'the handler and the wake-up thread', timeout=5)
        assert stop.signum == signal.SIGINT and stop.requested
    finally:
        stop.restore()
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == before
    assert signal.set_wakeup_fd(-1) == -1          # the wake-up fd is released too


# -- in-process: run_node as a node's main() runs it ------------------------------------------
@pytest.mark.ros
def test_double_sigint_in_process_tears_down_fully_with_status_0():
    """The second SIGINT (launch's) arrives during the teardown: it must not cut it short."""
    from gyro_rotor.ros.runner import run_node
    from gyro_rotor.ros.sim_node import RotorSimNode

    seen = {}

    class Node(RotorSimNode):
        def on_shutdown(self):
            seen['published'] = dict(self.published)
            os.kill(os.getpid(), signal.SIGINT)          # launch's forwarded SIGINT
            os.kill(os.getpid(), signal.SIGTERM)         # and a SIGTERM on top
            time.sleep(0.05)                             # (the handlers run meanwhile)
            super().on_shutdown()
            seen['on_shutdown'] = True

        def destroy_node(self):
            seen['destroyed'] = super().destroy_node() or True

    def make():
        seen['node'] = Node()
        return seen['node']

    def interrupt():
        node_helpers.wait_until(lambda: 'node' in seen and
                                seen['node'].published['joint_states'] >= 50,
                                'rotor_sim publishing', timeout=60)
        os.kill(os.getpid(), signal.SIGINT)              # the terminal's Ctrl-C

    t = threading.Thread(target=interrupt, daemon=True)
    t.start()
    before = signal.getsignal(signal.SIGINT)
    status = run_node(make, ['--ros-args', '-p', 'scene:=precession',
                             '-p', 'publish_rate:=500.0'], restore_signals=True)
    t.join(5)
    assert status == 0
    assert seen.get('on_shutdown') and seen.get('destroyed')
    assert seen['published']['joint_states'] >= 50
    assert not seen['node']._thread                       # the loop thread was stopped
    assert signal.getsignal(signal.SIGINT) is before


@pytest.mark.ros
def test_a_node_runs_blas_on_one_thread_and_the_limit_is_put_back():
    """rotor_analysis's small products: one BLAS thread in a node (runner's module doc)."""
    from gyro_rotor.errors import ParameterError
    from gyro_rotor.ros.runner import run_node
    import numpy  # noqa: F401 (loads OpenBLAS, whatever the tests before this one imported)
    from threadpoolctl import threadpool_info, threadpool_limits

    def blas_threads():
        return {p['num_threads'] for p in threadpool_info() if p['user_api'] == 'blas'}

    seen = {}

    def make():
        seen['threads'] = blas_threads()
        raise ParameterError('the test stops here')

    with threadpool_limits(limits=2, user_api='blas'):     # the suite's runner sets 1
        outside = blas_threads()
        assert run_node(make, [], restore_signals=True) == 1
        assert seen['threads'] == {1}
        assert blas_threads() == outside
    assert outside == {2}


# -- the two nodes as processes, signalled as launch signals them ------------------------------
def _start_pair(tmp_path: Path, **sim_params):
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    an_log, sim_log = tmp_path / 'an.log', tmp_path / 'sim.log'
    an = NodeProcess('gyro_rotor.ros.analysis_node', {'output': str(tmp_path / 'bag')},
                     stdout=open(an_log, 'w'), stderr=subprocess.STDOUT, env=env)
    node_helpers.wait_for_log(an_log, 'recording to', an)
    sim = NodeProcess('gyro_rotor.ros.sim_node', {
        'scene': 'precession', 'publish_rate': 250.0, 'wait_for_subscribers': 1,
        'wait_for_node': 'rotor_analysis', **sim_params},
        stdout=open(sim_log, 'w'), stderr=subprocess.STDOUT, env=env)
    node_helpers.wait_for_log(sim_log, 'simulation time starts', sim)
    return an, sim, an_log, sim_log


@pytest.mark.ros
@pytest.mark.parametrize('first, second', [(signal.SIGINT, signal.SIGINT),
                                           (signal.SIGTERM, signal.SIGINT),
                                           (signal.SIGINT, None)],
                         ids=['ctrl-c', 'sigterm-then-launch-sigint', 'one-sigint'])
def test_nodes_signalled_as_under_launch_exit_0_and_the_bag_is_whole(tmp_path, first, second):
    an, sim, an_log, sim_log = _start_pair(tmp_path)
    node_helpers.wait_until(lambda: len(node_helpers.bag_on_disk(tmp_path / 'bag',
                                                                 '/energy')) > 100,
                            'samples in the bag', an)
    for sig in (first, second):
        if sig is None:
            continue
        for p in (sim, an):
            os.killpg(p.pid, sig)
        time.sleep(0.01)
    status = {n: p.proc.wait(30) for n, p in (('sim', sim), ('an', an))}
    texts = {'sim': sim_log.read_text(), 'an': an_log.read_text()}
    assert status == {'sim': 0, 'an': 0}, texts
    for text in texts.values():
        assert 'Traceback' not in text and 'KeyboardInterrupt' not in text, text
    assert check_bag(str(tmp_path / 'bag'), texts['sim']) == []


# -- under ros2 launch (upstream, built by ../shared/rostools) ---------------------------------
@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.parametrize('how', ['ctrl-c', 'sigterm-to-group', 'sigterm-to-launch'])
def test_ros2_launch_stopped_by_a_signal_is_clean(tmp_path, how, ros_domain_id):
    """``ros2 launch gyro_rotor gyro_rotor.launch.py``, stopped three ways.

    Ctrl-C (SIGINT to the process group): launch and both nodes exit 0, no "process has
    died", no traceback, the bag finalized with every message the simulator published.
    SIGTERM: the upstream launch of Jazzy dies at once (ros2/launch#666, exit status -15,
    the nodes' output lost with it); the nodes still stop cleanly, from the group's
    SIGTERM or, when only launch got it, from their parent's death, and the bag is
    finalized and whole.
    """
    env_sh = node_helpers.rostools_env()
    out = tmp_path / 'run'
    run = LaunchRun(env_sh, ['gyro_rotor', 'gyro_rotor.launch.py', 'robot_description:=false',
                             f'output:={out}'], str(tmp_path / 'launch.log'),
                    domain_id=ros_domain_id)
    try:
        # (a fresh overlay compiles the integrator kernels at the first start: generous)
        assert run.wait_for('simulation time starts', 120), run.text()
        node_helpers.wait_until(lambda: len(node_helpers.bag_on_disk(out, '/energy')) > 100,
                                'samples in the bag', run.proc)
    finally:
        if how == 'sigterm-to-launch':
            status = run.signal_launch(signal.SIGTERM)
        else:
            status = run.interrupt(signal.SIGINT if how == 'ctrl-c' else signal.SIGTERM)
    assert run.nodes_gone() == [], run.text()
    if how == 'ctrl-c':
        assert status == 0, run.text()
        assert run.problems() == [], run.text()
        assert check_bag(str(out), run.text()) == []
    else:
        assert status in (0, -signal.SIGTERM), run.text()
        assert [p for p in run.problems() if 'finish cleanly' not in p and 'exit' not in p] \
            == [], run.text()
        assert check_bag(str(out)) == []
