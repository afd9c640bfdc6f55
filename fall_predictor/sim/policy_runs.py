"""A learned policy's runs of a dataset: what it is (for the manifest), its push protocol, and one
run's world, controller and live sensor model.

A learned policy walks on its sensors, so its runs make the sensor readings as they go (the bag
records what the policy saw), and each run draws a commanded velocity before its push
(:class:`~fall_predictor.sim.pushes.CommandedPushes`) instead of C_bal's gait.
"""
from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Optional

from fall_predictor.profiles.profile import RobotProfile
from fall_predictor.profiles.profile import PolicyControllerProfile
from fall_predictor.robot.control import PolicyControl
from fall_predictor.robot.learned_policy import LearnedPolicy
from fall_predictor.robot.policy_config import load_policy_config
from fall_predictor.sim.pushes import CommandedPushes
from fall_predictor.sim.sensors import SensorParams, SensorSuite


def _sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def policy_manifest(policy: PolicyControllerProfile) -> dict:
    """What a dataset records of the learned policy that walked it: its name and the SHA-256 of
    its deploy config and network (another network is another controller)."""
    config = load_policy_config(policy.policy_path, check_network=False)
    return {'name': policy.name, 'config_sha256': _sha256(policy.policy_path),
            'network': Path(config.policy_path).name, 'network_sha256': _sha256(config.policy_path)}


def commanded_pushes(policy: PolicyControllerProfile) -> CommandedPushes:
    """The push protocol of ``policy``'s datasets: its force and command ranges, the onset over one
    period of its gait clock (1 s without one), on its physics step's grid."""
    deploy = load_policy_config(policy.policy_path, check_network=False)
    return CommandedPushes(policy, deploy.gait_period_s or 1.0, deploy.physics_dt_s)


def policy_run(profile: RobotProfile, policy: PolicyControllerProfile, learned: LearnedPolicy,
               command, sensor_noise_scale: float, sensor_seed: int, world,
               sensor_params: Optional[SensorParams] = None) -> dict:
    """``run_trajectory``'s arguments for one run of ``learned`` (the policy ``policy`` of
    ``profile``'s robot, its network loaded once by the caller) walking at ``command`` in
    ``world``, its sensors made live (noise x ``sensor_noise_scale``, seeded by
    ``sensor_seed``; ``sensor_params``: other sensors, a randomised world's)."""
    params = sensor_params or SensorParams(noise_scale=sensor_noise_scale)
    suite = SensorSuite(params, seed=sensor_seed,
                        dt_s=world.dt_s, profile=profile)
    return {'world': world, 'controller': PolicyControl(learned, command, name=policy.name),
            'sensors': suite}


def load_learned_policy(policy: PolicyControllerProfile) -> LearnedPolicy:
    """The policy's network and deploy config, loaded (sizes checked)."""
    return LearnedPolicy.from_yaml(policy.policy_path)


def physics_dt_s(policy: Optional[PolicyControllerProfile]) -> Optional[float]:
    """The physics step ``policy`` was deployed with [s] (None for C_bal: the engine's own)."""
    if policy is None:
        return None
    return load_policy_config(policy.policy_path, check_network=False).physics_dt_s
