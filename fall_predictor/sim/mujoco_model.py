"""A robot profile's MuJoCo model, and the facts of it the MuJoCo world needs.

* :func:`load_model`: the profile's MJCF (a scene with its ground, as a team deploys its policy
  on it), or its URDF, given a free base and a ground plane (MuJoCo imports a URDF's root as
  fixed, and a URDF has no ground); mesh paths resolved as for PyBullet
  (:mod:`~fall_predictor.sim.urdf_loading`);
* :func:`robot_geoms`: which geometries are the ground and which are the robot's;
* :func:`fixed_frame_in_body`: where a frame of the URDF (an IMU) sits on a body MuJoCo has;
* :class:`FloatingBase`: the robot's base, free in the world through a free joint or, as some
  teams' MJCFs have it (humanoid-gym's), three slide joints and a ball joint;
* :func:`stand_on_ground`: the base height at which the lowest foot geometry touches the ground.
"""
from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Iterable, Optional, Sequence

# Rendering without a display (the package's renders are headless); a user's choice stands.
os.environ.setdefault('MUJOCO_GL', 'egl')
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from fall_predictor.monitor.rotations import rpy_matrix  # noqa: E402
from fall_predictor.profiles.profile import ProfileError, RobotProfile  # noqa: E402
from fall_predictor.sim.disturbances import ground_around  # noqa: E402
from fall_predictor.sim.urdf_loading import resolve_urdf_text  # noqa: E402

#: How far above the ground the lowest foot geometry starts [m] (it settles in a step).
START_CLEARANCE_M = 0.001


#: Attributes MJCF files of older MuJoCo releases carry that this one refuses, and why they can
#: go: ``<flag sensornoise>`` (MuJoCo's sensor noise, dropped in 3.x: the package's own sensor
#: model makes the readings).
OBSOLETE_ATTRIBUTES = {'sensornoise': 'MuJoCo no longer has sensor noise (the package models its own sensors)'}


def load_model(profile: RobotProfile) -> mujoco.MjModel:
    """The MuJoCo model of ``profile``'s robot (module docstring). An MJCF that names an attribute
    this MuJoCo no longer has (:data:`OBSOLETE_ATTRIBUTES`) is read without it, with a warning;
    any other error says which file MuJoCo could not read."""
    if profile.mjcf_path is not None:
        try:
            return mujoco.MjModel.from_xml_path(str(profile.mjcf_path))
        except ValueError as error:
            return _without_obsolete_attributes(profile.mjcf_path, error)
    text = resolve_urdf_text(profile.sim_urdf_path.read_text())
    spec = mujoco.MjSpec.from_string(text)
    spec.meshdir = str(profile.sim_urdf_path.parent)
    spec.compiler.discardvisual = False
    root = spec.worldbody.first_body()
    root.add_freejoint()
    spec.worldbody.add_geom(name='ground', type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0.0, 0.0, 0.05])
    return spec.compile()


def model_with_terrain(profile: RobotProfile, boxes) -> mujoco.MjModel:
    """:func:`load_model`'s model with ``boxes`` (sim/disturbances.TerrainBox) fixed to the world
    as box geometries named ``terrain_<k>``: their friction decides a contact's (priority 1 over
    the robot's geometries; MuJoCo otherwise takes the larger of the two). Flush boxes (a slip's
    patch) are laid in the ground: the floor is taken out of contact and level boxes
    ``ground_<k>`` with its contact properties lie around them (disturbances.ground_around)."""
    if profile.mjcf_path is not None:
        try:
            spec = mujoco.MjSpec.from_file(str(profile.mjcf_path))
        except ValueError as error:
            spec = _spec_without_obsolete_attributes(profile.mjcf_path, error)
    else:
        text = resolve_urdf_text(profile.sim_urdf_path.read_text())
        spec = mujoco.MjSpec.from_string(text)
        spec.meshdir = str(profile.sim_urdf_path.parent)
        spec.compiler.discardvisual = False
        spec.worldbody.first_body().add_freejoint()
        spec.worldbody.add_geom(name='ground', type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0.0, 0.0, 0.05])
    return compile_with_terrain(spec, boxes)


def compile_with_terrain(spec: mujoco.MjSpec, boxes) -> mujoco.MjModel:
    """``spec`` compiled with ``boxes`` laid as :func:`model_with_terrain` says (its floor: the
    world body's named colliding geometries)."""
    floors = [g.name for g in spec.worldbody.geoms]
    for k, box in enumerate(boxes):
        x, y, z, w = box.quaternion_xyzw()
        spec.worldbody.add_geom(name=f'terrain_{k}', type=mujoco.mjtGeom.mjGEOM_BOX,
                                size=list(box.half_extents_m), pos=list(box.centre_m), quat=[w, x, y, z],
                                friction=[box.friction, 0.005, 0.0001], priority=1, rgba=list(box.rgba))
    around = ground_around(boxes)
    for k, (centre, half) in enumerate(around):
        # Drawn as the floor (_ground_as_boxes).
        spec.worldbody.add_geom(name=f'ground_{k}', type=mujoco.mjtGeom.mjGEOM_BOX, size=list(half),
                                pos=list(centre), rgba=[0.0, 0.0, 0.0, 0.0])
    model = spec.compile()
    if around:
        _ground_as_boxes(model, floors, len(around))
    return model


def _ground_as_boxes(model: mujoco.MjModel, floor_names: Sequence[str], n_boxes: int) -> None:
    """Take the floor (the world body's colliding geometries of the robot's own model) out of
    contact and give the ``ground_<k>`` boxes laid in its place its contact properties (friction,
    priority, solver parameters, margin), so that a foot on them meets the floor it met."""
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name) for name in floor_names if name]
    floors = [g for g in ids if g >= 0 and (model.geom_contype[g] or model.geom_conaffinity[g])]
    if not floors:
        raise ValueError('the MuJoCo model has no named floor geometry to lay a flush patch in')
    f = floors[0]
    boxes = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f'ground_{k}') for k in range(n_boxes)]
    for field in ('geom_contype', 'geom_conaffinity', 'geom_condim', 'geom_priority', 'geom_friction',
                  'geom_solmix', 'geom_solref', 'geom_solimp', 'geom_margin', 'geom_gap'):
        values = getattr(model, field)
        values[boxes] = values[f]
    model.geom_contype[floors] = 0
    model.geom_conaffinity[floors] = 0
    # The boxes drawn as the floor was (its material: a checkerboard), the floor not at all: a
    # floor drawn just below the patch's top shows through it at a depth buffer's resolution,
    # and a reflecting one mirrors the patch's body above it.
    model.geom_matid[boxes] = model.geom_matid[f]
    model.geom_rgba[boxes] = model.geom_rgba[f]
    model.geom_matid[floors] = -1
    model.geom_rgba[floors] = 0.0


def _without_obsolete_attributes(path, error: ValueError) -> mujoco.MjModel:
    """``path`` read again without the obsolete attributes MuJoCo refused; ValueError (naming the
    file) for any other error."""
    import re
    import warnings

    found = re.search(r"unrecognized attribute: '(\w+)'", str(error))
    if found is None or found.group(1) not in OBSOLETE_ATTRIBUTES:
        raise ProfileError(f'MuJoCo cannot read it: {error}', file=path, field='mjcf',
                           fix='fix the MJCF (or the file it names)') from None
    text = Path(path).read_text()
    for name, why in OBSOLETE_ATTRIBUTES.items():
        pattern = re.compile(rf'\s{name}\s*=\s*(["\'])[^"\']*\1')
        if pattern.search(text):
            text = pattern.sub('', text)
            warnings.warn(f'{path}: attribute {name!r} left out ({why})')
    spec = mujoco.MjSpec.from_string(text)
    spec.modelfiledir = str(Path(path).resolve().parent)
    try:
        return spec.compile()
    except ValueError as again:
        raise ValueError(f'MuJoCo cannot read {path}: {again}') from None


def _spec_without_obsolete_attributes(path, error: ValueError) -> mujoco.MjSpec:
    """The spec of ``path`` read without the obsolete attributes MuJoCo refused (see
    :func:`_without_obsolete_attributes`)."""
    import re
    found = re.search(r"unrecognized attribute: '(\w+)'", str(error))
    if found is None or found.group(1) not in OBSOLETE_ATTRIBUTES:
        raise ValueError(f'MuJoCo cannot read {path}: {error}') from None
    text = Path(path).read_text()
    for name in OBSOLETE_ATTRIBUTES:
        text = re.sub(rf'\s{name}\s*=\s*(["\'])[^"\']*\1', '', text)
    spec = mujoco.MjSpec.from_string(text)
    spec.modelfiledir = str(Path(path).resolve().parent)
    return spec


def robot_geoms(model: mujoco.MjModel, root_body: int) -> tuple[frozenset, frozenset]:
    """(the ground's geometries: those of the world body, the robot's colliding geometries: those
    of the bodies under ``root_body``)."""
    robot_bodies = {b for b in range(model.nbody) if _under(model, b, root_body)}
    collides = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
    ground = frozenset(g for g in range(model.ngeom) if model.geom_bodyid[g] == 0 and collides[g])
    robot = frozenset(g for g in range(model.ngeom)
                      if model.geom_bodyid[g] in robot_bodies and collides[g])
    if not ground:
        raise ValueError('the MuJoCo model has no ground geometry (a geom of the world body)')
    return ground, robot


def _under(model: mujoco.MjModel, body: int, root: int) -> bool:
    while body > 0:
        if body == root:
            return True
        body = int(model.body_parentid[body])
    return False


def fixed_frame_in_body(model: mujoco.MjModel, profile: RobotProfile, frame: str
                        ) -> tuple[int, np.ndarray, np.ndarray]:
    """(body id, position [m], rotation) of ``frame`` in a body of ``model``: the body or site
    of that name, else the URDF's chain of fixed joints from ``frame`` up to a link MuJoCo has
    (its fixed links are fused into their parents)."""
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, frame)
    if body >= 0:
        return body, np.zeros(3), np.eye(3)
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, frame)
    if site >= 0:
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, model.site_quat[site])
        return int(model.site_bodyid[site]), model.site_pos[site].copy(), rot.reshape(3, 3)
    joints = {j.find('child').get('link'): j for j in ET.parse(profile.urdf_path).getroot()
              .iter('joint') if j.get('type') == 'fixed'}
    position, rotation, link = np.zeros(3), np.eye(3), frame
    while link in joints:
        origin = joints[link].find('origin')
        xyz = np.array([float(v) for v in (origin.get('xyz', '0 0 0') if origin is not None
                                           else '0 0 0').split()])
        rpy = [float(v) for v in (origin.get('rpy', '0 0 0') if origin is not None
                                  else '0 0 0').split()]
        parent_rot = rpy_matrix(*rpy)
        position, rotation = xyz + parent_rot @ position, parent_rot @ rotation
        link = joints[link].find('parent').get('link')
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, link)
        if body >= 0:
            return body, position, rotation
    raise ProfileError(f'frame {frame!r} is neither a body nor a site of the MuJoCo model, nor '
                       'fixed in the URDF to a link the model has', file=profile.source,
                       field='imu_frame' if frame == profile.imu_frame else None,
                       fix='name a body or site of the MJCF, or a URDF link fixed to one')


class FloatingBase:
    """The body that carries the robot, free in the world: a free joint, or three slide joints
    along the world's axes and a ball joint on a body of the world (the same six degrees of
    freedom). ValueError, in words, for a model with neither."""

    def __init__(self, model: mujoco.MjModel, source: object = 'the MuJoCo model') -> None:
        free = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
        if len(free) == 1:
            j = free[0]
            self.body = int(model.jnt_bodyid[j])
            adr = int(model.jnt_qposadr[j])
            self._position = [adr, adr + 1, adr + 2]
            self._quat = adr + 3
            self.dofs = list(range(int(model.jnt_dofadr[j]), int(model.jnt_dofadr[j]) + 6))
            self._offset = np.zeros(3)
            return
        for body in range(1, model.nbody):
            if model.body_parentid[body] != 0:
                continue
            joints = [j for j in range(model.njnt) if model.jnt_bodyid[j] == body]
            slides = {int(np.argmax(np.abs(model.jnt_axis[j]))): j for j in joints
                      if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE
                      and np.isclose(np.abs(model.jnt_axis[j]).max(), 1.0)}
            balls = [j for j in joints if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL]
            if sorted(slides) == [0, 1, 2] and len(balls) == 1:
                self.body = body
                self._position = [int(model.jnt_qposadr[slides[k]]) for k in range(3)]
                self._signs = [float(np.sign(model.jnt_axis[slides[k]][k])) for k in range(3)]
                self._quat = int(model.jnt_qposadr[balls[0]])
                self.dofs = ([int(model.jnt_dofadr[slides[k]]) for k in range(3)]
                             + list(range(int(model.jnt_dofadr[balls[0]]),
                                          int(model.jnt_dofadr[balls[0]]) + 3)))
                self._offset = model.body_pos[body].copy()
                return
        raise ValueError(f'{source}: the robot\'s base must be free in the world: a free joint, '
                         f'or three slide joints (x, y, z) and a ball joint on one body; found '
                         f'{len(free)} free joints and no such body')

    def set_pose(self, data: mujoco.MjData, position: Optional[Sequence[float]],
                 quat_wxyz: Sequence[float]) -> None:
        """Put the base's body at ``position`` [m] (None: leave it) with orientation
        ``quat_wxyz``."""
        data.qpos[self._quat:self._quat + 4] = quat_wxyz
        if position is not None:
            for k, adr in enumerate(self._position):
                data.qpos[adr] = (position[k] - self._offset[k]) * getattr(self, '_signs', (1, 1, 1))[k]

    def raise_by(self, data: mujoco.MjData, dz_m: float) -> None:
        """Move the base up by ``dz_m`` [m]."""
        data.qpos[self._position[2]] += dz_m * getattr(self, '_signs', (1, 1, 1))[2]


def stand_on_ground(model: mujoco.MjModel, data: mujoco.MjData, base: FloatingBase,
                    feet: Iterable[int]) -> None:
    """Move the base up or down so that the lowest point of the feet's colliding geometries lies
    :data:`START_CLEARANCE_M` above the ground (z = 0)."""
    feet = set(feet)
    mujoco.mj_kinematics(model, data)
    lowest = math.inf
    for g in range(model.ngeom):
        if model.geom_bodyid[g] not in feet or not (model.geom_contype[g] or model.geom_conaffinity[g]):
            continue
        lowest = min(lowest, _lowest_point(model, data, g))
    if not math.isfinite(lowest):
        raise ValueError('the feet have no colliding geometry')
    base.raise_by(data, START_CLEARANCE_M - lowest)


def _lowest_point(model: mujoco.MjModel, data: mujoco.MjData, geom: int) -> float:
    """The lowest world z of a geometry: exact for spheres, capsules, boxes and meshes (their
    vertices), else that of the box around it."""
    kind, size = model.geom_type[geom], model.geom_size[geom]
    centre, rot = data.geom_xpos[geom], data.geom_xmat[geom].reshape(3, 3)
    if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        return float(centre[2] - size[0])
    if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        return float(centre[2] - abs(rot[2, 2]) * size[1] - size[0])
    if kind == mujoco.mjtGeom.mjGEOM_MESH:
        mesh = model.geom_dataid[geom]
        start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        vertices = model.mesh_vert[start:start + count]
        return float((centre + vertices @ rot.T)[:, 2].min())
    # Boxes (and the box around anything else): the corner lowest in the world.
    half = size if kind == mujoco.mjtGeom.mjGEOM_BOX else model.geom_aabb[geom, 3:]
    return float(centre[2] - np.abs(rot[2, :]) @ half)
