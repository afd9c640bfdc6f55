"""A learned walking policy as a controller: sensors and a velocity command in, joint position
targets out, once per policy period.

:class:`LearnedPolicy` puts together what a team's sim2sim loop does around its network
(Unitree's ``deploy_mujoco.py``, humanoid-gym's ``sim2sim.py``): it matches the sample's joints to
the policy's by name, builds the observation (:mod:`~fall_predictor.robot.observations`), runs the
network (:mod:`~fall_predictor.robot.networks`), clips the action when the config says so, keeps
it as the next observation's last action, and turns it into targets
``action x action_scale + default angles`` (or ``+ 0``: ``action_offset: zero``). The joint PD
loop that tracks the targets at the physics rate (``kp``, ``kd``, ``tau_limit``) is the
caller's: the simulator's or the robot's drives.

The gait clock: the phase term counts from the clock's start, ``reset(start_s)``; without a
start, the first :meth:`LearnedPolicy.act` starts it. Unitree's loop calls its policy first one
policy period after the simulation starts (phase 0.02 s); humanoid-gym's at the start (phase 0):
give ``start_s`` to reproduce either exactly.

The IMU: the attitude and angular velocity must be those of the base (pelvis) frame, which is
where the policies' training reads them (a robot whose IMU is elsewhere, such as the G1's torso
IMU, must transform them first).
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional, Sequence, Union

import numpy as np

from fall_predictor.errors import TeamFileError
from fall_predictor.monitor.sensor_records import SensorSample
from fall_predictor.robot.networks import PolicyNetwork, load_network
from fall_predictor.robot.observations import ObservationBuilder
from fall_predictor.robot.policy_config import PolicyConfig, load_policy_config


class NonFiniteActions(TeamFileError):
    """The network gave NaN or inf: its file is named (weights that overflow, or NaN in them)."""


class LearnedPolicy:
    """A learned policy (its config and network) as a joint-target controller."""

    def __init__(self, config: PolicyConfig, network: Optional[PolicyNetwork] = None) -> None:
        self.config = config
        self.network = network if network is not None else load_network(config.policy_path)
        config.check_network(self.network)
        self.observations = ObservationBuilder(config)
        n = config.num_actions
        self._scale = np.asarray(config.action_scale, dtype=np.float64)
        self._offset = (np.asarray(config.default_angles_rad, dtype=np.float64)
                        if config.action_offset == 'default_angles' else np.zeros(n))
        self._clip = config.clip_actions
        self._names: Optional[tuple[str, ...]] = None
        self._index = np.arange(n)
        self.last_action = np.zeros(n, dtype=np.float32)
        self.start_s: Optional[float] = None
        self.reset()

    @classmethod
    def from_yaml(cls, path: Union[str, Path]) -> 'LearnedPolicy':
        """The policy of a config file (its network loaded once, sizes checked)."""
        return cls(load_policy_config(path, check_network=False))

    # -- what a caller needs to run it --------------------------------------------------------

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The joint of each target, in the policy's order."""
        return self.config.joint_names

    @property
    def period_s(self) -> float:
        """The policy period [s]: call :meth:`act` this often."""
        return self.config.period_s

    @property
    def physics_dt_s(self) -> float:
        """The physics (PD loop) step the policy was deployed with [s]."""
        return self.config.physics_dt_s

    @property
    def default_posture(self) -> dict[str, float]:
        """Joint name -> default angle [rad]: the posture an all-zero action holds (with
        ``action_offset: default_angles``) and the posture to start from."""
        return dict(zip(self.config.joint_names, self.config.default_angles_rad))

    @property
    def kp(self) -> np.ndarray:
        """PD stiffness per joint [N m/rad]."""
        return np.asarray(self.config.kp, dtype=np.float64)

    @property
    def kd(self) -> np.ndarray:
        """PD damping per joint [N m s/rad]."""
        return np.asarray(self.config.kd, dtype=np.float64)

    @property
    def tau_limit(self) -> Optional[np.ndarray]:
        """Torque limit per joint [N m], or None: the simulator model's own limits."""
        limit = self.config.tau_limit_nm
        return None if limit is None else np.asarray(limit, dtype=np.float64)

    def describe(self) -> str:
        c = self.config
        return (f'{c.source.name}: {c.observation_layout} observation of {c.obs_size} '
                f'({c.frame_stack} frame(s)), {c.num_actions} joints at {1.0 / c.period_s:g} Hz; '
                f'{self.network.describe()}')

    # -- running ------------------------------------------------------------------------------

    def reset(self, start_s: Optional[float] = None) -> None:
        """A new run: network state zeroed, last action zero, stacked frames forgotten, the gait
        clock started at ``start_s`` (None: at the next :meth:`act`)."""
        self.network.reset()
        self.observations.reset()
        self.last_action[:] = 0.0
        self.start_s = start_s

    def act(self, t_s: float, sensors: SensorSample, command: Sequence[float]) -> np.ndarray:
        """Joint position targets [rad] in :attr:`joint_names` order, from the sensors at time
        ``t_s`` [s] and ``command`` = (vx [m/s], vy [m/s], yaw rate [rad/s])."""
        if self.start_s is None:
            self.start_s = t_s
        index = self._joint_index(sensors.joint_names)
        obs = self.observations.build(t_s - self.start_s, sensors.imu_quat_xyzw, sensors.gyro_rad_s,
                                      np.asarray(sensors.q)[index], np.asarray(sensors.dq)[index],
                                      command, self.last_action)
        action = self.network(obs)
        if not np.isfinite(action).all() and np.isfinite(obs).all():
            bad = [j for j, a in zip(self.config.joint_names, action) if not np.isfinite(a)]
            raise NonFiniteActions(
                f'the network gave {"NaN" if np.isnan(action).any() else "inf"} actions at '
                f't = {t_s:.3f} s ({", ".join(bad[:3])}{" ..." if len(bad) > 3 else ""}) from a finite '
                'observation', file=self.config.policy_path, field='policy_path',
                fix='its weights overflow or hold NaN: export the trained policy again')
        if self._clip is not None:
            np.clip(action, -self._clip, self._clip, out=action)
        self.last_action[:] = action
        return action * self._scale + self._offset

    def _joint_index(self, names: tuple[str, ...]) -> np.ndarray:
        """Index into the sample's joint arrays of each policy joint (cached per name tuple)."""
        if names != self._names:
            position = {name: k for k, name in enumerate(names)}
            missing = [j for j in self.config.joint_names if j not in position]
            if missing:
                raise ValueError(f'{self.config.source.name}: the sensor sample has no joint '
                                 f'{missing[0]!r}' + (f' (nor {", ".join(missing[1:])})' if missing[1:] else '')
                                 + f'; it has {", ".join(names)}')
            self._index = np.array([position[j] for j in self.config.joint_names])
            self._names = tuple(names)
        return self._index
