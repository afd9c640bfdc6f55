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

import heapq
import os
import sys
import warnings
from collections.abc import Callable, Collection, Iterator, Sequence
from contextlib import ExitStack, contextmanager, suppress
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
from fall_predictor.data.topics import (FEATURES, FEATURES_LABEL, JOINT_STATES, MEASUREMENT,
                                        MEASUREMENT_LABEL, PUSH, STATE, STATE_LABEL,
                                        TOPICS_BY_NAME, WORLD_FRAME, QosSpec, WireFormatError)
from fall_predictor.data.wire import (FeatureSample, JointStateSample, PredictorState, PushEvent,
                                      check_layout, pack_features, pack_measurement, pack_state,
                                      push_from_wire, unpack_features, unpack_measurement,
                                      unpack_state)
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
        self._write(topic, msg_type, t_ns, lambda: typestore().serialize_cdr(msg, msg_type))

    def write_raw(self, topic: str, msg_type: str, t_ns: int, data: bytes) -> None:
        """Write the CDR-serialized message ``data`` of ``msg_type`` at log time ``t_ns`` [ns]."""
        self._write(topic, msg_type, t_ns, lambda: data)

    def _write(self, topic: str, msg_type: str, t_ns: int, serialized: Callable[[], bytes]) -> None:
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
            self._writer.write(connection, t_ns, serialized())
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
        """A PredictorState on ``/fall_predictor/state`` (layout v2) at log time ``state.t``."""
        msg = self._float64_array(pack_state(state), STATE_LABEL)
        self.write(STATE.name, STATE.msg_type, time_to_ns(state.t), msg)

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


#: Parts of a recording split by duration (the recorder's ``run_NNN/part_MMM``).
PART_GLOB = 'part_*'


def bag_parts(path: str | os.PathLike[str]) -> list[Path]:
    """The bags that make up the recording at ``path``: ``[path]`` for one bag, else its
    finished parts (``part_*`` directories with a ``metadata.yaml``) in order.

    A part without ``metadata.yaml`` was still being written when its recorder was killed: it is
    left out with a warning (``fall-predictor repair-bag`` recovers what it holds).
    """
    bag = Path(path)
    if (bag / 'metadata.yaml').exists() or not bag.is_dir():
        return [bag]
    parts = sorted(p for p in bag.glob(PART_GLOB) if p.is_dir())
    if not parts:
        return [bag]
    finished = [p for p in parts if (p / 'metadata.yaml').exists()]
    for part in parts:
        if part not in finished:
            warnings.warn(f'{part}: unfinished part (its recorder was stopped while writing it) '
                          'left out; fall-predictor repair-bag recovers its messages')
    if not finished:
        raise BagError(f'{bag}: no finished part (every part lacks metadata.yaml)')
    return finished


def iter_messages(path: str | os.PathLike[str],
                  topics: Optional[Collection[str]] = None) -> Iterator[BagMessage]:
    """Messages of the bag (or split recording, see :func:`bag_parts`) at ``path`` in log time
    order, all topics or only ``topics``."""
    streams = []
    with ExitStack() as stack:
        for bag in bag_parts(path):
            reader = stack.enter_context(_open_reader(bag))
            streams.append(_messages(reader, bag, topics))
        yield from heapq.merge(*streams, key=lambda message: message.t_ns)


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
    check_layout(msg.layout, STATE_LABEL, len(msg.data))
    return unpack_state(msg.data)


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

    ``path`` is one bag or a split recording (:func:`bag_parts`). Raises BagError if the bag is
    missing or damaged, a ``required`` topic is absent or empty,
    a known topic has the wrong type, any decoded message is malformed, or fewer messages are
    read than ``metadata.yaml`` declares.
    """
    bag = Path(path)
    decoded: dict[str, list[object]] = {}
    topics: dict[str, str] = {}
    declared: dict[str, int] = {}
    parts = bag_parts(bag)
    for part in parts:                  # the parts of a split recording follow each other
        with _open_reader(part) as reader:
            for c in reader.connections:
                if topics.setdefault(c.topic, c.msgtype) != c.msgtype:
                    raise BagError(f'{part}: topic {c.topic} has type {c.msgtype}, '
                                   f'{topics[c.topic]} in an earlier part')
                declared[c.topic] = declared.get(c.topic, 0) + c.msgcount
                spec = TOPICS_BY_NAME.get(c.topic)
                if spec is not None and spec.msg_type != c.msgtype:
                    raise BagError(f'{part}: topic {c.topic} has type {c.msgtype}, expected '
                                   f'{spec.msg_type}')
                if c.topic in _DECODERS:
                    decoded.setdefault(c.topic, [])
            for message in _messages(reader, part, decoded.keys()):
                try:
                    decoded[message.topic].append(decode(message))
                except WireFormatError as exc:
                    raise BagError(f'{part}: malformed {message.topic} message at '
                                   f'{message.t_ns} ns: {exc}') from exc
    for topic in required:
        if not declared.get(topic):
            state = 'has no messages' if topic in topics else 'is missing'
            raise BagError(f'{bag}: required topic {topic} {state}')
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
