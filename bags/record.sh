#!/bin/bash
# Regenerate the sample bags: bags/record.sh [SCENE ...]
#   (default: precession upright pole_slip twin_gimbal)
# Both nodes run as separate processes on a private ROS domain, at real time (250 Hz); the
# simulator publishes /clock (publish_clock, its default) and stops at t_end = 12 s
# (stop_at_t_end), then both get SIGINT and the recorder finalizes the bag. Chunks are
# zstd-compressed to keep the repository small. Each bag is checked afterwards: finalized,
# every sample from t = 0 to t_end, and /clock up to t_end (`ros2 bag play` republishes it).
set -euo pipefail
cd "$(dirname "$0")"
PY=${PY:-../.venv/bin/python}
export PYTHONPATH="$(cd .. && pwd)${PYTHONPATH:+:$PYTHONPATH}"
export ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-$((100 + RANDOM % 100))}
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
T_END=${T_END:-12.0}
for scene in "${@:-precession upright pole_slip twin_gimbal}"; do
  for s in $scene; do
    rm -rf "$s"
    "$PY" -m gyro_rotor.ros.analysis_node --ros-args -p output:="$s" -p compression:=zstd \
        -p window_s:=8.0 > "/tmp/record_$s.analysis.log" 2>&1 &
    an=$!
    # the simulator holds t = 0 until the recorder subscribes (seq 0 is recorded)
    "$PY" -m gyro_rotor.ros.sim_node --ros-args -p scene:="$s" -p real_time_factor:=1.0 \
        -p t_end:="$T_END" -p stop_at_t_end:=true -p publish_clock:=true \
        -p wait_for_subscribers:=1 -p wait_for_node:=rotor_analysis \
        > "/tmp/record_$s.sim.log" 2>&1 &
    sim=$!
    sleep "$(python3 -c "print(float('$T_END') + 5.0)")"
    kill -INT "$sim"; wait "$sim" || true
    sleep 1.5          # the last results are published and recorded
    kill -INT "$an"; wait "$an"
    "$PY" - "$s" "$T_END" <<'PY'
import sys
import warnings

from gyro_rotor.bag.bagio import open_bag

path, t_end = sys.argv[1], float(sys.argv[2])
with warnings.catch_warnings():
    warnings.simplefilter('error')
    reader = open_bag(path)
n = int(round(t_end * 250)) + 1
clock = [m.clock.sec + 1e-9 * m.clock.nanosec for _, _, m in reader.decoded('/clock')]
counts = {t: i.count for t, i in reader.topics.items()}
assert counts.get('/joint_states') == n, (path, counts)
assert clock and abs(clock[-1] - t_end) < 1e-9, (path, clock[-1:] if clock else 'no /clock')
print(f'{path}: {counts["/joint_states"]} samples, {len(clock)} /clock up to {clock[-1]:g} s')
PY
    echo "$s: $(du -sh "$s" | cut -f1)"
  done
done
