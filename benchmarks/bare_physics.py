"""Bare physics of the same motion: the PyBullet calls that drive a simulation, recorded, then
replayed alone into a fresh world (for the speed benchmarks).

"Bare PyBullet stepping of the same robot" must step the same contacts as the simulation it is
compared with. Stepping the robot from its first posture without its servos lets it collapse:
lying on the ground with some twenty contact points, it costs about twice what the walking robot
costs per step, and made the simulator look twice as close to its physics as it is. Here the
joint torques and push forces the simulation sent are replayed call for call, and the replay must
end where the simulation ended (:data:`MAX_POSE_ERROR_M`), so both stepped the same motion.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
import pybullet

from fall_predictor.sim import pybullet_world as simulator_module
from fall_predictor.sim.pybullet_world import PybulletWorld

#: The calls that drive the physics (everything else only reads it).
RECORDED = ('setJointMotorControlArray', 'applyExternalForce', 'stepSimulation')

#: How far the replay's final base pose may be from the simulation's (m, and unit quaternion).
MAX_POSE_ERROR_M = 1e-9


class RecordingPyBullet:
    """pybullet, with the calls that drive the physics recorded (cleared on every reset)."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, tuple, dict]] = []

    def __getattr__(self, name: str) -> Any:
        real = getattr(pybullet, name)
        if name == 'resetSimulation':
            def reset(*args, **kwargs):
                self.calls.clear()
                return real(*args, **kwargs)
            return reset
        if name not in RECORDED:
            return real

        def record(*args, **kwargs):
            self.calls.append((name, args, kwargs))
            return real(*args, **kwargs)
        return record


def base_pose(sim: PybulletWorld) -> np.ndarray:
    """The base's position and quaternion, as one 7-vector."""
    return np.concatenate(pybullet.getBasePositionAndOrientation(sim.robot, physicsClientId=sim.client))


def record_calls(run: Callable[[], PybulletWorld]) -> tuple[list[tuple[str, tuple, dict]], np.ndarray]:
    """The physics-driving calls ``run`` makes through the simulator module (from its last
    reset on), and the base pose of the simulator it returns at the end."""
    proxy = RecordingPyBullet()
    simulator_module.pb = proxy
    try:
        sim = run()
    finally:
        simulator_module.pb = pybullet
    return proxy.calls, base_pose(sim)


def replay(sim: PybulletWorld, joint_positions, torso_position,
           calls: list[tuple[str, tuple, dict]]) -> tuple[float, int, np.ndarray]:
    """Bare physics: ``sim`` reset to the recorded run's first posture, then ``calls`` only.
    Returns the CPU seconds of the replay loop, its physics steps, and the final base pose."""
    sim.reset(joint_positions, torso_position)
    functions = {name: getattr(pybullet, name) for name in RECORDED}
    bound = [(functions[name], args, kwargs) for name, args, kwargs in calls]
    cpu0 = time.process_time()
    for function, args, kwargs in bound:
        function(*args, **kwargs)
    cpu = time.process_time() - cpu0
    steps = sum(1 for name, _, _ in calls if name == 'stepSimulation')
    return cpu, steps, base_pose(sim)
