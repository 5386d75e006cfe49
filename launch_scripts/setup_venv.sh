#!/usr/bin/env bash
# Create (or update) the project's virtual environment at .venv from pip only:
# the pinned requirements.txt (ROS 2 kilted wheels, numpy, scipy, control, rosbags, ...) and the
# three ament_python packages of src/ in editable mode, so their console scripts are on .venv/bin.
# Idempotent: a second run only checks that everything is installed.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$root/.venv"
stamp="$venv/.requirements.sha"
want="$(cat "$root/requirements.txt" "$root"/src/*/setup.py | sha256sum | cut -d' ' -f1)"

if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] && [ -x "$venv/bin/python" ]; then
  exit 0
fi
if ! command -v python3 >/dev/null; then
  echo "setup_venv: python3 (3.11) is required" >&2; exit 1
fi
if [ ! -x "$venv/bin/python" ]; then
  if ! python3 -m venv "$venv" 2>/dev/null; then
    # Debian's python3 ships venv/ensurepip separately
    echo "setup_venv: installing python3-venv with apt-get" >&2
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv >/dev/null
    rm -rf "$venv"; python3 -m venv "$venv"
  fi
fi
echo "setup_venv: installing pinned dependencies into $venv (about a minute on a fresh machine)" >&2
"$venv/bin/python" -m pip install -q --disable-pip-version-check --upgrade pip >/dev/null
"$venv/bin/python" -m pip install -q --disable-pip-version-check -r "$root/requirements.txt" 2> >(grep -v "^WARNING: Location" >&2)
"$venv/bin/python" -m pip install -q --disable-pip-version-check --no-deps --no-build-isolation \
  -e "$root/src/mr_damper_model" -e "$root/src/mr_damper_rig" -e "$root/src/quarter_car_sim"
echo "$want" > "$stamp"
