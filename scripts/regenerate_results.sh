#!/usr/bin/env bash
# Regenerate the dataset-dependent results of docs/results.md on the current robot: the
# 1000-trajectory dataset, its statistics and Fig. 6 plots, the cross-validated sweep (Table 2,
# Fig. 10/11), the shipped model and its evaluation, the robot's robustness and credibility.
# About 1.5 h on 2 cores. Data goes to data/ (not committed); figures and JSON to docs/.
set -euo pipefail
cd "$(dirname "$0")/.."
FP=.venv/bin/fall-predictor
JOBS=${JOBS:-2}
$FP generate --trajectories 1000 --seed 0 --out data/d1000 --jobs "$JOBS" --json
$FP stats data/d1000 --plots docs/figures --jobs "$JOBS" --json > docs/dataset_stats.json
$FP sweep --data data/d1000 --folds 10 --out docs/sweep --jobs "$JOBS" --json > /dev/null
$FP train --data data/d1000 --tau-plus=-0.25 --tau-his-recommended 0.06 --out models/default_model.json --jobs "$JOBS"
.venv/bin/python scripts/model_evaluation.py --sweep docs/sweep/sweep.json --model models/default_model.json \
  --out models/default_model.evaluation.json
$FP robustness --jobs "$JOBS" --json --out benchmarks/results/robustness.json > /dev/null
.venv/bin/python benchmarks/bench_robot_credibility.py --trajectories 100 > /dev/null
.venv/bin/python scripts/fig2_force_sweep.py --model models/default_model.json --tau-his 0.06 --jobs "$JOBS"
