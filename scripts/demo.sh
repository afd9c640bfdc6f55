#!/usr/bin/env bash
# The README's main job: set everything up, then bring up the ROS 2 fall monitor (simulator,
# features, predictor, controller nodes as separate processes) and push the robot 3 times,
# printing one JSON line per push. Extra arguments go to `fall-predictor bringup`. Seed 11's
# pushes: two the robot survives (64 N, 101 N), then one it does not (449 N), which the monitor
# predicts and C_fall takes over from (docs/results.md, "The main job").
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
exec .venv/bin/fall-predictor bringup --pushes 3 --seed 11 --json "$@"
