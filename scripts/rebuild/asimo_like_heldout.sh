#!/usr/bin/env bash
# Rebuilds the results page's held-out table of the ASIMO-like robot under C_bal (docs/results.md,
# "Prediction quality: the ASIMO-like robot under C_bal") from a fresh clone: development and
# held-out runs, the three shipped models trained as shipped, each evaluated once held out, the
# baselines with thresholds chosen on the development runs; then the table, beside the committed
# figures (exit 1 where one differs). About 3 h on 2 cores.
#   scripts/rebuild/asimo_like_heldout.sh OUT_DIR      (DATA=dir of datasets to reuse, JOBS=2)
source "$(dirname "$0")/common.sh"
$FP generate --trajectories 1000 --seed 0 --sensor-noise 1 --jobs "$JOBS" --out "$DATA/d1000s" --json > "$OUT/generate_dev.json"
$FP generate --trajectories 1000 --seed 2026 --sensor-noise 1 --jobs "$JOBS" --out "$DATA/t1000s_2026" --json > "$OUT/generate_test.json"
DEV=$DATA/d1000s TEST=$DATA/t1000s_2026
train_shipped default_model.json "$DEV" --mirror --tau-plus=-0.25 --tau-his 0.06
train_shipped boosted_model.json "$DEV" --tau-plus=-0.25 --learner boosting --param decision_threshold=0.5 --mirror --tau-his 0.08
train_shipped conservative_model.json "$DEV" --tau-plus=0 --learner boosting --param decision_threshold=1.0 --mirror --tau-his 0.08
for m in default_model.json boosted_model.json conservative_model.json; do heldout "$m" "$TEST"; done
$PY benchmarks/bench_heldout_baselines.py --dev "$DEV" --test "$TEST" --jobs "$JOBS" --out "$OUT/heldout/baselines.json"
$PY scripts/rebuild/heldout_table.py "$OUT/heldout" --compare docs/prediction/asimo_like/heldout | tee "$OUT/table.md"
