"""The fall detector most ROS humanoids run today, as a baseline: torso tilt and
angular-velocity thresholds with a smoothing time, in the style of the bit-bots humanoid control
module's falling check (``bitbots_hcm``), computed from the IMU topic alone.

Per axis (roll about x, pitch about y, each a *fused angle* of the IMU orientation, so that the
heading does not enter) an axis is falling when it rotates away from upright, or is past the
point of no return (``|angle| > angle_thr``), and its rate exceeds the rate threshold scaled
down linearly to zero as the angle approaches ``angle_thr``::

    |omega| > rate_thr * max(1 - |angle| / angle_thr, 0)

Either axis falling is an alarm. The smoothing time (an alarm only once every sample within it
alarms) is the run-time window ``tau_his`` of the learned lists, so the sweep chooses it on the
same grid and folds, together with the two thresholds (:mod:`fall_predictor.learning.fair_baselines`).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from fall_predictor.data.dataset import cached_bag_arrays, has_sensor_topics, read_index
from fall_predictor.monitor.geometry import fused_roll_pitch  # noqa: F401 (part of this module's API)
from fall_predictor.monitor.records import TrajectoryFeatures

IMU_CACHE_FORMAT = 'fall_predictor/imu-cache/v1'
#: Threshold grid: fused tilt [deg] x angular rate [rad/s].
ANGLE_THRESHOLDS_DEG = (10.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0, 50.0, 60.0)
RATE_THRESHOLDS_RAD_S = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0)


def threshold_grid(angles_deg: Sequence[float] = ANGLE_THRESHOLDS_DEG,
                   rates_rad_s: Sequence[float] = RATE_THRESHOLDS_RAD_S) -> list[tuple[float, float]]:
    """Every (tilt [deg], rate [rad/s]) threshold pair of the grid."""
    return [(float(a), float(r)) for a in angles_deg for r in rates_rad_s]


def tilt_alarms(signals: np.ndarray, angle_thr_deg: float, rate_thr_rad_s: float) -> np.ndarray:
    """Per sample, whether the detector calls a fall (before smoothing).

    ``signals`` (n, 4): fused roll, fused pitch [rad], roll rate, pitch rate [rad/s] (gyro x, y
    in the torso frame); rows with NaN (no IMU sample) never alarm.
    """
    angle_thr = math.radians(angle_thr_deg)
    s = np.asarray(signals, dtype=float)
    angle, rate = s[:, :2], s[:, 2:]
    with np.errstate(invalid='ignore'):
        away = angle * rate >= 0.0             # rotating away from upright (any way, when upright)
        beyond = np.abs(angle) > angle_thr
        scale = np.maximum(1.0 - np.abs(angle) / angle_thr, 0.0)
        fast = np.abs(rate) > rate_thr_rad_s * scale
        falling = (away | beyond) & fast
    return np.any(falling & np.isfinite(s[:, :2]) & np.isfinite(rate), axis=1)


def _imu_entry(data_dir: Path, bag: str, trajectory_id: str) -> dict[str, np.ndarray]:
    from fall_predictor.data.sensorbag import read_imu

    def from_bag() -> dict[str, np.ndarray]:
        t, quat, gyro = read_imu(data_dir / bag)
        return {'t': t, 'roll_pitch': fused_roll_pitch(quat), 'gyro': gyro}

    return cached_bag_arrays(data_dir, bag, f'imu_{trajectory_id}', IMU_CACHE_FORMAT, from_bag,
                             ('fall_predictor.data.sensorbag', 'fall_predictor.monitor.geometry'))


def aligned_signals(imu: dict[str, np.ndarray], t: np.ndarray) -> np.ndarray:
    """The IMU signals (n, 4) at the feature sample times ``t`` [s] (same millisecond), NaN where
    the IMU has no sample."""
    out = np.full((len(t), 4), np.nan)
    where = {int(k): i for i, k in enumerate(np.round(imu['t'] * 1000.0).astype(np.int64))}
    for j, k in enumerate(np.round(np.asarray(t) * 1000.0).astype(np.int64)):
        i = where.get(int(k))
        if i is not None:
            out[j, :2] = imu['roll_pitch'][i]
            out[j, 2:] = imu['gyro'][i, :2]
    return out


def imu_signals_cached(data_dir, trajectories: Sequence[TrajectoryFeatures], jobs: int = 1,
                       progress: bool = False) -> Optional[list[np.ndarray]]:
    """Per trajectory, the detector's signals (n, 4) at its feature samples; None when the
    dataset was recorded without sensor topics. Read once per bag and cached as
    ``DATA/cache/imu_<trajectory id>.npz``."""
    from joblib import delayed
    from tqdm import tqdm

    from fall_predictor.data.parallel import local_parallel

    data_dir = Path(data_dir)
    if not has_sensor_topics(data_dir):
        return None
    bags = {row.trajectory_id: row.bag for row in read_index(data_dir)}
    entries = local_parallel(jobs)(
        delayed(_imu_entry)(data_dir, bags[traj.trajectory_id], traj.trajectory_id)
        for traj in tqdm(trajectories, desc='imu', unit='traj', disable=not progress))
    return [aligned_signals(imu, traj.t) for imu, traj in zip(entries, trajectories)]
