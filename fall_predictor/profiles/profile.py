"""Robot profiles: everything the package knows of a robot beyond its URDF, in one file per robot.

A profile is a YAML file (``profiles/<name>/profile.yaml`` for the shipped robots, or any path a
user gives with ``--robot PATH`` or the nodes' ``robot`` parameter). Paths inside it are relative
to the file. What it holds (method §1, §10):

- the robot description: the URDF the monitor and Pinocchio read, and the one the simulator loads
  (which may differ: PyBullet needs meshes, and numbers joints depth-first);
- the feet: the link each sole is fixed to, the sole frame (taken from the URDF when it has it,
  else added at ``sole_origin_in_foot_m`` in the foot link's frame), the sole rectangle, and the
  foot's force/torque sensor frame, or none;
- the IMU frame of readings that name none; the total mass;
- when the robot is down and the CoM guard (method §4, §6), scaled to the robot's size;
- joint groups (legs in hip-to-ankle order, arms, head), servo gains per group, the posture held
  outside the legs, and the push forces that make the dataset's fall fraction (method §3);
- the simulator the robot runs in (PyBullet from its URDF, or MuJoCo from its MJCF or URDF) and
  the controllers it walks with: the package's C_bal and any learned policy of its team, each
  with its own push range and shipped model (method §13):

      controllers:
        unitree_rl_gym:
          policy: controllers/unitree_rl_gym/policy.yaml  # the team's deploy config (robot/
                                                          # policy_config.py), its network beside it
          push_force_n: [0.0, 800.0]     # the push range of this controller's datasets (method §3)
          command:                       # commanded velocities drawn per run, uniform
            vx_m_s: [0.0, 0.6]
            vy_m_s: [-0.3, 0.3]
            yaw_rate_rad_s: [-0.5, 0.5]
          settle_s: 2.0                  # walking before the push window opens [s]
          model: g1_unitree_rl_model.json   # the shipped model for this robot and controller
      default_controller: unitree_rl_gym
      simulator: mujoco                  # pybullet (default) or mujoco
      mjcf: scene.xml                    # MuJoCo's model (else MuJoCo loads the URDF)

Nothing here imports the simulator or ROS: the onboard monitor loads profiles too.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional, Union

import yaml

from fall_predictor.monitor.lowstate import LowStateProfile, parse_unitree_hg
from fall_predictor.errors import TeamFileError
from fall_predictor.monitor.records import SoleGeometry
from fall_predictor.profiles.controller_entries import (C_BAL, PolicyControllerProfile, _mapping,
                                                       parse_controllers)
from fall_predictor.monitor.robot_description import SIDES, SensorLayout, joint_limits_of

PROFILES_DIR = Path(__file__).resolve().parent
PROFILE_FILE = 'profile.yaml'
#: The robot every command and node serves unless told otherwise.
DEFAULT_ROBOT = 'asimo_like'


class ProfileError(TeamFileError):
    """A robot profile is missing or malformed; the message names the file and the key."""


@dataclass(frozen=True)
class FootProfile:
    """One foot: where its sole is and what measures its contact."""

    side: str                                   #: 'l' or 'r'
    foot_link: str                              #: the URDF link the sole is fixed to
    sole_frame: str                             #: origin at the sole's centre, x forward, z up
    sole_length_m: float
    sole_width_m: float
    #: The sole frame's origin in the foot link's frame [m] (used when the URDF lacks the frame).
    sole_origin_in_foot_m: tuple[float, float, float]
    #: The frame the foot's force/torque sensor reports in; None: the foot has no F/T sensor.
    force_torque_frame: Optional[str]
    #: The sole frame's axes turned from the foot link's (URDF roll, pitch, yaw [rad]): for a
    #: foot link whose axes are not x forward, z up when the robot stands.
    sole_rpy_in_foot_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def sole(self) -> SoleGeometry:
        return SoleGeometry(self.sole_frame, self.sole_length_m, self.sole_width_m,
                            self.foot_link, self.sole_origin_in_foot_m, self.sole_rpy_in_foot_rad)

    def sole_rotation_in_foot(self):
        """The sole frame's rotation in the foot link's frame (a 3 x 3 array)."""
        from fall_predictor.monitor.rotations import rpy_matrix
        return rpy_matrix(*self.sole_rpy_in_foot_rad)


@dataclass(frozen=True)
class ServoGains:
    """One joint's PD loop and drive: gains, passive damping and reflected rotor inertia."""

    kp_nm_per_rad: float
    kd_nms_per_rad: float
    damping_nms: float
    armature_kgm2: float


@dataclass(frozen=True)
class RobotProfile:
    """One robot, as :func:`load_profile` reads it from its profile file."""

    name: str
    description: str
    source: Path                                #: the profile file
    urdf_path: Path                             #: the robot description (monitor, Pinocchio)
    sim_urdf_path: Path                         #: what the simulator loads
    total_mass_kg: float
    imu_frame: str
    feet: dict[str, FootProfile]
    fallen_com_height_m: float                  #: below this CoM height the robot is down
    guard_com_height_m: float                   #: the CoM guard of the predictor (method §6)
    joint_groups: dict[str, tuple[str, ...]]
    servo_gains: dict[str, ServoGains] = field(default_factory=dict)
    push_force_n: tuple[float, float] = (0.0, 0.0)
    #: Its datasets draw a gait per trajectory (method §3); False: they walk the profile's gait.
    gait_variety: bool = True
    #: The simulated ground's shape: 'plane' (infinite) or 'slab' (a box with the same top face,
    #: which spares PyBullet testing links far above it; sim/pybullet_world.py).
    sim_ground: str = 'plane'
    #: The balance controller's settings that differ for this robot: per part ('gait', 'reflex',
    #: 'stabilizer'), field -> value (robot/balance_controller.py GaitConfig, ReflexConfig, ...).
    controller: dict[str, dict[str, Union[float, bool]]] = field(default_factory=dict)
    #: Joint angles [rad] of the posture the controller holds outside the legs (others: zero).
    posture: dict[str, float] = field(default_factory=dict)
    #: The shipped model trained on this robot and its default controller: a file name in the
    #: package's models/.
    model: str = 'default_model.json'
    #: The simulator the robot runs in unless told otherwise: 'pybullet' or 'mujoco'.
    simulator: str = 'pybullet'
    #: MuJoCo's model of the robot (a scene with its ground), or None: MuJoCo loads the URDF.
    mjcf_path: Optional[Path] = None
    #: The learned policies the robot walks with, by name (C_bal needs no entry: C_BAL).
    controllers: dict[str, PolicyControllerProfile] = field(default_factory=dict)
    #: The controller of its datasets and nodes unless told otherwise.
    default_controller: str = C_BAL
    #: How a Unitree humanoid's ``lowstate`` names its motors (monitor/lowstate.py), or None.
    unitree_hg: Optional[LowStateProfile] = None
    #: ``monitor.joint_limits``: per joint, the limits the monitor judges its encoders by in
    #: place of the URDF's (``lower_rad``, ``upper_rad``, ``velocity_rad_s``; any of them).
    joint_limits: dict[str, dict[str, float]] = field(default_factory=dict)
    #: C_bal's datasets' ranges of the disturbances beyond pushes (profiles/cause_ranges.py).
    causes: dict = field(default_factory=dict)

    # -- controllers -------------------------------------------------------------------------
    @property
    def controller_names(self) -> tuple[str, ...]:
        """Every controller the robot can walk with: C_bal, then its learned policies."""
        return (C_BAL, *self.controllers)

    def controller_profile(self, name: Optional[str] = None) -> Optional[PolicyControllerProfile]:
        """The learned policy ``name`` (default: the robot's default controller), or None for
        C_bal; ProfileError for a controller the profile does not know."""
        name = name or self.default_controller
        if name == C_BAL:
            return None
        if name not in self.controllers:
            raise ProfileError(f'{self.source}: robot {self.name!r} has no controller {name!r}; '
                               f'it has {", ".join(self.controller_names)}')
        return self.controllers[name]

    def model_for(self, controller: Optional[str] = None) -> str:
        """The shipped model of this robot and ``controller`` (default: its default one):
        C_bal's is the profile's ``model`` (when C_bal is not the default, ProfileError)."""
        name = controller or self.default_controller
        policy = self.controller_profile(name)
        if policy is None:
            if self.default_controller != C_BAL:
                raise ProfileError(f'{self.source}: robot {self.name!r} ships no model for '
                                   f'{C_BAL!r}')
            return self.model
        return policy.model or self.model

    def push_force_range_n(self, controller: Optional[str] = None) -> tuple[float, float]:
        """The push force range of ``controller``'s datasets [N] (method §3)."""
        policy = self.controller_profile(controller)
        return self.push_force_n if policy is None else policy.push_force_n

    def cause_ranges(self, controller: Optional[str] = None) -> dict:
        """``controller``'s ranges of the disturbances beyond pushes (profiles/cause_ranges.py)."""
        policy = self.controller_profile(controller)
        return self.causes if policy is None else policy.causes

    # -- what the monitor needs --------------------------------------------------------------
    def sensor_layout(self) -> SensorLayout:
        """Soles, IMU frame and the feet with a force/torque sensor."""
        return SensorLayout({side: self.feet[side].sole() for side in SIDES}, self.imu_frame,
                            tuple(side for side in SIDES if self.feet[side].force_torque_frame),
                            self.joint_limits)

    def urdf_xml(self) -> str:
        """The robot description's text (``/robot_description``)."""
        return self.urdf_path.read_text()

    # -- joints --------------------------------------------------------------------------------
    @functools.cached_property
    def joint_names(self) -> tuple[str, ...]:
        """The movable joints in the simulator URDF's order (the order of the controller's joint
        vectors; Pinocchio's own order may differ)."""
        import xml.etree.ElementTree as ET
        root = ET.parse(self.sim_urdf_path).getroot()
        return tuple(j.get('name') for j in root.iter('joint')
                     if j.get('type') in ('revolute', 'continuous', 'prismatic'))

    def leg_joints(self, side: str) -> tuple[str, ...]:
        """The joints of leg ``side`` from hip to ankle."""
        return self.joint_groups[f'{side}_leg']

    def legs_and_upper_body(self) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """Both legs' joints (left then right) and every other joint, in the joint order: the
        two joint state messages of a robot whose legs and upper body have their own drivers."""
        legs = self.leg_joints('l') + self.leg_joints('r')
        return legs, tuple(n for n in self.joint_names if n not in legs)

    def group_of(self, joint: str) -> str:
        """The joint group ``joint`` belongs to (ProfileError if none)."""
        for group, joints in self.joint_groups.items():
            if joint in joints:
                return group
        raise ProfileError(f'{self.source}: joint {joint!r} is in no joint group')

    def gains_for(self, joint: str) -> ServoGains:
        """The servo gains of ``joint``: by its name without the side prefix, else by its name."""
        for key in (joint, _unsided(joint)):
            if key in self.servo_gains:
                return self.servo_gains[key]
        raise ProfileError(f'{self.source}: no servo_gains entry for joint {joint!r} '
                           f'(looked for {joint!r} and {_unsided(joint)!r})')


def _unsided(joint: str) -> str:
    for prefix in ('l_', 'r_', 'left_', 'right_'):
        if joint.startswith(prefix):
            return joint[len(prefix):]
    return joint


def available_profiles() -> tuple[str, ...]:
    """The names of the shipped robot profiles."""
    return tuple(sorted(p.parent.name for p in PROFILES_DIR.glob(f'*/{PROFILE_FILE}')))


def profile_path(robot: Union[str, Path]) -> Path:
    """The profile file of ``robot``: a shipped profile's name, or a path to a profile file."""
    text = str(robot)
    if text.endswith(('.yaml', '.yml')) or '/' in text:
        path = Path(text).expanduser()
        if path.is_dir() and (path / PROFILE_FILE).is_file():     # the profile's folder
            path = path / PROFILE_FILE
        if not path.is_file():
            raise ProfileError(f'robot profile {text!r}: no such file')
        return path.resolve()
    path = PROFILES_DIR / text / PROFILE_FILE
    if not path.is_file():
        import difflib
        near = difflib.get_close_matches(text, available_profiles(), n=1)
        raise ProfileError(f'unknown robot {text!r}' + (f' (did you mean {near[0]!r}?)' if near else '')
                           + f': the shipped profiles are {", ".join(available_profiles())}; or give '
                           'the path to a profile file')
    return path


def profile_reference(robot: Union[str, Path]) -> str:
    """How a dataset's manifest names ``robot``'s profile: a shipped profile by its name (the
    dataset moves between machines), any other by its file's absolute path (the dataset is read
    from other working directories)."""
    return str(robot) if str(robot) in available_profiles() else str(profile_path(robot))


_CACHE: dict[Path, RobotProfile] = {}


def load_profile(robot: Union[str, Path] = DEFAULT_ROBOT) -> RobotProfile:
    """Read and check the profile of ``robot`` (a name or a path); ProfileError says what is wrong."""
    path = profile_path(robot)
    cached = _CACHE.get(path)
    if cached is None:
        try:
            raw = yaml.safe_load(path.read_text())
        except yaml.YAMLError as exc:
            raise ProfileError(f'{path}: not valid YAML: {exc}') from exc
        cached = _CACHE[path] = _parse(path, raw)
    return cached


class _Reader:
    """Typed access to one mapping of the profile, naming the file and key in every error."""

    def __init__(self, path: Path, raw: Any, where: str = '') -> None:
        if not isinstance(raw, dict):
            raise ProfileError(f'{path}: {where or "the file"} must be a mapping')
        self.path, self.raw, self.where = path, raw, where

    def _key(self, key: str) -> str:
        return f'{self.where}.{key}' if self.where else key

    def get(self, key: str, default: Any = ...) -> Any:
        if key not in self.raw:
            if default is ...:
                raise ProfileError(f'{self.path}: missing key {self._key(key)!r}')
            return default
        return self.raw[key]

    def text(self, key: str, default: Any = ...) -> Any:
        value = self.get(key, default)
        if value is not None and not isinstance(value, str):
            raise ProfileError(f'{self.path}: {self._key(key)} must be a string, got {value!r}')
        return value

    def number(self, key: str, low: float = -math.inf, high: float = math.inf,
               default: Any = ...) -> float:
        value = self.get(key, default)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not low <= value <= high:
            raise ProfileError(f'{self.path}: {self._key(key)} must be a number in '
                               f'[{low:g}, {high:g}], got {value!r}')
        return float(value)

    def vector(self, key: str, n: int, default: Any = ...) -> tuple[float, ...]:
        value = self.get(key, default)
        if (not isinstance(value, (list, tuple)) or len(value) != n
                or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in value)):
            raise ProfileError(f'{self.path}: {self._key(key)} must be a list of {n} numbers, '
                               f'got {value!r}')
        return tuple(float(v) for v in value)

    def child(self, key: str, default: Any = ...) -> '_Reader':
        return _Reader(self.path, self.get(key, default), self._key(key))

    def file(self, key: str, default: Any = ...) -> Path:
        rel = self.text(key, default)
        path = (self.path.parent / rel).resolve()
        if not path.is_file():
            raise ProfileError(f'{self.path}: {self._key(key)} names {rel!r}, which is not a file '
                               f'(looked for {path})')
        return path


def _parse(path: Path, raw: Any) -> RobotProfile:
    r = _Reader(path, raw)
    feet = {}
    for side in SIDES:
        f = r.child('feet').child(side)
        feet[side] = FootProfile(
            side, f.text('foot_link'), f.text('sole_frame'),
            f.number('sole_length_m', 0.01, 1.0), f.number('sole_width_m', 0.01, 1.0),
            f.vector('sole_origin_in_foot_m', 3, (0.0, 0.0, 0.0)),
            f.text('force_torque_frame', None), f.vector('sole_rpy_in_foot', 3, (0.0, 0.0, 0.0)))
    groups_raw = r.child('joint_groups')
    groups = {}
    for group, joints in groups_raw.raw.items():
        if not isinstance(joints, list) or not all(isinstance(j, str) for j in joints):
            raise ProfileError(f'{path}: joint_groups.{group} must be a list of joint names')
        groups[str(group)] = tuple(joints)
    for side in SIDES:
        if f'{side}_leg' not in groups:
            raise ProfileError(f'{path}: joint_groups needs {side}_leg (hip to ankle)')
    gains = {}
    for key, value in r.get('servo_gains', {}).items():
        g = _Reader(path, {'v': value}, f'servo_gains.{key}').vector('v', 4)
        gains[str(key)] = ServoGains(*g)
    monitor = r.child('monitor')
    fallen = monitor.number('fallen_com_height_m', 0.05, 3.0)
    guard = monitor.number('guard_com_height_m', fallen, 3.0)
    try:
        joint_limits = joint_limits_of(monitor.get('joint_limits', {}))
    except ValueError as error:
        raise ProfileError(f'{path}: {error}') from None
    controller = {}
    for part, fields in r.get('controller', {}).items():
        if part not in ('gait', 'reflex', 'stabilizer') or not isinstance(fields, dict):
            raise ProfileError(f'{path}: controller.{part}: expected gait, reflex or stabilizer, '
                               'each a mapping of settings')
        controller[part] = {}
        for k, v in fields.items():
            if not isinstance(v, bool):
                v = _Reader(path, {'v': v}, f'controller.{part}.{k}').number('v')
            controller[part][str(k)] = v
    posture = {str(k): _Reader(path, {'v': v}, f'posture.{k}').number('v', -math.pi, math.pi)
               for k, v in r.get('posture', {}).items()}
    unknown = sorted(set(posture) - {j for joints in groups.values() for j in joints})
    if unknown:
        raise ProfileError(f'{path}: posture names joints in no joint group: {unknown}')
    gait_variety = r.get('gait_variety', True)
    if not isinstance(gait_variety, bool):
        raise ProfileError(f'{path}: gait_variety must be true or false, got {gait_variety!r}')
    sim_ground = r.text('sim_ground', 'plane')
    if sim_ground not in ('plane', 'slab'):
        raise ProfileError(f"{path}: sim_ground must be 'plane' or 'slab', got {sim_ground!r}")
    urdf = r.file('urdf')
    # A name of the world registry (sim/world.py WORLDS), checked where a world is made: an engine
    # registered at run time is as good as a shipped one.
    simulator = r.text('simulator', 'pybullet')
    mjcf = r.file('mjcf') if r.get('mjcf', None) is not None else None
    try:
        controllers = parse_controllers(path, r.get('controllers', None))
        unitree_hg = parse_unitree_hg(path, r.get('unitree_hg', None))
        causes = _mapping(r.get('causes', None), 'causes')
    except ValueError as error:
        raise ProfileError(str(error)) from None
    default_controller = r.text('default_controller', C_BAL)
    if default_controller != C_BAL and default_controller not in controllers:
        raise ProfileError(f'{path}: default_controller {default_controller!r} is neither '
                           f'{C_BAL!r} nor one of its controllers {sorted(controllers)}')
    return RobotProfile(
        name=r.text('name'), description=r.text('description', ''), source=path,
        urdf_path=urdf, sim_urdf_path=r.file('sim_urdf', str(urdf)),
        total_mass_kg=r.number('total_mass_kg', 1.0, 1000.0), imu_frame=r.text('imu_frame'),
        feet=feet, fallen_com_height_m=fallen, guard_com_height_m=guard, joint_groups=groups,
        servo_gains=gains,
        push_force_n=r.vector('push_force_n', 2, (0.0, 0.0)), gait_variety=gait_variety,
        sim_ground=sim_ground,
        controller=controller,
        posture=posture, model=r.text('model', 'default_model.json'), simulator=simulator,
        mjcf_path=mjcf, controllers=controllers, default_controller=default_controller,
        unitree_hg=unitree_hg, joint_limits=joint_limits,
        causes=causes)
