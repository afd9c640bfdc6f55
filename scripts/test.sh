#!/usr/bin/env bash
# The README's test command: set everything up, then run the test suite on every core (pytest-xdist:
# each worker runs whole modules, so the DDS tests of two workers never share a ROS domain:
# test/test_nodes_support.py). Arguments go to pytest (-m "not slow": the fast tier; -n 0: one
# process).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
exec .venv/bin/python -m pytest -q -n auto --dist loadfile "$@"
