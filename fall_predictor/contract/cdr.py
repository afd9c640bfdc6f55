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
"""
from __future__ import annotations

import struct
from typing import Optional

import numpy as np

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
