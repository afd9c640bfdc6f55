"""Per-sample decision time of OnlinePredictor.step versus a scikit-learn tree on one sample.

A weighted tree of the given depth is grown on synthetic data (falling = a noisy nonlinear
function of the features, 4:1 weights) and rewritten as a decision list; the predictor uses
that list in every contact mode. Each call is timed on its own with ``time.perf_counter_ns``
over fresh feature vectors; the JSON printed holds the median and 99th percentile [us] of:

* ``step_list_input``: ``OnlinePredictor.step(t, x, mode)`` with ``x`` a list of floats;
* ``step_numpy_input``: the same with ``x`` a float64 numpy array (converted inside);
* ``sklearn_tree_predict``: ``DecisionTreeClassifier.predict(x.reshape(1, -1))``, same tree.

Usage: ``python benchmarks/bench_predictor.py [--depth 8] [--samples 20000]``.
"""
from __future__ import annotations

import argparse
import json
import platform
import time

import numpy as np

from fall_predictor.monitor.decision_list import PerModeDecisionLists
from fall_predictor.learning.learners import TreeListLearner
from fall_predictor.monitor.predictor import OnlinePredictor
from fall_predictor.monitor.records import BALANCED, N_CONTACT_MODES, N_FEATURES


def timing_summary(durations_ns: list[int]) -> dict[str, float]:
    us = np.asarray(durations_ns) / 1000.0
    return {'median_us': round(float(np.median(us)), 3),
            'p99_us': round(float(np.percentile(us, 99)), 3),
            'calls': len(durations_ns)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--depth', type=int, default=8, help='tree depth (default 8)')
    parser.add_argument('--samples', type=int, default=20000, help='timed calls per method')
    parser.add_argument('--seed', type=int, default=0)
    args = parser.parse_args()

    rng = np.random.default_rng(args.seed)
    X = rng.normal(size=(50000, N_FEATURES))
    score = X[:, 0] + 0.5 * X[:, 3] - X[:, 5] * X[:, 6] + 0.3 * rng.normal(size=X.shape[0])
    y = (score > 1.5).astype(np.int8)
    learner = TreeListLearner(max_depth=args.depth, min_samples_leaf=20)
    learner.fit(X, y, np.where(y == BALANCED, 4.0, 1.0))
    decision_list = learner.decision_list_
    predictor = OnlinePredictor(PerModeDecisionLists(tuple([decision_list] * N_CONTACT_MODES)),
                                tau_his_s=0.02)

    X_test = rng.normal(size=(args.samples, N_FEATURES))
    X_test[:, 2] = 0.59                         # CoM height: keep the guard off
    rows = X_test.tolist()
    modes = rng.integers(0, N_CONTACT_MODES, args.samples).tolist()
    clock = time.perf_counter_ns

    def time_steps(inputs) -> list[int]:
        predictor.reset()
        durations = []
        for i, (x, mode) in enumerate(zip(inputs, modes)):
            start = clock()
            predictor.step(i * 0.001, x, mode)
            durations.append(clock() - start)
        return durations

    time_steps(rows[:1000])                     # warm-up
    step_list = time_steps(rows)
    step_numpy = time_steps(list(X_test))
    tree = learner.estimator_
    sklearn_calls = min(args.samples, 3000)
    sklearn_durations = []
    for x in X_test[:sklearn_calls]:
        one = x.reshape(1, -1)
        start = clock()
        tree.predict(one)
        sklearn_durations.append(clock() - start)

    print(json.dumps({
        'tree_depth': tree.get_depth(),
        'list_depth_rules': decision_list.depth,
        'list_rule_size': decision_list.rule_size,
        'step_list_input': timing_summary(step_list),
        'step_numpy_input': timing_summary(step_numpy),
        'sklearn_tree_predict': timing_summary(sklearn_durations),
        'python': platform.python_version(),
        'machine': platform.machine(),
    }, indent=1))


if __name__ == '__main__':
    main()
