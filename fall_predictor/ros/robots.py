"""Which robot a node serves: the ``robot`` parameter, read as a robot profile (profiles/)."""
from __future__ import annotations

from fall_predictor.monitor.fall_monitor import FallenConfig
from fall_predictor.profiles.profile import DEFAULT_ROBOT, ProfileError, RobotProfile, load_profile
from fall_predictor.ros.parameters import NodeStartupError, ParamSpec

ROBOT_PARAM = ParamSpec('robot', DEFAULT_ROBOT, 'robot profile: a shipped profile name or the path '
                        'to a profile file (URDF, sole frames and size, IMU frame, foot sensors, '
                        'mass)', read_only=True)


#: Profiles whose static checks passed in this process (a node asks more than once).
_CHECKED: set = set()


def profile_for(robot: str) -> RobotProfile:
    """The profile of ``robot`` once the static part of ``fall-predictor check`` passes
    (sim/checks.py: the profile, URDF, MJCF, deploy configs and networks); NodeStartupError with
    the first failure in one line (file, field, what to do) otherwise."""
    from fall_predictor.errors import one_line
    try:
        profile = load_profile(robot)
        if profile.source not in _CHECKED:
            from fall_predictor.sim.checks import require_static_checks
            require_static_checks(robot)
            _CHECKED.add(profile.source)
        return profile
    except ProfileError as exc:
        error = NodeStartupError(f'robot profile: {one_line(exc)}')
        error.team_file = True              # exit 2 (ros/runner.py): a mistake in a team's file
        raise error from exc


def fallen_config_for(robot: str) -> FallenConfig:
    """When robot ``robot`` is down and when it stands again (method §4)."""
    profile = profile_for(robot)
    return FallenConfig(profile.fallen_com_height_m, profile.guard_com_height_m)
