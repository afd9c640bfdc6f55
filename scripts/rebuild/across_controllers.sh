#!/usr/bin/env bash
# Rebuilds the results page's table of models across controllers (docs/results.md, "Across
# controllers"): the shipped G1 models made under C_bal evaluated on the G1 under Unitree's policy,
# the policy's model on the G1 under C_bal, and one model trained on both controllers' development
# runs evaluated on both held-out sets; per run too. The held-out sets are those of
# g1_c_bal_heldout.sh and g1_unitree_rl_heldout.sh (DATA=their data directory reuses them).
# About 2 h on 2 cores from nothing, 40 min with the datasets.
#   scripts/rebuild/across_controllers.sh OUT_DIR      (DATA=dir of datasets to reuse, JOBS=2)
source "$(dirname "$0")/common.sh"
$FP generate --robot g1_12dof --trajectories 1000 --seed 2026 --jobs "$JOBS" --out "$DATA/g1pol_dev1000" --json > "$OUT/generate_policy_dev.json"
$FP generate --robot g1_12dof --trajectories 1000 --seed 4052 --jobs "$JOBS" --out "$DATA/g1pol_test1000" --json > "$OUT/generate_policy_test.json"
# C_bal's development runs: the first 600 of g1_c_bal_heldout.sh's (seed 101; a run depends only
# on the seed and its index), enough beside the policy's 1000 and half the time.
$FP generate --robot g1 --trajectories 600 --seed 101 --sensor-noise 1 --jobs "$JOBS" --out "$DATA/g1_dev600" --json > "$OUT/generate_c_bal_dev.json"
$FP generate --robot g1 --trajectories 1000 --seed 5050 --sensor-noise 1 --jobs "$JOBS" --out "$DATA/g1_test1000_5050" --json > "$OUT/generate_c_bal_test.json"
POLICY_TEST=$DATA/g1pol_test1000 C_BAL_TEST=$DATA/g1_test1000_5050

# across NAME MODEL TEST SUFFIX: a model evaluated once on another controller's held-out runs.
across() {
  $FP evaluate --data "$3" --model "$2" --jobs "$JOBS" --per-run "$OUT/heldout/${1}_on_$4.runs.csv" \
    --json > "$OUT/heldout/${1}_on_$4.json"
}
for m in g1_attitude_model g1_model g1_conservative_model; do
  across "$m" "models/$m.json" "$POLICY_TEST" g1_unitree_rl
done
across g1_unitree_rl_model models/g1_unitree_rl_model.json "$C_BAL_TEST" g1_c_bal

# One model on both controllers' development runs, at the policy model's operating point (the
# label window, threshold and history window its nested choice gave).
$FP train --data "$DATA/g1pol_dev1000" --data "$DATA/g1_dev600" --tau-plus=-0.5 --learner boosting \
  --param decision_threshold=0.5 --attitude --mirror --tau-his 0.044 --jobs "$JOBS" \
  --out "$OUT/g1_both_controllers_model.json" --json > "$OUT/train_g1_both_controllers_model.json"
across g1_both_controllers_model "$OUT/g1_both_controllers_model.json" "$POLICY_TEST" g1_unitree_rl
across g1_both_controllers_model "$OUT/g1_both_controllers_model.json" "$C_BAL_TEST" g1_c_bal
$PY scripts/rebuild/heldout_table.py "$OUT/heldout" --compare docs/prediction/across_controllers | tee "$OUT/table.md"
