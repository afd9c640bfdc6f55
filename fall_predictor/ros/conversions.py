"""The rclpy side of :mod:`fall_predictor.contract`: QoS profiles, the message classes, and the
conversions of the topics that carry no monitor record (trigger, direction, pushes, modes).

The monitor's records go to and from their messages through :mod:`fall_predictor.contract.messages`
with :data:`TYPES`, the rclpy message classes by ROS type name; this module only adds what is
specific to rclpy.
"""
from __future__ import annotations

import array
import math
from collections.abc import Sequence

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, Quaternion, Vector3, Vector3Stamped, Wrench, WrenchStamped
from numpy.typing import ArrayLike
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Bool, Header, String

from fall_predictor.contract import messages
from fall_predictor.contract.topics import (HEADING_FRAME, PUSH_REQUEST_FRAME, WORLD_FRAME, QosSpec,
                                            check_controller_mode)
from fall_predictor.contract.wire import PushEvent, push_from_wire
from fall_predictor.monitor.plausibility import MAX_PUSH_FORCE_N
from fall_predictor.monitor.records import PUSH_DURATION_S, PushSpec
from fall_predictor.monitor.sensor_records import JointStateReading
from fall_predictor.msg import (ContactPoint, FallEvent, FallState, Features, Measurement,
                                SoleContact)

_RELIABILITY = {'reliable': ReliabilityPolicy.RELIABLE,
                'best_effort': ReliabilityPolicy.BEST_EFFORT}
_DURABILITY = {'volatile': DurabilityPolicy.VOLATILE,
               'transient_local': DurabilityPolicy.TRANSIENT_LOCAL}

#: rclpy message classes by ROS type name, for :mod:`fall_predictor.contract.messages`.
TYPES = {
    'builtin_interfaces/msg/Time': Time, 'std_msgs/msg/Header': Header,
    'geometry_msgs/msg/Point': Point, 'geometry_msgs/msg/Vector3': Vector3,
    'geometry_msgs/msg/Quaternion': Quaternion, 'geometry_msgs/msg/Wrench': Wrench,
    'geometry_msgs/msg/WrenchStamped': WrenchStamped, 'sensor_msgs/msg/Imu': Imu,
    'sensor_msgs/msg/JointState': JointState,
    'fall_predictor/msg/ContactPoint': ContactPoint, 'fall_predictor/msg/SoleContact': SoleContact,
    'fall_predictor/msg/Measurement': Measurement, 'fall_predictor/msg/Features': Features,
    'fall_predictor/msg/FallState': FallState, 'fall_predictor/msg/FallEvent': FallEvent,
    # float64[] fields as rclpy stores them (its strict field checks refuse numpy arrays).
    'float64[]': lambda values: array.array('d', np.ascontiguousarray(values).tobytes()),
}


def qos_profile(spec: QosSpec) -> QoSProfile:
    """QosSpec -> rclpy QoSProfile (KEEP_LAST history with the spec's depth)."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=spec.depth,
                      reliability=_RELIABILITY[spec.reliability],
                      durability=_DURABILITY[spec.durability])


#: The largest stamp a builtin_interfaces/Time holds [ns].
MAX_STAMP_NS = (messages.MAX_STAMP_SEC + 1) * 1_000_000_000 - 1


def stamp(ns: int) -> Time:
    """Integer nanoseconds (ROS time) -> builtin_interfaces/Time."""
    return messages.time_msg(TYPES, ns)


def sim_ns(t: float) -> int:
    """Simulation time [s] -> integer nanoseconds (the simulator's stamps)."""
    return round(t * 1e9)


def falling_msg(falling: bool) -> Bool:
    """The trigger on ``/fall_predictor/falling``."""
    return Bool(data=bool(falling))


def fall_direction_msg(ns: int, direction_xy: Sequence[float]) -> Vector3Stamped:
    """A unit heading-frame direction (x, y) of the sample stamped ``ns`` -> Vector3Stamped."""
    msg = Vector3Stamped()
    msg.header.stamp = stamp(ns)
    msg.header.frame_id = HEADING_FRAME
    msg.vector.x, msg.vector.y, msg.vector.z = float(direction_xy[0]), float(direction_xy[1]), 0.0
    return msg


def joint_state_to_msg(ns: int, names: Sequence[str], positions: ArrayLike,
                       velocities: ArrayLike = (), efforts: ArrayLike = ()) -> JointState:
    """Joint values stamped ``ns`` -> JointState ([rad], [rad/s], [N m])."""
    return messages.joint_state_msg(TYPES, JointStateReading(
        ns, tuple(names), np.asarray(positions, dtype=np.float64),
        np.asarray(velocities, dtype=np.float64), np.asarray(efforts, dtype=np.float64)))


def push_to_msg(t: float, force_xyz: ArrayLike) -> WrenchStamped:
    """Push onset ``t`` [s] and world force [N] -> ``/fall_predictor/push`` WrenchStamped."""
    push = PushEvent(t, np.asarray(force_xyz, dtype=np.float64))
    msg = WrenchStamped()
    msg.header.stamp = stamp(sim_ns(push.t))
    msg.header.frame_id = WORLD_FRAME
    msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z = (float(v) for v in push.force)
    return msg


def push_from_msg(msg: WrenchStamped) -> PushEvent:
    """``/fall_predictor/push`` WrenchStamped -> PushEvent; raises WireFormatError."""
    force = msg.wrench.force
    return push_from_wire(messages.stamp_ns(msg), msg.header.frame_id,
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
    torque about the CoM, ``(0, 0, h) x F`` [N m] (see ``contract.topics.PUSH_REQUEST``)."""
    angle = math.radians(push.angle_deg)
    fx, fy = push.force_n * math.cos(angle), push.force_n * math.sin(angle)
    msg = WrenchStamped()
    msg.header.stamp = stamp(sim_ns(push.t_push))
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
    requested = messages.stamp_ns(msg) / 1e9
    onset = max(round(round(requested / dt_s) * dt_s, 9), now_s)
    return PushSpec(force_n=math.sqrt(force_sq), angle_deg=math.degrees(math.atan2(f.y, f.x)),
                    height_m=height, t_push=onset, duration_s=PUSH_DURATION_S)
