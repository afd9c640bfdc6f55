"""The array layouts on the wire: what the contract's per-sample messages hold, and time stamps.

Topic names, types and QoS are in :mod:`fall_predictor.contract.topics`. This module has no
ROS imports: the rclpy nodes (through :mod:`fall_predictor.ros.conversions`) and the bag tools
(:mod:`fall_predictor.data.bagio`) both map these definitions onto their own message objects.

Only message types from ROS 2 ``common_interfaces`` are used, so fixed-layout
``std_msgs/msg/Float64MultiArray`` arrays carry the per-sample records. Each array's layout is
versioned by its ``layout.dim[0].label``; a reader rejects any label it does not know.

Measurement layout v1 (float64, ``N = 26 + 3 * (n_left + n_right)`` values)::

    [0]      t                  simulation time [s]
    [1:4]    com                whole-body CoM, world [m]
    [4:7]    lin_mom            linear momentum, world [kg m/s]
    [7:10]   ang_mom            angular momentum about the CoM, world [kg m^2/s]
    [10]     heading            pelvis yaw [rad]
    [11:14]  cop                centre of pressure, world [m]; all three NaN if no contact
    [14:17]  left_foot          left sole centre x, y [m] and yaw [rad]
    [17:20]  right_foot         right sole centre x, y [m] and yaw [rad]
    [20]     non_foot_contact   0 or 1
    [21:24]  push_force         external push now, world [N]
    [24]     n_left             number of left sole contact rows (a non-negative integer)
    [25]     n_right            number of right sole contact rows
    [26:]    n_left rows of (x [m], y [m], normal_force [N]), then n_right rows

Features layout v1 (17 float64): ``[0]`` t [s], ``[1:16]`` the 15 features in
:data:`~fall_predictor.monitor.records.FEATURE_NAMES` order, ``[16]`` the contact mode index
(:data:`~fall_predictor.monitor.records.CONTACT_MODE_NAMES`).

State layout v2 (11 float64, ``/fall_predictor/state``; read by slot, no strings): the
``I_STATE_*`` / ``S_STATE_*`` constants below, documented slot by slot in the README.

Every field is also checked against the bounds of :mod:`fall_predictor.monitor.plausibility`:
a value no robot can produce is rejected like a malformed one, by :class:`WireFormatError`
naming the field. Header stamps and bag log times are the samples' own (simulation) time.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NamedTuple, Optional, Protocol

import numpy as np
from numpy.typing import ArrayLike

from fall_predictor.contract.topics import (WORLD_FRAME, WireFormatError, check_stamp_s, ns_to_time,
                                            time_to_ns)
from fall_predictor.monitor.plausibility import (JOINT_VALUE_BOUNDS, MAX_PUSH_FORCE_N,
                                                 ImplausibleSample, check_feature_bounds,
                                                 check_measurement_bounds)
from fall_predictor.monitor.plausibility import check_time as _check_time
from fall_predictor.monitor.records import FEATURE_NAMES, N_CONTACT_MODES, N_FEATURES, Measurement


# --------------------------------------------------------------------------------------------
# Float64MultiArray layouts
# --------------------------------------------------------------------------------------------

class LayoutDim(Protocol):
    """Duck type of ``std_msgs/msg/MultiArrayDimension`` (rclpy and rosbags alike)."""

    label: str
    size: int
    stride: int


class Layout(Protocol):
    """Duck type of ``std_msgs/msg/MultiArrayLayout``."""

    dim: Sequence[LayoutDim]
    data_offset: int


def check_layout(layout: Layout, expected_label: str, n_data: int) -> None:
    """Check a received layout: one dimension, the expected label, size = stride = ``n_data``."""
    if len(layout.dim) != 1:
        raise WireFormatError(
            f'layout must have exactly 1 dimension labelled {expected_label!r}, '
            f'got {len(layout.dim)}')
    dim = layout.dim[0]
    if dim.label != expected_label:
        raise WireFormatError(f'layout label {dim.label!r} is not {expected_label!r}')
    if dim.size != n_data or dim.stride != n_data:
        raise WireFormatError(
            f'{expected_label}: layout size/stride {dim.size}/{dim.stride} '
            f'disagree with {n_data} data values')
    if layout.data_offset != 0:
        raise WireFormatError(f'{expected_label}: data_offset must be 0, got {layout.data_offset}')


def _as_vector(data: ArrayLike, what: str) -> np.ndarray:
    """A private float64 1-D copy of ``data``."""
    try:
        arr = np.array(data, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise WireFormatError(f'{what}: data is not a float64 vector ({exc})') from None
    if arr.ndim != 1:
        raise WireFormatError(f'{what}: data must be 1-D, got shape {arr.shape}')
    return arr


def check_time_bounds(t: float) -> float:
    """A sample time [s] within the plausibility bounds, else WireFormatError."""
    try:
        return _check_time(t)
    except ImplausibleSample as error:
        raise WireFormatError(str(error)) from None


def _count(value: float, what: str) -> int:
    if not (math.isfinite(value) and value >= 0 and value == int(value)):
        raise WireFormatError(f'{what} must be a non-negative integer, got {value!r}')
    return int(value)


# --------------------------------------------------------------------------------------------
# Measurement
# --------------------------------------------------------------------------------------------

I_T = 0
S_COM = slice(1, 4)
S_LIN_MOM = slice(4, 7)
S_ANG_MOM = slice(7, 10)
I_HEADING = 10
S_COP = slice(11, 14)
S_LEFT_FOOT = slice(14, 17)
S_RIGHT_FOOT = slice(17, 20)
I_NON_FOOT_CONTACT = 20
S_PUSH_FORCE = slice(21, 24)
I_N_LEFT = 24
I_N_RIGHT = 25
MEASUREMENT_HEADER_LEN = 26

_MEASUREMENT_FIELDS: tuple[tuple[str, slice], ...] = (
    ('t', slice(I_T, I_T + 1)), ('com', S_COM), ('lin_mom', S_LIN_MOM), ('ang_mom', S_ANG_MOM),
    ('heading', slice(I_HEADING, I_HEADING + 1)), ('cop', S_COP), ('left_foot', S_LEFT_FOOT),
    ('right_foot', S_RIGHT_FOOT),
    ('non_foot_contact', slice(I_NON_FOOT_CONTACT, I_NON_FOOT_CONTACT + 1)),
    ('push_force', S_PUSH_FORCE),
)


def _vec3(value: ArrayLike, what: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (3,):
        raise WireFormatError(f'measurement.{what} must have shape (3,), got {arr.shape}')
    return arr


def _contact_rows(value: ArrayLike, what: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise WireFormatError(f'measurement.{what} must have shape (k, 3), got {arr.shape}')
    return arr


def pack_measurement(m: Measurement) -> np.ndarray:
    """Measurement -> layout v1 float64 array. The result is checked as a receiver would."""
    left = _contact_rows(m.left_contacts, 'left_contacts')
    right = _contact_rows(m.right_contacts, 'right_contacts')
    n_left, n_right = left.shape[0], right.shape[0]
    out = np.empty(MEASUREMENT_HEADER_LEN + 3 * (n_left + n_right), dtype=np.float64)
    out[I_T] = m.t
    out[S_COM] = _vec3(m.com, 'com')
    out[S_LIN_MOM] = _vec3(m.lin_mom, 'lin_mom')
    out[S_ANG_MOM] = _vec3(m.ang_mom, 'ang_mom')
    out[I_HEADING] = m.heading
    out[S_COP] = _vec3(m.cop, 'cop')
    out[S_LEFT_FOOT] = _vec3(m.left_foot, 'left_foot')
    out[S_RIGHT_FOOT] = _vec3(m.right_foot, 'right_foot')
    out[I_NON_FOOT_CONTACT] = 1.0 if m.non_foot_contact else 0.0
    out[S_PUSH_FORCE] = _vec3(m.push_force, 'push_force')
    out[I_N_LEFT] = n_left
    out[I_N_RIGHT] = n_right
    split = MEASUREMENT_HEADER_LEN + 3 * n_left
    out[MEASUREMENT_HEADER_LEN:split] = left.ravel()
    out[split:] = right.ravel()
    _check_measurement(out)
    return out


def _check_measurement(a: np.ndarray) -> tuple[int, int]:
    """Validate a layout v1 array; return (n_left, n_right)."""
    if a.size < MEASUREMENT_HEADER_LEN:
        raise WireFormatError(
            f'measurement: {a.size} values, fewer than the {MEASUREMENT_HEADER_LEN}-value header')
    h = a[:MEASUREMENT_HEADER_LEN].tolist()     # Python floats: cheaper to check one by one
    n_left = _count(h[I_N_LEFT], 'measurement n_left')
    n_right = _count(h[I_N_RIGHT], 'measurement n_right')
    expected = MEASUREMENT_HEADER_LEN + 3 * (n_left + n_right)
    if a.size != expected:
        raise WireFormatError(
            f'measurement: {a.size} values, but n_left={n_left} and n_right={n_right} '
            f'need {expected}')
    finite = np.isfinite(a)
    if not (finite[S_COP].all() or np.isnan(a[S_COP]).all()):
        raise WireFormatError(f'measurement.cop must be all finite or all NaN, got {a[S_COP]}')
    finite[S_COP] = True
    if not finite.all():
        index = int(np.argmin(finite))
        raise WireFormatError(f'measurement.{_field_at(index)} is not finite: {a[index]!r}')
    if h[I_NON_FOOT_CONTACT] not in (0.0, 1.0):
        raise WireFormatError(
            f'measurement.non_foot_contact must be 0 or 1, got {h[I_NON_FOOT_CONTACT]!r}')
    try:
        check_measurement_bounds(h[I_T], h[S_COM], h[S_LIN_MOM], h[S_ANG_MOM], h[I_HEADING],
                                 h[S_COP], h[S_LEFT_FOOT], h[S_RIGHT_FOOT], h[S_PUSH_FORCE],
                                 a[MEASUREMENT_HEADER_LEN:])
    except ImplausibleSample as error:
        raise WireFormatError(f'measurement: {error}') from None
    return n_left, n_right


def _field_at(index: int) -> str:
    for name, part in _MEASUREMENT_FIELDS:
        if part.start <= index < part.stop:
            return name
    row, column = divmod(index - MEASUREMENT_HEADER_LEN, 3)
    return f'contacts row {row} column {column}'


def unpack_measurement(data: ArrayLike) -> Measurement:
    """Layout v1 float64 array -> Measurement (arrays are private copies)."""
    a = _as_vector(data, 'measurement')
    n_left, n_right = _check_measurement(a)
    split = MEASUREMENT_HEADER_LEN + 3 * n_left
    return Measurement(
        t=float(a[I_T]),
        com=a[S_COM],
        lin_mom=a[S_LIN_MOM],
        ang_mom=a[S_ANG_MOM],
        heading=float(a[I_HEADING]),
        cop=a[S_COP],
        left_contacts=a[MEASUREMENT_HEADER_LEN:split].reshape(n_left, 3),
        right_contacts=a[split:].reshape(n_right, 3),
        left_foot=a[S_LEFT_FOOT],
        right_foot=a[S_RIGHT_FOOT],
        non_foot_contact=bool(a[I_NON_FOOT_CONTACT]),
        push_force=a[S_PUSH_FORCE],
    )


# --------------------------------------------------------------------------------------------
# Features
# --------------------------------------------------------------------------------------------

FEATURES_LEN = 2 + N_FEATURES


class FeatureSample(NamedTuple):
    """One features message: time [s], the 15 features then the base's attitude (19 values,
    the attitude NaN when not sent; method §8c), the contact mode index."""

    t: float
    x: np.ndarray
    mode: int


def _mode_index(value: float, what: str) -> int:
    mode = _count(value, what)
    if mode >= N_CONTACT_MODES:
        raise WireFormatError(f'{what} must be < {N_CONTACT_MODES}, got {mode}')
    return mode


def pack_features(t: float, x: ArrayLike, mode: int) -> np.ndarray:
    """(t [s], 15 features, contact mode index) -> features layout v1 array."""
    xs = np.asarray(x, dtype=np.float64)
    if xs.shape != (N_FEATURES,):
        raise WireFormatError(f'features must have shape ({N_FEATURES},), got {xs.shape}')
    out = np.empty(FEATURES_LEN, dtype=np.float64)
    out[0] = t
    out[1:1 + N_FEATURES] = xs
    out[-1] = mode
    _check_features(out)
    return out


def _check_features(a: np.ndarray) -> int:
    if a.size != FEATURES_LEN:
        raise WireFormatError(f'features: {a.size} values, expected {FEATURES_LEN}')
    finite = np.isfinite(a)
    if not finite.all():
        index = int(np.argmin(finite))
        name = ('t', *FEATURE_NAMES, 'mode')[index]
        raise WireFormatError(f'features.{name} is not finite: {a[index]!r}')
    v = a.tolist()                          # Python floats: cheaper to check one by one
    try:
        check_feature_bounds(v[0], v[1:1 + N_FEATURES])
    except ImplausibleSample as error:
        raise WireFormatError(f'features: {error}') from None
    return _mode_index(v[-1], 'features contact mode')


def unpack_features(data: ArrayLike) -> FeatureSample:
    """Features layout v1 array -> FeatureSample (x is a private copy)."""
    a = _as_vector(data, 'features')
    mode = _check_features(a)
    return FeatureSample(float(a[0]), a[1:1 + N_FEATURES], mode)


# --------------------------------------------------------------------------------------------
# Predictor state (Float64MultiArray, layout v2)
# --------------------------------------------------------------------------------------------

#: ``diagnostic_msgs/DiagnosticStatus`` levels used on ``/diagnostics``.
LEVEL_OK, LEVEL_WARN, LEVEL_ERROR, LEVEL_STALE = 0, 1, 2, 3
#: State status codes (slot ``I_STATE_STATUS``): predicted on a fresh sample; the monitor is
#: disabled (``~/enable`` false: no trigger); stale (the sample was too old, invalid, or no
#: input arrived for ``stale_timeout_s``: no prediction, the latch is kept).
STATUS_OK, STATUS_DISABLED, STATUS_STALE = 0, 1, 2
_STATUS_NAMES = ('ok', 'disabled', 'stale')

#: State layout v2 slots (11 float64; flags are 0.0 or 1.0).
I_STATE_T = 0               #: sample time [s] of the features the state was computed from
I_STATE_STATUS = 1          #: STATUS_OK, STATUS_DISABLED or STATUS_STALE
I_STATE_FALLING = 2         #: the prediction (window applied), 1 = falling
I_STATE_LATCHED = 3         #: falling was predicted since the last reset (the trigger)
I_STATE_ATOMIC = 4          #: the contact mode's decision list said falling
I_STATE_GUARD = 5           #: the CoM was below the guard height
I_STATE_CONTACT_MODE = 6    #: contact mode index, -1 when unknown (stale)
I_STATE_TAU_HIS = 7         #: history window in use [s]
I_STATE_TIME_TO_FALL = 8    #: predicted time left until fallen [s]; NaN when not predicted
S_STATE_DIRECTION = slice(9, 11)   #: predicted fall direction (x, y), heading frame; NaN if none
STATE_LEN = 11
STATE_SLOT_NAMES = ('t', 'status', 'falling', 'latched', 'atomic', 'guard', 'contact_mode',
                    'tau_his_s', 'time_to_fall_s', 'fall_direction_x', 'fall_direction_y')


@dataclass(frozen=True, slots=True)
class PredictorState:
    """The predictor's output for one source sample (``/fall_predictor/state``).

    ``falling`` is the published decision (history window applied); ``atomic`` the decision
    list's raw output; ``guard`` the CoM guard (method §5); ``latched`` whether falling was
    predicted since the last reset. ``stale_reason`` set means degraded (no prediction; the
    reason goes to ``/diagnostics``, the wire carries only the status); ``enabled`` false means
    the monitor is switched off (no trigger).
    """

    t: float                            #: sample time of the source sample [s]
    falling: bool
    atomic: bool
    guard: bool
    latched: bool
    contact_mode: Optional[int]         #: index into CONTACT_MODE_NAMES; None if unknown
    tau_his_s: float                    #: history window [s]
    stale_reason: Optional[str] = None  #: why inputs are stale/missing/invalid
    enabled: bool = True
    time_to_fall_s: float = math.nan    #: predicted time left until fallen [s]
    fall_direction: tuple[float, float] = (math.nan, math.nan)  #: unit (x, y), heading frame

    @property
    def status(self) -> int:
        """STATUS_STALE if degraded, else STATUS_DISABLED if disabled, else STATUS_OK."""
        if self.stale_reason is not None:
            return STATUS_STALE
        return STATUS_OK if self.enabled else STATUS_DISABLED

    @property
    def message(self) -> str:
        """One word for logs: falling, balanced, disabled or stale."""
        if self.status != STATUS_OK:
            return _STATUS_NAMES[self.status]
        return 'falling' if self.falling else 'balanced'


def pack_state(state: PredictorState) -> np.ndarray:
    """PredictorState -> state layout v2 array, checked as a receiver would."""
    out = np.empty(STATE_LEN, dtype=np.float64)
    out[I_STATE_T] = state.t
    out[I_STATE_STATUS] = state.status
    out[I_STATE_FALLING] = float(bool(state.falling))
    out[I_STATE_LATCHED] = float(bool(state.latched))
    out[I_STATE_ATOMIC] = float(bool(state.atomic))
    out[I_STATE_GUARD] = float(bool(state.guard))
    out[I_STATE_CONTACT_MODE] = -1.0 if state.contact_mode is None else state.contact_mode
    out[I_STATE_TAU_HIS] = state.tau_his_s
    out[I_STATE_TIME_TO_FALL] = state.time_to_fall_s
    out[S_STATE_DIRECTION] = state.fall_direction
    unpack_state(out)
    return out


def _flag(a: Sequence[float], index: int) -> bool:
    if a[index] not in (0.0, 1.0):
        raise WireFormatError(f'state.{STATE_SLOT_NAMES[index]} must be 0 or 1, got {a[index]!r}')
    return bool(a[index])


def unpack_state(data: ArrayLike) -> PredictorState:
    """State layout v2 array -> PredictorState; raises WireFormatError naming the slot.

    A stale state comes back with ``stale_reason='stale'`` (the reason is not on the wire).
    """
    a = _as_vector(data, 'state')
    if a.size != STATE_LEN:
        raise WireFormatError(f'state: {a.size} values, expected {STATE_LEN}')
    v = a.tolist()                          # Python floats: cheaper to check one by one
    for index in range(I_STATE_TIME_TO_FALL):
        if not math.isfinite(v[index]):
            raise WireFormatError(f'state.{STATE_SLOT_NAMES[index]} is not finite: {v[index]!r}')
    check_time_bounds(v[I_STATE_T])
    status = v[I_STATE_STATUS]
    if status not in (STATUS_OK, STATUS_DISABLED, STATUS_STALE):
        raise WireFormatError(f'state.status must be 0, 1 or 2, got {status!r}')
    mode = v[I_STATE_CONTACT_MODE]
    if mode != -1.0:
        _mode_index(mode, 'state.contact_mode')
    tau = v[I_STATE_TAU_HIS]
    if tau < 0.0:
        raise WireFormatError(f'state.tau_his_s must be >= 0 s, got {tau!r}')
    ttf = v[I_STATE_TIME_TO_FALL]
    if not (math.isnan(ttf) or 0.0 <= ttf <= 1e3):
        raise WireFormatError(f'state.time_to_fall_s must be NaN or in [0, 1000] s, got {ttf!r}')
    dx, dy = float(v[S_STATE_DIRECTION][0]), float(v[S_STATE_DIRECTION][1])
    if not (math.isnan(dx) and math.isnan(dy)) and not abs(math.hypot(dx, dy) - 1.0) <= 1e-6:
        raise WireFormatError(f'state.fall_direction must be a unit vector or NaN, got {(dx, dy)}')
    return PredictorState(
        t=float(v[I_STATE_T]), falling=_flag(v, I_STATE_FALLING), atomic=_flag(v, I_STATE_ATOMIC),
        guard=_flag(v, I_STATE_GUARD), latched=_flag(v, I_STATE_LATCHED),
        contact_mode=None if mode == -1.0 else int(mode), tau_his_s=float(tau),
        stale_reason='stale' if status == STATUS_STALE else None,
        enabled=status != STATUS_DISABLED, time_to_fall_s=_nan_or(ttf),
        fall_direction=(_nan_or(dx), _nan_or(dy)))


def _nan_or(value: float) -> float:
    # The one math.nan object, so that states compare equal field by field (NaN is NaN).
    return math.nan if math.isnan(value) else float(value)


# --------------------------------------------------------------------------------------------
# Joint states, pushes, controller mode
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class JointStateSample:
    """One ``sensor_msgs/JointState``: names, positions [rad], velocities [rad/s], efforts [N m].

    Velocities and efforts are either empty (not reported) or one per joint.
    """

    t: float                    #: header stamp [s]: simulation time, or ROS time from a robot
    names: tuple[str, ...]
    position: np.ndarray
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(0))
    effort: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        check_stamp_s(self.t, 'joint state')
        n = len(self.names)
        if len(set(self.names)) != n:
            raise WireFormatError(f'joint state names are not unique: {list(self.names)}')
        for what, optional in (('position', False), ('velocity', True), ('effort', True)):
            arr = _as_vector(getattr(self, what), f'joint state {what}')
            if arr.size != n and not (optional and arr.size == 0):
                allowed = f'{n}' + (' or 0' if optional else '')
                raise WireFormatError(
                    f'joint state has {n} names but {arr.size} {what} values (need {allowed})')
            if not np.isfinite(arr).all():
                raise WireFormatError(f'joint state {what} is not finite: {arr}')
            if arr.size and not np.abs(arr).max() <= JOINT_VALUE_BOUNDS[what]:
                raise WireFormatError(f'joint state {what} beyond {JOINT_VALUE_BOUNDS[what]:g}: '
                                      f'{np.abs(arr).max():.6g}')
            object.__setattr__(self, what, arr)
        object.__setattr__(self, 'names', tuple(self.names))


@dataclass(frozen=True, slots=True)
class PushEvent:
    """One push as carried by ``/fall_predictor/push``: onset [s] and world force [N].

    The force is constant for :data:`~fall_predictor.monitor.records.PUSH_DURATION_S` (not on the wire).
    """

    t: float                        #: onset, simulation time [s] (the header stamp)
    force: np.ndarray               #: (3,) world force [N]

    def __post_init__(self) -> None:
        time_to_ns(self.t)
        force = np.array(self.force, dtype=np.float64)
        if force.shape != (3,) or not np.isfinite(force).all():
            raise WireFormatError(f'push force must be 3 finite values [N], got {self.force!r}')
        if not np.linalg.norm(force) <= MAX_PUSH_FORCE_N:
            raise WireFormatError(f'push force beyond {MAX_PUSH_FORCE_N:g} N: {self.force!r}')
        object.__setattr__(self, 'force', force)


def push_from_wire(stamp_ns: int, frame_id: str, force: ArrayLike) -> PushEvent:
    """Fields of a ``/fall_predictor/push`` WrenchStamped -> PushEvent (frame must be world)."""
    if frame_id != WORLD_FRAME:
        raise WireFormatError(f'push frame_id {frame_id!r} is not {WORLD_FRAME!r}')
    return PushEvent(ns_to_time(stamp_ns), np.asarray(force, dtype=np.float64))

