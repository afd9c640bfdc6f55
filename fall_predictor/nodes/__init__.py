"""The onboard fall monitor as ROS 2 nodes (rclpy), one module per node.

``simulator_node`` (the robot), ``controller_node`` (C_bal, then C_fall), ``feature_node``
(features and contact mode), ``predictor_node`` (the fall prediction on
``/fall_predictor/state``) and ``recorder_node`` (bags); :mod:`.common` holds what they share.
Run one with ``python -m fall_predictor.nodes.<node> --ros-args --params-file
config/fall_predictor.yaml``, all of them with :mod:`fall_predictor.bringup` or
``launch/fall_predictor.launch.py``.
"""
from __future__ import annotations

from pathlib import Path

from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

PACKAGE = 'fall_predictor'


def package_share_dir() -> Path:
    """The package's share directory (``config/``, ``models/``, ``launch/``): from the ament
    index when the package is installed, else the source tree holding ``fall_predictor/``."""
    try:
        return Path(get_package_share_directory(PACKAGE))
    except (PackageNotFoundError, OSError):
        return Path(__file__).resolve().parents[2]
