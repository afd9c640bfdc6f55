"""The simulator seam: what a physics world of a robot is, whichever engine runs it.

A world (:class:`World`) loads one robot (its profile), starts it in a posture, applies joint
commands (:class:`~fall_predictor.robot.control.JointCommand`) through the robot's drives at every
physics step, applies the pushes of the push protocol, steps, and measures: the exact state the
labels and C_bal read (:class:`~fall_predictor.monitor.records.Measurement`) and the exact sensor
quantities the sensor model turns into readings (:class:`~fall_predictor.sim.sensors.SensorTruth`).
Nothing above this seam imports an engine: the push protocol (:class:`~fall_predictor.sim.pushes.
PushProtocol`), the sensor model, the drivers' timing, the ground truth, the recording and the
controllers exist once.

The engines are registered by name in :data:`WORLDS` (the profile's ``simulator:`` and every
``--simulator``/``simulator`` parameter take these names): PyBullet
(:class:`~fall_predictor.sim.pybullet_world.PybulletWorld`, from the URDF) and MuJoCo
(:class:`~fall_predictor.sim.mujoco_world.MujocoWorld`, from the MJCF or the URDF). A third engine
is one module with a class of the :class:`World` methods, constructed as ``cls(profile, dt_s=None,
**options)``, and one line in :data:`WORLDS` (or :func:`register_world` at run time).
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Optional, Protocol, Sequence, Union

import numpy as np

from fall_predictor.monitor.records import Measurement, PushSpec
from fall_predictor.profiles.profile import RobotProfile

#: Contacts reported with less normal force than this carry no load (solver slop) [N], in any
#: engine.
MIN_CONTACT_FORCE_N = 1e-6


@dataclass(frozen=True)
class TerrainContact:
    """One loaded contact of the robot with a terrain box (sim/disturbances.py): which box (its
    index in the terrain), the robot's foot ('l', 'r') or None for another link, the point [m],
    and the forces on the robot [N] along the contact normal and in its plane (friction)."""

    box: int
    side: Optional[str]
    point_m: np.ndarray
    normal_force_n: np.ndarray
    friction_force_n: np.ndarray


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
        """Hold ``command`` (robot/control.JointCommand) until the next one: fitted onto the
        world's joints (:meth:`~fall_predictor.robot.control.JointCommand.fit_onto`), a joint it
        does not name keeping what it held."""

    def schedule_push(self, push: PushSpec) -> None:
        """Apply ``push`` when the world's time reaches its onset."""

    def step(self) -> Measurement:
        """One physics step (drives and push applied), then the new state."""

    def joint_states(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Joint positions [rad], velocities [rad/s] and drive torques [N m] (profile order)."""

    def sensor_truth(self):
        """The exact sensor quantities of the current state (sim/sensors.SensorTruth)."""

    def save_state(self) -> object:
        """A snapshot of the world (an engine's own token) to :meth:`restore` later."""

    def restore(self, state: object, tick: int, measurement: Measurement) -> None:
        """Return to ``state`` (a :meth:`save_state` taken at ``tick``, whose sample was
        ``measurement``), whatever was simulated since; no push pending."""

    def render(self, width: int, height: int, target: Sequence[float], yaw_deg: float,
               pitch_deg: float = -12.0, distance_m: float = 2.6) -> np.ndarray:
        """An RGB image (height, width, 3), the camera ``distance_m`` from ``target`` [m], looking
        along ``yaw_deg`` [deg], ``pitch_deg`` [deg] below the horizon."""

    def close(self) -> None:
        """Release the engine."""

    # -- disturbances beyond pushes (sim/disturbances.py); optional: a world without them runs
    # pushes only, and says so when asked for more ------------------------------------------------
    def set_terrain(self, boxes: Sequence) -> None:
        """Lay ``boxes`` (sim/disturbances.TerrainBox) fixed to the ground from the next
        :meth:`start` on, the robot starting on the highest one under it (none: the flat ground).
        A flush box (a slip's patch, ``TerrainBox.flush``) is part of the ground: the engine lays
        the ground around it as level boxes (``disturbances.ground_around``) with its ground's
        contact properties, and nothing under it."""

    def terrain_contacts(self) -> list[TerrainContact]:
        """The robot's loaded contacts with the terrain boxes at the current step."""

    def set_randomization(self, randomization) -> None:
        """Randomise the world (sim/randomization.WorldRandomization: ground friction, link
        masses, drives) from the next :meth:`start` on; None: the nominal world."""

    def schedule_fault(self, fault) -> None:
        """Apply ``fault`` (sim/disturbances.JointFault; None: none) to the drive of its joint
        from its start on, until the next :meth:`start`."""


#: The registered engines: name -> the world class, or 'module:Class' imported when first used
#: (a robot simulated in one engine never imports another's).
WORLDS: dict[str, Union[str, type]] = {
    'pybullet': 'fall_predictor.sim.pybullet_world:PybulletWorld',
    'mujoco': 'fall_predictor.sim.mujoco_world:MujocoWorld',
}
#: The simulators the package ships, by name (the registry's names at import).
SIMULATORS: tuple[str, ...] = tuple(WORLDS)


def simulator_names() -> tuple[str, ...]:
    """Every registered simulator's name, those registered at run time included."""
    return tuple(WORLDS)


def register_world(name: str, world_class: Union[str, type]) -> None:
    """Register ``world_class`` (a class of the :class:`World` methods, or its 'module:Class') as
    simulator ``name``; an engine of that name already registered is replaced."""
    if not name or not isinstance(name, str):
        raise ValueError(f'a simulator is registered under a non-empty name, got {name!r}')
    WORLDS[name] = world_class


def world_class(simulator: str) -> type:
    """The world class registered as ``simulator`` (ValueError naming the registered ones)."""
    entry = WORLDS.get(simulator)
    if entry is None:
        raise ValueError(f'simulator must be one of {", ".join(WORLDS)}, got {simulator!r}')
    if isinstance(entry, str):
        module, _, name = entry.partition(':')
        entry = getattr(importlib.import_module(module), name)
    return entry


def make_world(profile: RobotProfile, simulator: Optional[str] = None,
               dt_s: Optional[float] = None, **options) -> World:
    """A world of ``profile``'s robot in ``simulator`` (default: the profile's); ``dt_s``: the
    physics step (default: the engine's for this robot: 1 ms in PyBullet, the MJCF's in
    MuJoCo); ``options``: the engine's settings (``PybulletConfig`` fields for PyBullet)."""
    simulator = simulator or profile.simulator
    try:
        cls = world_class(simulator)
    except ValueError as error:
        source = '' if simulator != profile.simulator else f'{profile.source}: '
        raise ValueError(f'{source}{error}') from None
    return cls(profile, dt_s=dt_s, **options)


#: The optional World methods of disturbances beyond pushes.
DISTURBANCE_METHODS = ('set_terrain', 'terrain_contacts', 'schedule_fault')


def require_disturbances(world: World, cause: str) -> None:
    """ValueError, naming the engine, when ``world`` cannot lay terrain or fail a joint."""
    missing = [name for name in DISTURBANCE_METHODS if not callable(getattr(world, name, None))]
    if missing:
        raise ValueError(f'the {type(world).__name__} world cannot simulate a {cause}: it lacks '
                         f'{", ".join(missing)} (sim/world.py World)')
