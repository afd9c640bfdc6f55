#!/usr/bin/env bash
# The evaluation in one command: the cross-validated sweep with nested operating points,
# Wilson / bootstrap intervals, lists-alone misses and leads, baselines over the tau_his grid with
# thresholds chosen on training folds, and the chosen predictors on a held-out test dataset.
#
#   scripts/evaluation_pipeline.sh TRAIN_DIR TEST_DIR OUT_DIR [extra sweep arguments...]
#
# TRAIN_DIR and TEST_DIR are datasets from `fall-predictor generate` with different seeds, e.g.
#   fall-predictor generate --trajectories 1000 --seed 0    --out data/d1000 --jobs 2
#   fall-predictor generate --trajectories 300  --seed 1000 --out data/t300  --jobs 2
# Writes OUT_DIR/sweep.json (nested_selection, baselines_nested), OUT_DIR/table.md,
# OUT_DIR/test_set.json and the figures; extra arguments go to `fall-predictor sweep`
# (e.g. --quick --folds 5 for a development run).
set -euo pipefail
if [ "$#" -lt 3 ]; then
    sed -n 2,13p "$0"; exit 2
fi
train=$1; test=$2; out=$3; shift 3
here=$(cd "$(dirname "$0")/.." && pwd)
fp=${FALL_PREDICTOR:-$here/.venv/bin/fall-predictor}
jobs=${JOBS:-2}
mkdir -p "$out"
"$fp" sweep --data "$train" --test-data "$test" --out "$out" --jobs "$jobs" "$@" --json \
    > "$out/summary.json"
echo "wrote $out/sweep.json, $out/table.md, $out/test_set.json and $out/summary.json"
