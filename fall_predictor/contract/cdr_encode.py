"""The messages a generated bag holds at 1 kHz, written straight to their serialized form (CDR).

Recording a simulated run writes four to five messages per 1 ms step (the robot's joint states,
IMU and two foot wrenches, and the ground-truth ``fall_predictor/msg/Measurement``). Building a
message object for each and serializing it through the ``rosbags`` type store cost about a sixth
of dataset generation; these functions pack the same bytes with ``struct`` (a few µs a message):
the joint names block is packed once per set of names, fixed layouts are one ``pack`` call.

The output is plain little-endian CDR (encapsulation ``0x0001``) byte for byte as
``Typestore.serialize_cdr`` writes it (tested field for field against it, and read back by
:mod:`fall_predictor.contract.cdr` and rosbags): members aligned to their own size from the end of
the 4-byte encapsulation header, strings and sequences led by a ``uint32`` count, a string's count
including its terminating NUL, no padding after the last member. What the writers refuse
(:class:`~fall_predictor.contract.wire.WireFormatError`) is what the message constructors refuse:
stamps outside ``builtin_interfaces/Time``.
"""
from __future__ import annotations

import math
import struct
from functools import lru_cache
from typing import Optional

import numpy as np

from fall_predictor.contract.messages import MAX_STAMP_SEC, quaternion_xyzw
from fall_predictor.contract.topics import WireFormatError
from fall_predictor.monitor.records import Measurement
from fall_predictor.monitor.sensor_records import ImuReading, JointStateReading, WrenchReading
from fall_predictor.monitor.timeline import NS_PER_S

_ENCAPSULATION = b'\x00\x01\x00\x00'
_UINT32 = struct.Struct('<I')
_STAMP = struct.Struct('<iI')
# sensor_msgs/Imu after its header: orientation (4), covariance (9), angular velocity (3),
# covariance (9), linear acceleration (3), covariance (9); all covariances zero (unknown).
_IMU_ZEROS = (0.0,) * 9
_IMU = struct.Struct('<37d')
_WRENCH = struct.Struct('<6d')
# Measurement from com to base_orientation: com 3, linear momentum 3, angular momentum 3,
# heading, quaternion 4.
_MEASUREMENT_HEAD = struct.Struct('<14d')
_SOLE_POSE = struct.Struct('<3d')
_NAN3 = (math.nan, math.nan, math.nan)


def _pad(offset: int, size: int) -> bytes:
    """The zero bytes that align payload ``offset`` to ``size``."""
    return b'\x00' * (-offset % size)


@lru_cache(maxsize=64)
def _string(text: str, offset: int) -> bytes:
    """A CDR string at payload ``offset``: alignment, count (with the NUL), bytes, NUL."""
    data = text.encode()
    return _pad(offset, 4) + _UINT32.pack(len(data) + 1) + data + b'\x00'


def _header(ns: int, frame_id: str) -> bytes:
    """Encapsulation and ``std_msgs/Header`` (stamp of integer ns, frame) at payload offset 0."""
    sec, nanosec = divmod(int(ns), NS_PER_S)
    if not 0 <= sec <= MAX_STAMP_SEC:
        raise WireFormatError(f'stamp {ns} ns is outside builtin_interfaces/Time')
    return _ENCAPSULATION + _STAMP.pack(sec, nanosec) + _string(frame_id, 8)


def _float64s(values: np.ndarray, offset: int) -> bytes:
    """A ``float64[]`` at payload ``offset`` (its elements aligned to 8 only when there are any)."""
    array = np.asarray(values, dtype='<f8').ravel()
    head = _pad(offset, 4) + _UINT32.pack(array.size)
    if not array.size:
        return head
    return head + _pad(offset + len(head), 8) + array.tobytes()


@lru_cache(maxsize=16)
def _names(names: tuple[str, ...], offset: int) -> bytes:
    """A ``string[]`` at payload ``offset`` (a driver sends the same names in every message)."""
    out = _pad(offset, 4) + _UINT32.pack(len(names))
    for name in names:
        out += _string(name, offset + len(out))
    return out


def joint_state_cdr(reading: JointStateReading, frame_id: str = '') -> bytes:
    """``sensor_msgs/JointState`` of ``reading``."""
    out = _header(reading.stamp_ns, frame_id)
    out += _names(tuple(reading.names), len(out) - 4)
    out += _float64s(reading.position, len(out) - 4)
    out += _float64s(reading.velocity, len(out) - 4)
    return out + _float64s(reading.effort, len(out) - 4)


def imu_cdr(reading: ImuReading) -> bytes:
    """``sensor_msgs/Imu`` of ``reading`` (all covariances zero: unknown)."""
    head = _header(reading.stamp_ns, reading.frame_id)
    return head + _pad(len(head) - 4, 8) + _IMU.pack(
        *np.asarray(reading.orientation_xyzw, dtype=float).tolist(), *_IMU_ZEROS,
        *np.asarray(reading.angular_velocity, dtype=float).tolist(), *_IMU_ZEROS,
        *np.asarray(reading.linear_acceleration, dtype=float).tolist(), *_IMU_ZEROS)


def wrench_cdr(reading: WrenchReading) -> bytes:
    """``geometry_msgs/WrenchStamped`` of ``reading``."""
    head = _header(reading.stamp_ns, reading.frame_id)
    return head + _pad(len(head) - 4, 8) + _WRENCH.pack(*np.asarray(reading.wrench, dtype=float).tolist())


def _sole(foot, contacts: np.ndarray, offset: int) -> bytes:
    """``fall_predictor/msg/SoleContact`` at payload ``offset`` (8-aligned)."""
    rows = np.asarray(contacts, dtype='<f8').reshape(-1, 3)
    out = _SOLE_POSE.pack(float(foot[0]), float(foot[1]), float(foot[2])) + _UINT32.pack(len(rows))
    if len(rows):
        out += _pad(offset + len(out), 8) + rows.tobytes()
    return out


def measurement_cdr(ns: int, frame_id: str, m: Optional[Measurement], fault: str = '') -> bytes:
    """``fall_predictor/msg/Measurement``: ``m`` at stamp ``ns``, or (``m`` None) the fault;
    the same message as :func:`fall_predictor.contract.messages.measurement_msg` builds."""
    if m is None:
        if not fault:
            raise WireFormatError('a measurement message without a measurement needs a fault')
        values = (*_NAN3, *_NAN3, *_NAN3, math.nan, 0.0, 0.0, 0.0, 1.0)
        cop, feet, contacts = _NAN3, (_NAN3, _NAN3), (np.zeros((0, 3)), np.zeros((0, 3)))
        non_foot, push = False, (0.0, 0.0, 0.0)
    else:
        values = (*np.asarray(m.com, dtype=float).tolist(), *np.asarray(m.lin_mom, dtype=float).tolist(),
                  *np.asarray(m.ang_mom, dtype=float).tolist(), float(m.heading),
                  *quaternion_xyzw(m.torso_rotation))
        cop, feet = m.cop, (m.left_foot, m.right_foot)
        contacts = (m.left_contacts, m.right_contacts)
        non_foot, push = bool(m.non_foot_contact), m.push_force
    head = _header(ns, frame_id)
    head += _string(fault, len(head) - 4)
    out = head + _pad(len(head) - 4, 8) + _MEASUREMENT_HEAD.pack(*values)
    out += _pad(len(out) - 4, 8) + _SOLE_POSE.pack(*(float(v) for v in cop[:3]))
    for foot, rows in zip(feet, contacts):
        out += _pad(len(out) - 4, 8)
        out += _sole(foot, rows, len(out) - 4)
    out += b'\x01' if non_foot else b'\x00'
    return out + _pad(len(out) - 4, 8) + _SOLE_POSE.pack(*(float(v) for v in push[:3]))
