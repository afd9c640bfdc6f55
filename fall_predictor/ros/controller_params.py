"""The controller node's parameters (:mod:`fall_predictor.ros.controller_node`): the walking
controller, C_bal's settings, and a learned policy's velocity command with the ranges the robot
profile gives it; the robot description whose joint states a policy reads."""
from __future__ import annotations

from typing import TYPE_CHECKING

from fall_predictor.monitor.robot_description import DescriptionError
from fall_predictor.profiles.profile import RobotProfile
from fall_predictor.ros.parameters import NodeStartupError, ParamSpec
from fall_predictor.ros.robots import ROBOT_PARAM
from fall_predictor.ros.simulated_world import (CONTROLLER_PARAM, SIMULATOR_PARAM,
                                                ControllerChoice)

if TYPE_CHECKING:
    from fall_predictor.monitor.robot_description import RobotDescription

PARAMS = (
    ROBOT_PARAM, CONTROLLER_PARAM,
    ParamSpec(SIMULATOR_PARAM.name, '', "the simulator the robot runs in ('' = the robot "
              "profile's): C_bal steps at its physics step", read_only=True),
    ParamSpec('walk_duration_s', 300.0, 'C_bal: length of the planned walk [s] of simulation '
              'time, from the start of a run; the robot stands afterwards', 1.0, 86400.0,
              read_only=True),
    ParamSpec('reflex_enabled', True, "C_bal's stepping reflex on large momentum (method §2)",
              read_only=True),
    ParamSpec('fall_trigger_enabled', True, 'switch to C_fall when the trigger says falling; '
              'false: the walking controller throughout (as in data generation)'),
    ParamSpec('ground_truth', False, 'C_bal: read the simulator\'s exact state '
              '(fall_predictor/ground_truth, published with its sensors) instead of '
              'fall_predictor/measurement: the simulated robot\'s own controller then does not '
              'depend on the monitor\'s estimator', read_only=True),
)

#: The velocity command's parameters: (name, what it commands, the robot profile's range field,
#: the bound of its value for C_bal, which ignores it).
_COMMANDS = (('command_vx_m_s', 'forward speed [m/s]', 'vx_m_s', 2.0),
             ('command_vy_m_s', 'leftward speed [m/s]', 'vy_m_s', 2.0),
             ('command_yaw_rate_rad_s', 'yaw rate [rad/s]', 'yaw_rate_rad_s', 2.0))


def command_params(choice: ControllerChoice, controller) -> tuple[ParamSpec, ...]:
    """The velocity command parameters: for a learned policy (``controller``, its
    robot/control.PolicyControl) within the robot profile's command ranges (widened to take the
    command it walks at when built, the deploy config's initial command: their default); for
    C_bal, which ignores them, zero within a sane bound."""
    specs = []
    for k, (name, what, field, bound) in enumerate(_COMMANDS):
        if choice.policy is None:
            specs.append(ParamSpec(name, 0.0, f'a learned policy\'s commanded {what}; C_bal '
                                   'ignores it', -bound, bound))
            continue
        default = float(controller.velocity_command[k])
        low, high = getattr(choice.policy.command, field)
        low, high = min(low, default), max(high, default)
        specs.append(ParamSpec(name, default, f'{choice.name}\'s commanded {what}, within the '
                               f'robot profile\'s range [{low:g}, {high:g}] (settable while '
                               'running; default: the deploy config\'s initial command)',
                               low, high))
    return tuple(specs)


def policy_robot(profile: RobotProfile, choice: ControllerChoice, policy) -> 'RobotDescription':
    """The robot description (monitor/robot_description.py: its joints and their plausible
    ranges) whose joint states the learned policy ``policy`` (its controller) reads; NodeStartupError when the
    robot's URDF cannot serve or lacks a joint the policy commands."""
    try:
        robot = profile.sensor_layout().description(profile.urdf_xml())
    except (DescriptionError, OSError) as error:
        raise NodeStartupError(f'robot {profile.name!r}: {error}') from error
    missing = [j for j in policy.joint_names if j not in robot.joint_names]
    if missing:
        raise NodeStartupError(f'controller {choice.name!r} reads joints robot {profile.name!r} '
                               f'does not have: {", ".join(missing)}')
    return robot
