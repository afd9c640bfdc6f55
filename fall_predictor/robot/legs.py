"""Leg inverse kinematics of any robot profile: where the controller's leg joints go so that each
sole reaches its target pose with the base at its pose.

Two solvers behind one interface (:class:`LegSolver`):

- :class:`ClosedFormLegs`, for legs whose three hip axes meet in a point and whose two ankle axes
  meet in a point, in the order hip yaw, roll, pitch, knee, ankle pitch, roll (the ASIMO-like
  robot): the closed form of robot/kinematics.py, its geometry read from the URDF;
- :class:`NumericLegs`, for any 6-joint leg (the G1's hip pitch-roll-yaw with offset axes):
  damped least squares on Pinocchio's sole-frame Jacobian, warm-started from the last two
  solutions of the same leg and the same ``stream`` (extrapolated), so that at 1 kHz one or two
  iterations suffice. A controller that solves one leg twice a tick for different base
  attitudes (the reflex step's swing leg: upright, and for the measured tilt) names each a
  stream: extrapolating from the other one's solution started the solver 0.4 rad off, and near
  the leg's reach it ended on another branch, the hip at its limits (a G1 launched into the air).

Both take the base (the URDF's root link) pose and each sole's target pose in the world, and
return the six leg angles in the profile's leg order (``joint_groups.<side>_leg``).
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np
import pinocchio as pin
from scipy.linalg import lapack

from fall_predictor.monitor.robot_description import SIDES, RobotDescription
from fall_predictor.profiles.profile import RobotProfile
from fall_predictor.robot import kinematics as kin


class LegSolver:
    """The interface: :meth:`solve` and the indices of each leg's joints in the robot's joint
    vector (the URDF order)."""

    def __init__(self, profile: RobotProfile, robot: RobotDescription) -> None:
        self.profile = profile
        self.robot = robot
        #: The controller's joint order (the simulator URDF's), and each leg's indices in it.
        self.joint_names = profile.joint_names
        self.leg_indices = {side: np.array([self.joint_names.index(j) for j in profile.leg_joints(side)])
                            for side in SIDES}

    def solve(self, side: str, base_pos: np.ndarray, base_rot: np.ndarray, sole_pos: np.ndarray,
              sole_rot: np.ndarray, stream: str = 'upright') -> np.ndarray:
        """The six leg angles [rad] of ``side`` that put its sole at ``sole_pos``, ``sole_rot``
        (world) with the base at ``base_pos``, ``base_rot``; ``stream`` names a sequence of
        solves that moves smoothly from tick to tick (module docs)."""
        raise NotImplementedError


class ClosedFormLegs(LegSolver):
    """Closed-form IK (module docs); the hip and ankle centres and the link lengths from the URDF."""

    def __init__(self, profile: RobotProfile, robot: RobotDescription) -> None:
        super().__init__(profile, robot)
        model = robot.model
        self.hip_in_base, self.ankle_in_sole = {}, {}
        lengths = []
        for side in SIDES:
            joints = [model.getJointId(j) for j in profile.leg_joints(side)]
            # Read from the joint placements themselves (exact, not through a chain of products):
            # the hip centre in the base, the knee from the hip, the ankle from the knee.
            self.hip_in_base[side] = model.jointPlacements[joints[0]].translation.copy()
            thigh, shank = (math.hypot(*model.jointPlacements[joints[i]].translation) for i in (3, 4))
            lengths.append((thigh, shank))
            # The ankle centre (the ankle roll joint's origin) seen from the sole frame.
            self.ankle_in_sole[side] = model.frames[robot.sole_ids[side]].placement.inverse().translation.copy()
        self.thigh_m, self.shank_m = lengths[0]

    def solve(self, side, base_pos, base_rot, sole_pos, sole_rot, stream='upright'):
        hip = base_pos + base_rot @ self.hip_in_base[side]
        ankle = sole_pos + sole_rot @ self.ankle_in_sole[side]
        return kin.leg_ik(hip, base_rot, ankle, sole_rot, self.thigh_m, self.shank_m)


#: The streams a controller may solve each leg in per tick (:meth:`LegSolver.solve`).
STREAMS = ('upright', 'tilted')

#: The error of a solve that made no iteration (read only).
_UNSOLVED = np.full(6, np.inf)


def _clip(x: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """``np.clip`` of finite values, without its ~5 us of argument handling (twice a solve)."""
    return np.minimum(np.maximum(x, lower), upper)


class NumericLegs(LegSolver):
    """Damped least squares on the sole frame (module docs), each leg on a model of its own chain
    (the base and the six leg joints; the rest locked at zero), so the forward kinematics of an
    iteration visits 7 joints, not the whole robot's."""

    def __init__(self, profile: RobotProfile, robot: RobotDescription, tolerance_m: float = 1e-5,
                 max_iterations: int = 20, damping: float = 1e-4) -> None:
        super().__init__(profile, robot)
        self.tolerance_m = tolerance_m
        self.max_iterations = max_iterations
        self.damping = damping
        self._chains = {side: _LegChain.of(robot, profile.leg_joints(side), robot.sole_ids[side])
                        for side in SIDES}
        #: Per (side, stream): the last two solutions and the side's solve count at the last.
        self._streams: dict[tuple[str, str], tuple[np.ndarray, Optional[np.ndarray], int]] = {}
        self._count = {side: 0 for side in SIDES}
        self._eye = np.eye(6)
        self.last_error = 0.0

    def solve(self, side, base_pos, base_rot, sole_pos, sole_rot, stream='upright'):
        chain = self._chains[side]
        target = pin.SE3(base_rot, base_pos).actInv(pin.SE3(sole_rot, sole_pos))   # in the base
        self._count[side] = count = self._count[side] + 1
        leg, previous, last_count = self._streams.get((side, stream), (None, None, 0))
        if leg is not None and count - last_count > len(STREAMS):
            leg = previous = None           # not solved on the last tick: its motion is stale
        if leg is None:
            # The side's latest solution in any stream, else the neutral pose.
            latest = max((entry for key, entry in self._streams.items() if key[0] == side),
                         key=lambda entry: entry[2], default=None)
            start = np.clip(0.0, chain.lower, chain.upper) if latest is None else latest[0]
        elif previous is None:
            start = leg
        else:
            # Targets move smoothly at 1 kHz: the last step's motion, repeated, is most often
            # within tolerance already (one forward kinematics, no Jacobian).
            start = _clip(2.0 * leg - previous, chain.lower, chain.upper)
        solution, err = self._iterate(chain, target, start)
        if not err < self.tolerance_m and previous is not None:
            # Not converged from the extrapolation: from the last solution itself, if better.
            again, err_again = self._iterate(chain, target, leg)
            if err_again < err:
                solution, err = again, err_again
        self.last_error = err
        self._streams[(side, stream)] = (solution, leg, count)
        return solution.copy()

    def _iterate(self, chain: '_LegChain', target: pin.SE3, start: np.ndarray
                 ) -> tuple[np.ndarray, float]:
        """Damped least squares from ``start``: the leg angles and their pose error (inf: none)."""
        model, data, q, frame = chain.model, chain.data, chain.q, chain.frame
        iq, iv, lower, upper = chain.q_index, chain.v_index, chain.lower, chain.upper
        tolerance, damped, local = self.tolerance_m, self.damping * self._eye, pin.ReferenceFrame.LOCAL
        q[iq] = start
        err = _UNSOLVED
        for _ in range(self.max_iterations):
            pin.computeJointJacobians(model, data, q)       # and the joints' placements
            current = pin.updateFramePlacement(model, data, frame)
            relative = current.actInv(target)
            err = pin.log6(relative).vector
            if float(np.abs(err).max()) < tolerance:     # NaN: not converged
                break
            jac = pin.Jlog6(relative) @ pin.getFrameJacobian(model, data, frame, local)[:, iv]
            jac_t = jac.T
            # The damped normal equations are symmetric positive definite: LAPACK's Cholesky
            # solve, called directly (numpy's solve costs ~5x as much through its call path).
            _, step, info = lapack.dposv(jac_t @ jac + damped, jac_t @ err)
            if info != 0:                   # not finite: no step (the clip keeps the last q)
                break
            q[iq] = _clip(q[iq] + step, lower, upper)
        error = float(np.abs(err).max())
        return q[iq].copy(), (error if error == error else math.inf)      # NaN: no solution


class _LegChain:
    """One leg's own model: the robot with every joint but the root and the leg's locked at zero
    (their neutral), its data, the sole frame and the leg joints' indices and limits."""

    def __init__(self, model: pin.Model, frame: int, leg_joints: tuple[str, ...]) -> None:
        self.model, self.data, self.frame = model, model.createData(), frame
        ids = [model.getJointId(j) for j in leg_joints]
        self.iq = np.array([model.joints[i].idx_q for i in ids])
        self.iv = np.array([model.joints[i].idx_v for i in ids])
        # A leg's joints are consecutive in its chain's model: slices (views, not copies).
        self.q_index, self.v_index = _as_slice(self.iq), _as_slice(self.iv)
        self.lower = model.lowerPositionLimit[self.iq]
        self.upper = model.upperPositionLimit[self.iq]
        self.q = pin.neutral(model)

    @classmethod
    def of(cls, robot: RobotDescription, leg_joints: tuple[str, ...], sole_frame: int) -> '_LegChain':
        full = robot.model
        keep = {full.getJointId(j) for j in leg_joints}
        root = 1 if full.joints[1].shortname() == 'JointModelFreeFlyer' else None
        lock = [j for j in range(1, full.njoints) if j not in keep and j != root]
        model = pin.buildReducedModel(full, lock, pin.neutral(full))
        return cls(model, model.getFrameId(full.frames[sole_frame].name), leg_joints)


def _as_slice(indices: np.ndarray):
    """``indices`` as a slice when they are consecutive (the same elements), else themselves."""
    first = int(indices[0])
    consecutive = np.array_equal(indices, np.arange(first, first + len(indices)))
    return slice(first, first + len(indices)) if consecutive else indices


def leg_solver(profile: RobotProfile) -> LegSolver:
    """The closed form where the legs allow it (hip and ankle axes meeting in points), else numeric."""
    robot = profile.sensor_layout().description(profile.urdf_xml())
    return ClosedFormLegs(profile, robot) if _closed_form_applies(profile, robot) else NumericLegs(profile, robot)


def _closed_form_applies(profile: RobotProfile, robot: RobotDescription) -> bool:
    model = robot.model
    for side in SIDES:
        joints = [model.getJointId(j) for j in profile.leg_joints(side)]
        # Consecutive hip joints (and the two ankle joints) at one point: zero offsets between them.
        for b in (1, 2, 5):
            if np.linalg.norm(model.jointPlacements[joints[b]].translation) > 1e-9:
                return False
        axes = []
        for j in joints:
            name = model.joints[j].shortname()
            axes.append(name[-1] if name.startswith('JointModelR') and name[-1] in 'XYZ' else '?')
        if axes != ['Z', 'X', 'Y', 'Y', 'Y', 'X']:
            return False
    return True
