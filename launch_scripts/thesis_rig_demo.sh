#!/usr/bin/env bash
# Offline thesis demo (issue 2 "main job"): simulate the thesis rig test, identify it, print the
# parameter tables and save the plots. No ROS needed.
#
#   bash launch_scripts/thesis_rig_demo.sh [OUT_DIR] [SEED]      (default out/thesis_demo, seed 1)
#
# 1. mr-damper-rig-test: Spencer plant scaled to the thesis damper, cam 1.1 Hz / 30 mm, coil
#    0-2 A in 0.5 A steps (4 cam periods each), 1 kHz, 2 N load-cell noise, 16-bit DAQ.
# 2. mr-damper-identify: ONE kwok-current model over all currents (table, params JSON, plot),
#    then the thesis Table 4.3 layout: Kwok per current (table, JSON, per-current plot).
# Outputs in OUT_DIR: thesis_rig_test.csv, truth.json (the Spencer truth), kwok_current.json/.png,
# kwok_per_current_<level>A.json, kwok_per_current.png, tables.txt. About 10 s.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="${1:-$root/out/thesis_demo}"
seed="${2:-1}"
bash "$root/launch_scripts/setup_venv.sh"
bin="$root/.venv/bin"
export OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-1}"
mkdir -p "$out"
{
  echo "== simulated thesis rig test (seed $seed) =="
  "$bin/mr-damper-rig-test" --out "$out/thesis_rig_test.csv" --seed "$seed" \
    --truth-out "$out/truth.json"
  echo
  echo "== one kwok-current model over all currents =="
  "$bin/mr-damper-identify" "$out/thesis_rig_test.csv" --model kwok-current --seed "$seed" \
    --out "$out/kwok_current.json" --plot "$out/kwok_current.png"
  echo
  echo "== Kwok per current (thesis Table 4.3 layout) =="
  "$bin/mr-damper-identify" "$out/thesis_rig_test.csv" --model kwok --per-current \
    --seed "$seed" --out "$out/kwok_per_current.json" --plot "$out/kwok_per_current.png"
} | tee "$out/tables.txt"
echo
echo "thesis_rig_demo: outputs in $out"
