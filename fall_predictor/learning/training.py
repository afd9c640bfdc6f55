"""Training on a dataset (method §8): the learner registry, the sample stride, loading a dataset's
features (or several datasets' for one model, :func:`load_training_data`), training one decision
list per contact mode, and a summary of the learned rules.

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
import hashlib
import math
import os
import warnings
from dataclasses import dataclass
from pathlib import Path
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
                    attitude: bool = False, *, guard_com_height_m: Optional[float] = None,
                    robot_mass_kg: Optional[float] = None
                    ) -> tuple[PerModeDecisionLists, ModelMetadata]:
    """:func:`train_model` on a dataset already loaded (``report``, of ``data_dir``) with a
    learner from :func:`check_training_settings`. The model's CoM guard [m] and robot mass [kg]
    are ``data_dir``'s unless given (several datasets merged: :func:`train_on_data`)."""
    sample_stride = check_sample_stride(sample_stride)
    require_outcomes(report.trajectories, data_dir, need_balanced=False)
    lists = fit_strided(model_inputs(report.trajectories, attitude), tau_plus_s, learner,
                        sample_stride, mirror=mirror)
    # the time-to-fall trees and the robot mass (fall direction) ship in the model.
    from fall_predictor.data.dataset import dataset_guard_com_height_m, robot_total_mass_kg
    from fall_predictor.learning.time_to_fall_training import fit_time_to_fall
    time_to_fall = fit_time_to_fall(report.trajectories, sample_stride)
    if guard_com_height_m is None:
        guard_com_height_m = dataset_guard_com_height_m(data_dir)
    if robot_mass_kg is None:
        robot_mass_kg = robot_total_mass_kg(data_dir)
    metadata = ModelMetadata(
        tau_plus_s=float(tau_plus_s), balanced_weight=BALANCED_WEIGHT,
        falling_weight=FALLING_WEIGHT, learner_name=type(learner).__name__,
        learner_params=learner.get_params(), dataset_fingerprint=report.fingerprint,
        recommended_tau_his_s=recommended_tau_his_s, sample_stride=sample_stride,
        feature_settings=dataclasses.replace(report.settings, guard_com_height_m=guard_com_height_m),
        robot_mass_kg=robot_mass_kg,
        time_to_fall=time_to_fall, state=report.state, mirror=mirror)
    return lists, metadata


def train_on_data(data: TrainingData, tau_plus_s: float, learner: RuleListLearner,
                  sample_stride: int = DEFAULT_SAMPLE_STRIDE,
                  recommended_tau_his_s: Optional[float] = None, mirror: bool = False,
                  attitude: bool = False) -> tuple[PerModeDecisionLists, ModelMetadata]:
    """:func:`train_on_report` on the datasets of ``data`` merged (:func:`load_training_data`),
    with their common CoM guard and their mean robot mass; one dataset is trained on exactly
    as :func:`train_on_report` trains it."""
    return train_on_report(data.report, data.where, tau_plus_s, learner, sample_stride,
                           recommended_tau_his_s, mirror, attitude,
                           guard_com_height_m=data.guard_com_height_m,
                           robot_mass_kg=data.robot_mass_kg)


# -- several datasets, one model ------------------------------------------------------------------
#: The robot masses of datasets trained into one model may differ by this fraction at most (the
#: heaviest over the lightest): a model belongs to one robot.
MASS_AGREEMENT = 0.05


@dataclass(frozen=True)
class DatasetPart:
    """One dataset of a training set as loaded: its directory, the prefix of its trajectory ids
    in the merged set (``''``: the only dataset, ids as recorded), its own report, its robot's
    CoM guard [m] and mass [kg]."""

    data_dir: Path
    prefix: str
    report: LoadReport
    guard_com_height_m: float
    robot_mass_kg: float

    @property
    def n_trajectories(self) -> int:
        return len(self.report.trajectories)

    @property
    def n_fallen(self) -> int:
        return sum(bool(t.fallen) for t in self.report.trajectories)

    def to_json(self) -> dict[str, Any]:
        return {'data': str(self.data_dir), 'trajectory_id_prefix': self.prefix or None,
                'n_trajectories': self.n_trajectories, 'n_fallen': self.n_fallen,
                'unreadable': len(self.report.errors), 'unsettled': len(self.report.unsettled),
                'dataset_fingerprint': self.report.fingerprint, 'state': self.report.state,
                'guard_com_height_m': self.guard_com_height_m, 'robot_mass_kg': self.robot_mass_kg}


@dataclass(frozen=True)
class TrainingData:
    """The datasets one model is trained on (:func:`load_training_data`): each one's part, and
    their trajectories merged into one report (a single dataset's own report), the CoM guard
    [m] they share and their mean robot mass [kg]."""

    parts: tuple[DatasetPart, ...]
    report: LoadReport
    guard_com_height_m: float
    robot_mass_kg: float

    @property
    def where(self) -> str:
        """The datasets' directories, as messages name them."""
        return ', '.join(str(part.data_dir) for part in self.parts)


def combined_fingerprint(fingerprints: Sequence[str]) -> str:
    """The fingerprint of several datasets' fingerprints, in their order."""
    h = hashlib.sha256()
    for fingerprint in fingerprints:
        h.update(f'{fingerprint};'.encode())
    return h.hexdigest()[:16]


def _id_prefixes(data_dirs: Sequence[Path]) -> list[str]:
    """The trajectory-id prefix of each dataset: its directory's name, numbered by position
    (``2-name``) when two datasets' directories share a name."""
    names = [d.resolve().name or str(d) for d in data_dirs]
    if len(set(names)) == len(names):
        return names
    return [f'{k}-{name}' for k, name in enumerate(names, start=1)]


def _named_values(data_dirs: Sequence[Path], values: Sequence[Any], fmt=str) -> str:
    return ', '.join(f'{d}: {fmt(v)}' for d, v in zip(data_dirs, values))


def _check_agreement(data_dirs: Sequence[Path], states: Sequence[str], notes: Sequence[Optional[str]],
                     guards: Sequence[float], masses: Sequence[float]) -> None:
    """DatasetError, naming the datasets and their values, unless one model can be trained on
    them all: the same state, the same CoM guard, masses within :data:`MASS_AGREEMENT`."""
    if len(set(states)) > 1:
        why = ''.join(f'; {note}' for note in notes if note)
        raise DatasetError(f'the datasets give features from different states ('
                           f'{_named_values(data_dirs, states)}){why}: one model is trained on one '
                           'state (--state true, or datasets recorded alike)')
    if len(set(guards)) > 1:
        raise DatasetError(f'the datasets\' robots have different CoM guards ('
                           f'{_named_values(data_dirs, guards, lambda g: f"{g:g} m")}): a model runs '
                           'with one guard; train a model per robot')
    light, heavy = int(np.argmin(masses)), int(np.argmax(masses))
    if masses[heavy] > masses[light] * (1.0 + MASS_AGREEMENT):
        raise DatasetError(f'the datasets\' robots weigh {masses[light]:g} kg ({data_dirs[light]}) and '
                           f'{masses[heavy]:g} kg ({data_dirs[heavy]}), '
                           f'{100.0 * (masses[heavy] / masses[light] - 1.0):.0f} % apart: a model '
                           f'belongs to one robot (masses within {100.0 * MASS_AGREEMENT:g} %)')


def _merged_report(parts: Sequence[DatasetPart]) -> LoadReport:
    """The parts' reports as one: trajectory ids (and the keys of errors, unsettled and refused
    samples) prefixed with their dataset's prefix, so that two datasets' ``traj_00000`` stay two
    runs. DatasetError unless their features were computed with the same settings."""
    first = parts[0].report.settings
    if any(part.report.settings != first for part in parts):
        raise DatasetError('the datasets\' features were computed with different settings ('
                           + _named_values([p.data_dir for p in parts],
                                           [p.report.settings for p in parts]) + ')')

    def keyed(part: DatasetPart, by_id: dict[str, Any]) -> dict[str, Any]:
        return {f'{part.prefix}/{tid}': value for tid, value in by_id.items()}

    notes = [part.report.note for part in parts if part.report.note]
    return LoadReport(
        [dataclasses.replace(t, trajectory_id=f'{part.prefix}/{t.trajectory_id}')
         for part in parts for t in part.report.trajectories],
        {k: v for part in parts for k, v in keyed(part, part.report.errors).items()},
        sum(part.report.rebuilt for part in parts),
        combined_fingerprint([part.report.fingerprint for part in parts]), first,
        parts[0].report.state, '; '.join(notes) if notes else None,
        {k: v for part in parts for k, v in keyed(part, part.report.unsettled).items()},
        {k: v for part in parts for k, v in keyed(part, part.report.refused).items()})


def load_training_data(data_dirs: PathLike | Sequence[PathLike], jobs: int = 1,
                       skip_unreadable: bool = False, progress: bool = False,
                       state: str = 'true') -> TrainingData:
    """One or more datasets loaded for one model (:func:`load_dataset` each: its own feature
    cache, its own robot profile for estimation, ``skip_unreadable`` for each), their
    trajectories merged in the order given.

    What a model holds once must agree, checked before any features are computed: the
    ``state`` each dataset gives features from (:func:`~fall_predictor.data.dataset.resolve_state`),
    its robot's CoM guard, its robot's mass (within :data:`MASS_AGREEMENT`; the model stores
    their mean), and, once loaded, the feature settings; else DatasetError naming the
    datasets and their values. The same directory twice is refused too. With several
    datasets, trajectory ids are prefixed with their dataset's directory name
    (``name/traj_00042``, :func:`_merged_report`) and the fingerprint is that of theirs in
    order (:func:`combined_fingerprint`); one dataset is its report as loaded.
    """
    from fall_predictor.data.dataset import (dataset_guard_com_height_m, resolve_state,
                                             robot_total_mass_kg)

    dirs = [Path(data_dirs)] if isinstance(data_dirs, (str, os.PathLike)) else [Path(d) for d in data_dirs]
    if not dirs:
        raise ValueError('no dataset to train on')
    resolved = [d.resolve() for d in dirs]
    for k, d in enumerate(resolved):
        if d in resolved[:k]:
            raise DatasetError(f'{dirs[k]}: the same dataset given twice')
    states, notes = zip(*(resolve_state(d, state) for d in dirs))
    guards = [dataset_guard_com_height_m(d) for d in dirs]
    masses = [robot_total_mass_kg(d) for d in dirs]
    _check_agreement(dirs, states, notes, guards, masses)
    prefixes = _id_prefixes(dirs) if len(dirs) > 1 else ['']
    parts = tuple(DatasetPart(d, prefix, load_dataset(d, jobs, skip_unreadable, progress, s), guard, mass)
                  for d, prefix, s, guard, mass in zip(dirs, prefixes, states, guards, masses))
    if len(parts) == 1:
        return TrainingData(parts, parts[0].report, guards[0], masses[0])
    return TrainingData(parts, _merged_report(parts), guards[0], float(np.mean(masses)))


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
