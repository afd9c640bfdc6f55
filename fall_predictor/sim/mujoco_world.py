"""The robot in MuJoCo: the second engine behind the simulator seam (:mod:`fall_predictor.sim.world`).

A team checks its learned policy in MuJoCo before the robot (sim2sim), on the MJCF it deploys
with; :class:`MujocoWorld` loads that model (the profile's ``mjcf``, a scene with its ground), or
the robot's URDF when the profile has none (a free base and a ground plane added), and gives what
the PyBullet world gives: the exact state as a :class:`~fall_predictor.monitor.records.Measurement`
(CoM and its momenta from MuJoCo's subtree quantities, the feet's contacts and the CoP from its
contact forces), the exact sensor quantities (:class:`~fall_predictor.sim.sensors.SensorTruth`:
joint encoders, the IMU at the profile's IMU frame, each foot's ground wrench where the profile
has an F/T sensor), the pushes of the one push protocol (:class:`~fall_predictor.sim.world.
PushProtocol`, applied as ``xfrc_applied`` on the base) and state snapshots.

Drives: a command with its own PD gains (a learned policy's) is tracked as its deploy loop tracks
it, ``kp (target - q) - kd dq`` every physics step, clamped to the command's torque limits or the
model's (the joint's ``actuatorfrcrange``, else the actuator's ``ctrlrange``, else the URDF's
effort); a command without gains (C_bal) is tracked by the robot's servos
(:func:`~fall_predictor.robot.actuation.servo_torques`, the profile's table, its viscous friction
and rotor inertia). Torques go through the model's motor actuators when it has one per joint (as
Unitree's deploy writes ``ctrl``), else straight onto the joints.

Frames come from the URDF: the IMU frame the profile names is found in the MJCF (a body or a
site) or, as in Unitree's 12-joint G1 (no IMU site), through the URDF's fixed joints from a link
MuJoCo has.
"""
from __future__ import annotations

import math
import os
from dataclasses import replace
from typing import Optional

# Rendering without a display (the package's renders are headless); a user's choice stands.
os.environ.setdefault('MUJOCO_GL', 'egl')
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from fall_predictor.monitor import rotations
from fall_predictor.monitor.records import Measurement, PushSpec
from fall_predictor.profiles.profile import ProfileError, RobotProfile
from fall_predictor.robot.control import JointCommand
from fall_predictor.sim.mujoco_model import (FloatingBase, fixed_frame_in_body, load_model,
                                             model_with_terrain, robot_geoms, stand_on_ground)
from fall_predictor.sim.disturbances import STUCK_PLAY_RAD, FaultProtocol, start_height_m
from fall_predictor.sim.pushes import PushProtocol
from fall_predictor.sim.world import MIN_CONTACT_FORCE_N, TerrainContact


class MujocoWorld:
    """One robot in one MuJoCo world (module docstring); see :class:`~fall_predictor.sim.world.
    World` for the methods."""

    def __init__(self, profile: RobotProfile, dt_s: Optional[float] = None) -> None:
        self.profile = profile
        self._dt_override = dt_s
        #: The robot's own model (no terrain), and the terrain of the model in use.
        self._flat_model = load_model(profile)
        self._terrain: tuple = ()
        self._fault = FaultProtocol()
        self._random = None               #: the run's randomised world (sim/randomization.py)
        self._load(self._flat_model)
        self.t = 0.0
        self.tick = 0

    def _load(self, model: mujoco.MjModel) -> None:
        """Use ``model`` (the robot's, with or without terrain): its data and indices."""
        profile = self.profile
        self.model = model
        if self._dt_override is not None:
            self.model.opt.timestep = float(self._dt_override)
        self.data = mujoco.MjData(self.model)
        m = self.model
        self._renderer = None
        self.dt_s = float(m.opt.timestep)
        self.joint_names = profile.joint_names
        ids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name) for name in self.joint_names]
        missing = [n for n, i in zip(self.joint_names, ids) if i < 0]
        if missing:
            raise ProfileError(f'the MuJoCo model ({profile.mjcf_path or profile.sim_urdf_path}) '
                               f'has no joint {missing}', file=profile.source, field='joint_groups',
                               fix='give the MJCF the URDF\'s joint names')
        self._qadr = np.array([m.jnt_qposadr[i] for i in ids])
        self._dadr = np.array([m.jnt_dofadr[i] for i in ids])
        self._base = FloatingBase(m, profile.source)
        self._root_body = self._base.body
        #: The base's six degrees of freedom (velocity indices).
        self.base_dofs = self._base.dofs
        self.total_mass = float(m.body_subtreemass[self._root_body])
        # Motor actuators, one per joint: torques as ``ctrl`` (gear 1), as a deploy loop writes.
        by_joint = {int(m.actuator_trnid[a, 0]): a for a in range(m.nu)
                    if m.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
                    and float(m.actuator_gear[a, 0]) == 1.0}
        self._actuators = (np.array([by_joint[i] for i in ids])
                           if all(i in by_joint for i in ids) else None)
        self._effort = self._effort_limits(ids)
        self.feet = {side: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, foot.foot_link)
                     for side, foot in profile.feet.items()}
        if min(self.feet.values()) < 0:
            raise ProfileError(f'the MuJoCo model ({profile.mjcf_path or profile.sim_urdf_path}) '
                               f'lacks a foot link {[f.foot_link for f in profile.feet.values()]}',
                               file=profile.source, field='feet', fix='name bodies of the MJCF')
        self._sole = {side: np.asarray(foot.sole_origin_in_foot_m)
                      for side, foot in profile.feet.items()}
        self._sole_rot = {side: foot.sole_rotation_in_foot() for side, foot in profile.feet.items()}
        self._ground, self._robot_geoms = robot_geoms(m, self._root_body)
        self._foot_of_body = {body: side for side, body in self.feet.items()}
        self._imu_body, self._imu_offset, self._imu_rotation = fixed_frame_in_body(
            m, profile, profile.imu_frame)
        self._push = PushProtocol()
        self._servo = None
        self._targets = np.zeros(len(ids))
        self._kp: Optional[np.ndarray] = None
        self._kd: Optional[np.ndarray] = None
        self._limit = self._effort
        self._tau = np.zeros(len(ids))
        self._prev: Optional[Measurement] = None
        self._terrain_geoms = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f'terrain_{k}')
                               for k in range(len(self._terrain))]
        self._terrain_set = frozenset(self._terrain_geoms)
        # Boxes standing on the ground (an obstacle, a platform): a link other than a foot on
        # one is no fall. A flush one (a slip's patch) is ground.
        self._raised_terrain = frozenset(g for g, box in zip(self._terrain_geoms, self._terrain) if not box.flush)
        self._joint_ids = ids
        self._joint_limits = (m.jnt_range[ids].copy(), m.jnt_limited[ids].copy())
        # The nominal masses, inertias and ground friction a randomised start scales.
        self._robot_bodies = np.array([b for b in range(m.nbody) if m.body_rootid[b] == m.body_rootid[self._root_body]
                                       and b != 0])
        self._nominal = (m.body_mass.copy(), m.body_inertia.copy(), m.geom_friction.copy(), m.geom_priority.copy())
        self._floor = np.array(sorted(set(self._ground) - set(self._terrain_geoms)), dtype=int)
        self._scales = (1.0, 1.0, 1.0)

    def _effort_limits(self, joint_ids: list[int]) -> np.ndarray:
        m = self.model
        out = []
        for k, j in enumerate(joint_ids):
            limit = math.inf
            if m.jnt_actfrclimited[j]:
                limit = float(max(abs(m.jnt_actfrcrange[j, 0]), abs(m.jnt_actfrcrange[j, 1])))
            elif self._actuators is not None and m.actuator_ctrllimited[self._actuators[k]]:
                limit = float(np.abs(m.actuator_ctrlrange[self._actuators[k]]).max())
            out.append(limit)
        limits = np.array(out)
        if not np.isfinite(limits).all():
            from fall_predictor.robot.actuation import servo_arrays
            urdf = servo_arrays(1.0, self.profile, self.joint_names).effort
            limits = np.where(np.isfinite(limits), limits, urdf)
        return limits

    # -- world ---------------------------------------------------------------------------------
    def start(self, posture) -> Measurement:
        """A fresh world with the robot at rest in ``posture`` (robot/control.Posture): its joint
        angles and yaw, the base where given, else low enough that the lowest foot geometry
        touches the ground."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        # A joint a fault left stuck is free again.
        m.jnt_range[self._joint_ids], m.jnt_limited[self._joint_ids] = self._joint_limits
        self._fault.clear()
        self._randomize()
        q = np.array([posture.joint_angles.get(n, 0.0) for n in self.joint_names])
        d.qpos[self._qadr] = q
        half = 0.5 * posture.base_yaw_rad
        self._base.set_pose(d, posture.base_position_m, (math.cos(half), 0.0, 0.0, math.sin(half)))
        if posture.base_position_m is None:
            stand_on_ground(m, d, self._base, self.feet.values())
        lift = start_height_m(self._terrain, (0.0, 0.0))
        if lift:
            self._base.raise_by(d, lift)
        mujoco.mj_forward(m, d)
        self._targets = q.copy()
        self._tau = np.zeros(len(q))
        self._push.clear()
        self._prev = None
        self.t = 0.0
        self.tick = 0
        return self.measure()

    def apply(self, command) -> None:
        """Hold ``command`` (robot/control.JointCommand) until the next one (a joint it does not
        name keeps its target; with gains, such a joint is undriven)."""
        if command.joint_names != self.joint_names:
            command = command.fit_onto(self.joint_names, JointCommand(self.joint_names, self._targets))
        self._targets = np.array(command.targets_rad, dtype=float)
        if not command.has_gains:
            self._use_servos()
            self._kp = self._kd = None
        else:
            self._kp, self._kd = np.asarray(command.kp, float), np.asarray(command.kd, float)
        limit = command.tau_limit_nm
        self._limit = self._effort if limit is None else np.minimum(np.asarray(limit), self._effort)

    def _use_servos(self) -> None:
        """The robot's own servos (C_bal's commands): the profile's table, with its rotor inertia
        and viscous friction on the joints (once)."""
        if self._servo is not None:
            return
        from fall_predictor.robot.actuation import servo_arrays
        self._servo = servo_arrays(1.0, self.profile, self.joint_names)
        self.model.dof_armature[self._dadr] = self._servo.armature
        self.model.dof_damping[self._dadr] = self._servo.damping

    def schedule_push(self, push: PushSpec) -> None:
        self._push.schedule(push)

    # -- disturbances beyond pushes (sim/disturbances.py) ------------------------------------------
    def set_terrain(self, boxes) -> None:
        """Lay ``boxes`` (sim/disturbances.TerrainBox) from the next :meth:`start` on: the model
        is compiled again with them (mujoco_model.model_with_terrain); none: the robot's own."""
        boxes = tuple(boxes)
        if boxes == self._terrain:
            return
        # The model left behind is the robot's own again (a stuck joint freed, masses and friction
        # nominal): it is read as nominal when it comes back.
        m = self.model
        m.jnt_range[self._joint_ids], m.jnt_limited[self._joint_ids] = self._joint_limits
        m.body_mass[:], m.body_inertia[:], m.geom_friction[:], m.geom_priority[:] = self._nominal
        self._terrain = boxes
        self._load(model_with_terrain(self.profile, boxes) if boxes else self._flat_model)

    def terrain_contacts(self) -> list[TerrainContact]:
        """The robot's loaded contacts with the terrain boxes at the current step."""
        m, d = self.model, self.data
        box_of = {g: k for k, g in enumerate(self._terrain_geoms)}
        force6 = np.zeros(6)
        out = []
        for i in range(d.ncon):
            c = d.contact[i]
            g1, g2 = int(c.geom1), int(c.geom2)
            if g1 in box_of and g2 in self._robot_geoms:
                box, robot_geom, sign = box_of[g1], g2, 1.0
            elif g2 in box_of and g1 in self._robot_geoms:
                box, robot_geom, sign = box_of[g2], g1, -1.0
            else:
                continue
            mujoco.mj_contactForce(m, d, i, force6)
            if force6[0] <= MIN_CONTACT_FORCE_N:
                continue
            frame = c.frame.reshape(3, 3)
            normal = sign * force6[0] * frame[0]
            friction = sign * (force6[1] * frame[1] + force6[2] * frame[2])
            out.append(TerrainContact(box, self._foot_of_body.get(int(m.geom_bodyid[robot_geom])),
                                      c.pos.copy(), normal, friction))
        return out

    def set_randomization(self, randomization) -> None:
        """Randomise the world (sim/randomization.WorldRandomization) from the next :meth:`start`
        on; None: the nominal world."""
        self._random = randomization

    def _randomize(self) -> None:
        """The nominal masses, inertias and ground friction, then the run's randomisation: every
        robot body's mass and inertia scaled, the base's given the added mass, the floor's
        friction deciding its contacts (priority over the robot's geometries)."""
        m = self.model
        mass, inertia, friction, priority = self._nominal
        m.body_mass[:], m.body_inertia[:], m.geom_friction[:], m.geom_priority[:] = mass, inertia, friction, priority
        r = self._random
        self._scales = (1.0, 1.0, 1.0) if r is None else r.drive_scales()
        if r is not None:
            bodies = self._robot_bodies
            m.body_mass[bodies] *= r.link_mass_scale
            m.body_inertia[bodies] *= r.link_mass_scale
            base = self._root_body
            new = max(m.body_mass[base] + r.added_base_mass_kg, 0.1 * mass[base])
            m.body_inertia[base] *= new / m.body_mass[base]
            m.body_mass[base] = new
            m.geom_friction[self._floor, 0] = r.friction
            m.geom_priority[self._floor] = 2
        self.total_mass = (float(m.body_subtreemass[self._root_body]) if r is None
                           else float(m.body_mass[self._robot_bodies].sum()))

    def schedule_fault(self, fault) -> None:
        """Fail ``fault``'s joint drive from its start (sim/disturbances.JointFault)."""
        self._fault.schedule(fault, self.joint_names)

    def step(self) -> Measurement:
        m, d = self.model, self.data
        q, dq = d.qpos[self._qadr], d.qvel[self._dadr]
        kp_scale, kd_scale, limit_scale = self._scales
        if self._kp is None and self._servo is not None:
            from fall_predictor.robot.actuation import servo_torques
            servo = self._servo if self._random is None else replace(
                self._servo, kp=self._servo.kp * kp_scale, kd=self._servo.kd * kd_scale,
                effort=self._servo.effort * limit_scale)
            tau = servo_torques(servo, self._targets, q, dq)
        else:
            tau = kp_scale * self._kp * (self._targets - q) - kd_scale * self._kd * dq
        limit = self._limit if limit_scale == 1.0 else self._limit * limit_scale
        tau = np.minimum(np.maximum(tau, -limit), limit)
        # A faulty drive gives a share of its torque; a stuck joint is locked by its limits
        # (sim/disturbances.py).
        tau = self._fault.torques(self.t, tau)
        stuck = self._fault.stuck_joint(self.t, q)
        if stuck is not None:
            j = self._joint_ids[stuck[0]]
            m.jnt_range[j] = (stuck[1] - STUCK_PLAY_RAD, stuck[1] + STUCK_PLAY_RAD)
            m.jnt_limited[j] = 1
        self._tau = tau
        if self._actuators is not None:
            d.ctrl[self._actuators] = tau
        else:
            d.qfrc_applied[self._dadr] = tau
        applied = self._apply_push()
        mujoco.mj_step(m, d)
        # mj_step leaves the kinematics and velocities of the state it started from: the ground
        # forces of its contacts are those that acted over the step (kept, as PyBullet reports
        # them); the positions and velocities are brought to the new state.
        self._last_contacts, self._non_foot = self._contacts()
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_comVel(m, d)
        self.tick += 1
        self.t = self.tick * self.dt_s
        measurement = self.measure(contacts_now=False)
        measurement.push_force = applied
        return measurement

    def _apply_push(self) -> np.ndarray:
        d = self.data
        d.xfrc_applied[self._root_body] = 0.0
        if self._push.push is None:
            return np.zeros(3)
        body = self._root_body
        rot = d.xmat[body].reshape(3, 3)
        com = None if self._prev is None else self._prev.com
        applied = self._push.force_at(self.t, d.xpos[body].copy(), rot, com)
        if applied is None:
            return np.zeros(3)
        force, point = applied
        # xfrc_applied acts at the body's centre of mass: the force, and its moment about it.
        d.xfrc_applied[body, :3] = force
        d.xfrc_applied[body, 3:] = np.cross(point - d.xipos[body], force)
        return force.copy()

    def joint_states(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        d = self.data
        return d.qpos[self._qadr].copy(), d.qvel[self._dadr].copy(), self._tau.copy()

    # -- measuring -------------------------------------------------------------------------------
    def _contacts(self) -> tuple[dict[str, list], bool]:
        """Per foot its loaded contacts (point, force on the robot, world frame), and whether
        another link touches the ground, from the last forward pass's contacts."""
        m, d = self.model, self.data
        per_foot: dict[str, list] = {'l': [], 'r': []}
        non_foot = False
        force6 = np.zeros(6)
        for i in range(d.ncon):
            c = d.contact[i]
            g1, g2 = int(c.geom1), int(c.geom2)
            if g1 in self._ground and g2 in self._robot_geoms:
                robot_geom, sign = g2, 1.0        # the force on geom2 along the normal 1 -> 2
            elif g2 in self._ground and g1 in self._robot_geoms:
                robot_geom, sign = g1, -1.0
            else:
                continue
            mujoco.mj_contactForce(m, d, i, force6)
            frame = c.frame.reshape(3, 3)
            world = sign * (frame.T @ force6[:3])
            if world[2] <= MIN_CONTACT_FORCE_N:
                continue
            side = self._foot_of_body.get(int(m.geom_bodyid[robot_geom]))
            if side is None:
                # Another link on the ground (a flush patch is ground); on a terrain box standing on
                # it (a shin over an obstacle) it is not.
                non_foot = non_foot or (g1 if sign > 0 else g2) not in self._raised_terrain
            else:
                per_foot[side].append((c.pos.copy(), world))
        return per_foot, non_foot

    def measure(self, contacts_now: bool = True) -> Measurement:
        """CoM, momenta about the CoM, heading, contacts and CoP of the current state (the
        contacts: those of the last step, else, ``contacts_now``, of the last forward pass)."""
        m, d = self.model, self.data
        mujoco.mj_subtreeVel(m, d)
        root = self._root_body
        com = d.subtree_com[root].copy()
        lin_mom = self.total_mass * d.subtree_linvel[root]
        ang_mom = d.subtree_angmom[root].copy()
        rot = d.xmat[root].reshape(3, 3).copy()
        if contacts_now:
            self._last_contacts, self._non_foot = self._contacts()
        per_foot, non_foot = self._last_contacts, self._non_foot
        rows = {side: np.array([(p[0], p[1], f[2]) for p, f in per_foot[side]], dtype=float
                               ).reshape(-1, 3) for side in ('l', 'r')}
        both = np.vstack([rows['l'], rows['r']])
        total = both[:, 2].sum()
        cop = (np.array([both[:, 2] @ both[:, 0] / total, both[:, 2] @ both[:, 1] / total, 0.0])
               if total > 0 else np.full(3, np.nan))
        feet = {}
        for side, body in self.feet.items():
            frame = d.xmat[body].reshape(3, 3)
            p = d.xpos[body] + frame @ self._sole[side]
            sole = frame @ self._sole_rot[side]
            feet[side] = np.array([p[0], p[1], math.atan2(sole[1, 0], sole[0, 0])])
        measurement = Measurement(t=self.t, com=com, lin_mom=lin_mom, ang_mom=ang_mom,
                                  heading=math.atan2(rot[1, 0], rot[0, 0]), cop=cop,
                                  left_contacts=rows['l'], right_contacts=rows['r'],
                                  left_foot=feet['l'], right_foot=feet['r'],
                                  non_foot_contact=non_foot, torso_rotation=rot)
        self._prev = measurement
        return measurement

    def sensor_truth(self):
        """The exact sensor quantities of the current state (sim/sensors.SensorTruth)."""
        from fall_predictor.sim.sensors import SensorTruth
        m, d = self.model, self.data
        body = self._imu_body
        body_rot = d.xmat[body].reshape(3, 3)
        velocity = np.zeros(6)
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, body, velocity, 0)
        omega, v_origin = velocity[:3], velocity[3:]      # world axes, at the body's origin
        imu_rot = body_rot @ self._imu_rotation
        v_imu = v_origin + np.cross(omega, body_rot @ self._imu_offset)
        q, dq, tau = self.joint_states()
        wrenches = {side: self._ground_wrench(side) if foot.force_torque_frame else None
                    for side, foot in self.profile.feet.items()}
        return SensorTruth(t=self.t, q=q, dq=dq, tau=tau,
                           imu_quat_xyzw=np.array(rotations.from_matrix(imu_rot)),
                           imu_velocity_world=v_imu, gyro_rad_s=imu_rot.T @ omega,
                           left_wrench=wrenches['l'], right_wrench=wrenches['r'])

    def _ground_wrench(self, side: str) -> np.ndarray:
        """The ground's reaction on one sole, about the sole origin, in the sole frame."""
        d = self.data
        body = self.feet[side]
        frame = d.xmat[body].reshape(3, 3)
        origin = d.xpos[body] + frame @ self._sole[side]
        rot = frame @ self._sole_rot[side]
        force, torque = np.zeros(3), np.zeros(3)
        for point, f in self._last_contacts[side]:
            force += f
            torque += np.cross(point - origin, f)
        return np.concatenate([rot.T @ force, rot.T @ torque])

    def render(self, width: int, height: int, target, yaw_deg: float, pitch_deg: float = -12.0,
               distance_m: float = 2.6) -> np.ndarray:
        """An RGB image (height, width, 3) of the world (MuJoCo's offscreen renderer: set
        ``MUJOCO_GL=egl`` or ``osmesa`` before MuJoCo is imported on a machine without a display),
        the camera ``distance_m`` from ``target``, looking along ``yaw_deg``, ``pitch_deg``
        (the angles as PyBullet's camera takes them, so that both engines' renders match)."""
        renderer = self._renderer
        if renderer is None or (renderer.width, renderer.height) != (width, height):
            self.model.vis.global_.offwidth = max(self.model.vis.global_.offwidth, width)
            self.model.vis.global_.offheight = max(self.model.vis.global_.offheight, height)
            renderer = self._renderer = mujoco.Renderer(self.model, height, width)
        camera = mujoco.MjvCamera()
        camera.lookat[:] = target
        camera.distance = distance_m
        camera.azimuth = yaw_deg - 90.0         # PyBullet's yaw 0 looks along +y; MuJoCo's along +x
        camera.elevation = pitch_deg
        renderer.update_scene(self.data, camera)
        return renderer.render().copy()

    # -- snapshots ---------------------------------------------------------------------------------
    def save_state(self) -> np.ndarray:
        """The world's full integration state (restored exactly by :meth:`restore`)."""
        spec = mujoco.mjtState.mjSTATE_INTEGRATION
        state = np.empty(mujoco.mj_stateSize(self.model, spec))
        mujoco.mj_getState(self.model, self.data, state, spec)
        return state

    def restore(self, state: np.ndarray, tick: int, measurement: Measurement) -> None:
        """Return to :meth:`save_state`'s snapshot taken at ``tick`` (its sample ``measurement``)."""
        mujoco.mj_setState(self.model, self.data, state, mujoco.mjtState.mjSTATE_INTEGRATION)
        mujoco.mj_forward(self.model, self.data)
        self.tick = tick
        self.t = tick * self.dt_s
        self._push.clear()
        self._prev = measurement

    def close(self) -> None:
        """Nothing to release (MuJoCo's model and data are freed with this object)."""

    def __enter__(self) -> 'MujocoWorld':
        return self

    def __exit__(self, *exc) -> None:
        self.close()


