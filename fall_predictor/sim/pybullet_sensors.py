"""The exact sensor quantities of the PyBullet world's state (:class:`~fall_predictor.sim.sensors.
SensorTruth`): the joint encoders and drive torques, the IMU at the profile's IMU frame, and each
foot's ground wrench where the profile has an F/T sensor."""
from __future__ import annotations

import numpy as np
from fall_predictor.sim.pybullet_quiet import pb

from fall_predictor.monitor.geometry import cross3
from fall_predictor.sim.sensors import IMU_POSITION_IN_TORSO_M, SensorTruth


def _ground_wrench(sim, side: str, contacts) -> np.ndarray:
    """Ground reaction on one sole, about the sole origin, in the sole frame."""
    foot = sim.foot_links[side]
    frame_pos, frame_orn = sim.link_frame_pose(foot)
    # The foot's link frame is at the ankle centre; the sole frame has the same axes.
    rot = np.array(pb.getMatrixFromQuaternion(frame_orn)).reshape(3, 3)
    foot_profile = sim.profile.feet[side]
    origin = np.asarray(frame_pos) + rot @ np.asarray(foot_profile.sole_origin_in_foot_m)
    if any(foot_profile.sole_rpy_in_foot_rad):       # sole axes turned from the foot link's
        rot = rot @ foot_profile.sole_rotation_in_foot()
    # Summed in Python floats: a foot has a few contact points per step, and numpy's per-call
    # cost on 3-vectors was a fifth of the generation's time.
    ox, oy, oz = origin.tolist()
    fx = fy = fz = tx = ty = tz = 0.0
    for cp in contacts:
        if cp[3] != foot:
            continue
        (nx, ny, nz), fn = cp[7], cp[9]
        (ax, ay, az), fa = cp[11], cp[10]
        (bx, by, bz), fb = cp[13], cp[12]
        px, py, pz = cp[6][0] - ox, cp[6][1] - oy, cp[6][2] - oz
        cx = nx * fn + ax * fa + bx * fb
        cy = ny * fn + ay * fa + by * fb
        cz = nz * fn + az * fa + bz * fb
        fx, fy, fz = fx + cx, fy + cy, fz + cz
        tx, ty, tz = tx + py * cz - pz * cy, ty + pz * cx - px * cz, tz + px * cy - py * cx
    return np.concatenate([rot.T @ np.array([fx, fy, fz]), rot.T @ np.array([tx, ty, tz])])


def sensor_truth(sim) -> SensorTruth:
    """The exact sensor quantities of ``sim``'s current state (a :class:`PybulletWorld`)."""
    c = sim.client
    profile = sim.profile
    imu_link = sim.link_index.get(profile.imu_frame)
    if imu_link is None:
        # The IMU on the base link, at its frame origin: PyBullet's base frame is the base's
        # inertial frame (same axes, origin at its CoM).
        pos, orn = pb.getBasePositionAndOrientation(sim.robot, physicsClientId=c)
        lin, ang = pb.getBaseVelocity(sim.robot, physicsClientId=c)
        rot = np.array(pb.getMatrixFromQuaternion(orn)).reshape(3, 3)
        imu_from_com = rot @ (np.asarray(IMU_POSITION_IN_TORSO_M) - sim.base_inertial_xyz)
        omega = np.asarray(ang)
        v_imu = np.asarray(lin) + cross3(omega, imu_from_com)
    else:
        # An IMU frame of its own (a massless link on a fixed joint): its pose from PyBullet, its
        # velocity from the body it is fixed to (PyBullet's velocities of massless links are not
        # those of their frames).
        ls = pb.getLinkState(sim.robot, imu_link, computeForwardKinematics=1, physicsClientId=c)
        orn = ls[5]
        rot = np.array(pb.getMatrixFromQuaternion(orn)).reshape(3, 3)
        parent = sim.link_parent[imu_link]
        if parent < 0:
            body_com, _ = pb.getBasePositionAndOrientation(sim.robot, physicsClientId=c)
            lin, ang = pb.getBaseVelocity(sim.robot, physicsClientId=c)
        else:
            ps = pb.getLinkState(sim.robot, parent, computeLinkVelocity=1, computeForwardKinematics=1,
                                 physicsClientId=c)
            body_com, lin, ang = ps[0], ps[6], ps[7]
        omega = np.asarray(ang)
        v_imu = np.asarray(lin) + cross3(omega, np.asarray(ls[4]) - np.asarray(body_com))
    contacts = sim.ground_contacts()
    q, dq, tau = sim.joint_states()
    wrenches = {side: _ground_wrench(sim, side, contacts) if foot.force_torque_frame else None
                for side, foot in profile.feet.items()}
    return SensorTruth(t=sim.t, q=q, dq=dq, tau=tau, imu_quat_xyzw=np.asarray(orn, dtype=float),
                       imu_velocity_world=v_imu, gyro_rad_s=rot.T @ omega,
                       left_wrench=wrenches['l'], right_wrench=wrenches['r'])
