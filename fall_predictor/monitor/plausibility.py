"""Physical plausibility of the monitor's inputs: the one place where the bounds live.

A value can be finite, well formed and still impossible for a humanoid: a CoM 1e154 m away,
a sample time of 1e10 s, momentum of 1e308 kg m/s, a CoM that moves 0.6 m in one millisecond.
Such values overflow later arithmetic (squared distances, nanosecond stamps) or fool the
predictor (a CoM at height 0 is "certainly fallen"). Every input is therefore checked twice:

* **bounds, per sample** (:func:`check_measurement`, :func:`check_measurement_bounds`,
  :func:`check_feature_bounds`): each field within a stated range (table below). The state
  estimator's output is checked where it is made (an implausible estimate becomes a fault, so
  the monitor says DEGRADED, live and offline alike), and the wire layer
  (:mod:`fall_predictor.contract.wire`) applies them to every decoded message, so the live nodes
  and the offline bag readers reject the same samples.
* **continuity, between samples** (:class:`ContinuityCheck`): a sample that moved the CoM or
  changed a momentum faster than physics allows since the last accepted sample is rejected.
  The feature extractor applies it, so it is the same live and offline.

Bounds (SI units; "horizontal range" is measured from the CoM's ground projection):

========================  ===================================================================
sample time ``t``         [0, 1e7] s (115 days; nanosecond stamps stay far below 2^63)
CoM x, y                  within 1e4 m of the world origin
CoM height                [0, 2] m
CoP, feet, contacts       within 2 m horizontally of the CoM; contact/CoP z within [-0.5, 2] m
linear momentum           norm <= 2000 kg m/s (a 100 kg robot at 20 m/s)
angular momentum          norm <= 500 kg m^2/s
push force                norm <= 1e5 N
contact normal force      [0, 1e5] N
heading                   within [-1e3, 1e3] rad (any yaw, unwrapped)
joint states              |position| <= 100 rad, |velocity| <= 1e3 rad/s, |effort| <= 1e5 N m
========================  ===================================================================

The robot's raw sensors (the state estimator's input, :class:`SensorBounds`) are bounded by what a
humanoid and its sensors can do:

========================  ===================================================================
joint position            finite, within the joint's limits +- 0.5 rad (continuous joints: any)
joint velocity            finite, at most 5 x the joint's velocity limit (none given: 1e3 rad/s)
joint effort              finite, at most 3 x the URDF's effort limit (none given: 1e4 N m)
IMU angular velocity      norm <= 35 rad/s (2000 deg/s, the widest range of MEMS gyroscopes)
IMU specific force        norm <= 300 m/s^2 (30 g: a torso's impact on the ground stays below)
IMU orientation           a quaternion of norm 1 +- 0.1
foot force / torque       norm <= 20 body weights [N]; torque norm <= 20 body weights x 0.5 m
========================  ===================================================================

A joint's limits are the URDF's unless the robot profile's ``monitor.joint_limits`` states its own
(a URDF's limits are often a controller's soft limits inside the hard stops). A joint reading
between its limits and the bound above is **flagged, not refused**: a real robot's walking and
falling take joints past their URDF limits (a slipping foot turns its ankle past the stop; the
G1 under its policy reaches 0.26 rad past an ankle pitch limit as it hits the ground in MuJoCo,
another maker's humanoid 0.20 rad past an ankle roll limit, and measured speeds beyond the
rated ones at impacts), and the estimate of such a sample is as good as any. A sample is flagged
(counted, its reason in the estimator's diagnostics) when a joint lies more than
:data:`JOINT_FLAG_MARGIN_RAD` beyond its limits or moves faster than
:data:`JOINT_FLAG_VELOCITY_FACTOR` x its velocity limit; it is refused only beyond the table's
bounds: :data:`JOINT_LIMIT_MARGIN_RAD` (29 deg) past a hard stop takes a broken joint or a
reading in the wrong unit or order, and :data:`JOINT_VELOCITY_LIMIT_FACTOR` x a motor's rated
speed a broken encoder.

Text from the wire is bounded too: a fault, a reason or a log line carries at most
:data:`MAX_TEXT_CHARS` characters of it (:func:`bound_text`), a name (a joint, a frame) at most
:data:`MAX_NAME_CHARS` (:func:`bound_names`), a robot description at most
:data:`MAX_DESCRIPTION_CHARS`, so that a megabyte string is neither copied into every state nor
logged whole.

Continuity limits between consecutive accepted samples ``dt`` apart: CoM speed 20 m/s, rate of
linear momentum 5e5 N, rate of angular momentum 2e5 N m. They are generous on purpose: over 60
trajectories of the simulated dataset the largest sample-to-sample values were 2.7 m/s, 4.3e4 N
and 1.2e4 N m (rigid ground impacts of falling robots), 7 to 16 times below the limits; a glitch
of the kind that matters (a CoM reported at the origin, a momentum of 1e300) is far beyond them
or beyond the bounds. A run of ``resync_samples``
consecutive rejections is taken as a real discontinuity (a robot lifted and put down
elsewhere): the check then accepts the current sample and starts over from it.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

#: Sample times [s] must lie in [0, MAX_SAMPLE_TIME_S].
MAX_SAMPLE_TIME_S = 1e7
#: |CoM x|, |CoM y| [m] at most this far from the world origin.
MAX_WORLD_COORDINATE_M = 1e4
#: CoM height range [m].
COM_HEIGHT_RANGE_M = (0.0, 2.0)
#: CoP, feet and contact points at most this far horizontally from the CoM [m].
MAX_HORIZONTAL_OFFSET_M = 2.0
#: z of the CoP and contact points [m].
CONTACT_HEIGHT_RANGE_M = (-0.5, 2.0)
#: Norm bounds of the momenta and forces.
MAX_LINEAR_MOMENTUM_KG_M_S = 2000.0
MAX_ANGULAR_MOMENTUM_KG_M2_S = 500.0
MAX_PUSH_FORCE_N = 1e5
MAX_CONTACT_FORCE_N = 1e5
MAX_ABS_HEADING_RAD = 1e3
#: Joint state bounds: |position| [rad], |velocity| [rad/s], |effort| [N m].
JOINT_VALUE_BOUNDS = {'position': 100.0, 'velocity': 1e3, 'effort': 1e5}
#: Feature bounds: rates of linear [N] and angular [N m] momentum.
MAX_LINEAR_MOMENTUM_RATE_N = 5e5
MAX_ANGULAR_MOMENTUM_RATE_N_M = 2e5
#: Continuity: fastest CoM motion [m/s] between accepted samples.
MAX_COM_SPEED_M_S = 20.0


#: Raw sensor bounds (see the second table): joint position margin beyond the joint's limits
#: [rad], joint velocity as a multiple of its limit and without one [rad/s], IMU, foot sensors.
JOINT_LIMIT_MARGIN_RAD = 0.5
JOINT_VELOCITY_LIMIT_FACTOR = 5.0
MAX_JOINT_VELOCITY_RAD_S = 1e3
#: A joint past its limits by more than this [rad], or faster than this x its velocity limit,
#: flags the sample (kept, counted, said in the diagnostics): encoder noise and a joint's give at
#: its stop stay below 0.05 rad (3 deg); the motors' rated speed is the velocity limit.
JOINT_FLAG_MARGIN_RAD = 0.05
JOINT_FLAG_VELOCITY_FACTOR = 1.0
JOINT_EFFORT_LIMIT_FACTOR = 3.0
MAX_JOINT_EFFORT_N_M = 1e4
MAX_IMU_ANGULAR_VELOCITY_RAD_S = 35.0
MAX_IMU_SPECIFIC_FORCE_M_S2 = 300.0
IMU_QUATERNION_NORM_TOLERANCE = 0.1
MAX_FOOT_FORCE_BODY_WEIGHTS = 20.0
FOOT_TORQUE_ARM_M = 0.5


#: Characters of wire text kept in a fault, a reason or a log line; of one name; of a URDF.
MAX_TEXT_CHARS = 500
MAX_NAME_CHARS = 100
MAX_DESCRIPTION_CHARS = 50_000_000
#: Names listed in one line (the rest counted).
MAX_NAMES_LISTED = 6


def bound_text(text: str, limit: int = MAX_TEXT_CHARS) -> str:
    """``text`` cut to ``limit`` characters, saying how long it was."""
    if len(text) <= limit:
        return text
    return f'{text[:limit]}... ({len(text)} characters, cut)'


def bound_names(names: Sequence[str], count: int = MAX_NAMES_LISTED) -> str:
    """The first ``count`` of ``names``, each bounded to :data:`MAX_NAME_CHARS`, joined, with how
    many more there are."""
    shown = ', '.join(bound_text(str(n), MAX_NAME_CHARS) for n in list(names)[:count])
    return shown + (f' and {len(names) - count} more' if len(names) > count else '')


class ImplausibleSample(ValueError):
    """A sample outside the physical bounds or continuity limits (the message says which)."""


def _floats(values: Sequence[float]) -> list[float]:
    """``values`` as a list of floats (a 1-D array's ``tolist``: iterating an array costs ten
    times as much, as each element becomes a numpy scalar first)."""
    if isinstance(values, np.ndarray) and values.ndim == 1:
        return values.astype(float, copy=False).tolist()
    return [float(v) for v in values]


def _norm3(v: Sequence[float]) -> float:
    # math.hypot does not overflow for finite inputs up to the float range.
    return math.hypot(float(v[0]), float(v[1]), float(v[2]))


def check_time(t: float, what: str = 'sample time') -> float:
    """``t`` as a float if it is finite and within [0, MAX_SAMPLE_TIME_S] s."""
    t = float(t)
    if not (0.0 <= t <= MAX_SAMPLE_TIME_S):
        raise ImplausibleSample(f'{what} {t!r} s is outside [0, {MAX_SAMPLE_TIME_S:g}] s')
    return t


def _check_norm(value: Sequence[float], limit: float, what: str, unit: str) -> None:
    norm = _norm3(value)
    if not norm <= limit:
        raise ImplausibleSample(f'|{what}| = {norm:.6g} {unit} exceeds {limit:g} {unit}')


def _check_point(point: Sequence[float], com: Sequence[float], what: str,
                 check_z: bool = True) -> None:
    offset = math.hypot(float(point[0]) - float(com[0]), float(point[1]) - float(com[1]))
    if not offset <= MAX_HORIZONTAL_OFFSET_M:
        raise ImplausibleSample(f'{what} is {offset:.6g} m from the CoM horizontally '
                                f'(at most {MAX_HORIZONTAL_OFFSET_M} m)')
    if check_z:
        low, high = CONTACT_HEIGHT_RANGE_M
        if not low <= float(point[2]) <= high:
            raise ImplausibleSample(f'{what} z = {float(point[2])!r} m is outside [{low}, {high}] m')


def check_measurement_bounds(t: Optional[float], com: Sequence[float], lin_mom: Sequence[float],
                             ang_mom: Sequence[float], heading: float, cop: Sequence[float],
                             left_foot: Sequence[float], right_foot: Sequence[float],
                             push_force: Sequence[float], contacts: np.ndarray) -> None:
    """Raise :class:`ImplausibleSample` naming the first field outside the bounds table.

    ``cop`` may be all NaN (no contact); ``contacts`` holds the (x, y, normal force) of each
    contact point of both feet: a (k, 3) array, or one flat list of floats (x, y, force, x, ...).
    Values are assumed finite (the wire layer checks that first). ``t`` None: the time is checked
    elsewhere (by the time rule of :mod:`~fall_predictor.monitor.timeline`).
    """
    if t is not None:
        check_time(t)
    flat = contacts if isinstance(contacts, list) else (
        np.asarray(contacts, dtype=np.float64).ravel().tolist())
    if _within_bounds(_floats(com), _floats(lin_mom), _floats(ang_mom), float(heading),
                      _floats(cop), _floats(left_foot), _floats(right_foot), _floats(push_force)):
        _check_contacts(flat, float(com[0]), float(com[1]))
        return
    # Outside: the checks one by one, to name the first field that is.
    if not (abs(float(com[0])) <= MAX_WORLD_COORDINATE_M
            and abs(float(com[1])) <= MAX_WORLD_COORDINATE_M):
        raise ImplausibleSample(f'CoM x, y = {float(com[0])!r}, {float(com[1])!r} m are more '
                                f'than {MAX_WORLD_COORDINATE_M:g} m from the origin')
    low, high = COM_HEIGHT_RANGE_M
    if not low <= float(com[2]) <= high:
        raise ImplausibleSample(f'CoM height {float(com[2])!r} m is outside [{low}, {high}] m')
    _check_norm(lin_mom, MAX_LINEAR_MOMENTUM_KG_M_S, 'linear momentum', 'kg m/s')
    _check_norm(ang_mom, MAX_ANGULAR_MOMENTUM_KG_M2_S, 'angular momentum', 'kg m^2/s')
    if not abs(float(heading)) <= MAX_ABS_HEADING_RAD:
        raise ImplausibleSample(f'heading {float(heading)!r} rad exceeds {MAX_ABS_HEADING_RAD:g}')
    if not math.isnan(float(cop[0])):
        _check_point(cop, com, 'CoP')
    _check_point(left_foot, com, 'left foot', check_z=False)
    _check_point(right_foot, com, 'right foot', check_z=False)
    _check_norm(push_force, MAX_PUSH_FORCE_N, 'push force', 'N')
    _check_contacts(flat, float(com[0]), float(com[1]))


def _within_bounds(com: list, lin_mom: list, ang_mom: list, heading: float, cop: list,
                   left_foot: list, right_foot: list, push_force: list) -> bool:
    """Whether every field but the contacts is within the bounds (floats; NaN fails each test,
    as in :func:`check_measurement_bounds`): one expression, no call per field."""
    hypot = math.hypot
    cx, cy, cz = com
    low, high = COM_HEIGHT_RANGE_M
    z_low, z_high = CONTACT_HEIGHT_RANGE_M
    return (abs(cx) <= MAX_WORLD_COORDINATE_M and abs(cy) <= MAX_WORLD_COORDINATE_M
            and low <= cz <= high
            and hypot(*lin_mom) <= MAX_LINEAR_MOMENTUM_KG_M_S
            and hypot(*ang_mom) <= MAX_ANGULAR_MOMENTUM_KG_M2_S
            and abs(heading) <= MAX_ABS_HEADING_RAD
            and (math.isnan(cop[0]) or (hypot(cop[0] - cx, cop[1] - cy) <= MAX_HORIZONTAL_OFFSET_M
                                        and z_low <= cop[2] <= z_high))
            and hypot(left_foot[0] - cx, left_foot[1] - cy) <= MAX_HORIZONTAL_OFFSET_M
            and hypot(right_foot[0] - cx, right_foot[1] - cy) <= MAX_HORIZONTAL_OFFSET_M
            and hypot(*push_force) <= MAX_PUSH_FORCE_N)


def _check_contacts(flat: list[float], com_x: float, com_y: float) -> None:
    """Contact rows (x, y, normal force) as one flat list of floats, against the bounds."""
    if len(flat) % 3:
        raise ImplausibleSample('contacts must be rows of (x, y, normal force), '
                                f'got {len(flat)} values')
    hypot = math.hypot
    for k in range(0, len(flat), 3):
        offset = hypot(flat[k] - com_x, flat[k + 1] - com_y)
        if not offset <= MAX_HORIZONTAL_OFFSET_M:
            raise ImplausibleSample(f'a contact point is {offset:.6g} m from the CoM horizontally '
                                    f'(at most {MAX_HORIZONTAL_OFFSET_M} m)')
        if not 0.0 <= flat[k + 2] <= MAX_CONTACT_FORCE_N:
            raise ImplausibleSample(f'contact normal forces must be in [0, {MAX_CONTACT_FORCE_N:g}]'
                                    f' N, got {flat[k + 2]:.6g}')


def check_measurement(m) -> None:
    """Raise :class:`ImplausibleSample` if a measurement (:class:`~fall_predictor.monitor.records.
    Measurement`) is not one a humanoid can be in: a value that should be finite is not (a CoP all
    finite or all NaN; contacts and the base orientation finite), or a field is outside the bounds
    table. The one check of a measurement wherever it comes from: the state estimator's output
    (:class:`~fall_predictor.monitor.sensor_pipeline.SensorPipeline`, live and offline alike), a
    decoded message, a measurement handed over in process."""
    # One list of floats for all fields: this check runs on every estimate, and numpy's cost
    # per call (~0.5 us) would be most of it.
    v = np.concatenate((m.com, m.lin_mom, m.ang_mom, m.left_foot, m.right_foot, m.push_force,
                        m.cop, np.ravel(m.left_contacts), np.ravel(m.right_contacts)),
                       dtype=np.float64).tolist()
    heading = float(m.heading)
    rotation = m.torso_rotation
    finite = math.isfinite
    # A sum is finite when every term is (or overflows for terms near the float range, which
    # the exact test below then tells apart): one test instead of one per value.
    if not finite(sum(v[:18]) + heading) and not all(map(finite, [*v[:18], heading])):
        raise ImplausibleSample('measurement has non-finite values (and no fault)')
    cop = v[18:21]
    if not (finite(cop[0]) and finite(cop[1]) and finite(cop[2])
            or math.isnan(cop[0]) and math.isnan(cop[1]) and math.isnan(cop[2])):
        raise ImplausibleSample(f'measurement.cop must be all finite or all NaN, got {cop}')
    contacts = v[21:]
    if not finite(sum(contacts)) and not all(map(finite, contacts)):
        raise ImplausibleSample('measurement contacts are not finite')
    if rotation is not None and not finite(sum(rotation.ravel().tolist())):
        if not np.isfinite(rotation).all():
            raise ImplausibleSample('measurement base orientation is not finite')
    com, lin, ang, left, right, push = v[0:3], v[3:6], v[6:9], v[9:12], v[12:15], v[15:18]
    if _within_bounds(com, lin, ang, heading, cop, left, right, push):
        _check_contacts(contacts, com[0], com[1])
    else:
        check_measurement_bounds(None, com, lin, ang, heading, cop, left, right, push, contacts)


def check_feature_bounds(t: Optional[float], x: Sequence[float]) -> None:
    """Raise :class:`ImplausibleSample` if a feature vector (method §6, CoP frame) is out of bounds.

    Same table as the measurements; the rates use the rate bounds of this module (``t`` None:
    not checked here).
    """
    if t is not None:
        check_time(t)
    if not math.hypot(float(x[0]), float(x[1])) <= MAX_HORIZONTAL_OFFSET_M:
        raise ImplausibleSample(f'CoM is {math.hypot(float(x[0]), float(x[1])):.6g} m from the '
                                f'CoP horizontally (at most {MAX_HORIZONTAL_OFFSET_M} m)')
    low, high = COM_HEIGHT_RANGE_M
    if not low <= float(x[2]) <= high:
        raise ImplausibleSample(f'CoM height {float(x[2])!r} m is outside [{low}, {high}] m')
    _check_norm(x[3:6], MAX_LINEAR_MOMENTUM_KG_M_S, 'linear momentum', 'kg m/s')
    _check_norm(x[6:9], MAX_ANGULAR_MOMENTUM_KG_M2_S, 'angular momentum', 'kg m^2/s')
    _check_norm(x[9:12], MAX_LINEAR_MOMENTUM_RATE_N, 'rate of linear momentum', 'N')
    _check_norm(x[12:15], MAX_ANGULAR_MOMENTUM_RATE_N_M, 'rate of angular momentum', 'N m')


@dataclass
class ContinuityCheck:
    """Rejects a sample that moved further than physics allows since the last accepted one.

    Args:
        resync_samples: after this many consecutive rejections the current sample is accepted
            and becomes the new reference (a real discontinuity, not a glitch).
    """

    resync_samples: int = 20
    max_com_speed_m_s: float = MAX_COM_SPEED_M_S
    max_linear_momentum_rate_n: float = MAX_LINEAR_MOMENTUM_RATE_N
    max_angular_momentum_rate_n_m: float = MAX_ANGULAR_MOMENTUM_RATE_N_M

    def __post_init__(self) -> None:
        if self.resync_samples < 1:
            raise ValueError(f'resync_samples must be >= 1, got {self.resync_samples}')
        self.reset()

    def reset(self) -> None:
        """Forget the reference sample (the next sample is accepted as is)."""
        self._last: tuple[float, tuple[float, ...]] | None = None
        self.rejected_in_a_row = 0
        self.resyncs = 0

    def check(self, t: float, com: Sequence[float], lin_mom: Sequence[float],
              ang_mom: Sequence[float]) -> bool:
        """Accept the sample (it becomes the reference) or raise :class:`ImplausibleSample`.

        ``t`` must be later than the reference's time (the caller checks the order). Returns
        True when the sample was accepted by a resynchronisation (the caller should drop any
        history built on the samples before the discontinuity).
        """
        values = (*map(float, com), *map(float, lin_mom), *map(float, ang_mom))
        if self._last is not None:
            t0, last = self._last
            dt = float(t) - t0
            problem = None
            if dt > 0.0:
                com_step = math.hypot(values[0] - last[0], values[1] - last[1], values[2] - last[2])
                p_step = math.hypot(values[3] - last[3], values[4] - last[4], values[5] - last[5])
                l_step = math.hypot(values[6] - last[6], values[7] - last[7], values[8] - last[8])
                if not com_step <= self.max_com_speed_m_s * dt:
                    problem = f'the CoM moved {com_step:.6g} m in {dt:.6g} s'
                elif not p_step <= self.max_linear_momentum_rate_n * dt:
                    problem = f'linear momentum changed by {p_step:.6g} kg m/s in {dt:.6g} s'
                elif not l_step <= self.max_angular_momentum_rate_n_m * dt:
                    problem = f'angular momentum changed by {l_step:.6g} kg m^2/s in {dt:.6g} s'
            if problem is not None:
                self.rejected_in_a_row += 1
                if self.rejected_in_a_row < self.resync_samples:
                    raise ImplausibleSample(f'jump: {problem} (faster than physics allows)')
                self.resyncs += 1
        resynced = self.rejected_in_a_row > 0
        self.rejected_in_a_row = 0
        self._last = (float(t), values)
        return resynced


def check_imu(orientation_xyzw: Sequence[float], angular_velocity: Sequence[float],
              linear_acceleration: Sequence[float]) -> Optional[str]:
    """Why an IMU reading is impossible (non-finite or beyond the sensor bounds), or None."""
    q, w, a = _floats(orientation_xyzw), _floats(angular_velocity), _floats(linear_acceleration)
    if len(q) != 4 or len(w) != 3 or len(a) != 3:
        return f'IMU reading has {len(q)}/{len(w)}/{len(a)} values instead of 4/3/3'
    if not all(map(math.isfinite, q + w + a)):
        return 'IMU reading is not finite'
    norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    if not abs(norm - 1.0) <= IMU_QUATERNION_NORM_TOLERANCE:
        return f'IMU orientation is not a unit quaternion (norm {norm:.3g})'
    if not _norm3(w) <= MAX_IMU_ANGULAR_VELOCITY_RAD_S:
        return (f'IMU angular velocity {_norm3(w):.4g} rad/s beyond '
                f'{MAX_IMU_ANGULAR_VELOCITY_RAD_S:g} rad/s')
    if not _norm3(a) <= MAX_IMU_SPECIFIC_FORCE_M_S2:
        return (f'IMU acceleration {_norm3(a):.4g} m/s^2 beyond {MAX_IMU_SPECIFIC_FORCE_M_S2:g} m/s^2')
    return None


def check_wrench(wrench: Sequence[float], robot_weight_n: float) -> Optional[str]:
    """Why a foot force/torque reading is impossible for a robot of ``robot_weight_n``, or None."""
    w = _floats(wrench)
    if len(w) != 6 or not all(map(math.isfinite, w)):
        return 'foot wrench is not 6 finite values'
    max_force = MAX_FOOT_FORCE_BODY_WEIGHTS * robot_weight_n
    if not _norm3(w[:3]) <= max_force:
        return f'foot force {_norm3(w[:3]):.4g} N beyond {max_force:.4g} N (20 body weights)'
    if not _norm3(w[3:]) <= max_force * FOOT_TORQUE_ARM_M:
        return f'foot torque {_norm3(w[3:]):.4g} N m beyond {max_force * FOOT_TORQUE_ARM_M:.4g} N m'
    return None


@dataclass(frozen=True)
class JointBounds:
    """Per-joint limits of the encoders (arrays in one joint order): the URDF's, or the robot
    profile's where it states them (:meth:`with_limits`).

    ``lower``/``upper`` are the position limits [rad] (-inf/+inf for continuous joints), ``velocity``
    the velocity limits [rad/s] and ``effort`` the effort limits [N m or N] (inf where none is
    given; ``effort`` None: none for every joint). A reading past them is flagged
    (:meth:`exceedances`), refused only when impossible (:meth:`violations`): the module docstring.
    """

    names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    effort: Optional[np.ndarray] = None

    def with_limits(self, limits: dict[str, dict[str, float]]) -> 'JointBounds':
        """These bounds with a robot's own limits of some joints: per joint name, any of
        ``lower_rad``, ``upper_rad``, ``velocity_rad_s``. ValueError names a joint these bounds
        lack or limits out of order."""
        index = {name: i for i, name in enumerate(self.names)}
        lower, upper, velocity = self.lower.copy(), self.upper.copy(), self.velocity.copy()
        for name, given in limits.items():
            if name not in index:
                raise ValueError(f'joint_limits names joint {name!r}, which the robot description '
                                 f'lacks (it has {bound_names(self.names)})')
            i = index[name]
            lower[i] = given.get('lower_rad', lower[i])
            upper[i] = given.get('upper_rad', upper[i])
            velocity[i] = given.get('velocity_rad_s', velocity[i])
            if not lower[i] <= upper[i] or not velocity[i] > 0.0:
                raise ValueError(f'joint_limits.{name}: lower_rad must be <= upper_rad and '
                                 f'velocity_rad_s > 0, got {lower[i]}, {upper[i]}, {velocity[i]}')
        return JointBounds(self.names, lower, upper, velocity, self.effort)

    @functools.cached_property
    def max_effort(self) -> np.ndarray:
        """The largest effort accepted per joint [N m or N]."""
        if self.effort is None:
            return np.full(len(self.names), MAX_JOINT_EFFORT_N_M)
        return np.where(np.isfinite(self.effort), JOINT_EFFORT_LIMIT_FACTOR * self.effort,
                        MAX_JOINT_EFFORT_N_M)

    def _tier(self, margin_rad: float, factor: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(lowest, highest position [rad], highest speed [rad/s]) of one tier, per joint."""
        v_max = np.where(np.isfinite(self.velocity), factor * self.velocity, MAX_JOINT_VELOCITY_RAD_S)
        return self.lower - margin_rad, self.upper + margin_rad, v_max

    @functools.cached_property
    def _limits(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The bounds of the possible (:meth:`violations`)."""
        return self._tier(JOINT_LIMIT_MARGIN_RAD, JOINT_VELOCITY_LIMIT_FACTOR)

    @functools.cached_property
    def _flag_limits(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The limits past which a reading is flagged (:meth:`exceedances`)."""
        return self._tier(JOINT_FLAG_MARGIN_RAD, JOINT_FLAG_VELOCITY_FACTOR)

    def violations(self, q: np.ndarray, dq: np.ndarray) -> list[str]:
        """Each joint whose position or velocity is impossible, in words (empty: all possible)."""
        return self._outside(self._limits, q, dq, 'impossible: ')

    def exceedances(self, q: np.ndarray, dq: np.ndarray) -> list[str]:
        """Each joint past its limits or speed but within the possible, in words (empty: none)."""
        return self._outside(self._flag_limits, q, dq, '')

    def _outside(self, tier: tuple, q: np.ndarray, dq: np.ndarray, prefix: str) -> list[str]:
        low, high, v_max = tier
        # Comparisons with NaN are False (no floating-point warning): NaN counts as outside.
        bad_q = ~((q >= low) & (q <= high))
        bad_v = ~(np.abs(dq) <= v_max)
        bad = bad_q | bad_v
        if not np.count_nonzero(bad):
            return []
        out = []
        for i in np.flatnonzero(bad):
            name = self.names[i]
            if bad_q[i]:
                out.append(f'{prefix}joint {name} at {q[i]:.4g} rad, outside its limits '
                           f'[{self.lower[i]:.3g}, {self.upper[i]:.3g}] rad by more than '
                           f'{high[i] - self.upper[i]:.3g} rad')
            else:
                out.append(f'{prefix}joint {name} moving at {dq[i]:.4g} rad/s, beyond '
                           f'{v_max[i]:.3g} rad/s')
        return out
