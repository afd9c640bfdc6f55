"""The cross-validation of the package (method §5, §9): k-fold by trajectory, stratified by outcome.

A trajectory is never split between training and test (:func:`stratified_trajectory_folds`);
:func:`grouped_trajectory_folds` keeps groups of trajectories whole as well (a push impulse band,
a cause: :func:`~fall_predictor.learning.run_groups.fold_groups`), so that no fold is tested on
a group its training saw (method §11 "A budget that holds").
:func:`cross_validate_grid` trains once per (training size, fold, ``tau_plus``); the test fold's
atomic predictions are computed once and every ``tau_his`` (a run-time parameter: no
retraining) is evaluated from them. :func:`aggregate_folds` averages the fold results as the
paper reports them (:class:`SweepPoint`); :func:`cross_validated_evaluation` does both for one
``tau_plus``.
"""
from __future__ import annotations

import math
import os
import tempfile
import time
from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np

from fall_predictor.data.parallel import compute_parallel
from fall_predictor.learning.learners import RuleListLearner
from fall_predictor.learning.metrics import (EvaluationResult, evaluate_atomic, mean_or_nan,
                                             std_or_nan)
from fall_predictor.learning.training import (DEFAULT_SAMPLE_STRIDE, check_sample_stride,
                                              fit_strided, mean_nonempty_depth)
from fall_predictor.monitor.records import FALLING, GUARD_COM_HEIGHT_M, TrajectoryFeatures


def stratified_trajectory_folds(trajectories: Sequence[TrajectoryFeatures], folds: int,
                                seed: int) -> list[np.ndarray]:
    """Split trajectory indices into ``folds`` test folds, stratified by outcome.

    Fallen and balanced trajectories are each shuffled (``seed``) and dealt round-robin, one
    continuing sequence over both outcomes, so fold sizes differ by at most one and so do
    each fold's counts of either outcome. A trajectory is never split.
    """
    if isinstance(folds, bool) or not isinstance(folds, int) or not 2 <= folds <= len(trajectories):
        raise ValueError(f'folds must be an int in [2, {len(trajectories)}], got {folds!r}')
    rng = np.random.default_rng(seed)
    fallen = np.array([traj.fallen for traj in trajectories])
    order = np.concatenate([rng.permutation(np.flatnonzero(fallen)),
                            rng.permutation(np.flatnonzero(~fallen))])
    fold_of = np.empty(len(trajectories), dtype=int)
    fold_of[order] = np.arange(order.size) % folds
    return [np.flatnonzero(fold_of == k) for k in range(folds)]


def grouped_trajectory_folds(groups: Sequence, folds: int, seed: int) -> list[np.ndarray]:
    """Split trajectory indices into at most ``folds`` test folds, each group (``groups[i]``: the
    group of trajectory ``i``, any hashable) whole in one fold: fewer folds when there are fewer
    groups. The groups are dealt largest first (ties in a ``seed``-shuffled order), each to the
    fold holding the fewest trajectories so far (ties: the lower fold), so fold sizes stay close."""
    if isinstance(folds, bool) or not isinstance(folds, int) or folds < 2:
        raise ValueError(f'folds must be an int >= 2, got {folds!r}')
    members: dict = {}
    for i, group in enumerate(groups):
        members.setdefault(group, []).append(i)
    if len(members) < 2:
        raise ValueError(f'{len(members)} group: grouped folds need at least 2 groups')
    names = list(members)
    shuffled = [names[k] for k in np.random.default_rng(seed).permutation(len(names))]
    order = sorted(shuffled, key=lambda g: -len(members[g]))        # stable: the shuffle breaks ties
    n_folds = min(folds, len(members))
    test_folds: list[list[int]] = [[] for _ in range(n_folds)]
    for group in order:
        min(test_folds, key=len).extend(members[group])
    return [np.array(sorted(f), dtype=int) for f in test_folds]


@dataclass(frozen=True)
class FoldFit:
    """One training of the cross-validation and its test-fold results."""

    fold: int
    tau_plus_s: float
    train_size: Optional[int]                #: as requested; None: all the other folds
    n_train: int                             #: trajectories trained on
    rule_sizes: tuple[int, ...]              #: per contact mode
    depths: tuple[int, ...]                  #: rules per contact mode
    fit_s: float                             #: wall time of the training [s]
    results: dict[float, EvaluationResult]   #: per tau_his [s], on the test fold
    #: With decision thresholds asked for (boosted trees): per threshold [log-odds], per tau_his.
    by_threshold: dict[float, dict[float, EvaluationResult]] = field(default_factory=dict)

    @property
    def mean_rule_size(self) -> float:
        return float(np.mean(self.rule_sizes))


class _Trajectories:
    """The trajectories as one argument object: joblib's Dask backend sends an argument that
    is a (weak-referenceable) object once per call to the workers instead of once per task;
    local processes get its memory-mapped arrays by reference."""

    def __init__(self, items: Sequence[TrajectoryFeatures]):
        self.items = list(items)


def _fit_and_predict(trajectories: _Trajectories, train_index: np.ndarray, test_index: np.ndarray,
                     tau_plus_s: float, learner: RuleListLearner, sample_stride: int,
                     mirror: bool = False, scores: bool = False
                     ) -> tuple[list[np.ndarray], tuple[int, ...], tuple[int, ...], float,
                                Optional[list[np.ndarray]]]:
    """Train on the trajectories ``train_index`` (with their mirror images if ``mirror``);
    atomic falling predictions (bool per sample) on those of ``test_index``, and with ``scores``
    the scores the model thresholds (``PerModeDecisionLists.score``)."""
    train = [trajectories.items[i] for i in train_index]
    test = [trajectories.items[i] for i in test_index]
    start = time.perf_counter()
    lists = fit_strided(train, tau_plus_s, learner, sample_stride, mirror=mirror)
    fit_s = time.perf_counter() - start
    atomic = [lists.predict(traj.X, traj.mode) == FALLING for traj in test]
    score = [lists.score(traj.X, traj.mode) for traj in test] if scores else None
    return atomic, lists.rule_sizes, lists.depths, fit_s, score


def _training_subset(train_index: np.ndarray, trajectories: Sequence[TrajectoryFeatures],
                     n_train: Optional[int], rng: np.random.Generator) -> np.ndarray:
    """``n_train`` of ``train_index`` (all if None), drawn with the outcome mix of the whole."""
    if n_train is None or n_train >= train_index.size:
        return train_index
    fallen = np.array([trajectories[i].fallen for i in train_index])
    n_fallen = int(round(n_train * fallen.mean()))
    n_fallen = min(max(n_fallen, 1 if fallen.any() else 0), int(fallen.sum()))
    chosen = np.concatenate([rng.choice(train_index[fallen], n_fallen, replace=False),
                             rng.choice(train_index[~fallen], n_train - n_fallen, replace=False)])
    return np.sort(chosen)


def _shared_memory_view(trajectories: Sequence[TrajectoryFeatures], folder: str
                        ) -> list[TrajectoryFeatures]:
    """The trajectories with memory-mapped, read-only arrays, so that worker processes get
    them by reference instead of a pickled copy per task."""
    import joblib

    path = os.path.join(folder, 'trajectories.joblib')
    joblib.dump(list(trajectories), path)
    return joblib.load(path, mmap_mode='r')


def cross_validate_grid(trajectories: Sequence[TrajectoryFeatures], learner: RuleListLearner,
                        tau_plus_values: Sequence[float], tau_his_values: Sequence[float],
                        folds: int = 10, seed: int = 0,
                        sample_stride: int = DEFAULT_SAMPLE_STRIDE,
                        train_sizes: Sequence[Optional[int]] = (None,), jobs: int = 1,
                        progress: bool = False,
                        guard_com_height_m: float = GUARD_COM_HEIGHT_M,
                        mirror: bool = False,
                        decision_thresholds: Sequence[float] = (),
                        groups: Optional[Sequence] = None) -> list[FoldFit]:
    """k-fold cross-validation by trajectory over a grid: one training per (training size,
    tau_plus, fold), all ``tau_his_values`` [s] evaluated from its atomic predictions.

    Folds come from :func:`stratified_trajectory_folds` (``seed``). A training size ``n``
    trains on ``n`` trajectories drawn from the other folds with their outcome mix (seeded by
    ``seed``, the fold and ``n``); ``None`` (or ``n`` at least the available count) trains on
    all of them. ``jobs`` trainings run in parallel processes (the trajectories reach them
    memory-mapped from a temporary folder, deleted afterwards), or on the Dask cluster of an
    enclosing :func:`~fall_predictor.data.parallel.compute_backend`. The test folds are evaluated
    with the CoM guard ``guard_com_height_m`` [m]: the robot's (a dataset's callers pass
    :func:`~fall_predictor.data.dataset.dataset_guard_com_height_m`; the default is the
    ASIMO-like robot's). With ``mirror`` each training also learns from its trajectories'
    left-right mirror images (the test folds stay as recorded). With ``decision_thresholds``
    (boosted trees) each fold's model is also evaluated at each of them
    (:attr:`FoldFit.by_threshold`), from one pass of scores. With ``groups`` (one per trajectory)
    the folds are :func:`grouped_trajectory_folds` (at most ``folds``) instead.
    """
    from joblib import delayed
    from tqdm import tqdm

    tau_plus_values = [float(v) for v in tau_plus_values]
    tau_his_values = tuple(float(v) for v in tau_his_values)
    if not tau_plus_values or not tau_his_values:
        raise ValueError('need at least one tau_plus and one tau_his value')
    if any(not math.isfinite(v) for v in tau_plus_values):
        raise ValueError(f'tau_plus values must be finite, got {tau_plus_values}')
    if any(not (math.isfinite(v) and v >= 0.0) for v in tau_his_values):
        raise ValueError(f'tau_his values must be finite and >= 0, got {tau_his_values}')
    sample_stride = check_sample_stride(sample_stride)
    if groups is None:
        test_folds = stratified_trajectory_folds(trajectories, folds, seed)
    else:
        if len(groups) != len(trajectories):
            raise ValueError(f'{len(trajectories)} trajectories but {len(groups)} groups')
        test_folds = grouped_trajectory_folds(groups, folds, seed)
    all_index = np.arange(len(trajectories))
    tasks = []
    for n_train in train_sizes:
        for fold, test_index in enumerate(test_folds):
            train_index = np.setdiff1d(all_index, test_index)
            rng = np.random.default_rng([seed, fold, n_train or 0])
            chosen = _training_subset(train_index, trajectories, n_train, rng)
            for tau_plus_s in tau_plus_values:
                tasks.append((fold, tau_plus_s, n_train, chosen, test_index))

    with tempfile.TemporaryDirectory(prefix='fall_predictor_cv_') as folder:
        shared = _Trajectories(_shared_memory_view(trajectories, folder) if jobs > 1 else trajectories)
        outputs = compute_parallel(jobs, return_as='generator')(
            delayed(_fit_and_predict)(shared, chosen, test_index, tau_plus_s, learner, sample_stride,
                                      mirror, bool(decision_thresholds))
            for _, tau_plus_s, _, chosen, test_index in tasks)
        fits = []
        for (fold, tau_plus_s, n_train, chosen, test_index), output in tqdm(
                zip(tasks, outputs), total=len(tasks), desc='trainings', unit='fit',
                disable=not progress):
            atomic, rule_sizes, depths, fit_s, scores = output
            test = [trajectories[i] for i in test_index]
            size = float(np.mean(rule_sizes))
            results = evaluate_atomic(test, atomic, tau_his_values,
                                      guard_com_height_m=guard_com_height_m, mean_rule_size=size)
            by_threshold = {float(d): evaluate_atomic(test, [s > d for s in scores], tau_his_values,
                                                      guard_com_height_m=guard_com_height_m,
                                                      mean_rule_size=size)
                            for d in decision_thresholds}
            fits.append(FoldFit(fold, tau_plus_s, n_train, int(chosen.size), tuple(rule_sizes),
                                tuple(depths), fit_s, results, by_threshold))
    return fits


@dataclass(frozen=True)
class SweepPoint:
    """One (tau_plus, tau_his) predictor, cross-validated (times [s]).

    Rates and times are means over folds (the paper's convention; folds where a value is
    undefined are left out), ``*_std`` their population standard deviations; counts are
    totals over folds (each trajectory is tested once). ``mean_depth`` averages the number of
    rules over non-empty lists; ``n_train`` is the mean number of training trajectories.
    """

    tau_plus_s: float
    tau_his_s: float
    n_train: float
    fpr: float
    fpr_std: float
    tau_lead_s: float
    tau_lead_std_s: float
    lead_fraction: float
    oracle_lead_s: float
    mean_rule_size: float
    mean_depth: float
    n_balanced: int
    n_fallen: int
    n_false_positives: int
    n_missed: int
    n_pre_push_alarms_balanced: int
    n_pre_push_alarms_fallen: int
    per_fold: tuple[EvaluationResult, ...]

    @property
    def n_pre_push_alarms(self) -> int:
        return self.n_pre_push_alarms_balanced + self.n_pre_push_alarms_fallen


def aggregate_folds(fits: Sequence[FoldFit], tau_his_s: float) -> SweepPoint:
    """Combine the folds of one (training size, tau_plus) at one ``tau_his_s`` [s]."""
    if not fits or len({fit.tau_plus_s for fit in fits}) != 1:
        raise ValueError('aggregate_folds needs the fits of one tau_plus')
    results = [fit.results[float(tau_his_s)] for fit in fits]
    return SweepPoint(
        tau_plus_s=fits[0].tau_plus_s, tau_his_s=float(tau_his_s),
        n_train=float(np.mean([fit.n_train for fit in fits])),
        fpr=mean_or_nan([r.fpr for r in results]), fpr_std=std_or_nan([r.fpr for r in results]),
        tau_lead_s=mean_or_nan([r.tau_lead_s for r in results]),
        tau_lead_std_s=std_or_nan([r.tau_lead_s for r in results]),
        lead_fraction=mean_or_nan([r.lead_fraction for r in results]),
        oracle_lead_s=mean_or_nan([r.oracle_lead_s for r in results]),
        mean_rule_size=float(np.mean([fit.mean_rule_size for fit in fits])),
        mean_depth=float(np.mean([mean_nonempty_depth(fit.depths) for fit in fits])),
        n_balanced=sum(r.n_balanced for r in results), n_fallen=sum(r.n_fallen for r in results),
        n_false_positives=sum(r.n_false_positives for r in results),
        n_missed=sum(r.n_missed for r in results),
        n_pre_push_alarms_balanced=sum(r.n_pre_push_alarms_balanced for r in results),
        n_pre_push_alarms_fallen=sum(r.n_pre_push_alarms_fallen for r in results),
        per_fold=tuple(results))


def cross_validated_evaluation(trajectories: Sequence[TrajectoryFeatures],
                               learner: RuleListLearner, tau_plus_s: float,
                               tau_his_values: Sequence[float], folds: int = 10, seed: int = 0,
                               sample_stride: int = DEFAULT_SAMPLE_STRIDE, jobs: int = 1,
                               progress: bool = False,
                               guard_com_height_m: float = GUARD_COM_HEIGHT_M) -> list[SweepPoint]:
    """k-fold cross-validated method §5 metrics of one ``tau_plus_s`` [s], one point per
    ``tau_his`` in ``tau_his_values`` [s], with the CoM guard ``guard_com_height_m`` [m]
    (:func:`cross_validate_grid`)."""
    fits = cross_validate_grid(trajectories, learner, (tau_plus_s,), tau_his_values, folds, seed,
                               sample_stride, jobs=jobs, progress=progress,
                               guard_com_height_m=guard_com_height_m)
    return [aggregate_folds(fits, tau) for tau in tau_his_values]
