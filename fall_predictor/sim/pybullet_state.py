"""The exact state of the PyBullet world's robot (:class:`~fall_predictor.sim.pybullet_world.
PybulletWorld`): CoM, momenta about the CoM, heading, contacts and CoP from one batch of PyBullet
reads per step, and the frames and contacts the sensor truth (sim/pybullet_sensors.py) reuses from
those reads."""
from __future__ import annotations

import math

import numpy as np

from fall_predictor.monitor.records import Measurement
from fall_predictor.sim.pybullet_quiet import pb
from fall_predictor.sim.world import MIN_CONTACT_FORCE_N



# Rotation matrix entries from quaternion products (x, y, z, w = q0..q3): entry k is
# 2 (q_a q_b + s q_c q_d), and 1 minus that on the diagonal; the products' indices into the
# flattened outer product q q^T, and the signs s.
_R_A = np.array([5, 1, 2, 1, 0, 6, 2, 6, 0])       # yy, xy, xz, xy, xx, yz, xz, yz, xx
_R_B = np.array([10, 11, 7, 11, 10, 3, 7, 3, 5])   # zz, zw, yw, zw, zz, xw, yw, xw, yy
_R_SIGN = np.array([1.0, -1.0, 1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0])
_R_DIAGONAL = np.array([0, 4, 8])


def quaternions_to_matrices(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) from PyBullet quaternions (n, 4) in (x, y, z, w) order.

    All nine entries at once from the outer products (a few array operations for all bodies, not
    ~40); each entry is the same floating-point expression as written out, e.g. 1 - 2 (yy + zz),
    2 (xy - zw) (a - b is a + (-b) exactly)."""
    n = len(q)
    products = (q[:, :, None] * q[:, None, :]).reshape(n, 16)
    # Into a C-ordered array (a fancy-indexed result is column-major here, and the einsums of the
    # angular momentum sum in another order on it: other last bits).
    out = np.empty((n, 9))
    np.multiply(products[:, _R_B], _R_SIGN, out=out)
    out += products[:, _R_A]
    out *= 2
    out[:, _R_DIAGONAL] = 1 - out[:, _R_DIAGONAL]
    return out.reshape(n, 3, 3)


def link_frame_pose(world, link: int) -> tuple[tuple, tuple]:
    """World position and quaternion (x, y, z, w) of ``link``'s frame (not its inertial frame)
    at the current step: from this step's measurement when it read them, else from PyBullet."""
    measured = world._measured
    if measured is not None and measured[0] == world.tick and link in world._row:
        state = measured[1][world._row[link]]
        return state[4], state[5]
    state = pb.getLinkState(world.robot, link, computeForwardKinematics=1, physicsClientId=world.client)
    return state[4], state[5]

def ground_contacts(world) -> tuple:
    """PyBullet's contact points between the robot and the ground at the current step."""
    measured = world._measured
    if measured is not None and measured[0] == world.tick:
        return measured[2]
    return _contact_points(world)


def _contact_points(world) -> tuple:
    """The robot's contact points with the ground and with any terrain box on it (its top is
    ground to a foot; sim/disturbances.py)."""
    contacts = pb.getContactPoints(bodyA=world.robot, bodyB=world.plane, physicsClientId=world.client)
    if world.terrain_bodies:
        from fall_predictor.sim.pybullet_terrain import terrain_contact_points
        contacts = tuple(contacts) + terrain_contact_points(world)
    return contacts

def measure(world) -> Measurement:
    """CoM, momenta about the CoM, heading, contacts and CoP of the current state."""
    c = world.client
    base_pos, base_orn = pb.getBasePositionAndOrientation(world.robot, physicsClientId=c)
    base_lin, base_ang = pb.getBaseVelocity(world.robot, physicsClientId=c)
    links = pb.getLinkStates(world.robot, world.bodies[1:], computeLinkVelocity=1,
                             computeForwardKinematics=1, physicsClientId=c)
    # One row of (position, quaternion, linear velocity, angular velocity) per body (one flat
    # list, then one array: cheaper than an array of row tuples).
    flat = [*base_pos, *base_orn, *base_lin, *base_ang]
    for ls in links:
        flat += ls[0]
        flat += ls[1]
        flat += ls[6]
        flat += ls[7]
    state = np.array(flat).reshape(-1, 13)
    pos, quat, vel, omega = state[:, 0:3], state[:, 3:7], state[:, 7:10], state[:, 10:13]
    m = world.masses
    com = m @ pos / world.total_mass
    lin_mom = m @ vel
    # Angular momentum about the CoM: orbital part sum m (r - c) x v, plus each link's
    # spin R I R^T w (R: inertial frame orientation, I: its diagonal inertia).
    rel = pos - com
    mv = vel * m[:, None]
    ang = np.array([(rel[:, 1] * mv[:, 2] - rel[:, 2] * mv[:, 1]).sum(),
                    (rel[:, 2] * mv[:, 0] - rel[:, 0] * mv[:, 2]).sum(),
                    (rel[:, 0] * mv[:, 1] - rel[:, 1] * mv[:, 0]).sum()])
    rots = quaternions_to_matrices(quat)
    w_body = np.einsum('nji,nj->ni', rots, omega)
    ang += np.einsum('nij,nj->i', rots, world.inertias * w_body)
    rot0 = rots[0]
    heading = math.atan2(rot0[1, 0], rot0[0, 0])

    contacts = _contact_points(world)
    # Kept for the sensor truth of the same step (sim.sensors), which needs the same reads.
    world._measured = (world.tick, links, contacts)
    per_foot: dict[int, list[tuple[float, float, float]]] = {lk: [] for lk in world.foot_links.values()}
    non_foot = False
    for cp in contacts:
        if cp[9] <= MIN_CONTACT_FORCE_N:
            continue
        link = cp[3]
        if link in per_foot:
            per_foot[link].append((cp[6][0], cp[6][1], cp[9]))
        elif cp[2] == world.plane or cp[2] in world.flush_bodies:
            # Another link on the ground (a slip's flush patch is ground); on a terrain box (a
            # shin over an obstacle) it is not.
            non_foot = True
    left = np.array(per_foot[world.foot_links['l']], dtype=float).reshape(-1, 3)
    right = np.array(per_foot[world.foot_links['r']], dtype=float).reshape(-1, 3)
    both = np.vstack([left, right])
    total_force = both[:, 2].sum()
    if total_force > 0:
        cop = np.array([both[:, 2] @ both[:, 0] / total_force, both[:, 2] @ both[:, 1] / total_force, 0.0])
    else:
        cop = np.full(3, np.nan)
    feet = {}
    for side, lk in world.foot_links.items():
        # The sole centre: the foot link's frame (not its inertial frame) and the sole offset.
        state = links[world._row[lk]]
        frame_rot = np.array(pb.getMatrixFromQuaternion(state[5])).reshape(3, 3)
        fp = np.asarray(state[4]) + frame_rot @ world._sole_offsets[side]
        if world._sole_rotations[side] is not None:
            frame_rot = frame_rot @ world._sole_rotations[side]
        feet[side] = np.array([fp[0], fp[1], math.atan2(frame_rot[1, 0], frame_rot[0, 0])])
    meas = Measurement(t=world.t, com=com, lin_mom=lin_mom, ang_mom=ang, heading=heading, cop=cop,
                       left_contacts=left, right_contacts=right, left_foot=feet['l'],
                       right_foot=feet['r'], non_foot_contact=non_foot, torso_rotation=rot0)
    world._prev_measurement = meas
    return meas
