"""Terrain boxes, joint faults and domain randomisation in the PyBullet world (the engine's side of
sim/disturbances.py and sim/randomization.py).

Boxes are static bodies (mass 0) made with the world at each start; a contact on one has the box's
friction (PyBullet multiplies the two bodies' lateral frictions, the feet's being 1.0 by default,
:class:`~fall_predictor.sim.pybullet_world.PybulletConfig`). A stuck joint is locked by its joint
limits (enforced by PyBullet's multibody solver), set to its angle at the fault's start.
"""
from __future__ import annotations

import numpy as np
import pybullet as pb

from fall_predictor.sim.disturbances import STUCK_PLAY_RAD, TerrainBox, ground_around
from fall_predictor.sim.world import MIN_CONTACT_FORCE_N, TerrainContact


def add_box(client: int, box: TerrainBox) -> int:
    """A static body of ``box``; its id."""
    shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=list(box.half_extents_m), physicsClientId=client)
    visual = pb.createVisualShape(pb.GEOM_BOX, halfExtents=list(box.half_extents_m), rgbaColor=list(box.rgba),
                                  physicsClientId=client)
    body = pb.createMultiBody(0, shape, visual, list(box.centre_m), list(box.quaternion_xyzw()),
                              physicsClientId=client)
    pb.changeDynamics(body, -1, lateralFriction=box.friction, physicsClientId=client)
    return body


#: How far below z = 0 the ground is drawn when boxes lay it around a flush patch [m] (drawn
#: only: the patch's top face shows above it).
GROUND_DRAWN_BELOW_M = 0.001


def ground_of_boxes(client: int, boxes) -> int:
    """The ground as one static body of level boxes around the flush boxes of ``boxes``
    (disturbances.ground_around), in place of the plane or slab: nothing lies under a flush
    patch, so that within Bullet's contact margin a foot on it meets the patch alone. -1 when
    ``boxes`` has no flush box (the ground is the profile's)."""
    around = ground_around(boxes)
    if not around:
        return -1
    shape = pb.createCollisionShapeArray(
        [pb.GEOM_BOX] * len(around), halfExtents=[list(h) for _, h in around],
        collisionFramePositions=[list(c) for c, _ in around], physicsClientId=client)
    # A body without a visual shape is drawn as its collision shape: a speck below the ground
    # instead, the ground drawn as a plane (draw_ground_plane).
    speck = pb.createVisualShape(pb.GEOM_SPHERE, radius=1e-3, visualFramePosition=[0.0, 0.0, -1.0],
                                 physicsClientId=client)
    return pb.createMultiBody(0, shape, speck, physicsClientId=client)


def draw_ground_plane(client: int, z_m: float = 0.0) -> None:
    """The checkerboard plane PyBullet draws a plane ground as, at height ``z_m``, colliding with
    nothing."""
    drawn = pb.createMultiBody(0, pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=client),
                               basePosition=[0.0, 0.0, z_m], physicsClientId=client)
    pb.setCollisionFilterGroupMask(drawn, -1, 0, 0, physicsClientId=client)


def terrain_contact_points(world) -> tuple:
    """PyBullet's contact points between the robot and every terrain body, in the boxes' order."""
    out: tuple = ()
    for body in world.terrain_bodies:
        out += tuple(pb.getContactPoints(bodyA=world.robot, bodyB=body, physicsClientId=world.client))
    return out


def terrain_contacts(world) -> list[TerrainContact]:
    """The robot's loaded contacts with the terrain boxes at the current step."""
    side_of = {link: side for side, link in world.foot_links.items()}
    box_of = {body: k for k, body in enumerate(world.terrain_bodies)}
    out = []
    for cp in terrain_contact_points(world):
        if cp[9] <= MIN_CONTACT_FORCE_N:
            continue
        # cp[7]: the normal on B (the box) towards A (the robot); friction along two directions.
        normal = np.asarray(cp[7]) * cp[9]
        friction = cp[10] * np.asarray(cp[11]) + cp[12] * np.asarray(cp[13])
        out.append(TerrainContact(box_of[cp[2]], side_of.get(cp[3]), np.asarray(cp[6]), normal, friction))
    return out


def lock_joint(world, index: int, angle_rad: float) -> None:
    """Lock joint ``index`` (profile order) at ``angle_rad`` with its limits."""
    pb.changeDynamics(world.robot, world.joint_indices[index], jointLowerLimit=angle_rad - STUCK_PLAY_RAD,
                      jointUpperLimit=angle_rad + STUCK_PLAY_RAD, physicsClientId=world.client)


def randomize_dynamics(world, randomization, n_links: int) -> None:
    """The ground's friction and the links' masses of a freshly loaded robot, randomised: every
    link with mass scaled (its inertia with it), the base then given the added mass."""
    c = world.client
    pb.changeDynamics(world.plane, -1, lateralFriction=randomization.friction, physicsClientId=c)
    for link in [-1, *range(n_links)]:
        info = pb.getDynamicsInfo(world.robot, link, physicsClientId=c)
        mass = info[0]
        if mass <= 0.0:
            continue
        new = max(mass * randomization.link_mass_scale
                  + (randomization.added_base_mass_kg if link == -1 else 0.0), 0.1 * mass)
        inertia = np.asarray(info[2]) * (new / mass)
        pb.changeDynamics(world.robot, link, mass=new, localInertiaDiagonal=inertia.tolist(), physicsClientId=c)
