"""Unitree's humanoid low-level state as the monitor's sensor records (method §12, "A Unitree
humanoid's own topic").

A Unitree G1 publishes no ``joint_states``, ``imu/data`` or stamps: through unitree_ros2 it
publishes ``lowstate`` (``unitree_hg/msg/LowState``) at 500 Hz: ``motor_state[35]`` indexed by
motor (``q``, ``dq``, ``tau_est``, a status word), the pelvis IMU's ``imu_state`` (quaternion
w-x-y-z, gyroscope, accelerometer), ``tick`` (a millisecond counter), ``mode_pr`` (ankles as
pitch/roll or as motors A/B) and ``mode_machine`` (which G1 variant). :class:`LowStateConverter`
turns each :class:`LowStateRecord` into what the monitor reads from any other robot, a
:class:`~fall_predictor.monitor.sensor_records.JointStateReading` and an
:class:`~fall_predictor.monitor.sensor_records.ImuReading` at one stamp
(:class:`LowStateSample`), which :meth:`~fall_predictor.monitor.sensor_pipeline.SensorPipeline.lowstate`
takes: the same sync, time rule, plausibility bounds and estimator as every input. The robot's
facts (the motor table of each variant, the IMU frame, the joints a policy holds) come from the
robot profile's ``unitree_hg`` section (:class:`LowStateProfile`).

**Stamps.** Each sample is stamped on the receiver's clock, its spacing taken from ``tick``:
``stamp = tick_ns + offset``, where ``offset`` is the least ``receive - tick`` seen so far (the
least-delayed message), allowed to grow by ``drift_ppm`` of the elapsed tick time (the two clocks
drift) and to shrink by at most half a tick step per message (so stamps always advance by at least
half the tick's own step). Receive-time jitter therefore never reaches the spacing, and a lost
message leaves a gap of its ticks, which the time rule counts as missing samples. On the tick:

* **wrap** (``2^32 - 1`` ms to ``0``, after 49.7 days): the counter is read modulo ``2^32``, so
  the spacing is exact across it; said once in words, never a fault;
* **gap** (ticks missing): the stamps keep the gap; the time rule counts the missing samples, and
  a gap longer than its ``max_step_s`` starts a new run (a pause), as for any stream;
* **repeated tick, same readings**: the same message delivered twice: dropped, counted;
* **repeated tick, new readings**: the robot's counter stalled: the sample is stamped one tick
  step on and is a fault (DEGRADED, named): its spacing is a guess;
* **tick back** (not a wrap: the robot's low-level board restarted, or another robot publishes):
  the stamps continue from the receive time; that sample is a fault (DEGRADED, named).

**Faults** (each a DEGRADED state in words, never a fall): a ``mode_machine`` the profile does not
describe (its motors would be named wrong), ankles reported as motors A/B (``mode_pr`` 1), a
motor of the table whose status word has an error bit (``motor_error_mask``), and, through the
IMU bounds, a zero quaternion. Joints a policy holds (the waist and arms under Unitree's 12-joint
policy) far from their targets are a warning, not a fault: the estimate is right, the model was
trained with them held.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Optional, Sequence

import numpy as np

from fall_predictor.monitor.plausibility import check_imu
from fall_predictor.monitor.sensor_records import ImuReading, JointStateReading

#: Motor slots of ``LowState.motor_state``.
MOTOR_SLOTS = 35
#: ``tick`` is a uint32 millisecond counter.
TICK_MODULUS = 1 << 32
TICK_NS = 1_000_000
#: ``mode_pr`` of ankles reported as pitch and roll joints (1: as the two motors A and B).
MODE_PR_PITCH_ROLL = 0


@dataclass(slots=True)
class LowStateRecord:
    """The fields of one ``unitree_hg/msg/LowState`` the monitor reads (arrays: one value per
    motor slot, 35)."""

    tick: int                        #: [ms], uint32
    mode_machine: int
    mode_pr: int
    imu_quat_wxyz: np.ndarray        #: (4,) w, x, y, z: the IMU's attitude in the world
    gyro_rad_s: np.ndarray           #: (3,) in the IMU frame
    accel_m_s2: np.ndarray           #: (3,) specific force in the IMU frame (+g up at rest)
    q: np.ndarray                    #: (35,) [rad]
    dq: np.ndarray                   #: (35,) [rad/s]
    tau_est: np.ndarray              #: (35,) [N m]
    motor_status: np.ndarray         #: (35,) uint32 status words (``motorstate``)


@dataclass(frozen=True)
class LowStateVariant:
    """One robot variant (one ``mode_machine``): the joint of each motor slot ('' for a slot the
    variant does not use) and the description's joints it lacks, held rigid at an angle."""

    mode_machine: int
    name: str                                        #: Unitree's name of the variant's model
    motors: tuple[str, ...]
    fixed_joints: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if len(self.motors) > MOTOR_SLOTS:
            raise ValueError(f'variant {self.name}: {len(self.motors)} motors, LowState has {MOTOR_SLOTS}')
        named = [m for m in self.motors if m]
        if len(set(named)) != len(named) or set(named) & set(self.fixed_joints):
            raise ValueError(f'variant {self.name}: a joint named twice')


@dataclass(frozen=True)
class LowStateProfile:
    """A robot profile's ``unitree_hg`` section."""

    variants: dict[int, LowStateVariant]
    #: Joints a controller holds at a target [rad] (Unitree's 12-joint policy: waist and arms).
    held_joints: dict[str, float] = field(default_factory=dict)
    held_tolerance_rad: float = 0.2
    #: Bits of a motor's status word that report an error.
    motor_error_mask: int = 0xFFFFFFFF

    def __post_init__(self) -> None:
        if not self.variants:
            raise ValueError('unitree_hg: no variant')
        if not 0.0 < self.held_tolerance_rad < 3.2:
            raise ValueError(f'held_tolerance_rad must be in (0, 3.2), got {self.held_tolerance_rad}')

    def describe(self) -> str:
        return ', '.join(f'{m} ({v.name})' for m, v in sorted(self.variants.items()))


@dataclass(frozen=True)
class LowStateConfig:
    """How ticks become stamps (module docstring)."""

    #: How fast the robot's tick clock may run slow against the receiver's [ppm].
    drift_ppm: float = 200.0


@dataclass(slots=True)
class LowStateSample:
    """One LowState as the sensor pipeline takes it: the joints and the IMU at ``stamp_ns``, or
    the fault that makes it unusable (then the readings may be None); a warning in words."""

    stamp_ns: int
    joints: Optional[JointStateReading]
    imu: Optional[ImuReading]
    fault: str = ''
    warning: str = ''


class LowStateConverter:
    """LowState records (with their receive time) -> :class:`LowStateSample` s (module docstring).

    ``profile``: the robot profile's section; ``imu_frame``: the IMU's link (the profile's);
    ``robot_joints``: the description's joints (others of the table are left out; empty: all);
    ``topic``: the resolved topic name, for the words; ``profile_name``: for the words.
    """

    def __init__(self, profile: LowStateProfile, imu_frame: str,
                 robot_joints: Sequence[str] = (), topic: str = '/lowstate',
                 profile_name: str = 'the robot profile',
                 config: LowStateConfig = LowStateConfig()) -> None:
        self.profile = profile
        self.imu_frame = imu_frame
        self.topic = topic
        self.profile_name = profile_name
        self.config = config
        self._robot_joints = frozenset(robot_joints)
        self._layouts: dict[int, tuple] = {}
        self._variant_seen: Optional[int] = None
        self._notices: list[str] = []
        self.counts = {'lowstate_messages': 0, 'duplicate_messages': 0, 'repeated_ticks': 0,
                       'tick_restarts': 0, 'tick_wraps': 0, 'motor_faults': 0,
                       'mode_machine_mismatches': 0, 'held_joint_warnings': 0}
        self.reset()

    def reset(self) -> None:
        """Forget the tick history: the next message anchors the stamps on its receive time."""
        self._last: Optional[LowStateRecord] = None
        self._tick_ns = 0               # unwrapped tick time of the last message [ns]
        self._offset_ns = 0
        self._step_ns = TICK_NS         # the last tick step [ns]
        self._stamp_ns = 0
        self._receive_ns = 0

    def take_notices(self) -> list[str]:
        """What happened to the tick since the last call, in words, each once (for a log line)."""
        out, self._notices = self._notices, []
        return out

    # -- stamps -----------------------------------------------------------------------------
    def _stamp(self, record: LowStateRecord, receive_ns: int) -> tuple[Optional[int], str]:
        """(stamp [ns], fault) of a message; stamp None for a duplicate delivery."""
        last = self._last
        if last is None:
            self._tick_ns, self._offset_ns = 0, receive_ns
            return self._advance(receive_ns, receive_ns), ''
        ticks = (record.tick - last.tick) % TICK_MODULUS
        fault = ''
        if ticks == 0:
            if (np.array_equal(record.q, last.q) and np.array_equal(record.imu_quat_wxyz, last.imu_quat_wxyz)):
                self.counts['duplicate_messages'] += 1
                return None, ''
            self.counts['repeated_ticks'] += 1
            self._tick_ns += self._step_ns
            fault = (f'{self.topic} tick {record.tick} repeated with new readings: the robot\'s '
                     f'tick counter stalled, this sample\'s spacing is unknown')
        elif ticks >= TICK_MODULUS // 2:
            self.counts['tick_restarts'] += 1
            elapsed_ns = max(receive_ns - self._receive_ns, TICK_NS)
            self._tick_ns += elapsed_ns
            self._offset_ns = self._stamp_ns + elapsed_ns - self._tick_ns
            fault = (f'{self.topic} tick went back from {last.tick} to {record.tick} ms (not a wrap): '
                     'the robot\'s low-level board restarted, or another robot publishes; stamps go '
                     'on from the receive time')
            self._notices.append(fault)
            return self._advance(self._stamp_ns + elapsed_ns, receive_ns), fault
        else:
            if record.tick < last.tick:
                self.counts['tick_wraps'] += 1
                self._notices.append(f'{self.topic} tick wrapped from {last.tick} to {record.tick} '
                                     'ms (a 32-bit millisecond counter, every 49.7 days): counted on '
                                     'across it, the spacing kept')
            self._step_ns = ticks * TICK_NS
            self._tick_ns += self._step_ns
        # The least receive delay seen, free to grow with the clocks' drift, never shrinking by
        # more than half a tick step at once (module docstring).
        step = self._step_ns
        drifted = self._offset_ns + round(step * self.config.drift_ppm * 1e-6)
        floor = self._offset_ns - step // 2
        self._offset_ns = max(min(drifted, receive_ns - self._tick_ns), floor)
        return self._advance(self._tick_ns + self._offset_ns, receive_ns), fault

    def _advance(self, stamp_ns: int, receive_ns: int) -> int:
        self._stamp_ns, self._receive_ns = stamp_ns, receive_ns
        return stamp_ns

    # -- readings ---------------------------------------------------------------------------
    def _layout(self, variant: LowStateVariant) -> tuple:
        """(slots, names) of the variant's motors the description has, then its fixed joints."""
        cached = self._layouts.get(variant.mode_machine)
        if cached is None:
            keep = self._robot_joints
            used = [(k, n) for k, n in enumerate(variant.motors) if n and (not keep or n in keep)]
            fixed = [(n, a) for n, a in variant.fixed_joints.items() if not keep or n in keep]
            held_at = [(k, n) for k, n in enumerate(variant.motors) if n in self.profile.held_joints]
            held = (np.array([k for k, _ in held_at], dtype=np.int64), tuple(n for _, n in held_at),
                    np.array([self.profile.held_joints[n] for _, n in held_at]))
            cached = (np.array([k for k, _ in used], dtype=np.int64), tuple(n for _, n in used),
                      tuple(n for n, _ in fixed), np.array([a for _, a in fixed], dtype=float), held)
            self._layouts[variant.mode_machine] = cached
        return cached

    def convert(self, record: LowStateRecord, receive_ns: int) -> Optional[LowStateSample]:
        """The sample of one message received at ``receive_ns`` (the receiver's clock), or None
        for the same message delivered twice."""
        self.counts['lowstate_messages'] += 1
        stamp_ns, fault = self._stamp(record, receive_ns)
        if stamp_ns is None:
            return None
        self._last = record
        variant = self.profile.variants.get(int(record.mode_machine))
        if variant is None:
            self.counts['mode_machine_mismatches'] += 1
            return LowStateSample(stamp_ns, None, None, _join(fault, (
                f'{self.topic} says mode_machine {record.mode_machine}, but {self.profile_name} '
                f'describes {self.profile.describe()}: its motors would be named wrong; start the '
                'monitor with the profile of this robot\'s variant')))
        if variant.mode_machine != self._variant_seen:
            self._variant_seen = variant.mode_machine
            named = sum(1 for m in variant.motors if m)
            self._notices.append(f'{self.topic}: mode_machine {variant.mode_machine} '
                                 f'({variant.name}), {named} motors named by {self.profile_name}')
        if record.mode_pr != MODE_PR_PITCH_ROLL:
            return LowStateSample(stamp_ns, None, None, _join(fault, (
                f'{self.topic} reports the ankles as motors A/B (mode_pr {record.mode_pr}), not as '
                'pitch and roll joints: the monitor reads them in pitch/roll mode (mode_pr 0)')))
        slots, names, fixed_names, fixed_q, held = self._layout(variant)
        status = np.asarray(record.motor_status)[slots].astype(np.int64) & self.profile.motor_error_mask
        good = status == 0
        if not good.all():
            self.counts['motor_faults'] += 1
            bad = [f'motor {slots[i]} ({names[i]}) status 0x{int(status[i]):x}'
                   for i in np.flatnonzero(~good)[:3]]
            fault = _join(fault, f'{self.topic}: error bits in {", ".join(bad)}: its readings are '
                                 'not used')
            slots, names = slots[good], tuple(n for n, g in zip(names, good) if g)
        n_fixed = len(fixed_names)
        joints = JointStateReading(
            stamp_ns, names + fixed_names,
            np.concatenate([np.asarray(record.q, dtype=float)[slots], fixed_q]),
            np.concatenate([np.asarray(record.dq, dtype=float)[slots], np.zeros(n_fixed)]),
            np.concatenate([np.asarray(record.tau_est, dtype=float)[slots], np.zeros(n_fixed)]))
        w, x, y, z = (float(c) for c in record.imu_quat_wxyz)
        imu: Optional[ImuReading] = ImuReading(
            stamp_ns, self.imu_frame, np.array([x, y, z, w]),
            np.asarray(record.gyro_rad_s, dtype=float), np.asarray(record.accel_m_s2, dtype=float))
        # The IMU comes in the same message as the joints: a reading out of its bounds is this
        # sample's fault (not bridged from its neighbours as a separate stream's would be).
        refused = check_imu(imu.orientation_xyzw, imu.angular_velocity, imu.linear_acceleration)
        if refused is not None:
            imu, fault = None, _join(fault, f'{self.topic} imu_state refused: {refused}')
        return LowStateSample(stamp_ns, joints, imu, fault, self._held_warning(record, held))

    def _held_warning(self, record: LowStateRecord, held: tuple) -> str:
        slots, names, targets = held
        if not len(slots):
            return ''
        q = np.asarray(record.q, dtype=float)[slots]
        off = np.abs(q - targets)
        tolerance = self.profile.held_tolerance_rad
        if not (off > tolerance).any():
            return ''
        self.counts['held_joint_warnings'] += 1
        worst = [i for i in np.argsort(-off)[:3] if off[i] > tolerance]
        listed = ', '.join(f'{names[i]} at {q[i]:.2f} rad (held at {targets[i]:.2f})' for i in worst)
        return (f'{int((off > tolerance).sum())} held joints more than {tolerance:g} rad off their '
                f'targets: {listed}; the model of {self.profile_name} was trained with them held')


def _join(*faults: str) -> str:
    return '; '.join(f for f in faults if f)


# -- the profile's section ---------------------------------------------------------------------
#: A robot profile's ``unitree_hg`` section (``profiles/g1/profile.yaml`` has one)::
#:
#:     unitree_hg:
#:       variants:                   # one per mode_machine the profile describes
#:         - mode_machine: 5
#:           name: g1_29dof_rev_1_0  # Unitree's name of the variant's model
#:           motors: [left_hip_pitch_joint, ...]   # the joint of each motor slot, '' for none
#:           fixed_joints: {}        # the description's joints the variant lacks, rigid [rad]
#:       held_joints: {waist_yaw_joint: 0.0, ...}  # joints the controller holds, at their targets
#:       held_tolerance_rad: 0.2     # a held joint further off is a warning
#:       motor_error_mask: 0xFFFFFFFF  # the bits of a motor's status word that are errors
_KEYS = {'variants', 'held_joints', 'held_tolerance_rad', 'motor_error_mask'}


def _angles(path, where: str, raw: Any) -> dict[str, float]:
    if raw is None:
        return {}
    if not isinstance(raw, dict) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in raw.values()):
        raise ValueError(f'{path}: {where} must map joint names to angles [rad]')
    return {str(k): float(v) for k, v in raw.items()}


def parse_unitree_hg(path, raw: Any) -> Optional[LowStateProfile]:
    """The ``unitree_hg`` section of profile ``path`` (None when absent; ValueError naming the
    key when wrong)."""
    if raw is None:
        return None
    if not isinstance(raw, dict) or set(raw) - _KEYS:
        raise ValueError(f'{path}: unitree_hg takes {sorted(_KEYS)}')
    variants = {}
    for k, v in enumerate(raw.get('variants') or []):
        where = f'unitree_hg.variants[{k}]'
        if not isinstance(v, dict) or set(v) - {'mode_machine', 'name', 'motors', 'fixed_joints'}:
            raise ValueError(f'{path}: {where} takes mode_machine, name, motors, fixed_joints')
        motors = v.get('motors')
        if (not isinstance(v.get('mode_machine'), int) or not isinstance(v.get('name'), str)
                or not isinstance(motors, list) or not all(isinstance(m, str) for m in motors)):
            raise ValueError(f'{path}: {where} needs mode_machine (an integer), name and motors '
                             '(the joint name of each motor slot)')
        variants[v['mode_machine']] = LowStateVariant(
            v['mode_machine'], v['name'], tuple(motors),
            _angles(path, f'{where}.fixed_joints', v.get('fixed_joints')))
    mask = raw.get('motor_error_mask', 0xFFFFFFFF)
    if not isinstance(mask, int) or not 0 <= mask < (1 << 32):
        raise ValueError(f'{path}: unitree_hg.motor_error_mask must be a 32-bit integer')
    tolerance = raw.get('held_tolerance_rad', 0.2)
    if isinstance(tolerance, bool) or not isinstance(tolerance, (int, float)):
        raise ValueError(f'{path}: unitree_hg.held_tolerance_rad must be a number [rad]')
    return LowStateProfile(variants, _angles(path, 'unitree_hg.held_joints', raw.get('held_joints')),
                           float(tolerance), mask)
