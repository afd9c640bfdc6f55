#!/usr/bin/env bash
# Rebuilds the results page's held-out table of the Unitree G1 under C_bal (docs/results.md,
# "Prediction quality: the Unitree G1 under C_bal") from a fresh clone: its development and
# held-out runs, the three shipped models trained as shipped, each evaluated once held out, the
# baselines with thresholds chosen on the development runs; then the table, beside the committed
# figures (exit 1 where one differs). About 2 h on 2 cores.
#   scripts/rebuild/g1_c_bal_heldout.sh OUT_DIR      (DATA=dir of datasets to reuse, JOBS=2)
source "$(dirname "$0")/common.sh"
$FP generate --robot g1 --trajectories 1000 --seed 101 --sensor-noise 1 --jobs "$JOBS" --out "$DATA/g1_dev1000" --json > "$OUT/generate_dev.json"
$FP generate --robot g1 --trajectories 1000 --seed 5050 --sensor-noise 1 --jobs "$JOBS" --out "$DATA/g1_test1000_5050" --json > "$OUT/generate_test.json"
DEV=$DATA/g1_dev1000 TEST=$DATA/g1_test1000_5050
train_shipped g1_attitude_model.json "$DEV" --tau-plus=-0.25 --learner boosting --param decision_threshold=0.0 --attitude --mirror --tau-his 0.08
train_shipped g1_model.json "$DEV" --tau-plus=-0.25 --mirror --tau-his 0.06
train_shipped g1_conservative_model.json "$DEV" --tau-plus=-0.75 --learner boosting --param decision_threshold=3.0 --attitude --mirror --tau-his 0.08
for m in g1_attitude_model.json g1_model.json g1_conservative_model.json; do heldout "$m" "$TEST"; done
$PY benchmarks/bench_heldout_baselines.py --dev "$DEV" --test "$TEST" --jobs "$JOBS" --out "$OUT/heldout/baselines.json"
$PY scripts/rebuild/heldout_table.py "$OUT/heldout" --compare docs/prediction/g1_c_bal/heldout | tee "$OUT/table.md"
