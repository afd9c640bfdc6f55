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

from fall_predictor.sim.disturbances import STUCK_PLAY_RAD, TerrainBox
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
