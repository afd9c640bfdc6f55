"""The sensor model against the simulator's exact state: physics, determinism, parameters."""
import math

import numpy as np
import pytest

from fall_predictor.monitor.records import PushSpec, STANDARD_GRAVITY_M_S2
from fall_predictor.profiles import asimo_like_urdf as rm
from fall_predictor.sim.sensors import SensorParams, SensorSuite, apply_sensors
from fall_predictor.sim.trajectory import run_trajectory


@pytest.fixture(scope='module')
def run():
    # 1.2 s of walking with a 60 N push at 0.8 s: stance changes, loaded and unloaded soles.
    return run_trajectory(PushSpec(60.0, 0.0, 0.1, 0.8), 1.2, record_sensors=True)


def test_the_feet_carry_the_robot_and_their_cop_is_the_simulators(run):
    truths = run.sensor_truths
    assert len(truths) == len(run.measurements)
    for k in range(100, len(truths), 97):
        s, m = truths[k], run.measurements[k]
        fz = s.left_wrench[2] + s.right_wrench[2]
        # Quasi-static: the ground carries the weight, to within the CoM's vertical acceleration.
        assert fz == pytest.approx(rm.TOTAL_MASS_KG * STANDARD_GRAVITY_M_S2, rel=0.15)
        # CoP from the wrenches (soles flat at yaw ~0: sole frames parallel to the world).
        cops = []
        for side, w in (('l', s.left_wrench), ('r', s.right_wrench)):
            if w[2] > 1.0:
                foot = m.left_foot if side == 'l' else m.right_foot
                cops.append((w[2], foot[0] - w[4] / w[2], foot[1] + w[3] / w[2]))
        f = np.array(cops)
        cop = f[:, 0] @ f[:, 1:] / f[:, 0].sum()
        assert cop == pytest.approx(m.cop[:2], abs=0.004)


def test_readings_are_seeded_and_deterministic(run):
    a = apply_sensors(run.sensor_truths[:200], seed=3)
    b = apply_sensors(run.sensor_truths[:200], seed=3)
    c = apply_sensors(run.sensor_truths[:200], seed=4)
    assert all(np.array_equal(x.q, y.q) and np.array_equal(x.accel_m_s2, y.accel_m_s2) for x, y in zip(a, b))
    assert not np.array_equal(a[50].q, c[50].q)


def test_noise_free_readings_are_the_truth_one_sample_late_and_quantised(run):
    params = SensorParams(noise_scale=0.0)
    out = apply_sensors(run.sensor_truths[:300], params)
    e = params.encoders
    for k in (10, 150, 299):
        truth = run.sensor_truths[k - 1]       # 1 ms latency
        assert np.max(np.abs(out[k].q - truth.q)) <= e.position_quantum_rad / 2 + 1e-12
        assert out[k].imu_quat_xyzw == pytest.approx(truth.imu_quat_xyzw, abs=1e-12)
        assert np.max(np.abs(out[k].left_wrench[:3] - truth.left_wrench[:3])) <= 1 / 32 + 1e-9


def test_the_accelerometer_reads_gravity_up_when_standing_still(run):
    out = apply_sensors(run.sensor_truths[:200], SensorParams(noise_scale=0.0))
    acc = np.mean([r.accel_m_s2 for r in out[50:200]], axis=0)
    # The torso is nearly upright before the walk has started: +g along its z axis.
    assert acc == pytest.approx([0.0, 0.0, STANDARD_GRAVITY_M_S2], abs=0.3)


def test_default_noise_has_the_documented_spread(run):
    params = SensorParams()
    suite = SensorSuite(params, seed=0)
    gyro = np.array([suite.read(run.sensor_truths[0]).gyro_rad_s for _ in range(2000)])
    expected = params.imu.gyro_noise_density_rad_s_sqrt_hz * math.sqrt(500.0)
    # The reading is quantised with a step comparable to the noise: spread within 50 %.
    assert np.std(gyro[:, 0]) == pytest.approx(expected, rel=0.5)
    assert SensorParams(noise_scale=2.0).to_dict()['noise_scale'] == 2.0
    with pytest.raises(ValueError):
        SensorParams(noise_scale=-1.0)
