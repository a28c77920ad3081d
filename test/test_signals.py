"""Signals as a stop request (gyro_rotor.signals) and the command line's exit on a signal.

A handler that raises KeyboardInterrupt wherever the main thread is came out of rclpy's C
calls as a ``TypeError``/``RuntimeError`` traceback (monitor ce52d5c, demo 2990b49). The
loops record the signal and leave at their boundaries; ``gyro-rotor``'s main() reports
the interrupt as one even where rclpy made another exception of it.
"""

import os
import signal
import threading

from gyro_rotor.cli import main as cli_main
from gyro_rotor.cli.commands import demo
from gyro_rotor.signals import exit_status, Stopped, StopSignals
import node_helpers
import pytest


def _handlers(signums):
    return {s: signal.getsignal(s) for s in signums}


def test_the_first_signal_is_recorded_not_raised_and_acted_on_at_check():
    before = _handlers(demo.SIGNALS)
    sig = StopSignals(demo.SIGNALS).install()
    try:
        sig.check()                                 # nothing yet
        assert not sig.requested
        os.kill(os.getpid(), signal.SIGHUP)         # no KeyboardInterrupt here
        os.kill(os.getpid(), signal.SIGINT)         # a second one: the first one counts
        os.kill(os.getpid(), signal.SIGTERM)
        assert sig.requested and sig.signum == signal.SIGHUP and sig.repeats == 2
        with pytest.raises(Stopped) as stop:
            sig.check()
        assert stop.value.signum == signal.SIGHUP
        assert isinstance(stop.value, KeyboardInterrupt)
    finally:
        sig.restore()
    assert _handlers(demo.SIGNALS) == before


def test_restore_with_ignore_leaves_the_signals_ignored():
    before = _handlers((signal.SIGINT, signal.SIGTERM))
    sig = StopSignals().install()
    try:
        sig.restore(ignore=True)
        assert _handlers((signal.SIGINT, signal.SIGTERM)) == {
            signal.SIGINT: signal.SIG_IGN, signal.SIGTERM: signal.SIG_IGN}
    finally:
        for s, h in before.items():
            signal.signal(s, h)


def test_at_once_raises_from_the_handler_after_recording():
    with StopSignals((signal.SIGINT,), at_once=True) as sig:
        with pytest.raises(Stopped) as stop:
            os.kill(os.getpid(), signal.SIGINT)
            signal.sigtimedwait([], 0)              # (the handler runs before this)
        assert stop.value.signum == signal.SIGINT and sig.requested


def test_outside_the_main_thread_nothing_is_installed():
    before = _handlers((signal.SIGINT, signal.SIGTERM))
    seen = []

    def run():
        sig = StopSignals().install()
        seen.append(sig.requested)
        sig.restore()

    t = threading.Thread(target=run)
    t.start()
    t.join()
    assert seen == [False]
    assert _handlers((signal.SIGINT, signal.SIGTERM)) == before


@pytest.mark.parametrize('signum, word', [(signal.SIGINT, 'interrupted'),
                                          (signal.SIGTERM, 'terminated')])
def test_main_reports_a_stop_at_a_loop_boundary_with_128_plus_its_number(
        monkeypatch, capsys, signum, word):
    def command(argv):
        raise Stopped(signum)
    monkeypatch.setattr(cli_main, '_main', command)
    assert cli_main.main([]) == exit_status(signum) == 128 + signum
    assert capsys.readouterr().err.strip() == word


def test_main_reports_an_interrupt_that_rclpy_turned_into_another_exception(
        monkeypatch, capsys):
    """A Ctrl-C inside pybind11's conversion of a message came out as a TypeError."""
    before = signal.getsignal(signal.SIGINT)

    def command(argv):
        try:
            os.kill(os.getpid(), signal.SIGINT)
            signal.sigtimedwait([], 0)
        except KeyboardInterrupt:
            raise TypeError('Unable to convert function return value to a Python type')
        raise AssertionError('main() installed no SIGINT handler')
    monkeypatch.setattr(cli_main, '_main', command)
    assert cli_main.main([]) == 130
    assert capsys.readouterr().err.strip() == 'interrupted'
    assert signal.getsignal(signal.SIGINT) == before


def test_main_lets_an_error_without_a_signal_through(monkeypatch):
    def command(argv):
        raise TypeError('a bug of ours')
    monkeypatch.setattr(cli_main, '_main', command)
    with pytest.raises(TypeError, match='a bug of ours'):
        cli_main.main([])


# -- an executor's wait, ended by the signal (rotor_sim's main(), rt-bench) -----------------
@pytest.mark.ros
def test_spin_for_acts_on_a_signal_at_once_where_the_waker_triggers_a_guard(ros_domain_id):
    """A signal during a 60 s wait of the executor ends it at once, not when the wait ends.

    The waker thread triggers a guard condition of the executor's node; a signal that comes
    before the wait starts leaves the guard triggered, so there is no race to lose.
    """
    import time
    from gyro_rotor.ros.runner import spin_for
    from gyro_rotor.tools.launch import SideNode
    side = SideNode('gyro_rotor_test_spin_for', ros_domain_id)
    guard = side.node.create_guard_condition(lambda: None)
    signals = StopSignals((signal.SIGINT,)).install(wake=guard.trigger)
    try:
        threading.Thread(target=os.kill, args=(os.getpid(), signal.SIGINT)).start()
        t0 = time.monotonic()
        with pytest.raises(Stopped):
            spin_for(side.ex, 60.0, signals, step=60.0)
        assert time.monotonic() - t0 < 30.0        # without the waker: 60 s
    finally:
        signals.restore()
        side.close()


# -- a command that spins rclpy, stopped by Ctrl-C: soak ------------------------------------
@pytest.mark.ros
@pytest.mark.slow
def test_soak_ctrl_c_stops_the_nodes_finalizes_the_bag_and_exits_130(tmp_path):
    """SIGINT once the soak runs its nodes: 130, 'interrupted', no traceback, no orphans.

    The soak's listener spins rclpy (its main thread mostly inside rclpy's C calls); it
    used Python's default handler, whose KeyboardInterrupt may come out of pybind11 as
    another exception with a traceback, past the stopping of the nodes.
    """
    import re
    import sys
    from gyro_rotor.tools.launch import check_bag
    out = tmp_path / 'soak'
    pids = []

    def on_line(line, p):
        if line.startswith('soak: ROS_DOMAIN_ID'):
            pids.extend(int(x) for x in re.findall(r'pid (\d+)', line))
            # the nodes run: the recorder has written energy samples to the disk
            node_helpers.wait_until(lambda: node_helpers.bag_on_disk(out / 'bag', '/energy'),
                                    'energy samples on disk', proc=p, timeout=120.0)
            p.send_signal(signal.SIGINT)
    status, stdout, stderr = node_helpers.run_reading(
        [sys.executable, '-m', 'gyro_rotor', 'soak', '--duration', '600', '--out', str(out)],
        on_line, 180.0, tmp_path)
    both = stdout[-3000:] + '\n--- stderr ---\n' + stderr[-3000:]
    assert len(pids) == 2, both
    assert 'Traceback' not in stderr + stdout, both
    assert status == 130 and stderr.strip().splitlines()[-1] == 'interrupted', both
    for pid in pids:                 # the nodes were stopped (and reaped), not orphaned
        assert not os.path.exists(f'/proc/{pid}'), (pid, both)
    sim_log = (out / 'rotor_sim.log').read_text()
    assert check_bag(str(out / 'bag'), sim_log) == [], sim_log[-2000:]
