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


def _reference_readings(truths, params, seed, profile=rm.PROFILE):
    """The sensor model written out one step at a time, as the method states it (an independent
    statement of what :meth:`SensorSuite.read_many` computes on arrays)."""
    from collections import deque

    from fall_predictor.monitor import rotations
    from fall_predictor.sim import sensors

    def quantise(x, quantum):
        return x if quantum <= 0 else np.round(x / quantum) * quantum

    rng, k = np.random.default_rng(seed), params.noise_scale
    e, i, f = params.encoders, params.imu, params.force_torque
    n = len(profile.joint_names)
    q_bias = k * e.position_bias_rad * rng.standard_normal(n)
    gyro_bias = k * i.gyro_bias_rad_s * rng.standard_normal(3)
    accel_bias = k * i.accel_bias_m_s2 * rng.standard_normal(3)
    att_bias = k * np.array([i.tilt_bias_rad, i.tilt_bias_rad, i.yaw_bias_rad]) * rng.standard_normal(3)
    ft_bias = {s: k * np.concatenate([f.force_bias_n * rng.standard_normal(3),
                                      f.torque_bias_nm * rng.standard_normal(3)]) for s in 'lr'}
    lines = {name: deque(maxlen=max(0, int(round(lat / 0.001))) + 1)
             for name, lat in (('enc', e.latency_s), ('imu', i.latency_s), ('ft', f.latency_s))}
    sqrt_nyquist = math.sqrt(500.0)
    out, prev_v = [], None
    for t in truths:
        q = quantise(t.q + q_bias + k * e.position_noise_rad * rng.standard_normal(n), e.position_quantum_rad)
        dq = quantise(t.dq + k * e.velocity_noise_rad_s * rng.standard_normal(n), e.velocity_quantum_rad_s)
        tau = quantise(t.tau + k * e.effort_noise_nm * rng.standard_normal(n), e.effort_quantum_nm)
        rot = rotations.matrix(t.imu_quat_xyzw)
        acc = np.zeros(3) if prev_v is None else (t.imu_velocity_world - prev_v) / 0.001
        prev_v = t.imu_velocity_world.copy()
        specific = rot.T @ (acc + np.array([0.0, 0.0, sensors._G]))
        gyro = quantise(t.gyro_rad_s + gyro_bias + k * i.gyro_noise_density_rad_s_sqrt_hz * sqrt_nyquist
                        * rng.standard_normal(3), i.gyro_quantum_rad_s)
        accel = quantise(specific + accel_bias + k * i.accel_noise_density_m_s2_sqrt_hz * sqrt_nyquist
                         * rng.standard_normal(3), i.accel_quantum_m_s2)
        err = att_bias + k * i.orientation_noise_rad * rng.standard_normal(3)
        quat = np.array(rotations.multiply(rotations.from_rotation_vector(*err.tolist()), t.imu_quat_xyzw))
        wrenches = []
        for side, w in (('l', t.left_wrench), ('r', t.right_wrench)):
            if w is None:
                wrenches.append(None)
                continue
            raw = w + ft_bias[side] + k * np.concatenate([f.force_noise_n * rng.standard_normal(3),
                                                          f.torque_noise_nm * rng.standard_normal(3)])
            wrenches.append(np.concatenate([quantise(raw[:3], f.force_quantum_n),
                                            quantise(raw[3:], f.torque_quantum_nm)]))
        delayed = []
        for name, value in (('enc', (q, dq, tau)), ('imu', (quat, gyro, accel)), ('ft', wrenches)):
            lines[name].append(value)
            delayed.append(lines[name][0])
        out.append(delayed)
    return out


@pytest.mark.parametrize('force_torque', [True, False])
def test_readings_of_a_run_are_the_step_by_step_models_bit_for_bit(run, force_torque):
    from dataclasses import replace

    from fall_predictor.sim.sensors import EncoderParams, ForceTorqueParams, ImuParams
    # Latencies of 3, 2 and 4 samples, so that each delay line is read across the chunks below.
    params = SensorParams(noise_scale=1.5, encoders=EncoderParams(latency_s=0.003),
                          imu=ImuParams(latency_s=0.002), force_torque=ForceTorqueParams(latency_s=0.004))
    truths = run.sensor_truths[:400]
    if not force_torque:                      # a robot without foot F/T sensors (the G1)
        truths = [replace(t, left_wrench=None, right_wrench=None) for t in truths]
    expected = _reference_readings(truths, params, seed=11)
    suite = SensorSuite(params, seed=11)
    got, start = [], 0
    for size in (1, 2, 1, 5, 40, 151, 200):   # one step at a time, then chunks of a run
        got += suite.read_many(truths[start:start + size]) if size > 1 else [suite.read(truths[start])]
        start += size
    assert len(got) == len(truths) == len(expected)
    for reading, ((q, dq, tau), (quat, gyro, accel), wrenches) in zip(got, expected):
        for a, b in ((reading.q, q), (reading.dq, dq), (reading.tau, tau), (reading.imu_quat_xyzw, quat),
                     (reading.gyro_rad_s, gyro), (reading.accel_m_s2, accel)):
            np.testing.assert_array_equal(a, b)
        for a, b in ((reading.left_wrench, wrenches[0]), (reading.right_wrench, wrenches[1])):
            assert (a is None) == (b is None) == (not force_torque)
            if b is not None:
                np.testing.assert_array_equal(a, b)
    assert apply_sensors([], params) == []
