"""The topic contract: every topic and service name, message type, QoS, rate and frame id.

The single place where the ROS interface of the package is named. It has no ROS imports: the
rclpy nodes (through :mod:`fall_predictor.ros.conversions`) and the bag tools
(:mod:`fall_predictor.data.bagio`) map these definitions onto their own message objects. The
array layouts carried by some of these topics are in :mod:`fall_predictor.data.wire`.
"""
from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Literal, Optional

from fall_predictor.monitor.records import PUSH_DURATION_S


class WireFormatError(ValueError):
    """A message or array does not follow the wire contract of this module."""


# --------------------------------------------------------------------------------------------
# QoS, rates, frames, topics
# --------------------------------------------------------------------------------------------

Reliability = Literal['reliable', 'best_effort']
Durability = Literal['volatile', 'transient_local']


@dataclass(frozen=True, slots=True)
class QosSpec:
    """A QoS profile without ROS imports. History is always KEEP_LAST with ``depth``."""

    reliability: Reliability
    durability: Durability
    depth: int

    def __post_init__(self) -> None:
        if self.reliability not in ('reliable', 'best_effort'):
            raise ValueError(f'unknown reliability {self.reliability!r}')
        if self.durability not in ('volatile', 'transient_local'):
            raise ValueError(f'unknown durability {self.durability!r}')
        if self.depth < 1:
            raise ValueError(f'QoS depth must be >= 1, got {self.depth}')

    def describe(self) -> str:
        """Short human-readable form, e.g. ``reliable, volatile, keep_last 1000``."""
        return f'{self.reliability}, {self.durability}, keep_last {self.depth}'


#: 1 kHz streams: reliable, volatile, 1 s of samples buffered.
STREAM_QOS = QosSpec('reliable', 'volatile', 1000)
#: Latched state (late joiners get the last value).
LATCHED_QOS = QosSpec('reliable', 'transient_local', 1)
#: Sparse events (pushes, diagnostics).
EVENT_QOS = QosSpec('reliable', 'volatile', 10)

#: Simulation (and measurement, feature, state) rate [Hz]: one sample per 1 ms step.
SIM_RATE_HZ = 1000.0
#: Default rate of ``/joint_states`` [Hz] (a node parameter may change it).
JOINT_STATE_RATE_HZ = 100.0
#: Nominal rate of ``/diagnostics`` [Hz].
DIAGNOSTICS_RATE_HZ = 1.0
#: Frame of world-fixed vectors (pushes).
WORLD_FRAME = 'world'

MEASUREMENT_LABEL = 'fall_predictor/measurement/v1'
FEATURES_LABEL = 'fall_predictor/features/v1'


@dataclass(frozen=True, slots=True)
class TopicSpec:
    """One row of the interface table."""

    name: str                       #: topic name
    msg_type: str                   #: ROS 2 type name, e.g. 'std_msgs/msg/Float64MultiArray'
    qos: QosSpec
    rate_hz: Optional[float]        #: nominal rate [Hz]; None for event-driven topics
    frame_id: Optional[str]         #: header.frame_id; None when the type has no header
    layout: Optional[str]           #: Float64MultiArray layout label; None for other types
    content: str                    #: one-line description for the README


MEASUREMENT = TopicSpec(
    '/fall_predictor/measurement', 'std_msgs/msg/Float64MultiArray', STREAM_QOS, SIM_RATE_HZ,
    None, MEASUREMENT_LABEL, 'one simulation sample (Measurement), layout v1')
FEATURES = TopicSpec(
    '/fall_predictor/features', 'std_msgs/msg/Float64MultiArray', STREAM_QOS, SIM_RATE_HZ,
    None, FEATURES_LABEL, 't, the 15 features, contact mode index')
STATE = TopicSpec(
    '/fall_predictor/state', 'diagnostic_msgs/msg/DiagnosticArray', STREAM_QOS, SIM_RATE_HZ,
    '', None, 'predictor output: OK balanced, WARN falling, STALE degraded')
JOINT_STATES = TopicSpec(
    '/joint_states', 'sensor_msgs/msg/JointState', STREAM_QOS, JOINT_STATE_RATE_HZ,
    '', None, 'robot joint positions, velocities, efforts (visualisation, bags)')
PUSH = TopicSpec(
    '/fall_predictor/push', 'geometry_msgs/msg/WrenchStamped', EVENT_QOS, None,
    WORLD_FRAME, None, f'push onset (stamp) and world force [N], lasting {PUSH_DURATION_S} s')
#: Frame of a push request's force: the robot's heading frame (x forward, y left, z up).
PUSH_REQUEST_FRAME = 'heading'
#: Input of the simulator node: a push to apply. ``header.stamp`` = requested onset in
#: simulation time (a time already past means "at the next step"); ``wrench.force`` = the
#: horizontal force [N] in :data:`PUSH_REQUEST_FRAME`; ``wrench.torque`` = its moment about
#: the CoM [N m], ``(0, 0, h) x force`` for an application point ``h`` metres above the CoM.
#: The force lasts ``PUSH_DURATION_S`` (0.1 s, SPEC §3).
PUSH_REQUEST = TopicSpec(
    '/fall_predictor/push_request', 'geometry_msgs/msg/WrenchStamped', EVENT_QOS, None,
    PUSH_REQUEST_FRAME, None,
    'push to apply: onset (stamp), heading-frame force [N], torque about the CoM [N m]')
CONTROLLER_MODE = TopicSpec(
    '/fall_predictor/controller_mode', 'std_msgs/msg/String', LATCHED_QOS, None,
    None, None, "active controller: 'balance' or 'fall'")
JOINT_COMMANDS = TopicSpec(
    '/fall_predictor/joint_commands', 'sensor_msgs/msg/JointState', STREAM_QOS, SIM_RATE_HZ,
    '', None, 'target joint angles (position field) of the active controller')
CLOCK = TopicSpec(
    '/clock', 'rosgraph_msgs/msg/Clock', STREAM_QOS, SIM_RATE_HZ,
    None, None, 'simulation time')
DIAGNOSTICS = TopicSpec(
    '/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray', EVENT_QOS, DIAGNOSTICS_RATE_HZ,
    '', None, 'node health')

#: The interface table, in README order.
TOPICS: tuple[TopicSpec, ...] = (
    MEASUREMENT, FEATURES, STATE, JOINT_STATES, PUSH, PUSH_REQUEST, CONTROLLER_MODE,
    JOINT_COMMANDS, CLOCK, DIAGNOSTICS,
)
TOPICS_BY_NAME: dict[str, TopicSpec] = {spec.name: spec for spec in TOPICS}

CONTROLLER_MODES: tuple[str, ...] = ('balance', 'fall')


def topics_markdown_table(topics: Iterable[TopicSpec] = TOPICS) -> str:
    """The interface table in Markdown (for the README)."""
    lines = ['| topic | type | QoS | rate | frame | content |', '|---|---|---|---|---|---|']
    for spec in topics:
        rate = 'on event' if spec.rate_hz is None else f'{spec.rate_hz:g} Hz'
        frame = '-' if not spec.frame_id else f'`{spec.frame_id}`'
        content = spec.content if spec.layout is None else f'{spec.content} (`{spec.layout}`)'
        lines.append(f'| `{spec.name}` | `{spec.msg_type}` | {spec.qos.describe()} | {rate} '
                     f'| {frame} | {content} |')
    return '\n'.join(lines) + '\n'


# --------------------------------------------------------------------------------------------
# Time
# --------------------------------------------------------------------------------------------

def time_to_ns(t: float) -> int:
    """Simulation time [s] to integer nanoseconds (bag log time, header stamps)."""
    if not math.isfinite(t) or t < 0.0:
        raise WireFormatError(f'time must be finite and >= 0 s, got {t!r}')
    return round(t * 1e9)


def time_to_stamp(t: float) -> tuple[int, int]:
    """Simulation time [s] to a ``builtin_interfaces/Time`` pair (sec, nanosec)."""
    sec, nanosec = divmod(time_to_ns(t), 1_000_000_000)
    return sec, nanosec


def stamp_to_ns(sec: int, nanosec: int) -> int:
    """A ``builtin_interfaces/Time`` pair to integer nanoseconds."""
    return sec * 1_000_000_000 + nanosec


def ns_to_time(ns: int) -> float:
    """Integer nanoseconds to simulation time [s] (nearest float)."""
    return ns / 1e9


# --------------------------------------------------------------------------------------------
# Nodes and services
# --------------------------------------------------------------------------------------------
#: Node names of the simulated system, in start order; the recorder is optional.
PIPELINE_NODES = ('predictor_node', 'feature_node', 'controller_node', 'simulator_node')
RECORDER_NODE = 'recorder_node'
#: ``std_srvs/srv/Trigger``: put the robot back to standing and start a new run.
RESET_SERVICE = '/simulator_node/reset'
#: ``std_srvs/srv/SetBool``: pause (true) or resume (false) the simulation.
PAUSE_SERVICE = '/simulator_node/pause'


def check_controller_mode(mode: str) -> str:
    """Return ``mode`` if it is one of :data:`CONTROLLER_MODES`."""
    if mode not in CONTROLLER_MODES:
        raise WireFormatError(f'controller mode {mode!r} is not one of {CONTROLLER_MODES}')
    return mode


# --------------------------------------------------------------------------------------------
# Robot sensor topics (issue 10): what a real robot publishes; the state estimator's input
# --------------------------------------------------------------------------------------------
#: Frame of the torso IMU (the torso link's origin and axes).
IMU_FRAME = 'torso'
#: Frames of the ankle F/T wrenches (URDF sole frames: the sole underside centres).
SOLE_FRAME_IDS = {'l': 'l_sole', 'r': 'r_sole'}
#: Joint encoders at the simulation rate, with efforts (the /joint_states of JOINT_STATES,
#: published at 1 kHz when the simulator publishes its sensors).
SENSOR_JOINT_STATES = TopicSpec(
    '/joint_states', 'sensor_msgs/msg/JointState', STREAM_QOS, SIM_RATE_HZ,
    '', None, 'joint encoders: positions, velocities, efforts of all 26 joints')
IMU = TopicSpec(
    '/imu/data', 'sensor_msgs/msg/Imu', STREAM_QOS, SIM_RATE_HZ,
    IMU_FRAME, None, 'torso IMU: orientation, angular velocity, specific force')
LEFT_FOOT_WRENCH = TopicSpec(
    '/left_foot/wrench', 'geometry_msgs/msg/WrenchStamped', STREAM_QOS, SIM_RATE_HZ,
    SOLE_FRAME_IDS['l'], None, 'left ankle F/T: ground reaction on the sole [N, N m]')
RIGHT_FOOT_WRENCH = TopicSpec(
    '/right_foot/wrench', 'geometry_msgs/msg/WrenchStamped', STREAM_QOS, SIM_RATE_HZ,
    SOLE_FRAME_IDS['r'], None, 'right ankle F/T: ground reaction on the sole [N, N m]')
ROBOT_DESCRIPTION = TopicSpec(
    '/robot_description', 'std_msgs/msg/String', LATCHED_QOS, None,
    None, None, 'URDF of the robot, with sole frames l_sole and r_sole')
#: The estimator's output and the simulator's exact state: both carry the measurement layout.
#: With sensors on, MEASUREMENT is the estimate and this topic the ground truth (evaluation only).
GROUND_TRUTH = TopicSpec(
    '/fall_predictor/ground_truth', 'std_msgs/msg/Float64MultiArray', STREAM_QOS, SIM_RATE_HZ,
    None, MEASUREMENT_LABEL, 'simulator exact state (evaluation only), measurement layout v1')
SENSOR_TOPICS: tuple[TopicSpec, ...] = (
    SENSOR_JOINT_STATES, IMU, LEFT_FOOT_WRENCH, RIGHT_FOOT_WRENCH, ROBOT_DESCRIPTION, GROUND_TRUTH)
SENSOR_TOPICS_BY_NAME: dict[str, TopicSpec] = {spec.name: spec for spec in SENSOR_TOPICS}
#: Bag metadata key (rosbag2 ``custom_data``) holding the sensor model's parameters (JSON).
SENSOR_PARAMS_METADATA_KEY = 'fall_predictor.sensor_params'
