"""A robot's sensor streams with a known answer, for the tests (no tests here)."""
from __future__ import annotations

import numpy as np


def g1_standing(n: int, period_ns: int = 2_000_000):
    """A G1 standing still, knees bent, as its drivers publish it: 29 joints with efforts at
    500 Hz, the pelvis IMU, no foot F/T sensors; and what the estimator must find (known answer):
    the CoM height above the soles and the CoP at the CoM's ground projection."""
    import pinocchio as pin

    from fall_predictor.monitor.sensor_records import ImuReading, JointStateReading
    from fall_predictor.profiles.profile import load_profile
    profile = load_profile('g1')
    robot = profile.sensor_layout().description(profile.urdf_xml())
    model, data = robot.model, robot.model.createData()
    q_joints = np.zeros(len(robot.joint_names))
    for side in ('l', 'r'):
        hip, _, _, knee, ankle, _ = profile.leg_joints(side)
        for name, angle in ((hip, -0.3), (knee, 0.6), (ankle, -0.3)):
            q_joints[robot.joint_names.index(name)] = angle
    q = robot.configuration(q_joints)
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    com = pin.centerOfMass(model, data, q)
    soles = {s: data.oMf[robot.sole_ids[s]] for s in ('l', 'r')}
    # The weight shared by the lever rule; each sole's CoP under the CoM (feet level, symmetric).
    weight = robot.total_mass_kg * 9.81
    lam = (com[1] - soles['l'].translation[1]) / (soles['r'].translation[1] - soles['l'].translation[1])
    tau = pin.rnea(model, data, q, np.zeros(model.nv), np.zeros(model.nv)).copy()
    for side, share in (('l', 1 - lam), ('r', lam)):
        offset = com - soles[side].translation
        fz = share * weight
        wrench = np.array([0.0, 0.0, fz, offset[1] * fz, -offset[0] * fz, 0.0])
        tau -= pin.getFrameJacobian(model, data, robot.sole_ids[side], pin.ReferenceFrame.LOCAL).T @ wrench
    order = list(reversed(robot.joint_names))                  # the driver's order, not the URDF's
    index = [robot.joint_names.index(name) for name in order]
    imu_rot = data.oMf[model.getFrameId(profile.imu_frame)].rotation
    stamp0 = 1_764_000_000_000_000_000                         # epoch time, as on a robot
    out = []
    for k in range(n):
        stamp = stamp0 + k * period_ns
        out.append(('joints', JointStateReading(stamp, tuple(order), q_joints[index], np.zeros(len(order)),
                                                tau[robot.idx_v][index])))
        out.append(('imu', ImuReading(stamp + 300_000, profile.imu_frame,
                                      pin.Quaternion(imu_rot).coeffs().copy(), np.zeros(3),
                                      imu_rot.T @ np.array([0.0, 0.0, 9.81]))))
    sole_z = soles['l'].translation[2]
    return out, com[2] - sole_z, com[:2] - (soles['l'].translation[:2] + soles['r'].translation[:2]) / 2
