"""Reading rosbag2 bags (MCAP storage) in the message contract of :mod:`fall_predictor.contract`.

Uses the pure-Python ``rosbags`` library (no rclpy), with the ROS 2 Jazzy type store and this
package's own messages (:func:`typestore`); writing is :mod:`fall_predictor.data.bag_writer`. The
per-sample topics are read in both forms: the typed messages, and the ``Float64MultiArray``
layouts of bags recorded before them (:mod:`fall_predictor.contract.wire`).

Log time of every message = its stamp [ns]. Any failure to read (missing, truncated or corrupt
bag, malformed message, missing required topic) raises :class:`BagError` naming the bag; library
exceptions never escape.
"""
from __future__ import annotations

import dataclasses
import heapq
import os
import struct
import warnings
from collections.abc import Collection, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any, Literal, NamedTuple, Optional, cast

import numpy as np
from rosbags.interfaces import MessageDefinitionFormat
from rosbags.rosbag2 import Reader
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from fall_predictor.contract import messages
from fall_predictor.contract.definitions import message_definitions
from fall_predictor.contract.unitree_hg import unitree_hg_definitions
from fall_predictor.contract.topics import (FEATURES, FEATURES_LABEL, JOINT_STATES, MEASUREMENT,
                                            MEASUREMENT_LABEL, PUSH, STATE, STATE_LABEL,
                                            TOPICS_BY_NAME, WireFormatError, ns_to_time,
                                            stamp_to_ns)
from fall_predictor.contract.wire import (FeatureSample, JointStateSample, PushEvent, check_layout,
                                          push_from_wire, unpack_features, unpack_measurement,
                                          unpack_state)
from fall_predictor.monitor.fall_monitor import MonitorState
from fall_predictor.monitor.records import Measurement

#: rosbag2 metadata version written by ROS 2 Jazzy (rosbag2 0.26).
ROSBAG2_VERSION: Literal[9] = 9

#: A rosbags type store message object (a dataclass generated at run time).
RosbagsMsg = Any


class BagError(Exception):
    """A bag cannot be written or read. The message names the bag and the problem."""


@lru_cache(maxsize=1)
def typestore() -> Typestore:
    """The ROS 2 Jazzy message type store with this package's own messages and Unitree's
    low-level state (``vendor/unitree_hg``: a G1's ``lowstate`` recordings), built once."""
    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for name, text in {**message_definitions(), **unitree_hg_definitions()}.items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return store


#: Bytes a message may carry after its last member. rmw_fastrtps sends a message in a buffer it
#: sized beforehand, counting the alignment of an 8-byte array's elements even where the array is
#: empty: a ``sensor_msgs/msg/JointState`` without efforts (a robot that measures none) arrives
#: with 4 unwritten bytes after its last member, one without velocities and efforts with 8.
#: rosbags' ``Typestore.deserialize_cdr`` refuses more than 3. A message that does not decode
#: whole is refused whatever follows it.
MAX_TRAILING_BYTES = 16


def deserialize_cdr(raw: bytes | memoryview, msg_type: str,
                    store: Optional[Typestore] = None) -> RosbagsMsg:
    """A message in CDR, as a publisher sent it, as a rosbags message object of ``msg_type``.

    rosbags' own decoding (``Typestore.deserialize_cdr``), except that up to
    :data:`MAX_TRAILING_BYTES` after the last member are accepted, so that what Fast DDS sends is
    read. ``store`` defaults to the package's :func:`typestore`. Raises rosbags' ``SerdeError``
    for anything else that does not decode as ``msg_type``, and rosbags' ``TypesysError`` for a
    type the store lacks.
    """
    store = typestore() if store is None else store
    if len(raw) < 4 or bytes(raw[:2]) not in (b'\x00\x00', b'\x00\x01'):
        raise SerdeError('Invalid or unsupported CDR encapsulation.')
    msgdef = store.get_msgdef(msg_type)
    decode = msgdef.deserialize_cdr_le if raw[1] else msgdef.deserialize_cdr_be
    try:
        message, end = decode(raw[4:], 0, msgdef.cls, store)
    except (struct.error, UnicodeDecodeError, ValueError) as exc:
        raise SerdeError(f'Could not deserialize {msg_type!r}: {exc}') from exc
    trailing = len(raw) - 4 - end
    if trailing > MAX_TRAILING_BYTES:
        raise SerdeError(f'{msg_type}: {trailing} bytes after its last member (at most '
                         f'{MAX_TRAILING_BYTES})')
    return message


@lru_cache(maxsize=64)
def recorded_typestore(msg_type: str, definition: str) -> Typestore:
    """The type store that decodes messages of ``msg_type`` recorded with ``definition``, the
    message definition a bag stores with each topic (ros2msg text with its dependencies).

    The package's own :func:`typestore` when the bag's definition declares the same fields for
    every type it names; else a store built from the bag's definition alone, so that a bag recorded
    with an earlier version of a message (``Features`` before ``base_attitude``) decodes as it was
    written. An empty definition (a bag that stores none) gives the package's store. Raises
    :class:`BagError` for a definition rosbags cannot parse.
    """
    own = typestore()
    if not definition.strip():
        return own
    try:
        recorded = get_types_from_msg(definition, msg_type)
    except Exception as exc:
        raise BagError(f'the recorded definition of {msg_type} does not parse: '
                       f'{describe(exc)}') from exc
    if all(own.fielddefs.get(name) == fields for name, fields in recorded.items()):
        return own
    store = get_typestore(Stores.EMPTY)
    store.register(recorded)
    return store


def describe(exc: BaseException) -> str:
    return f'{type(exc).__name__}: {exc}'


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
                       f'{describe(exc)}') from exc
    try:
        yield reader
    finally:
        reader.close()


def _messages(reader: Reader, path: Path,
              topics: Optional[Collection[str]]) -> Iterator[BagMessage]:
    connections = [c for c in reader.connections if topics is None or c.topic in topics]
    if not connections:
        return
    try:
        stores = {c.id: recorded_typestore(
            c.msgtype, c.msgdef.data if c.msgdef.format == MessageDefinitionFormat.MSG else '')
            for c in connections}
    except BagError as exc:
        raise BagError(f'{path}: {exc}') from exc
    raw_messages = reader.messages(connections=connections)
    while True:
        try:
            connection, t_ns, raw = next(raw_messages)
        except StopIteration:
            return
        except Exception as exc:
            raise BagError(f'{path}: damaged bag: {describe(exc)}') from exc
        try:
            msg = deserialize_cdr(raw, connection.msgtype, stores[connection.id])
        except Exception as exc:
            raise BagError(f'{path}: {connection.topic} message at {t_ns} ns does not decode '
                           f'as {connection.msgtype}: {describe(exc)}') from exc
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


#: The type of the per-sample topics in bags recorded before the typed messages.
LEGACY_ARRAY_TYPE = 'std_msgs/msg/Float64MultiArray'


class BagState(NamedTuple):
    """A ``/fall_predictor/state`` message of a bag: sample time [s] and the monitor's state."""

    t: float
    state: MonitorState


class Fault(NamedTuple):
    """A per-sample message that carries a fault instead of values (a recorded live run whose
    estimator had no estimate for that sample): kept out of the records, counted."""

    t: float
    fault: str


def _decode_measurement(msg: RosbagsMsg) -> Measurement | Fault:
    if hasattr(msg, 'layout'):              # a bag recorded before the typed messages
        check_layout(msg.layout, MEASUREMENT_LABEL, len(msg.data))
        return unpack_measurement(msg.data)
    decoded = messages.measurement_from_msg(msg)
    if decoded.measurement is None:
        return Fault(decoded.stamp_ns / 1e9, decoded.fault)
    return decoded.measurement


def _decode_features(msg: RosbagsMsg) -> FeatureSample | Fault:
    if hasattr(msg, 'layout'):
        check_layout(msg.layout, FEATURES_LABEL, len(msg.data))
        return unpack_features(msg.data)
    decoded = messages.features_from_msg(msg)
    if decoded.x is None:
        return Fault(decoded.stamp_ns / 1e9, decoded.fault)
    return FeatureSample(decoded.stamp_ns / 1e9, decoded.x, decoded.mode)


def _decode_joint_state(msg: RosbagsMsg) -> JointStateSample:
    return JointStateSample(ns_to_time(_header_ns(msg)), tuple(msg.name), msg.position,
                            msg.velocity, msg.effort)


def _decode_push(msg: RosbagsMsg) -> PushEvent:
    force = msg.wrench.force
    return push_from_wire(_header_ns(msg), msg.header.frame_id, (force.x, force.y, force.z))


def _decode_state(msg: RosbagsMsg) -> object:
    if hasattr(msg, 'layout'):              # v2 array: the legacy PredictorState record
        check_layout(msg.layout, STATE_LABEL, len(msg.data))
        return unpack_state(msg.data)
    stamp_ns, state = messages.fall_state_from_msg(msg)
    return BagState(stamp_ns / 1e9, state)


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
    """All ``/joint_states`` messages of a bag as arrays (N rows, J joints).

    One row per message when every message names the same joints. A robot whose drivers publish
    its joints in groups (split joint states: the legs in one message, the upper body in another,
    maybe at other rates) gives one row per stamp, each group's values in its own columns and NaN
    where that group sent nothing at that stamp (also for the velocities or efforts of a group
    that sends none while another does).
    """

    names: tuple[str, ...]
    t: np.ndarray                   #: (N,) header stamps [s]
    position: np.ndarray            #: (N, J) [rad]
    velocity: np.ndarray            #: (N, J) [rad/s], or (N, 0) if no message has any
    effort: np.ndarray              #: (N, J) [N m], or (N, 0) if no message has any


@dataclass(slots=True)
class RecordedTrajectory:
    """The decoded content of one bag. A topic absent from the bag gives None (never an
    empty or zero-filled stand-in); ``topics`` lists every topic found with its type."""

    path: Path
    topics: dict[str, str]
    measurements: Optional[list[Measurement]]
    features: Optional[list[FeatureSample]]
    states: Optional[list[object]]         #: BagState (legacy bags: PredictorState)
    joint_states: Optional[JointStateSeries]
    pushes: Optional[list[PushEvent]]
    #: Per topic: the samples that carried a fault instead of values (left out above).
    faults: dict[str, list[Fault]] = dataclasses.field(default_factory=dict)


def _joint_groups(path: Path, samples: list[JointStateSample]) -> list[tuple[str, ...]]:
    """The distinct joint name lists of the messages, in order of appearance: one, or the
    disjoint groups of split joint states (BagError where a list overlaps an earlier one: a
    joint renamed, added or reordered during the recording)."""
    groups: dict[tuple[str, ...], None] = {}
    seen: set[str] = set()
    for sample in samples:
        if sample.names in groups:
            continue
        if seen.intersection(sample.names):     # (a message naming a joint twice is malformed)
            raise BagError(f'{path}: {JOINT_STATES.name} joint names change at t={sample.t} s')
        groups[sample.names] = None
        seen.update(sample.names)
    return list(groups)


def _joint_series(path: Path, samples: list[JointStateSample]) -> JointStateSeries:
    if not samples:
        empty = np.zeros((0, 0))
        return JointStateSeries((), np.zeros(0), empty, empty, empty)
    groups = _joint_groups(path, samples)
    for group in groups:
        of_group = [s for s in samples if s.names == group]
        for what in ('velocity', 'effort'):
            sizes = {getattr(s, what).size for s in of_group}
            if len(sizes) > 1:
                raise BagError(f'{path}: {JOINT_STATES.name} {what} sizes vary: {sorted(sizes)}')
    if len(groups) == 1:
        return JointStateSeries(
            names=groups[0],
            t=np.array([s.t for s in samples]),
            position=np.stack([s.position for s in samples]),
            velocity=np.stack([s.velocity for s in samples]),
            effort=np.stack([s.effort for s in samples]))
    return _merged_groups(path, groups, samples)


def _merged_groups(path: Path, groups: list[tuple[str, ...]],
                   samples: list[JointStateSample]) -> JointStateSeries:
    """Split joint states as one row per stamp, in stamp order (see :class:`JointStateSeries`)."""
    names = tuple(name for group in groups for name in group)
    column = {group: slice(start, start + len(group)) for group, start in zip(
        groups, np.cumsum([0, *map(len, groups[:-1])]).tolist())}
    row = {t: k for k, t in enumerate(sorted({sample.t for sample in samples}))}
    shape = (len(row), len(names))
    position = np.full(shape, np.nan)
    arrays = {'velocity': np.full(shape, np.nan), 'effort': np.full(shape, np.nan)}
    filled = np.zeros(shape, dtype=bool)
    for sample in samples:
        k, columns = row[sample.t], column[sample.names]
        if filled[k, columns].any():
            raise BagError(f'{path}: {JOINT_STATES.name} has two messages of the same joints '
                           f'at t={sample.t} s')
        filled[k, columns] = True
        position[k, columns] = sample.position
        for what, values in arrays.items():
            given = getattr(sample, what)
            if given.size:
                values[k, columns] = given
    recorded = {what: any(getattr(s, what).size for s in samples) for what in arrays}
    return JointStateSeries(
        names=names, t=np.array(list(row)), position=position,
        **{what: values if recorded[what] else np.zeros((shape[0], 0))
           for what, values in arrays.items()})


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
                if spec is not None and spec.msg_type != c.msgtype and not (
                        spec.layout is None and c.msgtype == LEGACY_ARRAY_TYPE
                        and c.topic in (MEASUREMENT.name, FEATURES.name, STATE.name)):
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

    faults = {topic: [r for r in records if isinstance(r, Fault)] for topic, records in decoded.items()}
    faults = {topic: found for topic, found in faults.items() if found}
    for topic in faults:
        decoded[topic] = [r for r in decoded[topic] if not isinstance(r, Fault)]
    joint_samples = decoded.get(JOINT_STATES.name)
    return RecordedTrajectory(
        path=bag,
        topics=topics,
        measurements=cast('Optional[list[Measurement]]', decoded.get(MEASUREMENT.name)),
        features=cast('Optional[list[FeatureSample]]', decoded.get(FEATURES.name)),
        states=decoded.get(STATE.name),
        joint_states=(None if joint_samples is None
                      else _joint_series(bag, cast('list[JointStateSample]', joint_samples))),
        pushes=cast('Optional[list[PushEvent]]', decoded.get(PUSH.name)),
        faults=faults,
    )
