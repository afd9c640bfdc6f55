"""State estimator: the monitor's :class:`Measurement` from the robot's own sensors.

ROS-free (numpy + Pinocchio). From the URDF (with ``l_sole`` / ``r_sole`` frames) and one
sample of joint encoders, torso IMU and ankle F/T sensors (:class:`SensorSample`) it
estimates, at 1 kHz:

* **torso orientation**: the gyroscope integrated, pulled towards the IMU's attitude output
  with gain ``attitude_gain`` per sample (a complementary filter: the attitude output's
  white noise is averaged out, its bias is not); yaw relative to the first sample plus
  ``initial_yaw_rad`` (the world frame is the frame the robot started in, its origin at
  ``initial_xy_m`` on the loaded soles' centres at the first sample);
* **floating-base position and velocity**: the part of each loaded sole on the ground (its
  corners within ``tilt_tolerance_m`` of the lowest: the whole sole, an edge or a corner) is
  anchored where it touched down (z = 0), re-anchored when that part changes; leg kinematics
  from the anchor gives the base position, and the contact point's velocity with the base
  held still gives the base velocity (a still contact moves the base by minus that). A complementary filter integrates the accelerometer and
  corrects with the force-weighted kinematic position and velocity (gains ``position_gain``,
  ``velocity_gain``); with no loaded sole it integrates the IMU alone. A sole whose kinematic
  velocity is more than ``slip_velocity_m_s`` from the IMU prediction is taken as slipping:
  left out and re-anchored (if all slip for ``max_slip_samples``, the closest is used);
* **CoM and centroidal momentum**: ``pinocchio.centerOfMass`` and
  ``pinocchio.computeCentroidalMomentum`` (linear momentum, angular momentum about the CoM);
* **contacts and CoP**: a sole with normal force above ``contact_force_n`` is loaded; its
  CoP in the sole frame is (-ty / fz, tx / fz); the whole-body CoP is the force-weighted
  mean. The contacts handed to the feature code are the sole's corners that lie within
  ``tilt_tolerance_m`` of its lowest corner (a tilted sole rests on an edge or a corner),
  with the normal force split between them so that their weighted mean is the sole's CoP
  (bilinear on a flat sole, linear along an edge).

What the sensors cannot tell: ``non_foot_contact`` is always False (no skin sensors; a fall is
then seen from the CoM height alone) and ``push_force`` is zero.

Bad input never raises from :meth:`StateEstimator.update`: a sample with NaN joints or IMU,
a stamp not after the previous one, or a stamp more than ``max_gap_s`` after it is rejected
(``None`` returned, the reason in :attr:`StateEstimator.last_issue`; a large gap re-anchors the
soles); so is every sample before the first loaded sole (the base position is unknown
until a sole anchors it); a missing or NaN foot sensor makes that foot unloaded (``degraded`` lists it). A URDF
without the sole frames, or joint names the URDF lacks, raise ``ValueError`` at construction
or on the first sample.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np
import pinocchio as pin

from fall_predictor.monitor.records import STANDARD_GRAVITY_M_S2, Measurement

SOLE_FRAMES = {'l': 'l_sole', 'r': 'r_sole'}
#: Sole size of the shipped robot (SPEC §1) [m]; another robot passes its own.
DEFAULT_SOLE_LENGTH_M = 0.225
DEFAULT_SOLE_WIDTH_M = 0.157


@dataclass(frozen=True)
class EstimatorConfig:
    contact_force_n: float = 10.0
    attitude_gain: float = 0.02
    position_gain: float = 0.05
    velocity_gain: float = 0.05
    tilt_tolerance_m: float = 0.002
    #: A sole whose kinematic base velocity is this far from the IMU prediction slips [m/s].
    slip_velocity_m_s: float = 0.25
    #: After this many samples with every loaded sole slipping, the closest one is trusted.
    max_slip_samples: int = 20
    max_gap_s: float = 0.05
    sole_length_m: float = DEFAULT_SOLE_LENGTH_M
    sole_width_m: float = DEFAULT_SOLE_WIDTH_M
    initial_yaw_rad: float = 0.0
    #: World xy of the loaded soles' midpoint at the first sample [m].
    initial_xy_m: tuple[float, float] = (0.0, 0.0)


@dataclass(slots=True)
class SensorSample:
    """One sample of the robot's sensors (what the ROS topics carry).

    Wrenches (fx, fy, fz, tx, ty, tz) are the ground's on each sole, in the sole frame;
    None where that sensor is missing. ``gyro_rad_s`` and ``accel_m_s2`` (specific force) are
    in the torso (IMU) frame; ``imu_quat_xyzw`` is the IMU's attitude output.
    """

    t: float
    joint_names: Sequence[str]
    q: np.ndarray
    dq: np.ndarray
    imu_quat_xyzw: np.ndarray
    gyro_rad_s: np.ndarray
    accel_m_s2: np.ndarray
    left_wrench: Optional[np.ndarray]
    right_wrench: Optional[np.ndarray]


def quat_xyzw_to_matrix(q: np.ndarray) -> np.ndarray:
    x, y, z, w = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b for 3-vectors (numpy's cross costs ~25 us a call; this ~2 us)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


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


class StateEstimator:
    """Streams :class:`SensorSample` in, :class:`Measurement` out (see the module docstring)."""

    def __init__(self, urdf_xml: str, config: EstimatorConfig = EstimatorConfig()):
        self.config = config
        try:
            self.model = pin.buildModelFromXML(urdf_xml, pin.JointModelFreeFlyer())
        except Exception as exc:  # Pinocchio raises its own types on malformed XML
            raise ValueError(f'cannot build a model from the URDF: {exc}') from exc
        self.data = self.model.createData()
        missing = [f for f in SOLE_FRAMES.values() if not self.model.existFrame(f)]
        if missing:
            raise ValueError(f'the URDF has no frame {missing}: the estimator needs sole frames '
                             f'{tuple(SOLE_FRAMES.values())} at the soles\' underside centres')
        self.sole_ids = {s: self.model.getFrameId(f) for s, f in SOLE_FRAMES.items()}
        self.total_mass_kg = float(sum(inert.mass for inert in self.model.inertias))
        half_l, half_w = config.sole_length_m / 2, config.sole_width_m / 2
        self.sole_corners = np.array([[half_l, half_w, 0.0], [half_l, -half_w, 0.0],
                                      [-half_l, -half_w, 0.0], [-half_l, half_w, 0.0]])
        self._joint_map: Optional[tuple[tuple[str, ...], np.ndarray, np.ndarray]] = None
        self.reset()

    def reset(self) -> None:
        """Forget the state: the next sample initialises it."""
        self.t: Optional[float] = None
        self.rot: Optional[np.ndarray] = None
        self.p = np.zeros(3)
        self.v = np.zeros(3)
        self._yaw_offset = 0.0
        #: Per sole: (which corners touch, world position of their centre), or None.
        self.anchors: dict[str, Optional[tuple]] = {'l': None, 'r': None}
        self.last_issue: Optional[str] = None
        self.degraded: tuple[str, ...] = ()
        self.n_rejected = 0
        self._have_fix = False      # a sole has anchored the base position
        self._slipping = 0          # consecutive samples with every loaded sole slipping

    # -- helpers ---------------------------------------------------------------------
    def _indices(self, names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
        key = tuple(names)
        if self._joint_map is None or self._joint_map[0] != key:
            iq, iv = [], []
            for n in key:
                if not self.model.existJointName(n):
                    raise ValueError(f'joint {n!r} is not in the URDF')
                j = self.model.joints[self.model.getJointId(n)]
                iq.append(j.idx_q)
                iv.append(j.idx_v)
            self._joint_map = (key, np.array(iq), np.array(iv))
        return self._joint_map[1], self._joint_map[2]

    def _reject(self, why: str) -> None:
        self.last_issue = why
        self.n_rejected += 1

    @staticmethod
    def _wrench(w) -> Optional[np.ndarray]:
        if w is None:
            return None
        w = np.asarray(w, dtype=float)
        return w if w.shape == (6,) and np.all(np.isfinite(w)) else None

    # -- the filter ------------------------------------------------------------------
    def update(self, s: SensorSample) -> Optional[Measurement]:
        """One sensor sample in; the estimated measurement, or None if the sample is rejected."""
        cfg = self.config
        iq, iv = self._indices(s.joint_names)
        q_j, dq_j = np.asarray(s.q, dtype=float), np.asarray(s.dq, dtype=float)
        imu = [np.asarray(a, dtype=float) for a in (s.imu_quat_xyzw, s.gyro_rad_s, s.accel_m_s2)]
        if (q_j.shape != (len(iq),) or dq_j.shape != (len(iq),) or imu[0].shape != (4,)
                or imu[1].shape != (3,) or imu[2].shape != (3,) or not math.isfinite(s.t)
                or not np.isfinite(np.concatenate([q_j, dq_j, *imu])).all()
                or float(imu[0] @ imu[0]) < 1e-12):
            self._reject('non-finite or malformed joint or IMU data')
            return None
        if self.t is not None and s.t <= self.t:
            self._reject(f'stamp {s.t:.6f} s not after the previous {self.t:.6f} s')
            return None
        if self.t is not None and s.t - self.t > cfg.max_gap_s:
            self.last_issue = f'gap of {s.t - self.t:.3f} s: soles re-anchored'
            self.anchors = {'l': None, 'r': None}
        else:
            self.last_issue = None
        wrenches = {'l': self._wrench(s.left_wrench), 'r': self._wrench(s.right_wrench)}
        self.degraded = tuple(f'{side}_foot_sensor' for side, w in wrenches.items() if w is None)
        quat, gyro, accel = imu
        r_imu = quat_xyzw_to_matrix(quat)
        first = self.t is None or self.rot is None
        dt = 0.0 if first else min(s.t - self.t, cfg.max_gap_s)
        if first:
            yaw0 = math.atan2(r_imu[1, 0], r_imu[0, 0])
            self._yaw_offset = cfg.initial_yaw_rad - yaw0
        r_meas = _rot_z(self._yaw_offset) @ r_imu
        if first:
            rot = r_meas
        else:
            rot = self.rot @ pin.exp3(gyro * dt)
            rot = pin.exp3(cfg.attitude_gain * pin.log3(r_meas @ rot.T)) @ rot
        self.rot = rot

        # Kinematics with the base at the origin and still (linear), turning at the gyro rate.
        nq = self.model.nq
        qp = np.zeros(nq)
        qp[3:7] = pin.Quaternion(rot).coeffs()
        qp[iq] = q_j
        vp = np.zeros(self.model.nv)
        vp[3:6] = gyro
        vp[iv] = dq_j
        pin.forwardKinematics(self.model, self.data, qp, vp)
        pin.updateFramePlacements(self.model, self.data)
        loaded = {}
        for side, w in wrenches.items():
            if w is not None and w[2] > cfg.contact_force_n:
                loaded[side] = w
            else:
                self.anchors[side] = None
        poses = {side: self.data.oMf[self.sole_ids[side]] for side in ('l', 'r')}
        rel = {side: poses[side].translation.copy() for side in ('l', 'r')}
        rot_sole = {side: poses[side].rotation.copy() for side in ('l', 'r')}
        # The part of each loaded sole on the ground: the corners within the tolerance of the
        # lowest one (all four on a flat sole, an edge or a corner on a tilted one), and its
        # centre (sole frame) and position relative to the base.
        touch, point_local, point_rel = {}, {}, {}
        for side in loaded:
            corners = (rot_sole[side] @ self.sole_corners.T).T
            touch[side] = corners[:, 2] <= corners[:, 2].min() + cfg.tilt_tolerance_m
            point_local[side] = self.sole_corners[touch[side]].mean(axis=0)
            point_rel[side] = rel[side] + rot_sole[side] @ point_local[side]
        if first:
            if loaded:
                # The world frame goes on the soles' centres (the sole frames' origins), not on
                # the part judged on the ground: that part hangs on the first, unfiltered tilt
                # (0.5 deg of IMU error makes an edge of a flat sole: half a sole's shift).
                mid = np.mean([rel[side] for side in loaded], axis=0)
                ground = np.mean([point_rel[side][2] for side in loaded])
                self.p = np.array([cfg.initial_xy_m[0] - mid[0], cfg.initial_xy_m[1] - mid[1], -ground])
            self.v = np.zeros(3)
        else:
            a_world = rot @ accel - np.array([0.0, 0.0, STANDARD_GRAVITY_M_S2])
            self.v = self.v + a_world * dt
            self.p = self.p + self.v * dt
        if loaded:
            per_side = {}
            for side, w in loaded.items():
                # A sole's ground contact stays where it touched down (z = 0); when the part on
                # the ground changes (flat -> edge on tilting), it is re-anchored there.
                key = tuple(touch[side])
                if self.anchors[side] is None or self.anchors[side][0] != key:
                    anchor = self.p + point_rel[side]
                    anchor[2] = 0.0
                    self.anchors[side] = (key, anchor)
                vel = pin.getFrameVelocity(self.model, self.data, self.sole_ids[side], pin.LOCAL_WORLD_ALIGNED)
                v_point = vel.linear + _cross(vel.angular, point_rel[side] - rel[side])
                per_side[side] = (w[2], self.anchors[side][1] - point_rel[side], -v_point)
            if self._have_fix and not first:
                # Slip: a sole whose kinematic base velocity disagrees with the IMU prediction
                # by more than slip_velocity_m_s is sliding; it is left out and re-anchored.
                # If every sole slips for max_slip_samples samples, the closest one is trusted.
                residual = {side: float(np.linalg.norm(v - self.v)) for side, (_, _, v) in per_side.items()}
                keep = {side for side, r in residual.items() if r <= cfg.slip_velocity_m_s}
                self._slipping = 0 if keep else self._slipping + 1
                if not keep and self._slipping > cfg.max_slip_samples:
                    keep = {min(residual, key=residual.get)}
                for side in set(per_side) - keep:
                    self.anchors[side] = None
                per_side = {side: per_side[side] for side in keep}
            if per_side:
                weights = sum(f for f, _, _ in per_side.values())
                p_meas = sum(f * p for f, p, _ in per_side.values()) / weights
                v_meas = sum(f * v for f, _, v in per_side.values()) / weights
                if first or not self._have_fix:
                    self.p, self.v = p_meas, v_meas
                    self._have_fix = True
                else:
                    self.p = self.p + cfg.position_gain * (p_meas - self.p)
                    self.v = self.v + cfg.velocity_gain * (v_meas - self.v)
        self.t = s.t
        if not self._have_fix:
            self.last_issue = 'no loaded sole yet: the base position is unknown'
            return None
        return self._measurement(s.t, qp, vp, rot, rel, rot_sole, loaded, touch)

    def _measurement(self, t: float, qp: np.ndarray, vp: np.ndarray, rot: np.ndarray,
                     rel: dict, rot_sole: dict, loaded: dict, touch: dict) -> Measurement:
        qp[0:3] = self.p
        vp[0:3] = rot.T @ self.v
        # Forward kinematics, CoM (data.com[0]) and the centroidal momentum h_G in one pass.
        h = pin.computeCentroidalMomentum(self.model, self.data, qp, vp)
        com = self.data.com[0].copy()
        contacts, feet, cops, forces = {}, {}, [], []
        for side in ('l', 'r'):
            r_s, o_s = rot_sole[side], rel[side] + self.p
            feet[side] = np.array([o_s[0], o_s[1], math.atan2(r_s[1, 0], r_s[0, 0])])
            if side not in loaded:
                contacts[side] = np.zeros((0, 3))
                continue
            w = loaded[side]
            cop_local = np.array([-w[4] / w[2], w[3] / w[2]])
            world = (r_s @ self.sole_corners.T).T + o_s
            touching = touch[side]
            f = split_force_to_corners(self.sole_corners[touching, :2], cop_local, float(w[2]))
            contacts[side] = np.column_stack([world[touching, 0], world[touching, 1], f])
            cop_w = r_s @ np.array([cop_local[0], cop_local[1], 0.0]) + o_s
            cops.append(cop_w[:2])
            forces.append(float(w[2]))
        if forces:
            total = sum(forces)
            cop = np.array([sum(f * c[0] for f, c in zip(forces, cops)) / total,
                            sum(f * c[1] for f, c in zip(forces, cops)) / total, 0.0])
        else:
            cop = np.full(3, np.nan)
        return Measurement(t=t, com=com, lin_mom=np.array(h.linear), ang_mom=np.array(h.angular),
                           heading=math.atan2(rot[1, 0], rot[0, 0]), cop=cop,
                           left_contacts=contacts['l'], right_contacts=contacts['r'],
                           left_foot=feet['l'], right_foot=feet['r'], non_foot_contact=False,
                           torso_rotation=rot.copy())

    def run(self, samples: Sequence[SensorSample]) -> list[Optional[Measurement]]:
        """A whole recording through :meth:`update` (the offline path: same code, same state)."""
        return [self.update(s) for s in samples]
