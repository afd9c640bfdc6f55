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
test -x "$work/install/fall_predictor/lib/fall_predictor/fall-predictor" \
  || { echo "colcon build: entry point missing from lib/fall_predictor"; ls -R "$work/install" | head -50; exit 1; }
echo "colcon build: OK (entry points in install/fall_predictor/lib/fall_predictor)"
