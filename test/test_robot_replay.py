"""A recorded push replayed over DDS into ``fall_monitor --estimator`` the way a robot's drivers
publish it, with the shipped model: the trigger comes before the fall, with the lead of the
simulator-timed stream (within 0.05 s), and a survived push raises no alarm.

The robot's side (this test's node) publishes ``robot_description`` once, then each recording in
real time: joint states at 500 Hz, split into legs and upper body, in reverse order; IMU and foot
wrenches at 1 kHz, 0.3 and 0.4 ms after the encoders; every stamp ROS time (now, nanoseconds since
1970), so the monitor's age check runs against its own clock as on a robot. The reference is the
same recording through the same chain offline with the simulator's timing (1 kHz, one stamp per
step, :class:`~fall_predictor.monitor.chain.OnboardChain`).
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest

from fall_predictor.monitor.chain import OnboardChain
from fall_predictor.monitor.fall_monitor import EVENT_FALLING, FallenConfig, FallMonitor
from fall_predictor.monitor.model_file import load_model
from fall_predictor.monitor.records import FALLEN_COM_HEIGHT_M, GUARD_COM_HEIGHT_M, PushSpec
from fall_predictor.monitor.sensor_pipeline import SensorPipeline
from fall_predictor.profiles import asimo_like_urdf as rm
from fall_predictor.ros.bringup import ros_environment, start_process, stop_nodes
from fall_predictor.ros.sensor_replay import SensorReplayer
from fall_predictor.sim.drivers import DriverTiming, driver_messages
from fall_predictor.sim.sensors import SensorParams, apply_sensors
from fall_predictor.sim.trajectory import run_trajectory
from test_nodes_support import ros_context, test_domain_id

MODEL = Path(__file__).resolve().parents[1] / 'models' / 'default_model.json'
NAMESPACE = '/robot2'
LEGS = tuple(f'{s}_{j}' for s in rm.SIDES for j in rm.LEG_JOINTS)
UPPER = tuple(n for n in rm.JOINT_NAMES if n not in LEGS)
TIMING = DriverTiming.robot(500.0, (LEGS, UPPER))
#: (force [N], direction [deg]) at t = 1 s: the first falls, the second does not.
PUSHES = {'fall': (420.0, 0.0), 'survived': (250.0, 0.0)}


@pytest.fixture(scope='module')
def recordings():
    out = {}
    for k, (name, (force_n, angle_deg)) in enumerate(PUSHES.items()):
        run = run_trajectory(PushSpec(force_n, angle_deg, 0.1, 1.0), 2.6, record_sensors=True)
        out[name] = (run, apply_sensors(run.sensor_truths, SensorParams(), seed=k))
    assert out['fall'][0].fallen and not out['survived'][0].fallen
    return out


def offline_alarm_s(samples) -> float | None:
    """The simulator-timed reference: the first FALLING event's time [s] through the chain."""
    lists, metadata = load_model(MODEL)
    layout = rm.PROFILE.sensor_layout()
    chain = OnboardChain(
        SensorPipeline(layout.description(rm.URDF_PATH.read_text()), layout.imu_frame),
        metadata.feature_settings,
        FallMonitor(lists, metadata.recommended_tau_his_s,
                    FallenConfig(FALLEN_COM_HEIGHT_M, GUARD_COM_HEIGHT_M),
                    metadata.feature_settings.sample_period_s,
                    metadata.feature_settings.guard_com_height_m, rm.TOTAL_MASS_KG))
    for stream, reading in driver_messages(samples):
        for out in chain.add(stream, reading):
            if out.event is not None and out.event.kind == EVENT_FALLING:
                return out.stamp_ns / 1e9
    return None


def test_robot_streams_over_dds_give_the_simulator_timed_alarms(recordings, tmp_path):
    domain = test_domain_id(170)
    monitor = start_process('fall_monitor', [
        sys.executable, '-m', 'fall_predictor.ros.fall_monitor', '--estimator', '--ros-args',
        '-r', f'__ns:={NAMESPACE}', '-p', f'model_path:={MODEL}',
        '-p', f'driving_joints:={list(LEGS)}'.replace("'", '"'),
        '-p', 'start_type_description_service:=false'], ros_environment(domain), tmp_path)
    results = {}
    try:
        with ros_context(domain) as context:
            robot = SensorReplayer(context, NAMESPACE)
            assert robot.spin_until(robot.connected, 60.0), monitor.log_tail()
            robot.publish_description(rm.URDF_PATH.read_text())
            time.sleep(1.0)                 # the estimator builds its model of the robot
            for name, (run, samples) in recordings.items():
                robot.reset_monitor()
                results[name] = robot.replay(samples, TIMING)
            robot.destroy()
    finally:
        codes = stop_nodes({'fall_monitor': monitor})
    assert codes == {'fall_monitor': 0}, monitor.log_tail(40)
    run, samples = recordings['fall']
    reference = offline_alarm_s(samples)
    assert reference is not None and reference < run.t_fallen
    alarm = results['fall'].first_alarm_s
    assert alarm is not None and alarm < run.t_fallen, (results, monitor.log_tail(40))
    assert abs((run.t_fallen - alarm) - (run.t_fallen - reference)) <= 0.05, (alarm, reference, results, monitor.log_tail(60))
    assert results['survived'].first_alarm_s is None, results
    # One state per joint state cycle of the legs, stamped with it (best effort: a loaded machine
    # may lose some, counted by the nodes; a sample that came too late is answered STALE), besides
    # the STALE states of the predictor's wall-clock watchdog, which answer no sample (a pause of
    # the loaded machine longer than stale_timeout_s makes some).
    for result in results.values():
        cycles = result.joint_messages // 2
        assert 0.5 * cycles <= result.sample_states <= cycles, result
