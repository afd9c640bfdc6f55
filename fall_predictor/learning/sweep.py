"""The cross-validated sweep (SPEC §9, :func:`run_sweep`) and its settings (:class:`SweepConfig`).

k-fold cross-validation by trajectory (:mod:`fall_predictor.learning.crossval`: stratified by
outcome, a trajectory is never split) over a grid of ``tau_plus`` (training) and ``tau_his``
(run time): one training per (fold, tau_plus); the test fold's atomic predictions are computed
once and every ``tau_his`` is evaluated from them. Fold results are averaged as the paper
reports them. A learning curve (cross-validated trainings on fewer trajectories) is added at
FP-L2's settings. The hand-coded baselines (CoM height, horizontal linear momentum, capture
point) are evaluated on the same trajectories, and the analogues of the paper's predictors
are picked on the Pareto front (:mod:`fall_predictor.learning.selection`). Outputs:
``sweep.json``, ``table.md`` (:mod:`fall_predictor.learning.report`) and PNG figures
(:mod:`fall_predictor.learning.plots`: Fig. 10 and Fig. 11 analogues and a learning curve).
The CLI subcommand ``sweep`` is a thin wrapper.
"""
from __future__ import annotations

import dataclasses
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional, Sequence

import numpy as np

from fall_predictor.data.dataset import STATES, DatasetError
from fall_predictor.data.parallel import compute_backend
from fall_predictor.learning.baselines import pareto_front
from fall_predictor.learning.crossval import (FoldFit, SweepPoint, aggregate_folds,
                                              cross_validate_grid)
from fall_predictor.learning.evaluation import (BaselineCurves, BaselineGrids, baseline_curves,
                                                capture_point_distances_cached, json_float)
from fall_predictor.learning.learners import RuleListLearner
from fall_predictor.learning.plots import plot_sweep
from fall_predictor.learning.report import sweep_json, sweep_table
from fall_predictor.learning.fair_baselines import cross_validated_baselines
from fall_predictor.learning.nested import nested_report_json
from fall_predictor.learning.plots_intervals import plot_pareto_intervals
from fall_predictor.learning.selection import PaperPredictor, select_paper_analogues
from fall_predictor.learning.training import (BALANCED_WEIGHT, DEFAULT_SAMPLE_STRIDE,
                                              FALLING_WEIGHT, PathLike, check_sample_stride,
                                              load_dataset, make_learner, require_outcomes)
from fall_predictor.monitor.fileio import atomic_write_text
from fall_predictor.monitor.records import TrajectoryFeatures

#: SPEC §9's range of tau_plus [s] and the history windows [s] of the sweep.
DEFAULT_TAU_PLUS_VALUES_S = (-1.5, -1.25, -1.0, -0.75, -0.5, -0.25, 0.0, 0.25, 0.5)
DEFAULT_TAU_HIS_VALUES_S = (0.0, 0.004, 0.008, 0.016, 0.03, 0.044, 0.06, 0.08, 0.1)
#: Learning curve: training-set sizes (trajectories) at FP-L2's settings (SPEC §9).
DEFAULT_LEARNING_CURVE_SIZES = (50, 100, 250, 500, 900)
LEARNING_CURVE_TAU_PLUS_S = -0.25
LEARNING_CURVE_TAU_HIS_S = 0.06


@dataclass(frozen=True)
class SweepConfig:
    """Settings of :func:`run_sweep` (times [s]); validated on construction."""

    folds: int = 10
    seed: int = 0
    tau_plus_values_s: tuple[float, ...] = DEFAULT_TAU_PLUS_VALUES_S
    tau_his_values_s: tuple[float, ...] = DEFAULT_TAU_HIS_VALUES_S
    learner_name: str = 'tree'
    learner_params: dict[str, Any] = field(default_factory=dict)
    sample_stride: int = DEFAULT_SAMPLE_STRIDE
    #: Training-set sizes of the learning curve; sizes at or above the trajectories available
    #: for training are replaced by "all of them"; empty: no learning curve.
    learning_curve_sizes: tuple[int, ...] = DEFAULT_LEARNING_CURVE_SIZES
    learning_curve_tau_plus_s: float = LEARNING_CURVE_TAU_PLUS_S
    learning_curve_tau_his_s: float = LEARNING_CURVE_TAU_HIS_S
    baseline_grids: BaselineGrids = BaselineGrids()
    capture_point: bool = True
    #: Features from the 'true' or the 'estimated' state (data/dataset.py); the sweep records
    #: the state actually used (a dataset without sensor topics has only the true one).
    state: str = 'true'

    def __post_init__(self) -> None:
        object.__setattr__(self, 'tau_plus_values_s', tuple(float(v) for v in self.tau_plus_values_s))
        object.__setattr__(self, 'tau_his_values_s', tuple(float(v) for v in self.tau_his_values_s))
        object.__setattr__(self, 'learning_curve_sizes', tuple(self.learning_curve_sizes))
        if isinstance(self.folds, bool) or not isinstance(self.folds, int) or self.folds < 2:
            raise ValueError(f'folds must be an int >= 2, got {self.folds!r}')
        if not self.tau_plus_values_s or not self.tau_his_values_s:
            raise ValueError('need at least one tau_plus and one tau_his value')
        if any(not math.isfinite(v) for v in self.tau_plus_values_s):
            raise ValueError(f'tau_plus values must be finite, got {self.tau_plus_values_s}')
        if any(not (math.isfinite(v) and v >= 0.0) for v in self.tau_his_values_s):
            raise ValueError(f'tau_his values must be finite and >= 0, got {self.tau_his_values_s}')
        if any(isinstance(n, bool) or not isinstance(n, int) or n < 2
               for n in self.learning_curve_sizes):
            raise ValueError(f'learning-curve sizes must be ints >= 2, got {self.learning_curve_sizes}')
        if not (math.isfinite(self.learning_curve_tau_plus_s)
                and math.isfinite(self.learning_curve_tau_his_s)
                and self.learning_curve_tau_his_s >= 0.0):
            raise ValueError('the learning curve needs a finite tau_plus and a tau_his >= 0')
        check_sample_stride(self.sample_stride)
        make_learner(self.learner_name, self.learner_params)
        if self.state not in STATES:
            raise ValueError(f'state must be one of {STATES}, got {self.state!r}')

    @classmethod
    def quick(cls, **overrides: Any) -> SweepConfig:
        """A reduced grid for development runs: 5 tau_plus, 5 tau_his, a short learning
        curve and coarse baseline grids."""
        settings: dict[str, Any] = dict(
            tau_plus_values_s=(-1.5, -0.75, -0.25, 0.0, 0.5),
            tau_his_values_s=(0.0, 0.016, 0.044, 0.06, 0.1),
            learning_curve_sizes=(10, 25, 50), baseline_grids=BaselineGrids.coarse())
        settings.update(overrides)
        return cls(**settings)

    def as_json(self) -> dict[str, Any]:
        learner = make_learner(self.learner_name, self.learner_params)
        return {'folds': self.folds, 'seed': self.seed,
                'tau_plus_values_s': list(self.tau_plus_values_s),
                'tau_his_values_s': list(self.tau_his_values_s),
                'learner': {'name': self.learner_name, 'class': type(learner).__name__,
                            'params': learner.get_params()},
                'sample_stride': self.sample_stride,
                'balanced_weight': BALANCED_WEIGHT, 'falling_weight': FALLING_WEIGHT,
                'learning_curve_sizes': list(self.learning_curve_sizes),
                'learning_curve_tau_plus_s': self.learning_curve_tau_plus_s,
                'learning_curve_tau_his_s': self.learning_curve_tau_his_s,
                'baseline_grids': {k: [json_float(v) for v in values] for k, values
                                   in dataclasses.asdict(self.baseline_grids).items()},
                'capture_point': self.capture_point, 'state': self.state}


@dataclass(frozen=True)
class SweepTiming:
    """Wall times [s] of the parts of a sweep, and the trainings' count and fit times."""

    load_s: float
    capture_point_s: float
    baselines_s: float
    cross_validation_s: float
    plots_s: float
    total_s: float
    n_fits: int
    fit_s_total: float                 #: sum of the trainings' own wall times (all processes)
    fit_s_mean_full: float             #: mean fit time of the full-size trainings
    jobs: int


@dataclass(frozen=True)
class SweepResult:
    """Everything :func:`run_sweep` computed (also written to ``sweep.json``)."""

    config: SweepConfig
    data_dir: str
    dataset_fingerprint: str
    n_trajectories: int
    n_fallen: int
    unreadable: dict[str, str]
    points: tuple[SweepPoint, ...]               #: every (tau_plus, tau_his), all training data
    pareto: tuple[SweepPoint, ...]               #: the non-dominated points
    selected: tuple[tuple[PaperPredictor, SweepPoint], ...]
    learning_curve: tuple[SweepPoint, ...]       #: at the learning curve's tau_plus and tau_his
    fits: tuple[FoldFit, ...]
    baselines: BaselineCurves
    timing: SweepTiming
    command: Optional[str]                       #: the command line that ran the sweep, if any
    files: tuple[str, ...]
    #: SPEC §11 baselines: tau_his grid, thresholds chosen on the other folds (nested)
    baselines_nested: Optional[dict[str, Any]] = None


def run_sweep(data_dir: PathLike, out_dir: PathLike, config: SweepConfig = SweepConfig(),
              jobs: int = 1, skip_unreadable: bool = False, progress: bool = False,
              command: Optional[str] = None, scheduler: Optional[str] = None) -> SweepResult:
    """Cross-validated sweep over ``config``'s tau_plus x tau_his grid, learning curve and
    baselines on the dataset ``data_dir``; writes ``sweep.json``, ``table.md`` and PNGs to
    ``out_dir`` and returns what it wrote.

    Trainings: ``folds`` x (number of tau_plus values + learning-curve sizes below the full
    training set); ``jobs`` processes run them (and load the features), or, with ``scheduler``
    (a Dask scheduler's address), the cluster's workers run the trainings while ``jobs`` local
    processes load the features (:mod:`fall_predictor.data.parallel`); the results are the same.
    """
    started = time.perf_counter()
    out_dir = Path(out_dir)
    report = load_dataset(data_dir, jobs, skip_unreadable, progress, config.state)
    config = dataclasses.replace(config, state=report.state)     # the state actually used
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
    baselines = baseline_curves(trajectories, distances, config.baseline_grids)
    from fall_predictor.learning.tilt_detector import imu_signals_cached
    imu = imu_signals_cached(data_dir, trajectories, jobs, progress)
    baselines_nested = cross_validated_baselines(trajectories, distances, config.baseline_grids,
                                                 config.tau_his_values_s, config.folds,
                                                 config.seed, imu=imu)
    baselines_s = time.perf_counter() - start

    start = time.perf_counter()
    learner = make_learner(config.learner_name, config.learner_params)
    with compute_backend(scheduler):
        fits = cross_validate_grid(trajectories, learner, config.tau_plus_values_s,
                                   config.tau_his_values_s, config.folds, config.seed,
                                   config.sample_stride, jobs=jobs, progress=progress)
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

    start = time.perf_counter()
    out_dir.mkdir(parents=True, exist_ok=True)
    figures = plot_sweep(out_dir, points, pareto, selected, tuple(learning_curve), baselines,
                         config)
    grid_fits = [fit for fit in fits if fit.train_size is None]
    if grid_fits:
        figures = list(figures) + [plot_pareto_intervals(
            out_dir / 'pareto_intervals.png', grid_fits, points,
            nested_report_json(grid_fits, {}), baselines_nested)]
    plots_s = time.perf_counter() - start
    sweep_fit_ids = {id(fit) for fit in fits}
    all_fits = tuple(fits) + tuple(fit for fit in curve_fits if id(fit) not in sweep_fit_ids)
    timing = SweepTiming(
        load_s=load_s, capture_point_s=capture_point_s, baselines_s=baselines_s,
        cross_validation_s=cross_validation_s, plots_s=plots_s,
        total_s=time.perf_counter() - started, n_fits=len(all_fits),
        fit_s_total=float(sum(fit.fit_s for fit in all_fits)),
        fit_s_mean_full=float(np.mean([fit.fit_s for fit in fits])), jobs=jobs)
    result = SweepResult(
        config=config, data_dir=str(data_dir), dataset_fingerprint=report.fingerprint,
        n_trajectories=len(trajectories), n_fallen=sum(t.fallen for t in trajectories),
        unreadable=dict(report.errors), points=points, pareto=pareto, selected=selected,
        learning_curve=tuple(learning_curve), fits=all_fits, baselines=baselines, timing=timing,
        command=command, baselines_nested=baselines_nested,
        files=tuple(str(p) for p in figures)
        + (str(out_dir / 'sweep.json'), str(out_dir / 'table.md')))
    atomic_write_text(out_dir / 'sweep.json', json.dumps(sweep_json(result), indent=1) + '\n')
    atomic_write_text(out_dir / 'table.md', sweep_table(result))
    return result


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
                                   progress=progress)
    if reuse:
        fits += [fit for fit in sweep_fits if fit.tau_plus_s == config.learning_curve_tau_plus_s]
    return fits
