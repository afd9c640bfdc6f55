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
  ``max_slip_s``, the closest is used). The ground holds the robot up: integrated alone through
  a fall, the position never takes the CoM below the ground (it stops there, its downward
  velocity with it), so the estimate of a fallen robot stays a fallen robot's. The base follows
  from the point by kinematics;
* **CoM and centroidal momentum**: ``pinocchio.computeCentroidalMomentum`` (linear momentum,
  angular momentum about the CoM);
* **contacts and CoP**: a sole with normal force above ``contact_force_n`` is loaded (a foot without
  a force sensor, one of ``effort_feet``: its wrench from the leg's joint efforts, or with no
  efforts from statics); each foot's wrench is taken in its sensor's frame (the sample's
  ``wrench_frames``; empty: the sole frame) and carried to the sole frame
  (:mod:`~fall_predictor.monitor.foot_wrenches`), where the CoP is (-ty / fz, tx / fz), kept on
  the sole (a sole's CoP lies under it: one computed off it, from a light load's torque noise or
  the effort-derived wrench of a slipping, falling leg, is moved to the sole's nearest edge); the
  whole-body CoP is the force-weighted mean. The contacts handed to the feature code are the
  sole's corners that lie within ``tilt_tolerance_m`` of its lowest corner, with the normal force
  split between them so that their weighted mean is the sole's CoP
  (:mod:`~fall_predictor.monitor.sole_contact`).

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

from fall_predictor.monitor import rotations
from fall_predictor.monitor.foot_wrenches import FootWrenches, all_finite
from fall_predictor.monitor.plausibility import COM_HEIGHT_RANGE_M
from fall_predictor.monitor.records import STANDARD_GRAVITY_M_S2, Measurement
from fall_predictor.monitor.robot_description import SIDES, DescriptionError, RobotDescription
from fall_predictor.monitor.sensor_records import SensorSample
from fall_predictor.monitor.sole_contact import SoleContacts

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_NO_CONTACT = np.zeros((0, 3))

# Per sample the filter works on 3-vectors as float triples and on the attitude as a quaternion
# (monitor.rotations): a numpy call on a 3-vector costs ~0.5 us, many times its arithmetic, and
# the estimator runs at the sensors' rate (1 kHz).


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


@dataclass(slots=True)
class _Kinematics:
    """One sample's kinematics relative to the floating base's origin: the base at the origin with
    the estimated orientation, not translating, turning at the estimated rate; world axes."""

    q: np.ndarray                   #: full configuration (base at the origin, estimated attitude)
    v: np.ndarray                   #: full velocity (base: not translating, turning at omega_b)
    attitude: tuple                 #: estimated base orientation in the world, quaternion x, y, z, w
    #: Per side: the sole's pose, its origin relative to the base origin, world axes, as the rows
    #: of its homogeneous transform (floats: r00, r01, r02, x in the first row, ...).
    sole_pose: dict
    sole_vel: dict                  #: per side: linear velocity of its origin, angular velocity (6)
    imu_pos: list                   #: IMU point relative to the base origin
    imu_vel: list                   #: IMU point velocity relative to the base origin
    imu_pose: list                  #: IMU frame pose, world axes: rows of its homogeneous transform
    com: list                       #: CoM relative to the base origin
    lin_mom: list                   #: linear momentum of the base-fixed motion [kg m/s]
    ang_mom: np.ndarray             #: angular momentum about the CoM [kg m^2/s]


class StateEstimator:
    """Streams :class:`SensorSample` in, :class:`Measurement` out (see the module docstring)."""

    def __init__(self, robot: RobotDescription, config: EstimatorConfig = EstimatorConfig(),
                 imu_frame: str = '', effort_feet: tuple[str, ...] = ()) -> None:
        self.robot = robot
        self.config = config
        #: Both soles' wrenches; feet without a force sensor (``effort_feet``) from the joint
        #: efforts or statics (monitor.foot_wrenches).
        self.foot_wrenches = FootWrenches(robot, effort_feet, config.effort_contact_height_m,
                                          config.kinematic_contact_height_m)
        self.model, self.data = robot.model, robot.data
        #: The IMU frame of samples that do not name one (the robot profile's IMU link).
        self.imu_frame = imu_frame
        self.total_mass_kg = robot.total_mass_kg
        self.soles = SoleContacts(robot.soles, config.tilt_tolerance_m)
        self._sole_ids = tuple((side, robot.sole_ids[side]) for side in SIDES)
        #: Per IMU frame name: (frame id, its rotation in the base frame as a matrix and as a
        #: quaternion if it is fixed to the floating base else None, None; whether that rotation is
        #: the identity).
        self._imus: dict[str, tuple] = {}
        self._orders: dict[tuple[str, ...], Optional[np.ndarray]] = {}
        # The last joint-name tuple seen and its order: the sensor input hands the same tuple
        # object with every sample of a message layout (hashing 30 names costs more than this).
        self._last_names: Optional[tuple] = None
        self._last_order: Optional[np.ndarray] = None
        self.reset()

    @property
    def effort_feet(self) -> tuple[str, ...]:
        """The feet without a force sensor."""
        return self.foot_wrenches.effort_feet

    @property
    def wrench_source(self) -> str:
        """Where the last sample's sensor-less feet took their wrench from: 'sensors' (every foot
        has one), 'efforts' or 'statics'."""
        return self.foot_wrenches.source

    def reset(self) -> None:
        """Forget the state: the next sample initialises it."""
        self.t: Optional[float] = None
        #: The base's attitude in the world, quaternion (x, y, z, w); None before the first sample.
        self.attitude: Optional[tuple] = None
        self.p = (0.0, 0.0, 0.0)    # the IMU point, world [m]
        self.v = (0.0, 0.0, 0.0)    # its velocity, world [m/s]
        self._yaw_correction = rotations.IDENTITY
        #: Per sole: (which corners touch, world position of their centre), or None.
        self.anchors: dict[str, Optional[tuple]] = {'l': None, 'r': None}
        self.last_issue: Optional[str] = None
        self.n_rejected = 0
        self._have_fix = False      # a sole has anchored the position
        self._slipping_s = 0.0      # how long every loaded sole has been slipping [s]

    # -- helpers ---------------------------------------------------------------------
    def _order(self, names: Sequence[str]) -> Optional[np.ndarray]:
        """Indices mapping a sample's joints onto the description's order (None: the same order)."""
        if names is self._last_names:
            return self._last_order
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
        if type(names) is tuple:       # immutable: its identity stands for its contents
            self._last_names, self._last_order = names, self._orders[key]
        return self._orders[key]

    def _imu(self, name: str) -> tuple:
        """(frame id, rotation in the base frame as a matrix and a quaternion or None, None,
        identity?) of IMU frame ``name``."""
        found = self._imus.get(name)
        if found is None:
            imu_id = self.robot.frame_id(name, 'IMU')
            frame = self.model.frames[imu_id]
            if frame.parentJoint == 1:      # fixed to the floating base: its place is a constant
                rotation = frame.placement.rotation.copy()
                found = (imu_id, rotation, tuple(pin.Quaternion(rotation).coeffs().tolist()),
                         bool(np.array_equal(rotation, np.eye(3))))
            else:
                found = (imu_id, None, None, False)
            self._imus[name] = found
        return found

    def _reject(self, why: str) -> None:
        self.last_issue = why
        self.n_rejected += 1

    def _kinematics(self, s: SensorSample, q_j: np.ndarray, dq_j: np.ndarray, quat: list,
                    gyro: np.ndarray, dt: float, first: bool) -> _Kinematics:
        """The IMU's place on the robot (a constant when it is fixed to the floating base, else from
        a pass of the joints' kinematics with a still, upright base) gives the base's attitude and
        rate; then one pass of the whole robot with that attitude and rate gives every frame, the
        CoM and the momentum in world axes, relative to the base origin."""
        robot, model, data, cfg = self.robot, self.model, self.data, self.config
        q = robot.configuration(q_j)
        v = robot.velocity(dq_j)
        imu_id, r_bi, q_bi, aligned = self._imu(s.imu_frame or self.imu_frame)
        if r_bi is not None:
            omega_b = gyro if aligned else r_bi @ gyro
        else:
            pin.forwardKinematics(model, data, q, v)
            r_bi = pin.updateFramePlacement(model, data, imu_id).rotation   # the IMU in the base
            q_bi = pin.Quaternion(r_bi).coeffs().tolist()
            omega_b = r_bi @ gyro - pin.getFrameVelocity(model, data, imu_id, _LWA).angular
        # The IMU's attitude carried to the base.
        q_wi = rotations.normalized(quat)
        q_wb = q_wi if aligned else rotations.multiply(q_wi, rotations.conjugate(q_bi))
        if first:
            self._yaw_correction = rotations.about_z(cfg.initial_yaw_rad - rotations.yaw(q_wb))
        measured = rotations.multiply(self._yaw_correction, q_wb)
        if first or self.attitude is None:
            attitude = measured
        else:
            # The gyro integrated (a rotation in the base frame), then pulled towards the measured
            # attitude by the share 1 - exp(-dt / tau) of the rotation between them (world frame).
            wx, wy, wz = omega_b.tolist()
            predicted = rotations.multiply(self.attitude,
                                           rotations.from_rotation_vector(wx * dt, wy * dt, wz * dt))
            gain = 1.0 - math.exp(-dt / cfg.attitude_time_constant_s)
            ex, ey, ez = rotations.rotation_vector(
                rotations.multiply(measured, rotations.conjugate(predicted)))
            attitude = rotations.normalized(rotations.multiply(
                rotations.from_rotation_vector(gain * ex, gain * ey, gain * ez), predicted))
        # The whole robot: base at the origin with this attitude, turning at omega_b.
        q[3:7] = attitude
        v[3:6] = omega_b
        h = pin.computeCentroidalMomentum(model, data, q, v)      # also the kinematics and CoM
        sole_pose, sole_vel = {}, {}
        for side, sole_id in self._sole_ids:
            sole_pose[side] = pin.updateFramePlacement(model, data, sole_id).homogeneous.tolist()
            sole_vel[side] = pin.getFrameVelocity(model, data, sole_id, _LWA).vector.tolist()
        imu = pin.updateFramePlacement(model, data, imu_id).homogeneous.tolist()
        momentum = h.vector.tolist()
        return _Kinematics(q, v, attitude, sole_pose, sole_vel,
                           [imu[0][3], imu[1][3], imu[2][3]],
                           pin.getFrameVelocity(model, data, imu_id, _LWA).vector.tolist()[:3],
                           imu, data.com[0].tolist(), momentum[:3],
                           np.array(momentum[3:]))

    # -- the filter ------------------------------------------------------------------
    def update(self, s: SensorSample) -> Optional[Measurement]:
        """One sensor sample in; the estimated measurement, or None if the sample is rejected."""
        cfg = self.config
        try:
            order = self._order(s.joint_names)
            q_j, dq_j = np.asarray(s.q, dtype=float), np.asarray(s.dq, dtype=float)
            quat = np.asarray(s.imu_quat_xyzw, dtype=float)
            gyro = np.asarray(s.gyro_rad_s, dtype=float)
            accel = np.asarray(s.accel_m_s2, dtype=float)
            n = len(s.joint_names)
            if (q_j.shape != (n,) or dq_j.shape != (n,) or quat.shape != (4,)
                    or gyro.shape != (3,) or accel.shape != (3,) or not math.isfinite(s.t)
                    or not (all_finite(q_j) and all_finite(dq_j))
                    or not all(map(math.isfinite,
                                   imu_values := quat.tolist() + gyro.tolist() + accel.tolist()))
                    or _squared_norm(imu_values[:4]) < 1e-12):
                self._reject('non-finite or malformed joint or IMU data')
                return None
            if order is not None:
                q_j, dq_j = q_j[order], dq_j[order]
            if self.t is not None and s.t <= self.t:
                self._reject(f'time {s.t:.6f} s not after the previous {self.t:.6f} s')
                return None
            first = self.t is None or self.attitude is None
            dt = 0.0 if first else min(s.t - self.t, cfg.max_gap_s)
            kin = self._kinematics(s, q_j, dq_j, imu_values[:4], gyro, dt, first)
            wrenches = self.foot_wrenches.read(s, order, kin.q, kin.v, kin.sole_pose, kin.com)
        except DescriptionError as error:
            self._reject(str(error))
            return None
        if self.t is not None and s.t - self.t > cfg.max_gap_s:
            self.last_issue = f'gap of {s.t - self.t:.3f} s: soles re-anchored'
            self.anchors = {'l': None, 'r': None}
        else:
            self.last_issue = None
        self.attitude = kin.attitude
        loaded = {}                 # per loaded sole: its wrench as floats (fx, fy, fz, tx, ty, tz)
        for side, w in wrenches.items():
            if w is not None and w[2] > cfg.contact_force_n:
                loaded[side] = w
            else:
                self.anchors[side] = None
        # The part of each loaded sole on the ground (monitor.sole_contact), its centre's position
        # relative to the base origin and its velocity.
        touch, point_rel, point_vel = {}, {}, {}
        for side in loaded:
            pose = kin.sole_pose[side]
            touch[side] = part = self.soles.ground_part(side, pose)
            (r00, r01, _, sx), (r10, r11, _, sy), (r20, r21, _, sz), _ = pose
            cx, cy = part.centre                        # the sole's underside is at z = 0
            dx, dy, dz = r00 * cx + r01 * cy, r10 * cx + r11 * cy, r20 * cx + r21 * cy
            point_rel[side] = (sx + dx, sy + dy, sz + dz)
            vx, vy, vz, wx, wy, wz = kin.sole_vel[side]
            point_vel[side] = (vx + (wy * dz - wz * dy), vy + (wz * dx - wx * dz),
                               vz + (wx * dy - wy * dx))
        first_fix = not self._have_fix and bool(loaded)
        ix, iy, iz = kin.imu_pos
        if first_fix:
            # The world frame is placed at the first sample with a loaded sole: its origin on the
            # soles' centres (the sole frames' origins), not on the part judged on the ground,
            # which hangs on the first, unfiltered tilt (0.5 deg of IMU error makes an edge of a
            # flat sole: half a sole's shift).
            n_loaded = len(loaded)
            mid_x = sum(kin.sole_pose[side][0][3] for side in loaded) / n_loaded
            mid_y = sum(kin.sole_pose[side][1][3] for side in loaded) / n_loaded
            ground = sum(point_rel[side][2] for side in loaded) / n_loaded
            self.p = ((cfg.initial_xy_m[0] - mid_x) + ix, (cfg.initial_xy_m[1] - mid_y) + iy,
                      -ground + iz)
            self.v = (0.0, 0.0, 0.0)
        elif not first:
            (r00, r01, r02, _), (r10, r11, r12, _), (r20, r21, r22, _), _ = kin.imu_pose
            fx, fy, fz = imu_values[7:]                 # the specific force, IMU frame
            ax, ay, az = (r00 * fx + r01 * fy + r02 * fz, r10 * fx + r11 * fy + r12 * fz,
                          r20 * fx + r21 * fy + r22 * fz)
            (px, py, pz), (vx, vy, vz) = self.p, self.v
            vx, vy, vz = vx + ax * dt, vy + ay * dt, vz + (az - STANDARD_GRAVITY_M_S2) * dt
            self.v = (vx, vy, vz)
            self.p = (px + vx * dt, py + vy * dt, pz + vz * dt)
        if loaded:
            self._correct(kin, loaded, touch, point_rel, point_vel, first_fix, dt)
        if self._have_fix:
            self._stop_at_ground(kin)
        self.t = s.t
        if not self._have_fix:
            self.last_issue = 'no loaded sole yet: the base position is unknown'
            return None
        return self._measurement(s.t, kin, loaded, touch)

    def _correct(self, kin: _Kinematics, loaded: dict, touch: dict, point_rel: dict,
                 point_vel: dict, first_fix: bool, dt: float) -> None:
        """The kinematic correction of the IMU point from the soles on the ground (``dt``: the
        time since the previous sample [s]; ``first_fix``: the world frame was just placed)."""
        cfg = self.config
        per_side = {}
        (px, py, _), (ix, iy, iz), (ivx, ivy, ivz) = self.p, kin.imu_pos, kin.imu_vel
        for side, w in loaded.items():
            # A sole's ground contact stays where it touched down (z = 0); when the part on
            # the ground changes (flat -> edge on tilting), it is re-anchored there.
            key = touch[side].key
            anchor = self.anchors[side]
            rx, ry, rz = point_rel[side]
            if anchor is None or anchor[0] != key:
                anchor = self.anchors[side] = (key, ((px - ix) + rx, (py - iy) + ry, 0.0))
            ax, ay, az = anchor[1]
            vx, vy, vz = point_vel[side]
            per_side[side] = (w[2], ((ax - rx) + ix, (ay - ry) + iy, (az - rz) + iz),
                              (ivx - vx, ivy - vy, ivz - vz))
        if not first_fix:
            # Slip: a sole whose kinematic velocity disagrees with the IMU prediction by more
            # than slip_velocity_m_s is sliding; it is left out and re-anchored. If every sole
            # slips for max_slip_s, the closest one is trusted.
            residual = {}
            ex, ey, ez = self.v
            for side, (_, _, (vx, vy, vz)) in per_side.items():
                residual[side] = math.sqrt((vx - ex) ** 2 + (vy - ey) ** 2 + (vz - ez) ** 2)
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
            p_meas, v_meas = _towards(p_a, p_b, share), _towards(v_a, v_b, share)
        if first_fix:
            self.p, self.v = p_meas, v_meas
            self._have_fix = True
        else:
            self.p = _towards(self.p, p_meas, 1.0 - math.exp(-dt / cfg.position_time_constant_s))
            self.v = _towards(self.v, v_meas, 1.0 - math.exp(-dt / cfg.velocity_time_constant_s))

    def _stop_at_ground(self, kin: _Kinematics) -> None:
        """A CoM below the ground is where the ground stopped it: dead reckoning with no sole on
        the ground (a fall's impact) overshoots."""
        (px, py, pz), iz = self.p, kin.imu_pos[2]
        com_z = kin.com[2] + (pz - iz)
        if com_z < COM_HEIGHT_RANGE_M[0]:
            # A micrometre above: the CoM is recomputed from the base and must not round below.
            self.p = (px, py, pz + (COM_HEIGHT_RANGE_M[0] + 1e-6 - com_z))
            vx, vy, vz = self.v
            self.v = (vx, vy, max(vz, 0.0))

    def _measurement(self, t: float, kin: _Kinematics, loaded: dict, touch: dict) -> Measurement:
        (px, py, pz), (ix, iy, iz) = self.p, kin.imu_pos
        bx, by, bz = px - ix, py - iy, pz - iz          # the base origin in the world
        contacts, feet = {}, {}
        cop_x = cop_y = force_sum = 0.0
        for side in SIDES:
            pose = kin.sole_pose[side]
            (r00, r01, _, sx), (r10, r11, _, sy) = pose[0], pose[1]
            ox, oy = sx + bx, sy + by
            feet[side] = np.array([ox, oy, math.atan2(r10, r00)])
            if side not in loaded:
                contacts[side] = _NO_CONTACT
                continue
            _, _, fz, tx, ty, _ = loaded[side]
            cx, cy = self.soles.on_sole(side, -ty / fz, tx / fz)     # the sole's CoP, sole frame
            contacts[side] = self.soles.contacts(side, touch[side], pose, (ox, oy), cx, cy, fz)
            cop_x += fz * (r00 * cx + r01 * cy + ox)
            cop_y += fz * (r10 * cx + r11 * cy + oy)
            force_sum += fz
        if force_sum > 0.0:
            cop = np.array([cop_x / force_sum, cop_y / force_sum, 0.0])
        else:
            cop = np.full(3, np.nan)
        # Momentum of the base-fixed motion plus the whole body translating with the base.
        mass = self.total_mass_kg
        (lx, ly, lz), (vx, vy, vz), (ivx, ivy, ivz) = kin.lin_mom, self.v, kin.imu_vel
        lin_mom = np.array([lx + mass * (vx - ivx), ly + mass * (vy - ivy), lz + mass * (vz - ivz)])
        cx, cy, cz = kin.com
        return Measurement(t=t, com=np.array([cx + bx, cy + by, cz + bz]), lin_mom=lin_mom,
                           ang_mom=kin.ang_mom, heading=rotations.yaw(kin.attitude), cop=cop,
                           left_contacts=contacts['l'], right_contacts=contacts['r'],
                           left_foot=feet['l'], right_foot=feet['r'], non_foot_contact=False,
                           torso_rotation=rotations.matrix(kin.attitude))

    def run(self, samples: Sequence[SensorSample]) -> list[Optional[Measurement]]:
        """A whole recording through :meth:`update` (the offline path: same code, same state)."""
        return [self.update(s) for s in samples]


def _squared_norm(q: Sequence[float]) -> float:
    """The squared norm of a quaternion given as four floats."""
    x, y, z, w = q
    return x * x + y * y + z * z + w * w


def _towards(a: tuple, b: tuple, share: float) -> tuple:
    """The point ``share`` of the way from 3-vector ``a`` to ``b`` (float triples)."""
    return (a[0] + share * (b[0] - a[0]), a[1] + share * (b[1] - a[1]), a[2] + share * (b[2] - a[2]))
