"""The robot's sensor messages read straight from their serialized form (CDR).

A subscription created with ``raw=True`` hands its callback the message as DDS delivered it.
rclpy's own path turns every message into a Python message object first (~30 µs for a
``JointState``, an ``Imu`` or a ``WrenchStamped``, measured with ``rclpy.serialization``), and
the monitor then copies that object into its reading record; at 1 kHz a sample brings four such
messages. Reading the three sensor types here costs a few µs each: fixed layouts are one
``struct`` call, the joint names are decoded only when they differ from the previous message's
(a driver sends the same names every time), and the ``float64[]`` arrays are numpy views of the
message.

Only plain little-endian CDR is read (encapsulation ``0x0001``, what ROS 2's DDS middlewares
publish by default); any other encapsulation, or a message that does not parse, raises
:class:`CdrError`, and the caller decodes it the general way (rclpy's deserialization). The
records are the ones :mod:`fall_predictor.contract.messages` builds from message objects,
field for field (tested against rclpy's own serialization).

**Writing.** Recording a simulated run writes four to five messages per 1 ms step (the robot's
joint states, IMU and two foot wrenches, and the ground-truth ``fall_predictor/msg/Measurement``);
building a message object for each and serializing it through the ``rosbags`` type store cost a
sixth of dataset generation. :func:`joint_state_cdr`, :func:`imu_cdr`, :func:`wrench_cdr` and
:func:`measurement_cdr` pack the same bytes with ``struct`` (a few µs a message; the joint names
block once per set of names): plain little-endian CDR byte for byte as ``rosbags``'
``serialize_cdr`` writes it (tested against it, and read back by this module and by rosbags):
members aligned to their own size from the end of the 4-byte encapsulation header, strings and
sequences led by a ``uint32`` count, a string's count including its NUL, no padding after the
last member. They refuse (:class:`~fall_predictor.contract.topics.WireFormatError`) what the
message constructors refuse: stamps outside ``builtin_interfaces/Time``.

The predictor node publishes its ``fall_predictor/msg/FallState`` for every sample the same way
(:func:`fall_state_cdr`, handed to rclpy as bytes): building the message object, its header,
stamp and vector, then converting it for the middleware cost about a tenth of the monitor's own
CPU per sample.
"""
from __future__ import annotations

import math
import struct
from functools import lru_cache
from typing import Optional

import numpy as np

from fall_predictor.contract.messages import (CONTACT_MODE_UNKNOWN, MAX_STAMP_SEC,
                                              quaternion_xyzw)
from fall_predictor.contract.topics import WireFormatError
from fall_predictor.monitor.fall_monitor import MonitorState
from fall_predictor.monitor.records import Measurement
from fall_predictor.monitor.sensor_records import ImuReading, JointStateReading, WrenchReading
from fall_predictor.monitor.timeline import NS_PER_S

#: Encapsulation header of plain little-endian CDR (XCDR1), then two option bytes.
CDR_LE = b'\x00\x01'
#: Offsets are counted from the end of the 4-byte encapsulation header (CDR alignment origin).
_ORIGIN = 4
_STAMP = struct.Struct('<iI')
_UINT32 = struct.Struct('<I')
_IMU = struct.Struct('<37d')            # orientation 4, covariance 9, angular velocity 3, cov. 9,
#                                         linear acceleration 3, cov. 9
_WRENCH = struct.Struct('<6d')


class CdrError(ValueError):
    """Not plain little-endian CDR of the expected type (the caller decodes it another way)."""


def _header(data: bytes) -> tuple[int, str, int]:
    """``std_msgs/Header`` at the start: (stamp [ns], frame_id, offset after it)."""
    if data[:2] != CDR_LE:
        raise CdrError(f'encapsulation {data[:2].hex()} is not plain little-endian CDR')
    sec, nanosec = _STAMP.unpack_from(data, _ORIGIN)
    (length,) = _UINT32.unpack_from(data, _ORIGIN + 8)
    start = _ORIGIN + 12
    end = start + length
    if length == 0 or end > len(data) or data[end - 1] != 0:
        raise CdrError('header.frame_id is not a terminated string inside the message')
    return sec * NS_PER_S + nanosec, data[start:end - 1].decode(), end - _ORIGIN


def _align(offset: int, size: int) -> int:
    return offset + (-offset) % size


def _float64s(data: bytes, offset: int) -> tuple[np.ndarray, int]:
    """A ``float64[]`` at payload ``offset``: (a read-only view, the offset after it)."""
    offset = _align(offset, 4)
    (count,) = _UINT32.unpack_from(data, _ORIGIN + offset)
    offset = _align(offset + 4, 8) if count else offset + 4
    end = offset + 8 * count
    if _ORIGIN + end > len(data):
        raise CdrError('a float64[] runs past the end of the message')
    return np.frombuffer(data, '<f8', count, _ORIGIN + offset), end


class JointStateDecoder:
    """``sensor_msgs/JointState`` -> JointStateReading; remembers the last names block, so that
    a driver's unchanged names cost one comparison, not 30 string decodings."""

    def __init__(self) -> None:
        self._names_bytes = b''
        self._names: tuple[str, ...] = ()

    def __call__(self, data: bytes) -> JointStateReading:
        try:
            return self._decode(data)
        except (struct.error, UnicodeDecodeError) as error:
            raise CdrError(f'sensor_msgs/JointState: {error}') from None

    def _decode(self, data: bytes) -> JointStateReading:
        stamp_ns, _, offset = _header(data)
        start = _ORIGIN + _align(offset, 4)
        cached = self._names_bytes
        if cached and data[start:start + len(cached)] == cached:
            names, offset = self._names, start + len(cached) - _ORIGIN
        else:
            names, offset = self._decode_names(data, start)
        position, offset = _float64s(data, offset)
        velocity, offset = _float64s(data, offset)
        effort, _ = _float64s(data, offset)
        return JointStateReading(stamp_ns, names, position, velocity, effort)

    def _decode_names(self, data: bytes, start: int) -> tuple[tuple[str, ...], int]:
        (count,) = _UINT32.unpack_from(data, start)
        offset = start + 4 - _ORIGIN
        names: list[str] = []
        for _ in range(count):
            offset = _align(offset, 4)
            (length,) = _UINT32.unpack_from(data, _ORIGIN + offset)
            begin, end = _ORIGIN + offset + 4, _ORIGIN + offset + 4 + length
            if length == 0 or end > len(data) or data[end - 1] != 0:
                raise CdrError('a joint name is not a terminated string inside the message')
            names.append(data[begin:end - 1].decode())
            offset = end - _ORIGIN
        self._names_bytes = data[start:_ORIGIN + offset]
        self._names = tuple(names)
        return self._names, offset


def _fixed_after_header(data: bytes, layout: struct.Struct, type_name: str
                        ) -> tuple[int, str, tuple[float, ...]]:
    """A stamped message whose body is ``layout`` (doubles): (stamp [ns], frame_id, values)."""
    try:
        stamp_ns, frame_id, offset = _header(data)
        return stamp_ns, frame_id, layout.unpack_from(data, _ORIGIN + _align(offset, 8))
    except (struct.error, UnicodeDecodeError) as error:
        raise CdrError(f'{type_name}: {error}') from None


def imu_reading(data: bytes) -> ImuReading:
    """``sensor_msgs/Imu`` -> ImuReading (covariances are not read)."""
    stamp_ns, frame_id, v = _fixed_after_header(data, _IMU, 'sensor_msgs/Imu')
    return ImuReading(stamp_ns, frame_id, np.array(v[0:4]), np.array(v[13:16]),
                      np.array(v[25:28]))


def wrench_reading(data: bytes) -> WrenchReading:
    """``geometry_msgs/WrenchStamped`` -> WrenchReading."""
    stamp_ns, frame_id, v = _fixed_after_header(data, _WRENCH, 'geometry_msgs/WrenchStamped')
    return WrenchReading(stamp_ns, frame_id, np.array(v))


# --------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------

_ENCAPSULATION = CDR_LE + b'\x00\x00'
# sensor_msgs/Imu after its header: orientation (4), covariance (9), angular velocity (3),
# covariance (9), linear acceleration (3), covariance (9); all covariances zero (unknown).
_IMU_ZEROS = (0.0,) * 9
# Measurement from com to base_orientation: com 3, linear momentum 3, angular momentum 3,
# heading, quaternion 4.
_MEASUREMENT_HEAD = struct.Struct('<14d')
_DOUBLES3 = struct.Struct('<3d')
_NAN3 = (math.nan, math.nan, math.nan)


def _pad(offset: int, size: int) -> bytes:
    """The zero bytes that align payload ``offset`` to ``size``."""
    return b'\x00' * (-offset % size)


@lru_cache(maxsize=64)
def _packed_string(text: str, offset: int) -> bytes:
    """A CDR string at payload ``offset``: alignment, count (with the NUL), bytes, NUL."""
    data = text.encode()
    return _pad(offset, 4) + _UINT32.pack(len(data) + 1) + data + b'\x00'


def _packed_header(ns: int, frame_id: str) -> bytes:
    """Encapsulation and ``std_msgs/Header`` (stamp of integer ns, frame) at payload offset 0."""
    sec, nanosec = divmod(int(ns), NS_PER_S)
    if not 0 <= sec <= MAX_STAMP_SEC:
        raise WireFormatError(f'stamp {ns} ns is outside builtin_interfaces/Time')
    return _ENCAPSULATION + _STAMP.pack(sec, nanosec) + _packed_string(frame_id, 8)


def _packed_float64s(values: np.ndarray, offset: int) -> bytes:
    """A ``float64[]`` at payload ``offset`` (its elements aligned to 8 only when there are any)."""
    array = np.asarray(values, dtype='<f8').ravel()
    head = _pad(offset, 4) + _UINT32.pack(array.size)
    if not array.size:
        return head
    return head + _pad(offset + len(head), 8) + array.tobytes()


@lru_cache(maxsize=16)
def _packed_names(names: tuple[str, ...], offset: int) -> bytes:
    """A ``string[]`` at payload ``offset`` (a driver sends the same names in every message)."""
    out = _pad(offset, 4) + _UINT32.pack(len(names))
    for name in names:
        out += _packed_string(name, offset + len(out))
    return out


def joint_state_cdr(reading: JointStateReading, frame_id: str = '') -> bytes:
    """``sensor_msgs/JointState`` of ``reading``."""
    out = _packed_header(reading.stamp_ns, frame_id)
    out += _packed_names(tuple(reading.names), len(out) - 4)
    out += _packed_float64s(reading.position, len(out) - 4)
    out += _packed_float64s(reading.velocity, len(out) - 4)
    return out + _packed_float64s(reading.effort, len(out) - 4)


def imu_cdr(reading: ImuReading) -> bytes:
    """``sensor_msgs/Imu`` of ``reading`` (all covariances zero: unknown)."""
    head = _packed_header(reading.stamp_ns, reading.frame_id)
    return head + _pad(len(head) - 4, 8) + _IMU.pack(
        *np.asarray(reading.orientation_xyzw, dtype=float).tolist(), *_IMU_ZEROS,
        *np.asarray(reading.angular_velocity, dtype=float).tolist(), *_IMU_ZEROS,
        *np.asarray(reading.linear_acceleration, dtype=float).tolist(), *_IMU_ZEROS)


def wrench_cdr(reading: WrenchReading) -> bytes:
    """``geometry_msgs/WrenchStamped`` of ``reading``."""
    head = _packed_header(reading.stamp_ns, reading.frame_id)
    return head + _pad(len(head) - 4, 8) + _WRENCH.pack(*np.asarray(reading.wrench, dtype=float).tolist())


def _packed_sole(foot, contacts: np.ndarray, offset: int) -> bytes:
    """``fall_predictor/msg/SoleContact`` at payload ``offset`` (8-aligned)."""
    rows = np.asarray(contacts, dtype='<f8').reshape(-1, 3)
    out = _DOUBLES3.pack(float(foot[0]), float(foot[1]), float(foot[2])) + _UINT32.pack(len(rows))
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
    head = _packed_header(ns, frame_id)
    head += _packed_string(fault, len(head) - 4)
    out = head + _pad(len(head) - 4, 8) + _MEASUREMENT_HEAD.pack(*values)
    out += _pad(len(out) - 4, 8) + _DOUBLES3.pack(*(float(v) for v in cop[:3]))
    for foot, rows in zip(feet, contacts):
        out += _pad(len(out) - 4, 8)
        out += _packed_sole(foot, rows, len(out) - 4)
    out += b'\x01' if non_foot else b'\x00'
    return out + _pad(len(out) - 4, 8) + _DOUBLES3.pack(*(float(v) for v in push[:3]))


_UINT8 = struct.Struct('<B')
# FallState after its reason: falling, latched, atomic, guard (bool), contact_mode (uint8).
_STATE_FLAGS = struct.Struct('<5B')
# FallState's last members: time_to_fall, fall_direction (x, y, z), tau_his.
_STATE_TAIL = struct.Struct('<5d')


def fall_state_cdr(ns: int, frame_id: str, state: MonitorState) -> bytes:
    """``fall_predictor/msg/FallState`` of ``state`` at the input sample's stamp ``ns``: the
    message :func:`fall_predictor.contract.messages.fall_state_msg` builds, serialized."""
    out = _packed_header(ns, frame_id) + _UINT8.pack(state.status)
    out += _packed_string(state.reason, len(out) - _ORIGIN)
    out += _STATE_FLAGS.pack(bool(state.falling), bool(state.latched), bool(state.atomic),
                             bool(state.guard),
                             CONTACT_MODE_UNKNOWN if state.contact_mode is None else state.contact_mode)
    dx, dy = state.fall_direction
    return out + _pad(len(out) - _ORIGIN, 8) + _STATE_TAIL.pack(
        float(state.time_to_fall_s), float(dx), float(dy), 0.0 if math.isfinite(dx) else math.nan,
        float(state.tau_his_s))
