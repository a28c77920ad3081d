#!/bin/bash
# Regenerate the sample bags: bags/record.sh [SCENE ...]
#   (default: precession upright pole_slip twin_gimbal)
# Both nodes run as separate processes on a private ROS domain, at real time (250 Hz); the
# simulation stops at t_end = 12 s (stop_at_t_end), then both get SIGINT and the recorder
# finalizes the bag. Chunks are zstd-compressed to keep the repository small.
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
        -p t_end:="$T_END" -p stop_at_t_end:=true -p wait_for_subscribers:=1 \
        -p wait_for_node:=rotor_analysis > "/tmp/record_$s.sim.log" 2>&1 &
    sim=$!
    sleep "$(python3 -c "print(float('$T_END') + 5.0)")"
    kill -INT "$sim"; wait "$sim" || true
    sleep 1.5          # the last results are published and recorded
    kill -INT "$an"; wait "$an"
    echo "$s: $(du -sh "$s" | cut -f1)"
  done
done
