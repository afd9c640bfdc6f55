#!/usr/bin/env bash
# Rebuilds the results page's held-out table of the G1 under Unitree's learned policy in MuJoCo
# (docs/results.md, "Prediction quality: the Unitree G1 under Unitree's learned walking policy")
# from a fresh clone: development and held-out runs, the operating point chosen by nested
# cross-validation on the development runs (label window, decision threshold, history window; the
# FPR <= 0.02 budget), the shipped model trained at it, evaluated once held out, the baselines with
# thresholds chosen on the development runs; then the table, beside the committed figures (exit 1
# where one differs). About 2.5 h on 2 cores.
#   scripts/rebuild/g1_unitree_rl_heldout.sh OUT_DIR      (DATA=dir of datasets to reuse, JOBS=2)
source "$(dirname "$0")/common.sh"
$FP generate --robot g1_12dof --trajectories 1000 --seed 2026 --jobs "$JOBS" --out "$DATA/g1pol_dev1000" --json > "$OUT/generate_dev.json"
$FP generate --robot g1_12dof --trajectories 1000 --seed 4052 --jobs "$JOBS" --out "$DATA/g1pol_test1000" --json > "$OUT/generate_test.json"
DEV=$DATA/g1pol_dev1000 TEST=$DATA/g1pol_test1000
$PY benchmarks/bench_boosted_trees.py --data "$DEV" --test "$TEST" --folds 5 --mirror --attitude \
  --thresholds 0,0.5,1,1.5,2,3,4,5,6 --tau-plus=-0.5 --tau-plus=-0.25 --tau-plus=0 \
  --budgets 0,0.01,0.02,0.06 --jobs "$JOBS" --out "$OUT/boosted_trees.json"
# The nested choice at the FPR <= 0.02 budget: (tau_plus, decision threshold, tau_his).
read -r TAU_PLUS THRESHOLD TAU_HIS < <($PY -c "import json, sys
c = json.load(open(sys.argv[1]))['nested']['boosting_attitude']['0.02']['chosen_on_all_folds']
print(*c)" "$OUT/boosted_trees.json")
train_shipped g1_unitree_rl_model.json "$DEV" --tau-plus="$TAU_PLUS" --learner boosting \
  --param decision_threshold="$THRESHOLD" --attitude --mirror --tau-his "$TAU_HIS"
heldout g1_unitree_rl_model.json "$TEST"
$PY benchmarks/bench_heldout_baselines.py --dev "$DEV" --test "$TEST" --budgets 0,0.01,0.02,0.06 --jobs "$JOBS" \
  --out "$OUT/heldout/baselines.json"
$PY scripts/rebuild/heldout_table.py "$OUT/heldout" --compare docs/prediction/g1_unitree_rl/heldout | tee "$OUT/table.md"
