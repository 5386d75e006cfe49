#!/usr/bin/env bash
# The README's main job: the whole MR damper suite over ROS 2 on this machine.
#   bash launch_scripts/main.sh [mr-damper-suite options, e.g. --duration 60 --out DIR]
# Sets up .venv if needed (launch_scripts/setup_venv.sh), then runs .venv/bin/mr-damper-suite
# (package mr_damper_bringup):
# virtual rig -> live identifier -> quarter car with skyhook through the identified inverse model,
# 30 s by default, progress lines every 5 s, then the summary (identified vs true damper, error
# over time, live skyhook vs passive on the same road, fail-safe time, messages lost).
# Outputs (suite.mcap: every topic of the run, summary.json, hysteresis.png, convergence.png,
# ride.png, logs/) go to runs/suite
# unless --out is given. DDS stays on loopback (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) on a
# random private ROS_DOMAIN_ID (20..220) unless --domain-id is given.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/launch_scripts/setup_venv.sh"
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
status=0
"$root/.venv/bin/mr-damper-suite" "$@" || status=$?
if [ "$status" -ne 0 ]; then
  echo "main.sh: the suite ended with status $status (see the node logs in the output folder)" >&2
fi
exit "$status"
