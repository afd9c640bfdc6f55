"""State estimator: the monitor's :class:`Measurement` from the robot's own sensors (method §10).

ROS-free (numpy + Pinocchio). From the robot description (:class:`RobotDescription`: the URDF with
the sole frames) and one synchronised sample of joint encoders, IMU and foot force/torque sensors
(:class:`~fall_predictor.monitor.sensor_records.SensorSample`) it estimates:

* **base orientation**: the IMU may sit on any link (the sample's ``imu_frame``, resolved in the
  description; empty: the description's default IMU frame); its attitude and angular velocity are
  carried to the floating base through the leg and torso kinematics. The base's angular velocity
  is integrated and pulled towards the IMU's attitude output with time constant
  ``attitude_time_constant_s`` (a complementary filter: the attitude output's white noise is
  averaged out, its bias is not; every time constant is in seconds, so the filter behaves the same
  at any sample rate: a sample ``dt`` apart corrects by ``1 - exp(-dt / tau)``); yaw
  relative to the first sample plus ``initial_yaw_rad`` (the world frame is the frame the robot
  started in, its origin at ``initial_xy_m`` on the loaded soles' centres at the first sample with a
  loaded sole);
* **the IMU point's position and velocity**: the accelerometer measures the specific force of the
  IMU point, so the filter runs on that point: it integrates the accelerometer and corrects with
  the force-weighted kinematic position and velocity of the point (time constants
  ``position_time_constant_s``, ``velocity_time_constant_s``) from the soles on the ground: the part of each loaded sole on the ground (its
  corners within ``tilt_tolerance_m`` of the lowest: the whole sole, an edge or a corner) is
  anchored where it touched down (z = 0), re-anchored when that part changes; a still contact moves
  the IMU point by minus the contact's velocity relative to it. With no loaded sole it integrates
  the IMU alone. A sole whose kinematic velocity is more than ``slip_velocity_m_s`` from the IMU
  prediction is taken as slipping: left out and re-anchored (if all slip for
  ``max_slip_s``, the closest is used). The base follows from the point by kinematics;
* **CoM and centroidal momentum**: ``pinocchio.computeCentroidalMomentum`` (linear momentum,
  angular momentum about the CoM);
* **contacts and CoP**: a sole with normal force above ``contact_force_n`` is loaded (a foot without
  a force sensor, one of ``effort_feet``: its wrench from the leg's joint efforts, or with no
  efforts from statics, :mod:`~fall_predictor.monitor.effort_wrench`); each foot's
  wrench is taken in its sensor's frame (the sample's ``wrench_frames``; empty: the sole frame) and
  carried to the sole frame, where the CoP is (-ty / fz, tx / fz); the whole-body CoP is the
  force-weighted mean. The contacts handed to the feature code are the sole's corners that lie
  within ``tilt_tolerance_m`` of its lowest corner, with the normal force split between them so
  that their weighted mean is the sole's CoP (bilinear on a flat sole, linear along an edge).

What the sensors cannot tell: ``non_foot_contact`` is always False (no skin sensors; a fall is
then seen from the CoM height alone) and ``push_force`` is zero.

Bad input never raises from :meth:`StateEstimator.update`: a sample with missing joints, NaN joints
or IMU, a frame the description lacks, a time not after the previous one, or a foot wrench missing
where the robot has that sensor is rejected (``None`` returned, the reason in
:attr:`StateEstimator.last_issue`); a time more than ``max_gap_s`` after the previous re-anchors the
soles; so is every sample before the first loaded sole (the base position is unknown until a sole
anchors it). A URDF without the sole frames, or one the estimator cannot model, raises
:class:`~fall_predictor.monitor.robot_description.DescriptionError` at construction.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np
import pinocchio as pin

from fall_predictor.monitor.effort_wrench import EffortWrench
from fall_predictor.monitor.geometry import cross3
from fall_predictor.monitor.records import STANDARD_GRAVITY_M_S2, Measurement
from fall_predictor.monitor.robot_description import SIDES, DescriptionError, RobotDescription
from fall_predictor.monitor.sensor_records import SensorSample

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_GRAVITY = np.array([0.0, 0.0, STANDARD_GRAVITY_M_S2])
_NO_CONTACT = np.zeros((0, 3))
_ZEROS6 = np.zeros(6)


@dataclass(frozen=True)
class EstimatorConfig:
    contact_force_n: float = 10.0
    attitude_time_constant_s: float = 0.05
    position_time_constant_s: float = 0.02
    velocity_time_constant_s: float = 0.02
    tilt_tolerance_m: float = 0.002
    #: A sole whose kinematic velocity is this far from the IMU prediction slips [m/s].
    slip_velocity_m_s: float = 0.25
    #: After every loaded sole has slipped for this long [s], the closest one is trusted.
    max_slip_s: float = 0.02
    max_gap_s: float = 0.05
    #: Without foot F/T sensors or efforts: soles this close to the lowest are on the ground [m].
    kinematic_contact_height_m: float = 0.003
    #: Feet whose wrench comes from joint efforts: a sole higher than this above the lowest is in
    #: the air whatever its effort-derived force (a swinging leg's inertia reads as up to ~40 N).
    effort_contact_height_m: float = 0.015
    initial_yaw_rad: float = 0.0
    #: World xy of the loaded soles' midpoint at the first sample [m].
    initial_xy_m: tuple[float, float] = (0.0, 0.0)


def _rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _yaw(rot: np.ndarray) -> float:
    return math.atan2(rot[1, 0], rot[0, 0])


def split_force_to_corners(corners: np.ndarray, cop: np.ndarray, fz: float) -> np.ndarray:
    """Normal force ``fz`` split over contact ``corners`` (k, 2) of one sole, in its frame,
    so that the force-weighted mean is ``cop`` (clipped to the corners' hull); (k,) forces."""
    k = len(corners)
    if k == 1:
        return np.array([fz])
    if k == 2:
        a, b = corners
        d = b - a
        s = float(np.clip((cop - a) @ d / max(d @ d, 1e-12), 0.0, 1.0))
        return fz * np.array([1.0 - s, s])
    if k == 4:
        lo, hi = corners.min(axis=0), corners.max(axis=0)
        u = np.clip((cop - lo) / np.maximum(hi - lo, 1e-12), 0.0, 1.0)
        wx = np.where(corners[:, 0] > (lo[0] + hi[0]) / 2, u[0], 1.0 - u[0])
        wy = np.where(corners[:, 1] > (lo[1] + hi[1]) / 2, u[1], 1.0 - u[1])
        return fz * wx * wy
    return np.full(k, fz / k)


@dataclass(frozen=True)
class _GroundPart:
    """The corners of a sole on the ground (all four, an edge or one corner), sole frame."""

    key: bytes                      #: which corners (the boolean mask's bytes)
    centre: np.ndarray              #: their centre (3,)
    corners: np.ndarray             #: (k, 3)
    flat: bool                      #: all four: the sole lies flat


@dataclass
class _Kinematics:
    """One sample's kinematics relative to the floating base's origin: the base at the origin with
    the estimated orientation, not translating, turning at the estimated rate; world axes."""

    q: np.ndarray                   #: full configuration (base at the origin, estimated attitude)
    v: np.ndarray                   #: full velocity (base: not translating, turning at omega_b)
    rot: np.ndarray                 #: estimated base orientation in the world
    omega_b: np.ndarray             #: base angular velocity, base frame [rad/s]
    sole_pos: dict                  #: per side: sole origin relative to the base origin
    sole_rot: dict                  #: per side: sole orientation in the world
    sole_vel: dict                  #: per side: (linear velocity of the sole origin, angular velocity)
    imu_pos: np.ndarray             #: IMU point relative to the base origin
    imu_vel: np.ndarray             #: IMU point velocity relative to the base origin
    imu_rot: np.ndarray             #: IMU frame orientation in the world
    com: np.ndarray                 #: CoM relative to the base origin
    lin_mom: np.ndarray             #: linear momentum of the base-fixed motion [kg m/s]
    ang_mom: np.ndarray             #: angular momentum about the CoM [kg m^2/s]


class StateEstimator:
    """Streams :class:`SensorSample` in, :class:`Measurement` out (see the module docstring)."""

    def __init__(self, robot: RobotDescription, config: EstimatorConfig = EstimatorConfig(),
                 imu_frame: str = '', effort_feet: tuple[str, ...] = ()) -> None:
        self.robot = robot
        #: Feet without a force sensor: their wrench from the joint efforts (monitor.effort_wrench).
        self.effort_feet = tuple(effort_feet)
        self._effort = EffortWrench(robot) if self.effort_feet else None
        #: Where the last sample's effort-less feet took their wrench from: 'efforts', 'statics'.
        self.wrench_source = 'sensors'
        self.config = config
        self.model, self.data = robot.model, robot.data
        #: The IMU frame of samples that do not name one (the robot profile's IMU link).
        self.imu_frame = imu_frame
        self.total_mass_kg = robot.total_mass_kg
        self.sole_corners = {side: robot.soles[side].corners() for side in SIDES}
        self._half_sole = {side: (robot.soles[side].length_m / 2, robot.soles[side].width_m / 2)
                           for side in SIDES}
        #: Per IMU frame id: (its rotation in the base frame, whether that is the identity) if
        #: it is fixed to the floating base, else ().
        self._imu_on_base: dict[int, tuple] = {}
        #: Per (side, corners touching as bytes): that part of the sole.
        self._ground_parts: dict[tuple[str, bytes], _GroundPart] = {}
        self._orders: dict[tuple[str, ...], Optional[np.ndarray]] = {}
        self.reset()

    def reset(self) -> None:
        """Forget the state: the next sample initialises it."""
        self.t: Optional[float] = None
        self.rot: Optional[np.ndarray] = None
        self.p = np.zeros(3)        # the IMU point, world [m]
        self.v = np.zeros(3)        # its velocity, world [m/s]
        self._yaw_correction = np.eye(3)
        #: Per sole: (which corners touch, world position of their centre), or None.
        self.anchors: dict[str, Optional[tuple]] = {'l': None, 'r': None}
        self.last_issue: Optional[str] = None
        self.n_rejected = 0
        self._have_fix = False      # a sole has anchored the position
        self._slipping_s = 0.0      # how long every loaded sole has been slipping [s]

    # -- helpers ---------------------------------------------------------------------
    def _order(self, names: Sequence[str]) -> Optional[np.ndarray]:
        """Indices mapping a sample's joints onto the description's order (None: the same order)."""
        key = tuple(names)
        if key not in self._orders:
            if key == self.robot.joint_names:
                self._orders[key] = None
            else:
                missing = set(self.robot.joint_names) - set(key)
                if missing:
                    raise DescriptionError(f'joints {sorted(missing)} of the robot description are '
                                           'missing from the sample')
                self._orders[key] = np.array([key.index(n) for n in self.robot.joint_names])
        return self._orders[key]

    def _reject(self, why: str) -> None:
        self.last_issue = why
        self.n_rejected += 1

    @staticmethod
    def _wrench(w) -> Optional[np.ndarray]:
        if w is None:
            return None
        w = np.asarray(w, dtype=float)
        # A product with zeros is NaN exactly when an element is not finite (one call, not three).
        return w if w.shape == (6,) and w @ _ZEROS6 == 0.0 else None

    def _sole_wrench(self, side: str, w: np.ndarray, frame: str) -> np.ndarray:
        """A wrench measured in ``frame`` (a sensor frame of the description; empty: the sole
        frame), carried to the sole frame (the ground reaction about the sole origin)."""
        if not frame:
            return w
        sole_id = self.robot.sole_ids[side]
        fid = self.robot.frame_id(frame, f'{"left" if side == "l" else "right"} foot force sensor')
        if fid == sole_id:
            return w
        sensor = pin.updateFramePlacement(self.model, self.data, fid)
        placement = self.data.oMf[sole_id].actInv(sensor)      # the sensor in the sole frame
        f = placement.rotation @ w[:3]
        tau = placement.rotation @ w[3:] + cross3(placement.translation, f)
        return np.concatenate([f, tau])

    def _wrenches_without_sensors(self, s: SensorSample, order: Optional[np.ndarray],
                                  kin: _Kinematics) -> dict[str, Optional[np.ndarray]]:
        """The wrenches of the feet without a force sensor: from the joint efforts when the sample
        has them all, else from the kinematics and statics (monitor.effort_wrench)."""
        tau = np.asarray(s.tau, dtype=float)
        if tau.shape == (len(s.joint_names),) and np.isfinite(tau).all():
            found = self._effort.wrenches(kin.q, kin.v, tau if order is None else tau[order])
            lowest = min(kin.sole_pos[side][2] for side in SIDES)
            for side in SIDES:
                if kin.sole_pos[side][2] > lowest + self.config.effort_contact_height_m:
                    found[side] = None
            self.wrench_source = 'efforts'
        else:
            found = self._effort.kinematic(kin.com, kin.sole_pos, kin.sole_rot,
                                           self.config.kinematic_contact_height_m)
            self.wrench_source = 'statics'
        return {side: found[side] for side in self.effort_feet}

    def _kinematics(self, s: SensorSample, q_j: np.ndarray, dq_j: np.ndarray, dt: float,
                    first: bool) -> _Kinematics:
        """The IMU's place on the robot (a constant when it is fixed to the floating base, else from
        a pass of the joints' kinematics with a still, upright base) gives the base's attitude and
        rate; then one pass of the whole robot with that attitude and rate gives every frame, the
        CoM and the momentum in world axes, relative to the base origin."""
        robot, model, data, cfg = self.robot, self.model, self.data, self.config
        q = robot.configuration(q_j)
        v = np.zeros(model.nv)
        v[robot.idx_v] = dq_j
        imu_id = robot.frame_id(s.imu_frame or self.imu_frame, 'IMU')
        on_base = self._imu_on_base.get(imu_id)
        if on_base is None:
            frame = model.frames[imu_id]
            rotation = frame.placement.rotation.copy()
            on_base = self._imu_on_base[imu_id] = (rotation, np.array_equal(rotation, np.eye(3))) \
                if frame.parentJoint == 1 else ()
        if on_base:
            # An IMU fixed to the floating base (the common case): its place is a constant.
            r_bi, aligned = on_base
            omega_b = r_bi @ np.asarray(s.gyro_rad_s, dtype=float)
        else:
            pin.forwardKinematics(model, data, q, v)
            r_bi = pin.updateFramePlacement(model, data, imu_id).rotation   # the IMU in the base
            omega_b = r_bi @ np.asarray(s.gyro_rad_s, dtype=float) - \
                pin.getFrameVelocity(model, data, imu_id, _LWA).angular
        # The IMU's attitude carried to the base.
        r_wi = pin.Quaternion(np.asarray(s.imu_quat_xyzw, dtype=float)).normalized().matrix()
        r_wb = r_wi if on_base and aligned else r_wi @ r_bi.T
        if first:
            self._yaw_correction = _rot_z(cfg.initial_yaw_rad - _yaw(r_wb))
        r_meas = self._yaw_correction @ r_wb
        if first or self.rot is None:
            rot = r_meas
        else:
            rot = self.rot @ pin.exp3(omega_b * dt)
            gain = 1.0 - math.exp(-dt / cfg.attitude_time_constant_s)
            rot = pin.exp3(gain * pin.log3(r_meas @ rot.T)) @ rot
        # The whole robot: base at the origin with this attitude, turning at omega_b.
        q[3:7] = pin.Quaternion(rot).coeffs()
        v[3:6] = omega_b
        h = pin.computeCentroidalMomentum(model, data, q, v)      # also the kinematics and CoM
        sole_pos, sole_rot, sole_vel = {}, {}, {}
        for side in SIDES:
            sole_id = robot.sole_ids[side]
            placement = pin.updateFramePlacement(model, data, sole_id)
            vel = pin.getFrameVelocity(model, data, sole_id, _LWA)
            sole_pos[side], sole_rot[side] = placement.translation, placement.rotation
            sole_vel[side] = (vel.linear, vel.angular)
        imu = pin.updateFramePlacement(model, data, imu_id)
        return _Kinematics(q, v, rot, omega_b, sole_pos, sole_rot, sole_vel, imu.translation,
                           pin.getFrameVelocity(model, data, imu_id, _LWA).linear, imu.rotation,
                           data.com[0].copy(), h.linear, h.angular)

    # -- the filter ------------------------------------------------------------------
    def update(self, s: SensorSample) -> Optional[Measurement]:
        """One sensor sample in; the estimated measurement, or None if the sample is rejected."""
        cfg = self.config
        try:
            order = self._order(s.joint_names)
            q_j, dq_j = np.asarray(s.q, dtype=float), np.asarray(s.dq, dtype=float)
            imu = [np.asarray(a, dtype=float) for a in (s.imu_quat_xyzw, s.gyro_rad_s, s.accel_m_s2)]
            if (q_j.shape != (len(s.joint_names),) or dq_j.shape != q_j.shape
                    or imu[0].shape != (4,) or imu[1].shape != (3,) or imu[2].shape != (3,)
                    or not math.isfinite(s.t)
                    or not (np.concatenate([q_j, dq_j, *imu]) * 0.0).sum() == 0.0   # NaN or inf
                    or float(imu[0] @ imu[0]) < 1e-12):
                self._reject('non-finite or malformed joint or IMU data')
                return None
            if order is not None:
                q_j, dq_j = q_j[order], dq_j[order]
            if self.t is not None and s.t <= self.t:
                self._reject(f'time {s.t:.6f} s not after the previous {self.t:.6f} s')
                return None
            first = self.t is None or self.rot is None
            dt = 0.0 if first else min(s.t - self.t, cfg.max_gap_s)
            kin = self._kinematics(s, q_j, dq_j, dt, first)
            wrenches = {}
            for side, w, frame in (('l', s.left_wrench, s.wrench_frames[0]),
                                   ('r', s.right_wrench, s.wrench_frames[1])):
                w = self._wrench(w)
                wrenches[side] = None if w is None else self._sole_wrench(side, w, frame)
            if self._effort is not None:
                wrenches.update(self._wrenches_without_sensors(s, order, kin))
        except DescriptionError as error:
            self._reject(str(error))
            return None
        if self.t is not None and s.t - self.t > cfg.max_gap_s:
            self.last_issue = f'gap of {s.t - self.t:.3f} s: soles re-anchored'
            self.anchors = {'l': None, 'r': None}
        else:
            self.last_issue = None
        self.rot = kin.rot
        loaded = {}
        for side, w in wrenches.items():
            if w is not None and w[2] > cfg.contact_force_n:
                loaded[side] = w
            else:
                self.anchors[side] = None
        # The part of each loaded sole on the ground: the corners within the tolerance of the
        # lowest one (all four on a flat sole, an edge or a corner on a tilted one), its centre
        # (sole frame), its position relative to the base origin and its velocity.
        touch, point_rel, point_vel = {}, {}, {}
        for side in loaded:
            r_s = kin.sole_rot[side]
            touch[side] = part = self._ground_part(side, r_s)
            offset = r_s @ part.centre
            point_rel[side] = kin.sole_pos[side] + offset
            v_origin, w_sole = kin.sole_vel[side]
            point_vel[side] = v_origin + cross3(w_sole, offset)
        first_fix = not self._have_fix and bool(loaded)
        if first_fix:
            # The world frame is placed at the first sample with a loaded sole: its origin on the
            # soles' centres (the sole frames' origins), not on the part judged on the ground,
            # which hangs on the first, unfiltered tilt (0.5 deg of IMU error makes an edge of a
            # flat sole: half a sole's shift).
            mid = sum(kin.sole_pos[side] for side in loaded) / len(loaded)
            ground = sum(point_rel[side][2] for side in loaded) / len(loaded)
            base = np.array([cfg.initial_xy_m[0] - mid[0], cfg.initial_xy_m[1] - mid[1], -ground])
            self.p = base + kin.imu_pos
            self.v = np.zeros(3)
        elif not first:
            a_world = kin.imu_rot @ np.asarray(s.accel_m_s2, dtype=float) - _GRAVITY
            self.v = self.v + a_world * dt
            self.p = self.p + self.v * dt
        if loaded:
            self._correct(kin, loaded, touch, point_rel, point_vel, first_fix, dt)
        self.t = s.t
        if not self._have_fix:
            self.last_issue = 'no loaded sole yet: the base position is unknown'
            return None
        return self._measurement(s.t, kin, loaded, touch)

    def _ground_part(self, side: str, r_s: np.ndarray) -> _GroundPart:
        """The part of sole ``side`` (orientation ``r_s``) on the ground: its corners within
        ``tilt_tolerance_m`` of the lowest."""
        corners = self.sole_corners[side]
        heights = corners @ r_s[2]
        touching = heights <= heights.min() + self.config.tilt_tolerance_m
        key = (side, touching.tobytes())
        part = self._ground_parts.get(key)
        if part is None:
            part = self._ground_parts[key] = _GroundPart(
                key[1], corners[touching].mean(axis=0), corners[touching], bool(touching.all()))
        return part

    def _correct(self, kin: _Kinematics, loaded: dict, touch: dict, point_rel: dict,
                 point_vel: dict, first_fix: bool, dt: float) -> None:
        """The kinematic correction of the IMU point from the soles on the ground (``dt``: the
        time since the previous sample [s]; ``first_fix``: the world frame was just placed)."""
        cfg = self.config
        per_side = {}
        base_now = self.p - kin.imu_pos
        for side, w in loaded.items():
            # A sole's ground contact stays where it touched down (z = 0); when the part on
            # the ground changes (flat -> edge on tilting), it is re-anchored there.
            key = touch[side].key
            anchor = self.anchors[side]
            if anchor is None or anchor[0] != key:
                anchor = base_now + point_rel[side]
                anchor[2] = 0.0
                anchor = self.anchors[side] = (key, anchor)
            per_side[side] = (float(w[2]), anchor[1] - point_rel[side] + kin.imu_pos,
                              kin.imu_vel - point_vel[side])
        if not first_fix:
            # Slip: a sole whose kinematic velocity disagrees with the IMU prediction by more
            # than slip_velocity_m_s is sliding; it is left out and re-anchored. If every sole
            # slips for max_slip_s, the closest one is trusted.
            residual = {}
            for side, (_, _, v) in per_side.items():
                d = v - self.v
                residual[side] = math.sqrt(float(d @ d))
            keep = [side for side, r in residual.items() if r <= cfg.slip_velocity_m_s]
            self._slipping_s = 0.0 if keep else self._slipping_s + dt
            if not keep and self._slipping_s > cfg.max_slip_s:
                keep = [min(residual, key=residual.get)]
            if len(keep) < len(per_side):
                for side in per_side:
                    if side not in keep:
                        self.anchors[side] = None
                per_side = {side: per_side[side] for side in keep}
        if not per_side:
            return
        if len(per_side) == 1:
            (_, p_meas, v_meas), = per_side.values()
        else:
            (f_a, p_a, v_a), (f_b, p_b, v_b) = per_side.values()
            share = f_b / (f_a + f_b)
            p_meas = p_a + share * (p_b - p_a)
            v_meas = v_a + share * (v_b - v_a)
        if first_fix:
            self.p, self.v = p_meas, v_meas
            self._have_fix = True
        else:
            self.p = self.p + (1.0 - math.exp(-dt / cfg.position_time_constant_s)) * (p_meas - self.p)
            self.v = self.v + (1.0 - math.exp(-dt / cfg.velocity_time_constant_s)) * (v_meas - self.v)

    def _contact_forces(self, side: str, part: _GroundPart, cop_local: tuple[float, float],
                        fz: float) -> np.ndarray:
        """The sole's normal force split over its corners on the ground (split_force_to_corners;
        the flat sole, the common case, in closed form: bilinear weights of the CoP)."""
        if not part.flat:
            return split_force_to_corners(part.corners[:, :2], np.array(cop_local), fz)
        half_l, half_w = self._half_sole[side]
        u = min(1.0, max(0.0, (cop_local[0] + half_l) / (2 * half_l)))
        w = min(1.0, max(0.0, (cop_local[1] + half_w) / (2 * half_w)))
        # Corners: front left, front right, back right, back left (SoleGeometry.corners).
        return np.array([u * w * fz, u * (1.0 - w) * fz, (1.0 - u) * (1.0 - w) * fz,
                         (1.0 - u) * w * fz])

    def _measurement(self, t: float, kin: _Kinematics, loaded: dict, touch: dict) -> Measurement:
        rot = kin.rot
        base = self.p - kin.imu_pos
        contacts, feet = {}, {}
        cop_x = cop_y = force_sum = 0.0
        for side in SIDES:
            r_s, o_s = kin.sole_rot[side], kin.sole_pos[side] + base
            ox, oy, _ = o_s.tolist()
            feet[side] = np.array([ox, oy, _yaw(r_s)])
            if side not in loaded:
                contacts[side] = _NO_CONTACT
                continue
            _, _, fz, tx, ty, _ = loaded[side].tolist()
            cx, cy = -ty / fz, tx / fz
            part = touch[side]
            world = part.corners @ r_s.T + o_s
            world[:, 2] = self._contact_forces(side, part, (cx, cy), fz)
            contacts[side] = world
            (r00, r01, _), (r10, r11, _) = r_s[:2].tolist()
            cop_x += fz * (r00 * cx + r01 * cy + ox)
            cop_y += fz * (r10 * cx + r11 * cy + oy)
            force_sum += fz
        if force_sum > 0.0:
            cop = np.array([cop_x / force_sum, cop_y / force_sum, 0.0])
        else:
            cop = np.full(3, np.nan)
        # Momentum of the base-fixed motion plus the whole body translating with the base.
        lin_mom = kin.lin_mom + self.total_mass_kg * (self.v - kin.imu_vel)
        return Measurement(t=t, com=kin.com + base, lin_mom=lin_mom, ang_mom=kin.ang_mom.copy(),
                           heading=_yaw(rot), cop=cop,
                           left_contacts=contacts['l'], right_contacts=contacts['r'],
                           left_foot=feet['l'], right_foot=feet['r'], non_foot_contact=False,
                           torso_rotation=rot.copy())

    def run(self, samples: Sequence[SensorSample]) -> list[Optional[Measurement]]:
        """A whole recording through :meth:`update` (the offline path: same code, same state)."""
        return [self.update(s) for s in samples]
