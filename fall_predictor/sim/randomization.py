"""Domain randomisation of a run's world, engine-free: what is drawn and in which ranges.

The worlds a model will meet differ from the nominal one as the worlds a learned policy is trained
in do (legged_gym-style domain randomisation): the ground's friction, the links' masses and an
added payload on the base, the drives' strength and PD gains, the sensors' latency and the IMU's
bias. The default ranges are those of that training: unitree_rl_gym's G1 (friction 0.1–1.25, an
added base mass of −1 to 3 kg) and the common legged_gym forks' (link masses ×0.9–1.1, motor
strength ×0.9–1.1, Kp and Kd ×0.8–1.2, a control delay of up to 4 policy steps of 5 ms, an IMU
mounting offset of up to 1.2°).

A run's draw (:class:`WorldRandomization`) reaches the engine through the World seam's optional
``set_randomization`` (sim/world.py: from the next start; None: the nominal world) and the sensor
model through :meth:`WorldRandomization.sensor_params`. How each engine applies it: the ground's
friction decides a foot's contact (PyBullet: the product with the feet's 1.0; MuJoCo: by geom
priority); every link's mass and inertia scale together, the base's then gain the payload (its
inertia scaled with its mass); the drives' Kp, Kd and torque limits scale with the strength, the
gains with their own factors.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace

import numpy as np


@dataclass(frozen=True)
class RandomizationRanges:
    """The ranges each run's :class:`WorldRandomization` is drawn from, uniformly (module docs)."""

    friction: tuple[float, float] = (0.1, 1.25)
    added_base_mass_kg: tuple[float, float] = (-1.0, 3.0)
    link_mass_scale: tuple[float, float] = (0.9, 1.1)
    motor_strength: tuple[float, float] = (0.9, 1.1)
    kp_scale: tuple[float, float] = (0.8, 1.2)
    kd_scale: tuple[float, float] = (0.8, 1.2)
    latency_s: tuple[float, float] = (0.0, 0.02)
    imu_tilt_bias_deg: tuple[float, float] = (0.0, 1.2)

    def to_dict(self) -> dict:
        return {k: list(v) for k, v in asdict(self).items()}


@dataclass(frozen=True)
class WorldRandomization:
    """One run's randomised world (module docs)."""

    friction: float = 1.0
    added_base_mass_kg: float = 0.0
    link_mass_scale: float = 1.0
    motor_strength: float = 1.0
    kp_scale: float = 1.0
    kd_scale: float = 1.0
    latency_s: float = 0.001
    imu_tilt_bias_deg: float = 0.2

    @classmethod
    def sample(cls, ranges: RandomizationRanges, rng: np.random.Generator) -> 'WorldRandomization':
        """One draw; the order of draws is fixed so a seed always gives the same world."""
        return cls(**{name: round(float(rng.uniform(*pair)), 6) for name, pair in asdict(ranges).items()})

    def to_dict(self) -> dict:
        return asdict(self)

    def sensor_params(self, params):
        """``params`` (sim/sensors.SensorParams) with this run's latency (encoders, IMU and
        force/torque sensors alike, at least one sample) and IMU tilt bias."""
        latency = max(self.latency_s, 0.001)
        return replace(params, encoders=replace(params.encoders, latency_s=latency),
                       imu=replace(params.imu, latency_s=latency,
                                   tilt_bias_rad=math.radians(self.imu_tilt_bias_deg)),
                       force_torque=replace(params.force_torque, latency_s=latency))

    def drive_scales(self) -> tuple[float, float, float]:
        """(Kp factor, Kd factor, torque-limit factor) of every drive."""
        s = self.motor_strength
        return s * self.kp_scale, s * self.kd_scale, s


def randomization_rng(seed: int, index: int) -> np.random.Generator:
    """The random stream of run ``index``'s world (apart from its push's and cause's)."""
    return np.random.default_rng([seed, index, 58])
