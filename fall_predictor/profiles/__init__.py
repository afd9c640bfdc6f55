"""Robot profiles: one YAML file per robot (``<name>/profile.yaml``, beside its URDF) and their
loader (:mod:`.profile`). Every robot-specific fact of the package lives here.

May import: ``monitor`` (the sole geometry and sensor layout types). Loaded by the onboard
nodes too: nothing here imports the simulator or ROS.
"""
from fall_predictor.profiles.profile import (DEFAULT_ROBOT, FootProfile, ProfileError, RobotProfile,
                                             ServoGains, available_profiles, load_profile,
                                             profile_path, profile_reference)

__all__ = ['DEFAULT_ROBOT', 'FootProfile', 'ProfileError', 'RobotProfile', 'ServoGains',
           'available_profiles', 'load_profile', 'profile_path', 'profile_reference']
