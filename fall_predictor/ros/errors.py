"""Errors of the ROS side that light modules raise (no rclpy import here)."""
from __future__ import annotations


class BringupError(RuntimeError):
    """The bring-up failed (a node did not start or died, the simulation got stuck)."""
