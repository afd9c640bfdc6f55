"""Training the time-to-fall regressor with scikit-learn, exported to the
numpy-free trees of :mod:`fall_predictor.monitor.time_to_fall` and
:mod:`fall_predictor.monitor.boosted_trees`.

Two regressors, the target ``t_fallen - t`` [s] at every ``sample_stride``-th sample:

* :func:`fit_time_to_fall` (``train``): one tree per contact mode with at least
  ``min_mode_samples`` samples, and a fallback tree on all of them, on the falling states
  (method §5: ``t_push <= t < t_fallen`` of a falling trajectory);
* :func:`fit_time_to_fall_at_triggers` (``fit-time-to-fall``, method §8d): boosted trees over the
  15 features on the samples the monitor reports a time to fall on, from each of a model's
  triggers until fallen (:func:`time_left_after_triggers`).
"""
from __future__ import annotations

from typing import Optional, Sequence

import numpy as np

from fall_predictor.learning.labels import label_states
from fall_predictor.monitor.boosted_trees import BoostedTimeToFall
from fall_predictor.monitor.records import FALLING, N_CONTACT_MODES, N_FEATURES, TrajectoryFeatures
from fall_predictor.monitor.time_to_fall import RegressionTree, TimeToFallRegressor

DEFAULT_MAX_DEPTH = 8
DEFAULT_MIN_SAMPLES_LEAF = 20
DEFAULT_MIN_MODE_SAMPLES = 200
#: The boosted regressor's settings (scikit-learn's ``HistGradientBoostingRegressor``: trees of up
#: to 31 leaves, squared error), chosen by cross-validation on the development data of both robots
#: at their shipped models' triggers (``benchmarks/bench_time_to_fall_cv.py``).
TIME_TO_FALL_LEARNER_PARAMS = {'max_iter': 100, 'learning_rate': 0.1, 'max_leaf_nodes': 31,
                               'min_samples_leaf': 20}


def falling_states(trajectories: Sequence[TrajectoryFeatures], sample_stride: int = 10
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Features (n, 15), modes (n,) and time to fall [s] (n,) of the falling states."""
    xs, modes, ttf = [], [], []
    for traj in trajectories:
        if not traj.fallen:
            continue
        y = label_states(traj.t, traj.t_push, traj.t_fallen)
        idx = np.flatnonzero(y == FALLING)[::sample_stride]
        xs.append(traj.X[idx])
        modes.append(traj.mode[idx])
        ttf.append(traj.t_fallen - traj.t[idx])
    if not xs:
        raise ValueError('no falling trajectory: nothing to learn a time to fall from')
    return np.concatenate(xs), np.concatenate(modes), np.concatenate(ttf)


def export_tree(estimator) -> RegressionTree:
    """A fitted ``DecisionTreeRegressor`` as a :class:`RegressionTree`."""
    tree = estimator.tree_
    leaf = tree.children_left == -1
    return RegressionTree(
        feature=tuple(int(f) for f in np.where(leaf, -1, tree.feature)),
        threshold=tuple(float(v) for v in np.where(leaf, 0.0, tree.threshold)),
        left=tuple(int(v) for v in tree.children_left),
        right=tuple(int(v) for v in tree.children_right),
        value=tuple(float(v) for v in tree.value[:, 0, 0]))


def fit_time_to_fall(trajectories: Sequence[TrajectoryFeatures], sample_stride: int = 10,
                     max_depth: int = DEFAULT_MAX_DEPTH,
                     min_samples_leaf: int = DEFAULT_MIN_SAMPLES_LEAF,
                     min_mode_samples: int = DEFAULT_MIN_MODE_SAMPLES,
                     random_state: Optional[int] = 0) -> TimeToFallRegressor:
    """Per-mode regression trees of the time to fall (absolute error criterion is too slow at
    this size: squared error, so leaves hold means), on the falling states."""
    X, mode, ttf = falling_states(trajectories, sample_stride)
    return fit_time_to_fall_samples(X, mode, ttf, max_depth, min_samples_leaf, min_mode_samples,
                                    random_state)


def fit_time_to_fall_samples(X: np.ndarray, mode: np.ndarray, ttf: np.ndarray,
                             max_depth: int = DEFAULT_MAX_DEPTH,
                             min_samples_leaf: int = DEFAULT_MIN_SAMPLES_LEAF,
                             min_mode_samples: int = DEFAULT_MIN_MODE_SAMPLES,
                             random_state: Optional[int] = 0) -> TimeToFallRegressor:
    """The trees of :func:`fit_time_to_fall` on given samples: features ``X`` (n, 15), contact
    modes (n,), time left until fallen [s] (n,)."""
    from sklearn.tree import DecisionTreeRegressor

    def fit(mask: np.ndarray) -> RegressionTree:
        model = DecisionTreeRegressor(max_depth=max_depth, min_samples_leaf=min_samples_leaf,
                                      random_state=random_state)
        return export_tree(model.fit(X[mask], ttf[mask]))

    fallback = fit(np.ones(ttf.size, dtype=bool))
    trees = tuple(fit(mode == m) if np.count_nonzero(mode == m) >= min_mode_samples else None
                  for m in range(N_CONTACT_MODES))
    return TimeToFallRegressor(trees, fallback)


def time_left_after_triggers(trajectories: Sequence[TrajectoryFeatures],
                             triggers: Sequence[Optional[int]], stride: int = 10
                             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Features (N, 15), contact modes (N,), time left until fallen [s] (N,) and whether the
    sample is the trigger (N,), at every ``stride``-th sample from each in-time trigger (a sample
    index, None for none) until fallen: the samples the monitor reports a time to fall on."""
    rows = []
    for traj, k in zip(trajectories, triggers):
        if k is None:
            continue
        end = int(np.searchsorted(traj.t, traj.t_fallen))
        rows += [(traj.X[j, :N_FEATURES], int(traj.mode[j]), traj.t_fallen - traj.t[j], j == k)
                 for j in range(k, max(end, k + 1), stride)]
    if not rows:
        return (np.zeros((0, N_FEATURES)), np.zeros(0, dtype=int), np.zeros(0),
                np.zeros(0, dtype=bool))
    X, modes, left, at_trigger = (np.array([r[i] for r in rows]) for i in range(4))
    return X, modes, left, at_trigger


def fit_time_to_fall_at_triggers(trajectories: Sequence[TrajectoryFeatures],
                                 triggers: Sequence[Optional[int]], stride: int = 10,
                                 random_state: int = 0) -> BoostedTimeToFall:
    """Boosted trees of the time left until fallen (:data:`TIME_TO_FALL_LEARNER_PARAMS`) on the
    samples from each trigger until fallen (:func:`time_left_after_triggers`)."""
    X, _, left, _ = time_left_after_triggers(trajectories, triggers, stride)
    return fit_boosted_time_to_fall(X, left, random_state)


def fit_boosted_time_to_fall(X: np.ndarray, left: np.ndarray,
                             random_state: int = 0) -> BoostedTimeToFall:
    """The boosted trees of :func:`fit_time_to_fall_at_triggers` on given samples: features
    ``X`` (n, 15) and the time left until fallen [s] (n,)."""
    from sklearn.ensemble import HistGradientBoostingRegressor

    from fall_predictor.learning.boosting import exported_trees

    if left.size == 0:
        raise ValueError('no trigger on a fall: nothing to learn a time to fall from')
    model = HistGradientBoostingRegressor(**TIME_TO_FALL_LEARNER_PARAMS, random_state=random_state)
    bias, trees = exported_trees(model.fit(X, left), N_FEATURES)
    return BoostedTimeToFall(trees, bias)
