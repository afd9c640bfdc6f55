"""Which robot a node serves: the ``robot`` parameter, read as a robot profile (profiles/)."""
from __future__ import annotations

from fall_predictor.monitor.fall_monitor import FallenConfig
from fall_predictor.profiles import DEFAULT_ROBOT, ProfileError, RobotProfile, load_profile
from fall_predictor.ros.parameters import NodeStartupError, ParamSpec

ROBOT_PARAM = ParamSpec('robot', DEFAULT_ROBOT, 'robot profile: a shipped profile name or the path '
                        'to a profile file (URDF, sole frames and size, IMU frame, foot sensors, '
                        'mass)', read_only=True)


def profile_for(robot: str) -> RobotProfile:
    """The profile of ``robot``; NodeStartupError (with the profile's complaint) if it cannot load."""
    try:
        return load_profile(robot)
    except ProfileError as exc:
        raise NodeStartupError(f'robot profile: {exc}') from exc


def fallen_config_for(robot: str) -> FallenConfig:
    """When robot ``robot`` is down and when it stands again (method §4)."""
    profile = profile_for(robot)
    return FallenConfig(profile.fallen_com_height_m, profile.guard_com_height_m)
