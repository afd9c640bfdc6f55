"""The rclpy side of :mod:`fall_predictor.data.wire`: QoS profiles and message conversions.

This is the only module of the core package that imports rclpy and message packages. Every
conversion delegates layout and validation to :mod:`fall_predictor.data.wire`; the functions here
only move values between wire records and rclpy message objects.

Float64 arrays go into ``msg.data`` as ``array.array('d')`` built from the numpy buffer: that is
the type rclpy stores internally, so the setter keeps it without a per-element loop, and it is
accepted also when ``ROS_PYTHON_CHECK_FIELDS=1`` (a numpy array is not).
"""
from __future__ import annotations

import array
import math
from collections.abc import Sequence

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Vector3Stamped, WrenchStamped
from numpy.typing import ArrayLike
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64MultiArray, MultiArrayDimension, String

from fall_predictor.data.topics import (FEATURES_LABEL, HEADING_FRAME, MEASUREMENT_LABEL,
                                        PUSH_REQUEST_FRAME, STATE_LABEL, WORLD_FRAME, QosSpec,
                                        check_controller_mode, ns_to_time, stamp_to_ns,
                                        time_to_stamp)
from fall_predictor.data.wire import (FeatureSample, JointStateSample, PredictorState, PushEvent,
                                      check_layout, pack_features, pack_measurement, pack_state,
                                      push_from_wire, unpack_features, unpack_measurement,
                                      unpack_state)
from fall_predictor.monitor.plausibility import MAX_PUSH_FORCE_N
from fall_predictor.monitor.records import PUSH_DURATION_S, Measurement, PushSpec

_RELIABILITY = {'reliable': ReliabilityPolicy.RELIABLE,
                'best_effort': ReliabilityPolicy.BEST_EFFORT}
_DURABILITY = {'volatile': DurabilityPolicy.VOLATILE,
               'transient_local': DurabilityPolicy.TRANSIENT_LOCAL}


def qos_profile(spec: QosSpec) -> QoSProfile:
    """QosSpec -> rclpy QoSProfile (KEEP_LAST history with the spec's depth)."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=spec.depth,
                      reliability=_RELIABILITY[spec.reliability],
                      durability=_DURABILITY[spec.durability])


def stamp(t: float) -> Time:
    """Simulation time [s] -> builtin_interfaces/Time."""
    sec, nanosec = time_to_stamp(t)
    return Time(sec=sec, nanosec=nanosec)


def _stamp_ns(time: Time) -> int:
    return stamp_to_ns(time.sec, time.nanosec)


def _float64_array(values: np.ndarray) -> array.array:
    return array.array('d', np.ascontiguousarray(values, dtype=np.float64).tobytes())


def float64_array_msg(values: np.ndarray, label: str) -> Float64MultiArray:
    """A 1-D float64 array -> Float64MultiArray with one dimension labelled ``label``."""
    n = len(values)
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label=label, size=n, stride=n)]
    msg.data = _float64_array(values)
    return msg


def _checked_data(msg: Float64MultiArray, label: str) -> np.ndarray:
    data = np.frombuffer(msg.data, dtype=np.float64)
    check_layout(msg.layout, label, data.size)
    return data


def measurement_to_msg(m: Measurement) -> Float64MultiArray:
    """Measurement -> ``/fall_predictor/measurement`` message (layout v1)."""
    return float64_array_msg(pack_measurement(m), MEASUREMENT_LABEL)


def measurement_from_msg(msg: Float64MultiArray) -> Measurement:
    """``/fall_predictor/measurement`` message -> Measurement; raises WireFormatError."""
    return unpack_measurement(_checked_data(msg, MEASUREMENT_LABEL))


def features_to_msg(t: float, x: ArrayLike, mode: int) -> Float64MultiArray:
    """(t [s], 15 features, contact mode index) -> ``/fall_predictor/features`` message."""
    return float64_array_msg(pack_features(t, x, mode), FEATURES_LABEL)


def features_from_msg(msg: Float64MultiArray) -> FeatureSample:
    """``/fall_predictor/features`` message -> FeatureSample; raises WireFormatError."""
    return unpack_features(_checked_data(msg, FEATURES_LABEL))


def state_to_msg(state: PredictorState) -> Float64MultiArray:
    """PredictorState -> ``/fall_predictor/state`` message (layout v2)."""
    return float64_array_msg(pack_state(state), STATE_LABEL)


def state_from_msg(msg: Float64MultiArray) -> PredictorState:
    """``/fall_predictor/state`` message -> PredictorState; raises WireFormatError."""
    return unpack_state(_checked_data(msg, STATE_LABEL))


def falling_msg(falling: bool) -> Bool:
    """The trigger on ``/fall_predictor/falling``."""
    return Bool(data=bool(falling))


def fall_direction_msg(t: float, direction_xy: Sequence[float]) -> Vector3Stamped:
    """A unit heading-frame direction (x, y) at sample time ``t`` [s] -> Vector3Stamped."""
    msg = Vector3Stamped()
    msg.header.stamp = stamp(t)
    msg.header.frame_id = HEADING_FRAME
    msg.vector.x, msg.vector.y, msg.vector.z = float(direction_xy[0]), float(direction_xy[1]), 0.0
    return msg


def joint_state_to_msg(t: float, names: Sequence[str], positions: ArrayLike,
                       velocities: ArrayLike = (), efforts: ArrayLike = ()) -> JointState:
    """Joint values at sim time ``t`` [s] -> JointState ([rad], [rad/s], [N m])."""
    sample = JointStateSample(t, tuple(names), np.asarray(positions, dtype=np.float64),
                              np.asarray(velocities, dtype=np.float64),
                              np.asarray(efforts, dtype=np.float64))
    msg = JointState(name=list(sample.names))
    msg.header.stamp = stamp(t)
    msg.position = _float64_array(sample.position)
    msg.velocity = _float64_array(sample.velocity)
    msg.effort = _float64_array(sample.effort)
    return msg


def joint_state_from_msg(msg: JointState) -> JointStateSample:
    """JointState -> JointStateSample (time from the header stamp); raises WireFormatError."""
    return JointStateSample(ns_to_time(_stamp_ns(msg.header.stamp)), tuple(msg.name),
                            np.frombuffer(msg.position, dtype=np.float64),
                            np.frombuffer(msg.velocity, dtype=np.float64),
                            np.frombuffer(msg.effort, dtype=np.float64))


def push_to_msg(t: float, force_xyz: ArrayLike) -> WrenchStamped:
    """Push onset ``t`` [s] and world force [N] -> ``/fall_predictor/push`` WrenchStamped."""
    push = PushEvent(t, np.asarray(force_xyz, dtype=np.float64))
    msg = WrenchStamped()
    msg.header.stamp = stamp(push.t)
    msg.header.frame_id = WORLD_FRAME
    msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z = (float(v) for v in push.force)
    return msg


def push_from_msg(msg: WrenchStamped) -> PushEvent:
    """``/fall_predictor/push`` WrenchStamped -> PushEvent; raises WireFormatError."""
    force = msg.wrench.force
    return push_from_wire(_stamp_ns(msg.header.stamp), msg.header.frame_id,
                          (force.x, force.y, force.z))


def controller_mode_msg(mode: str) -> String:
    """'balance' | 'fall' -> ``/fall_predictor/controller_mode`` String."""
    return String(data=check_controller_mode(mode))


# -- push requests (input of the simulator node) ------------------------------------------------
#: Largest accepted application height of a requested push, above or below the CoM [m].
MAX_PUSH_HEIGHT_M = 1.0
#: Tolerance of the push request checks (force.z = 0, torque = (0, 0, h) x F).
_PUSH_TOLERANCE = 1e-6


def push_request_to_msg(push: PushSpec) -> WrenchStamped:
    """A push request for the simulator node: onset stamp, heading-frame force [N] and its
    torque about the CoM, ``(0, 0, h) x F`` [N m] (see ``data.topics.PUSH_REQUEST``)."""
    angle = math.radians(push.angle_deg)
    fx, fy = push.force_n * math.cos(angle), push.force_n * math.sin(angle)
    msg = WrenchStamped()
    msg.header.stamp = stamp(push.t_push)
    msg.header.frame_id = PUSH_REQUEST_FRAME
    msg.wrench.force.x, msg.wrench.force.y = fx, fy
    msg.wrench.torque.x, msg.wrench.torque.y = -push.height_m * fy, push.height_m * fx
    return msg


def push_request_from_msg(msg: WrenchStamped, now_s: float, dt_s: float) -> PushSpec:
    """A push request message -> the PushSpec to schedule at or after ``now_s`` [s].

    The onset is the header stamp rounded to the ``dt_s`` grid, or ``now_s`` if that is
    earlier. Raises ValueError naming the problem: unknown frame, non-finite or vertical force,
    a torque that is not ``(0, 0, h) x force``, or ``|h|`` above :data:`MAX_PUSH_HEIGHT_M`.
    """
    if msg.header.frame_id not in ('', PUSH_REQUEST_FRAME):
        raise ValueError(f"push request frame_id must be '{PUSH_REQUEST_FRAME}' or empty, "
                         f'got {msg.header.frame_id!r}')
    f, tau = msg.wrench.force, msg.wrench.torque
    values = (f.x, f.y, f.z, tau.x, tau.y, tau.z)
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f'push request force/torque must be finite, got {values}')
    if abs(f.z) > _PUSH_TOLERANCE:
        raise ValueError(f'push force must be horizontal (force.z = 0), got {f.z} N')
    if not math.hypot(f.x, f.y) <= MAX_PUSH_FORCE_N:
        raise ValueError(f'push force {math.hypot(f.x, f.y):.6g} N beyond {MAX_PUSH_FORCE_N:g} N')
    force_sq = f.x * f.x + f.y * f.y
    height = (f.x * tau.y - f.y * tau.x) / force_sq if force_sq > 0.0 else 0.0
    expected = np.array([-height * f.y, height * f.x, 0.0])
    if not np.allclose((tau.x, tau.y, tau.z), expected, rtol=0.0,
                       atol=_PUSH_TOLERANCE * max(1.0, math.sqrt(force_sq))):
        raise ValueError(f'push torque {(tau.x, tau.y, tau.z)} N m is not (0, 0, h) x force')
    if abs(height) > MAX_PUSH_HEIGHT_M:
        raise ValueError(f'push height {height:.3f} m above the CoM exceeds '
                         f'{MAX_PUSH_HEIGHT_M} m')
    requested = stamp_to_ns(msg.header.stamp.sec, msg.header.stamp.nanosec) / 1e9
    onset = max(round(round(requested / dt_s) * dt_s, 9), now_s)
    return PushSpec(force_n=math.sqrt(force_sq), angle_deg=math.degrees(math.atan2(f.y, f.x)),
                    height_m=height, t_push=onset, duration_s=PUSH_DURATION_S)
