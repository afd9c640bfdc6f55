"""When and where the robot falls, judged at trigger time.

For every fallen trajectory on which the predictor triggers in time (its first falling output
at or after the push and before ``t_fallen``), at the trigger sample ``k``:

* **time to fall**: ``|predicted - (t_fallen - t_k)|`` [s], the prediction from the model's
  :class:`~fall_predictor.monitor.time_to_fall.TimeToFallRegressor`;
* **direction**: the angle [deg] between the predicted direction of the trigger sample
  (:func:`~fall_predictor.monitor.fall_direction.momentum_direction`, reported as
  ``direction_error_deg``; :func:`~fall_predictor.monitor.fall_direction.capture_point_direction`
  as ``direction_error_deg_capture_point``) and the direction the CoM actually left in: its horizontal displacement (world frame) from
  ``t_k`` to ``t_fallen``, turned into the heading frame of ``t_k``. The CoM and heading come
  from the bags (the features are CoP-relative), cached as ``DATA/cache/com_<id>.npz``.

Each is summarised as ``{median, p90, max, n}`` (NaN/None when no trajectory qualifies).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Optional, Sequence, Union

import numpy as np

from fall_predictor.data.dataset import DatasetError, cached_bag_arrays, read_index, read_manifest
from fall_predictor.monitor.decision_list import PerModeDecisionLists
from fall_predictor.monitor.fall_direction import (angular_error_rad, capture_point_direction,
                                                   momentum_direction)
from fall_predictor.monitor.records import GUARD_COM_HEIGHT_M, N_FEATURES, TrajectoryFeatures
from fall_predictor.monitor.time_to_fall import TimeToFallRegressor

PathLike = Union[str, 'os.PathLike[str]']
COM_CACHE_FORMAT = 'fall_predictor/com-heading-cache/v2'


def trigger_indices(trajectories: Sequence[TrajectoryFeatures], lists: PerModeDecisionLists,
                    tau_his_s: float, guard_com_height_m: float = GUARD_COM_HEIGHT_M
                    ) -> list[Optional[int]]:
    """Per trajectory, the sample index of the in-time trigger on a fallen trajectory (first
    falling output in ``[t_push, t_fallen)``, CoM guard on at ``guard_com_height_m`` [m]: the
    model's), else None. A model that reads the base's attitude gets it (method §8c). The
    falling output is ``evaluate``'s (:func:`~fall_predictor.learning.metrics.windowed_prediction`:
    the window restarts after a hole as onboard)."""
    from fall_predictor.learning.metrics import windowed_prediction
    from fall_predictor.learning.training import model_inputs
    out: list[Optional[int]] = []
    for traj in model_inputs(trajectories, lists.reads_attitude):
        if not traj.fallen:
            out.append(None)
            continue
        falling = windowed_prediction(lists, traj, tau_his_s, guard_com_height_m)
        hits = np.flatnonzero(falling & (traj.t >= traj.t_push) & (traj.t < traj.t_fallen))
        out.append(int(hits[0]) if hits.size else None)
    return out


def summary(values: Sequence[float]) -> dict[str, Any]:
    """``{median, p90, max, n}`` of the finite values (None when there are none)."""
    v = np.asarray([x for x in values if math.isfinite(x)], dtype=float)
    if v.size == 0:
        return {'median': None, 'p90': None, 'max': None, 'n': 0}
    return {'median': float(np.median(v)), 'p90': float(np.percentile(v, 90)),
            'max': float(v.max()), 'n': int(v.size)}


def time_to_fall_errors(trajectories: Sequence[TrajectoryFeatures], triggers: Sequence[Optional[int]],
                        regressor: TimeToFallRegressor) -> list[float]:
    """Absolute time-to-fall error [s] at each trigger."""
    errors = []
    for traj, k in zip(trajectories, triggers):
        if k is None:
            continue
        predicted = regressor.predict_one(traj.X[k].tolist(), int(traj.mode[k]))
        errors.append(abs(predicted - (traj.t_fallen - traj.t[k])))
    return errors


def _com_entry(data_dir: Path, bag: str, trajectory_id: str) -> dict[str, np.ndarray]:
    from fall_predictor.data.bagio import read_trajectory

    def from_bag() -> dict[str, np.ndarray]:
        ms = read_trajectory(data_dir / bag).measurements or []
        return {'t': np.array([m.t for m in ms], dtype=float),
                'com_xy': np.array([m.com[:2] for m in ms]).reshape(len(ms), 2),
                'heading': np.array([m.heading for m in ms], dtype=float)}

    return cached_bag_arrays(data_dir, bag, f'com_{trajectory_id}', COM_CACHE_FORMAT, from_bag,
                             ('fall_predictor.data.bagio',))


def actual_direction(com_xy: np.ndarray, heading: np.ndarray, t: np.ndarray, k: int,
                     t_fallen: float) -> np.ndarray:
    """Unit (2,) heading-frame direction of the CoM's displacement from sample ``k`` to
    ``t_fallen`` (heading of sample ``k``)."""
    j = min(int(np.searchsorted(t, t_fallen)), t.size - 1)
    dx, dy = com_xy[j] - com_xy[k]
    c, s = math.cos(heading[k]), math.sin(heading[k])
    hx, hy = c * dx + s * dy, -s * dx + c * dy
    norm = math.hypot(hx, hy)
    return np.array([hx / norm, hy / norm]) if norm > 0.0 else np.full(2, np.nan)


DIRECTIONS = {'momentum': momentum_direction, 'capture_point': capture_point_direction}


def actual_directions(data_dir: PathLike, trajectories: Sequence[TrajectoryFeatures],
                      triggers: Sequence[Optional[int]]) -> list[Optional[np.ndarray]]:
    """Per trajectory, the unit (2,) heading-frame direction the CoM left in from its trigger
    sample to ``t_fallen`` (:func:`actual_direction`), from the dataset's true CoM; None where
    there is no trigger, or the direction is undefined. Empty for a robot's recordings (no
    true CoM to compare with)."""
    data_dir = Path(data_dir)
    if read_manifest(data_dir).get('ground_truth') is False:
        return []
    bags = {row.trajectory_id: row.bag for row in read_index(data_dir)}
    out: list[Optional[np.ndarray]] = []
    for traj, k in zip(trajectories, triggers):
        if k is None:
            out.append(None)
            continue
        com = _com_entry(data_dir, bags[traj.trajectory_id], traj.trajectory_id)
        # The true CoM at the feature samples' times (estimated features may skip samples).
        at = np.searchsorted(com['t'], traj.t - 5e-4)
        if at.max() >= com['t'].size or np.abs(com['t'][at] - traj.t).max() > 5e-4:
            raise DatasetError(f'{traj.trajectory_id}: the true CoM misses feature sample times')
        actual = actual_direction(com['com_xy'][at], com['heading'][at], traj.t, k, traj.t_fallen)
        out.append(actual if np.all(np.isfinite(actual)) else None)
    return out


@dataclass(frozen=True)
class DirectionSamples:
    """Features at the triggers (``X``, (N, 15)) and the unit directions the CoM then left in
    (``actual``, (N, 2), heading frame), one row per triggered fall with a defined direction."""

    X: np.ndarray
    actual: np.ndarray


def direction_samples(data_dir: PathLike, trajectories: Sequence[TrajectoryFeatures],
                      triggers: Sequence[Optional[int]]) -> DirectionSamples:
    """The features at ``triggers`` and the directions the CoM then left in
    (:func:`actual_directions`: the dataset's true CoM)."""
    rows, actual = [], []
    for traj, k, a in zip(trajectories, triggers, actual_directions(data_dir, trajectories, triggers)):
        if a is not None:
            rows.append(np.asarray(traj.X[k, :N_FEATURES], dtype=float))   # a model's inputs may
                                                                            # go on (the attitude)
            actual.append(a)
    return DirectionSamples(np.array(rows, dtype=float).reshape(len(rows), N_FEATURES),
                            np.array(actual, dtype=float).reshape(len(actual), 2))


def direction_errors_deg(samples: DirectionSamples, direction: Union[str, Callable] = 'momentum',
                         mass_kg: float = 1.0) -> list[float]:
    """Angular error [deg] of a predicted fall direction (a name of :data:`DIRECTIONS`, or a
    function of the features and the mass such as a learned direction's ``direction``) at each
    sample; a prediction that is not defined (NaN) is left out."""
    predict = DIRECTIONS[direction] if isinstance(direction, str) else direction
    errors = []
    for x, actual in zip(samples.X, samples.actual):
        predicted = predict(x.tolist(), mass_kg)
        if np.all(np.isfinite(predicted)):
            errors.append(math.degrees(angular_error_rad(predicted, actual)))
    return errors


def when_where_lines(payload: dict[str, Any]) -> list[str]:
    """Text lines for the ``time_to_fall_error_s`` / ``direction_error_deg`` of an evaluation."""
    lines = []
    for key, unit in (('time_to_fall_error_s', 's'), ('direction_error_deg', 'deg'),
                      ('direction_error_deg_momentum', 'deg')):
        e = payload.get(key)
        if key == 'direction_error_deg_momentum' and payload.get('fall_direction') != 'learned':
            continue                        # the same as direction_error_deg
        if e is not None and e['n']:
            label = (f'{key} ({payload["fall_direction"]})' if key == 'direction_error_deg'
                     and 'fall_direction' in payload else key)
            lines.append(f'{label}: median {e["median"]:.3f} {unit}, p90 {e["p90"]:.3f}, max '
                         f'{e["max"]:.3f} over {e["n"]} triggers')
    return lines
