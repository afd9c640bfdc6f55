# Sourced by the rebuild scripts: run from the repository root, a fresh clone's venv, the output
# directory (argument 1; created, its data/ under it unless DATA names a directory of datasets
# to reuse: generation is deterministic and resumable), and the parallelism.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
[ -x .venv/bin/fall-predictor ] || scripts/setup.sh
FP=.venv/bin/fall-predictor
PY=.venv/bin/python
OUT=${1:?usage: $0 OUT_DIR}
DATA=${DATA:-$OUT/data}
JOBS=${JOBS:-2}
mkdir -p "$OUT/heldout" "$DATA"

# train_shipped NAME DEV ARGS...: a shipped model's recipe (train, then its direction and time to
# fall on the same data), written to $OUT/NAME.
train_shipped() {
  local name=$1 dev=$2; shift 2
  $FP train --data "$dev" "$@" --out "$OUT/$name" --jobs "$JOBS" --json > "$OUT/train_${name%.json}.json"
  $FP fit-direction --data "$dev" --model "$OUT/$name" --out "$OUT/$name" --jobs "$JOBS" --json > /dev/null
  $FP fit-time-to-fall --data "$dev" --model "$OUT/$name" --out "$OUT/$name" --jobs "$JOBS" --json > /dev/null
}

# heldout NAME TEST: the model $OUT/NAME evaluated once on the held-out set TEST, per run too.
heldout() {
  local name=$1 test=$2
  $FP evaluate --data "$test" --model "$OUT/$name" --jobs "$JOBS" --per-run "$OUT/heldout/${name%.json}.runs.csv" \
    --json > "$OUT/heldout/$name"  portable "$OUT/heldout/$name"
}

# portable FILE...: the JSON's paths relative to the repository (or <tmp>/...), never this
# machine's folders (evaluate names its --per-run file as given).
portable() { $PY benchmarks/portable_paths.py "$@"; }
