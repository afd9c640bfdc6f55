"""Unitree's humanoid low-level state on the wire: ``lowstate`` (``unitree_hg/msg/LowState``).

The topic as unitree_ros2 publishes it (:data:`LOWSTATE`), the message read straight from its CDR
bytes (:func:`lowstate_record`, what the estimator node does at 500 Hz) or from a message object of
rclpy or rosbags (:func:`lowstate_from_msg`), and written (:func:`lowstate_cdr`: replays, tests,
bags). The definitions are Unitree's own ``.msg`` files, shipped unchanged with their license in
``vendor/unitree_hg`` (:func:`unitree_hg_definitions`), so that the bag tools read a
``ros2 bag record /lowstate`` recording without Unitree's software installed.

The layout (plain little-endian CDR, offsets from the end of the 4-byte encapsulation header):
``version`` uint32[2] at 0, ``mode_pr`` 8, ``mode_machine`` 9, ``tick`` 12, ``imu_state`` 16
(quaternion float32[4], gyroscope[3], accelerometer[3], rpy[3], temperature int16 at 68),
``motor_state[35]`` from 70: each ``mode`` uint8, then from a 4-byte boundary ``q``, ``dq``,
``ddq``, ``tau_est`` float32, ``temperature`` int16[2], ``vol`` float32, ``sensor`` uint32[2],
``motorstate`` uint32, ``reserve`` uint32[4] (56 bytes a motor, ``q`` of motor k at 72 + 56 k);
then ``wireless_remote`` uint8[40], ``reserve`` uint32[4], ``crc``: 2088 bytes. Tested against
rosbags' serialization. Read so, a message costs 6 µs; rclpy's message object of it ~0.7 ms (35
nested ``MotorState`` objects), a third of the 2 ms between messages.
"""
from __future__ import annotations

import os
import sys
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from fall_predictor.contract.topics import SENSOR_SUB_QOS, QosSpec, TopicSpec, WireFormatError
from fall_predictor.monitor.lowstate import MOTOR_SLOTS, LowStateRecord

PACKAGE = 'unitree_hg'
LOWSTATE_TYPE = 'unitree_hg/msg/LowState'
#: The rate of ``lowstate`` (unitree_ros2's "high frequency" low state; ``lf/lowstate`` is slower).
LOWSTATE_RATE_HZ = 500.0
#: unitree_sdk2's DDS writers publish with DDS's default QoS (reliable, volatile, keep last 1);
#: unitree_ros2's examples read with rclcpp's default (reliable, depth 10). The monitor reads
#: best effort (matches a reliable or a best-effort writer; REP 2003 sensor data): a reader
#: that falls behind gets fresh samples, and a lost one shows in the tick's gap.
LOWSTATE_QOS = QosSpec('reliable', 'volatile', 1)
LOWSTATE = TopicSpec(
    '/lowstate', LOWSTATE_TYPE, LOWSTATE_QOS, LOWSTATE_RATE_HZ, None, None,
    'a Unitree humanoid\'s low-level state (input:=unitree_hg): motors by index, pelvis IMU, '
    'tick [ms], mode_machine', SENSOR_SUB_QOS)

_CDR_LE = b'\x00\x01'
_ORIGIN = 4
PAYLOAD_BYTES = 2088
_MOTOR = np.dtype({'names': ['q', 'dq', 'ddq', 'tau_est', 'temperature', 'vol', 'sensor',
                             'motorstate'],
                   'formats': ['<f4', '<f4', '<f4', '<f4', ('<i2', 2), '<f4', ('<u4', 2), '<u4'],
                   'offsets': [0, 4, 8, 12, 16, 20, 24, 32], 'itemsize': 56})
_MOTORS_AT = 72           # q of motor 0
_MOTOR_MODE_AT = (70, *(68 + 56 * k for k in range(1, MOTOR_SLOTS)))
_IMU = np.dtype('<f4')


def definitions_dir() -> Path:
    """The folder holding Unitree's ``LowState.msg`` (FileNotFoundError if none does): this
    package's vendored copy (source tree, or installed in its share folder), else an installed
    ``unitree_hg`` (unitree_ros2)."""
    candidates = [Path(__file__).resolve().parents[2] / 'vendor' / PACKAGE / 'msg']
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    for prefix in (*prefixes, sys.prefix):
        candidates += [Path(prefix) / 'share' / 'fall_predictor' / 'vendor' / PACKAGE / 'msg',
                       Path(prefix) / 'share' / PACKAGE / 'msg']
    for folder in candidates:
        if (folder / 'LowState.msg').is_file():
            return folder
    raise FileNotFoundError(f'no {PACKAGE} message definitions in {[str(c) for c in candidates]}')


@lru_cache(maxsize=1)
def unitree_hg_definitions() -> dict[str, str]:
    """``{'unitree_hg/msg/LowState': text, ...}``: the three messages of the low-level state."""
    folder = definitions_dir()
    return {f'{PACKAGE}/msg/{name}': (folder / f'{name}.msg').read_text()
            for name in ('IMUState', 'MotorState', 'LowState')}


def lowstate_record(data: bytes) -> LowStateRecord:
    """A serialized ``LowState`` (plain little-endian CDR) as a record; WireFormatError for
    anything else (another encapsulation, a short message)."""
    if data[:2] != _CDR_LE:
        raise WireFormatError(f'LowState: encapsulation {bytes(data[:2]).hex()} is not plain '
                              'little-endian CDR')
    if len(data) < _ORIGIN + PAYLOAD_BYTES:
        raise WireFormatError(f'LowState: {len(data)} bytes, expected {_ORIGIN + PAYLOAD_BYTES}')
    head = data[_ORIGIN + 8:_ORIGIN + 16]
    imu = np.frombuffer(data, _IMU, 10, _ORIGIN + 16).astype(float)
    motors = np.frombuffer(data, _MOTOR, MOTOR_SLOTS, _ORIGIN + _MOTORS_AT)
    return LowStateRecord(
        tick=int.from_bytes(head[4:8], 'little'), mode_machine=head[1], mode_pr=head[0],
        imu_quat_wxyz=imu[0:4], gyro_rad_s=imu[4:7], accel_m_s2=imu[7:10],
        q=motors['q'].astype(float), dq=motors['dq'].astype(float),
        tau_est=motors['tau_est'].astype(float), motor_status=motors['motorstate'].copy())


def lowstate_cdr(record: LowStateRecord, motor_mode: int = 1) -> bytes:
    """A record as the serialized ``LowState`` a robot publishes (every motor's ``mode`` set to
    ``motor_mode``, the fields the record lacks zero)."""
    buffer = bytearray(_ORIGIN + PAYLOAD_BYTES)
    buffer[:2] = _CDR_LE
    buffer[_ORIGIN + 8] = int(record.mode_pr)
    buffer[_ORIGIN + 9] = int(record.mode_machine)
    buffer[_ORIGIN + 12:_ORIGIN + 16] = (int(record.tick) % (1 << 32)).to_bytes(4, 'little')
    imu = np.frombuffer(buffer, _IMU, 10, _ORIGIN + 16)
    imu[:] = np.concatenate([record.imu_quat_wxyz, record.gyro_rad_s, record.accel_m_s2])
    motors = np.frombuffer(buffer, _MOTOR, MOTOR_SLOTS, _ORIGIN + _MOTORS_AT)
    for name, values in (('q', record.q), ('dq', record.dq), ('tau_est', record.tau_est),
                         ('motorstate', record.motor_status)):
        motors[name] = values
    for at in _MOTOR_MODE_AT:
        buffer[_ORIGIN + at] = motor_mode
    return bytes(buffer)


def lowstate_from_msg(msg: Any) -> LowStateRecord:
    """A ``LowState`` message object (rclpy's or rosbags') as a record."""
    try:
        imu = msg.imu_state
        motors = msg.motor_state
        if len(motors) != MOTOR_SLOTS:
            raise WireFormatError(f'LowState with {len(motors)} motors, expected {MOTOR_SLOTS}')
        return LowStateRecord(
            tick=int(msg.tick), mode_machine=int(msg.mode_machine), mode_pr=int(msg.mode_pr),
            imu_quat_wxyz=np.asarray(imu.quaternion, dtype=float),
            gyro_rad_s=np.asarray(imu.gyroscope, dtype=float),
            accel_m_s2=np.asarray(imu.accelerometer, dtype=float),
            q=np.array([m.q for m in motors], dtype=float),
            dq=np.array([m.dq for m in motors], dtype=float),
            tau_est=np.array([m.tau_est for m in motors], dtype=float),
            motor_status=np.array([m.motorstate for m in motors], dtype=np.uint32))
    except AttributeError as error:
        raise WireFormatError(f'not a unitree_hg/msg/LowState: {error}') from None
