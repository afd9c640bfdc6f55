"""The PyBullet world of a robot (the world seam's PyBullet engine, sim/world.py): stepping at the
physics step, pushes, the robot's servos, exact measurements.

One :class:`PybulletWorld` owns one PyBullet physics client (DIRECT by default, GUI on request).
:meth:`PybulletWorld.start` (the seam's) and :meth:`PybulletWorld.reset` (the engine's: a joint
vector and a base pose) build a fresh world (ground and robot) for each trajectory, so runs are
independent and reproducible: the same initial posture, controller and push give a bit-identical
trajectory. The robot's exact state is read in :mod:`fall_predictor.sim.pybullet_state`, its
sensors' in :mod:`fall_predictor.sim.pybullet_sensors`.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Optional, Sequence

import numpy as np
from fall_predictor.sim.pybullet_quiet import pb

from fall_predictor.monitor.records import STANDARD_GRAVITY_M_S2, Measurement, PushSpec
from fall_predictor.profiles.profile import DEFAULT_ROBOT, RobotProfile, load_profile
from fall_predictor.robot.actuation import ServoArrays, servo_arrays, servo_torques
from fall_predictor.robot.control import JointCommand
from fall_predictor.sim import pybullet_state
from fall_predictor.sim.urdf_loading import pybullet_urdf
from fall_predictor.sim.pushes import PushProtocol
from fall_predictor.sim.disturbances import FaultProtocol, start_height_m

GRAVITY = STANDARD_GRAVITY_M_S2
DT_S = 0.001
#: Half the side of a slab ground [m] (and half its thickness): far beyond any walk.
GROUND_HALF_EXTENT_M = 100.0
#: How far [m] the robot is lifted before a snapshot is restored (:meth:`PybulletWorld.restore`):
#: far above any link's reach of the ground, so no contact survives.
LIFT_BEFORE_RESTORE_M = 50.0
#: A posture without a base position starts this high [m], then is lowered onto the ground.
STAND_SEARCH_HEIGHT_M = 3.0
#: How far above the ground its lowest geometry then starts [m] (it settles in a step).
START_CLEARANCE_M = 0.001


@dataclass(frozen=True)
class PybulletConfig:
    dt_s: float = DT_S
    gui: bool = False
    #: Fewer than ~50 iterations leave a standing robot vibrating (momentum ~0.5 kg m/s) and
    #: its CoP millimetres off the CoM projection; see the README (speed).
    solver_iterations: int = 50
    ground_friction: float = 1.0
    foot_friction: float = 1.0
    #: 'pd_torque' (default): the robot's joint servos of robot/actuation.py (PD torque loops,
    #: torque-speed envelope, viscous friction, rotor armature). 'position': PyBullet's position
    #: motors (gain 0.4, effort-limited only), the robot of the results published before the
    #: stabilizer (docs/results.md says which figures used which).
    actuation: str = 'pd_torque'
    #: Scale of every servo's Kp and Kd with 'pd_torque'; 1 = the robot's real gains.
    servo_gain_scale: float = 1.0
    position_gain: float = 0.4
    velocity_gain: float = 1.0

    def __post_init__(self) -> None:
        if self.actuation not in ('position', 'pd_torque'):
            raise ValueError(f"actuation must be 'position' or 'pd_torque', got {self.actuation!r}")


class PybulletWorld:
    """The robot in a fresh PyBullet world; :meth:`step` applies joint targets and measures."""

    def __init__(self, profile: Optional[RobotProfile] = None, dt_s: Optional[float] = None,
                 config: PybulletConfig = PybulletConfig(), **options) -> None:
        """``profile``: the robot (default: the package's default robot); ``dt_s``: the physics
        step (default: ``config``'s, 1 ms); ``options``: :class:`PybulletConfig` fields that
        override ``config``'s (the world seam passes an engine's settings so)."""
        if dt_s is not None:
            options['dt_s'] = dt_s
        self.config = config = replace(config, **options) if options else config
        #: The simulated robot (its profile: URDF, feet, servo gains).
        self.profile = profile or load_profile(DEFAULT_ROBOT)
        self._urdf = str(pybullet_urdf(self.profile.sim_urdf_path))
        self.client = pb.connect(pb.GUI if config.gui else pb.DIRECT)
        if self.client < 0:
            raise RuntimeError('could not start a PyBullet physics client')
        self.robot = -1
        self.plane = -1
        self._ground_drawn = False
        self._boxes_ground = False
        self.t = 0.0
        self.tick = 0
        self._measured = None      # this step's PyBullet reads (measure)
        self._push = PushProtocol()
        self._push_force_world = np.zeros(3)
        self._prev_measurement: Optional[Measurement] = None
        self._targets = np.zeros(0)
        self._torques = np.zeros(0)
        #: Terrain boxes laid at each start (sim/disturbances.py) and their bodies; the fault.
        self._terrain: tuple = ()
        self.terrain_bodies: list[int] = []
        self.flush_bodies: frozenset = frozenset()
        self._fault = FaultProtocol()
        self._stuck = False
        #: The run's randomised world (sim/randomization.py), None: nominal; the drives it scaled.
        self._random = None
        self._scaled_servo: Optional[tuple] = None

    # -- world -------------------------------------------------------------------------
    def reset(self, joint_positions: Sequence[float], torso_position: Sequence[float],
              torso_yaw_rad: float = 0.0) -> Measurement:
        """A fresh world with the robot at rest in the given posture; returns the first sample."""
        c = self.client
        pb.resetSimulation(physicsClientId=c)
        pb.setGravity(0, 0, -GRAVITY, physicsClientId=c)
        pb.setTimeStep(self.config.dt_s, physicsClientId=c)
        pb.setPhysicsEngineParameter(numSolverIterations=self.config.solver_iterations,
                                     deterministicOverlappingPairs=1, physicsClientId=c)
        self._ground_drawn = False
        self.plane = self._ground()
        pb.changeDynamics(self.plane, -1, lateralFriction=self.config.ground_friction, physicsClientId=c)
        if self._terrain:
            from fall_predictor.sim.pybullet_terrain import add_box
            self.terrain_bodies = [add_box(c, box) for box in self._terrain]
        else:
            self.terrain_bodies = []
        #: Terrain bodies that are ground (flush with it: a slip's patch).
        self.flush_bodies = frozenset(b for b, box in zip(self.terrain_bodies, self._terrain) if box.flush)
        orn = pb.getQuaternionFromEuler((0, 0, torso_yaw_rad))
        # The base link frame at torso_position (PyBullet's base pose is its inertial frame).
        self.robot = pb.loadURDF(self._urdf, torso_position, orn,
                                 flags=pb.URDF_USE_INERTIA_FROM_FILE, physicsClientId=c)
        infos = [pb.getJointInfo(self.robot, i, physicsClientId=c)
                 for i in range(pb.getNumJoints(self.robot, physicsClientId=c))]
        #: The actuated joints (fixed joints of frames and sensors aside), in the URDF's order.
        self.joint_indices = [i for i, info in enumerate(infos) if info[2] != pb.JOINT_FIXED]
        self.joint_names = tuple(infos[i][1].decode() for i in self.joint_indices)
        self.n_joints = len(self.joint_indices)
        self.link_names = [info[12].decode() for info in infos]
        self.link_index = {name: i for i, name in enumerate(self.link_names)}
        #: Each link's parent link (-1: the base), and the base's inertial frame origin in its
        #: link frame: read once here, used every step (sim/pybullet_sensors.sensor_truth).
        self.link_parent = [info[16] for info in infos]
        self.base_inertial_xyz = np.asarray(pb.getDynamicsInfo(self.robot, -1, physicsClientId=c)[3])
        if self.joint_names != self.profile.joint_names:
            raise RuntimeError(f'PyBullet numbers the joints {self.joint_names}, not in the URDF\'s '
                               f'order {self.profile.joint_names}')
        self.foot_links = {side: self.link_index[foot.foot_link]
                           for side, foot in self.profile.feet.items()}
        self.servo: ServoArrays = servo_arrays(self.config.servo_gain_scale, self.profile,
                                               self.joint_names)
        pb.changeDynamics(self.robot, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=c)
        for k, i in enumerate(self.joint_indices):
            # method §2: no link (air) damping. The drive's viscous friction acts in step(); its
            # rotor's reflected inertia (armature) is added to the driven link's inertia about the
            # joint axis (exact for that joint; proximal joints see it too, a few % of theirs).
            info = pb.getJointInfo(self.robot, i, physicsClientId=c)
            dynamics = pb.getDynamicsInfo(self.robot, i, physicsClientId=c)
            inertia = np.array(dynamics[2])
            if self.config.actuation == 'pd_torque':
                if np.allclose(dynamics[4], (0.0, 0.0, 0.0, 1.0)):
                    # Principal axes along the link frame's: the armature about the joint axis.
                    inertia += self.servo.armature[k] * np.abs(np.asarray(info[13]))
                else:
                    # Rotated principal axes (PyBullet takes a diagonal only): the armature on
                    # every principal moment, exact about the joint axis (sum of u_i^2 = 1).
                    inertia += self.servo.armature[k]
            pb.changeDynamics(self.robot, i, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0,
                              localInertiaDiagonal=inertia.tolist(), physicsClientId=c)
        for link in self.foot_links.values():
            pb.changeDynamics(self.robot, link, lateralFriction=self.config.foot_friction, physicsClientId=c)
        if self._random is not None:
            from fall_predictor.sim.pybullet_terrain import randomize_dynamics
            randomize_dynamics(self, self._random, len(infos))
        for i, q in zip(self.joint_indices, joint_positions):
            pb.resetJointState(self.robot, i, q, 0.0, physicsClientId=c)
        if self.config.actuation == 'pd_torque':
            # Torque control: switch PyBullet's default velocity motors off.
            pb.setJointMotorControlArray(self.robot, self.joint_indices, pb.VELOCITY_CONTROL,
                                         forces=[0.0] * self.n_joints, physicsClientId=c)
        #: The bodies with mass (base, then the links; massless frame links add nothing to the
        #: CoM or the momenta) and the feet, measured every step.
        self.bodies = [-1] + [i for i in range(len(infos))
                              if pb.getDynamicsInfo(self.robot, i, physicsClientId=c)[0] > 0.0
                              or i in self.foot_links.values()]
        self._row = {link: row for row, link in enumerate(self.bodies[1:])}
        self.masses = np.array([pb.getDynamicsInfo(self.robot, i, physicsClientId=c)[0]
                                for i in self.bodies])
        self.inertias = np.array([pb.getDynamicsInfo(self.robot, i, physicsClientId=c)[2]
                                  for i in self.bodies])
        self._sole_offsets = {side: np.asarray(foot.sole_origin_in_foot_m)
                              for side, foot in self.profile.feet.items()}
        #: The sole frames' axes in the foot links' (None: the same axes, the common case).
        self._sole_rotations = {side: None if not any(foot.sole_rpy_in_foot_rad)
                                else foot.sole_rotation_in_foot()
                                for side, foot in self.profile.feet.items()}
        self.total_mass = float(self.masses.sum())
        self.t = 0.0
        self.tick = 0
        self._measured = None      # this step's PyBullet reads (measure)
        self._push.clear()
        self._push_force_world = np.zeros(3)
        self._fault.clear()
        self._stuck = False
        self._prev_measurement = None
        self.set_joint_targets(joint_positions)
        self._torques = np.zeros(self.n_joints)
        self._read_joints()
        return self.measure()

    def _ground(self) -> int:
        """The ground body: the profile's plane or slab, its top face at z = 0; around a flush
        terrain box (a slip's patch), level boxes in their place (pybullet_terrain.ground_of_boxes)."""
        c = self.client
        if self._terrain:
            from fall_predictor.sim.pybullet_terrain import ground_of_boxes
            body = ground_of_boxes(c, self._terrain)
            if body >= 0:
                self._boxes_ground = True
                if self.config.gui:
                    self.draw_ground()
                return body
        self._boxes_ground = False
        if self.profile.sim_ground != 'slab':
            return pb.createMultiBody(0, pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=c),
                                      physicsClientId=c)
        # A slab 200 m square. An infinite plane's bounding box overlaps every link's, so PyBullet
        # tested each of the G1's 24 mesh hulls against it every step (0.20 ms of a 0.69 ms step);
        # the slab's lets it skip the links above it. A body without a visual shape is drawn as
        # its collision shape: the slab gets a speck below the ground instead (draw_ground).
        half = GROUND_HALF_EXTENT_M
        slab = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[half, half, half],
                                       collisionFramePosition=[0.0, 0.0, -half], physicsClientId=c)
        speck = pb.createVisualShape(pb.GEOM_SPHERE, radius=1e-3, visualFramePosition=[0.0, 0.0, -1.0],
                                     physicsClientId=c)
        body = pb.createMultiBody(0, slab, speck, physicsClientId=c)
        if self.config.gui:
            self.draw_ground()
        return body

    def draw_ground(self) -> None:
        """Show a slab ground as the checkerboard plane a plane ground is drawn as (a plane that
        collides with nothing), for the GUI and for rendered frames (once per world)."""
        if (self.profile.sim_ground != 'slab' and not self._boxes_ground) or self._ground_drawn:
            return
        self._ground_drawn = True
        from fall_predictor.sim.pybullet_terrain import GROUND_DRAWN_BELOW_M, draw_ground_plane
        draw_ground_plane(self.client, -GROUND_DRAWN_BELOW_M if self._boxes_ground else 0.0)

    def restore(self, state: int, tick: int, measurement: Measurement) -> None:
        """Return to a ``pybullet.saveState`` snapshot taken at ``tick`` (its sample
        ``measurement``), whatever was simulated since.

        ``restoreState`` writes the saved contact points into the contact manifolds that exist
        when it is called, matched by body pair. A link with several collision shapes (the G1's
        four sole spheres: one manifold per sphere, all of one pair) is given one of them, and
        which one depends on the order the manifolds were made in since the snapshot: the
        continuation then depended on the trajectories simulated before it. So the robot is
        first lifted clear of the ground and the contacts recomputed, which drops every
        manifold: the restore then meets the same fresh ones each time. A robot with one
        shape per link (the ASIMO-like one) continues bit for bit as if never interrupted.
        """
        c = self.client
        position, orientation = pb.getBasePositionAndOrientation(self.robot, physicsClientId=c)
        clear = [position[0], position[1], position[2] + LIFT_BEFORE_RESTORE_M]
        pb.resetBasePositionAndOrientation(self.robot, clear, orientation, physicsClientId=c)
        pb.performCollisionDetection(physicsClientId=c)
        pb.restoreState(state, physicsClientId=c)
        # The clock and the last sample are the snapshot's, with no push pending.
        self.tick = tick
        self._measured = None      # this step's PyBullet reads (measure)
        self.t = tick * self.config.dt_s
        self._push.clear()
        self._push_force_world = np.zeros(3)
        self._prev_measurement = measurement
        self._read_joints()
        self._torques = np.zeros(self.n_joints)

    def close(self) -> None:
        if self.client >= 0:
            pb.disconnect(self.client)
            self.client = -1

    def __enter__(self) -> 'PybulletWorld':
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- actuation ---------------------------------------------------------------------
    def set_joint_targets(self, positions: Sequence[float]) -> None:
        """Position targets [rad] of the 26 joint servos (held until the next call)."""
        targets = np.asarray(positions, dtype=float)
        if targets.shape != (self.n_joints,) or not np.isfinite(targets).all():
            raise ValueError(f'expected {self.n_joints} finite joint targets')
        self._targets = targets.copy()
        if self.config.actuation == 'position':
            n = self.n_joints
            pb.setJointMotorControlArray(self.robot, self.joint_indices, pb.POSITION_CONTROL,
                                         targetPositions=targets.tolist(),
                                         forces=self.servo.effort.tolist(),
                                         positionGains=[self.config.position_gain] * n,
                                         velocityGains=[self.config.velocity_gain] * n,
                                         physicsClientId=self.client)

    def schedule_push(self, push: PushSpec) -> None:
        """Apply ``push`` when simulation time reaches ``push.t_push`` (one push at a time)."""
        self._push.schedule(push)

    def _update_push(self) -> None:
        if self._push.push is None or self.t < self._push.push.t_push - 1e-9:
            self._push_force_world = np.zeros(3)
            return
        base_pos, base_orn = pb.getBasePositionAndOrientation(self.robot, physicsClientId=self.client)
        rot = np.array(pb.getMatrixFromQuaternion(base_orn)).reshape(3, 3)
        com = self._prev_measurement.com if self._prev_measurement is not None else None
        applied = self._push.force_at(self.t, np.asarray(base_pos), rot, com)
        if applied is None:
            self._push_force_world = np.zeros(3)
            return
        self._push_force_world, point_world = applied
        pb.applyExternalForce(self.robot, -1, self._push_force_world.tolist(), point_world.tolist(),
                              pb.WORLD_FRAME, physicsClientId=self.client)

    # -- the world seam (sim/world.py) ---------------------------------------------------------
    @property
    def dt_s(self) -> float:
        return self.config.dt_s

    def start(self, posture) -> Measurement:
        """A fresh world with the robot at rest in ``posture`` (robot/control.Posture): at its
        base position (C_bal gives one), or with none (a learned policy's posture) standing with
        its lowest geometry just above the ground, as in MuJoCo."""
        q0 = [posture.joint_angles.get(name, 0.0) for name in self.profile.joint_names]
        if posture.base_position_m is not None:
            x, y, z = posture.base_position_m
            return self.reset(q0, (x, y, z + start_height_m(self._terrain, (x, y))), posture.base_yaw_rad)
        self.reset(q0, (0.0, 0.0, STAND_SEARCH_HEIGHT_M), posture.base_yaw_rad)
        c = self.client
        gaps = [point[8] for body in (self.plane, *self.terrain_bodies)
                for point in pb.getClosestPoints(self.robot, body, STAND_SEARCH_HEIGHT_M, physicsClientId=c)]
        if not gaps:
            raise ValueError(f'{self.profile.source}: no geometry of the robot within '
                             f'{STAND_SEARCH_HEIGHT_M} m of the ground in its starting posture')
        position, orientation = pb.getBasePositionAndOrientation(self.robot, physicsClientId=c)
        lowered = (position[0], position[1], position[2] - min(gaps) + START_CLEARANCE_M)
        pb.resetBasePositionAndOrientation(self.robot, lowered, orientation, physicsClientId=c)
        self._measured = None
        self._prev_measurement = None
        self._read_joints()
        return self.measure()

    def apply(self, command) -> None:
        """Hold ``command`` (robot/control.JointCommand): its targets, tracked by the robot's
        servos (the profile's table; a command with its own gains is tracked by those, within the
        drives' envelope; a joint it does not name keeps its target and gains)."""
        if command.joint_names != self.joint_names:
            gains = (self.servo.kp, self.servo.kd) if command.has_gains else (None, None)
            command = command.fit_onto(self.joint_names,
                                       JointCommand(self.joint_names, self._targets, *gains))
        if command.has_gains and not (np.array_equal(command.kp, self.servo.kp)
                                      and np.array_equal(command.kd, self.servo.kd)):
            self.servo = replace(self.servo, kp=np.array(command.kp), kd=np.array(command.kd))
        self.set_joint_targets(command.targets_rad)

    def sensor_truth(self):
        """The exact sensor quantities of the current state (sim/sensors.py)."""
        from fall_predictor.sim.pybullet_sensors import sensor_truth
        return sensor_truth(self)

    def render(self, width: int, height: int, target: Sequence[float], yaw_deg: float,
               pitch_deg: float = -12.0, distance_m: float = 2.6) -> np.ndarray:
        """An RGB image (height, width, 3) of the world (PyBullet's TinyRenderer, headless),
        the camera ``distance_m`` from ``target``, looking along ``yaw_deg``, ``pitch_deg``."""
        c = self.client
        self.draw_ground()
        view = pb.computeViewMatrixFromYawPitchRoll(
            cameraTargetPosition=[float(v) for v in target], distance=distance_m, yaw=yaw_deg,
            pitch=pitch_deg, roll=0.0, upAxisIndex=2, physicsClientId=c)
        proj = pb.computeProjectionMatrixFOV(fov=45.0, aspect=width / height, nearVal=0.05,
                                             farVal=10.0, physicsClientId=c)
        _, _, rgba, _, _ = pb.getCameraImage(width, height, view, proj,
                                             renderer=pb.ER_TINY_RENDERER, physicsClientId=c)
        return np.reshape(np.asarray(rgba, dtype=np.uint8), (height, width, 4))[:, :, :3]

    def set_randomization(self, randomization) -> None:
        """Randomise the world (sim/randomization.WorldRandomization) from the next :meth:`start`
        on; None: the nominal world."""
        if randomization is not None and self.config.actuation != 'pd_torque':
            raise ValueError("domain randomisation needs the torque drives (actuation 'pd_torque')")
        self._random = randomization

    def _drives(self) -> ServoArrays:
        """The servo arrays the drives run with: the robot's, scaled by the randomisation."""
        if self._random is None:
            return self.servo
        if self._scaled_servo is None or self._scaled_servo[0] is not self.servo:
            kp, kd, limit = self._random.drive_scales()
            self._scaled_servo = (self.servo, replace(self.servo, kp=self.servo.kp * kp, kd=self.servo.kd * kd,
                                                      effort=self.servo.effort * limit))
        return self._scaled_servo[1]

    def set_terrain(self, boxes) -> None:
        """Lay ``boxes`` (sim/disturbances.TerrainBox) from the next :meth:`start` on."""
        self._terrain = tuple(boxes)

    def terrain_contacts(self) -> list:
        """The robot's loaded contacts with the terrain boxes (sim/world.TerrainContact)."""
        from fall_predictor.sim.pybullet_terrain import terrain_contacts
        return terrain_contacts(self)

    def schedule_fault(self, fault) -> None:
        """Fail ``fault``'s joint drive from its start (sim/disturbances.JointFault)."""
        if fault is not None and self.config.actuation != 'pd_torque':
            raise ValueError("an actuator fault needs the torque drives (actuation 'pd_torque')")
        self._fault.schedule(fault, self.joint_names)
        self._stuck = False

    def save_state(self) -> int:
        """A snapshot of the world to :meth:`restore` later."""
        return pb.saveState(physicsClientId=self.client)

    # -- stepping and measuring ------------------------------------------------------------
    def step(self) -> Measurement:
        """Advance one physics step (pushes applied) and measure the new state."""
        self._update_push()
        applied = self._push_force_world.copy()
        if self.config.actuation == 'pd_torque':
            # The servos close their loops on the joint state at the start of the step; a faulty
            # drive gives a share of its torque (sim/disturbances.py).
            self._torques = self._fault.torques(
                self.t, servo_torques(self._drives(), self._targets, self._q, self._dq))
            if not self._stuck and (stuck := self._fault.stuck_joint(self.t, self._q)) is not None:
                from fall_predictor.sim.pybullet_terrain import lock_joint
                lock_joint(self, *stuck)
                self._stuck = True
            # The joint sees the motor torque and the drive's viscous friction.
            joint_torques = self._torques - self.servo.damping * self._dq
            pb.setJointMotorControlArray(self.robot, self.joint_indices, pb.TORQUE_CONTROL,
                                         forces=joint_torques.tolist(), physicsClientId=self.client)
        pb.stepSimulation(physicsClientId=self.client)
        self._read_joints()
        self.tick += 1
        self.t = self.tick * self.config.dt_s
        m = self.measure()
        m.push_force = applied
        return m

    def _read_joints(self) -> None:
        states = pb.getJointStates(self.robot, self.joint_indices, physicsClientId=self.client)
        n = len(states)
        self._q = np.fromiter((s[0] for s in states), float, n)
        self._dq = np.fromiter((s[1] for s in states), float, n)
        if self.config.actuation == 'position' and self._torques.size:
            self._torques = np.array([s[3] for s in states])

    def joint_states(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Joint positions [rad], velocities [rad/s] and the motor torques [N m] of the last step."""
        return self._q.copy(), self._dq.copy(), self._torques.copy()

    # -- the robot's exact state (sim/pybullet_state.py) ----------------------------------------
    def link_frame_pose(self, link: int) -> tuple[tuple, tuple]:
        """World position and quaternion (x, y, z, w) of ``link``'s frame at the current step."""
        return pybullet_state.link_frame_pose(self, link)

    def ground_contacts(self) -> tuple:
        """PyBullet's contact points between the robot and the ground at the current step."""
        return pybullet_state.ground_contacts(self)

    def measure(self) -> Measurement:
        """CoM, momenta about the CoM, heading, contacts and CoP of the current state."""
        return pybullet_state.measure(self)
