"""What a team's deploy config and network can get wrong, found before any simulation (method §13).

For each learned controller a profile names (``controllers.<name>.policy``): the deploy config
reads (robot/policy_config.py); its joints are the URDF's; the network loads and its sizes fit
(observation = network input, network output = actions = joints); the PD gains are present and
positive; the action scale is positive; the default angles are radians inside the joints' limits;
and, run for a second at the default posture with the robot upright and still, the network's
actions are finite and bounded (a network whose weights overflow gives NaN or inf: named here,
never as a joint target deep in a simulation).
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from fall_predictor.profiles.checks import Check, failed, nearest, passed
from fall_predictor.profiles.profile import PolicyControllerProfile, RobotProfile

#: Policy steps run at the default posture to check the actions.
STILL_STEPS = 50
#: |action x action_scale| above this at the default posture, upright and still [rad]: a target
#: this far from the default angles is no stance.
MAX_STILL_TARGET_OFFSET_RAD = 1.5
#: The network's own actions at rest beyond this: the network (or its input) is wrong, not the
#: scale (Unitree's G1 policy: up to 1.4).
MAX_STILL_ACTION = 20.0
#: A default angle beyond this [rad] is no joint angle of a humanoid: degrees, most likely.
DEGREES_LIKE_RAD = math.pi
#: Default angles may sit this far outside the URDF's limits [rad] (rounding of published values).
LIMIT_SLACK_RAD = 0.02


def policy_checks(profile: RobotProfile, policy: PolicyControllerProfile,
                  joint_limits: dict[str, tuple[float, float]]) -> list[Check]:
    """The checks of ``policy`` (module docstring); ``joint_limits``: the URDF's movable joints,
    name -> (lower, upper) [rad]."""
    from fall_predictor.robot.networks import load_network
    from fall_predictor.robot.policy_config import PolicyConfigError, read_policy_config

    label = f'{policy.name}: '
    try:
        config = read_policy_config(policy.policy_path)
    except PolicyConfigError as error:
        field = _field(str(error), policy.policy_path)
        found = _without(str(error), policy.policy_path)
        if field and found.startswith(f'{field}: '):
            found = found[len(field) + 2:]
        return [failed(label + 'deploy config', found,
                       'fix that field (robot/policy_config.py documents each)',
                       policy.policy_path, field)]
    checks = [passed(label + 'deploy config', f'{config.observation_layout} observation of '
                     f'{config.obs_size}, {config.num_actions} joints at {1 / config.period_s:g} Hz')]
    unknown = [j for j in config.joint_names if j not in joint_limits]
    if unknown:
        checks.append(failed(label + 'policy joints', f'{unknown[0]!r} is not a movable joint of '
                             f'{profile.urdf_path.name}{nearest(unknown[0], joint_limits)}',
                             'list the URDF/MJCF joint of each action in joint_names',
                             config.source, 'joint_names'))
        return checks
    try:
        network = load_network(config.policy_path)
    except (ValueError, OSError, EOFError) as error:
        return checks + [failed(label + 'network', _without(str(error), str(config.policy_path)),
                                'export the policy again (TorchScript .pt or ONNX)',
                                config.policy_path, 'policy_path')]
    try:
        config.check_network(network)
    except PolicyConfigError as error:
        field = 'joint_names' if 'actions' in str(error) else 'observation'
        return checks + [failed(label + 'network sizes', _without(str(error), config.source)
                                .replace('policy_path ', ''), 'make the observation (layout, '
                                'terms, frame_stack) and joint_names fit the network',
                                config.source, field)]
    checks.append(passed(label + 'network sizes', f'{config.policy_path.name}: {network.input_size}'
                         f' inputs = the observation, {network.output_size} outputs = the joints'))
    checks += _gains_and_scale(config, label)
    checks.append(_default_angles(config, joint_limits, label))
    checks.append(_still_actions(config, network, label))
    return checks


def _gains_and_scale(config, label: str) -> list[Check]:
    checks = []
    for field, values in (('kps', config.kp), ('kds', config.kd)):
        bad = [j for j, v in zip(config.joint_names, values) if not v > 0]
        if bad:
            checks.append(failed(label + 'PD gains', f'{field} is not > 0 for {", ".join(bad[:3])}'
                                 + (' ...' if len(bad) > 3 else ''), f'give each joint a {field} > 0 '
                                 '(the drives\' gains the policy was trained with: with none the '
                                 'joint is limp or oscillates)', config.source, field))
    if not checks:
        checks.append(passed(label + 'PD gains', 'kps and kds > 0 for every joint'))
    if any(s <= 0 for s in config.action_scale):
        checks.append(failed(label + 'action scale', f'action_scale {min(config.action_scale):g} is '
                             'not > 0: every target moves against the action',
                             'write the positive scale the policy was trained with',
                             config.source, 'action_scale'))
    return checks


def _default_angles(config, limits: dict[str, tuple[float, float]], label: str) -> Check:
    angles = dict(zip(config.joint_names, config.default_angles_rad))
    degrees = {j: a for j, a in angles.items() if abs(a) > DEGREES_LIKE_RAD}
    if degrees:
        return failed(label + 'default angles', 'look like degrees: ' + ', '.join(
            f'{j} {a:g}' for j, a in list(degrees.items())[:3]), 'write them in radians ('
            + ', '.join(f'{math.radians(a):.3f}' for a in list(degrees.values())[:3]) + ' ...)',
            config.source, 'default_angles')
    outside = {j: a for j, a in angles.items()
               if not limits[j][0] - LIMIT_SLACK_RAD <= a <= limits[j][1] + LIMIT_SLACK_RAD}
    if outside:
        j, a = next(iter(outside.items()))
        return failed(label + 'default angles', f'{j} {a:g} rad is outside its URDF limits '
                      f'[{limits[j][0]:g}, {limits[j][1]:g}]', 'write the default posture in '
                      'radians, in joint_names order', config.source, 'default_angles')
    return passed(label + 'default angles', 'radians, inside the URDF limits')


def _still_actions(config, network, label: str) -> Check:
    """One second of policy steps at the default posture, upright, still, at the initial
    command: every action finite, every target near the default angles."""
    from fall_predictor.monitor.sensor_records import SensorSample
    from fall_predictor.robot.learned_policy import LearnedPolicy, NonFiniteActions

    policy = LearnedPolicy(config, network)
    n = config.num_actions
    sample = SensorSample(0.0, config.joint_names, np.asarray(config.default_angles_rad),
                          np.zeros(n), np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3),
                          np.array([0.0, 0.0, 9.81]))
    default = np.asarray(config.default_angles_rad)
    largest = largest_action = 0.0
    try:
        with np.errstate(all='ignore'):     # overflowing weights: said below, not as warnings
            for k in range(STILL_STEPS):
                targets = policy.act(k * config.period_s, sample, config.command_init)
                largest = max(largest, float(np.max(np.abs(targets - default))))
                largest_action = max(largest_action, float(np.max(np.abs(policy.last_action))))
    except NonFiniteActions as error:
        return failed(label + 'actions at rest', error.problem, error.fix or '',
                      config.policy_path, 'policy_path')
    finally:
        network.reset()
    if largest > MAX_STILL_TARGET_OFFSET_RAD:
        found = (f'standing still at the default posture the targets move up to {largest:.2f} rad '
                 f'from the default angles (actions up to {largest_action:.1f})')
        if largest_action <= MAX_STILL_ACTION:          # ordinary actions, scaled too far
            return failed(label + 'actions at rest', found, 'write the action_scale the policy '
                          'was trained with (legged_gym: 0.25; radians per action unit)',
                          config.source, 'action_scale')
        return failed(label + 'actions at rest', found, 'check the network\'s weights and the '
                      'observation\'s scales', config.policy_path, 'policy_path')
    return passed(label + 'actions at rest', f'finite, targets within {largest:.2f} rad of the '
                  f'default posture over {STILL_STEPS} steps')


def _without(message: str, path) -> str:
    return message.replace(f'{path}: ', '', 1)


def _field(message: str, path) -> Optional[str]:
    head = _without(message, path).split(':', 1)[0]
    return head if head and ' ' not in head else None
