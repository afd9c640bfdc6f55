"""Write and read rosbag2 bags (MCAP storage) with the topics of :mod:`fall_predictor.data.wire`.

Uses the pure-Python ``rosbags`` library (no rclpy), with the ROS 2 Jazzy type store. Bags are
rosbag2 directories (``metadata.yaml`` + one ``.mcap`` file), metadata version 9 as written by
Jazzy's rosbag2, so ``ros2 bag info/play`` reads them. Chunks are zstd-compressed inside the
MCAP file (MCAP's own compression, transparent to readers), with a zstd content checksum so
that damaged chunks are detected rather than decoded into wrong numbers.

Log time of every message = simulation time [ns]. Any failure to read (missing, truncated or
corrupt bag, malformed message, missing required topic) raises :class:`BagError` naming the
bag; library exceptions never escape.
"""
from __future__ import annotations

import os
import sys
from collections.abc import Collection, Iterator, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from functools import lru_cache, partial
from pathlib import Path
from types import TracebackType
from typing import Any, Literal, Optional, cast

import numpy as np
from numpy.typing import ArrayLike
from rosbags.interfaces import (
    Connection,
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import Reader, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.rosbag2.storage_mcap import McapWriter
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from fall_predictor.monitor.records import Measurement
from fall_predictor.data.topics import (FEATURES, FEATURES_LABEL, JOINT_STATES, MEASUREMENT, MEASUREMENT_LABEL, PUSH, STATE, TOPICS_BY_NAME, WORLD_FRAME, QosSpec, WireFormatError)
from fall_predictor.data.wire import (FeatureSample, JointStateSample, PredictorState, PushEvent, check_layout, pack_features, pack_measurement, push_from_wire, state_from_diagnostic, state_to_status, unpack_features, unpack_measurement)
from fall_predictor.data.topics import ns_to_time, stamp_to_ns, time_to_ns, time_to_stamp

if sys.version_info >= (3, 14):
    from compression import zstd
else:
    from backports import zstd

#: rosbag2 metadata version written by ROS 2 Jazzy (rosbag2 0.26).
ROSBAG2_VERSION: Literal[9] = 9

#: A rosbags type store message object (a dataclass generated at run time).
RosbagsMsg = Any


class BagError(Exception):
    """A bag cannot be written or read. The message names the bag and the problem."""


@lru_cache(maxsize=1)
def typestore() -> Typestore:
    """The ROS 2 Jazzy message type store (built once, ~0.15 s)."""
    return get_typestore(Stores.ROS2_JAZZY)


def _describe(exc: BaseException) -> str:
    return f'{type(exc).__name__}: {exc}'


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


# --------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------

class BagWriter:
    """Context manager writing one rosbag2 bag directory in MCAP storage.

    ``path`` must not exist. With ``compress`` (default) MCAP chunks are zstd-compressed with
    a checksum; without it chunks carry no checksum (rosbags writes none), so damage inside a
    chunk may go unnoticed.
    Topics are registered on first use, with the QoS of their :data:`~fall_predictor.data.wire.TOPICS`
    row (so ``ros2 bag play`` offers the same QoS). If the ``with`` block raises, the bag is
    left without ``metadata.yaml`` (``ros2 bag reindex`` can recover it).
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
            raise BagError(f'{self.path}: cannot create bag: {_describe(exc)}') from exc
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
            raise BagError(f'{self.path}: cannot finish bag: {_describe(error)}') from error

    def write(self, topic: str, msg_type: str, t_ns: int, msg: object) -> None:
        """Write a rosbags message object ``msg`` of ``msg_type`` at log time ``t_ns`` [ns]."""
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
                    topic, msg_type, typestore=typestore(), offered_qos_profiles=qos)
                self._connections[topic] = connection
            self._writer.write(connection, t_ns, typestore().serialize_cdr(msg, msg_type))
        except Exception as exc:
            raise BagError(f'{self.path}: cannot write {topic}: {_describe(exc)}') from exc

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

    def _float64_array(self, values: np.ndarray, label: str) -> RosbagsMsg:
        types = self._types
        n = len(values)
        layout = types['std_msgs/msg/MultiArrayLayout'](
            dim=[types['std_msgs/msg/MultiArrayDimension'](label=label, size=n, stride=n)],
            data_offset=0)
        return types['std_msgs/msg/Float64MultiArray'](layout=layout, data=values)

    def write_measurement(self, m: Measurement) -> None:
        """One Measurement on ``/fall_predictor/measurement`` at log time ``m.t``.

        Raises WireFormatError (not BagError) if ``m`` itself violates the wire contract.
        """
        msg = self._float64_array(pack_measurement(m), MEASUREMENT_LABEL)
        self.write(MEASUREMENT.name, MEASUREMENT.msg_type, time_to_ns(m.t), msg)

    def write_features(self, t: float, x: ArrayLike, mode: int) -> None:
        """Features (t [s], 15 values, contact mode index) on ``/fall_predictor/features``."""
        msg = self._float64_array(pack_features(t, x, mode), FEATURES_LABEL)
        self.write(FEATURES.name, FEATURES.msg_type, time_to_ns(t), msg)

    def write_state(self, state: PredictorState) -> None:
        """A PredictorState on ``/fall_predictor/state`` at log time ``state.t``."""
        types = self._types
        fields = state_to_status(state)
        status = types['diagnostic_msgs/msg/DiagnosticStatus'](
            level=fields.level, name=fields.name, message=fields.message, hardware_id='',
            values=[types['diagnostic_msgs/msg/KeyValue'](key=key, value=value)
                    for key, value in fields.values])
        msg = types['diagnostic_msgs/msg/DiagnosticArray'](
            header=self._header(state.t), status=[status])
        self.write(STATE.name, STATE.msg_type, fields.stamp_ns, msg)

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


# --------------------------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class BagMessage:
    """One message of a bag, deserialised to a rosbags message object."""

    topic: str
    msg_type: str
    t_ns: int                       #: log time = simulation time [ns]
    msg: RosbagsMsg


@contextmanager
def _open_reader(path: Path) -> Iterator[Reader]:
    if not path.exists():
        raise BagError(f'{path}: bag does not exist')
    try:
        reader = Reader(path)
        reader.open()
    except Exception as exc:
        raise BagError(f'{path}: cannot open bag (missing part, truncated or corrupt): '
                       f'{_describe(exc)}') from exc
    try:
        yield reader
    finally:
        reader.close()


def _messages(reader: Reader, path: Path,
              topics: Optional[Collection[str]]) -> Iterator[BagMessage]:
    connections = [c for c in reader.connections if topics is None or c.topic in topics]
    if not connections:
        return
    store = typestore()
    raw_messages = reader.messages(connections=connections)
    while True:
        try:
            connection, t_ns, raw = next(raw_messages)
        except StopIteration:
            return
        except Exception as exc:
            raise BagError(f'{path}: damaged bag: {_describe(exc)}') from exc
        try:
            msg = store.deserialize_cdr(raw, connection.msgtype)
        except Exception as exc:
            raise BagError(f'{path}: {connection.topic} message at {t_ns} ns does not decode '
                           f'as {connection.msgtype}: {_describe(exc)}') from exc
        yield BagMessage(connection.topic, connection.msgtype, t_ns, msg)


def iter_messages(path: str | os.PathLike[str],
                  topics: Optional[Collection[str]] = None) -> Iterator[BagMessage]:
    """Messages of the bag at ``path`` in log time order, all topics or only ``topics``."""
    bag = Path(path)
    with _open_reader(bag) as reader:
        yield from _messages(reader, bag, topics)


def _header_ns(msg: RosbagsMsg) -> int:
    return stamp_to_ns(msg.header.stamp.sec, msg.header.stamp.nanosec)


def _decode_measurement(msg: RosbagsMsg) -> Measurement:
    check_layout(msg.layout, MEASUREMENT_LABEL, len(msg.data))
    return unpack_measurement(msg.data)


def _decode_features(msg: RosbagsMsg) -> FeatureSample:
    check_layout(msg.layout, FEATURES_LABEL, len(msg.data))
    return unpack_features(msg.data)


def _decode_joint_state(msg: RosbagsMsg) -> JointStateSample:
    return JointStateSample(ns_to_time(_header_ns(msg)), tuple(msg.name), msg.position,
                            msg.velocity, msg.effort)


def _decode_push(msg: RosbagsMsg) -> PushEvent:
    force = msg.wrench.force
    return push_from_wire(_header_ns(msg), msg.header.frame_id, (force.x, force.y, force.z))


def _decode_state(msg: RosbagsMsg) -> PredictorState:
    return state_from_diagnostic(_header_ns(msg), msg.status)


_DECODERS = {
    MEASUREMENT.name: _decode_measurement,
    FEATURES.name: _decode_features,
    STATE.name: _decode_state,
    JOINT_STATES.name: _decode_joint_state,
    PUSH.name: _decode_push,
}


def decode(message: BagMessage) -> object:
    """The wire record of a message on a decoded topic (Measurement, FeatureSample,
    PredictorState, JointStateSample, PushEvent); raises WireFormatError if malformed."""
    try:
        decoder = _DECODERS[message.topic]
    except KeyError:
        raise WireFormatError(f'no decoder for topic {message.topic}') from None
    return decoder(message.msg)


@dataclass(slots=True)
class JointStateSeries:
    """All ``/joint_states`` messages of a bag as arrays (N messages, J joints)."""

    names: tuple[str, ...]
    t: np.ndarray                   #: (N,) header stamps [s]
    position: np.ndarray            #: (N, J) [rad]
    velocity: np.ndarray            #: (N, J) [rad/s], or (N, 0) if not recorded
    effort: np.ndarray              #: (N, J) [N m], or (N, 0) if not recorded


@dataclass(slots=True)
class RecordedTrajectory:
    """The decoded content of one bag. A topic absent from the bag gives None (never an
    empty or zero-filled stand-in); ``topics`` lists every topic found with its type."""

    path: Path
    topics: dict[str, str]
    measurements: Optional[list[Measurement]]
    features: Optional[list[FeatureSample]]
    states: Optional[list[PredictorState]]
    joint_states: Optional[JointStateSeries]
    pushes: Optional[list[PushEvent]]


def _joint_series(path: Path, samples: list[JointStateSample]) -> JointStateSeries:
    if not samples:
        empty = np.zeros((0, 0))
        return JointStateSeries((), np.zeros(0), empty, empty, empty)
    names = samples[0].names
    for what in ('velocity', 'effort'):
        sizes = {getattr(s, what).size for s in samples}
        if len(sizes) > 1:
            raise BagError(f'{path}: {JOINT_STATES.name} {what} sizes vary: {sorted(sizes)}')
    for s in samples:
        if s.names != names:
            raise BagError(f'{path}: {JOINT_STATES.name} joint names change at t={s.t} s')
    return JointStateSeries(
        names=names,
        t=np.array([s.t for s in samples]),
        position=np.stack([s.position for s in samples]),
        velocity=np.stack([s.velocity for s in samples]),
        effort=np.stack([s.effort for s in samples]))


def read_trajectory(path: str | os.PathLike[str], *,
                    required: Collection[str] = (MEASUREMENT.name,)) -> RecordedTrajectory:
    """Read and validate a whole bag.

    Raises BagError if the bag is missing or damaged, a ``required`` topic is absent or empty,
    a known topic has the wrong type, any decoded message is malformed, or fewer messages are
    read than ``metadata.yaml`` declares.
    """
    bag = Path(path)
    decoded: dict[str, list[object]] = {}
    with _open_reader(bag) as reader:
        topics = {c.topic: c.msgtype for c in reader.connections}
        declared: dict[str, int] = {}
        for c in reader.connections:
            declared[c.topic] = declared.get(c.topic, 0) + c.msgcount
        for topic in required:
            if not declared.get(topic):
                state = 'has no messages' if topic in topics else 'is missing'
                raise BagError(f'{bag}: required topic {topic} {state}')
        for topic, msg_type in topics.items():
            spec = TOPICS_BY_NAME.get(topic)
            if spec is not None and spec.msg_type != msg_type:
                raise BagError(f'{bag}: topic {topic} has type {msg_type}, expected '
                               f'{spec.msg_type}')
            if topic in _DECODERS:
                decoded[topic] = []
        for message in _messages(reader, bag, decoded.keys()):
            try:
                decoded[message.topic].append(decode(message))
            except WireFormatError as exc:
                raise BagError(f'{bag}: malformed {message.topic} message at '
                               f'{message.t_ns} ns: {exc}') from exc
    for topic, records in decoded.items():
        if len(records) != declared[topic]:
            raise BagError(f'{bag}: {topic} has {len(records)} messages, metadata declares '
                           f'{declared[topic]}')

    joint_samples = decoded.get(JOINT_STATES.name)
    return RecordedTrajectory(
        path=bag,
        topics=topics,
        measurements=cast('Optional[list[Measurement]]', decoded.get(MEASUREMENT.name)),
        features=cast('Optional[list[FeatureSample]]', decoded.get(FEATURES.name)),
        states=cast('Optional[list[PredictorState]]', decoded.get(STATE.name)),
        joint_states=(None if joint_samples is None
                      else _joint_series(bag, cast('list[JointStateSample]', joint_samples))),
        pushes=cast('Optional[list[PushEvent]]', decoded.get(PUSH.name)),
    )
