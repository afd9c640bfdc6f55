#!/usr/bin/env bash
# Create or refresh .venv at the repository root and install every dependency from PyPI:
# ROS 2 Jazzy (rclpy on Fast DDS, common_interfaces) as wheels, this package (editable) with
# its Python dependencies, pytest and colcon; then the package's own messages (msg/*.msg), built
# with colcon against the wheels (scripts/build_interfaces.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3.11}
command -v "$PYTHON" >/dev/null || PYTHON=python3
"$PYTHON" -c 'import sys; assert sys.version_info[:2] == (3, 11), "Python 3.11 is required (ROS 2 Jazzy wheels)"'
if [ ! -x .venv/bin/python ] || ! .venv/bin/python -c 'import sys' 2>/dev/null; then
  rm -rf .venv
  "$PYTHON" -m venv .venv
fi
.venv/bin/python -m pip install --quiet --upgrade pip
.venv/bin/python -m pip install --quiet -r requirements.txt
scripts/build_interfaces.sh
.venv/bin/python -c 'import rclpy, pybullet, rosbags, sklearn, pinocchio, fall_predictor' 2>/dev/null
echo "setup: .venv ready ($(.venv/bin/python --version))"
