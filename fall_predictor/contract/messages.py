"""The monitor's records to and from their ROS messages: the package's own typed messages
(``fall_predictor/msg/*``) and the robot's standard sensor messages.

The same functions serve rclpy messages (the nodes) and rosbags messages (bags): both have the
same field names, so reading is duck-typed, and building takes the message classes by ROS type
name (``types['fall_predictor/msg/FallState']``: a dict of rclpy classes, or a rosbags type
store's ``types``), constructed with every field given.

Decoding checks what it reads: finite values where the message promises them and the physical
bounds of :mod:`fall_predictor.monitor.plausibility`; a message that breaks them raises
:class:`~fall_predictor.contract.topics.WireFormatError` naming the field.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, NamedTuple, Optional, Sequence

import numpy as np

from fall_predictor.contract.topics import WireFormatError
from fall_predictor.monitor.fall_monitor import STATUS_NAMES, MonitorState
from fall_predictor.monitor import plausibility, rotations
from fall_predictor.monitor.plausibility import ImplausibleSample, check_feature_bounds
from fall_predictor.monitor.records import N_CONTACT_MODES, N_FEATURES, Measurement
from fall_predictor.monitor.records import N_INPUTS_WITH_ATTITUDE as N_INPUTS
from fall_predictor.monitor.sensor_records import ImuReading, JointStateReading, WrenchReading
from fall_predictor.monitor.timeline import NS_PER_S

#: Message classes by ROS type name ('pkg/msg/Name').
MessageTypes = Mapping[str, Any]
#: ``FallState.contact_mode`` when the mode is unknown.
CONTACT_MODE_UNKNOWN = 255
#: Largest ``builtin_interfaces/Time.sec`` (int32).
MAX_STAMP_SEC = 2 ** 31 - 1


# --------------------------------------------------------------------------------------------
# Stamps and small types
# --------------------------------------------------------------------------------------------

def stamp_ns(msg: Any) -> int:
    """A stamped message's header stamp as integer nanoseconds (ROS time)."""
    stamp = msg.header.stamp
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def time_msg(types: MessageTypes, ns: int) -> Any:
    """``builtin_interfaces/Time`` of integer nanoseconds (WireFormatError outside its range)."""
    sec, nanosec = divmod(int(ns), NS_PER_S)
    if not 0 <= sec <= MAX_STAMP_SEC:
        raise WireFormatError(f'stamp {ns} ns is outside builtin_interfaces/Time')
    return types['builtin_interfaces/msg/Time'](sec=sec, nanosec=nanosec)


def header(types: MessageTypes, ns: int, frame_id: str = '') -> Any:
    return types['std_msgs/msg/Header'](stamp=time_msg(types, ns), frame_id=frame_id)


def _vector3(types: MessageTypes, v: Sequence[float]) -> Any:
    return types['geometry_msgs/msg/Vector3'](x=float(v[0]), y=float(v[1]), z=float(v[2]))


def _point(types: MessageTypes, v: Sequence[float]) -> Any:
    return types['geometry_msgs/msg/Point'](x=float(v[0]), y=float(v[1]), z=float(v[2]))


def _float64s(types: MessageTypes, values: Any) -> Any:
    """A ``float64[]`` field's value in the form the message library wants: ``types['float64[]']``
    converts (rclpy: ``array.array('d')``, what it stores and what its strict field checks
    accept), else a float64 numpy array (rosbags)."""
    convert = types.get('float64[]')
    values = np.asarray(values, dtype=np.float64)
    return values if convert is None else convert(values)


def _xyz(v: Any) -> list[float]:
    return [float(v.x), float(v.y), float(v.z)]


# --------------------------------------------------------------------------------------------
# The robot's sensor messages
# --------------------------------------------------------------------------------------------

def joint_state_reading(msg: Any) -> JointStateReading:
    """``sensor_msgs/JointState`` -> JointStateReading (sizes are checked by the joint table)."""
    return JointStateReading(stamp_ns(msg), tuple(msg.name), np.asarray(msg.position, dtype=float),
                             np.asarray(msg.velocity, dtype=float), np.asarray(msg.effort, dtype=float))


def imu_reading(msg: Any) -> ImuReading:
    """``sensor_msgs/Imu`` -> ImuReading (plausibility is checked by the sensor sync)."""
    o = msg.orientation
    return ImuReading(stamp_ns(msg), msg.header.frame_id,
                      np.array([o.x, o.y, o.z, o.w], dtype=float),
                      np.array(_xyz(msg.angular_velocity)), np.array(_xyz(msg.linear_acceleration)))


def wrench_reading(msg: Any) -> WrenchReading:
    """``geometry_msgs/WrenchStamped`` -> WrenchReading."""
    return WrenchReading(stamp_ns(msg), msg.header.frame_id,
                         np.array(_xyz(msg.wrench.force) + _xyz(msg.wrench.torque)))


def joint_state_msg(types: MessageTypes, reading: JointStateReading, frame_id: str = '') -> Any:
    return types['sensor_msgs/msg/JointState'](
        header=header(types, reading.stamp_ns, frame_id), name=list(reading.names),
        position=_float64s(types, reading.position), velocity=_float64s(types, reading.velocity),
        effort=_float64s(types, reading.effort))


def imu_msg(types: MessageTypes, reading: ImuReading) -> Any:
    q = [float(v) for v in reading.orientation_xyzw]
    unknown = np.zeros(9)               # sensor_msgs/Imu: an all-zero covariance means unknown
    return types['sensor_msgs/msg/Imu'](
        header=header(types, reading.stamp_ns, reading.frame_id),
        orientation=types['geometry_msgs/msg/Quaternion'](x=q[0], y=q[1], z=q[2], w=q[3]),
        orientation_covariance=unknown, angular_velocity=_vector3(types, reading.angular_velocity),
        angular_velocity_covariance=unknown,
        linear_acceleration=_vector3(types, reading.linear_acceleration),
        linear_acceleration_covariance=unknown)


def wrench_msg(types: MessageTypes, reading: WrenchReading) -> Any:
    w = reading.wrench
    return types['geometry_msgs/msg/WrenchStamped'](
        header=header(types, reading.stamp_ns, reading.frame_id),
        wrench=types['geometry_msgs/msg/Wrench'](force=_vector3(types, w[:3]),
                                                 torque=_vector3(types, w[3:])))


# --------------------------------------------------------------------------------------------
# Measurement
# --------------------------------------------------------------------------------------------

class StampedMeasurement(NamedTuple):
    """A decoded ``fall_predictor/msg/Measurement``: ``measurement`` is None when ``fault`` is set
    (its ``t`` is the stamp in seconds; a node replaces it by its run time)."""

    stamp_ns: int
    frame_id: str
    fault: str
    measurement: Optional[Measurement]
    #: Handed over in process only: the producer (applying the time rule) started a new run here.
    new_run: bool = False


def _sole(types: MessageTypes, foot: Sequence[float], contacts: np.ndarray) -> Any:
    point = types['fall_predictor/msg/ContactPoint']
    rows = np.asarray(contacts, dtype=float).reshape(-1, 3)
    return types['fall_predictor/msg/SoleContact'](
        x=float(foot[0]), y=float(foot[1]), yaw=float(foot[2]),
        contacts=[point(x=float(r[0]), y=float(r[1]), normal_force=float(r[2])) for r in rows])


def quaternion_xyzw(rot: Optional[np.ndarray]) -> list[float]:
    """A rotation matrix as a unit quaternion (x, y, z, w), w >= 0; identity for None."""
    if rot is None:
        return [0.0, 0.0, 0.0, 1.0]
    return list(rotations.from_matrix(rot))


def _rotation(q: Any) -> np.ndarray:
    x, y, z, w = float(q.x), float(q.y), float(q.z), float(q.w)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if not (math.isfinite(n) and abs(n - 1.0) <= 1e-3):
        raise WireFormatError(f'measurement.base_orientation is not a unit quaternion (norm {n})')
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def measurement_msg(types: MessageTypes, ns: int, frame_id: str, m: Optional[Measurement],
                    fault: str = '') -> Any:
    """A ``fall_predictor/msg/Measurement``: ``m`` at stamp ``ns``, or (``m`` None) the fault."""
    nan3 = (math.nan, math.nan, math.nan)
    if m is None:
        if not fault:
            raise WireFormatError('a measurement message without a measurement needs a fault')
        empty = np.zeros((0, 3))
        return types['fall_predictor/msg/Measurement'](
            header=header(types, ns, frame_id), fault=fault, com=_point(types, nan3),
            linear_momentum=_vector3(types, nan3), angular_momentum=_vector3(types, nan3),
            heading=math.nan, base_orientation=types['geometry_msgs/msg/Quaternion'](
                x=0.0, y=0.0, z=0.0, w=1.0),
            cop=_point(types, nan3), left_sole=_sole(types, nan3, empty),
            right_sole=_sole(types, nan3, empty), non_foot_contact=False,
            push_force=_vector3(types, (0.0, 0.0, 0.0)))
    q = quaternion_xyzw(m.torso_rotation)
    return types['fall_predictor/msg/Measurement'](
        header=header(types, ns, frame_id), fault=fault, com=_point(types, m.com),
        linear_momentum=_vector3(types, m.lin_mom), angular_momentum=_vector3(types, m.ang_mom),
        heading=float(m.heading),
        base_orientation=types['geometry_msgs/msg/Quaternion'](x=q[0], y=q[1], z=q[2], w=q[3]),
        cop=_point(types, m.cop), left_sole=_sole(types, m.left_foot, m.left_contacts),
        right_sole=_sole(types, m.right_foot, m.right_contacts),
        non_foot_contact=bool(m.non_foot_contact), push_force=_vector3(types, m.push_force))


def _contacts(sole: Any) -> np.ndarray:
    rows = [(float(c.x), float(c.y), float(c.normal_force)) for c in sole.contacts]
    return np.array(rows, dtype=float).reshape(-1, 3)


def check_measurement(m: Measurement) -> None:
    """The checks every measurement a node takes passes, decoded from a message or handed over
    in process (WireFormatError): :func:`fall_predictor.monitor.plausibility.check_measurement`."""
    try:
        plausibility.check_measurement(m)
    except ImplausibleSample as error:
        text = str(error)
        raise WireFormatError(text if text.startswith('measurement') else f'measurement: {text}'
                              ) from None


def measurement_from_msg(msg: Any) -> StampedMeasurement:
    """``fall_predictor/msg/Measurement`` -> StampedMeasurement, checked (WireFormatError;
    :func:`check_measurement`)."""
    ns = stamp_ns(msg)
    fault = plausibility.bound_text(str(msg.fault))         # wire text: bounded
    frame_id = plausibility.bound_text(str(msg.header.frame_id), plausibility.MAX_NAME_CHARS)
    if fault:
        return StampedMeasurement(ns, frame_id, fault, None)
    m = Measurement(t=ns / NS_PER_S, com=np.array(_xyz(msg.com)),
                    lin_mom=np.array(_xyz(msg.linear_momentum)),
                    ang_mom=np.array(_xyz(msg.angular_momentum)), heading=float(msg.heading),
                    cop=np.array(_xyz(msg.cop)), left_contacts=_contacts(msg.left_sole),
                    right_contacts=_contacts(msg.right_sole),
                    left_foot=np.array([float(msg.left_sole.x), float(msg.left_sole.y),
                                        float(msg.left_sole.yaw)]),
                    right_foot=np.array([float(msg.right_sole.x), float(msg.right_sole.y),
                                         float(msg.right_sole.yaw)]),
                    non_foot_contact=bool(msg.non_foot_contact),
                    push_force=np.array(_xyz(msg.push_force)), torso_rotation=None)
    check_measurement(m)
    m.torso_rotation = _rotation(msg.base_orientation)
    return StampedMeasurement(ns, frame_id, '', m)


# --------------------------------------------------------------------------------------------
# Features
# --------------------------------------------------------------------------------------------

class StampedFeatures(NamedTuple):
    """A decoded ``fall_predictor/msg/Features``; ``x`` is None when ``fault`` is set, else the
    15 features, or the 15 features and the base's attitude (19 values, the attitude maybe NaN;
    decoded from a message, always 19)."""

    stamp_ns: int
    fault: str
    x: Optional[np.ndarray]
    mode: Optional[int]
    base_tilt_rad: float
    #: Handed over in process only: the producer (applying the time rule) started a new run here.
    new_run: bool = False


def features_msg(types: MessageTypes, ns: int, x: Optional[Sequence[float]], mode: Optional[int],
                 base_tilt_rad: float = 0.0, fault: str = '') -> Any:
    """A ``fall_predictor/msg/Features`` at stamp ``ns``; ``x`` None with a ``fault``, else the 15
    features, or 19 values with the base's attitude (else the attitude is NaN)."""
    if x is None and not fault:
        raise WireFormatError('a features message without features needs a fault')
    values = np.full(N_INPUTS, np.nan)
    if x is not None:
        given = np.asarray(x, dtype=float)
        if given.shape not in ((N_FEATURES,), (N_INPUTS,)):
            raise WireFormatError(f'features must have shape ({N_FEATURES},) or ({N_INPUTS},) with '
                                  f'the attitude, got {given.shape}')
        values[:len(given)] = given
    return types['fall_predictor/msg/Features'](
        header=header(types, ns), fault=fault, features=values[:N_FEATURES],
        contact_mode=CONTACT_MODE_UNKNOWN if mode is None else int(mode),
        base_tilt=float(base_tilt_rad), base_attitude=values[N_FEATURES:])


def check_features(f: StampedFeatures) -> None:
    """The checks every features sample a node takes passes, decoded from a message or handed
    over in process (WireFormatError): none with a fault; else finite features of the model's
    length, a known contact mode, a base tilt in [0, pi] and the bounds of
    :mod:`~fall_predictor.monitor.plausibility`."""
    if f.fault:
        return
    x = f.x
    if x is None or x.shape not in ((N_FEATURES,), (N_INPUTS,)) or not np.isfinite(x[:N_FEATURES]).all():
        raise WireFormatError(f'features must be {N_FEATURES} finite values (and no fault)')
    roll_pitch, rates = x[N_FEATURES:N_FEATURES + 2], x[N_FEATURES + 2:]
    if (np.abs(roll_pitch) > math.pi / 2).any() or np.isinf(rates).any():
        raise WireFormatError(f'features.base_attitude: fused roll and pitch must lie in [-pi/2, '
                              f'pi/2] rad and the angular velocities be finite (or NaN), got '
                              f'{x[N_FEATURES:].tolist()}')
    if f.mode is None or not 0 <= f.mode < N_CONTACT_MODES:
        raise WireFormatError(f'features.contact_mode must be < {N_CONTACT_MODES}, got {f.mode}')
    if not 0.0 <= f.base_tilt_rad <= math.pi:
        raise WireFormatError(f'features.base_tilt must lie in [0, pi] rad, got {f.base_tilt_rad!r}')
    try:
        check_feature_bounds(None, x.tolist())
    except ImplausibleSample as error:
        raise WireFormatError(f'features: {error}') from None


_NO_ATTITUDE = (math.nan,) * (N_INPUTS - N_FEATURES)


def features_from_msg(msg: Any) -> StampedFeatures:
    """``fall_predictor/msg/Features`` -> StampedFeatures, checked (WireFormatError;
    :func:`check_features`)."""
    ns = stamp_ns(msg)
    fault = plausibility.bound_text(str(msg.fault))         # wire text: bounded
    if fault:
        return StampedFeatures(ns, fault, None, None, math.nan)
    # A bag recorded before Features carried the attitude decodes without the field (bagio
    # decodes with each bag's own definition): its samples lack the attitude, as NaN.
    attitude = getattr(msg, 'base_attitude', _NO_ATTITUDE)
    x = np.concatenate([np.asarray(msg.features, dtype=float), np.asarray(attitude, dtype=float)])
    decoded = StampedFeatures(ns, '', x, int(msg.contact_mode), float(msg.base_tilt))
    check_features(decoded)
    return decoded


# --------------------------------------------------------------------------------------------
# FallState and FallEvent
# --------------------------------------------------------------------------------------------

def fall_state_msg(types: MessageTypes, ns: int, frame_id: str, state: MonitorState) -> Any:
    """A ``fall_predictor/msg/FallState`` of ``state`` at the input sample's stamp ``ns``."""
    dx, dy = state.fall_direction
    return types['fall_predictor/msg/FallState'](
        header=header(types, ns, frame_id), status=state.status, reason=state.reason,
        falling=bool(state.falling), latched=bool(state.latched), atomic=bool(state.atomic),
        guard=bool(state.guard),
        contact_mode=CONTACT_MODE_UNKNOWN if state.contact_mode is None else state.contact_mode,
        time_to_fall=float(state.time_to_fall_s),
        fall_direction=_vector3(types, (dx, dy, 0.0 if math.isfinite(dx) else math.nan)),
        tau_his=float(state.tau_his_s))


def fall_state_from_msg(msg: Any) -> tuple[int, MonitorState]:
    """``fall_predictor/msg/FallState`` -> (stamp [ns], MonitorState), checked."""
    status = int(msg.status)
    if not 0 <= status < len(STATUS_NAMES):
        raise WireFormatError(f'state.status {status} is not one of the STATUS_* constants')
    mode = int(msg.contact_mode)
    if mode != CONTACT_MODE_UNKNOWN and not 0 <= mode < N_CONTACT_MODES:
        raise WireFormatError(f'state.contact_mode {mode} is not a contact mode')
    d = msg.fall_direction
    direction = (float(d.x), float(d.y))
    if not (all(math.isnan(v) for v in direction)
            or abs(math.hypot(*direction) - 1.0) <= 1e-6):
        raise WireFormatError(f'state.fall_direction must be a unit vector or NaN, got {direction}')
    ttf = float(msg.time_to_fall)
    if not (math.isnan(ttf) or 0.0 <= ttf <= 1e3):
        raise WireFormatError(f'state.time_to_fall must be NaN or in [0, 1000] s, got {ttf!r}')
    return stamp_ns(msg), MonitorState(
        status, str(msg.reason), bool(msg.falling), bool(msg.latched), bool(msg.atomic),
        bool(msg.guard), None if mode == CONTACT_MODE_UNKNOWN else mode, ttf, direction,
        float(msg.tau_his))


def fall_event_msg(types: MessageTypes, ns: int, frame_id: str, kind: int,
                   direction: tuple[float, float] = (math.nan, math.nan),
                   time_to_fall_s: float = math.nan, contact_mode: Optional[int] = None) -> Any:
    dx, dy = direction
    return types['fall_predictor/msg/FallEvent'](
        header=header(types, ns, frame_id), event=int(kind),
        direction=_vector3(types, (dx, dy, 0.0 if math.isfinite(dx) else math.nan)),
        time_to_fall=float(time_to_fall_s),
        contact_mode=CONTACT_MODE_UNKNOWN if contact_mode is None else int(contact_mode))
