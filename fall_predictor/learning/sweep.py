"""The cross-validated sweep (method §9, :func:`compute_sweep`): it computes, it writes nothing.

k-fold cross-validation by trajectory (:mod:`fall_predictor.learning.crossval`: stratified by
outcome, a trajectory is never split) over a grid of ``tau_plus`` (training) and ``tau_his``
(run time): one training per (fold, tau_plus); the test fold's atomic predictions are computed
once and every ``tau_his`` is evaluated from them. Fold results are averaged as the paper
reports them. A learning curve (cross-validated trainings on fewer trajectories) is added at
FP-L2's settings. The hand-coded baselines (CoM height, horizontal linear momentum, capture
point) are evaluated on the same trajectories, and the analogues of the paper's predictors
are picked on the Pareto front (:mod:`fall_predictor.learning.selection`).

The result is data (:mod:`fall_predictor.learning.sweep_results`: :class:`SweepConfig`,
:class:`SweepResult`, :class:`SweepTiming`, importable from here too);
:mod:`fall_predictor.learning.sweep_files` (``run_sweep``) computes it and writes ``sweep.json``,
``table.md`` (:mod:`fall_predictor.learning.report`) and the PNG figures
(:mod:`fall_predictor.learning.plots`). The CLI subcommand ``sweep`` is a thin wrapper.
"""
from __future__ import annotations

import dataclasses
import math
import time
from typing import Optional, Sequence

import numpy as np

from fall_predictor.data.dataset import DatasetError, dataset_guard_com_height_m
from fall_predictor.data.parallel import compute_backend
from fall_predictor.learning.baselines import pareto_front
from fall_predictor.learning.crossval import FoldFit, aggregate_folds, cross_validate_grid
from fall_predictor.learning.evaluation import baseline_curves, capture_point_distances_cached
from fall_predictor.learning.fair_baselines import cross_validated_baselines
from fall_predictor.learning.learners import RuleListLearner
from fall_predictor.learning.selection import select_paper_analogues
from fall_predictor.learning.sweep_results import (  # noqa: F401  (re-exported: callers import them from here)
    DEFAULT_LEARNING_CURVE_SIZES, DEFAULT_TAU_HIS_VALUES_S, DEFAULT_TAU_PLUS_VALUES_S,
    LEARNING_CURVE_TAU_HIS_S, LEARNING_CURVE_TAU_PLUS_S, SweepConfig, SweepResult, SweepTiming)
from fall_predictor.learning.training import PathLike, load_dataset, make_learner, require_outcomes
from fall_predictor.monitor.records import TrajectoryFeatures

__all__ = ['DEFAULT_LEARNING_CURVE_SIZES', 'DEFAULT_TAU_HIS_VALUES_S', 'DEFAULT_TAU_PLUS_VALUES_S',
           'LEARNING_CURVE_TAU_HIS_S', 'LEARNING_CURVE_TAU_PLUS_S', 'SweepConfig', 'SweepResult',
           'SweepTiming', 'compute_sweep']


def compute_sweep(data_dir: PathLike, config: SweepConfig = SweepConfig(), jobs: int = 1,
                  skip_unreadable: bool = False, progress: bool = False,
                  command: Optional[str] = None, scheduler: Optional[str] = None) -> SweepResult:
    """Cross-validated sweep over ``config``'s tau_plus x tau_his grid, learning curve and
    baselines on the dataset ``data_dir``; returns the result, writes nothing (``files`` is
    empty and ``timing.plots_s`` 0: :func:`fall_predictor.learning.sweep_files.run_sweep` fills
    them in when it writes the figures and the report).

    Trainings: ``folds`` x (number of tau_plus values + learning-curve sizes below the full
    training set); ``jobs`` processes run them (and load the features), or, with ``scheduler``
    (a Dask scheduler's address), the cluster's workers run the trainings while ``jobs`` local
    processes load the features (:mod:`fall_predictor.data.parallel`); the results are the same.
    Every predictor and baseline runs with ``config.guard_com_height_m``, by default the CoM
    guard of the dataset's robot (recorded in the result's config).
    """
    started = time.perf_counter()
    report = load_dataset(data_dir, jobs, skip_unreadable, progress, config.state)
    guard = (dataset_guard_com_height_m(data_dir) if config.guard_com_height_m is None
             else float(config.guard_com_height_m))
    # the state and the guard actually used
    config = dataclasses.replace(config, state=report.state, guard_com_height_m=guard)
    trajectories = report.trajectories
    require_outcomes(trajectories, data_dir, need_balanced=True)
    if len(trajectories) < config.folds:
        raise DatasetError(f'{data_dir}: {len(trajectories)} trajectories, fewer than '
                           f'{config.folds} folds')
    load_s = time.perf_counter() - started

    start = time.perf_counter()
    distances = (capture_point_distances_cached(data_dir, trajectories, jobs, progress, config.state)
                 if config.capture_point else None)
    capture_point_s = time.perf_counter() - start
    start = time.perf_counter()
    baselines = baseline_curves(trajectories, distances, config.baseline_grids, guard)
    baselines_nested = None
    if config.nested_baselines:
        from fall_predictor.learning.tilt_detector import imu_signals_cached
        imu = imu_signals_cached(data_dir, trajectories, jobs, progress)
        baselines_nested = cross_validated_baselines(
            trajectories, distances, config.baseline_grids, config.tau_his_values_s, config.folds,
            config.seed, imu=imu, guard_com_height_m=guard)
    baselines_s = time.perf_counter() - start

    start = time.perf_counter()
    learner = make_learner(config.learner_name, config.learner_params)
    with compute_backend(scheduler):
        fits = cross_validate_grid(trajectories, learner, config.tau_plus_values_s,
                                   config.tau_his_values_s, config.folds, config.seed,
                                   config.sample_stride, jobs=jobs, progress=progress,
                                   guard_com_height_m=guard, mirror=config.mirror)
        curve_fits = _learning_curve_fits(trajectories, learner, fits, config, jobs, progress)
    cross_validation_s = time.perf_counter() - start

    points = tuple(aggregate_folds([fit for fit in fits if fit.tau_plus_s == tau_plus], tau_his)
                   for tau_plus in config.tau_plus_values_s for tau_his in config.tau_his_values_s)
    by_size: dict[Optional[int], list[FoldFit]] = {}
    for fit in curve_fits:
        by_size.setdefault(fit.train_size, []).append(fit)
    learning_curve = sorted((aggregate_folds(group, config.learning_curve_tau_his_s)
                             for group in by_size.values()), key=lambda p: p.n_train)
    pareto = tuple(pareto_front(points))
    selected = tuple(select_paper_analogues(points))

    sweep_fit_ids = {id(fit) for fit in fits}
    all_fits = tuple(fits) + tuple(fit for fit in curve_fits if id(fit) not in sweep_fit_ids)
    timing = SweepTiming(
        load_s=load_s, capture_point_s=capture_point_s, baselines_s=baselines_s,
        cross_validation_s=cross_validation_s, plots_s=0.0,
        total_s=time.perf_counter() - started, n_fits=len(all_fits),
        fit_s_total=float(sum(fit.fit_s for fit in all_fits)),
        fit_s_mean_full=float(np.mean([fit.fit_s for fit in fits])), jobs=jobs)
    return SweepResult(
        config=config, data_dir=str(data_dir), dataset_fingerprint=report.fingerprint,
        n_trajectories=len(trajectories), n_fallen=sum(t.fallen for t in trajectories),
        unreadable=dict(report.errors), points=points, pareto=pareto, selected=selected,
        learning_curve=tuple(learning_curve), fits=all_fits, baselines=baselines, timing=timing,
        command=command, baselines_nested=baselines_nested, files=())


def _learning_curve_fits(trajectories: Sequence[TrajectoryFeatures], learner: RuleListLearner,
                         sweep_fits: Sequence[FoldFit], config: SweepConfig, jobs: int,
                         progress: bool) -> list[FoldFit]:
    """Cross-validated trainings of the learning curve, at its tau_plus and tau_his.

    Sizes at or above the smallest training set of a fold are dropped; the full-size point
    reuses the sweep's trainings when the sweep grid holds the curve's tau_plus and tau_his.
    """
    if not config.learning_curve_sizes:
        return []
    smallest_training_set = len(trajectories) - math.ceil(len(trajectories) / config.folds)
    sizes: list[Optional[int]] = sorted({n for n in config.learning_curve_sizes
                                         if n < smallest_training_set})
    reuse = (config.learning_curve_tau_plus_s in config.tau_plus_values_s
             and config.learning_curve_tau_his_s in config.tau_his_values_s)
    if not reuse:
        sizes.append(None)
    fits = []
    if sizes:
        fits = cross_validate_grid(trajectories, learner, (config.learning_curve_tau_plus_s,),
                                   (config.learning_curve_tau_his_s,), config.folds, config.seed,
                                   config.sample_stride, train_sizes=sizes, jobs=jobs,
                                   progress=progress, guard_com_height_m=config.guard_com_height_m,
                                   mirror=config.mirror)
    if reuse:
        fits += [fit for fit in sweep_fits if fit.tau_plus_s == config.learning_curve_tau_plus_s]
    return fits
