"""The topic contract: every topic and service name, message type, QoS, rate and frame id.

The single place where the ROS interface of the package is named. It has no ROS imports: the
rclpy nodes (through :mod:`fall_predictor.ros.conversions`) and the bag tools
(:mod:`fall_predictor.data.bagio`) map these definitions onto their own message objects. The
array layouts carried by some of these topics are in :mod:`fall_predictor.contract.wire`.
"""
from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Literal, Optional

from fall_predictor.monitor.plausibility import MAX_SAMPLE_TIME_S
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


#: 1 kHz streams as published: reliable, volatile, 1 s of samples kept for reliable readers
#: (the recorder) that fall briefly behind.
STREAM_QOS = QosSpec('reliable', 'volatile', 1000)
#: 1 kHz streams as the monitor and controller subscribe to them (REP 2003 sensor data):
#: best effort with a shallow queue, so a reader that falls behind gets fresh samples, not
#: a second-old backlog; a lost sample shows up in the gap counters.
SENSOR_SUB_QOS = QosSpec('best_effort', 'volatile', 10)
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
STATE_LABEL = 'fall_predictor/state/v2'
#: Frame of heading-frame vectors (fall direction, push requests): REP 120's
#: ``base_footprint``: on the ground below the robot, x along the pelvis heading, z up.
HEADING_FRAME = 'base_footprint'


@dataclass(frozen=True, slots=True)
class TopicSpec:
    """One row of the interface table.

    ``name`` is the topic's name in the root namespace, as bags store it. Nodes use
    :attr:`ros_name`: relative (no leading slash), so a node started in a namespace
    (``/robot1``) uses ``/robot1/fall_predictor/...``, except for the global topics
    ``/clock`` and ``/diagnostics``.
    """

    name: str                       #: topic name (root namespace; the bag topic name)
    msg_type: str                   #: ROS 2 type name, e.g. 'std_msgs/msg/Float64MultiArray'
    qos: QosSpec                    #: publisher QoS (and that of lossless readers: the recorder)
    rate_hz: Optional[float]        #: nominal rate [Hz]; None for event-driven topics
    frame_id: Optional[str]         #: header.frame_id; None when the type has no header
    layout: Optional[str]           #: Float64MultiArray layout label; None for other types
    content: str                    #: one-line description for the README
    sub_qos: Optional[QosSpec] = None   #: subscriber QoS of the nodes; None = ``qos``
    is_global: bool = False         #: resolved from the root namespace (``/clock``)

    @property
    def ros_name(self) -> str:
        """The name nodes create the topic with: relative unless the topic is global."""
        return self.name if self.is_global else self.name.lstrip('/')

    @property
    def subscription_qos(self) -> QosSpec:
        return self.qos if self.sub_qos is None else self.sub_qos


#: Frame of the state estimator's world-fixed vectors (REP 105).
ODOM_FRAME = 'odom'

MEASUREMENT = TopicSpec(
    '/fall_predictor/measurement', 'fall_predictor/msg/Measurement', STREAM_QOS, SIM_RATE_HZ,
    ODOM_FRAME, None, 'the whole-body state per sensor sample (state estimator), or its fault',
    SENSOR_SUB_QOS)
FEATURES = TopicSpec(
    '/fall_predictor/features', 'fall_predictor/msg/Features', STREAM_QOS, SIM_RATE_HZ,
    '', None, 'the 15 features, the contact mode, the base tilt and the base\'s attitude (fused '
    'roll, pitch, angular velocity about x and y: method §8c) per sample, or its fault',
    SENSOR_SUB_QOS)
STATE = TopicSpec(
    '/fall_predictor/state', 'fall_predictor/msg/FallState', STREAM_QOS, SIM_RATE_HZ,
    'base_footprint', None, 'the monitor per sample: status and reason, falling, latched, '
    'contact mode, time to fall, fall direction', SENSOR_SUB_QOS)
FALL_EVENT = TopicSpec(
    '/fall_predictor/fall_event', 'fall_predictor/msg/FallEvent', LATCHED_QOS, None,
    'base_footprint', None, 'the last change of the fall state: falling, fallen, standing, reset')
MARKERS = TopicSpec(
    '/fall_predictor/markers', 'visualization_msgs/msg/MarkerArray', EVENT_QOS, None, None, None,
    'what the monitor sees (monitor_markers, off unless started): support polygon, CoP, CoM, '
    'capture point, fall direction, status')
FALLING = TopicSpec(
    '/fall_predictor/falling', 'std_msgs/msg/Bool', LATCHED_QOS, None, None, None,
    'the trigger: true from the first falling prediction until the reset (latched)')
FALL_DIRECTION = TopicSpec(
    '/fall_predictor/fall_direction', 'geometry_msgs/msg/Vector3Stamped', LATCHED_QOS, None,
    HEADING_FRAME, None, 'predicted fall direction (unit, heading frame) at each falling event')
JOINT_STATES = TopicSpec(
    '/joint_states', 'sensor_msgs/msg/JointState', STREAM_QOS, JOINT_STATE_RATE_HZ,
    '', None, 'robot joint positions, velocities, efforts (visualisation, bags)', SENSOR_SUB_QOS)
PUSH = TopicSpec(
    '/fall_predictor/push', 'geometry_msgs/msg/WrenchStamped', EVENT_QOS, None,
    WORLD_FRAME, None, f'push onset (stamp) and world force [N], lasting {PUSH_DURATION_S} s')
#: Frame of a push request's force: the robot's heading frame (x forward, y left, z up).
PUSH_REQUEST_FRAME = HEADING_FRAME
#: Input of the simulator node: a push to apply. ``header.stamp`` = requested onset in
#: simulation time (a time already past means "at the next step"); ``wrench.force`` = the
#: horizontal force [N] in :data:`PUSH_REQUEST_FRAME`; ``wrench.torque`` = its moment about
#: the CoM [N m], ``(0, 0, h) x force`` for an application point ``h`` metres above the CoM.
#: The force lasts ``PUSH_DURATION_S`` (0.1 s, method §3).
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
    None, None, 'simulation time', is_global=True)
DIAGNOSTICS = TopicSpec(
    '/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray', EVENT_QOS, DIAGNOSTICS_RATE_HZ,
    '', None, 'node health', is_global=True)

#: The interface table, in README order.
TOPICS: tuple[TopicSpec, ...] = (
    MEASUREMENT, FEATURES, STATE, FALL_EVENT, FALLING, FALL_DIRECTION, MARKERS, JOINT_STATES, PUSH, PUSH_REQUEST,
    CONTROLLER_MODE, JOINT_COMMANDS, CLOCK, DIAGNOSTICS,
)
TOPICS_BY_NAME: dict[str, TopicSpec] = {spec.name: spec for spec in TOPICS}

CONTROLLER_MODES: tuple[str, ...] = ('balance', 'fall')


def topics_markdown_table(topics: Iterable[TopicSpec] = TOPICS) -> str:
    """The interface table in Markdown (for the README): names as nodes use them (relative
    unless global), the publisher QoS and, where the nodes read otherwise, the reader QoS."""
    lines = ['| topic | type | QoS (publisher; reader) | rate | frame | content |',
             '|---|---|---|---|---|---|']
    for spec in topics:
        rate = 'on event' if spec.rate_hz is None else f'{spec.rate_hz:g} Hz'
        frame = ('-' if not spec.frame_id else spec.frame_id if spec.frame_id.startswith('(')
                 else f'`{spec.frame_id}`')
        content = spec.content if spec.layout is None else f'{spec.content} (`{spec.layout}`)'
        qos = spec.qos.describe()
        if spec.sub_qos is not None:
            qos += f'; read {spec.sub_qos.describe()}'
        lines.append(f'| `{spec.ros_name}` | `{spec.msg_type}` | {qos} | {rate} '
                     f'| {frame} | {content} |')
    return '\n'.join(lines) + '\n'


# --------------------------------------------------------------------------------------------
# Time
# --------------------------------------------------------------------------------------------

#: Largest time [s] converted to a stamp: the plausibility bound of sample times (1e7 s);
#: beyond 2^31 s a ``builtin_interfaces/Time.sec`` would wrap to a negative number.
MAX_STAMP_TIME_S = MAX_SAMPLE_TIME_S
#: Stamps [s] a ``builtin_interfaces/Time`` holds (its ``sec`` is an int32): what a robot's
#: drivers stamp in ROS time (seconds since 1970), beyond the simulation-time bound above.
MAX_ROS_STAMP_S = 2.0 ** 31


def check_stamp_s(t: float, what: str) -> None:
    """WireFormatError unless ``t`` [s] is a stamp a ``builtin_interfaces/Time`` holds, whatever
    the clock (simulation or ROS time)."""
    if not (math.isfinite(t) and 0.0 <= t < MAX_ROS_STAMP_S):
        raise WireFormatError(f'{what} stamp {t!r} s is not a builtin_interfaces/Time')


def time_to_ns(t: float) -> int:
    """Simulation time [s] to integer nanoseconds (bag log time, header stamps)."""
    if not (math.isfinite(t) and 0.0 <= t <= MAX_STAMP_TIME_S):
        raise WireFormatError(f'time must be finite and within [0, {MAX_STAMP_TIME_S:g}] s, '
                              f'got {t!r}')
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
#: Service names relative to the caller's namespace (the nodes create them as ``~/<name>``).
#: ``std_srvs/srv/Trigger``: put the robot back to standing and start a new run.
RESET_SERVICE = 'simulator_node/reset'
#: ``std_srvs/srv/SetBool``: pause (true) or resume (false) the simulation.
PAUSE_SERVICE = 'simulator_node/pause'
#: ``std_srvs/srv/Trigger``: the one reset of the whole monitor (history, latch, trigger; the
#: monitor's other nodes and the controller follow the RESET event on FALL_EVENT). The only way
#: to undo a fall.
MONITOR_RESET_SERVICE = 'fall_predictor/reset'
#: ``std_srvs/srv/SetBool``: enable (true) or disable (false) the fall trigger.
ENABLE_SERVICE = 'fall_predictor/enable'


def check_controller_mode(mode: str) -> str:
    """Return ``mode`` if it is one of :data:`CONTROLLER_MODES`."""
    if mode not in CONTROLLER_MODES:
        raise WireFormatError(f'controller mode {mode!r} is not one of {CONTROLLER_MODES}')
    return mode


# --------------------------------------------------------------------------------------------
# Robot sensor topics: what a real robot publishes; the state estimator's input
# --------------------------------------------------------------------------------------------
#: The sensors' header.frame_id: frames of the robot's URDF, which its robot profile names (the
#: IMU's link; the F/T sensors' frames). Shown in the interface table as placeholders.
IMU_FRAME = '(IMU frame)'
WRENCH_FRAME = '(F/T frame)'
#: Joint encoders at the simulation rate, with efforts (the /joint_states of JOINT_STATES,
#: published at 1 kHz when the simulator publishes its sensors).
SENSOR_JOINT_STATES = TopicSpec(
    '/joint_states', 'sensor_msgs/msg/JointState', STREAM_QOS, SIM_RATE_HZ,
    '', None, 'joint encoders: positions, velocities (optional), efforts (optional)', SENSOR_SUB_QOS)
IMU = TopicSpec(
    '/imu/data', 'sensor_msgs/msg/Imu', STREAM_QOS, SIM_RATE_HZ,
    IMU_FRAME, None, 'IMU: orientation, angular velocity, specific force', SENSOR_SUB_QOS)
LEFT_FOOT_WRENCH = TopicSpec(
    '/left_foot/wrench', 'geometry_msgs/msg/WrenchStamped', STREAM_QOS, SIM_RATE_HZ,
    WRENCH_FRAME, None, 'left foot F/T (if the robot has one): ground reaction [N, N m]',
    SENSOR_SUB_QOS)
RIGHT_FOOT_WRENCH = TopicSpec(
    '/right_foot/wrench', 'geometry_msgs/msg/WrenchStamped', STREAM_QOS, SIM_RATE_HZ,
    WRENCH_FRAME, None, 'right foot F/T (if the robot has one): ground reaction [N, N m]',
    SENSOR_SUB_QOS)
ROBOT_DESCRIPTION = TopicSpec(
    '/robot_description', 'std_msgs/msg/String', LATCHED_QOS, None,
    None, None, 'URDF of the robot (sole frames: from it or its profile)')
#: The estimator's output and the simulator's exact state: both carry the measurement layout.
#: With sensors on, MEASUREMENT is the estimate and this topic the ground truth (evaluation only).
GROUND_TRUTH = TopicSpec(
    '/fall_predictor/ground_truth', 'fall_predictor/msg/Measurement', STREAM_QOS, SIM_RATE_HZ,
    ODOM_FRAME, None, 'simulator exact state (evaluation only)')
SENSOR_TOPICS: tuple[TopicSpec, ...] = (
    SENSOR_JOINT_STATES, IMU, LEFT_FOOT_WRENCH, RIGHT_FOOT_WRENCH, ROBOT_DESCRIPTION, GROUND_TRUTH)
SENSOR_TOPICS_BY_NAME: dict[str, TopicSpec] = {spec.name: spec for spec in SENSOR_TOPICS}
#: Bag metadata key (rosbag2 ``custom_data``) holding the sensor model's parameters (JSON).
SENSOR_PARAMS_METADATA_KEY = 'fall_predictor.sensor_params'
