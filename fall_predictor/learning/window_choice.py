"""The history window ``tau_his`` a model is trained with, chosen on its training data.

A model file carries the window it runs with (``recommended_tau_his_s``: the monitor's and
``evaluate``'s default). The shipped models got theirs from nested cross-validation of a sweep
(method §11); a model trained on a robot's own recordings needs one as well, chosen the same way
and on its training data alone. :func:`choose_tau_his` does what a sweep does for one setting of
the training (learner, ``tau_plus``, stride, mirror images, attitude, the robot's CoM guard):

* k-fold cross-validation by trajectory
  (:func:`~fall_predictor.learning.crossval.cross_validate_grid`): one training per fold, every
  window of the sweep's grid (:data:`~fall_predictor.learning.sweep_results.DEFAULT_TAU_HIS_VALUES_S`)
  evaluated on the held-out fold. By default (``folds_by='cause_band'``) the folds are grouped
  by cause and push impulse band (:func:`~fall_predictor.learning.run_groups.fold_groups`, one
  band per fold): no fold is tested on a band or a cause its training saw. ``'outcome'``: the
  sweep's folds, stratified by outcome;
* the held-out folds pooled per window (false positives over balanced trajectories, leads over
  fallen ones: :func:`~fall_predictor.learning.nested.pool_results`);
* the rule for an operating point (:func:`~fall_predictor.learning.nested.choose_setting`): the
  longest pooled lead among the windows whose FPR is within the budget ``max_fpr`` (ties: the
  smaller window); if none is, the lowest FPR. By default (``fpr_rule='ucb'``) the FPR checked
  is the one-sided Wilson upper bound at ``fpr_level`` (95 %) of the pooled held-out FPR, so that
  the budget holds on runs the model never saw (method §11 "A budget that holds"); ``'point'``
  checks the pooled FPR itself, the choice a sweep makes over all its folds.

For boosted trees the decision threshold is the operating point's other half (method §8a):
given ``decision_thresholds``, each fold's model is scored once and evaluated at every threshold
and window, and the pair is chosen by the same rule (:func:`choose_operating_point`).

The default budget is FP-L2's, FPR <= 0.06 (method §9), the operating point of the shipped
default model. The cross-validation needs two falls (every training then holds one) and a run
that does not fall (an FPR); with fewer, the window cannot be chosen
(:class:`WindowNotChosen`): ``train`` then stores none and says why, and to give one
(``--tau-his``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Optional, Sequence

from sklearn.base import clone

from fall_predictor.data.dataset import LoadReport
from fall_predictor.learning.crossval import cross_validate_grid
from fall_predictor.learning.learners import RuleListLearner
from fall_predictor.learning.nested import (DEFAULT_FPR_LEVEL, PooledFigures, check_fpr_rule,
                                            choose_setting, fpr_bound, fpr_rule_text, pool_results,
                                            pooled_json)
from fall_predictor.learning.run_groups import disturbances, fold_groups
from fall_predictor.learning.selection import PAPER_PREDICTORS
from fall_predictor.learning.sweep_results import DEFAULT_TAU_HIS_VALUES_S, checked_tau_his_values
from fall_predictor.learning.training import (DEFAULT_SAMPLE_STRIDE, DatasetPart, PathLike,
                                              check_training_settings, load_training_data,
                                              model_inputs, require_outcomes, train_on_data)
from fall_predictor.monitor.decision_list import PerModeDecisionLists
from fall_predictor.monitor.model_file import ModelMetadata
from fall_predictor.monitor.records import GUARD_COM_HEIGHT_M, TrajectoryFeatures

#: The default FPR budget: FP-L2's (method §9).
DEFAULT_MAX_FPR = next(p.fpr for p in PAPER_PREDICTORS if p.name == 'FP-L2')
#: Cross-validation folds of the choice (fewer when there are fewer trajectories).
DEFAULT_FOLDS = 10
#: How the choice's folds are made (:class:`WindowSearch`).
FOLDS_BY = ('cause_band', 'outcome')


class WindowNotChosen(ValueError):
    """The training data cannot choose a window (too few falls or no run that does not fall)."""


@dataclass(frozen=True)
class WindowSearch:
    """How :func:`choose_tau_his` chooses: the FPR budget, the folds and their seed, the grid [s]."""

    max_fpr: float = DEFAULT_MAX_FPR
    folds: int = DEFAULT_FOLDS
    seed: int = 0
    tau_his_values_s: tuple[float, ...] = DEFAULT_TAU_HIS_VALUES_S
    #: Boosted trees: the decision thresholds [log-odds] chosen among with the window (empty:
    #: the model's own threshold, the window alone).
    decision_thresholds: tuple[float, ...] = ()
    #: How the budget is checked: on the FPR's upper confidence bound ('ucb') or the FPR ('point').
    fpr_rule: str = 'ucb'
    #: The level of the 'ucb' rule's one-sided Wilson bound.
    fpr_level: float = DEFAULT_FPR_LEVEL
    #: The folds: grouped by cause and push impulse band ('cause_band'), or stratified by
    #: outcome ('outcome').
    folds_by: str = 'cause_band'

    def __post_init__(self) -> None:
        if not 0.0 <= self.max_fpr <= 1.0:
            raise ValueError(f'max_fpr must be in [0, 1], got {self.max_fpr!r}')
        check_fpr_rule(self.fpr_rule, self.fpr_level)
        if self.folds_by not in FOLDS_BY:
            raise ValueError(f'folds_by is one of {", ".join(FOLDS_BY)}, got {self.folds_by!r}')
        if isinstance(self.folds, bool) or not isinstance(self.folds, int) or self.folds < 2:
            raise ValueError(f'folds must be an int >= 2, got {self.folds!r}')
        object.__setattr__(self, 'tau_his_values_s',
                           tuple(sorted(set(checked_tau_his_values(self.tau_his_values_s)))))
        thresholds = tuple(float(v) for v in self.decision_thresholds)
        if any(v != v for v in thresholds):
            raise ValueError('decision thresholds must be numbers')
        object.__setattr__(self, 'decision_thresholds', tuple(sorted(set(thresholds))))


@dataclass(frozen=True)
class WindowChoice:
    """The window chosen, and the cross-validated figures it was chosen on."""

    tau_his_s: float
    search: WindowSearch
    folds: int                                   #: the folds used (at most ``search.folds``)
    within_budget: bool                          #: its FPR (by ``search.fpr_rule``) meets ``search.max_fpr``
    per_window: dict[float, PooledFigures]       #: every window's pooled held-out figures
    #: Boosted trees with thresholds searched: the one chosen, and every (threshold, window)'s
    #: figures (``per_window`` is then the chosen threshold's).
    decision_threshold: Optional[float] = None
    per_setting: Optional[dict[tuple[float, float], PooledFigures]] = None

    @property
    def chosen(self) -> PooledFigures:
        return self.per_window[self.tau_his_s]

    def to_json(self) -> dict[str, Any]:
        what = 'window' if self.decision_threshold is None else '(decision threshold, window)'
        rule = fpr_rule_text(self.search.fpr_rule, self.search.fpr_level)
        out = {'tau_his_s': self.tau_his_s, 'rule': f'the longest cross-validated lead where {rule} '
               f'is <= {self.search.max_fpr:g} (else the lowest); ties: the smaller {what}',
               'max_fpr': self.search.max_fpr, 'fpr_rule': self.search.fpr_rule,
               'fpr_level': self.search.fpr_level, 'folds_by': self.search.folds_by,
               'folds': self.folds, 'seed': self.search.seed,
               'within_budget': self.within_budget,
               'chosen_fpr_bound': fpr_bound(self.chosen, self.search.fpr_rule, self.search.fpr_level),
               'chosen': pooled_json(self.chosen),
               'per_window': [{'tau_his_s': tau, **pooled_json(p)}
                              for tau, p in sorted(self.per_window.items())]}
        if self.decision_threshold is not None:
            out['decision_threshold'] = self.decision_threshold
            out['per_setting'] = [{'decision_threshold': d, 'tau_his_s': tau, **pooled_json(p)}
                                  for (d, tau), p in sorted(self.per_setting.items())]
        return out


def choose_tau_his(trajectories: Sequence[TrajectoryFeatures], learner: RuleListLearner,
                   tau_plus_s: float, search: WindowSearch = WindowSearch(),
                   sample_stride: int = DEFAULT_SAMPLE_STRIDE,
                   guard_com_height_m: float = GUARD_COM_HEIGHT_M, mirror: bool = False,
                   jobs: int = 1, progress: bool = False,
                   groups: Optional[Sequence] = None) -> WindowChoice:
    """The history window of a model trained with these settings on ``trajectories`` (module
    docs: the inputs as the model reads them, :func:`~fall_predictor.learning.training.model_inputs`).
    :class:`WindowNotChosen` when they hold fewer than two falls or no run that does not fall.
    With ``search.folds_by == 'cause_band'``, ``groups`` is each trajectory's fold group
    (:func:`~fall_predictor.learning.run_groups.fold_groups`; None: every trajectory a push of
    unknown impulse, its own group)."""
    n_fallen = sum(bool(t.fallen) for t in trajectories)
    n_balanced = len(trajectories) - n_fallen
    if n_fallen < 2 or n_balanced < 1:
        raise WindowNotChosen(f'tau_his cannot be chosen by cross-validation on {n_fallen} fallen and '
                              f'{n_balanced} balanced trajectories (it needs 2 fallen and 1 '
                              'balanced): give the window (--tau-his)')
    folds = min(search.folds, len(trajectories))
    if search.folds_by == 'cause_band':
        if groups is None:
            groups = [(i,) for i in range(len(trajectories))]
        elif len(groups) != len(trajectories):
            raise ValueError(f'{len(trajectories)} trajectories but {len(groups)} groups')
        folds = min(folds, len(set(groups)))
    else:
        groups = None
    fits = cross_validate_grid(trajectories, learner, (tau_plus_s,), search.tau_his_values_s, folds,
                               search.seed, sample_stride, jobs=jobs, progress=progress,
                               guard_com_height_m=guard_com_height_m, mirror=mirror,
                               decision_thresholds=search.decision_thresholds, groups=groups)
    rule = {'max_fpr': search.max_fpr, 'rule': search.fpr_rule, 'level': search.fpr_level}

    def within(figures: PooledFigures) -> bool:
        return fpr_bound(figures, search.fpr_rule, search.fpr_level) <= search.max_fpr + 1e-12

    if search.decision_thresholds:
        per_setting = {(d, tau): pool_results([fit.by_threshold[d][tau] for fit in fits])
                       for d in search.decision_thresholds for tau in search.tau_his_values_s}
        threshold, tau_his_s = choose_setting(per_setting, **rule)
        per_window = {tau: per_setting[threshold, tau] for tau in search.tau_his_values_s}
        return WindowChoice(tau_his_s, search, folds, within(per_window[tau_his_s]), per_window,
                            threshold, per_setting)
    per_window = {tau: pool_results([fit.results[tau] for fit in fits])
                  for tau in search.tau_his_values_s}
    _, tau_his_s = choose_setting({(float(tau_plus_s), tau): figures
                                   for tau, figures in per_window.items()}, **rule)
    return WindowChoice(tau_his_s, search, folds, within(per_window[tau_his_s]), per_window)


#: The name the choice goes by when it includes a boosted model's decision threshold.
choose_operating_point = choose_tau_his


@dataclass(frozen=True)
class TrainedModel:
    """What ``train`` made: the model, its metadata, how its window was chosen (None: given, or
    not chosen: ``not_chosen`` says why), the datasets as loaded and merged (``report``), and
    each dataset's part of them (``datasets``, in the order given)."""

    lists: PerModeDecisionLists
    metadata: ModelMetadata
    window: Optional[WindowChoice]
    report: LoadReport
    not_chosen: Optional[str] = None
    datasets: tuple[DatasetPart, ...] = ()


def training_groups(data: Any, bands: int) -> list[tuple]:
    """Each trajectory's fold group (:func:`~fall_predictor.learning.run_groups.fold_groups`,
    ``bands`` push impulse bands) over every dataset of a training set, from their indexes."""
    from fall_predictor.data.dataset import read_index

    runs = {}
    for part in data.parts:
        runs.update(disturbances(read_index(part.data_dir), part.prefix))
    return fold_groups([t.trajectory_id for t in data.report.trajectories], runs, bands)


def train_choosing_window(data_dir: PathLike | Sequence[PathLike], tau_plus_s: float,
                          learner_name: str = 'tree',
                          learner_params: Optional[Mapping[str, Any]] = None,
                          sample_stride: int = DEFAULT_SAMPLE_STRIDE, jobs: int = 1,
                          tau_his_s: Optional[float] = None, search: WindowSearch = WindowSearch(),
                          skip_unreadable: bool = False, progress: bool = False,
                          state: str = 'true', mirror: bool = False,
                          attitude: bool = False) -> TrainedModel:
    """:func:`~fall_predictor.learning.training.train_model` with the model's window stored:
    ``tau_his_s`` [s] when given, else the one :func:`choose_tau_his` chooses on the same data
    (the dataset is loaded once); none when it cannot choose (:attr:`TrainedModel.not_chosen`).

    ``data_dir`` may be several datasets: one model is trained on all their trajectories
    (:func:`~fall_predictor.learning.training.load_training_data`: what must agree between
    them, trajectory ids kept apart), and the window is chosen by cross-validation over all of
    them, every trajectory a run of its own."""
    learner = check_training_settings(tau_plus_s, learner_name, learner_params, tau_his_s, attitude)
    if search.decision_thresholds and learner_name != 'boosting':
        raise ValueError('decision thresholds are chosen for boosted trees only (--learner boosting)')
    data = load_training_data(data_dir, jobs, skip_unreadable, progress, state)
    report = data.report
    require_outcomes(report.trajectories, data.where, need_balanced=False)
    window, not_chosen = None, None
    if tau_his_s is None:
        try:
            window = choose_tau_his(model_inputs(report.trajectories, attitude), learner, tau_plus_s,
                                    search, sample_stride, data.guard_com_height_m,
                                    mirror, jobs, progress, training_groups(data, search.folds))
            tau_his_s = window.tau_his_s
        except WindowNotChosen as why:
            not_chosen = str(why)
    if window is not None and window.decision_threshold is not None:
        # The model file records the threshold it runs with among its learner's settings (the
        # threshold does not change the fit).
        learner = clone(learner).set_params(decision_threshold=window.decision_threshold)
    lists, metadata = train_on_data(data, tau_plus_s, learner, sample_stride, tau_his_s, mirror,
                                    attitude)
    if window is not None and window.decision_threshold is not None:
        lists = lists.with_decision_threshold(window.decision_threshold)
    return TrainedModel(lists, metadata, window, report, not_chosen, data.parts)
