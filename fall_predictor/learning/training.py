"""Training on a dataset (method §8): the learner registry, the sample stride, loading a dataset's
features, training one decision list per contact mode, and a summary of the learned rules.

Everything here is core library (no ROS) and importable by tests and scripts; the CLI
subcommands ``train`` and ``rules`` are thin wrappers.

**Sample stride.** The 1 kHz samples of a trajectory are near-duplicates of their neighbours,
so learners are trained on every ``sample_stride``-th sample of each trajectory (indices 0,
K, 2K, ... from its first sample) with both class weights multiplied by the stride: a kept
sample stands for the K milliseconds around it. The balanced:falling weighting per unit time
(4:1, method §8) is unchanged, and so is the meaning of hyper-parameters expressed in weight
(``CoveringListLearner.min_coverage``: falling milliseconds; a tree's
``min_weight_fraction_leaf``). Hyper-parameters counted in samples
(``TreeListLearner.min_samples_leaf``) count kept samples, i.e. K ms each. Evaluation always
runs at the full 1 kHz: the history window ``tau_his`` is a run-time parameter.
"""
from __future__ import annotations

import dataclasses
import math
import os
import warnings
from typing import Any, Mapping, Optional, Sequence

import numpy as np

from fall_predictor.data.dataset import DatasetError, LoadReport, load_features
from fall_predictor.learning.boosting import BoostedTreesLearner
from fall_predictor.learning.learners import (CoveringListLearner, RuleListLearner, TreeListLearner,
                                              fit_predictor)
from fall_predictor.monitor.decision_list import PerModeDecisionLists
from fall_predictor.monitor.model_file import ModelMetadata
from fall_predictor.monitor.records import (CONTACT_MODE_NAMES, N_INPUTS_WITH_ATTITUDE,
                                            TrajectoryFeatures)

PathLike = str | os.PathLike

# -- learners -------------------------------------------------------------------------------------
LEARNER_CLASSES: dict[str, type[RuleListLearner]] = {'tree': TreeListLearner,
                                                     'covering': CoveringListLearner,
                                                     'boosting': BoostedTreesLearner}

#: Hyper-parameters the experiments use unless told otherwise (on top of each learner's own
#: defaults), for training at :data:`DEFAULT_SAMPLE_STRIDE`. Chosen by 10-fold cross-validation
#: of the quick sweep grid (5 tau_plus x 9 tau_his) on 80 generated trajectories (seed 11),
#: scored by :func:`~fall_predictor.learning.selection.pareto_mean_lead`, then checked on 80
#: others (seed 12). Tree: max_depth in {6, 8, 12} x min_samples_leaf in {1, 2, 5, 20} scored
#: within 0.02 s of each other (fold spread 0.3 s); the best, depth 8 and 5 kept samples (50 ms
#: of trajectory) per leaf, also beat the learner's default 20 on the check set (1.00 s against
#: 0.94 s). Covering: no setting of min_coverage, max_conditions, min_precision, prune_fraction
#: or n_bins beat the learner's defaults on both sets, so they stay. Boosting: the learner's own
#: defaults (50 trees of depth 3, sized for the onboard budget, not tuned); its decision
#: threshold is chosen with tau_his by nested CV (benchmarks/bench_boosted_trees.py).
DEFAULT_LEARNER_PARAMS: dict[str, dict[str, Any]] = {
    'tree': {'max_depth': 8, 'min_samples_leaf': 5},
    'covering': {},
    'boosting': {},
}

#: Default training stride: every 10th 1 kHz sample, weights x10 (see the module docs).
DEFAULT_SAMPLE_STRIDE = 10
#: method §8 class weights per sample at 1 kHz (balanced : falling = 4 : 1).
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


def check_sample_stride(sample_stride: int) -> int:
    """``sample_stride`` as an int; ValueError unless it is an int >= 1."""
    if isinstance(sample_stride, bool) or not isinstance(sample_stride, (int, np.integer)) \
            or sample_stride < 1:
        raise ValueError(f'sample_stride must be an int >= 1, got {sample_stride!r}')
    return int(sample_stride)


def subsample(traj: TrajectoryFeatures, sample_stride: int) -> TrajectoryFeatures:
    """``traj`` with every ``sample_stride``-th sample (views, not copies), times unchanged."""
    sample_stride = check_sample_stride(sample_stride)
    if sample_stride == 1:
        return traj
    attitude = None if traj.attitude is None else traj.attitude[::sample_stride]
    return dataclasses.replace(traj, t=traj.t[::sample_stride], X=traj.X[::sample_stride],
                               mode=traj.mode[::sample_stride], attitude=attitude)


def model_inputs(trajectories: Sequence[TrajectoryFeatures], attitude: bool
                 ) -> list[TrajectoryFeatures]:
    """The trajectories as a model sees them: with ``attitude`` (a model's ``reads_attitude``),
    the base's attitude after the features
    (:meth:`~fall_predictor.monitor.records.TrajectoryFeatures.with_attitude_inputs`, method §8c)."""
    return [t.with_attitude_inputs() for t in trajectories] if attitude else list(trajectories)


def fit_strided(trajectories: Sequence[TrajectoryFeatures], tau_plus_s: float,
                learner: RuleListLearner, sample_stride: int = DEFAULT_SAMPLE_STRIDE,
                balanced_weight: float = BALANCED_WEIGHT,
                falling_weight: float = FALLING_WEIGHT, mirror: bool = False) -> PerModeDecisionLists:
    """:func:`~fall_predictor.learning.learners.fit_predictor` on every ``sample_stride``-th sample;
    with ``mirror``, on the trajectories and their left-right mirror images
    (:mod:`fall_predictor.learning.mirror`).

    The class weights (per 1 kHz sample) are multiplied by ``sample_stride`` so that the
    weight per second of trajectory, and so the 4:1 ratio per unit time, is unchanged.
    ``tau_plus_s`` [s] as in method §8.
    """
    sample_stride = check_sample_stride(sample_stride)
    if mirror:
        from fall_predictor.learning.mirror import with_mirror_images
        trajectories = with_mirror_images(trajectories)
    return fit_predictor([subsample(traj, sample_stride) for traj in trajectories], tau_plus_s,
                         learner, balanced_weight * sample_stride, falling_weight * sample_stride)


# -- datasets -------------------------------------------------------------------------------------
def load_dataset(data_dir: PathLike, jobs: int = 1, skip_unreadable: bool = False,
                 progress: bool = False, state: str = 'true') -> LoadReport:
    """Features of every trajectory of ``data_dir`` (from the feature cache when up to date),
    computed from its ``state`` (``'true'`` or ``'estimated'``, :mod:`fall_predictor.data.dataset`).

    Raises :class:`~fall_predictor.data.dataset.DatasetError` if the directory is not a usable
    dataset, or if some bags are unreadable and ``skip_unreadable`` is False (the message names
    them); with ``skip_unreadable`` they are left out (``LoadReport.errors`` lists them).
    Trajectories that had not settled when their recording ended are left out with a warning
    (:class:`UnsettledTrajectories`; ``LoadReport.unsettled`` lists them and why).
    """
    report = load_features(data_dir, jobs=jobs, progress=progress, state=state)
    if report.errors and not skip_unreadable:
        listed = '; '.join(f'{tid}: {error}' for tid, error in list(report.errors.items())[:5])
        more = f' (and {len(report.errors) - 5} more)' if len(report.errors) > 5 else ''
        raise DatasetError(f'{data_dir}: {len(report.errors)} unreadable bag(s): {listed}{more}')
    if report.unsettled:
        listed = '; '.join(f'{tid}: {why}' for tid, why in list(report.unsettled.items())[:3])
        warnings.warn(f'{data_dir}: {len(report.unsettled)} trajectory(ies) left out, not settled when '
                      f'their recording ended (method §4): {listed}', UnsettledTrajectories, stacklevel=2)
    if not report.trajectories:
        raise DatasetError(f'{data_dir}: no readable trajectory')
    return report


class UnsettledTrajectories(UserWarning):
    """Trajectories left out of a dataset as loaded: neither fallen nor settled at their
    horizon (:attr:`~fall_predictor.data.dataset.LoadReport.unsettled` names them)."""


def require_outcomes(trajectories: Sequence[TrajectoryFeatures], where: PathLike,
                     need_balanced: bool) -> None:
    """DatasetError (naming ``where``) unless some trajectory falls and, with
    ``need_balanced``, some does not."""
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
                progress: bool = False, state: str = 'true', mirror: bool = False,
                attitude: bool = False) -> tuple[PerModeDecisionLists, ModelMetadata]:
    """Train one decision list per contact mode on every trajectory of ``data_dir``.

    ``tau_plus_s`` [s] withholds falling states before ``t_height_drop + tau_plus_s``;
    ``learner_name``/``learner_params`` choose the learner (:func:`make_learner`);
    ``sample_stride`` as in :func:`fit_strided`; ``jobs`` processes load the features;
    ``recommended_tau_his_s`` [s] is stored in the metadata as the run-time default;
    ``state`` is the state the features come from (stored in the metadata as the one actually
    used, see :func:`~fall_predictor.data.dataset.resolve_state`); with ``mirror`` the lists
    also learn from every trajectory's left-right mirror image (:func:`fit_strided`); with
    ``attitude``, the classifiers also read the base's attitude (method §8c; boosted trees only).

    The model's feature settings are those the features were computed with, and the CoM guard of
    the dataset's robot (:func:`~fall_predictor.data.dataset.dataset_guard_com_height_m`): the
    guard the model is evaluated and run with.

    ``train`` chooses the window when not given one
    (:func:`~fall_predictor.learning.window_choice.train_choosing_window`).
    """
    learner = check_training_settings(tau_plus_s, learner_name, learner_params, recommended_tau_his_s,
                                      attitude)
    check_sample_stride(sample_stride)
    report = load_dataset(data_dir, jobs, skip_unreadable, progress, state)
    return train_on_report(report, data_dir, tau_plus_s, learner, sample_stride,
                           recommended_tau_his_s, mirror, attitude)


def check_training_settings(tau_plus_s: float, learner_name: str,
                            learner_params: Optional[Mapping[str, Any]],
                            recommended_tau_his_s: Optional[float], attitude: bool) -> RuleListLearner:
    """The learner of :func:`train_model`'s settings, or ValueError naming the one that cannot be
    used (checked before any data is read)."""
    if not math.isfinite(tau_plus_s):
        raise ValueError(f'tau_plus_s must be finite, got {tau_plus_s!r}')
    if recommended_tau_his_s is not None and not (math.isfinite(recommended_tau_his_s)
                                                  and recommended_tau_his_s >= 0.0):
        raise ValueError(f'recommended_tau_his_s must be >= 0, got {recommended_tau_his_s!r}')
    learner = make_learner(learner_name, learner_params)
    if attitude and N_INPUTS_WITH_ATTITUDE not in learner.input_sizes:
        raise ValueError(f'{learner_name}: this learner reads the 15 features only; the base\'s '
                         'attitude needs boosted trees (--learner boosting)')
    return learner


def train_on_report(report: LoadReport, data_dir: PathLike, tau_plus_s: float,
                    learner: RuleListLearner, sample_stride: int = DEFAULT_SAMPLE_STRIDE,
                    recommended_tau_his_s: Optional[float] = None, mirror: bool = False,
                    attitude: bool = False) -> tuple[PerModeDecisionLists, ModelMetadata]:
    """:func:`train_model` on a dataset already loaded (``report``, of ``data_dir``) with a
    learner from :func:`check_training_settings`."""
    sample_stride = check_sample_stride(sample_stride)
    require_outcomes(report.trajectories, data_dir, need_balanced=False)
    lists = fit_strided(model_inputs(report.trajectories, attitude), tau_plus_s, learner,
                        sample_stride, mirror=mirror)
    # the time-to-fall trees and the robot mass (fall direction) ship in the model.
    from fall_predictor.data.dataset import dataset_guard_com_height_m, robot_total_mass_kg
    from fall_predictor.learning.time_to_fall_training import fit_time_to_fall
    time_to_fall = fit_time_to_fall(report.trajectories, sample_stride)
    metadata = ModelMetadata(
        tau_plus_s=float(tau_plus_s), balanced_weight=BALANCED_WEIGHT,
        falling_weight=FALLING_WEIGHT, learner_name=type(learner).__name__,
        learner_params=learner.get_params(), dataset_fingerprint=report.fingerprint,
        recommended_tau_his_s=recommended_tau_his_s, sample_stride=sample_stride,
        feature_settings=dataclasses.replace(
            report.settings, guard_com_height_m=dataset_guard_com_height_m(data_dir)),
        robot_mass_kg=robot_total_mass_kg(data_dir),
        time_to_fall=time_to_fall, state=report.state, mirror=mirror)
    return lists, metadata


def rules_summary(lists: PerModeDecisionLists) -> dict[str, Any]:
    """Per contact mode: rule size, depth and the list in Fig. 8 form; plus the means.

    ``mean_rule_size`` averages over all 16 modes (method §8); ``mean_depth`` averages the
    number of rules over the non-empty lists only (the paper's "depths typically 5 to 10").
    """
    modes = [{'mode': name, 'rule_size': decision_list.rule_size, 'depth': decision_list.depth,
              'text': decision_list.format(mode_name=name)}
             for name, decision_list in zip(CONTACT_MODE_NAMES, lists.lists)]
    return {'modes': modes, 'mean_rule_size': lists.mean_rule_size,
            'mean_depth': mean_nonempty_depth(lists.depths),
            'max_depth': max(lists.depths)}


def mean_nonempty_depth(depths: Sequence[int]) -> float:
    """Mean number of rules over the non-empty lists (0 if all are empty)."""
    nonempty = [d for d in depths if d > 0]
    return float(np.mean(nonempty)) if nonempty else 0.0
