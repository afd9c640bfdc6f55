"""The shipped model on a robot's sensor streams at other rates: the same alarms as at 1 kHz.

Simulated pushes (three falls, two survived) recorded with the sensor model, then published as a
robot's drivers would (:mod:`fall_predictor.sim.drivers`: split and reordered joint states, IMU
and foot sensors a fraction of a millisecond after the encoders, epoch stamps) at 1 kHz, with
joint states at 500 Hz, and with every sensor at 200 Hz, through the whole onboard chain
(:class:`~fall_predictor.monitor.chain.OnboardChain`, what ``fall_monitor --estimator`` runs).
Rate windows and the history window are in seconds, so every fall is called at every rate, with
the lead within 0.02 s of the simulator-timed stream's, and the survived pushes raise no alarm.
"""
from __future__ import annotations

from pathlib import Path

import pytest

from fall_predictor.monitor.chain import OnboardChain
from fall_predictor.monitor.fall_monitor import EVENT_FALLING, FallenConfig, FallMonitor
from fall_predictor.monitor.model_file import load_model
from fall_predictor.monitor.records import FALLEN_COM_HEIGHT_M, GUARD_COM_HEIGHT_M, PushSpec
from fall_predictor.monitor.sensor_pipeline import PipelineConfig, SensorPipeline
from fall_predictor.profiles import asimo_like_urdf as rm
from fall_predictor.sim.drivers import DriverTiming, driver_messages
from fall_predictor.sim.sensors import SensorParams, apply_sensors
from fall_predictor.sim.trajectory import run_trajectory

MODEL = Path(__file__).resolve().parents[1] / 'models' / 'default_model.json'
LEGS = tuple(f'{s}_{j}' for s in rm.SIDES for j in rm.LEG_JOINTS)
UPPER = tuple(n for n in rm.JOINT_NAMES if n not in LEGS)
EPOCH_NS = DriverTiming.robot().clock_offset_ns
#: (force [N], direction [deg]) of pushes at t = 1 s: the first three fall, the others do not.
PUSHES = ((420.0, 0.0), (450.0, 180.0), (400.0, -90.0), (250.0, 0.0), (200.0, 45.0))
TIMINGS = {
    'simulator_1khz': DriverTiming(),
    'robot_1khz': DriverTiming.robot(1000.0, (LEGS, UPPER)),
    'robot_joints_500hz': DriverTiming.robot(500.0, (LEGS, UPPER)),
    'robot_all_200hz': DriverTiming(joint_rate_hz=200.0, imu_rate_hz=200.0, wrench_rate_hz=200.0,
                                    imu_offset_s=0.0003, wrench_offset_s=0.0004,
                                    joint_groups=(LEGS, UPPER), reverse_joint_order=True,
                                    clock_offset_ns=EPOCH_NS),
}


@pytest.fixture(scope='module')
def recordings():
    out = []
    for k, (force_n, angle_deg) in enumerate(PUSHES):
        run = run_trajectory(PushSpec(force_n, angle_deg, 0.1, 1.0), 3.0, record_sensors=True)
        out.append((run, apply_sensors(run.sensor_truths, SensorParams(), seed=k)))
    return out


def first_alarm_s(samples, timing: DriverTiming) -> float | None:
    """Simulation time [s] of the first FALLING event of the chain over the drivers' messages."""
    lists, metadata = load_model(MODEL)
    settings = metadata.feature_settings
    layout = rm.PROFILE.sensor_layout()
    pipeline = SensorPipeline(layout.description(rm.URDF_PATH.read_text()), layout.imu_frame,
                              config=PipelineConfig(driving_joints=LEGS))
    monitor = FallMonitor(lists, metadata.recommended_tau_his_s,
                          FallenConfig(FALLEN_COM_HEIGHT_M, GUARD_COM_HEIGHT_M),
                          settings.sample_period_s, settings.guard_com_height_m, rm.TOTAL_MASS_KG)
    chain = OnboardChain(pipeline, settings, monitor)
    for stream, reading in driver_messages(samples, timing):
        for out in chain.add(stream, reading):
            if out.event is not None and out.event.kind == EVENT_FALLING:
                return (out.stamp_ns - timing.clock_offset_ns) / 1e9
    return None


def test_every_rate_calls_the_same_falls_with_the_same_lead(recordings):
    alarms = {name: [first_alarm_s(samples, timing) for _, samples in recordings]
              for name, timing in TIMINGS.items()}
    reference = alarms.pop('simulator_1khz')
    for k, (run, _) in enumerate(recordings):
        if run.fallen:
            assert reference[k] is not None and reference[k] < run.t_fallen, (k, reference[k])
        else:
            assert reference[k] is None, (k, reference[k])
    for name, times in alarms.items():
        for k, (run, _) in enumerate(recordings):
            if run.fallen:
                assert times[k] is not None, (name, k)
                lead, reference_lead = run.t_fallen - times[k], run.t_fallen - reference[k]
                assert abs(lead - reference_lead) <= 0.02, (name, k, lead, reference_lead)
            else:
                assert times[k] is None, (name, k, times[k])
