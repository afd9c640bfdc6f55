"""The controller seam: what any controller of a simulated robot is, whatever drives it (method §2,
§13).

A controller decides every :attr:`Controller.period_s` from what it observes and commands the
joints (:class:`JointCommand`: position targets, with the PD gains the drives apply, or the
robot's own servos when none). What it observes (:class:`Observation`) is either the robot's exact
state (the package's model-based C_bal, which the paper's method runs on the simulator's state) or
what the robot measures (a learned policy: the sensor model's readings, as on the robot's topics),
as :attr:`Controller.observes` says. Three implement it:

* :class:`BalanceControl`: C_bal (:class:`~fall_predictor.robot.controllers.BalanceController`),
  every physics step, on the exact state;
* :class:`PolicyControl`: a team's learned walking policy
  (:class:`~fall_predictor.robot.learned_policy.LearnedPolicy`) at its own rate, on the sensors,
  walking at a commanded velocity;
* :class:`HoldControl`: C_fall: hold the last command of the controller it takes over from.

:class:`ControllerSwitch` runs a walking controller until the trigger, then C_fall for good (method
§2: one-way), whichever the walking controller is. The simulator (a world of :mod:`fall_predictor.
sim.world`) and the recording loop are the same for all of them.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Protocol, Sequence

import numpy as np

from fall_predictor.monitor.records import Measurement
from fall_predictor.monitor.sensor_records import SensorSample

#: :attr:`Controller.observes` values.
OBSERVES_STATE, OBSERVES_SENSORS = 'state', 'sensors'


@dataclass(frozen=True)
class JointCommand:
    """Joint position targets [rad] of the joints ``joint_names`` and how the drives track them:
    ``kp`` [N m/rad] and ``kd`` [N m s/rad] per joint, applied at every physics step as
    ``kp (target - q) - kd dq``, clamped to ``tau_limit_nm`` (or the model's effort limits); all
    None: the robot's own servos (its profile's servo table, robot/actuation.py)."""

    joint_names: tuple[str, ...]
    targets_rad: np.ndarray
    kp: Optional[np.ndarray] = None
    kd: Optional[np.ndarray] = None
    tau_limit_nm: Optional[np.ndarray] = None

    def __post_init__(self) -> None:
        n = len(self.joint_names)
        for name in ('targets_rad', 'kp', 'kd', 'tau_limit_nm'):
            value = getattr(self, name)
            if value is not None and (np.shape(value) != (n,) or not np.isfinite(value).all()):
                raise ValueError(f'{name} must hold {n} finite values, got {value!r}')
        if (self.kp is None) != (self.kd is None):
            raise ValueError('kp and kd come together (or neither: the robot\'s servos)')


@dataclass(frozen=True)
class Observation:
    """What a controller may observe at time ``t_s``: the robot's exact state and what its
    sensors report (either may be None when the run does not make it)."""

    t_s: float
    measurement: Optional[Measurement] = None
    sensors: Optional[SensorSample] = None


@dataclass(frozen=True)
class Posture:
    """Where a run starts: joint angles [rad] by name (others: zero), the base's yaw [rad] and,
    when given, its position [m] (else the world stands the robot on the ground)."""

    joint_angles: dict[str, float]
    base_yaw_rad: float = 0.0
    base_position_m: Optional[tuple[float, float, float]] = None


class Controller(Protocol):
    """The controller seam (module docstring)."""

    #: A name for logs and datasets: 'c_bal', or the policy's.
    name: str
    #: The joints it commands, in the order of its commands.
    joint_names: tuple[str, ...]
    #: How often it decides [s] (its command is held in between).
    period_s: float
    #: :data:`OBSERVES_STATE` or :data:`OBSERVES_SENSORS`.
    observes: str

    def initial_posture(self) -> Posture:
        """The posture a run starts from."""

    def command(self, observation: Observation) -> JointCommand:
        """The joint command from ``observation`` (called every :attr:`period_s`)."""


class BalanceControl:
    """C_bal as a :class:`Controller`: every physics step, on the exact state."""

    name = 'c_bal'
    observes = OBSERVES_STATE

    def __init__(self, balance) -> None:
        #: The model-based balance controller (robot/controllers.py).
        self.balance = balance
        self.joint_names = tuple(balance.joint_names)
        self.period_s = float(balance.dt_s)

    def initial_posture(self) -> Posture:
        q0, torso0 = self.balance.initial_posture()
        return Posture(dict(zip(self.joint_names, map(float, q0))), 0.0,
                       tuple(float(v) for v in torso0))

    def command(self, observation: Observation) -> JointCommand:
        return JointCommand(self.joint_names, self.balance.update(observation.measurement))

    @property
    def reflex_event(self):
        """When and where C_bal's reflex stepped (None: it did not)."""
        return self.balance.reflex_event


class PolicyControl:
    """A learned walking policy as a :class:`Controller`: at its own rate, on the sensors, walking
    at ``command`` = (vx [m/s], vy [m/s], yaw rate [rad/s]); its drives' PD gains are its deploy
    config's."""

    observes = OBSERVES_SENSORS
    reflex_event = None

    def __init__(self, policy, command: Sequence[float] = (0.0, 0.0, 0.0),
                 name: Optional[str] = None) -> None:
        #: The policy (robot/learned_policy.py).
        self.policy = policy
        self.name = name or policy.config.source.parent.name
        self.velocity_command = tuple(float(v) for v in command)
        if len(self.velocity_command) != 3:
            raise ValueError(f'a velocity command is (vx, vy, yaw rate), got {command!r}')
        self.joint_names = tuple(policy.joint_names)
        self.period_s = float(policy.period_s)
        self._kp, self._kd, self._limit = policy.kp, policy.kd, policy.tau_limit
        policy.reset()

    def initial_posture(self) -> Posture:
        return Posture(self.policy.default_posture)

    def command(self, observation: Observation) -> JointCommand:
        if observation.sensors is None:
            raise ValueError(f'{self.name}: a learned policy observes the sensors; the run made none')
        targets = self.policy.act(observation.t_s, observation.sensors, self.velocity_command)
        return JointCommand(self.joint_names, targets, self._kp, self._kd, self._limit)


class HoldControl:
    """C_fall: hold the command of the controller it took over from (its targets, with its
    drives' gains), whatever it observes."""

    observes = OBSERVES_STATE
    name = 'c_fall'

    def __init__(self, held: JointCommand, period_s: float) -> None:
        self.held = held
        self.joint_names = held.joint_names
        self.period_s = period_s

    def initial_posture(self) -> Posture:
        return Posture(dict(zip(self.joint_names, map(float, self.held.targets_rad))))

    def command(self, observation: Observation) -> JointCommand:
        return self.held


class ControllerSwitch:
    """Runs a walking controller until :meth:`trigger_fall`, then C_fall for good (method §2:
    one-way). C_fall holds the walking controller's last command, or, before its first one, the
    posture it starts from (with its gains, when it brings its own: a policy's).

    ``walking``: a :class:`Controller`, or C_bal itself (a
    :class:`~fall_predictor.robot.controllers.BalanceController`, wrapped in
    :class:`BalanceControl`). :meth:`command` answers an observation; :meth:`update` answers C_bal's
    exact state with the joint targets alone (the model-based loops: data generation, the
    controller node).
    """

    def __init__(self, walking) -> None:
        if not hasattr(walking, 'command'):
            walking = BalanceControl(walking)
        self.walking: Controller = walking
        self.fall: Optional[HoldControl] = None
        self.t_switch: Optional[float] = None
        self.last: Optional[JointCommand] = None

    @property
    def mode(self) -> str:
        return 'fall' if self.fall is not None else 'balance'

    @property
    def active(self) -> Controller:
        return self.fall if self.fall is not None else self.walking

    @property
    def balance(self):
        """C_bal, when it is the walking controller (else None)."""
        return getattr(self.walking, 'balance', None)

    def trigger_fall(self, t: float) -> bool:
        """Switch to C_fall; returns False if already switched."""
        if self.fall is not None:
            return False
        held = self.last
        if held is None:
            posture = self.walking.initial_posture().joint_angles
            names = self.walking.joint_names
            gains = getattr(self.walking, '_kp', None), getattr(self.walking, '_kd', None)
            held = JointCommand(names, np.array([posture.get(n, 0.0) for n in names]), *gains)
        self.fall = HoldControl(held, self.walking.period_s)
        self.t_switch = t
        return True

    def command(self, observation: Observation) -> JointCommand:
        if self.fall is not None:
            return self.fall.command(observation)
        self.last = self.walking.command(observation)
        return self.last

    def update(self, m: Optional[Measurement]) -> np.ndarray:
        """The joint targets for the exact state ``m`` (a model-based walking controller)."""
        return self.command(Observation(0.0 if m is None else m.t, m)).targets_rad.copy()


def make_controller(profile, name: Optional[str] = None,
                    command: Optional[Sequence[float]] = None, dt_s: float = 0.001,
                    walk_duration_s: float = 3600.0) -> Controller:
    """The walking controller ``name`` of robot ``profile`` (default: its default controller):
    C_bal with the profile's settings, stepping every ``dt_s`` for ``walk_duration_s``, or the
    learned policy the profile names, walking at ``command`` (default: its deploy config's
    initial command)."""
    from fall_predictor.profiles.profile import C_BAL
    from fall_predictor.robot.controllers import BalanceController, controller_configs
    name = name or profile.default_controller
    policy_profile = profile.controller_profile(name)
    if policy_profile is None:
        if name != C_BAL:
            raise ValueError(f'unknown controller {name!r}')
        gait, reflex, stabilizer = controller_configs(profile)
        return BalanceControl(BalanceController(gait, reflex, dt_s, walk_duration_s=walk_duration_s,
                                                stabilizer=stabilizer, profile=profile))
    from fall_predictor.robot.learned_policy import LearnedPolicy
    policy = LearnedPolicy.from_yaml(policy_profile.policy_path)
    return PolicyControl(policy, policy.config.command_init if command is None else command,
                         name=policy_profile.name)
