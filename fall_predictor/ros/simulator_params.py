"""The simulator node's parameters (:mod:`fall_predictor.ros.simulator_node`), the checks across
them, and the sensor drivers' timing they describe."""
from __future__ import annotations

from collections.abc import Mapping
from typing import Optional

from fall_predictor.contract.topics import SIM_RATE_HZ
from fall_predictor.profiles.profile import RobotProfile
from fall_predictor.ros.parameters import ParamSpec, ParamValue
from fall_predictor.ros.robots import ROBOT_PARAM
from fall_predictor.ros.simulated_world import CONTROLLER_PARAM, SIMULATOR_PARAM
from fall_predictor.sim.drivers import DriverTiming

PARAMS = (
    ROBOT_PARAM, CONTROLLER_PARAM, SIMULATOR_PARAM,
    ParamSpec('lockstep', True, 'wait for the controller command of each sample before '
              'stepping (deterministic runs); false: step on a wall-clock timer', read_only=True),
    ParamSpec('real_time_factor', 1.0, 'simulated seconds per wall second (upper bound); '
              '0 = as fast as possible (lock-step only)', 0.0, 100.0),
    ParamSpec('command_timeout_s', 0.5, 'lock-step: wall time [s] to wait for the command of a '
              'sample before stepping with the last command (a missed command)', 0.001, 60.0),
    ParamSpec('joint_state_rate_hz', 100.0, 'rate of /joint_states in simulation time [Hz], '
              'rounded to a whole number of physics steps', 1.0, SIM_RATE_HZ, read_only=True),
    ParamSpec('stop_when_fallen', False, 'stop stepping at the first fallen sample (until '
              '~/reset); false: keep simulating the fallen robot'),
    ParamSpec('autostart', True, 'start a run at launch; false: wait for the first ~/reset',
              read_only=True),
    ParamSpec('random_push_period_s', 0.0, 'push the robot every this many simulated seconds '
              'with a push drawn from the method §3 distribution; 0 = off', 0.0, 3600.0,
              read_only=True),
    ParamSpec('random_push_seed', 0, 'seed of the random pushes', 0, 2**31 - 1,
              read_only=True),
    ParamSpec('publish_sensors', False, 'publish the robot sensor topics and the exact state on '
              '/fall_predictor/ground_truth (the measurement comes from state_estimator_node); '
              'a learned policy walks on them, so it needs this true', read_only=True),
    ParamSpec('sensor_noise_scale', 1.0, 'multiplier of every sensor noise and bias (0 = ideal)',
              0.0, 100.0, read_only=True),
    ParamSpec('sensor_seed', 0, 'seed of the sensor noise', 0, 2**31 - 1, read_only=True),
    ParamSpec('sensor_joint_rate_hz', 1000.0, 'rate of the sensors\' /joint_states [Hz]; a '
              'learned policy needs one per physics step', 1.0, 1000.0, read_only=True),
    ParamSpec('sensor_imu_rate_hz', 1000.0, 'rate of /imu/data [Hz]; a learned policy needs one '
              'per physics step', 1.0, 1000.0, read_only=True),
    ParamSpec('sensor_wrench_rate_hz', 1000.0, 'rate of the foot wrenches [Hz]', 1.0, 1000.0,
              read_only=True),
    ParamSpec('sensor_imu_offset_s', 0.0, 'IMU stamps this much after the encoders\' [s]', 0.0,
              0.00099, read_only=True),
    ParamSpec('sensor_wrench_offset_s', 0.0, 'foot wrench stamps this much after the encoders\' '
              '[s]', 0.0, 0.00099, read_only=True),
    ParamSpec('sensor_split_joints', False, 'publish the joint states as two messages (legs, upper '
              'body), as two controllers would', read_only=True),
)


def driver_timing(p: Mapping[str, ParamValue], profile: RobotProfile) -> DriverTiming:
    """How the simulated robot's drivers publish its sensors (the ``sensor_*`` parameters; a
    robot without upper-body joints, such as the 12-joint G1, publishes its legs alone)."""
    groups = tuple(g for g in profile.legs_and_upper_body() if g) \
        if p['sensor_split_joints'] else ()
    return DriverTiming(joint_rate_hz=float(p['sensor_joint_rate_hz']),
                        imu_rate_hz=float(p['sensor_imu_rate_hz']),
                        wrench_rate_hz=float(p['sensor_wrench_rate_hz']),
                        imu_offset_s=float(p['sensor_imu_offset_s']),
                        wrench_offset_s=float(p['sensor_wrench_offset_s']), joint_groups=groups)


def check_pacing(values: Mapping[str, ParamValue]) -> Optional[str]:
    """Why the pacing parameters cannot work together, or None."""
    if not values['lockstep'] and values['real_time_factor'] == 0.0:
        return 'real_time_factor must be > 0 without lockstep (a timer steps the world)'
    return None
