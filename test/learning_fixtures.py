"""Shared by the tests of ``fall_predictor.learning``: a private copy of the session's generated
dataset (import the fixture into a test module to use it), a hand-made sweep point and a
hand-made sweep result."""
import dataclasses
import math
import shutil
from pathlib import Path

import pytest

from fall_predictor.learning.baselines import CurvePoint, pareto_front
from fall_predictor.learning.crossval import SweepPoint
from fall_predictor.learning.evaluation import BaselineCurves
from fall_predictor.learning.metrics import EvaluationResult
from fall_predictor.learning.selection import select_paper_analogues
from fall_predictor.learning.sweep_results import SweepConfig, SweepResult, SweepTiming


@pytest.fixture(scope='session')
def fixture_dataset(small_dataset, tmp_path_factory) -> Path:
    """A private copy of the session's generated dataset (caches are written into it): one per
    test module that imports this fixture."""
    copy = tmp_path_factory.mktemp('data') / 'dataset'
    shutil.copytree(small_dataset, copy)    # copy2 keeps modification times, so cache entries stay valid
    return copy


def sweep_point(fpr: float, lead: float, tau_plus: float = 0.0, tau_his: float = 0.0) -> SweepPoint:
    """A cross-validated point with the given FPR and tau_lead [s] (10 + 10 trajectories)."""
    return SweepPoint(tau_plus, tau_his, 9.0, fpr, 0.0, lead, 0.0, lead / 2.0, 2.0, 1.0, 1.0,
                      10, 10, 0, 0, 0, 0, ())


def sweep_result(with_learning_curve: bool = True) -> SweepResult:
    """A hand-made sweep result: four points (one with an undefined lead), a learning curve and
    one point per baseline (the momentum one with an infinite frontal threshold)."""
    config = SweepConfig.quick(folds=2, tau_plus_values_s=(0.0, 0.5), tau_his_values_s=(0.0, 0.06),
                               learning_curve_sizes=(5,))
    points = (sweep_point(0.3, 0.9, 0.0, 0.0), sweep_point(0.05, 0.7, 0.0, 0.06),
              sweep_point(0.0, 0.2, 0.5, 0.0), sweep_point(0.0, math.nan, 0.5, 0.06))
    curve = (dataclasses.replace(sweep_point(0.2, 0.6, 0.0, 0.06), n_train=5.0, fpr_std=0.1),
             dataclasses.replace(sweep_point(0.05, 0.7, 0.0, 0.06), n_train=9.0, fpr_std=0.05))

    def baseline(threshold, fpr, lead):
        evaluation = EvaluationResult(20, 10, 10, round(fpr * 10), fpr, lead, 1, 0, 0, 1.0,
                                      lead / 1.0)
        return (CurvePoint(threshold, fpr, lead, evaluation),)

    baselines = BaselineCurves(com_height=baseline(0.45, 0.1, 0.14),
                               momentum=baseline((10.0, math.inf), 0.2, 0.6),
                               capture_point=baseline(-0.1, 0.4, 0.5))
    timing = SweepTiming(load_s=1.0, capture_point_s=2.0, baselines_s=0.5, cross_validation_s=9.0,
                         plots_s=1.5, total_s=14.0, n_fits=6, fit_s_total=8.0, fit_s_mean_full=1.2,
                         jobs=2)
    return SweepResult(config=config, data_dir='data', dataset_fingerprint='abc123',
                       n_trajectories=20, n_fallen=10, unreadable={'traj_9': 'truncated'},
                       points=points, pareto=tuple(pareto_front(points)),
                       selected=tuple(select_paper_analogues(points)),
                       learning_curve=curve if with_learning_curve else (), fits=(),
                       baselines=baselines, timing=timing, command='fall-predictor sweep',
                       files=('sweep.json', 'table.md'))
