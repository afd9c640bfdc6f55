#!/usr/bin/env bash
# Regenerate the dataset-dependent results of docs/results.md on the current robot: the
# 1000-trajectory dataset and a 300-trajectory held-out test set (another seed), both recorded
# with the robot's sensor topics; the cross-validated sweep on the estimated state with nested
# operating points and the held-out test set (Table 2, Fig. 10/11, Pareto front with intervals);
# the shipped model (estimated state) and its held-out evaluation; the same on the true state
# for comparison; the sensor-noise sweep; the robot's robustness and credibility.
# About 3 h on 2 cores. Data goes to data/ (not committed); figures and JSON to the folders of
# docs/ named after the question they answer (docs/results.md links each; benchmarks/README.md).
set -euo pipefail
cd "$(dirname "$0")/.."
FP=.venv/bin/fall-predictor
JOBS=${JOBS:-2}
$FP generate --trajectories 1000 --seed 0 --out data/d1000s --sensor-noise 1 --jobs "$JOBS" --json
$FP generate --trajectories 300 --seed 1 --out data/t300s --sensor-noise 1 --jobs "$JOBS" --json
$FP stats data/d1000s --plots docs/robots/asimo_like --jobs "$JOBS" --json > docs/robots/asimo_like/dataset_stats.json
scripts/evaluation_pipeline.sh data/d1000s data/t300s docs/prediction/asimo_like/sweep_plain_model --folds 10
# The shipped model: the mirrored lists at FP-L2's settings, evaluated by the mirrored sweep.
$FP sweep --data data/d1000s --out docs/prediction/asimo_like/sweep_default_model --jobs "$JOBS" --mirror --no-nested-baselines \
  --no-capture-point --tau-plus=-2,-1.5,-1.25,-1,-0.75,-0.5,-0.25,0,0.25,0.5,0.75 \
  --tau-his 0,0.004,0.008,0.016,0.03,0.044,0.06,0.08,0.1,0.15,0.2,0.3 --no-learning-curve --json > /dev/null
$FP train --data data/d1000s --mirror --tau-plus=-0.25 --tau-his-recommended 0.06 --out models/default_model.json --jobs "$JOBS"
# Its learned fall direction (method §8b), fitted at its triggers on the development set.
$FP fit-direction --data data/d1000s --model models/default_model.json --out models/default_model.json --jobs "$JOBS" --json
# Its time to fall (method §8d), fitted from each of its triggers until fallen on the same set.
$FP fit-time-to-fall --data data/d1000s --model models/default_model.json --out models/default_model.json --jobs "$JOBS" --json
# The conservative model (method §8a): boosted trees at the FPR-0 budget's setting, chosen with
# tau_plus by nested CV over the development data (benchmarks/bench_boosted_trees.py).
.venv/bin/python benchmarks/bench_boosted_trees.py --data data/d1000s --folds 5 --mirror \
  --tau-plus=-1.0 --tau-plus=-0.75 --tau-plus=-0.5 --tau-plus=-0.25 --tau-plus=0 --tau-plus=0.25 --tau-plus=0.5 --jobs "$JOBS" --out data/tau_plus_grid_asimo_like.json
$FP train --data data/d1000s --tau-plus=0 --learner boosting --param decision_threshold=1.0 --mirror \
  --tau-his-recommended 0.08 --out models/conservative_model.json --jobs "$JOBS"
$FP fit-direction --data data/d1000s --model models/conservative_model.json --out models/conservative_model.json --jobs "$JOBS" --json
$FP fit-time-to-fall --data data/d1000s --model models/conservative_model.json --out models/conservative_model.json --jobs "$JOBS" --json
.venv/bin/python scripts/model_evaluation.py --sweep docs/prediction/asimo_like/sweep_default_model/sweep.json --model models/default_model.json \
  --out models/default_model.evaluation.json \
  --dataset-command "fall-predictor generate --trajectories 1000 --seed 0 --out data/d1000s --sensor-noise 1 --jobs 2"
$FP evaluate --data data/t300s --model models/default_model.json --jobs "$JOBS" --json > docs/estimation/heldout_estimated.json
# The true state, same trajectories and settings, for the side-by-side.
$FP train --data data/d1000s --state true --tau-plus=-0.25 --tau-his-recommended 0.06 --out data/true_state_model.json --jobs "$JOBS"
$FP evaluate --data data/t300s --state true --model data/true_state_model.json --jobs "$JOBS" --json > docs/estimation/heldout_true.json
.venv/bin/python benchmarks/bench_true_vs_estimated.py --data data/d1000s --test data/t300s --jobs "$JOBS" --out docs/estimation/true_vs_estimated.json
.venv/bin/python benchmarks/bench_noise_sweep.py --model models/default_model.json --trajectories 40 --seed 2 \
  --work data/noise --jobs "$JOBS" --out docs/estimation/noise_sweep.json --plot docs/estimation/noise_sweep.png
.venv/bin/python benchmarks/bench_scale_out.py --trajectories 200 --work-dir data/scale --out docs/scale_out/scale_out_200.json
$FP robustness --jobs "$JOBS" --json --out docs/robots/asimo_like/robustness.json > /dev/null
.venv/bin/python benchmarks/bench_robot_credibility.py --trajectories 100 > /dev/null
.venv/bin/python scripts/fig2_force_sweep.py --model models/default_model.json --tau-his 0.06 --jobs "$JOBS"
# The monitor on a robot: timing benchmarks, each on an otherwise idle machine.
.venv/bin/python benchmarks/bench_monitor_latency.py --seconds 15 --deployment all --timing all --out docs/monitor/latency.json > /dev/null
.venv/bin/python benchmarks/bench_latency.py --duration 20 --sensors --single-process-monitor --composed-robot --real-time-factor 1 --out data/full_paced.json > /dev/null
.venv/bin/python benchmarks/bench_latency.py --duration 20 --sensors --single-process-monitor --composed-robot --real-time-factor 0 --out data/full_unpaced.json > /dev/null
.venv/bin/python -c "import json; runs = {k: json.load(open(f'data/full_{n}.json')) for k, n in (('paced_1x', 'paced'), ('unpaced', 'unpaced'))}
[r.pop('logs') for r in runs.values()]
json.dump({'what': 'the whole simulated system on the sensor topics (bench_latency.py --duration 20 --sensors --single-process-monitor --composed-robot), paced at real time and unpaced, back to back', **runs}, open('docs/monitor/full_system.json', 'w'), indent=1)"
.venv/bin/python benchmarks/bench_soak.py --minutes 10 --work runs/soak10 --out docs/monitor/soak.json > /dev/null
