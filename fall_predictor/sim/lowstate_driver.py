"""A Unitree humanoid's low-level board, simulated: the sensor model's readings as the
``lowstate`` messages a G1 publishes (method §12, "A Unitree humanoid's own topic").

Each reading (:class:`~fall_predictor.monitor.sensor_records.SensorSample`, one per physics step:
500 Hz under Unitree's policy) becomes one :class:`~fall_predictor.monitor.lowstate.LowStateRecord`
as the robot's board fills it: every joint at its motor slot of the profile's table (the motors
the simulated description lacks, the waist and arms the policy holds, at their held targets with
the encoders' noise), the pelvis IMU's quaternion w-x-y-z, gyroscope and accelerometer, ``tick``
in milliseconds from a board clock that started long before (no stamp), and ``mode_machine`` of
the variant. Each message arrives at the receiver ``latency_s`` later, plus a jitter, on the
receiver's clock (nanoseconds since 1970, as a robot's computer stamps). The tests and benchmarks
replay these through :class:`~fall_predictor.monitor.lowstate.LowStateConverter` (and, over DDS,
through the estimator node) against the same readings as ``joint_states`` and ``imu/data``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator, Optional, Sequence

import numpy as np

from fall_predictor.monitor.lowstate import (MOTOR_SLOTS, TICK_MODULUS, LowStateProfile,
                                             LowStateRecord)
from fall_predictor.monitor.sensor_records import SensorSample

#: The receiver's clock at the run's start: epoch time, as on a robot's computer [ns].
RECEIVE_EPOCH_NS = 1_764_000_000_000_000_000


@dataclass(frozen=True)
class BoardTiming:
    """How the board's messages reach the receiver."""

    first_tick_ms: int = 123_456_789         #: the board's tick at the run's start [ms]
    latency_s: float = 0.0004                #: least delay from the board to the receiver [s]
    jitter_s: float = 0.0003                 #: extra delay, uniform in [0, jitter) [s]
    held_noise_rad: float = 0.0005           #: encoder noise of the held joints [rad]
    seed: int = 0


def lowstate_records(readings: Sequence[SensorSample], profile: LowStateProfile,
                     mode_machine: int, timing: BoardTiming = BoardTiming()
                     ) -> Iterator[tuple[int, LowStateRecord]]:
    """(receive time [ns], record) of each reading, in arrival order (module docstring)."""
    variant = profile.variants[mode_machine]
    rng = np.random.default_rng(timing.seed)
    slot_of = {name: k for k, name in enumerate(variant.motors) if name}
    held = [(slot_of[n], target) for n, target in profile.held_joints.items() if n in slot_of]
    layout: Optional[tuple] = None
    for reading in readings:
        if layout is None or layout[0] != reading.joint_names:
            missing = [n for n in reading.joint_names if n not in slot_of]
            if missing:
                raise ValueError(f'joints without a motor slot in {variant.name}: {missing}')
            layout = (reading.joint_names, np.array([slot_of[n] for n in reading.joint_names]))
        slots = layout[1]
        q, dq, tau = np.zeros(MOTOR_SLOTS), np.zeros(MOTOR_SLOTS), np.zeros(MOTOR_SLOTS)
        for k, target in held:
            q[k] = target + timing.held_noise_rad * rng.standard_normal()
        q[slots], dq[slots] = reading.q, reading.dq
        if len(reading.tau):
            tau[slots] = reading.tau
        x, y, z, w = reading.imu_quat_xyzw
        tick_ms = round(reading.t * 1e3)
        record = LowStateRecord(
            tick=(timing.first_tick_ms + tick_ms) % TICK_MODULUS, mode_machine=mode_machine,
            mode_pr=0, imu_quat_wxyz=np.array([w, x, y, z]), gyro_rad_s=np.array(reading.gyro_rad_s),
            accel_m_s2=np.array(reading.accel_m_s2), q=q, dq=dq, tau_est=tau,
            motor_status=np.zeros(MOTOR_SLOTS, dtype=np.uint32))
        delay_s = timing.latency_s + timing.jitter_s * rng.random()
        yield RECEIVE_EPOCH_NS + round((reading.t + delay_s) * 1e9), record
