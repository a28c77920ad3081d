"""gyro-rotor monitor: topic statistics (pure) and a live run against rotor_sim."""

import math
import os
import signal
import subprocess
import sys

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


@pytest.mark.ros
def test_monitor_sees_the_simulation_topics():
    env = dict(os.environ)
    sim = subprocess.Popen([sys.executable, '-m', 'gyro_rotor.ros.sim_node', '--ros-args',
                            '-p', 'scene:=precession', '-p', 'real_time_factor:=1.0'],
                           env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                           text=True)
    try:
        r = subprocess.run([sys.executable, '-m', 'gyro_rotor', 'monitor', '--duration', '6',
                            '--period', '2'], env=env, capture_output=True, text=True,
                           timeout=60)
    finally:
        sim.send_signal(signal.SIGINT)
        sim.communicate(timeout=20)
    assert r.returncode == 0, r.stderr
    last = r.stdout.strip().split('\n\n')[-1]
    assert '/joint_states' in last and '/energy' in last
    assert 'E_star' in last and 'residual' in last
    line = next(ln for ln in last.splitlines() if ln.startswith('/joint_states '))
    assert float(line.split()[3]) > 0      # it counted messages
