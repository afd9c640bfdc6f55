"""The simulator seam: what a physics world of a robot is, whichever engine runs it.

A world (:class:`World`) loads one robot (its profile), starts it in a posture, applies joint
commands (:class:`~fall_predictor.robot.control.JointCommand`) through the robot's drives at every
physics step, applies the pushes of the push protocol, steps, and measures: the exact state the
labels and C_bal read (:class:`~fall_predictor.monitor.records.Measurement`) and the exact sensor
quantities the sensor model turns into readings (:class:`~fall_predictor.sim.sensors.SensorTruth`).
Two engines implement it: PyBullet (:class:`~fall_predictor.sim.simulator.Simulator`, from the
URDF) and MuJoCo (:class:`~fall_predictor.sim.mujoco_world.MujocoWorld`, from the MJCF or the
URDF). Nothing above this seam imports an engine: the push protocol (:class:`~fall_predictor.sim.
pushes.PushProtocol`), the
sensor model, the drivers' timing, the ground truth, the recording and the controllers exist once.
"""
from __future__ import annotations

from typing import Optional, Protocol

import numpy as np

from fall_predictor.monitor.records import Measurement, PushSpec
from fall_predictor.profiles import RobotProfile
from fall_predictor.profiles.profile import SIMULATORS


class World(Protocol):
    """A physics world of one robot (module docstring)."""

    profile: RobotProfile
    #: Physics step [s]; the current time [s] and step count.
    dt_s: float
    t: float
    tick: int
    #: The robot's movable joints, in the profile's order (the order of joint_states()).
    joint_names: tuple[str, ...]

    def start(self, posture) -> Measurement:
        """A fresh world with the robot at rest in ``posture`` (robot/control.Posture); the first
        sample."""

    def apply(self, command) -> None:
        """Hold ``command`` (robot/control.JointCommand) until the next one."""

    def schedule_push(self, push: PushSpec) -> None:
        """Apply ``push`` when the world's time reaches its onset."""

    def step(self) -> Measurement:
        """One physics step (drives and push applied), then the new state."""

    def joint_states(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Joint positions [rad], velocities [rad/s] and drive torques [N m] (profile order)."""

    def sensor_truth(self):
        """The exact sensor quantities of the current state (sim/sensors.SensorTruth)."""

    def close(self) -> None:
        """Release the engine."""


def make_world(profile: RobotProfile, simulator: Optional[str] = None,
               dt_s: Optional[float] = None, **options) -> World:
    """A world of ``profile``'s robot in ``simulator`` (default: the profile's); ``dt_s``: the
    physics step (default: the engine's for this robot: 1 ms in PyBullet, the MJCF's in
    MuJoCo); ``options``: the engine's settings (``SimulatorConfig`` fields for PyBullet)."""
    simulator = simulator or profile.simulator
    if simulator not in SIMULATORS:
        raise ValueError(f'simulator must be one of {SIMULATORS}, got {simulator!r}')
    if simulator == 'mujoco':
        from fall_predictor.sim.mujoco_world import MujocoWorld
        return MujocoWorld(profile, dt_s=dt_s, **options)
    from dataclasses import replace

    from fall_predictor.sim.simulator import Simulator, SimulatorConfig
    config = SimulatorConfig(**options)
    if dt_s is not None:
        config = replace(config, dt_s=dt_s)
    return Simulator(config, profile)
