"""What the robot's own sensors report: joint encoders, a torso IMU and ankle F/T sensors.

Each world of the simulator seam reads the exact (noise-free) sensor quantities of its state, a
:class:`SensorTruth` (``world.sensor_truth()``: PyBullet's in :mod:`~fall_predictor.sim.
pybullet_sensors`, MuJoCo's in :mod:`~fall_predictor.sim.mujoco_world`); a :class:`SensorSuite`
turns a stream of those into readings with white noise, a
constant per-run bias, quantisation and latency, seeded and deterministic. The same suite
object serves the live simulator node (one sample per step) and offline generation
(:func:`apply_sensors` over a recorded run): one implementation.

Default parameters, per 1 kHz sample (white noise standard deviation = density x sqrt(fs/2),
the Nyquist bandwidth of the sampled signal: at another rate, the noise of that rate's band):

* **Joint encoders** (:class:`EncoderParams`): a 19-bit absolute output-side encoder
  (e.g. Renishaw AksIM-2 19 bit: resolution 2 pi / 2^19 = 12 urad, noise about one count);
  velocity as the drive reports it (differenced and filtered, noise 0.01 rad/s, about one
  count per ms); effort from motor current (1 % of a 50 N m joint, 0.5 N m).
  Latency one control cycle (1 ms).
* **Torso IMU** (:class:`ImuParams`): Bosch BMI088 data sheet (BST-BMI088-DS001): gyroscope
  noise density 0.014 deg/s/sqrt(Hz), 16 bit at +-2000 deg/s (0.061 deg/s LSB), residual
  offset after start-up calibration 0.05 deg/s; accelerometer noise density 175 ug/sqrt(Hz),
  16 bit at +-24 g (0.73 mg LSB), residual offset after calibration 5 mg. The orientation
  is the IMU's on-board attitude filter output, with the accuracy of an industrial AHRS
  (Xsens MTi-600 series data sheet: roll/pitch 0.2 deg RMS dynamic, heading 1 deg):
  constant bias 0.2 deg roll/pitch and 1 deg yaw, white noise 0.02 deg. Latency 1 ms.
* **Ankle F/T sensors** (:class:`ForceTorqueParams`): a 6-axis strain-gauge sensor of the
  ATI Mini58 class (ATI F/T sensor catalogue, Mini58 SI-2800-120: force resolution
  about 1/16 N; torque quantum taken as 1/256 N m), noise 0.3 N and 0.02 N m,
  residual offset after zeroing 1 N and 0.05 N m (temperature drift over a run). Latency
  1 ms. The wrench is the ground reaction on the sole, in the sole frame (origin at the
  sole's underside centre): the foot below the sensor is taken as massless, as humanoid
  ankle sensors are usually compensated for.

``noise_scale`` multiplies every noise and bias term (0 = ideal sensors, still quantised
and delayed), for the noise sweep.
"""
from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Optional

import numpy as np

from fall_predictor.monitor import rotations
from fall_predictor.monitor.robot_description import SIDES
from fall_predictor.monitor.sensor_records import SensorSample
from fall_predictor.profiles.profile import RobotProfile
from fall_predictor.profiles import asimo_like_urdf as rm

SAMPLE_RATE_HZ = 1000.0
_NYQUIST_SQRT = math.sqrt(SAMPLE_RATE_HZ / 2.0)
_DEG = math.pi / 180.0
_G = 9.81
#: What the monitor needs to know of the simulated robot's sensors beyond its URDF.
SENSOR_LAYOUT = rm.PROFILE.sensor_layout()
#: IMU position in the torso link frame [m] (at the torso frame origin).
IMU_POSITION_IN_TORSO_M = (0.0, 0.0, 0.0)


def robot_description(profile: Optional[RobotProfile] = None) -> str:
    """A simulated robot's URDF with its sole frames (what ``/robot_description`` carries)."""
    return (profile or rm.PROFILE).urdf_xml()


@dataclass(frozen=True)
class EncoderParams:
    """Joint encoders and drive telemetry (all 26 joints)."""

    position_noise_rad: float = 1.2e-5
    position_bias_rad: float = 0.0
    position_quantum_rad: float = 2 * math.pi / 2 ** 19
    velocity_noise_rad_s: float = 0.01
    velocity_quantum_rad_s: float = 0.0
    effort_noise_nm: float = 0.5
    effort_quantum_nm: float = 0.01
    latency_s: float = 0.001


@dataclass(frozen=True)
class ImuParams:
    """Torso IMU: attitude output, gyroscope, accelerometer."""

    gyro_noise_density_rad_s_sqrt_hz: float = 0.014 * _DEG
    gyro_bias_rad_s: float = 0.05 * _DEG
    gyro_quantum_rad_s: float = 0.061 * _DEG
    accel_noise_density_m_s2_sqrt_hz: float = 175e-6 * _G
    accel_bias_m_s2: float = 5e-3 * _G
    accel_quantum_m_s2: float = 0.73e-3 * _G
    tilt_bias_rad: float = 0.2 * _DEG
    yaw_bias_rad: float = 1.0 * _DEG
    orientation_noise_rad: float = 0.02 * _DEG
    latency_s: float = 0.001


@dataclass(frozen=True)
class ForceTorqueParams:
    """One 6-axis ankle force/torque sensor (both feet use the same parameters)."""

    force_noise_n: float = 0.3
    force_bias_n: float = 1.0
    force_quantum_n: float = 1.0 / 16.0
    torque_noise_nm: float = 0.02
    torque_bias_nm: float = 0.05
    torque_quantum_nm: float = 1.0 / 256.0
    latency_s: float = 0.001


@dataclass(frozen=True)
class SensorParams:
    """The robot's sensor model; ``noise_scale`` scales every noise and bias term."""

    encoders: EncoderParams = field(default_factory=EncoderParams)
    imu: ImuParams = field(default_factory=ImuParams)
    force_torque: ForceTorqueParams = field(default_factory=ForceTorqueParams)
    noise_scale: float = 1.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.noise_scale) and self.noise_scale >= 0):
            raise ValueError(f'noise_scale must be finite and >= 0, got {self.noise_scale}')

    def to_dict(self) -> dict:
        """JSON-ready parameters (recorded in bag and dataset metadata)."""
        return asdict(self)


@dataclass(slots=True)
class SensorTruth:
    """Exact sensor quantities of one simulation step (world frame unless said otherwise)."""

    t: float
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    imu_quat_xyzw: np.ndarray
    imu_velocity_world: np.ndarray   #: velocity of the IMU point [m/s]
    gyro_rad_s: np.ndarray           #: torso frame
    left_wrench: Optional[np.ndarray]    #: None: the foot has no F/T sensor
    right_wrench: Optional[np.ndarray]


def _quantise(x: np.ndarray, quantum: float) -> np.ndarray:
    return x if quantum <= 0 else np.rint(x / quantum) * quantum


class SensorSuite:
    """Applies :class:`SensorParams` to a stream of :class:`SensorTruth`, one step at a time.

    Seeded: the same seed and the same truth stream give identical readings. Biases are
    drawn once per suite (one run); latency is a delay line of whole samples.
    """

    def __init__(self, params: SensorParams = SensorParams(), seed: int = 0,
                 dt_s: float = 1.0 / SAMPLE_RATE_HZ, profile: Optional[RobotProfile] = None):
        self.params = params
        #: The robot whose sensors these are: its joint order and its sensors' frames.
        profile = profile or rm.PROFILE
        self.joint_names = profile.joint_names
        self.imu_frame = profile.imu_frame
        self.wrench_frames = tuple(profile.feet[side].force_torque_frame or '' for side in SIDES)
        self.dt_s = dt_s
        self.rng = np.random.default_rng(seed)
        k = params.noise_scale
        e, i, f = params.encoders, params.imu, params.force_torque
        n = len(self.joint_names)
        self._q_bias = k * e.position_bias_rad * self.rng.standard_normal(n)
        self._gyro_bias = k * i.gyro_bias_rad_s * self.rng.standard_normal(3)
        self._accel_bias = k * i.accel_bias_m_s2 * self.rng.standard_normal(3)
        self._att_bias = k * np.array([i.tilt_bias_rad, i.tilt_bias_rad, i.yaw_bias_rad]) * self.rng.standard_normal(3)
        self._ft_bias = {s: k * np.concatenate([f.force_bias_n * self.rng.standard_normal(3),
                                                f.torque_bias_nm * self.rng.standard_normal(3)])
                         for s in SIDES}
        self._delays = {name: max(0, int(round(lat / dt_s)))
                        for name, lat in (('enc', e.latency_s), ('imu', i.latency_s), ('ft', f.latency_s))}
        self._buffers = {name: deque(maxlen=d + 1) for name, d in self._delays.items()}
        self._prev_v: Optional[np.ndarray] = None

    def _delayed(self, name: str, values: list) -> list:
        """The delay line ``name`` fed ``values`` in turn: what it puts out after each (the value
        ``delay`` samples before, or the first one ever while the line fills)."""
        buf = self._buffers[name]
        held = len(buf)
        stream = [*buf, *values]
        delay = buf.maxlen - 1
        buf.extend(values)
        return [stream[max(0, j - delay)] for j in range(held, len(stream))]

    def read(self, truth: SensorTruth) -> SensorSample:
        """The readings published at ``truth.t`` (the delayed, noisy sensor values)."""
        return self.read_many([truth])[0]

    def read_many(self, truths: Sequence[SensorTruth]) -> list[SensorSample]:
        """The readings published at each of ``truths`` in turn: the same numbers as :meth:`read`
        on each, computed for all at once (one draw of the generator, array arithmetic per
        quantity: the noise of a whole recorded run costs a few ms, not a tenth of its
        simulation)."""
        count = len(truths)
        if not count:
            return []
        p, k = self.params, self.params.noise_scale
        e, i, f = p.encoders, p.imu, p.force_torque
        n = len(truths[0].q)
        sides = [side for side, w in (('l', truths[0].left_wrench), ('r', truths[0].right_wrench))
                 if w is not None]
        # Each step draws, in this order: encoders q, dq, tau (n each), gyro, accel, attitude (3
        # each), then force and torque (3 each) of each foot with a sensor. One draw for all steps
        # gives the same numbers as a draw per step.
        noise = self.rng.standard_normal((count, 3 * n + 9 + 6 * len(sides)))
        q = _quantise(np.array([t.q for t in truths]) + self._q_bias
                      + k * e.position_noise_rad * noise[:, 0:n], e.position_quantum_rad)
        dq = _quantise(np.array([t.dq for t in truths])
                       + k * e.velocity_noise_rad_s * noise[:, n:2 * n], e.velocity_quantum_rad_s)
        tau = _quantise(np.array([t.tau for t in truths])
                        + k * e.effort_noise_nm * noise[:, 2 * n:3 * n], e.effort_quantum_nm)
        quat_true = [t.imu_quat_xyzw.tolist() for t in truths]
        # Specific force from the finite difference of the IMU point's velocity.
        v = np.array([t.imu_velocity_world for t in truths])
        previous = np.empty_like(v)
        previous[1:] = v[:-1]
        previous[0] = v[0] if self._prev_v is None else self._prev_v
        acc_world = (v - previous) / self.dt_s
        if self._prev_v is None:
            acc_world[0] = 0.0
        self._prev_v = v[-1].copy()
        specific = _in_imu_frame(quat_true, (acc_world + np.array([0.0, 0.0, _G])).tolist())
        # White noise over the Nyquist band of the sample rate (1 kHz: sqrt(500 Hz)).
        nyquist_sqrt = _NYQUIST_SQRT if self.dt_s == 1.0 / SAMPLE_RATE_HZ else math.sqrt(0.5 / self.dt_s)
        sig_g = k * i.gyro_noise_density_rad_s_sqrt_hz * nyquist_sqrt
        sig_a = k * i.accel_noise_density_m_s2_sqrt_hz * nyquist_sqrt
        m = 3 * n
        gyro = _quantise(np.array([t.gyro_rad_s for t in truths]) + self._gyro_bias
                         + sig_g * noise[:, m:m + 3], i.gyro_quantum_rad_s)
        accel = _quantise(specific + self._accel_bias + sig_a * noise[:, m + 3:m + 6], i.accel_quantum_m_s2)
        # Attitude error: a world-frame rotation (bias + white) applied to the true attitude.
        err = (self._att_bias + k * i.orientation_noise_rad * noise[:, m + 6:m + 9]).tolist()
        quat = [np.array(rotations.multiply(rotations.from_rotation_vector(*r), qt))
                for r, qt in zip(err, quat_true)]
        wrenches: dict[str, list] = {'l': [None] * count, 'r': [None] * count}
        for j, side in enumerate(sides):
            c = m + 9 + 6 * j
            raw = (np.array([t.left_wrench if side == 'l' else t.right_wrench for t in truths])
                   + self._ft_bias[side]
                   + k * np.concatenate([f.force_noise_n * noise[:, c:c + 3],
                                         f.torque_noise_nm * noise[:, c + 3:c + 6]], axis=1))
            wrenches[side] = list(np.concatenate([_quantise(raw[:, :3], f.force_quantum_n),
                                                  _quantise(raw[:, 3:], f.torque_quantum_nm)], axis=1))
        enc = self._delayed('enc', list(zip(q, dq, tau)))
        imu = self._delayed('imu', list(zip(quat, gyro, accel)))
        ft = self._delayed('ft', list(zip(wrenches['l'], wrenches['r'])))
        return [SensorSample(t=truth.t, joint_names=self.joint_names, q=en[0], dq=en[1], tau=en[2],
                             imu_quat_xyzw=im[0], gyro_rad_s=im[1], accel_m_s2=im[2],
                             left_wrench=w[0], right_wrench=w[1], imu_frame=self.imu_frame,
                             wrench_frames=self.wrench_frames)
                for truth, en, im, w in zip(truths, enc, imu, ft)]


def _in_imu_frame(quat_xyzw: list, vectors: list) -> np.ndarray:
    """Each world vector in its IMU frame, ``R^T v`` with ``R`` the rotation matrix of the
    quaternion (:func:`fall_predictor.monitor.rotations.matrix`): in floats, the same expressions
    and sums in the same order as that matrix's product with a vector, so the same bits."""
    out = []
    for (x, y, z, w), (a, b, c) in zip(quat_xyzw, vectors):
        r00, r01, r02 = 1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)
        r10, r11, r12 = 2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)
        r20, r21, r22 = 2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)
        out.append((r00 * a + r10 * b + r20 * c, r01 * a + r11 * b + r21 * c, r02 * a + r12 * b + r22 * c))
    return np.array(out)


def apply_sensors(truths: list[SensorTruth], params: SensorParams = SensorParams(),
                  seed: int = 0, profile: Optional[RobotProfile] = None) -> list[SensorSample]:
    """Readings of a whole recorded run (the same :class:`SensorSuite` a live node steps) of the
    robot ``profile`` (default: the shipped robot)."""
    suite = SensorSuite(params, seed, profile=profile)
    return suite.read_many(truths)
