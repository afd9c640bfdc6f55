"""Sensor faults through the whole onboard chain with the shipped model: a degraded state that says
why, never a fall, never a crash; normal again when the sensor is.

One unpushed walk recorded with the sensor model and published as a robot's drivers would
(:mod:`fall_predictor.sim.drivers`, epoch stamps), then each fault class injected into it and run
through :class:`~fall_predictor.monitor.chain.OnboardChain` (what ``fall_monitor --estimator``
runs). Each case asserts: no FALLING event, the fault's words in the DEGRADED states while it
lasts, OK states before it and again from 60 ms after it.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

from fall_predictor.monitor.chain import OnboardChain
from fall_predictor.monitor.fall_monitor import (EVENT_FALLING, STATUS_DEGRADED, STATUS_OK,
                                                 FallenConfig, FallMonitor)
from fall_predictor.monitor.model_file import load_model
from fall_predictor.monitor.records import FALLEN_COM_HEIGHT_M, GUARD_COM_HEIGHT_M, PushSpec
from fall_predictor.monitor.sensor_pipeline import PipelineConfig, SensorPipeline
from fall_predictor.monitor.sensor_records import JointStateReading
from fall_predictor.profiles import asimo_like_urdf as rm
from fall_predictor.sim.drivers import DriverTiming, driver_messages
from fall_predictor.sim.sensors import SensorParams, apply_sensors
from fall_predictor.sim.trajectory import run_trajectory

MODEL = Path(__file__).resolve().parents[1] / 'models' / 'default_model.json'
LEGS = tuple(f'{s}_{j}' for s in rm.SIDES for j in rm.LEG_JOINTS)
UPPER = tuple(n for n in rm.JOINT_NAMES if n not in LEGS)
TIMING = DriverTiming.robot(1000.0, (LEGS, UPPER))
EPOCH_NS = TIMING.clock_offset_ns
MS = 1_000_000
#: The fault lasts from FAULT_START to FAULT_END [ns after the start of the recording].
FAULT_START, FAULT_END = 800 * MS, 1300 * MS


@pytest.fixture(scope='module')
def messages():
    run = run_trajectory(None, 2.0, record_sensors=True)
    samples = apply_sensors(run.sensor_truths, SensorParams(), seed=4)
    return list(driver_messages(samples, TIMING))


def chain() -> OnboardChain:
    lists, metadata = load_model(MODEL)
    settings = metadata.feature_settings
    layout = rm.PROFILE.sensor_layout()
    pipeline = SensorPipeline(layout.description(rm.URDF_PATH.read_text()), layout.imu_frame,
                              config=PipelineConfig(driving_joints=LEGS))
    monitor = FallMonitor(lists, metadata.recommended_tau_his_s,
                          FallenConfig(FALLEN_COM_HEIGHT_M, GUARD_COM_HEIGHT_M),
                          settings.sample_period_s, settings.guard_com_height_m, rm.TOTAL_MASS_KG)
    return OnboardChain(pipeline, settings, monitor)


def during(reading, start: int = FAULT_START, end: int = FAULT_END) -> bool:
    return start <= reading.stamp_ns - EPOCH_NS < end


def drop_joint(name: str) -> Callable:
    def change(stream, r):
        if stream == 'joints' and name in r.names and during(r):
            keep = [i for i, n in enumerate(r.names) if n != name]
            return [(stream, replace(r, names=tuple(r.names[i] for i in keep),
                                     position=r.position[keep], velocity=r.velocity[keep],
                                     effort=r.effort[keep]))]
        return [(stream, r)]
    return change


def freeze_joint(name: str) -> Callable:
    frozen: dict[str, float] = {}

    def change(stream, r):
        if stream == 'joints' and name in r.names and during(r):
            i = r.names.index(name)
            position, velocity = r.position.copy(), r.velocity.copy()
            position[i] = frozen.setdefault(name, float(position[i]))
            velocity[i] = 2.0               # the drive says it moves; the encoder says it does not
            return [(stream, replace(r, position=position, velocity=velocity))]
        return [(stream, r)]
    return change


def imu_burst(stream, r):
    if stream == 'imu' and during(r, FAULT_START, FAULT_START + 10 * MS):
        return [(stream, replace(r, linear_acceleration=np.array([3000.0, 0.0, 9.81])))]
    return [(stream, r)]


def silence(target: str) -> Callable:
    def change(stream, r):
        return [] if stream == target and during(r, FAULT_START, FAULT_START + 300 * MS) else [(stream, r)]
    return change


def once(kind: str) -> Callable:
    """A single bad message at FAULT_START, besides the good ones."""
    def change(stream, r):
        out = [(stream, r)]
        if stream == 'joints' and 'l_hip_yaw' in r.names and r.stamp_ns - EPOCH_NS == FAULT_START:
            if kind == 'nan':
                position = r.position.copy()
                position[0] = np.nan
                out.append((stream, replace(r, stamp_ns=r.stamp_ns + 1, position=position)))
            elif kind == 'empty':
                out.append((stream, JointStateReading(r.stamp_ns + 1, (), np.zeros(0))))
            elif kind == 'sec_2_31_minus_1':
                out.append((stream, replace(r, stamp_ns=(2 ** 31 - 1) * 1_000_000_000)))
            elif kind == '1000_s_ahead':
                out.append((stream, replace(r, stamp_ns=r.stamp_ns + 1000 * 1_000_000_000)))
            elif kind == 'unknown_names':
                out.append((stream, JointStateReading(r.stamp_ns, ('gripper',), np.ones(1))))
        if stream == 'imu' and kind == 'huge_gyro' and r.stamp_ns - EPOCH_NS == FAULT_START + 300_000:
            out = [(stream, replace(r, angular_velocity=np.array([1e6, 0.0, 0.0])))]
        return out
    return change


CASES = {
    # case: (how the messages change, the words of the DEGRADED states (None: no such state))
    'joint missing 0.5 s': (drop_joint('l_knee_pitch'),
                            'joint l_knee_pitch not received for more than 50 ms'),
    'joint stuck 0.5 s': (freeze_joint('r_knee_pitch'), 'joint r_knee_pitch stuck at'),
    'IMU burst of 3000 m/s^2 for 10 ms': (imu_burst, None),
    'IMU stops 0.3 s': (silence('imu'), 'no /imu/data within 5 ms of /joint_states'),
    'left foot sensor stops 0.3 s': (silence('l'), 'no /left_foot/wrench within 5 ms'),
    'NaN joint position': (once('nan'), None),
    'empty joint states': (once('empty'), None),
    'stamp sec = 2^31 - 1': (once('sec_2_31_minus_1'), None),
    'joint stamp 1000 s ahead': (once('1000_s_ahead'), None),
    'huge gyro reading': (once('huge_gyro'), None),
    'joint names the URDF lacks': (once('unknown_names'), None),
}


@pytest.mark.parametrize('case', list(CASES))
def test_a_sensor_fault_degrades_never_falls_never_crashes(messages, case: str) -> None:
    change, words = CASES[case]
    c = chain()
    outputs, rejected = [], 0
    for stream, reading in messages:
        for s, r in change(stream, reading):
            try:
                outputs += c.add(s, r)
            except ValueError:              # malformed: the node logs, counts and drops it
                rejected += 1
    outputs += c.flush()
    assert not [o for o in outputs if o.event is not None and o.event.kind == EVENT_FALLING]
    assert not any(o.state.falling for o in outputs)
    rel = lambda o: o.stamp_ns - EPOCH_NS   # noqa: E731
    before = [o for o in outputs if 100 * MS <= rel(o) < FAULT_START]
    after = [o for o in outputs if rel(o) >= FAULT_END + 60 * MS]
    assert before and all(o.state.status == STATUS_OK for o in before), case
    assert after and all(o.state.status == STATUS_OK for o in after), case
    degraded = [o for o in outputs if o.state.status == STATUS_DEGRADED and rel(o) >= 100 * MS]
    if words is None:
        # Refused on arrival (or dropped by the time rule): at most the samples that had no
        # other reading within the tolerance are degraded, for no longer than the fault.
        assert all(FAULT_START <= rel(o) < FAULT_START + 20 * MS for o in degraded), case
    else:
        assert degraded and all(words in o.state.reason for o in degraded), (case, degraded[:1])
        assert all(FAULT_START <= rel(o) < FAULT_END + 60 * MS for o in degraded), case
    if case == 'NaN joint position':
        assert rejected == 1
    refused = {'IMU burst of 3000 m/s^2 for 10 ms': 10, 'huge gyro reading': 1}.get(case, 0)
    assert c.pipeline.sync.counts['refused_readings'] == refused, case


def test_a_position_dead_reckoned_into_the_ground_stops_there_and_stays_estimated(messages) -> None:
    """No sole loaded and the IMU in free fall (specific force 0) from FAULT_START: the estimator
    can only integrate gravity, and its CoM sinks as a dropped stone's does, until it reaches the
    ground, which stops it (method §10): where the ballistic path crosses zero the CoM height stays
    at the ground, and every sample keeps its estimate (none DEGRADED, none dropped): a robot on
    the ground, not a hole in the data."""
    def free_fall(stream, r):
        if not during(r, FAULT_START, 2_000 * MS):
            return [(stream, r)]
        if stream == 'imu':
            return [(stream, replace(r, linear_acceleration=np.zeros(3)))]
        if stream in ('l', 'r'):
            return [(stream, replace(r, wrench=np.zeros(6)))]
        return [(stream, r)]
    c = chain()
    outputs = [o for stream, reading in messages for s, r in free_fall(stream, reading)
               for o in c.add(s, r)] + c.flush()
    assert len(outputs) == c.pipeline.counts['estimates']          # a state for every estimate
    last = max((o for o in outputs if o.stamp_ns - EPOCH_NS < FAULT_START), key=lambda o: o.stamp_ns)
    z0, vz0 = float(last.measurement.com[2]), float(last.measurement.lin_mom[2]) / rm.TOTAL_MASS_KG
    # z0 + vz0 t - g t^2 / 2 = 0 (the joints go on moving: the CoM's offset from the base changes
    # by millimetres, a few milliseconds at the crossing speed of ~3.5 m/s).
    t_cross_s = (vz0 + np.sqrt(vz0 ** 2 + 2 * 9.81 * z0)) / 9.81
    falling = [o for o in outputs if FAULT_START <= o.stamp_ns - EPOCH_NS < 2_000 * MS]
    assert falling and all(o.measurement is not None and o.state.status != STATUS_DEGRADED
                           for o in falling)
    down = [o for o in falling if o.measurement.com[2] < 1e-3]
    first_s = (down[0].stamp_ns - last.stamp_ns) / 1e9
    assert first_s == pytest.approx(t_cross_s, abs=0.005)
    assert [o.stamp_ns for o in down] == [o.stamp_ns for o in falling
                                          if o.stamp_ns >= down[0].stamp_ns]    # it stays there
    assert all(0.0 <= o.measurement.com[2] for o in down)


def test_sporadic_faults_are_holes_that_do_not_delay_the_alarm() -> None:
    """A loaded computer delivers the IMU late now and then: the samples without an IMU reading
    within 5 ms get DEGRADED states, but they are holes in the data, not evidence against the
    fall (method §12): the alarm comes when the clean stream's does (within 10 ms), where restarting
    the window after each one held it back past the fall."""
    run = run_trajectory(PushSpec(420.0, 0.0, 0.1, 1.0), 2.6, record_sensors=True)
    assert run.fallen
    messages = list(driver_messages(apply_sensors(run.sensor_truths, SensorParams(), seed=0), TIMING))

    def alarm_and_degraded(drop) -> tuple[float, int]:
        c = chain()
        outputs = [o for s, r in messages if not drop(s, r) for o in c.add(s, r)] + c.flush()
        alarm = next(o.stamp_ns for o in outputs if o.event is not None
                     and o.event.kind == EVENT_FALLING)
        degraded = sum(o.state.status == STATUS_DEGRADED for o in outputs)
        return (alarm - EPOCH_NS) / 1e9, degraded
    clean_s, clean_degraded = alarm_and_degraded(lambda s, r: False)
    # The IMU silent for 7 ms of every 40 from the push on: 1-2 joint stamps per period without one.
    late_s, degraded = alarm_and_degraded(
        lambda s, r: s == 'imu' and r.stamp_ns - EPOCH_NS >= 1000 * MS
        and (r.stamp_ns - EPOCH_NS) % (40 * MS) < 7 * MS)
    assert degraded >= clean_degraded + 0.9 * (run.t_fallen - 1.0) / 0.040
    assert clean_s < run.t_fallen - 0.3
    assert late_s == pytest.approx(clean_s, abs=0.010)



def test_a_model_reading_the_attitude_gets_it_from_the_robots_streams(messages):
    """Boosted trees over the 19 inputs (method §8c), run on the robot's own streams: the chain
    computes the base's attitude from the estimated base orientation, so every estimate is OK;
    the inputs the monitor got are the offline path's (extract_features over the same
    measurements) and those of a robot standing upright (fused roll and pitch within 3 deg)."""
    from fall_predictor.monitor.boosted_trees import BoostedTrees
    from fall_predictor.monitor.decision_list import PerModeDecisionLists
    from fall_predictor.monitor.features import extract_features
    from fall_predictor.monitor.records import N_CONTACT_MODES
    from fall_predictor.monitor.time_to_fall import RegressionTree
    _, metadata = load_model(MODEL)
    settings = metadata.feature_settings
    # Falling only when the roll rate (input 17) exceeds 100 rad/s: never, standing.
    never = RegressionTree((17, -1, -1), (100.0, 0.0, 0.0), (1, -1, -1), (2, -1, -1),
                           (0.0, -1.0, 1.0), n_inputs=19)
    lists = PerModeDecisionLists(tuple(BoostedTrees((never,), 0.0) for _ in range(N_CONTACT_MODES)))
    layout = rm.PROFILE.sensor_layout()
    pipeline = SensorPipeline(layout.description(rm.URDF_PATH.read_text()), layout.imu_frame,
                              config=PipelineConfig(driving_joints=LEGS))
    monitor = FallMonitor(lists, 0.03, FallenConfig(FALLEN_COM_HEIGHT_M, GUARD_COM_HEIGHT_M),
                          settings.sample_period_s, settings.guard_com_height_m, rm.TOTAL_MASS_KG)
    chain = OnboardChain(pipeline, settings, monitor)
    assert chain.extractor.attitude
    seen, step = [], monitor.step

    def recording_step(t, x, mode, tilt):
        seen.append((t, np.array(x)))
        return step(t, x, mode, tilt)
    monitor.step = recording_step
    outputs = [o for stream, reading in messages for o in chain.add(stream, reading)]
    outputs = [o for o in outputs + chain.flush() if o.measurement is not None]  # not the
    # estimator's start (no loaded sole yet)
    assert len(outputs) > 1900 and all(o.state.status == STATUS_OK for o in outputs)
    assert not any(o.state.falling for o in outputs) and len(seen) == len(outputs)
    X, _ = extract_features([replace(o.measurement, t=t) for o, (t, _) in zip(outputs, seen)],
                            settings.rate_window_s, settings.sample_period_s,
                            settings.edge_tolerance_m, attitude=True)
    np.testing.assert_array_equal(np.array([x for _, x in seen]), X)
    assert X.shape[1] == 19 and np.all(np.abs(X[:, 15:17]) < np.radians(3.0))
