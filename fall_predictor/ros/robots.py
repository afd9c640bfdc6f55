"""Which robot a node serves: the ``robot`` parameter and what it means for the monitor."""
from __future__ import annotations

from fall_predictor.monitor.robot_description import SensorLayout
from fall_predictor.ros.parameters import NodeStartupError, ParamSpec

ROBOT_PARAM = ParamSpec('robot', 'asimo_like', 'robot profile: a profile name or a path to a '
                        'profile file (sole frames and size, IMU frame, foot sensors)',
                        read_only=True)


def sensor_layout_for(robot: str) -> SensorLayout:
    """The monitor's view of robot ``robot`` (NodeStartupError if unknown)."""
    from fall_predictor.robot import model as rm
    if robot == 'asimo_like':
        return rm.SENSOR_LAYOUT
    raise NodeStartupError(f'unknown robot {robot!r}: known robots are asimo_like')


def robot_mass_for(robot: str) -> float:
    """The total mass [kg] of robot ``robot``."""
    from fall_predictor.robot import model as rm
    sensor_layout_for(robot)
    return float(rm.TOTAL_MASS_KG)


def fallen_config_for(robot: str):
    """When robot ``robot`` is down and when it stands again (method §4)."""
    from fall_predictor.monitor.fall_monitor import FallenConfig
    from fall_predictor.monitor.records import FALLEN_COM_HEIGHT_M, GUARD_COM_HEIGHT_M
    sensor_layout_for(robot)
    return FallenConfig(FALLEN_COM_HEIGHT_M, GUARD_COM_HEIGHT_M)
