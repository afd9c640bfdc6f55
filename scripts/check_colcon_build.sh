#!/usr/bin/env bash
# `colcon build` of the package from a clean copy of the tracked files (colcon from PyPI).
set -euo pipefail
cd "$(dirname "$0")/.."
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/src/fall_predictor"
git ls-files -z | xargs -0 -I{} cp --parents {} "$work/src/fall_predictor/"
# Untracked-but-needed files do not exist in CI either, so only tracked files are built.
(cd "$work" && PATH="$OLDPWD/.venv/bin:$PATH" colcon build --event-handlers console_direct- >"$work/colcon.log" 2>&1) \
  || { cat "$work/colcon.log"; echo "colcon build FAILED"; exit 1; }
for exe in fall-predictor fall_monitor simulator_node controller_node feature_node predictor_node \
           recorder_node; do
  test -x "$work/install/fall_predictor/lib/fall_predictor/$exe" \
    || { echo "colcon build: $exe missing from lib/fall_predictor"; ls -R "$work/install" | head -50; exit 1; }
done
share="$work/install/fall_predictor/share/fall_predictor"
for file in launch/fall_predictor.launch.py launch/monitor.launch.py config/fall_predictor.yaml \
            config/monitor.yaml models/default_model.json examples/fall_consumer.py; do
  test -f "$share/$file" || { echo "colcon build: $file missing from share/fall_predictor"; exit 1; }
done
echo "colcon build: OK (executables in lib/fall_predictor, launch/config/models/examples in share)"
