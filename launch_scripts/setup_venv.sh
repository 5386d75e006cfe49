#!/usr/bin/env bash
# Create (or update) the project's virtual environment at .venv from pip only:
# the pinned requirements.txt (ROS 2 kilted wheels, numpy, scipy, control, rosbags, ...), the
# five ament_python packages of src/ in editable mode, so their console scripts are on .venv/bin,
# and the message package src/mr_damper_interfaces (ament_cmake + rosidl), built with cmake and
# a C/C++ compiler (installed with apt-get if missing) and installed into the venv prefix itself:
# the wheels' start-up hook (ros_wheels_bootstrapper.pth) puts <venv>/lib on LD_LIBRARY_PATH and
# the generated Python package lands in the venv's site-packages, so every node, test and script
# run with .venv/bin/python sees the typed messages without any environment variable.
# Idempotent: a second run with unchanged inputs (requirements, setup.py files, interface
# sources, this script) returns at once; any change redoes the pip step and the interface build.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$root/.venv"
stamp="$venv/.requirements.sha"
ifaces="$root/src/mr_damper_interfaces"
want="$(cat "$root/requirements.txt" "$root"/src/*/setup.py "${BASH_SOURCE[0]}" \
          "$ifaces/package.xml" "$ifaces/CMakeLists.txt" "$ifaces"/msg/*.msg \
        | sha256sum | cut -d' ' -f1)"

if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] && [ -x "$venv/bin/python" ]; then
  exit 0
fi
rm -f "$stamp"   # written again only at the end: a failed run is redone next time
build="$venv/build/mr_damper_interfaces"
# uninstall the interfaces built last time (files, then the folders they leave empty), so a
# removed .msg leaves nothing behind and pip never sees a half-removed egg-info
if [ -f "$build/install_manifest.txt" ]; then
  while IFS= read -r file; do
    rm -f -- "$file"
    rmdir -p --ignore-fail-on-non-empty -- "$(dirname -- "$file")" 2>/dev/null || true
  done < "$build/install_manifest.txt"
  rm -f -- "$build/install_manifest.txt"
fi
if ! command -v python3 >/dev/null; then
  echo "setup_venv: python3 (3.11) is required" >&2; exit 1
fi
apt_updated=0
apt_install() {
  echo "setup_venv: installing $* with apt-get" >&2
  if [ "$apt_updated" = 0 ]; then apt-get update -qq; apt_updated=1; fi
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$@" >/dev/null
}
if [ ! -x "$venv/bin/python" ]; then
  if ! python3 -m venv "$venv" 2>/dev/null; then
    # Debian's python3 ships venv/ensurepip separately
    apt_install python3-venv
    rm -rf "$venv"; python3 -m venv "$venv"
  fi
fi
echo "setup_venv: installing pinned dependencies into $venv (about a minute on a fresh machine)" >&2
"$venv/bin/python" -m pip install -q --disable-pip-version-check --upgrade pip >/dev/null
"$venv/bin/python" -m pip install -q --disable-pip-version-check -r "$root/requirements.txt" 2> >(grep -v "^WARNING: Location" >&2)
"$venv/bin/python" -m pip install -q --disable-pip-version-check --no-deps --no-build-isolation \
  -e "$root/src/mr_damper_model" -e "$root/src/mr_damper_rig" -e "$root/src/quarter_car_sim" \
  -e "$root/src/mr_damper_bringup" -e "$root/src/mr_damper_can"

# --- mr_damper_interfaces: C/C++ toolchain, mended CMake exports, build, install into the venv
missing=()
for tool in cmake make gcc g++; do
  command -v "$tool" >/dev/null || missing+=("$tool")
done
if [ "${#missing[@]}" -gt 0 ]; then
  apt_install cmake make gcc g++
fi
if ! "$venv/bin/python" -c 'import os, sys, sysconfig
sys.exit(not os.path.isfile(os.path.join(sysconfig.get_paths()["include"], "Python.h")))'; then
  apt_install python3-dev    # Python.h for the generated C extension modules
fi
# The *_msgs wheels' exported CMake files name the wheel builder's Python and numpy include
# folders (/opt/python/cp311-cp311/...); point them at this venv's (idempotent: a mended file no
# longer matches).
"$venv/bin/python" - <<'EOF'
import pathlib, re, sys, sysconfig
import numpy
py_inc, np_inc = sysconfig.get_paths()['include'], numpy.get_include()
for path in sorted(pathlib.Path(sys.prefix, 'share').glob('*/cmake/*Export.cmake')):
    text = path.read_text()
    new = re.sub(r'/opt/python/[^/;"]+/include/python[0-9.]+', py_inc, text)
    new = re.sub(r'/opt/python/[^;"]+/numpy/_core/include', np_inc, new)
    if new != text:
        path.write_text(new)
EOF
echo "setup_venv: building $ifaces into $venv (about 20 s)" >&2
rm -rf "$build"; mkdir -p "$build"
# (&& chains: `set -e` does not apply inside an `if` condition)
if ! ( export PATH="$venv/bin:$PATH" AMENT_PREFIX_PATH="$venv" CMAKE_PREFIX_PATH="$venv" &&
       cmake -S "$ifaces" -B "$build" -DCMAKE_INSTALL_PREFIX="$venv" \
         -DPython3_EXECUTABLE="$venv/bin/python" -DBUILD_TESTING=OFF \
         -DCMAKE_BUILD_TYPE=Release &&
       cmake --build "$build" -j "$(nproc 2>/dev/null || echo 2)" &&
       cmake --install "$build" ) >"$build.log" 2>&1; then
  tail -n 40 "$build.log" >&2
  echo "setup_venv: building mr_damper_interfaces failed (full log: $build.log)" >&2
  exit 1
fi
echo "$want" > "$stamp"
