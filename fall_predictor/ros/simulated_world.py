"""What the simulator and controller nodes share about the simulated robot: which controller walks
it and in which simulator (the ``controller`` and ``simulator`` parameters), the world built for
them, and the joint command the robot's drives apply to a command message.

A robot profile names its simulator and its default controller (C_bal, or a team's learned
walking policy): the nodes take those unless their parameters say otherwise. The world steps at
the physics step the controller needs: a learned policy's deploy config's (its PD loop ran at that
step in training and in its team's sim2sim), else the engine's own for the robot (PyBullet 1 ms,
the MJCF's in MuJoCo). The joint command topic carries targets only (``sensor_msgs/JointState``,
position field); the gains that track them are the drives' configuration, as on a robot: a
policy's deploy config's ``kp``/``kd`` (and torque limits), or the robot's own servos for C_bal
(:class:`~fall_predictor.robot.control.JointCommand` with gains None).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from fall_predictor.profiles.profile import ProfileError, RobotProfile
from fall_predictor.profiles.profile import C_BAL, PolicyControllerProfile
from fall_predictor.sim.world import SIMULATORS
from fall_predictor.robot.control import JointCommand, Posture
from fall_predictor.robot.policy_config import PolicyConfigError, load_policy_config
from fall_predictor.ros.parameters import NodeStartupError, ParamSpec
from fall_predictor.sim.drivers import DriverTiming

CONTROLLER_PARAM = ParamSpec(
    'controller', '', f"the walking controller: {C_BAL!r} (the balance controller) or a learned "
    "policy the robot profile names; '' = the profile's default controller", read_only=True)
SIMULATOR_PARAM = ParamSpec(
    'simulator', '', f"the simulator: {' or '.join(repr(s) for s in SIMULATORS)}; '' = the robot "
    "profile's", read_only=True)


@dataclass(frozen=True)
class ControllerChoice:
    """Who walks the robot and where: the controller's name, the simulator's, and the learned
    policy's profile entry (None for C_bal)."""

    name: str
    simulator: str
    policy: Optional[PolicyControllerProfile]

    @property
    def is_policy(self) -> bool:
        return self.policy is not None


def controller_choice(profile: RobotProfile, controller: str, simulator: str) -> ControllerChoice:
    """The choice of the ``controller`` and ``simulator`` parameters ('' = the profile's);
    NodeStartupError naming what the profile has when it has no such controller or simulator."""
    if simulator and simulator not in SIMULATORS:
        raise NodeStartupError(f'simulator must be one of {", ".join(SIMULATORS)} (or \'\' for the '
                               f'robot profile\'s, {profile.simulator}), got {simulator!r}')
    name = controller or profile.default_controller
    try:
        policy = profile.controller_profile(name)
    except ProfileError as error:
        raise NodeStartupError(str(error)) from error
    return ControllerChoice(name, simulator or profile.simulator, policy)


def physics_step_s(profile: RobotProfile, choice: ControllerChoice) -> float:
    """The world's physics step [s] for ``choice`` (module docstring), without building the world
    (a MuJoCo model is loaded to read its timestep)."""
    if choice.policy is not None:
        return _policy_config(choice.policy).physics_dt_s
    if choice.simulator == 'mujoco':
        from fall_predictor.sim.mujoco_model import load_model
        return float(load_model(profile).opt.timestep)
    from fall_predictor.sim.pybullet_world import PybulletConfig
    return PybulletConfig().dt_s


def _policy_config(policy: PolicyControllerProfile):
    try:
        return load_policy_config(policy.policy_path, check_network=False)
    except PolicyConfigError as error:
        raise NodeStartupError(f'controller {policy.name!r}: {error}') from error


def make_node_world(profile: RobotProfile, choice: ControllerChoice):
    """The world (sim/world.py) of ``choice``: its simulator, at the policy's physics step or the
    engine's own; NodeStartupError when the engine cannot load the robot."""
    from fall_predictor.sim.world import make_world
    dt_s = None if choice.policy is None else _policy_config(choice.policy).physics_dt_s
    try:
        return make_world(profile, choice.simulator, dt_s)
    except (RuntimeError, ValueError, OSError) as error:
        raise NodeStartupError(f'{choice.simulator} cannot simulate robot {profile.name!r}: '
                               f'{error}') from error


def walking_controller(profile: RobotProfile, choice: ControllerChoice, **settings):
    """``choice``'s walking controller (robot/control.make_controller, the one place a controller
    is built; ``settings`` go to it); NodeStartupError saying why it cannot be built."""
    from fall_predictor.robot.control import make_controller
    try:
        return make_controller(profile, choice.name, **settings)
    except (ValueError, OSError, RuntimeError) as error:
        raise NodeStartupError(f'controller {choice.name!r}: {error}') from error


class CommandDrives:
    """The robot's drives: a joint command message's targets (every joint of the robot, in the
    profile's order) -> the :class:`JointCommand` the world applies, fitted onto the joints the
    walking controller commands with its drives' gains and torque limits (a learned policy's), or
    tracked by the robot's servos (C_bal)."""

    def __init__(self, profile: RobotProfile, controller) -> None:
        """``controller``: the walking controller (robot/control.Controller) whose drives track the
        commands."""
        self.joint_names = tuple(profile.joint_names)
        held = controller.hold_command()
        missing = [j for j in held.joint_names if j not in self.joint_names]
        if missing:
            raise NodeStartupError(f'controller {controller.name!r} commands joints robot '
                                   f'{profile.name!r} does not have: {", ".join(missing)}')
        #: The drives' configuration: the controller's joints with its gains (None: the servos).
        self._drives: Optional[JointCommand] = held if held.has_gains else None
        #: Where the controller's runs start.
        self.posture: Posture = controller.initial_posture()

    def __call__(self, targets_rad: np.ndarray) -> JointCommand:
        """The command of ``targets_rad`` (the robot's joints in profile order)."""
        command = JointCommand(self.joint_names, np.asarray(targets_rad, dtype=np.float64))
        if self._drives is None:
            return command
        return command.fit_onto(self._drives.joint_names, self._drives)


def check_policy_timing(timing: DriverTiming, dt_s: float, choice: ControllerChoice) -> None:
    """A learned policy answers each joint state sample, and the lock-stepped simulator awaits the
    answer to every physics step: joint states and IMU readings must come at every step
    (NodeStartupError saying which rate is too low)."""
    for name, rate in (('sensor_joint_rate_hz', timing.joint_rate_hz),
                       ('sensor_imu_rate_hz', timing.imu_rate_hz)):
        if rate * dt_s < 1.0 - 1e-9:
            raise NodeStartupError(
                f'controller {choice.name!r} is a learned policy that answers every physics step '
                f'({dt_s * 1e3:g} ms) from the sensors of that step: {name} = {rate:g} Hz is below '
                f'{1.0 / dt_s:g} Hz')
