"""The estimator's input path (monitor/sensor_pipeline.py, sensor_sync.py) on sensor streams as a
robot's drivers publish them (sim/drivers.py), against the simulator's ground truth."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from fall_predictor.monitor.contact_modes import classify_contact_mode
from fall_predictor.monitor.estimator import StateEstimator
from fall_predictor.monitor.records import PushSpec
from fall_predictor.monitor.robot_description import RobotDescription
from fall_predictor.monitor.sensor_pipeline import PipelineConfig, SensorPipeline
from fall_predictor.monitor.sensor_records import ImuReading, JointStateReading
from fall_predictor.profiles import asimo_like_urdf as rm
from fall_predictor.sim.drivers import DriverTiming, driver_messages
from fall_predictor.sim.sensors import SensorParams, apply_sensors
from fall_predictor.sim.trajectory import run_trajectory

LEGS = tuple(f'{s}_{j}' for s in rm.SIDES for j in rm.LEG_JOINTS)
UPPER = tuple(n for n in rm.JOINT_NAMES if n not in LEGS)
EPOCH_NS = DriverTiming.robot().clock_offset_ns
#: Until a sole has anchored the base (the first few samples) there is no estimate [ns].
STARTED_NS = 10_000_000


@pytest.fixture(scope='module')
def run():
    return run_trajectory(PushSpec(60.0, 0.0, 0.1, 0.8), 1.3, record_sensors=True)


@pytest.fixture(scope='module')
def samples(run):
    return apply_sensors(run.sensor_truths, SensorParams(), seed=7)


@pytest.fixture(scope='module')
def robot() -> RobotDescription:
    return RobotDescription(rm.URDF_PATH.read_text(), rm.PROFILE.sensor_layout().soles)


def pipeline(robot: RobotDescription, **config) -> SensorPipeline:
    return SensorPipeline(robot, imu_frame=rm.PROFILE.imu_frame, config=PipelineConfig(**config))


def feed(p: SensorPipeline, messages) -> list:
    estimates = []
    for stream, reading in messages:
        if stream == 'joints':
            estimates.extend(p.joint_state(reading)[0])
        elif stream == 'imu':
            estimates.extend(p.imu(reading))
        else:
            estimates.extend(p.wrench(stream, reading))
    return estimates + p.flush()


def test_simulator_timing_gives_exactly_the_estimators_output(robot, samples):
    estimates = feed(pipeline(robot), driver_messages(samples[:600]))
    direct = StateEstimator(robot, imu_frame=rm.PROFILE.imu_frame).run(samples[:600])
    assert len(estimates) == 600
    for e, m in zip(estimates, direct):
        assert (e.measurement is None) == (m is None)
        if m is not None:
            # The same numbers up to round-off (run time from integer stamps, the quaternion
            # normalised once more).
            np.testing.assert_allclose(e.measurement.com, m.com, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(e.measurement.lin_mom, m.lin_mom, rtol=1e-9, atol=1e-12)


def test_a_robots_streams_track_the_truth_as_the_simulators_do(robot, samples, run):
    """500 Hz joint states split into legs and upper body, in reverse order; IMU and foot sensors
    at 1 kHz, 0.3 and 0.4 ms after the encoders; epoch stamps."""
    timing = DriverTiming.robot(joint_rate_hz=500.0, joint_groups=(LEGS, UPPER))
    estimates = feed(pipeline(robot, driving_joints=LEGS), driver_messages(samples, timing))
    assert len(estimates) == (len(samples) + 1) // 2            # one per 500 Hz joint cycle
    assert all(e.stamp_ns - EPOCH_NS == round(e.t * 1e9) + estimates[0].stamp_ns - EPOCH_NS
               for e in estimates)
    truth = {round(m.t * 1000): m for m in run.measurements}
    ok = [e for e in estimates if e.measurement is not None]
    assert len(ok) >= len(estimates) - 3 and all(not e.fault for e in ok)
    pairs = [(e.measurement, truth[round((e.stamp_ns - EPOCH_NS) / 1e6)]) for e in ok]
    com = np.array([np.linalg.norm(m.com - t.com) for m, t in pairs])
    lin = np.array([np.linalg.norm(m.lin_mom - t.lin_mom) for m, t in pairs])
    # The estimator's own aims (test_estimator.py), in the frame the estimator started in.
    offset = pairs[0][1].com[:2] - pairs[0][0].com[:2]
    com_xy = np.array([np.linalg.norm(m.com[:2] + offset - t.com[:2]) for m, t in pairs])
    assert np.percentile(com_xy, 99) <= 0.015 and np.percentile(np.abs(com - com_xy), 99) <= 0.015
    assert np.median(lin) <= 0.3 and np.percentile(lin, 99) <= 2.0
    agree = np.mean([classify_contact_mode(m) == classify_contact_mode(t) for m, t in pairs])
    assert agree >= 0.95


def _robot_messages(samples, **timing):
    return list(driver_messages(samples, DriverTiming.robot(joint_groups=(LEGS, UPPER), **timing)))


def test_an_imu_that_stops_is_a_fault_never_zero(robot, samples):
    messages = _robot_messages(samples[:400])
    gap = (EPOCH_NS + 200_000_000, EPOCH_NS + 250_000_000)        # no IMU for 50 ms
    kept = [(s, r) for s, r in messages if not (s == 'imu' and gap[0] <= r.stamp_ns < gap[1])]
    estimates = feed(pipeline(robot, driving_joints=LEGS), kept)
    faulty = [e for e in estimates if e.fault and e.stamp_ns > EPOCH_NS + STARTED_NS]
    assert faulty and all(e.measurement is None for e in faulty)
    assert all('no /imu/data within 5 ms of /joint_states' in e.fault for e in faulty)
    assert gap[0] + 5_000_000 <= min(e.stamp_ns for e in faulty) <= gap[0] + 7_000_000
    assert max(e.stamp_ns for e in faulty) < gap[1]
    assert estimates[-1].measurement is not None                 # back once the IMU is


def test_a_joint_that_stops_or_never_comes_is_named(robot, samples):
    messages = _robot_messages(samples[:300])
    # l_knee_pitch disappears from the legs' messages after 0.2 s.
    t_cut = EPOCH_NS + 200_000_000

    def drop_knee(stream, r):
        if stream == 'joints' and 'l_knee_pitch' in r.names and r.stamp_ns >= t_cut:
            keep = [i for i, n in enumerate(r.names) if n != 'l_knee_pitch']
            return stream, replace(r, names=tuple(r.names[i] for i in keep), position=r.position[keep],
                                   velocity=r.velocity[keep], effort=r.effort[keep])
        return stream, r
    estimates = feed(pipeline(robot, driving_joints=LEGS), [drop_knee(*m) for m in messages])
    late = [e for e in estimates if e.stamp_ns > t_cut + 60_000_000]
    assert late and all(e.fault == 'joint l_knee_pitch not received for more than 50 ms' for e in late)
    assert all(e.measurement is not None for e in estimates
               if EPOCH_NS + STARTED_NS < e.stamp_ns < t_cut)
    # The upper body's controller never publishes: every one of its joints is named at once.
    legs_only = [(s, r) for s, r in messages if s != 'joints' or 'l_hip_yaw' in r.names]
    first = feed(pipeline(robot, driving_joints=LEGS), legs_only)[0]
    assert first.measurement is None and first.fault.startswith('joints r_head') is False
    assert 'never received' in first.fault and 'head_tilt' in first.fault


def test_an_accelerometer_burst_is_refused_and_said(robot, samples):
    messages = _robot_messages(samples[:300])
    burst = (EPOCH_NS + 150_000_000, EPOCH_NS + 160_000_000)     # 10 ms of 3000 m/s^2
    spiked = [(s, replace(r, linear_acceleration=np.array([3000.0, 0.0, 9.81]))
               if s == 'imu' and burst[0] <= r.stamp_ns < burst[1] else r) for s, r in messages]
    p = pipeline(robot, driving_joints=LEGS)
    estimates = feed(p, spiked)
    refused = [e for e in estimates if 'refused' in e.fault]
    assert refused and all('IMU acceleration 3000 m/s^2 beyond 300 m/s^2' in e.fault for e in refused)
    assert p.sync.counts['refused_readings'] == 10
    # Estimates go on with the readings around the burst: only stamps with none within 5 ms fail.
    assert sum(e.measurement is None for e in estimates) <= 10


def test_unknown_joints_empty_and_stray_messages_never_break_it(robot, samples):
    p = pipeline(robot)
    messages = list(driver_messages(samples[:100]))
    feed(p, messages[:200])
    # Another controller's message (same stamp as the last joint states: it drives nothing).
    last_ns = p.timeline.last_ns
    extra = JointStateReading(last_ns, ('gripper', 'l_hip_yaw'), np.array([0.3, 0.0]))
    assert p.joint_state(extra) == ([], ['gripper'])
    assert p.joint_state(extra)[1] == []                         # reported once
    empty = JointStateReading(messages[200][1].stamp_ns, (), np.zeros(0))
    assert p.joint_state(empty) == ([], [])                      # carries no joint: drives nothing
    stray = replace(messages[204][1], stamp_ns=(2 ** 31 - 1) * 1_000_000_000)
    assert p.joint_state(stray)[0] == []                         # held as a jump candidate
    rest = feed(p, messages[200:])
    assert rest and rest[-1].measurement is not None and p.timeline.jumps == 0
    with pytest.raises(ValueError, match='1 names has 2 positions'):
        p.joint_state(JointStateReading(EPOCH_NS, ('l_hip_yaw',), np.zeros(2)))
    with pytest.raises(ValueError, match='not finite'):
        p.joint_state(JointStateReading(EPOCH_NS, ('l_hip_yaw',), np.array([np.nan])))
    assert p.imu(ImuReading(EPOCH_NS, 'torso', np.array([0.0, 0.0, 0.0, 2.0]), np.zeros(3),
                            np.zeros(3))) == []
    assert 'unit quaternion' in p.sync.refused['imu'][1]


def test_joint_velocities_are_optional(robot, samples, run):
    """A driver that reports positions only: velocities are differenced per joint, and the
    estimates still track the truth (momentum within twice the aim of reported velocities)."""
    stripped = [(s, replace(r, velocity=np.zeros(0)) if s == 'joints' else r)
                for s, r in driver_messages(samples)]
    estimates = [e for e in feed(pipeline(robot), stripped) if e.measurement is not None]
    truth = {round(m.t * 1000): m for m in run.measurements}
    lin = np.array([np.linalg.norm(e.measurement.lin_mom - truth[round(e.stamp_ns / 1e6)].lin_mom)
                    for e in estimates])
    assert len(estimates) >= len(samples) - 5
    assert np.median(lin) <= 0.6 and np.percentile(lin, 99) <= 3.0


@pytest.mark.parametrize('past_rad, refused', [(0.25, False), (0.8, True)])
def test_an_ankle_past_its_limit_is_flagged_and_estimated_unless_impossible(robot, samples, past_rad,
                                                                           refused):
    """From 0.2 s to 0.3 s the left ankle roll reads past its URDF limit (0.6 rad): by 0.25 rad, as
    a slipping foot turns it past the stop, the estimates go on, each flagged and counted; by
    0.8 rad (a broken joint, a reading in another unit) the samples are refused, saying why."""
    i = rm.JOINT_NAMES.index('l_ankle_roll')
    assert robot.joint_bounds.upper[robot.joint_bounds.names.index('l_ankle_roll')] == 0.6
    window = (0.2, 0.3)

    def past(s):
        if not window[0] <= s.t < window[1]:
            return s
        q = np.array(s.q, dtype=float)
        q[i] = 0.6 + past_rad
        return replace(s, q=q)
    p = pipeline(robot)
    estimates = feed(p, driver_messages([past(s) for s in samples[:500]]))
    inside = [e for e in estimates if window[0] <= e.t < window[1]]
    outside = [e for e in estimates if e.t >= window[1] + 0.01]
    assert len(inside) == 100 and outside and all(not e.flags for e in outside)
    if refused:
        assert all(e.measurement is None for e in inside)
        assert all(e.fault.startswith(f'impossible: joint l_ankle_roll at {0.6 + past_rad:.4g} rad, '
                                      'outside its limits [-0.6, 0.6] rad by more than 0.5 rad')
                   for e in inside), inside[0].fault
        assert p.counts['flagged'] == 0
    else:
        assert all(e.measurement is not None and not e.fault for e in inside)
        assert all(e.flags == 'joint l_ankle_roll at 0.85 rad, outside its limits [-0.6, 0.6] rad '
                   'by more than 0.05 rad' for e in inside), inside[0].flags
        assert p.counts['flagged'] == 100 and p.last_flags == inside[-1].flags
