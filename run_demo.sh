#!/usr/bin/env bash
# The main job: the live demo on the default scene (bootstraps .venv on first use).
# Usage: ./run_demo.sh [SCENE] [demo options]
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
"$here/bootstrap.sh"
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export MPLBACKEND=Agg
if "$here/.venv/bin/gyro-rotor" --help 2>/dev/null | grep -q ' demo '; then
  exec "$here/.venv/bin/gyro-rotor" demo "$@"
fi
exec "$here/.venv/bin/gyro-rotor" simulate "${@:-precession}"
