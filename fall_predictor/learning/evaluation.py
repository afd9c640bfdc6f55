"""Evaluating a trained model on a dataset (method §5), the hand-coded baselines next to it, and
their JSON form.

:func:`evaluate_model` runs a model over every trajectory of a dataset (no cross-validation:
see :mod:`fall_predictor.learning.crossval`); :func:`baseline_curves` evaluates the CoM-height,
momentum and capture-point baselines over threshold grids. The capture point's distances are
computed with the features and kept in the feature cache
(:func:`capture_point_distances_cached`). The CLI
subcommand ``evaluate`` is a thin wrapper; its per-run rows are
:mod:`fall_predictor.learning.per_run`'s, from the same alarms.

Samples the estimator or the feature extractor refused are holes, as onboard
(:mod:`fall_predictor.data.dataset`): :class:`ModelEvaluation` counts them (``refused``).

JSON has no NaN or infinity: :func:`json_float` writes them as null.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional, Sequence

import numpy as np

from fall_predictor.data.dataset import (PUSH_UNKNOWN, DatasetError, RefusedSamples,
                                         dataset_guard_com_height_m, is_robot_recordings,
                                         push_time_known, read_index, read_manifest)
from fall_predictor.learning.baselines import (CurvePoint, capture_point_curve, com_height_curve,
                                               momentum_curve, pareto_front)
from fall_predictor.learning.deployment import (DEFAULT_BAND_WIDTH_NS, deployment_figures,
                                                run_outcomes)
from fall_predictor.learning.metrics import EvaluationResult, evaluate_lists
from fall_predictor.learning.per_run import RunRecord, run_records
from fall_predictor.learning.run_groups import RunDisturbance, disturbances
from fall_predictor.learning.training import PathLike, load_dataset, model_inputs
from fall_predictor.monitor.decision_list import PerModeDecisionLists
from fall_predictor.monitor.records import GUARD_COM_HEIGHT_M, TrajectoryFeatures


# -- the capture point's distances, cached -------------------------------------------------------
def _capture_point_entry(data_dir: Path, row: Any, n_samples: int, state: str) -> np.ndarray:
    """Capture-point distances of one trajectory, from its feature cache entry."""
    from fall_predictor.data.bagio import BagError
    from fall_predictor.data.dataset import cached_feature_arrays

    try:
        arrays, _ = cached_feature_arrays(data_dir, row, state=state)
    except OSError as error:
        raise DatasetError(f'{data_dir / row.bag}: {error}') from error
    except BagError as error:
        raise DatasetError(str(error)) from error
    distance = arrays['cp_distance_m']
    if distance.size != n_samples:
        raise DatasetError(f'{data_dir / row.bag}: {distance.size} capture-point samples but '
                           f'{n_samples} feature samples')
    if np.isnan(distance).all():
        raise DatasetError(f'{data_dir}: dataset.json does not give the robot\'s total mass; '
                           'the capture point needs it')
    return distance


def capture_point_distances_cached(data_dir: PathLike, trajectories: Sequence[TrajectoryFeatures],
                                   jobs: int = 1, progress: bool = False, state: str = 'true'
                                   ) -> list[np.ndarray]:
    """Per trajectory, the capture point's signed distance [m] to the support polygon per sample.

    Computed with the features from the same ``state``
    (:func:`~fall_predictor.monitor.capture_point.capture_point_distances`) and kept in the
    feature cache (:func:`~fall_predictor.data.dataset.cached_feature_arrays`), so that sweeps
    do not read bags again.
    """
    from joblib import delayed
    from tqdm import tqdm

    from fall_predictor.data.parallel import local_parallel

    data_dir = Path(data_dir)
    rows = {row.trajectory_id: row for row in read_index(data_dir)}
    missing = [traj.trajectory_id for traj in trajectories if traj.trajectory_id not in rows]
    if missing:
        raise DatasetError(f'{data_dir}: trajectories not in the index: {", ".join(missing[:5])}')
    return local_parallel(jobs)(
        delayed(_capture_point_entry)(data_dir, rows[traj.trajectory_id], traj.t.size, state)
        for traj in tqdm(trajectories, desc='capture point', unit='traj', disable=not progress))


# -- baselines ------------------------------------------------------------------------------------
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
                    grids: BaselineGrids = BaselineGrids(),
                    guard_com_height_m: float = GUARD_COM_HEIGHT_M) -> BaselineCurves:
    """Evaluate the three hand-coded baselines over their threshold ``grids`` (CoM guard on at
    ``guard_com_height_m`` [m], the robot's; no history window, as in the paper)."""
    guard = {'guard_com_height_m': guard_com_height_m}
    return BaselineCurves(
        com_height=tuple(com_height_curve(trajectories, grids.com_height_m, **guard)),
        momentum=tuple(momentum_curve(trajectories, grids.momentum_sagittal,
                                      grids.momentum_frontal, **guard)),
        capture_point=(() if capture_point is None else
                       tuple(capture_point_curve(trajectories, capture_point,
                                                 grids.capture_point_margin_m, **guard))))


# -- JSON -----------------------------------------------------------------------------------------
def json_float(value: float) -> Optional[float]:
    """JSON has no NaN or infinity: those become null."""
    return float(value) if value is not None and math.isfinite(value) else None


def _json_value(value: Any) -> Any:
    if isinstance(value, float):
        return json_float(value)
    if isinstance(value, tuple):
        return [_json_value(v) for v in value]
    return value


def evaluation_result_json(result: EvaluationResult) -> dict[str, Any]:
    """The fields of ``result`` (NaN and infinity -> null; intervals as ``[low, high]``), plus the
    short names of the method §11 figures: ``misses_lists_only`` and ``tau_lead_lists_only``."""
    payload = {key: _json_value(value) for key, value in dataclasses.asdict(result).items()
               if key not in ('leads_s', 'alarms')}
    payload['misses_lists_only'] = result.n_missed_lists_only
    payload['tau_lead_lists_only'] = json_float(result.tau_lead_lists_only_s)
    return payload


def curve_point_json(point: CurvePoint) -> dict[str, Any]:
    """A baseline's point: its threshold(s) and its metrics (NaN and infinity -> null)."""
    threshold = point.threshold
    return {'threshold': (list(json_float(v) for v in threshold) if isinstance(threshold, tuple)
                          else json_float(threshold)),
            **evaluation_result_json(point.evaluation)}


# -- evaluation -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class ModelEvaluation:
    """A model evaluated on a dataset at one history window (times [s])."""

    result: EvaluationResult
    tau_his_s: float
    dataset_fingerprint: str
    unreadable: dict[str, str]             #: trajectories left out (unreadable bags)
    baselines: Optional[BaselineCurves] = None
    #: |predicted - true| time to fall [s] at the triggers: {median, p90, max, n}
    time_to_fall_error_s: Optional[dict[str, Any]] = None
    #: the model's fall direction's angular error [deg] at the triggers: {median, p90, max, n}
    #: (its learned direction, else the momentum's: ``fall_direction``)
    direction_error_deg: Optional[dict[str, Any]] = None
    #: the same for the capture-point direction (the physical default, less accurate here)
    direction_error_deg_capture_point: Optional[dict[str, Any]] = None
    #: the CoM guard [m] the model and the baselines were evaluated with (:func:`evaluate_model`)
    guard_com_height_m: float = GUARD_COM_HEIGHT_M
    #: trajectories left out: not fallen, not settled at their horizon (id -> why; method §4)
    unsettled: dict[str, str] = field(default_factory=dict)
    #: the same for the momentum's direction (the model's own when it has no learned one)
    direction_error_deg_momentum: Optional[dict[str, Any]] = None
    #: which direction ``direction_error_deg`` is: 'learned' or 'momentum'
    fall_direction: str = 'momentum'
    #: trajectory id -> the samples left out of it as holes, for those with any
    refused: dict[str, RefusedSamples] = field(default_factory=dict)
    #: per trajectory evaluated (the result's order): where its push time comes from
    #: (``'unknown'``: none; :func:`push_sources`)
    push_sources: dict[str, str] = field(default_factory=dict)
    #: the trajectories as evaluated, in the result's order (the per-run rows)
    trajectories: tuple[TrajectoryFeatures, ...] = ()
    #: per trajectory id, what disturbed it (cause, onset, a push's impulse) from the index
    runs: dict[str, RunDisturbance] = field(default_factory=dict)

    @property
    def refused_total(self) -> RefusedSamples:
        """The refused samples of all the trajectories evaluated, summed."""
        return RefusedSamples.summed(self.refused.values())

    def run_records(self) -> list[RunRecord]:
        """One :class:`~fall_predictor.learning.per_run.RunRecord` per trajectory evaluated."""
        return run_records(self.trajectories, self.result.alarms, self.push_sources, self.refused,
                           {tid: run.cause for tid, run in self.runs.items()})

    def deployment(self, band_width_ns: float = DEFAULT_BAND_WIDTH_NS) -> dict[str, Any]:
        """The deployer's figures: per cause, per hour of walking, per push impulse band
        (:mod:`fall_predictor.learning.deployment`)."""
        return deployment_figures(run_outcomes(self.trajectories, self.result.alarms, self.runs),
                                  band_width_ns)


def push_sources(data_dir: PathLike) -> dict[str, str]:
    """Per trajectory id, where its push time comes from: the index row's ``push_source``,
    ``'simulation'`` for a dataset's own (simulated or recorded) pushes, ``'unknown'`` where the
    recording's start stands in for it (:func:`~fall_predictor.data.dataset.push_time_known`)."""
    robot = is_robot_recordings(read_manifest(data_dir))
    return {row.trajectory_id: (row.push_source or 'simulation') if push_time_known(row, robot)
            else PUSH_UNKNOWN for row in read_index(data_dir)}


def evaluate_model(data_dir: PathLike, lists: PerModeDecisionLists, tau_his_s: float,
                   baselines: bool = False, jobs: int = 1, skip_unreadable: bool = False,
                   progress: bool = False, time_to_fall: Optional[Any] = None,
                   robot_mass_kg: Optional[float] = None, state: str = 'true',
                   guard_com_height_m: Optional[float] = None,
                   fall_direction: Optional[Any] = None) -> ModelEvaluation:
    """method §5 metrics of the predictor ``lists`` with history window ``tau_his_s`` [s] over
    every trajectory of ``data_dir``; with ``baselines``, the hand-coded baselines too.
    With a ``time_to_fall`` regressor and/or ``robot_mass_kg`` [kg], the time-to-fall and
    fall-direction errors at the triggers (:mod:`fall_predictor.learning.when_where`): the
    ``fall_direction`` (the model's learned one) when given, else the momentum's.
    ``state``: the features come from the true or the estimated state (data/dataset.py).

    The CoM guard is the model's, as on the robot, where the monitor runs a model with the
    feature settings it records: pass its ``feature_settings.guard_com_height_m`` [m] (the CLI
    does, as it passes the model's ``time_to_fall`` and ``robot_mass_kg``); None (lists without a
    model file) is the guard of the dataset's robot
    (:func:`~fall_predictor.data.dataset.dataset_guard_com_height_m`), the one a model trained on
    that dataset records. The baselines and the triggers use the same guard.

    A model that reads the base's attitude (method §8c) gets it after the features.

    No cross-validation: use a dataset the model was not trained on (or
    :func:`~fall_predictor.learning.sweep.compute_sweep`).
    """
    if not (math.isfinite(tau_his_s) and tau_his_s >= 0.0):
        raise ValueError(f'tau_his_s must be a finite number >= 0, got {tau_his_s!r}')
    guard = (dataset_guard_com_height_m(data_dir) if guard_com_height_m is None
             else float(guard_com_height_m))
    report = load_dataset(data_dir, jobs, skip_unreadable, progress, state)
    trajectories = model_inputs(report.trajectories, lists.reads_attitude)
    result = evaluate_lists(trajectories, lists, (tau_his_s,), guard_com_height_m=guard,
                            keep_alarms=True)[float(tau_his_s)]
    curves = None
    if baselines:
        distances = capture_point_distances_cached(data_dir, trajectories, jobs, progress, state)
        curves = baseline_curves(trajectories, distances, guard_com_height_m=guard)
    ttf_error = direction_error = cp_error = momentum_error = None
    if time_to_fall is not None or robot_mass_kg is not None:
        from fall_predictor.learning import when_where
        triggers = when_where.trigger_indices(trajectories, lists, tau_his_s, guard)
        if time_to_fall is not None:
            ttf_error = when_where.summary(
                when_where.time_to_fall_errors(trajectories, triggers, time_to_fall))
        if robot_mass_kg is not None:
            samples = when_where.direction_samples(data_dir, trajectories, triggers)
            momentum_error, cp_error = (when_where.summary(when_where.direction_errors_deg(
                samples, name, robot_mass_kg)) for name in ('momentum', 'capture_point'))
            direction_error = momentum_error if fall_direction is None else when_where.summary(
                when_where.direction_errors_deg(samples, fall_direction.direction, robot_mass_kg))
    return ModelEvaluation(result, float(tau_his_s), report.fingerprint, dict(report.errors),
                           curves, ttf_error, direction_error, cp_error, guard,
                           dict(report.unsettled), momentum_error,
                           'momentum' if fall_direction is None else 'learned',
                           dict(report.refused), push_sources(data_dir), tuple(trajectories),
                           disturbances(read_index(data_dir)))


def evaluation_json(evaluation: ModelEvaluation,
                    band_width_ns: float = DEFAULT_BAND_WIDTH_NS) -> dict[str, Any]:
    """``evaluation`` as a JSON-ready dict (NaN -> null); baselines as their Pareto fronts;
    ``deployment``: per cause, per hour of walking, per push impulse band of ``band_width_ns``
    [N s] (:meth:`ModelEvaluation.deployment`)."""
    payload: dict[str, Any] = {
        'tau_his_s': evaluation.tau_his_s, 'guard_com_height_m': evaluation.guard_com_height_m,
        **evaluation_result_json(evaluation.result),
        'n_pre_push_alarms': evaluation.result.n_pre_push_alarms,
        'dataset_fingerprint': evaluation.dataset_fingerprint,
        'unreadable': evaluation.unreadable,
        'unsettled_left_out': evaluation.unsettled,
        'time_to_fall_error_s': evaluation.time_to_fall_error_s,
        'direction_error_deg': evaluation.direction_error_deg,
        'direction_error_deg_capture_point': evaluation.direction_error_deg_capture_point,
        'direction_error_deg_momentum': evaluation.direction_error_deg_momentum,
        'fall_direction': evaluation.fall_direction,
        'refused_samples': evaluation.refused_total.total,
        'refused_samples_estimator': evaluation.refused_total.estimator,
        'refused_samples_features': evaluation.refused_total.features,
        'refused_by_trajectory': {tid: r.to_json() for tid, r in evaluation.refused.items()},
        'n_runs_push_time_unknown': sum(
            evaluation.push_sources.get(t.trajectory_id, PUSH_UNKNOWN) == PUSH_UNKNOWN
            for t in evaluation.trajectories),
        'deployment': evaluation.deployment(band_width_ns)}
    if evaluation.baselines is not None:
        payload['baselines'] = {name: [curve_point_json(p) for p in pareto_front(curve)]
                                for name, curve in evaluation.baselines.named().items()}
    return payload
