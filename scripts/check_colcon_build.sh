#!/usr/bin/env bash
# `colcon build` of the package from a clean copy of the tracked files (colcon from PyPI).
set -euo pipefail
cd "$(dirname "$0")/.."
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/src/fall_predictor"
git ls-files -z | xargs -0 -I{} cp --parents {} "$work/src/fall_predictor/"
# Untracked-but-needed files do not exist in CI either, so only tracked files are built.
venv=$PWD/.venv
start=$(date +%s)
(cd "$work" && PATH="$venv/bin:$PATH" AMENT_PREFIX_PATH="$venv" CMAKE_PREFIX_PATH="$venv" \
  colcon build --event-handlers console_direct- >"$work/colcon.log" 2>&1) \
  || { cat "$work/colcon.log"; echo "colcon build FAILED"; exit 1; }
seconds=$(( $(date +%s) - start ))
for exe in fall-predictor fall_monitor simulator_node controller_node feature_node predictor_node \
           recorder_node simulated_robot state_estimator_node; do
  test -x "$work/install/fall_predictor/lib/fall_predictor/$exe" \
    || { echo "colcon build: $exe missing from lib/fall_predictor"; ls -R "$work/install" | head -50; exit 1; }
done
share="$work/install/fall_predictor/share/fall_predictor"
for file in launch/fall_predictor.launch.py launch/monitor.launch.py config/fall_predictor.yaml \
            config/monitor.yaml models/default_model.json models/g1_model.json examples/fall_consumer.py; do
  test -f "$share/$file" || { echo "colcon build: $file missing from share/fall_predictor"; exit 1; }
done
# The installed package: the Python code and its generated messages import together, from the
# install tree alone (not from this checkout).
site="$work/install/fall_predictor/lib/python3.11/site-packages"
(cd "$work" && PYTHONPATH="$site" LD_LIBRARY_PATH="$work/install/fall_predictor/lib" \
  "$venv/bin/python" -c 'import fall_predictor, fall_predictor.msg as m, fall_predictor.ros.fall_monitor
assert fall_predictor.__file__.startswith("'"$site"'"), fall_predictor.__file__
m.FallState(); m.Measurement()
from fall_predictor.profiles.profile import available_profiles, load_profile
assert set(available_profiles()) >= {"asimo_like", "g1"}, available_profiles()
for name in available_profiles():
    assert load_profile(name).urdf_path.is_file()') \
  || { echo "colcon build: the installed package does not import"; exit 1; }
test -f "$work/install/fall_predictor/share/fall_predictor/msg/FallState.msg" \
  || { echo "colcon build: msg/FallState.msg missing from share/fall_predictor"; exit 1; }
for file in msg/LowState.msg LICENSE; do
  test -f "$share/vendor/unitree_hg/$file" \
    || { echo "colcon build: vendor/unitree_hg/$file missing from share/fall_predictor"; exit 1; }
done
echo "colcon build: OK in ${seconds} s (executables in lib/fall_predictor, messages and Python package" \
     "import from the install tree with the robot profiles, launch/config/models/examples/msg in share)"
