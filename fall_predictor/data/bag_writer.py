"""Writing rosbag2 bags (MCAP storage) in the message contract of :mod:`fall_predictor.contract`.

Uses the pure-Python ``rosbags`` library (no rclpy) with :func:`~fall_predictor.data.bagio.typestore`
(ROS 2 Jazzy's types and this package's own). Bags are rosbag2 directories (``metadata.yaml`` +
one ``.mcap`` file), metadata version 9 as written by Jazzy's rosbag2, so ``ros2 bag info/play``
reads them. Chunks are zstd-compressed inside the MCAP file (MCAP's own compression, transparent
to readers), with a zstd content checksum so that damaged chunks are detected rather than decoded
into wrong numbers. Log time of every message = its stamp [ns]; reading is
:mod:`fall_predictor.data.bagio`.
"""
from __future__ import annotations

import os
import sys
from collections.abc import Callable, Sequence
from contextlib import suppress
from functools import partial
from pathlib import Path
from types import TracebackType
from typing import Optional

import numpy as np
from numpy.typing import ArrayLike
from rosbags.interfaces import (Connection, Qos, QosDurability, QosHistory, QosLiveliness,
                                QosReliability, QosTime)
from rosbags.rosbag2 import Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.rosbag2.storage_mcap import McapWriter
from rosbags.typesys.store import Typestore

from fall_predictor.contract import cdr, messages
from fall_predictor.contract.topics import (FEATURES, HEADING_FRAME, JOINT_STATES, MEASUREMENT,
                                            ODOM_FRAME, PUSH, STATE, TOPICS_BY_NAME, WORLD_FRAME,
                                            QosSpec, time_to_ns, time_to_stamp)
from fall_predictor.contract.wire import JointStateSample, PushEvent
from fall_predictor.data.bagio import ROSBAG2_VERSION, BagError, RosbagsMsg, describe, typestore
from fall_predictor.monitor.fall_monitor import MonitorState
from fall_predictor.monitor.records import Measurement

if sys.version_info >= (3, 14):
    from compression import zstd
else:
    from backports import zstd


def _rosbags_qos(spec: QosSpec) -> Qos:
    zero = QosTime(0, 0)
    return Qos(
        history=QosHistory.KEEP_LAST, depth=spec.depth,
        reliability=(QosReliability.RELIABLE if spec.reliability == 'reliable'
                     else QosReliability.BEST_EFFORT),
        durability=(QosDurability.TRANSIENT_LOCAL if spec.durability == 'transient_local'
                    else QosDurability.VOLATILE),
        deadline=zero, lifespan=zero, liveliness=QosLiveliness.SYSTEM_DEFAULT,
        liveliness_lease_duration=zero, avoid_ros_namespace_conventions=False)


# The zstd frames of MCAP chunks carry a content checksum (xxhash64), verified by every zstd
# decoder, including the one in ros2 bag's MCAP plugin.
_compress_with_checksum = partial(
    zstd.compress, options={zstd.CompressionParameter.checksum_flag: 1})


class BagWriter:
    """Context manager writing one rosbag2 bag directory in MCAP storage.

    ``path`` must not exist. With ``compress`` (default) MCAP chunks are zstd-compressed with
    a checksum; without it chunks carry no checksum (rosbags writes none), so damage inside a
    chunk may go unnoticed.
    Topics are registered on first use, with the QoS of their :data:`~fall_predictor.contract.wire.TOPICS`
    row (so ``ros2 bag play`` offers the same QoS). If the ``with`` block raises, the bag is
    left without ``metadata.yaml`` (``fall-predictor repair-bag`` recovers it).
    """

    def __init__(self, path: str | os.PathLike[str], *, compress: bool = True) -> None:
        self.path = Path(path)
        self._compress = compress
        self._writer: Optional[Writer] = None
        self._connections: dict[str, Connection] = {}
        self._types = typestore().types

    def __enter__(self) -> BagWriter:
        try:
            writer = Writer(self.path, version=ROSBAG2_VERSION, storage_plugin=StoragePlugin.MCAP)
            if self._compress:
                writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
            writer.open()
        except Exception as exc:
            raise BagError(f'{self.path}: cannot create bag: {describe(exc)}') from exc
        if self._compress and isinstance(writer.storage, McapWriter):
            # rosbags 0.11 compresses chunks with this attribute; the checksum flag is
            # checked by test_mcap_chunks_are_zstd_with_checksum.
            writer.storage.compressor = _compress_with_checksum
        self._writer = writer
        return self

    def __exit__(self, exc_type: Optional[type[BaseException]], exc: Optional[BaseException],
                 tb: Optional[TracebackType]) -> None:
        writer, self._writer = self._writer, None
        assert writer is not None
        if exc_type is not None:
            with suppress(Exception):       # keep the caller's exception
                writer.abort()
            return
        try:
            writer.close()
        except Exception as error:
            raise BagError(f'{self.path}: cannot finish bag: {describe(error)}') from error

    def write(self, topic: str, msg_type: str, t_ns: int, msg: object) -> None:
        """Write a rosbags message object ``msg`` of ``msg_type`` at log time ``t_ns`` [ns]."""
        self._write(topic, msg_type, t_ns, lambda: typestore().serialize_cdr(msg, msg_type))

    def write_raw(self, topic: str, msg_type: str, t_ns: int, data: bytes, *,
                  store: Optional[Typestore] = None) -> None:
        """Write the CDR-serialized message ``data`` of ``msg_type`` at log time ``t_ns`` [ns].

        ``store``: the type store whose definition of ``msg_type`` the bag records for the topic
        (the package's :func:`~fall_predictor.data.bagio.typestore` by default); a copied
        message keeps the definition it was recorded with.
        """
        self._write(topic, msg_type, t_ns, lambda: data, store)

    def _write(self, topic: str, msg_type: str, t_ns: int, serialized: Callable[[], bytes],
               store: Optional[Typestore] = None) -> None:
        if self._writer is None:
            raise BagError(f'{self.path}: bag is not open (use BagWriter as a context manager)')
        spec = TOPICS_BY_NAME.get(topic)
        if spec is not None and spec.msg_type != msg_type:
            raise BagError(f'{self.path}: topic {topic} has type {spec.msg_type}, not {msg_type}')
        if t_ns < 0:
            raise BagError(f'{self.path}: log time must be >= 0 ns, got {t_ns}')
        connection = self._connections.get(topic)
        if connection is not None and connection.msgtype != msg_type:
            raise BagError(f'{self.path}: topic {topic} was written as {connection.msgtype}, '
                           f'not {msg_type}')
        try:
            if connection is None:
                qos = [] if spec is None else [_rosbags_qos(spec.qos)]
                connection = self._writer.add_connection(
                    topic, msg_type, typestore=typestore() if store is None else store,
                    offered_qos_profiles=qos)
                self._connections[topic] = connection
            self._writer.write(connection, t_ns, serialized())
        except Exception as exc:
            raise BagError(f'{self.path}: cannot write {topic}: {describe(exc)}') from exc

    def set_custom_data(self, key: str, value: str) -> None:
        """A key-value pair in the bag's ``metadata.yaml`` (``custom_data``)."""
        if self._writer is None:
            raise BagError(f'{self.path}: bag is not open (use BagWriter as a context manager)')
        self._writer.set_custom_data(key, value)

    def _stamp(self, t: float) -> RosbagsMsg:
        sec, nanosec = time_to_stamp(t)
        return self._types['builtin_interfaces/msg/Time'](sec=sec, nanosec=nanosec)

    def _header(self, t: float, frame_id: str = '') -> RosbagsMsg:
        return self._types['std_msgs/msg/Header'](stamp=self._stamp(t), frame_id=frame_id)

    def write_measurement(self, m: Measurement, topic: str = MEASUREMENT.name) -> None:
        """One Measurement (``fall_predictor/msg/Measurement``) on ``topic`` stamped and logged
        at ``m.t``. Raises WireFormatError (not BagError) if ``m`` breaks the contract."""
        ns = time_to_ns(m.t)
        messages.check_measurement(m)           # what a reader checks
        self.write_raw(topic, MEASUREMENT.msg_type, ns, cdr.measurement_cdr(ns, ODOM_FRAME, m))

    def write_features(self, t: float, x: ArrayLike, mode: int, base_tilt_rad: float = 0.0) -> None:
        """Features (15 values, contact mode index) at ``t`` [s] on ``/fall_predictor/features``."""
        ns = time_to_ns(t)
        msg = messages.features_msg(self._types, ns, x, mode, base_tilt_rad)
        messages.features_from_msg(msg)
        self.write(FEATURES.name, FEATURES.msg_type, ns, msg)

    def write_state(self, t: float, state: MonitorState) -> None:
        """A monitor state at sample time ``t`` [s] on ``/fall_predictor/state``."""
        ns = time_to_ns(t)
        msg = messages.fall_state_msg(self._types, ns, HEADING_FRAME, state)
        messages.fall_state_from_msg(msg)
        self.write(STATE.name, STATE.msg_type, ns, msg)

    def write_joint_state(self, t: float, names: Sequence[str], positions: ArrayLike,
                          velocities: ArrayLike = (), efforts: ArrayLike = (),
                          topic: str = JOINT_STATES.name) -> None:
        """Joint values at sim time ``t`` [s] ([rad], [rad/s], [N m]) as a JointState.

        ``topic`` may also be ``/fall_predictor/joint_commands``.
        """
        sample = JointStateSample(t, tuple(names), np.asarray(positions, dtype=np.float64),
                                  np.asarray(velocities, dtype=np.float64),
                                  np.asarray(efforts, dtype=np.float64))
        msg = self._types['sensor_msgs/msg/JointState'](
            header=self._header(t), name=list(sample.names), position=sample.position,
            velocity=sample.velocity, effort=sample.effort)
        self.write(topic, JOINT_STATES.msg_type, time_to_ns(t), msg)

    def write_push(self, t: float, force_xyz: ArrayLike) -> None:
        """A push with onset ``t`` [s] and world force [N] on ``/fall_predictor/push``."""
        push = PushEvent(t, np.asarray(force_xyz, dtype=np.float64))
        types = self._types
        vector = types['geometry_msgs/msg/Vector3']
        wrench = types['geometry_msgs/msg/Wrench'](
            force=vector(*(float(v) for v in push.force)), torque=vector(0.0, 0.0, 0.0))
        msg = types['geometry_msgs/msg/WrenchStamped'](
            header=self._header(t, WORLD_FRAME), wrench=wrench)
        self.write(PUSH.name, PUSH.msg_type, time_to_ns(t), msg)
