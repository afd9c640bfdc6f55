"""The IMU tilt detector baseline (bit-bots style), against known rotations and a recorded fall."""
import math

import numpy as np
import pytest

from fall_predictor.cli import main
from fall_predictor.data.dataset import load_features, read_index
from fall_predictor.learning.fair_baselines import cross_validated_baselines
from fall_predictor.learning.evaluation import BaselineGrids
from fall_predictor.learning.tilt_detector import (fused_roll_pitch, imu_signals_cached, threshold_grid,
                                                   tilt_alarms)


def _quat_xyzw(axis, angle_rad):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.r_[axis * math.sin(angle_rad / 2), math.cos(angle_rad / 2)]


def _mul(a, b):
    """Hamilton product of x, y, z, w quaternions."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz])


def test_fused_angles_of_pure_rotations_and_independence_of_heading():
    pitch = _quat_xyzw([0, 1, 0], math.radians(20))
    roll = _quat_xyzw([1, 0, 0], math.radians(-30))
    yawed = _mul(_quat_xyzw([0, 0, 1], math.radians(90)), pitch)     # heading first, then the tilt
    got = np.degrees(fused_roll_pitch(np.array([pitch, roll, yawed])))
    np.testing.assert_allclose(got, [[0, 20], [-30, 0], [0, 20]], atol=1e-9)


def test_alarm_rule_known_answers():
    thr = math.radians(40)
    rows = np.array([
        [0.0, 0.0, 0.0, 0.6],             # upright, pitching away at 0.6 > 0.5 rad/s -> alarm
        [0.0, 0.1, 0.0, -0.6],            # pitched forward, rotating back up -> no alarm
        [0.0, thr / 2, 0.0, 0.3],         # half-way: threshold 0.25 rad/s, 0.3 -> alarm
        [0.0, thr / 2, 0.0, 0.2],         # half-way, 0.2 -> no alarm
        [-thr * 1.1, 0.0, 0.01, 0.0],     # past the point of no return, any rate -> alarm
        [-0.2, 0.0, -0.6, 0.0],           # rolled left, rolling further left fast -> alarm
        [np.nan, np.nan, np.nan, np.nan],  # no IMU sample -> no alarm
    ])
    assert tilt_alarms(rows, 40.0, 0.5).tolist() == [True, False, True, False, True, True, False]


@pytest.fixture(scope='module')
def fall_dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp('tilt') / 'data'
    assert main(['generate', '--trajectories', '2', '--seed', '0', '--out', str(out), '--horizon', '0.8',
                 '--sensor-noise', '1', '--json']) == 0
    return out


def test_imu_signals_follow_the_true_torso_and_call_the_fall(fall_dataset):
    report = load_features(fall_dataset, progress=False, state='true')
    signals = imu_signals_cached(fall_dataset, report.trajectories)
    rows = {r.trajectory_id: r for r in read_index(fall_dataset)}
    assert any(r.fallen for r in rows.values()) and not all(r.fallen for r in rows.values())
    for traj, s in zip(report.trajectories, signals):
        assert s.shape == (traj.t.size, 4) and np.isfinite(s).all()
        # Physics: the walking torso is upright; a fallen robot's torso is far from it.
        tilt = np.degrees(np.max(np.abs(s[:, :2]), axis=1))
        assert np.percentile(tilt[traj.t < traj.t_push], 99) < 6.0
        if traj.fallen:
            assert tilt[-1] > 25.0
        alarm = tilt_alarms(s, 30.0, 1.0)
        pre_push = traj.t < traj.t_push
        assert not alarm[pre_push].any()                     # walking is not a fall
        if traj.fallen:
            assert alarm[(traj.t >= traj.t_push) & (traj.t <= traj.t_fallen)].any()
    nested = cross_validated_baselines(report.trajectories, None, BaselineGrids.coarse(), (0.0, 0.05),
                                       folds=2, seed=0, imu=signals)
    assert len(nested['imu_tilt']) > 0
    chosen = nested['imu_tilt'][0]['selected_in_hindsight']['threshold']
    assert tuple(chosen) in threshold_grid()


def test_no_signals_without_sensor_topics(tmp_path):
    out = tmp_path / 'plain'
    assert main(['generate', '--trajectories', '1', '--seed', '0', '--out', str(out), '--horizon', '0.2',
                 '--json']) == 0
    report = load_features(out, progress=False, state='true')
    assert imu_signals_cached(out, report.trajectories) is None
