#!/usr/bin/env bash
# The main job on the built-in simulator: install, run every identification trial on the simulated Js-2
# (six CiA 402 drives on an in-process virtual CAN bus), identify the model from the log, write the report.
# Output: runs/quickstart/session.mcap, runs/quickstart/model/{model.yaml, robot_identified.urdf, report.html, verdict.json}
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh
out=${1:-runs/quickstart}
mkdir -p "$out"
echo "[js2] 1/2 acquisition: js2-acquire --trial all -o $out/session.mcap"
.venv/bin/js2-acquire --trial all -o "$out/session.mcap" --force
echo "[js2] 2/2 identification: js2-identify $out/session.mcap -o $out/model"
.venv/bin/js2-identify "$out/session.mcap" -o "$out/model"
echo "[js2] done: open $out/model/report.html"
