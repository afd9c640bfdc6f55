"""The cross-validated sweep's results as data: its settings (:class:`SweepConfig`), what it
computed (:class:`SweepResult`) and its wall times (:class:`SweepTiming`).

:mod:`fall_predictor.learning.sweep` computes a :class:`SweepResult`;
:mod:`fall_predictor.learning.report` (``sweep.json``, ``table.md``) and
:mod:`fall_predictor.learning.plots` (the figures) read one; :mod:`fall_predictor.learning.sweep_files`
runs the sweep and writes them. This module imports none of them.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Optional

from fall_predictor.data.dataset import STATES
from fall_predictor.learning.crossval import FoldFit, SweepPoint
from fall_predictor.learning.evaluation import BaselineCurves, BaselineGrids, json_float
from fall_predictor.learning.selection import PaperPredictor
from fall_predictor.learning.training import (BALANCED_WEIGHT, DEFAULT_SAMPLE_STRIDE,
                                              FALLING_WEIGHT, check_sample_stride, make_learner)


#: method §9's range of tau_plus [s] and the history windows [s] of the sweep.
DEFAULT_TAU_PLUS_VALUES_S = (-1.5, -1.25, -1.0, -0.75, -0.5, -0.25, 0.0, 0.25, 0.5)
DEFAULT_TAU_HIS_VALUES_S = (0.0, 0.004, 0.008, 0.016, 0.03, 0.044, 0.06, 0.08, 0.1)


def checked_tau_his_values(values) -> tuple[float, ...]:
    """A grid of history windows [s] as floats: at least one, each finite and >= 0 (else
    ``ValueError``)."""
    windows = tuple(float(v) for v in values)
    if not windows:
        raise ValueError('need at least one tau_his value')
    if any(not (math.isfinite(v) and v >= 0.0) for v in windows):
        raise ValueError(f'tau_his values must be finite and >= 0, got {windows}')
    return windows
#: Learning curve: training-set sizes (trajectories) at FP-L2's settings (method §9).
DEFAULT_LEARNING_CURVE_SIZES = (50, 100, 250, 500, 900)
LEARNING_CURVE_TAU_PLUS_S = -0.25
LEARNING_CURVE_TAU_HIS_S = 0.06


@dataclass(frozen=True)
class SweepConfig:
    """Settings of the sweep (times [s]); validated on construction."""

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
    #: The CoM guard [m] of every predictor and baseline; None: the dataset's robot's
    #: (:func:`~fall_predictor.data.dataset.dataset_guard_com_height_m`). The sweep records the
    #: guard actually used.
    guard_com_height_m: Optional[float] = None
    #: Every training also learns from its trajectories' left-right mirror images
    #: (:mod:`fall_predictor.learning.mirror`); the test folds stay as recorded.
    mirror: bool = False
    #: The baselines' operating points chosen on training folds (nested, over the tau_his grid:
    #: the sweep's longest part); off for a sweep that compares learners (the hindsight baseline
    #: curves are computed either way).
    nested_baselines: bool = True

    def __post_init__(self) -> None:
        object.__setattr__(self, 'tau_plus_values_s', tuple(float(v) for v in self.tau_plus_values_s))
        object.__setattr__(self, 'tau_his_values_s', checked_tau_his_values(self.tau_his_values_s))
        object.__setattr__(self, 'learning_curve_sizes', tuple(self.learning_curve_sizes))
        if isinstance(self.folds, bool) or not isinstance(self.folds, int) or self.folds < 2:
            raise ValueError(f'folds must be an int >= 2, got {self.folds!r}')
        if not self.tau_plus_values_s:
            raise ValueError('need at least one tau_plus value')
        if any(not math.isfinite(v) for v in self.tau_plus_values_s):
            raise ValueError(f'tau_plus values must be finite, got {self.tau_plus_values_s}')
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
        for name in ('mirror', 'nested_baselines'):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f'{name} must be true or false, got {getattr(self, name)!r}')
        if self.guard_com_height_m is not None and not (
                isinstance(self.guard_com_height_m, (int, float)) and 0.0 <= self.guard_com_height_m <= 2.0):
            raise ValueError(f'guard_com_height_m must be None or in [0, 2] m, got {self.guard_com_height_m!r}')

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
                'capture_point': self.capture_point, 'state': self.state,
                'guard_com_height_m': self.guard_com_height_m, 'mirror': self.mirror,
                'nested_baselines': self.nested_baselines}


@dataclass(frozen=True)
class SweepTiming:
    """Wall times [s] of the parts of a sweep, and the trainings' count and fit times
    (``plots_s`` is 0 until the figures are written)."""

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
    """Everything the sweep computed (also written to ``sweep.json``); ``files``: what was
    written, empty until :func:`fall_predictor.learning.sweep_files.write_sweep_files`."""

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
    #: method §11 baselines: tau_his grid, thresholds chosen on the other folds (nested)
    baselines_nested: Optional[dict[str, Any]] = None

    @property
    def grid_fits(self) -> tuple[FoldFit, ...]:
        """The trainings of the tau_plus x tau_his grid (all the other folds, every tau_his of
        the grid evaluated): ``fits`` without the learning curve's own trainings."""
        grid_tau_his = set(self.config.tau_his_values_s)
        return tuple(fit for fit in self.fits if fit.train_size is None
                     and fit.tau_plus_s in self.config.tau_plus_values_s
                     and grid_tau_his <= set(fit.results))
