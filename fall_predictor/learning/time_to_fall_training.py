"""Training the time-to-fall regressor with scikit-learn, exported to the
numpy-free trees of :mod:`fall_predictor.monitor.time_to_fall`.

Trained on the falling states (method §5: ``t_push <= t < t_fallen`` of a falling trajectory) of
every falling trajectory, every ``sample_stride``-th sample; the target is ``t_fallen - t`` [s].
One tree per contact mode with at least ``min_mode_samples`` such samples, and a fallback tree
on all of them.
"""
from __future__ import annotations

from typing import Optional, Sequence

import numpy as np

from fall_predictor.learning.labels import label_states
from fall_predictor.monitor.records import FALLING, N_CONTACT_MODES, TrajectoryFeatures
from fall_predictor.monitor.time_to_fall import RegressionTree, TimeToFallRegressor

DEFAULT_MAX_DEPTH = 8
DEFAULT_MIN_SAMPLES_LEAF = 20
DEFAULT_MIN_MODE_SAMPLES = 200


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
    this size: squared error, so leaves hold means)."""
    from sklearn.tree import DecisionTreeRegressor

    X, mode, ttf = falling_states(trajectories, sample_stride)

    def fit(mask: np.ndarray) -> RegressionTree:
        model = DecisionTreeRegressor(max_depth=max_depth, min_samples_leaf=min_samples_leaf,
                                      random_state=random_state)
        return export_tree(model.fit(X[mask], ttf[mask]))

    fallback = fit(np.ones(ttf.size, dtype=bool))
    trees = tuple(fit(mode == m) if np.count_nonzero(mode == m) >= min_mode_samples else None
                  for m in range(N_CONTACT_MODES))
    return TimeToFallRegressor(trees, fallback)
