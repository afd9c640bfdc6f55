#!/usr/bin/env bash
# Rebuilds the results page's table of models across controllers (docs/results.md, "Across
# controllers"): the shipped G1 models made under C_bal evaluated on the G1 under Unitree's policy,
# the policy's model on the G1 under C_bal, and one model trained on both controllers' runs. The
# held-out sets are those of g1_c_bal_heldout.sh and g1_unitree_rl_heldout.sh (DATA=their data
# directory reuses them). The model on both is trained on the first 500 runs of the policy's
# development set and the first 500 of C_bal's held-out set, and tested on the policy's held-out
# set and the other 500 of C_bal's (split_dataset.py: runs depend on (seed, index) alone, so the
# halves are independent). About 2 h on 2 cores from nothing, 1 h with the datasets.
#   scripts/rebuild/across_controllers.sh OUT_DIR      (DATA=dir of datasets to reuse, JOBS=2)
source "$(dirname "$0")/common.sh"
$FP generate --robot g1_12dof --trajectories 1000 --seed 2026 --jobs "$JOBS" --out "$DATA/g1pol_dev1000" --json > "$OUT/generate_policy_dev.json"
$FP generate --robot g1_12dof --trajectories 1000 --seed 4052 --jobs "$JOBS" --out "$DATA/g1pol_test1000" --json > "$OUT/generate_policy_test.json"
$FP generate --robot g1 --trajectories 1000 --seed 5050 --sensor-noise 1 --jobs "$JOBS" --out "$DATA/g1_test1000_5050" --json > "$OUT/generate_c_bal_test.json"
POLICY_TEST=$DATA/g1pol_test1000 C_BAL_TEST=$DATA/g1_test1000_5050
[ -d "$OUT/g1pol_dev_a500" ] || $PY scripts/rebuild/split_dataset.py "$DATA/g1pol_dev1000" --first 500 "$OUT/g1pol_dev_a500" "$OUT/g1pol_dev_b500"
[ -d "$OUT/g1_5050_a500" ] || $PY scripts/rebuild/split_dataset.py "$C_BAL_TEST" --first 500 "$OUT/g1_5050_a500" "$OUT/g1_5050_b500"

# across NAME MODEL TEST SUFFIX: a model evaluated once on another controller's held-out runs.
across() {
  $FP evaluate --data "$3" --model "$2" --jobs "$JOBS" --per-run "$OUT/heldout/${1}_on_$4.runs.csv" \
    --json > "$OUT/heldout/${1}_on_$4.json"
  portable "$OUT/heldout/${1}_on_$4.json"
}
for m in g1_attitude_model g1_model g1_conservative_model; do
  across "$m" "models/$m.json" "$POLICY_TEST" g1_unitree_rl
done
across g1_unitree_rl_model models/g1_unitree_rl_model.json "$C_BAL_TEST" g1_c_bal
across g1_unitree_rl_model models/g1_unitree_rl_model.json "$OUT/g1_5050_b500" g1_c_bal_b500
for m in g1_attitude_model g1_conservative_model; do   # C_bal's own, on the half the model on both is tested on
  across "$m" "models/$m.json" "$OUT/g1_5050_b500" g1_c_bal_b500
done

# One model on both controllers' runs, at the policy model's operating point (the label window,
# threshold and history window its nested choice gave).
$FP train --data "$OUT/g1pol_dev_a500" --data "$OUT/g1_5050_a500" --tau-plus=-0.5 --learner boosting \
  --param decision_threshold=0.5 --attitude --mirror --tau-his 0.044 --jobs "$JOBS" \
  --out "$OUT/g1_both_controllers_model.json" --json > "$OUT/train_g1_both_controllers_model.json"
across g1_both_controllers_model "$OUT/g1_both_controllers_model.json" "$POLICY_TEST" g1_unitree_rl
across g1_both_controllers_model "$OUT/g1_both_controllers_model.json" "$OUT/g1_5050_b500" g1_c_bal_b500
# The control: the same recipe on the policy's 500 runs alone (what mixing in C_bal's runs costs).
$FP train --data "$OUT/g1pol_dev_a500" --tau-plus=-0.5 --learner boosting --param decision_threshold=0.5 \
  --attitude --mirror --tau-his 0.044 --jobs "$JOBS" --out "$OUT/g1_policy_half_model.json" --json \
  > "$OUT/train_g1_policy_half_model.json"
across g1_policy_half_model "$OUT/g1_policy_half_model.json" "$POLICY_TEST" g1_unitree_rl
$PY scripts/rebuild/heldout_table.py "$OUT/heldout" --compare docs/prediction/across_controllers | tee "$OUT/table.md"
