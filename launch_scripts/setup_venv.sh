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
# Quiet: a few progress lines on stderr; pip's, setuptools' and the build's output goes to
# .venv/setup.log, whose path and last lines are printed when a step fails.
# Needs: python3 (3.11) with venv and pip; cmake, make, gcc, g++ and the Python headers, which
# are installed with apt-get when missing (as root, or through sudo).
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
t_start=$SECONDS
say() { echo "setup_venv: $*" >&2; }
if ! command -v python3 >/dev/null; then
  say "python3 (3.11) is required"; exit 1
fi
mkdir -p "$venv"
log="$venv/setup.log"
: > "$log"
# run a step with its output in the log; on failure name the step, show the log's tail, stop
run() {
  local what="$1"; shift
  echo "=== $what: $*" >>"$log"
  if ! "$@" >>"$log" 2>&1; then
    say "FAILED: $what; last lines of $log:"
    tail -n 30 "$log" | sed 's/^/  | /' >&2
    say "full log: $log"
    exit 1
  fi
}
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
apt_updated=0
apt_install() {
  local sudo=()
  if [ "$(id -u)" != 0 ]; then
    if command -v sudo >/dev/null; then
      sudo=(sudo)
    else
      say "$* missing: install them (apt-get install $*) as root, or install sudo"; exit 1
    fi
  fi
  say "installing $* with apt-get"
  if [ "$apt_updated" = 0 ]; then
    run 'apt-get update' ${sudo[@]+"${sudo[@]}"} apt-get update -qq
    apt_updated=1
  fi
  run "apt-get install $*" ${sudo[@]+"${sudo[@]}"} env DEBIAN_FRONTEND=noninteractive \
    apt-get install -y -qq "$@"
}
if [ ! -x "$venv/bin/python" ]; then
  say "creating $venv"
  if ! python3 -m venv "$venv" >>"$log" 2>&1; then
    # Debian's python3 ships venv/ensurepip separately
    apt_install python3-venv
    rm -rf "$venv/bin" "$venv/lib" "$venv/lib64" "$venv/include" "$venv/pyvenv.cfg"
    run 'python3 -m venv' python3 -m venv "$venv"
  fi
fi
pip=("$venv/bin/python" -m pip install --disable-pip-version-check --no-input)
say "installing the pinned requirements (ROS 2 kilted wheels, numpy, scipy, ...) with pip"
run 'pip install --upgrade pip' "${pip[@]}" --upgrade pip
run 'pip install -r requirements.txt' "${pip[@]}" -r "$root/requirements.txt"
say "installing the eight Python packages of src/ (editable)"
run 'pip install -e src/...' "${pip[@]}" --no-deps --no-build-isolation \
  -e "$root/src/mr_damper_common" -e "$root/src/mr_damper_model" -e "$root/src/mr_damper_rig" -e "$root/src/quarter_car_sim" \
  -e "$root/src/mr_damper_bringup" -e "$root/src/mr_damper_can" \
  -e "$root/src/semi_active_control" -e "$root/src/mr_damper_gym"

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
mend='import pathlib, re, sys, sysconfig
import numpy
py_inc, np_inc = sysconfig.get_paths()["include"], numpy.get_include()
for path in sorted(pathlib.Path(sys.prefix, "share").glob("*/cmake/*Export.cmake")):
    text = path.read_text()
    new = re.sub(r"/opt/python/[^/;\"]+/include/python[0-9.]+", py_inc, text)
    new = re.sub(r"/opt/python/[^;\"]+/numpy/_core/include", np_inc, new)
    if new != text:
        path.write_text(new)'
run 'mend the CMake exports of the message wheels' "$venv/bin/python" -c "$mend"
say "building the messages (src/mr_damper_interfaces: cmake, rosidl) into $venv"
rm -rf "$build"; mkdir -p "$build"
cmake_env=(env PATH="$venv/bin:$PATH" AMENT_PREFIX_PATH="$venv" CMAKE_PREFIX_PATH="$venv")
run 'cmake configure' "${cmake_env[@]}" cmake -S "$ifaces" -B "$build" \
  -DCMAKE_INSTALL_PREFIX="$venv" -DPython3_EXECUTABLE="$venv/bin/python" -DBUILD_TESTING=OFF \
  -DCMAKE_BUILD_TYPE=Release
run 'cmake build' "${cmake_env[@]}" cmake --build "$build" -j "$(nproc 2>/dev/null || echo 2)"
run 'cmake install' "${cmake_env[@]}" cmake --install "$build"
echo "$want" > "$stamp"
say "done in $((SECONDS - t_start)) s (log: $log)"
