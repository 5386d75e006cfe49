#!/usr/bin/env bash
# The test command of README.md: set up .venv if needed, then run the whole pytest suite.
# Usage: bash tests/run_tests.sh [--fast] [PATH...] [pytest options]: with test paths (relative
# to the repository root; FILE::TEST works too) only those run, in one pytest. Without paths,
# all of tests/ in two pytest runs: first the tests not marked `integration` (numerics, files,
# lint: no node processes) on two pytest-xdist workers, then the `integration` tests (every
# test of tests/integration and the ones marked so elsewhere: real node processes) on two
# workers as well, each test file on one worker (`--dist loadfile`: a file's module fixtures
# start once), each worker in a ROS domain of its own (tests/conftest.py); the tests assert
# order and counts, never time, so two at once on two cores pass as one alone (8 instead of
# 17 minutes on this project's 2-vCPU VM); the exit status is the first failing run's. With
# -m, -k or -n of your own, one pytest as you asked. --fast: the unit tests only, for the
# edit-test loop (not tests/integration, nothing marked `integration` or `slow`), spread over
# one pytest-xdist worker per core (`-n auto`; a later `-n N` wins). CI (.ci/run) runs it all.
# ROS 2 nodes in the tests talk over loopback only: ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and a
# private ROS_DOMAIN_ID are set in tests/conftest.py; where the machine allows it (root with
# unshare), the whole run also happens in a private network namespace with only `lo` up.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/launch_scripts/setup_venv.sh"
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(( (RANDOM % 200) + 20 ))}"
export ROS_LOG_DIR="${ROS_LOG_DIR:-$(mktemp -d)}"
cd "$root"
args=()
split=1
for arg in "$@"; do
  if [ "$arg" = --fast ]; then
    args+=(--ignore=tests/integration -m 'not integration and not slow' -n auto)
    split=0
  else
    args+=("$arg")
    case "$arg" in
      -m|-k|-n|-m*|-k*|-n*|--numprocesses*) split=0 ;;
      -*) ;;
      *) if [ -e "${arg%%::*}" ]; then split=0; fi ;;
    esac
  fi
done
# without a test path pytest runs pytest.ini's `testpaths` (tests/) from the root
py="'$root/.venv/bin/python' -m pytest"
if [ "$split" = 1 ]; then
  runs=("$py -m 'not integration' -n 2 \"\$@\"" "$py -m integration -n 2 --dist loadfile \"\$@\"")
else
  runs=("$py \"\$@\"")
fi
script='rc=0'
for run in "${runs[@]}"; do
  script+="; $run || { r=\$?; [ \$rc != 0 ] || rc=\$r; }"
done
script+='; exit $rc'
if [ "$(id -u)" = 0 ] && command -v unshare >/dev/null && command -v ip >/dev/null \
   && unshare -n true 2>/dev/null; then
  exec unshare -n sh -c "ip link set lo up && ip link set lo multicast on &&
                         ip route add 224.0.0.0/4 dev lo && $script" netns \
    ${args[@]+"${args[@]}"}
fi
exec sh -c "$script" run_tests ${args[@]+"${args[@]}"}
