"""The controller seam: what any controller of a simulated robot is, whatever drives it (method §2,
§13).

A controller decides every :attr:`Controller.period_s` from what it observes and commands the
joints (:class:`JointCommand`: position targets, with the PD gains the drives apply, or the
robot's own servos when none). What it observes (:class:`Observation`) is either the robot's exact
state (the package's model-based C_bal, which the paper's method runs on the simulator's state) or
what the robot measures (a learned policy: the sensor model's readings, as on the robot's topics),
as :attr:`Controller.observes` says. Three implement it:

* :class:`BalanceControl`: C_bal (:class:`~fall_predictor.robot.balance_controller.BalanceController`),
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
            if value is None:
                continue
            # A torque limit may be +inf (none); every other value is finite.
            bad = (np.isnan(value) | (np.asarray(value) < 0) if name == 'tau_limit_nm'
                   else ~np.isfinite(value)) if np.shape(value) == (n,) else True
            if np.any(bad):
                raise ValueError(f'{name} must hold {n} finite values'
                                 + (' (limits >= 0, inf: none)' if name == 'tau_limit_nm' else '')
                                 + f', got {value!r}')
        if (self.kp is None) != (self.kd is None):
            raise ValueError('kp and kd come together (or neither: the robot\'s servos)')

    @property
    def has_gains(self) -> bool:
        """Whether the command brings its drives' PD gains (else the robot's servos track it)."""
        return self.kp is not None

    def fit_onto(self, joint_names: Sequence[str],
                 rest: Optional['JointCommand'] = None) -> 'JointCommand':
        """This command on ``joint_names`` (another order, more or fewer joints): a joint it names
        takes its target and gains; one it does not, ``rest``'s (what the drives held so far).
        Gains: this command's where it has them; a command without gains takes ``rest``'s (a
        targets-only message tracked by drives configured elsewhere); a joint neither names a
        gain for is undriven (kp = kd = 0, no torque limit). The one place a command meets
        another joint list: both worlds, the controller node and the simulator node fit so."""
        names = tuple(joint_names)
        if names == self.joint_names and (self.has_gains or rest is None or not rest.has_gains):
            return self
        mine = _positions(self.joint_names, names)
        held = _positions(rest.joint_names, names) if rest is not None else np.full(len(names), -1)
        missing = [n for n, a, b in zip(names, mine, held) if a < 0 and b < 0]
        if missing:
            raise ValueError(f'no target for joint(s) {", ".join(missing)}: the command names '
                             f'{", ".join(self.joint_names)}'
                             + ('' if rest is None else f', what the drives held {", ".join(rest.joint_names)}'))

        def merged(own: Optional[np.ndarray], other: Optional[np.ndarray], fill: float):
            if own is None and other is None:
                return None
            out = np.full(len(names), fill)
            if other is not None:
                out[held >= 0] = np.asarray(other, dtype=float)[held[held >= 0]]
            if own is not None:
                out[mine >= 0] = np.asarray(own, dtype=float)[mine[mine >= 0]]
            return out

        rest_targets = None if rest is None else rest.targets_rad
        targets = merged(self.targets_rad, rest_targets, 0.0)
        if not self.has_gains:
            if rest is None or not rest.has_gains:
                return JointCommand(names, targets)
            own = (None, None, None)
        else:
            own = (self.kp, self.kd, self.tau_limit_nm)
        other = (None, None, None) if rest is None else (rest.kp, rest.kd, rest.tau_limit_nm)
        return JointCommand(names, targets, merged(own[0], other[0], 0.0),
                            merged(own[1], other[1], 0.0), merged(own[2], other[2], np.inf))


def _positions(names: Sequence[str], wanted: Sequence[str]) -> np.ndarray:
    """Index into ``names`` of each of ``wanted`` (-1: not there)."""
    index = {name: k for k, name in enumerate(names)}
    return np.array([index.get(name, -1) for name in wanted], dtype=int)


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
    #: When and where the controller's own reflex stepped (C_bal's), else None.
    reflex_event: Optional[object]

    def initial_posture(self) -> Posture:
        """The posture a run starts from."""

    def command(self, observation: Observation) -> JointCommand:
        """The joint command from ``observation`` (called every :attr:`period_s`)."""

    def hold_command(self) -> JointCommand:
        """The command that holds :meth:`initial_posture`, tracked by its drives (its own gains,
        or the robot's servos): what C_fall holds when it takes over before the first command."""


class BalanceControl:
    """C_bal as a :class:`Controller`: every physics step, on the exact state."""

    name = 'c_bal'
    observes = OBSERVES_STATE

    def __init__(self, balance) -> None:
        #: The model-based balance controller (robot/balance_controller.py).
        self.balance = balance
        self.joint_names = tuple(balance.joint_names)
        self.period_s = float(balance.dt_s)

    def initial_posture(self) -> Posture:
        q0, torso0 = self.balance.initial_posture()
        return Posture(dict(zip(self.joint_names, map(float, q0))), 0.0,
                       tuple(float(v) for v in torso0))

    def command(self, observation: Observation) -> JointCommand:
        return JointCommand(self.joint_names, self.balance.update(observation.measurement))

    def hold_command(self) -> JointCommand:
        return _posture_command(self)

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
        #: The drives' gains and torque limits (its deploy config's): every command carries them.
        self.gains = (policy.kp, policy.kd, policy.tau_limit)
        policy.reset()

    def initial_posture(self) -> Posture:
        return Posture(self.policy.default_posture)

    def command(self, observation: Observation) -> JointCommand:
        if observation.sensors is None:
            raise ValueError(f'{self.name}: a learned policy observes the sensors; the run made none')
        targets = self.policy.act(observation.t_s, observation.sensors, self.velocity_command)
        return JointCommand(self.joint_names, targets, *self.gains)

    def hold_command(self) -> JointCommand:
        return _posture_command(self, *self.gains)


class HoldControl:
    """C_fall: hold the command of the controller it took over from (its targets, with its
    drives' gains), whatever it observes."""

    observes = OBSERVES_STATE
    name = 'c_fall'
    reflex_event = None

    def __init__(self, held: JointCommand, period_s: float) -> None:
        self.held = held
        self.joint_names = held.joint_names
        self.period_s = period_s

    def initial_posture(self) -> Posture:
        return Posture(dict(zip(self.joint_names, map(float, self.held.targets_rad))))

    def command(self, observation: Observation) -> JointCommand:
        return self.held

    def hold_command(self) -> JointCommand:
        return self.held


def _posture_command(controller, kp=None, kd=None, tau_limit_nm=None) -> JointCommand:
    """The command holding ``controller``'s initial posture (joints it does not set: zero)."""
    posture = controller.initial_posture().joint_angles
    targets = np.array([posture.get(name, 0.0) for name in controller.joint_names])
    return JointCommand(controller.joint_names, targets, kp, kd, tau_limit_nm)


class ControllerSwitch:
    """Runs a walking controller until :meth:`trigger_fall`, then C_fall for good (method §2:
    one-way). C_fall holds the walking controller's last command, or, before its first one, the
    posture it starts from (with its gains, when it brings its own: a policy's).

    ``walking``: a :class:`Controller` (:func:`make_controller`'s). :meth:`command` answers an
    observation; :meth:`update` answers C_bal's exact state with the joint targets alone (the
    model-based loops: data generation, the controller node).
    """

    def __init__(self, walking: Controller) -> None:
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
        held = self.last if self.last is not None else self.walking.hold_command()
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
                    walk_duration_s: float = 3600.0, *, gait=None, reflex=None,
                    stabilizer=None) -> Controller:
    """The walking controller ``name`` of robot ``profile`` (default: its default controller), the
    one place a controller is built (the CLI, data generation, the trajectory loop and the nodes
    all come here):

    * C_bal, stepping every ``dt_s`` [s] for a walk of ``walk_duration_s`` [s], with the profile's
      settings, or those given (``gait``, ``reflex``, ``stabilizer``: robot/balance_controller.py's
      ``GaitConfig``, ``ReflexConfig``, robot/stabilizer.py's ``StabilizerConfig``);
    * the learned policy the profile names, walking at ``command`` = (vx [m/s], vy [m/s], yaw rate
      [rad/s]) (default: its deploy config's initial command); its deploy config is parsed once
      per process (robot/policy_config.py), its network loaded for this controller (its state is
      this controller's).
    """
    from fall_predictor.profiles.profile import C_BAL
    name = name or profile.default_controller
    policy_profile = profile.controller_profile(name)
    if policy_profile is None:
        if name != C_BAL:
            raise ValueError(f'unknown controller {name!r}')
        from fall_predictor.robot.balance_controller import BalanceController, controller_configs
        own = controller_configs(profile)
        return BalanceControl(BalanceController(gait or own[0], reflex or own[1], dt_s,
                                                walk_duration_s=walk_duration_s,
                                                stabilizer=stabilizer or own[2], profile=profile))
    if gait is not None or reflex is not None or stabilizer is not None:
        raise ValueError(f'controller {name!r} is a learned policy: gait, reflex and stabilizer '
                         'are C_bal\'s settings')
    from fall_predictor.robot.learned_policy import LearnedPolicy
    policy = LearnedPolicy.from_yaml(policy_profile.policy_path)
    return PolicyControl(policy, policy.config.command_init if command is None else command,
                         name=policy_profile.name)
