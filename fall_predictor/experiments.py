"""Experiments behind the command line (SPEC §5, §8, §9): training, evaluation and the sweep.

Everything here is core library (no ROS) and importable by tests and scripts; the CLI
subcommands ``train``, ``rules``, ``evaluate`` and ``sweep`` are thin wrappers.

**Sample stride.** The 1 kHz samples of a trajectory are near-duplicates of their neighbours,
so learners are trained on every ``sample_stride``-th sample of each trajectory (indices 0,
K, 2K, ... from its first sample) with both class weights multiplied by the stride: a kept
sample stands for the K milliseconds around it. The balanced:falling weighting per unit time
(4:1, SPEC §8) is unchanged, and so is the meaning of hyper-parameters expressed in weight
(``CoveringListLearner.min_coverage``: falling milliseconds; a tree's
``min_weight_fraction_leaf``). Hyper-parameters counted in samples
(``TreeListLearner.min_samples_leaf``) count kept samples, i.e. K ms each. Evaluation always
runs at the full 1 kHz: the history window ``tau_his`` is a run-time parameter.

**Sweep** (:func:`run_sweep`). k-fold cross-validation by trajectory (stratified by outcome,
a trajectory is never split) over a grid of ``tau_plus`` (training) and ``tau_his`` (run time):
one training per (fold, tau_plus); the test fold's atomic predictions are computed once and
every ``tau_his`` is evaluated from them. Fold results are averaged as the paper reports them.
The hand-coded baselines (CoM height, horizontal linear momentum, capture point) are
evaluated on the same trajectories. Outputs: ``sweep.json``, ``table.md`` and PNG figures
(Fig. 10 and Fig. 11 analogues and a learning curve).
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Optional, Sequence

import numpy as np

from fall_predictor.baselines import (CurvePoint, capture_point_curve, capture_point_distances,
                                      com_height_curve, momentum_curve, pareto_front)
from fall_predictor.dataset import (DatasetError, LoadReport, bag_fingerprint, load_features,
                                    read_index)
from fall_predictor.decision_list import PerModeDecisionLists
from fall_predictor.learning import (CoveringListLearner, RuleListLearner, TreeListLearner,
                                     fit_predictor)
from fall_predictor.metrics import (EvaluationResult, evaluate_atomic, evaluate_lists,
                                    stratified_trajectory_folds)
from fall_predictor.model_file import ModelMetadata
from fall_predictor.records import CONTACT_MODE_NAMES, FALLING, TrajectoryFeatures

PathLike = str | os.PathLike

# -- learners -------------------------------------------------------------------------------------
LEARNER_CLASSES: dict[str, type[RuleListLearner]] = {'tree': TreeListLearner,
                                                     'covering': CoveringListLearner}

#: Hyper-parameters the experiments use unless told otherwise (on top of each learner's own
#: defaults), for training at :data:`DEFAULT_SAMPLE_STRIDE`. Chosen by 10-fold cross-validation
#: of the quick sweep grid (5 tau_plus x 9 tau_his) on 80 generated trajectories (seed 11),
#: scored by :func:`pareto_mean_lead`, then checked on 80 others (seed 12). Tree: max_depth in
#: {6, 8, 12} x min_samples_leaf in {1, 2, 5, 20} scored within 0.02 s of each other (fold spread
#: 0.3 s); the best, depth 8 and 5 kept samples (50 ms of trajectory) per leaf, also beat the
#: learner's default 20 on the check set (1.00 s against 0.94 s). Covering: no setting of
#: min_coverage, max_conditions, min_precision, prune_fraction or n_bins beat the learner's
#: defaults on both sets, so they stay.
DEFAULT_LEARNER_PARAMS: dict[str, dict[str, Any]] = {
    'tree': {'max_depth': 8, 'min_samples_leaf': 5},
    'covering': {},
}

#: Default training stride: every 10th 1 kHz sample, weights x10 (see the module docs).
DEFAULT_SAMPLE_STRIDE = 10
#: SPEC §8 class weights per sample at 1 kHz (balanced : falling = 4 : 1).
BALANCED_WEIGHT = 4.0
FALLING_WEIGHT = 1.0


def make_learner(name: str, params: Optional[Mapping[str, Any]] = None) -> RuleListLearner:
    """A learner by name (``'tree'`` or ``'covering'``) with :data:`DEFAULT_LEARNER_PARAMS`
    overridden by ``params``.

    Raises ValueError on an unknown learner, an unknown hyper-parameter or an invalid value
    (checked now rather than at the first fit).
    """
    if name not in LEARNER_CLASSES:
        raise ValueError(f'unknown learner {name!r}; expected one of {sorted(LEARNER_CLASSES)}')
    cls = LEARNER_CLASSES[name]
    merged = {**DEFAULT_LEARNER_PARAMS[name], **dict(params or {})}
    known = set(cls().get_params())
    unknown = sorted(set(merged) - known)
    if unknown:
        raise ValueError(f'unknown hyper-parameter(s) {", ".join(unknown)} for learner {name!r}; '
                         f'known: {", ".join(sorted(known))}')
    learner = cls(**merged)
    learner.check_params()
    return learner


def _check_stride(sample_stride: int) -> int:
    if isinstance(sample_stride, bool) or not isinstance(sample_stride, (int, np.integer)) \
            or sample_stride < 1:
        raise ValueError(f'sample_stride must be an int >= 1, got {sample_stride!r}')
    return int(sample_stride)


def subsample(traj: TrajectoryFeatures, sample_stride: int) -> TrajectoryFeatures:
    """``traj`` with every ``sample_stride``-th sample (views, not copies), times unchanged."""
    sample_stride = _check_stride(sample_stride)
    if sample_stride == 1:
        return traj
    return dataclasses.replace(traj, t=traj.t[::sample_stride], X=traj.X[::sample_stride],
                               mode=traj.mode[::sample_stride])


def fit_strided(trajectories: Sequence[TrajectoryFeatures], tau_plus_s: float,
                learner: RuleListLearner, sample_stride: int = DEFAULT_SAMPLE_STRIDE,
                balanced_weight: float = BALANCED_WEIGHT,
                falling_weight: float = FALLING_WEIGHT) -> PerModeDecisionLists:
    """:func:`~fall_predictor.learning.fit_predictor` on every ``sample_stride``-th sample.

    The class weights (per 1 kHz sample) are multiplied by ``sample_stride`` so that the
    weight per second of trajectory, and so the 4:1 ratio per unit time, is unchanged.
    ``tau_plus_s`` [s] as in SPEC §8.
    """
    sample_stride = _check_stride(sample_stride)
    return fit_predictor([subsample(traj, sample_stride) for traj in trajectories], tau_plus_s,
                         learner, balanced_weight * sample_stride, falling_weight * sample_stride)


# -- datasets -------------------------------------------------------------------------------------
def load_dataset(data_dir: PathLike, jobs: int = 1, skip_unreadable: bool = False,
                 progress: bool = False) -> LoadReport:
    """Features of every trajectory of ``data_dir`` (from the feature cache when up to date).

    Raises :class:`~fall_predictor.dataset.DatasetError` if the directory is not a usable
    dataset, or if some bags are unreadable and ``skip_unreadable`` is False (the message names
    them); with ``skip_unreadable`` they are left out (``LoadReport.errors`` lists them).
    """
    report = load_features(data_dir, jobs=jobs, progress=progress)
    if report.errors and not skip_unreadable:
        listed = '; '.join(f'{tid}: {error}' for tid, error in list(report.errors.items())[:5])
        more = f' (and {len(report.errors) - 5} more)' if len(report.errors) > 5 else ''
        raise DatasetError(f'{data_dir}: {len(report.errors)} unreadable bag(s): {listed}{more}')
    if not report.trajectories:
        raise DatasetError(f'{data_dir}: no readable trajectory')
    return report


def _require_outcomes(trajectories: Sequence[TrajectoryFeatures], where: PathLike,
                      need_balanced: bool) -> None:
    n_fallen = sum(traj.fallen for traj in trajectories)
    if n_fallen == 0:
        raise DatasetError(f'{where}: no trajectory falls, there is nothing to learn')
    if need_balanced and n_fallen == len(trajectories):
        raise DatasetError(f'{where}: every trajectory falls; FPR is undefined')


# -- training -------------------------------------------------------------------------------------
def train_model(data_dir: PathLike, tau_plus_s: float, learner_name: str = 'tree',
                learner_params: Optional[Mapping[str, Any]] = None,
                sample_stride: int = DEFAULT_SAMPLE_STRIDE, jobs: int = 1,
                recommended_tau_his_s: Optional[float] = None, skip_unreadable: bool = False,
                progress: bool = False) -> tuple[PerModeDecisionLists, ModelMetadata]:
    """Train one decision list per contact mode on every trajectory of ``data_dir``.

    ``tau_plus_s`` [s] withholds falling states before ``t_height_drop + tau_plus_s``;
    ``learner_name``/``learner_params`` choose the learner (:func:`make_learner`);
    ``sample_stride`` as in :func:`fit_strided`; ``jobs`` processes load the features;
    ``recommended_tau_his_s`` [s] is stored in the metadata as the run-time default.
    """
    if not math.isfinite(tau_plus_s):
        raise ValueError(f'tau_plus_s must be finite, got {tau_plus_s!r}')
    if recommended_tau_his_s is not None and not (math.isfinite(recommended_tau_his_s)
                                                  and recommended_tau_his_s >= 0.0):
        raise ValueError(f'recommended_tau_his_s must be >= 0, got {recommended_tau_his_s!r}')
    learner = make_learner(learner_name, learner_params)
    sample_stride = _check_stride(sample_stride)
    report = load_dataset(data_dir, jobs, skip_unreadable, progress)
    _require_outcomes(report.trajectories, data_dir, need_balanced=False)
    lists = fit_strided(report.trajectories, tau_plus_s, learner, sample_stride)
    metadata = ModelMetadata(
        tau_plus_s=float(tau_plus_s), balanced_weight=BALANCED_WEIGHT,
        falling_weight=FALLING_WEIGHT, learner_name=type(learner).__name__,
        learner_params=learner.get_params(), dataset_fingerprint=report.fingerprint,
        recommended_tau_his_s=recommended_tau_his_s, sample_stride=sample_stride)
    return lists, metadata


def rules_summary(lists: PerModeDecisionLists) -> dict[str, Any]:
    """Per contact mode: rule size, depth and the list in Fig. 8 form; plus the means.

    ``mean_rule_size`` averages over all 16 modes (SPEC §8); ``mean_depth`` averages the
    number of rules over the non-empty lists only (the paper's "depths typically 5 to 10").
    """
    modes = [{'mode': name, 'rule_size': decision_list.rule_size, 'depth': decision_list.depth,
              'text': decision_list.format(mode_name=name)}
             for name, decision_list in zip(CONTACT_MODE_NAMES, lists.lists)]
    return {'modes': modes, 'mean_rule_size': lists.mean_rule_size,
            'mean_depth': _mean_nonempty_depth(lists.depths),
            'max_depth': max(lists.depths)}


def _mean_nonempty_depth(depths: Sequence[int]) -> float:
    nonempty = [d for d in depths if d > 0]
    return float(np.mean(nonempty)) if nonempty else 0.0


# -- baselines ------------------------------------------------------------------------------------
CAPTURE_POINT_CACHE_FORMAT = 'fall_predictor/capture-point-cache/v1'


def _capture_point_entry(data_dir: Path, bag: str, trajectory_id: str,
                         n_samples: int) -> tuple[np.ndarray, bool]:
    """Capture-point distances of one trajectory from its cache entry or its bag."""
    from fall_predictor.bagio import BagError, read_trajectory

    bag_dir = data_dir / bag
    cache = data_dir / 'cache' / f'cp_{trajectory_id}.npz'
    try:
        fingerprint = bag_fingerprint(bag_dir)
    except OSError as error:
        raise DatasetError(f'{bag_dir}: {error}') from error
    if cache.exists():
        try:
            with np.load(cache, allow_pickle=False) as z:
                if (str(z['format']) == CAPTURE_POINT_CACHE_FORMAT
                        and str(z['fingerprint']) == fingerprint and z['distance'].size == n_samples):
                    return z['distance'], False
        except (OSError, ValueError, KeyError):
            pass  # an unreadable entry is rebuilt from the bag
    try:
        recorded = read_trajectory(bag_dir)
    except BagError as error:
        raise DatasetError(str(error)) from error
    distance = capture_point_distances(recorded.measurements)
    if distance.size != n_samples:
        raise DatasetError(f'{bag_dir}: {distance.size} measurements but {n_samples} feature '
                           'samples; rebuild the feature cache')
    cache.parent.mkdir(exist_ok=True)
    temporary = cache.with_name(cache.stem + '.tmp.npz')
    np.savez(temporary, format=CAPTURE_POINT_CACHE_FORMAT, fingerprint=fingerprint,
             distance=distance)
    os.replace(temporary, cache)
    return distance, True


def capture_point_distances_cached(data_dir: PathLike, trajectories: Sequence[TrajectoryFeatures],
                                   jobs: int = 1, progress: bool = False) -> list[np.ndarray]:
    """Per trajectory, the capture point's signed distance [m] to the support polygon per sample.

    Computed from the bag's measurements (:func:`~fall_predictor.baselines.capture_point_distances`)
    once and cached as ``DATA/cache/cp_<trajectory id>.npz``, keyed by the bag fingerprint like
    the feature cache, so that sweeps do not read bags again.
    """
    from joblib import Parallel, delayed
    from tqdm import tqdm

    data_dir = Path(data_dir)
    bags = {row.trajectory_id: row.bag for row in read_index(data_dir)}
    missing = [traj.trajectory_id for traj in trajectories if traj.trajectory_id not in bags]
    if missing:
        raise DatasetError(f'{data_dir}: trajectories not in the index: {", ".join(missing[:5])}')
    entries = Parallel(n_jobs=jobs)(
        delayed(_capture_point_entry)(data_dir, bags[traj.trajectory_id], traj.trajectory_id,
                                      traj.t.size)
        for traj in tqdm(trajectories, desc='capture point', unit='traj', disable=not progress))
    return [distance for distance, _ in entries]


@dataclass(frozen=True)
class BaselineGrids:
    """Threshold grids of the hand-coded baselines (units: m, kg m/s, m)."""

    com_height_m: tuple[float, ...] = tuple(np.round(np.arange(0.40, 0.6001, 0.005), 4))
    momentum_sagittal: tuple[float, ...] = tuple(float(a) for a in range(4, 41, 3)) + (math.inf,)
    momentum_frontal: tuple[float, ...] = tuple(float(b) for b in range(4, 41, 3)) + (math.inf,)
    capture_point_margin_m: tuple[float, ...] = tuple(np.round(np.arange(-0.30, 0.1001, 0.01), 3))

    @classmethod
    def coarse(cls) -> BaselineGrids:
        """Fewer thresholds, for quick runs."""
        return cls(com_height_m=tuple(np.round(np.arange(0.40, 0.6001, 0.01), 3)),
                   momentum_sagittal=(6.0, 10.0, 14.0, 18.0, 24.0, 32.0, math.inf),
                   momentum_frontal=(6.0, 10.0, 14.0, 18.0, 24.0, 32.0, math.inf),
                   capture_point_margin_m=tuple(np.round(np.arange(-0.30, 0.1001, 0.04), 3)))


@dataclass(frozen=True)
class BaselineCurves:
    """Each baseline's points (one per threshold) over the same trajectories."""

    com_height: tuple[CurvePoint, ...]
    momentum: tuple[CurvePoint, ...]
    capture_point: tuple[CurvePoint, ...]    #: empty when no capture-point distances were given

    def named(self) -> dict[str, tuple[CurvePoint, ...]]:
        return {'com_height': self.com_height, 'momentum': self.momentum,
                'capture_point': self.capture_point}


def baseline_curves(trajectories: Sequence[TrajectoryFeatures],
                    capture_point: Optional[Sequence[np.ndarray]] = None,
                    grids: BaselineGrids = BaselineGrids()) -> BaselineCurves:
    """Evaluate the three hand-coded baselines over their threshold ``grids`` (CoM guard on,
    no history window, as in the paper)."""
    return BaselineCurves(
        com_height=tuple(com_height_curve(trajectories, grids.com_height_m)),
        momentum=tuple(momentum_curve(trajectories, grids.momentum_sagittal,
                                      grids.momentum_frontal)),
        capture_point=(() if capture_point is None else
                       tuple(capture_point_curve(trajectories, capture_point,
                                                 grids.capture_point_margin_m))))


def _curve_point_json(point: CurvePoint) -> dict[str, Any]:
    threshold = point.threshold
    return {'threshold': (list(_json_float(v) for v in threshold) if isinstance(threshold, tuple)
                          else _json_float(threshold)),
            **_evaluation_json(point.evaluation)}


# -- evaluation -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class ModelEvaluation:
    """A model evaluated on a dataset at one history window (times [s])."""

    result: EvaluationResult
    tau_his_s: float
    dataset_fingerprint: str
    unreadable: dict[str, str]             #: trajectories left out (unreadable bags)
    baselines: Optional[BaselineCurves] = None


def evaluate_model(data_dir: PathLike, lists: PerModeDecisionLists, tau_his_s: float,
                   baselines: bool = False, jobs: int = 1, skip_unreadable: bool = False,
                   progress: bool = False) -> ModelEvaluation:
    """SPEC §5 metrics of the predictor ``lists`` with history window ``tau_his_s`` [s] over
    every trajectory of ``data_dir``; with ``baselines``, the hand-coded baselines too.

    No cross-validation: use a dataset the model was not trained on (or :func:`run_sweep`).
    """
    if not (math.isfinite(tau_his_s) and tau_his_s >= 0.0):
        raise ValueError(f'tau_his_s must be a finite number >= 0, got {tau_his_s!r}')
    report = load_dataset(data_dir, jobs, skip_unreadable, progress)
    trajectories = report.trajectories
    result = evaluate_lists(trajectories, lists, (tau_his_s,))[float(tau_his_s)]
    curves = None
    if baselines:
        distances = capture_point_distances_cached(data_dir, trajectories, jobs, progress)
        curves = baseline_curves(trajectories, distances)
    return ModelEvaluation(result, float(tau_his_s), report.fingerprint, dict(report.errors), curves)


def _json_float(value: float) -> Optional[float]:
    """JSON has no NaN or infinity: those become null."""
    return float(value) if value is not None and math.isfinite(value) else None


def _evaluation_json(result: EvaluationResult) -> dict[str, Any]:
    return {key: (_json_float(value) if isinstance(value, float) else value)
            for key, value in dataclasses.asdict(result).items()}


def evaluation_json(evaluation: ModelEvaluation) -> dict[str, Any]:
    """``evaluation`` as a JSON-ready dict (NaN -> null); baselines as their Pareto fronts."""
    payload: dict[str, Any] = {
        'tau_his_s': evaluation.tau_his_s, **_evaluation_json(evaluation.result),
        'n_pre_push_alarms': evaluation.result.n_pre_push_alarms,
        'dataset_fingerprint': evaluation.dataset_fingerprint,
        'unreadable': evaluation.unreadable}
    if evaluation.baselines is not None:
        payload['baselines'] = {name: [_curve_point_json(p) for p in pareto_front(curve)]
                                for name, curve in evaluation.baselines.named().items()}
    return payload


# -- cross-validation -----------------------------------------------------------------------------
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

    @property
    def mean_rule_size(self) -> float:
        return float(np.mean(self.rule_sizes))


def _fit_and_predict(train: Sequence[TrajectoryFeatures], test: Sequence[TrajectoryFeatures],
                     tau_plus_s: float, learner: RuleListLearner, sample_stride: int
                     ) -> tuple[list[np.ndarray], tuple[int, ...], tuple[int, ...], float]:
    """Train on ``train``; atomic falling predictions (bool per sample) on ``test``."""
    start = time.perf_counter()
    lists = fit_strided(train, tau_plus_s, learner, sample_stride)
    fit_s = time.perf_counter() - start
    atomic = [lists.predict(traj.X, traj.mode) == FALLING for traj in test]
    return atomic, lists.rule_sizes, lists.depths, fit_s


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
                        progress: bool = False) -> list[FoldFit]:
    """k-fold cross-validation by trajectory over a grid: one training per (training size,
    tau_plus, fold), all ``tau_his_values`` [s] evaluated from its atomic predictions.

    Folds come from :func:`~fall_predictor.metrics.stratified_trajectory_folds` (``seed``).
    A training size ``n`` trains on ``n`` trajectories drawn from the other folds with their
    outcome mix (seeded by ``seed``, the fold and ``n``); ``None`` (or ``n`` at least the
    available count) trains on all of them. ``jobs`` trainings run in parallel processes.
    """
    from joblib import Parallel, delayed
    from tqdm import tqdm

    tau_plus_values = [float(v) for v in tau_plus_values]
    tau_his_values = tuple(float(v) for v in tau_his_values)
    if not tau_plus_values or not tau_his_values:
        raise ValueError('need at least one tau_plus and one tau_his value')
    if any(not math.isfinite(v) for v in tau_plus_values):
        raise ValueError(f'tau_plus values must be finite, got {tau_plus_values}')
    if any(not (math.isfinite(v) and v >= 0.0) for v in tau_his_values):
        raise ValueError(f'tau_his values must be finite and >= 0, got {tau_his_values}')
    sample_stride = _check_stride(sample_stride)
    test_folds = stratified_trajectory_folds(trajectories, folds, seed)
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
        shared = _shared_memory_view(trajectories, folder) if jobs > 1 else list(trajectories)
        outputs = Parallel(n_jobs=jobs, return_as='generator')(
            delayed(_fit_and_predict)([shared[i] for i in chosen], [shared[i] for i in test_index],
                                      tau_plus_s, learner, sample_stride)
            for _, tau_plus_s, _, chosen, test_index in tasks)
        fits = []
        for (fold, tau_plus_s, n_train, chosen, test_index), output in tqdm(
                zip(tasks, outputs), total=len(tasks), desc='trainings', unit='fit',
                disable=not progress):
            atomic, rule_sizes, depths, fit_s = output
            test = [trajectories[i] for i in test_index]
            results = evaluate_atomic(test, atomic, tau_his_values,
                                      mean_rule_size=float(np.mean(rule_sizes)))
            fits.append(FoldFit(fold, tau_plus_s, n_train, int(chosen.size), tuple(rule_sizes),
                                tuple(depths), fit_s, results))
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


def _nanmean(values: Sequence[float]) -> float:
    finite = [v for v in values if not math.isnan(v)]
    return float(np.mean(finite)) if finite else math.nan


def _nanstd(values: Sequence[float]) -> float:
    finite = [v for v in values if not math.isnan(v)]
    return float(np.std(finite)) if finite else math.nan


def aggregate_folds(fits: Sequence[FoldFit], tau_his_s: float) -> SweepPoint:
    """Combine the folds of one (training size, tau_plus) at one ``tau_his_s`` [s]."""
    if not fits or len({fit.tau_plus_s for fit in fits}) != 1:
        raise ValueError('aggregate_folds needs the fits of one tau_plus')
    results = [fit.results[float(tau_his_s)] for fit in fits]
    return SweepPoint(
        tau_plus_s=fits[0].tau_plus_s, tau_his_s=float(tau_his_s),
        n_train=float(np.mean([fit.n_train for fit in fits])),
        fpr=_nanmean([r.fpr for r in results]), fpr_std=_nanstd([r.fpr for r in results]),
        tau_lead_s=_nanmean([r.tau_lead_s for r in results]),
        tau_lead_std_s=_nanstd([r.tau_lead_s for r in results]),
        lead_fraction=_nanmean([r.lead_fraction for r in results]),
        oracle_lead_s=_nanmean([r.oracle_lead_s for r in results]),
        mean_rule_size=float(np.mean([fit.mean_rule_size for fit in fits])),
        mean_depth=float(np.mean([_mean_nonempty_depth(fit.depths) for fit in fits])),
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
                               progress: bool = False) -> list[SweepPoint]:
    """k-fold cross-validated SPEC §5 metrics of one ``tau_plus_s`` [s], one point per
    ``tau_his`` in ``tau_his_values`` [s]."""
    fits = cross_validate_grid(trajectories, learner, (tau_plus_s,), tau_his_values, folds, seed,
                               sample_stride, jobs=jobs, progress=progress)
    return [aggregate_folds(fits, tau) for tau in tau_his_values]


def _point_json(point: SweepPoint, with_folds: bool = True) -> dict[str, Any]:
    payload = {key: (_json_float(value) if isinstance(value, float) else value)
               for key, value in dataclasses.asdict(point).items() if key != 'per_fold'}
    payload['n_pre_push_alarms'] = point.n_pre_push_alarms
    if with_folds:
        payload['per_fold'] = [_evaluation_json(r) for r in point.per_fold]
    return payload


# -- the sweep ------------------------------------------------------------------------------------
#: SPEC §9's range of tau_plus [s] and the history windows [s] of the sweep.
DEFAULT_TAU_PLUS_VALUES_S = (-1.5, -1.25, -1.0, -0.75, -0.5, -0.25, 0.0, 0.25, 0.5)
DEFAULT_TAU_HIS_VALUES_S = (0.0, 0.004, 0.008, 0.016, 0.03, 0.044, 0.06, 0.08, 0.1)
#: Learning curve: training-set sizes (trajectories) at FP-L2's settings (SPEC §9).
DEFAULT_LEARNING_CURVE_SIZES = (50, 100, 250, 500, 900)
LEARNING_CURVE_TAU_PLUS_S = -0.25
LEARNING_CURVE_TAU_HIS_S = 0.06


@dataclass(frozen=True)
class PaperPredictor:
    """A predictor of the paper's Table 2 (SPEC §9); times [s]."""

    name: str
    tau_plus_s: float
    tau_his_s: float
    fpr: float
    tau_lead_s: float
    mean_rule_size: float


PAPER_PREDICTORS = (PaperPredictor('FP-L1', -0.30, 0.016, 0.46, 0.90, 61.6),
                    PaperPredictor('FP-L2', -0.25, 0.060, 0.06, 0.76, 51.4),
                    PaperPredictor('FP-L3', 0.30, 0.044, 0.005, 0.43, 5.3))

#: How the analogues of the paper's predictors are picked (written into table.md).
SELECTION_RULE = ('the Pareto-front predictor with the longest tau_lead among those whose '
                  'fold-mean FPR does not exceed the paper\'s FPR for that predictor (if none '
                  'does, the front\'s lowest-FPR predictor)')


#: FPR budgets over which :func:`pareto_mean_lead` averages: the paper's predictors lie within.
PARETO_MAX_FPR = 0.5


def pareto_mean_lead(points: Sequence[Any], max_fpr: float = PARETO_MAX_FPR) -> float:
    """One number for a family of predictors: the best tau_lead [s] reachable within an FPR
    budget, averaged over budgets uniform in ``[0, max_fpr]`` (a budget no predictor meets
    counts 0). The area under the Pareto front, divided by ``max_fpr``; higher is better.

    ``points``: anything with ``fpr`` and ``tau_lead_s`` (NaN points are ignored).
    """
    if not 0.0 < max_fpr <= 1.0:
        raise ValueError(f'max_fpr must be in (0, 1], got {max_fpr!r}')
    area, best_lead = 0.0, 0.0
    front = [p for p in pareto_front(points) if p.fpr < max_fpr]
    for point, next_fpr in zip(front, [p.fpr for p in front[1:]] + [max_fpr]):
        best_lead = max(best_lead, point.tau_lead_s)
        area += best_lead * (next_fpr - point.fpr)
    return area / max_fpr


def select_paper_analogues(points: Sequence[SweepPoint]) -> list[tuple[PaperPredictor, SweepPoint]]:
    """For each of :data:`PAPER_PREDICTORS`, the sweep point chosen by :data:`SELECTION_RULE`."""
    front = pareto_front(points)
    if not front:
        return []
    chosen = []
    for paper in PAPER_PREDICTORS:
        within = [p for p in front if p.fpr <= paper.fpr + 1e-12]
        chosen.append((paper, max(within, key=lambda p: p.tau_lead_s) if within else front[0]))
    return chosen


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
        _check_stride(self.sample_stride)
        make_learner(self.learner_name, self.learner_params)

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
                'baseline_grids': {k: [_json_float(v) for v in values] for k, values
                                   in dataclasses.asdict(self.baseline_grids).items()},
                'capture_point': self.capture_point}


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


def run_sweep(data_dir: PathLike, out_dir: PathLike, config: SweepConfig = SweepConfig(),
              jobs: int = 1, skip_unreadable: bool = False, progress: bool = False,
              command: Optional[str] = None) -> SweepResult:
    """Cross-validated sweep over ``config``'s tau_plus x tau_his grid, learning curve and
    baselines on the dataset ``data_dir``; writes ``sweep.json``, ``table.md`` and PNGs to
    ``out_dir`` and returns what it wrote.

    Trainings: ``folds`` x (number of tau_plus values + learning-curve sizes below the full
    training set); ``jobs`` processes run them (and load the features).
    """
    started = time.perf_counter()
    out_dir = Path(out_dir)
    report = load_dataset(data_dir, jobs, skip_unreadable, progress)
    trajectories = report.trajectories
    _require_outcomes(trajectories, data_dir, need_balanced=True)
    if len(trajectories) < config.folds:
        raise DatasetError(f'{data_dir}: {len(trajectories)} trajectories, fewer than '
                           f'{config.folds} folds')
    load_s = time.perf_counter() - started

    start = time.perf_counter()
    distances = (capture_point_distances_cached(data_dir, trajectories, jobs, progress)
                 if config.capture_point else None)
    capture_point_s = time.perf_counter() - start
    start = time.perf_counter()
    baselines = baseline_curves(trajectories, distances, config.baseline_grids)
    baselines_s = time.perf_counter() - start

    start = time.perf_counter()
    learner = make_learner(config.learner_name, config.learner_params)
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
        command=command,
        files=tuple(str(p) for p in figures)
        + (str(out_dir / 'sweep.json'), str(out_dir / 'table.md')))
    _write_text(out_dir / 'sweep.json', json.dumps(sweep_json(result), indent=1) + '\n')
    _write_text(out_dir / 'table.md', sweep_table(result))
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


def _write_text(path: Path, text: str) -> None:
    temporary = path.with_name(path.name + '.tmp')
    temporary.write_text(text)
    os.replace(temporary, path)


def sweep_json(result: SweepResult) -> dict[str, Any]:
    """The ``sweep.json`` document (NaN and infinity written as null)."""
    front = {(p.tau_plus_s, p.tau_his_s) for p in result.pareto}
    return {
        'format': 'fall_predictor/sweep/v1',
        'command': result.command,
        'dataset': {'path': result.data_dir, 'fingerprint': result.dataset_fingerprint,
                    'n_trajectories': result.n_trajectories, 'n_fallen': result.n_fallen,
                    'n_balanced': result.n_trajectories - result.n_fallen,
                    'unreadable': result.unreadable},
        'settings': result.config.as_json(),
        'points': [{**_point_json(p), 'pareto': (p.tau_plus_s, p.tau_his_s) in front}
                   for p in result.points],
        'selected': [{'name': paper.name, 'paper': dataclasses.asdict(paper),
                      'ours': _point_json(point, with_folds=False)}
                     for paper, point in result.selected],
        'selection_rule': SELECTION_RULE,
        'pareto_mean_lead_s': {
            'max_fpr': PARETO_MAX_FPR, 'learned': _json_float(pareto_mean_lead(result.points)),
            **{f'baseline_{name}': _json_float(pareto_mean_lead(curve))
               for name, curve in result.baselines.named().items()}},
        'learning_curve': [_point_json(p) for p in result.learning_curve],
        'trainings': [{'fold': fit.fold, 'tau_plus_s': fit.tau_plus_s, 'n_train': fit.n_train,
                       'fit_s': fit.fit_s, 'mean_rule_size': fit.mean_rule_size,
                       'rule_sizes': list(fit.rule_sizes), 'depths': list(fit.depths)}
                      for fit in result.fits],
        'baselines': {name: [_curve_point_json(p) for p in curve]
                      for name, curve in result.baselines.named().items()},
        'timing': dataclasses.asdict(result.timing),
        'files': list(result.files),
    }


def _fmt(value: Optional[float], digits: int = 3) -> str:
    return '—' if value is None or (isinstance(value, float) and math.isnan(value)) \
        else f'{value:.{digits}f}'


def sweep_table(result: SweepResult) -> str:
    """``table.md``: the Table 2 analogue next to the paper, then every point of the grid."""
    c = result.config
    lines = [
        '# Cross-validated sweep', '',
        f'Dataset `{result.data_dir}`: {result.n_trajectories} trajectories, {result.n_fallen} '
        f'fallen (fingerprint `{result.dataset_fingerprint}`). {c.folds}-fold cross-validation by '
        f'trajectory (seed {c.seed}); learner `{c.learner_name}` '
        f'{make_learner(c.learner_name, c.learner_params).get_params()}, sample stride '
        f'{c.sample_stride}. FPR, tau_lead and lead fraction are means over folds; misses and '
        'pre-push alarms are totals.' + (f' Command: `{result.command}`.' if result.command else ''), '',
        '## Table 2 analogue', '',
        f'Selection rule: {SELECTION_RULE}.', '',
        '| | ' + ' | '.join(f'{paper.name} (paper) | ours' for paper, _ in result.selected) + ' |',
        '|---|' + '---|---|' * len(result.selected)]
    rows = [('tau_plus [s]', lambda p: p.tau_plus_s, 2), ('tau_his [s]', lambda p: p.tau_his_s, 3),
            ('FPR', lambda p: p.fpr, 3), ('tau_lead [s]', lambda p: p.tau_lead_s, 2),
            ('mean rule size', lambda p: p.mean_rule_size, 1)]
    for label, get, digits in rows:
        lines.append(f'| {label} | ' + ' | '.join(f'{_fmt(get(paper), digits)} | {_fmt(get(point), digits)}'
                                                   for paper, point in result.selected) + ' |')
    lines.append('| misses / fallen | ' + ' | '.join(f'— | {p.n_missed}/{p.n_fallen}'
                                                     for _, p in result.selected) + ' |')
    lines.append('| lead fraction | ' + ' | '.join(f'— | {_fmt(p.lead_fraction, 2)}'
                                                   for _, p in result.selected) + ' |')
    lines += ['', f'Mean best tau_lead over FPR budgets in [0, {PARETO_MAX_FPR}] (area under the '
              f'Pareto front / {PARETO_MAX_FPR}): learned {_fmt(pareto_mean_lead(result.points))} s; '
              + ', '.join(f'{name} {_fmt(pareto_mean_lead(curve))} s'
                          for name, curve in result.baselines.named().items()) + '.',
              '', '## Baselines (Pareto fronts over their thresholds, all trajectories)', '',
              'Each threshold is one predictor evaluated on every trajectory (no cross-validation: '
              'the front picks thresholds in hindsight). Paper: CoM height at FPR 0 gives tau_lead '
              '0.14 s, tau_lead 0.42 s costs FPR 0.92; momentum thresholds at best FPR 0.11 with '
              'tau_lead 0.60 s.', '',
              '| baseline | threshold | FPR | tau_lead [s] | misses |', '|---|---|---|---|---|']
    for name, curve in result.baselines.named().items():
        for point in pareto_front(curve):
            threshold = point.threshold
            text = (', '.join(_fmt(v, 3) if math.isfinite(v) else 'inf' for v in threshold)
                    if isinstance(threshold, tuple) else _fmt(threshold, 3))
            lines.append(f'| {name} | {text} | {_fmt(point.fpr)} | {_fmt(point.tau_lead_s, 2)} | '
                         f'{point.evaluation.n_missed} |')
    if result.learning_curve:
        lines += ['', f'## Learning curve (tau_plus {c.learning_curve_tau_plus_s} s, tau_his '
                  f'{c.learning_curve_tau_his_s} s)', '',
                  '| training trajectories | FPR | tau_lead [s] | mean rule size |', '|---|---|---|---|']
        for p in result.learning_curve:
            lines.append(f'| {p.n_train:.0f} | {_fmt(p.fpr)} ± {_fmt(p.fpr_std)} | '
                         f'{_fmt(p.tau_lead_s, 2)} ± {_fmt(p.tau_lead_std_s, 2)} | '
                         f'{_fmt(p.mean_rule_size, 1)} |')
    front = {(p.tau_plus_s, p.tau_his_s) for p in result.pareto}
    lines += ['', '## All predictors (* = Pareto front)', '',
              '| tau_plus [s] | tau_his [s] | FPR | tau_lead [s] | misses | pre-push alarms | '
              'oracle lead [s] | lead fraction | mean rule size | mean depth |',
              '|---|---|---|---|---|---|---|---|---|---|']
    for p in result.points:
        star = '*' if (p.tau_plus_s, p.tau_his_s) in front else ''
        lines.append(f'| {p.tau_plus_s:+.2f}{star} | {p.tau_his_s:.3f} | {_fmt(p.fpr)} | '
                     f'{_fmt(p.tau_lead_s, 2)} | {p.n_missed} | {p.n_pre_push_alarms} | '
                     f'{_fmt(p.oracle_lead_s, 2)} | {_fmt(p.lead_fraction, 2)} | '
                     f'{_fmt(p.mean_rule_size, 1)} | {_fmt(p.mean_depth, 1)} |')
    t = result.timing
    lines += ['', f'Wall times: total {t.total_s:.0f} s with {t.jobs} job(s); loading {t.load_s:.0f} s, '
              f'capture point {t.capture_point_s:.0f} s, baselines {t.baselines_s:.0f} s, '
              f'cross-validation {t.cross_validation_s:.0f} s ({t.n_fits} trainings, mean full-size '
              f'fit {t.fit_s_mean_full:.2f} s), plots {t.plots_s:.0f} s.', '']
    return '\n'.join(lines)


# -- figures --------------------------------------------------------------------------------------
def plot_sweep(out_dir: Path, points: Sequence[SweepPoint], pareto: Sequence[SweepPoint],
               selected: Sequence[tuple[PaperPredictor, SweepPoint]],
               learning_curve: Sequence[SweepPoint], baselines: BaselineCurves,
               config: SweepConfig) -> list[Path]:
    """Write the sweep's PNGs: ``fig10_tradeoff.png`` (tau_lead against FPR for every
    predictor, the Pareto front, the baselines and the paper's FP-L1..3),
    ``fig11_parameters.png`` (FPR, tau_lead, rule size against tau_plus, a line per tau_his)
    and, with a learning curve, ``fig11_learning_curve.png``. Returns the paths."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    paths = []
    markers = ('o', 's', '^')
    # Fig. 10: trade-off.
    fig, ax = plt.subplots(figsize=(10.0, 5.5))
    tau_plus_values = sorted({p.tau_plus_s for p in points})
    colours = plt.cm.viridis(np.linspace(0.0, 0.9, len(tau_plus_values)))
    for colour, tau_plus in zip(colours, tau_plus_values):
        group = [p for p in points if p.tau_plus_s == tau_plus]
        ax.scatter([p.fpr for p in group], [p.tau_lead_s for p in group], s=14, color=colour,
                   label=f'learned, tau+ = {tau_plus:+.2f} s')
    # Fronts as steps: between two front points the better lead needs the higher FPR.
    ax.plot([p.fpr for p in pareto], [p.tau_lead_s for p in pareto], '-', color='k', lw=1.2,
            drawstyle='steps-post', label='Pareto front (learned)')
    for (name, curve), style, colour in zip(baselines.named().items(), ('--', ':', '-.'),
                                            ('tab:red', 'tab:orange', 'tab:brown')):
        front = pareto_front(curve)
        if front:
            ax.plot([p.fpr for p in front], [p.tau_lead_s for p in front], style, color=colour,
                    lw=1.3, drawstyle='steps-post',
                    label=f'baseline front: {name.replace("_", " ")}')
    for marker, (paper, ours) in zip(markers, selected):
        ax.scatter([paper.fpr], [paper.tau_lead_s], marker=marker, s=70, facecolors='none',
                   edgecolors='tab:blue', label=f'{paper.name} (paper)')
        ax.scatter([ours.fpr], [ours.tau_lead_s], marker=marker, s=70, color='tab:blue',
                   label=f'{paper.name} analogue')
    ax.set_xlim(-0.02, 1.02)
    ax.set_ylim(bottom=0.0)
    ax.set_xlabel('FPR (fraction of balanced trajectories with a false alarm)')
    ax.set_ylabel('tau_lead [s]')
    ax.set_title(f'Fig. 10 analogue: {config.folds}-fold cross-validated predictors')
    ax.legend(fontsize=7, loc='upper left', bbox_to_anchor=(1.01, 1.0))
    ax.grid(alpha=0.3)
    paths.append(out_dir / 'fig10_tradeoff.png')
    fig.tight_layout()
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)

    # Fig. 11 (left column): statistics against tau_plus.
    fig, axes = plt.subplots(3, 1, figsize=(6.5, 8.5), sharex=True)
    tau_his_values = sorted({p.tau_his_s for p in points})
    colours = plt.cm.plasma(np.linspace(0.0, 0.85, len(tau_his_values)))
    for colour, tau_his in zip(colours, tau_his_values):
        group = sorted((p for p in points if p.tau_his_s == tau_his), key=lambda p: p.tau_plus_s)
        x = [p.tau_plus_s for p in group]
        axes[0].plot(x, [p.fpr for p in group], '.-', color=colour, label=f'tau_his = {tau_his:g} s')
        axes[1].plot(x, [p.tau_lead_s for p in group], '.-', color=colour)
    by_tau_plus = {p.tau_plus_s: p.mean_rule_size for p in points}
    axes[2].plot(sorted(by_tau_plus), [by_tau_plus[k] for k in sorted(by_tau_plus)], '.-', color='k')
    for marker, (paper, ours) in zip(markers, selected):
        for ax, value in zip(axes, (ours.fpr, ours.tau_lead_s, ours.mean_rule_size)):
            ax.scatter([ours.tau_plus_s], [value], marker=marker, s=60, facecolors='none',
                       edgecolors='tab:blue', zorder=5)
        axes[0].annotate(paper.name, (ours.tau_plus_s, ours.fpr), fontsize=7,
                         textcoords='offset points', xytext=(4, 4))
    axes[0].set_ylabel('FPR')
    axes[1].set_ylabel('tau_lead [s]')
    axes[2].set_ylabel('mean rule size')
    axes[2].set_xlabel('tau_plus [s]')
    axes[0].legend(fontsize=6.5, ncol=2)
    axes[0].set_title('Fig. 11 analogue (rule size does not depend on tau_his)')
    for ax in axes:
        ax.grid(alpha=0.3)
    paths.append(out_dir / 'fig11_parameters.png')
    fig.tight_layout()
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)

    # Fig. 11 (right column): learning curve.
    if learning_curve:
        fig, axes = plt.subplots(3, 1, figsize=(5.5, 8.5), sharex=True)
        n = [p.n_train for p in learning_curve]
        axes[0].errorbar(n, [p.fpr for p in learning_curve],
                         yerr=[p.fpr_std for p in learning_curve], fmt='o-', capsize=3)
        axes[1].errorbar(n, [p.tau_lead_s for p in learning_curve],
                         yerr=[p.tau_lead_std_s for p in learning_curve], fmt='o-', capsize=3)
        axes[2].plot(n, [p.mean_rule_size for p in learning_curve], 'o-')
        axes[0].set_ylabel('FPR')
        axes[1].set_ylabel('tau_lead [s]')
        axes[2].set_ylabel('mean rule size')
        axes[2].set_xlabel('training trajectories')
        axes[0].set_title(f'learning curve: tau_plus {config.learning_curve_tau_plus_s} s, '
                          f'tau_his {config.learning_curve_tau_his_s} s')
        for ax in axes:
            ax.grid(alpha=0.3)
        paths.append(out_dir / 'fig11_learning_curve.png')
        fig.tight_layout()
        fig.savefig(paths[-1], dpi=110)
        plt.close(fig)
    return paths
