"""Baselines evaluated as fairly as the learned lists (method §11): the same ``tau_his`` grid, and
thresholds chosen on training folds.

A hand-coded baseline has nothing to train, but its threshold *is* chosen; choosing it on all
trajectories and reporting it on the same ones (the paper's curves, and
:func:`~fall_predictor.learning.evaluation.baseline_curves`) favours it. Here every
(threshold, ``tau_his``) of a baseline is evaluated per test fold of the same stratified folds
as the learned lists, and "the longest lead at FPR <= x" is chosen on the other folds and
reported on the held-out one by :func:`~fall_predictor.learning.nested.nested_operating_point`
(the folds' results are wrapped as :class:`~fall_predictor.learning.crossval.FoldFit` with the
threshold's index in place of ``tau_plus``).
"""
from __future__ import annotations

from typing import Any, Callable, Optional, Sequence

import numpy as np

from fall_predictor.learning.baselines import COM_Z, LIN_MOM_X, LIN_MOM_Y
from fall_predictor.learning.crossval import FoldFit, stratified_trajectory_folds
from fall_predictor.learning.metrics import evaluate_atomic
from fall_predictor.learning.nested import NESTED_FPR_BUDGETS, nested_operating_point, pooled_json
from fall_predictor.monitor.records import GUARD_COM_HEIGHT_M, TrajectoryFeatures

AtomicFor = Callable[[int, Any], np.ndarray]


def baseline_fold_fits(trajectories: Sequence[TrajectoryFeatures], thresholds: Sequence[Any],
                       atomic_for: AtomicFor, tau_his_values: Sequence[float],
                       folds: Sequence[np.ndarray],
                       guard_com_height_m: float = GUARD_COM_HEIGHT_M) -> list[FoldFit]:
    """Per fold and threshold, the test fold's results for every ``tau_his`` [s], with the CoM
    guard ``guard_com_height_m`` [m] (the robot's)."""
    fits = []
    for fold, index in enumerate(folds):
        test = [trajectories[i] for i in index]
        for k, threshold in enumerate(thresholds):
            atomic = [atomic_for(int(i), threshold) for i in index]
            results = evaluate_atomic(test, atomic, tau_his_values,
                                      guard_com_height_m=guard_com_height_m)
            fits.append(FoldFit(fold, float(k), None, 0, (), (), 0.0, results))
    return fits


def _threshold_json(threshold: Any) -> Any:
    if isinstance(threshold, tuple):
        return [float(v) if np.isfinite(v) else None for v in threshold]
    return float(threshold)


def nested_baseline_json(trajectories: Sequence[TrajectoryFeatures], thresholds: Sequence[Any],
                         atomic_for: AtomicFor, tau_his_values: Sequence[float], folds: int,
                         seed: int, budgets: Sequence[float] = NESTED_FPR_BUDGETS,
                         guard_com_height_m: float = GUARD_COM_HEIGHT_M) -> list[dict[str, Any]]:
    """One baseline's nested operating points (per FPR budget), thresholds named; CoM guard
    ``guard_com_height_m`` [m]."""
    fold_index = stratified_trajectory_folds(trajectories, folds, seed)
    fits = baseline_fold_fits(trajectories, thresholds, atomic_for, tau_his_values, fold_index,
                              guard_com_height_m)
    out = []
    for budget in budgets:
        point = nested_operating_point(fits, budget)
        out.append({'max_fpr': budget, 'outer': pooled_json(point.outer),
                    'chosen_per_fold': [{'threshold': _threshold_json(thresholds[int(k)]),
                                         'tau_his_s': tau} for k, tau in point.chosen],
                    'hindsight': pooled_json(point.hindsight),
                    'selected_in_hindsight': {
                        'threshold': _threshold_json(thresholds[int(point.selected_in_hindsight[0])]),
                        'tau_his_s': point.selected_in_hindsight[1]}})
    return out


def cross_validated_baselines(trajectories: Sequence[TrajectoryFeatures],
                              capture_point: Optional[Sequence[np.ndarray]], grids: Any,
                              tau_his_values: Sequence[float], folds: int, seed: int,
                              budgets: Sequence[float] = NESTED_FPR_BUDGETS,
                              imu: Optional[Sequence[np.ndarray]] = None,
                              guard_com_height_m: float = GUARD_COM_HEIGHT_M) -> dict[str, Any]:
    """CoM height, momentum, (with distances) capture point and (with ``imu`` signals,
    :func:`~fall_predictor.learning.tilt_detector.imu_signals_cached`) the IMU tilt detector,
    each over its threshold grid (``grids``: a
    :class:`~fall_predictor.learning.evaluation.BaselineGrids`) x ``tau_his``, nested per FPR
    budget; every one with the CoM guard ``guard_com_height_m`` [m] (the robot's: a dataset's
    callers pass :func:`~fall_predictor.data.dataset.dataset_guard_com_height_m`)."""
    heights = [float(h) for h in grids.com_height_m]
    momentum = [(float(a), float(b)) for a in grids.momentum_sagittal
                for b in grids.momentum_frontal]
    baselines: dict[str, tuple[list, AtomicFor]] = {
        'com_height': (heights, lambda i, h: trajectories[i].X[:, COM_Z] < h),
        'momentum': (momentum, lambda i, ab: (np.abs(trajectories[i].X[:, LIN_MOM_X]) > ab[0])
                     | (np.abs(trajectories[i].X[:, LIN_MOM_Y]) > ab[1]))}
    if capture_point is not None:
        margins = [float(m) for m in grids.capture_point_margin_m]
        baselines['capture_point'] = (margins, lambda i, m: np.asarray(capture_point[i]) > -m)
    if imu is not None:
        from fall_predictor.learning.tilt_detector import threshold_grid, tilt_alarms
        baselines['imu_tilt'] = (threshold_grid(), lambda i, th: tilt_alarms(imu[i], *th))
    return {name: nested_baseline_json(trajectories, thresholds, atomic_for, tau_his_values,
                                       folds, seed, budgets, guard_com_height_m)
            for name, (thresholds, atomic_for) in baselines.items()}
