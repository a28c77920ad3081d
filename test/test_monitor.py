"""gyro-rotor monitor: topic statistics (pure) and a live run against rotor_sim."""

import math
import os
import signal
import subprocess
import sys
import threading

from gyro_rotor.tools.monitor import TopicStats
import pytest


def test_topic_stats_rate_jitter_and_gaps():
    s = TopicStats('/energy')
    for k in range(101):
        s.add(10.0 + k * 0.004, 100, seq=k)
    assert s.rate() == pytest.approx(250.0)
    assert s.jitter() == pytest.approx(0.0, abs=1e-9)
    s.add(11.0, 100, seq=105)          # 101..104 missing
    assert s.gaps == 4
    assert s.count == 102 and s.bytes == 10200
    assert math.isnan(TopicStats('/x').rate())


#: the bound on the wait for rotor_sim's topics to show in the monitor (a failure bound,
#: not a pace: the test stops at the first block that shows them)
SHOW_WITHIN_S = 120.0


def _sees(block: str, joints) -> bool:
    """Return whether one printed block shows both topics, their numbers and the joints."""
    lines = block.splitlines()
    stats = [ln for ln in lines if ln.startswith('/joint_states ')]
    values = [ln for ln in lines if ln.startswith('/joint_states: ')]
    return ('/energy' in block and 'E_star' in block and 'residual' in block
            and bool(stats) and float(stats[0].split()[3]) > 0
            and bool(values) and all(f' {j} ' in values[0] for j in joints))


@pytest.mark.ros
@pytest.mark.parametrize('scene, joints', [('precession', ('theta', 'phi_M')),
                                           ('twin_gimbal', ('alpha', 'z_R2'))])
def test_monitor_sees_the_simulation_topics(scene, joints):
    """The monitor, run until Ctrl-C, prints a block with the topics once rotor_sim is up.

    Synchronized on that block, not on a duration: a 6-s monitor started beside the node
    saw no topic under load (7.8 on 2 cores; twin_gimbal's node not yet publishing), once
    the monitor itself started fast (its imports made lazy).
    """
    env = dict(os.environ)
    sim = subprocess.Popen([sys.executable, '-m', 'gyro_rotor.ros.sim_node', '--ros-args',
                            '-p', f'scene:={scene}', '-p', 'real_time_factor:=1.0'],
                           env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                           text=True)
    mon = subprocess.Popen([sys.executable, '-m', 'gyro_rotor', 'monitor', '--period', '1'],
                           env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    watchdog = threading.Timer(SHOW_WITHIN_S, mon.kill)
    watchdog.start()
    seen, block = None, []
    try:
        for line in mon.stdout:         # blocks end with an empty line
            if line.strip():
                block.append(line)
                continue
            if _sees(''.join(block), joints):
                seen = ''.join(block)
                break
            block = []
    finally:
        watchdog.cancel()
        mon.send_signal(signal.SIGINT)
        _, err = mon.communicate(timeout=20)
        sim.send_signal(signal.SIGINT)
        sim.communicate(timeout=20)
    assert seen is not None, f'no block showed the topics within {SHOW_WITHIN_S:g} s: {err}'
    assert mon.returncode == 0, err


def test_array_values_names_numbers_by_the_messages_own_labels():
    from gyro_rotor.tools.monitor import array_values
    modes = array_values([['nutation', 'zero root'], ['pred_re', 'pred_im', 'status']],
                         [-0.5, 61.2, 1.0, 0.0, 0.0, 3.0])
    assert modes == {'nutation': {'pred_re': -0.5, 'pred_im': 61.2, 'status': 1.0},
                     'zero root': {'pred_re': 0.0, 'pred_im': 0.0, 'status': 3.0}}
    assert array_values([['a', 'b']], [1.0, 2.0]) == {'a': 1.0, 'b': 2.0}
    # labels that do not fit the data name nothing (never a shifted column)
    assert array_values([['a', 'b']], [1.0, 2.0, 3.0]) == {}
    assert array_values([['m1', 'm2'], ['x', 'y']], [1.0, 2.0, 3.0]) == {}


@pytest.mark.ros
def test_monitor_labels_analysis_modes_by_row_and_column():
    """The analysis node's 2-D analysis_modes: a line per mode, each number under its column."""
    from gyro_rotor.analysis.results import MODE_FIELDS, MODE_LABEL
    from gyro_rotor.cli.commands.monitor import Monitor
    from gyro_rotor.tools.monitor import TopicStats
    from rclpy.serialization import serialize_message
    from std_msgs.msg import Float64MultiArray, MultiArrayDimension
    names = ['nutation', 'housing twist', 'zero root (cyclic psi)']
    ncol = len(MODE_FIELDS)
    rows = [([-0.0018 - i, 61.19 + i, -0.002, 61.2, 3.0, 4.0, 0.5, float(i)]
             + [0.25 + i] * (ncol - 8)) for i in range(len(names))]
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label=','.join(names), size=len(rows),
                                          stride=len(rows) * ncol),
                      MultiArrayDimension(label=MODE_LABEL, size=ncol, stride=ncol)]
    msg.data = [v for row in rows for v in row]
    mon = Monitor(node=None)
    mon.stats['/analysis_modes'] = TopicStats('/analysis_modes')
    mon._callback('/analysis_modes', Float64MultiArray)(serialize_message(msg))
    lines = [ln for ln in mon.render().splitlines() if ln.startswith('/analysis_modes ')
             and ': ' in ln]
    assert len(lines) == len(names)
    for name, row, line in zip(names, rows, lines):
        assert line.startswith(f'/analysis_modes {name}: ')
        shown = dict(part.rsplit(' ', 1) for part in line.split(': ', 1)[1].split(', '))
        assert list(shown) == list(MODE_FIELDS)
        assert [float(v) for v in shown.values()] == pytest.approx(row, rel=1e-5)
