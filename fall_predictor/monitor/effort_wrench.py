"""Foot wrenches from the legs' joint efforts, for robots without foot force/torque sensors
(method §10).

Each leg is the chain of joints that moves its sole and no other (hip to ankle), found in the
description's kinematic tree. For the floating-base model ``M a + b(q, v) = tau + J_s^T F`` with
``F`` the ground's wrench on the sole (force and moment about the sole origin, in the sole frame,
as an F/T sensor reports it) and ``J_s`` the sole frame's Jacobian (LOCAL), the rows of the leg's
joints, with the legs' own accelerations neglected, give

    J_leg^T F = b_leg(q, v) - tau_leg

where ``b`` is the gravity and velocity torque of every link beyond each joint (the legs' own
weight, with the base oriented as estimated: gravity acts along the world's z). With six joints
per leg the system is square; it is solved in the least-squares sense, so a straight knee (a
singular ``J_leg``) yields the minimum-norm wrench instead of an explosion. What it cannot see:
the leg's inertial torques (a fast swing reads as a few newtons of contact force) and joint
friction the effort does not include.

With no efforts at all, :meth:`EffortWrench.kinematic` takes the contacts from the kinematics and
the forces from statics: the soles within ``contact_height_m`` of the lowest one are on the ground,
the robot's weight is shared between them by the lever rule along the line through their centres,
and each sole's CoP is the CoM's ground projection clamped into the sole. It tells support and
stance, not how near an edge the CoP is beyond what the CoM says.
"""
from __future__ import annotations

from typing import Optional

import numpy as np
import pinocchio as pin

from fall_predictor.monitor.robot_description import (SIDES, DescriptionError, RobotDescription,
                                                     slice_if_consecutive)

_LOCAL = pin.ReferenceFrame.LOCAL

try:
    # numpy's LU solve itself: np.linalg.solve's checks and error-state handling cost twice the
    # solve of two 6 x 6 systems (~2.7 of ~4 us), once per 1 kHz sample. A singular system gives
    # NaN instead of raising (EffortWrench.wrenches then solves it in the least-squares sense).
    # Where a numpy release moves it, the public function is used.
    from numpy.linalg._umath_linalg import solve as _solve
except ImportError:                                     # pragma: no cover - numpy internals
    _solve = np.linalg.solve


def leg_joint_ids(robot: RobotDescription, side: str) -> list[int]:
    """Model joint ids of the joints that move sole ``side`` and not the other one."""
    model = robot.model
    chains = {s: set(model.supports[model.frames[robot.sole_ids[s]].parentJoint]) for s in SIDES}
    other = next(s for s in SIDES if s != side)
    # Joint 0 is the universe and 1 the floating base: shared by both soles, never in a leg.
    return sorted(j for j in chains[side] - chains[other] if j > 1)


class EffortWrench:
    """The ground's wrench on each sole from one sample's joint efforts (module docs)."""

    def __init__(self, robot: RobotDescription) -> None:
        self.robot = robot
        self.data = robot.model.createData()          # its own: the estimator's stays untouched
        self.leg_v: dict[str, np.ndarray] = {}
        for side in SIDES:
            ids = leg_joint_ids(robot, side)
            if len(ids) < 6:
                raise DescriptionError(
                    f'the {"left" if side == "l" else "right"} leg has {len(ids)} joints of its own '
                    'in the URDF: estimating its foot wrench from joint efforts needs 6')
            self.leg_v[side] = np.array([robot.model.joints[j].idx_v for j in ids], dtype=np.int64)
        # Indices into the description's joint order (efforts arrive in that order).
        v_to_joint = {int(v): k for k, v in enumerate(robot.idx_v)}
        self.leg_tau = {side: np.array([v_to_joint[int(v)] for v in self.leg_v[side]])
                        for side in SIDES}
        self._zero_a = np.zeros(robot.model.nv)
        self._square = all(len(self.leg_v[side]) == 6 for side in SIDES)
        # The legs' columns: a slice when they are consecutive (cheaper than an index array).
        self._leg_cols = {side: slice_if_consecutive(cols) for side, cols in self.leg_v.items()}
        # Per leg: its sole frame and Jacobian columns; both legs' rows of b and of the efforts.
        self._jac_cols = tuple((robot.sole_ids[side], self._leg_cols[side]) for side in SIDES)
        self._b_rows = np.concatenate([self.leg_v[side] for side in SIDES])
        self._tau_rows = np.concatenate([self.leg_tau[side] for side in SIDES])
        self._a = np.zeros((len(SIDES), 6, 6))
        # A directly solved wrench beyond this (a hundred body weights, squared) comes from a
        # near-singular leg: solved again in the least-squares sense.
        self._max_wrench_sq = (100.0 * robot.total_mass_kg * 9.81) ** 2

    def wrenches(self, q: np.ndarray, v: np.ndarray,
                 tau_joints: np.ndarray) -> dict[str, Optional[np.ndarray]]:
        """Per side the wrench (fx, fy, fz, tx, ty, tz) in the sole frame; ``q``, ``v``: the full
        configuration (any base position, the base oriented as estimated: gravity acts along the
        world's z) and velocity (the base part: its angular velocity in the base frame),
        ``tau_joints``: efforts [N m] in the description's joint order."""
        model, data = self.robot.model, self.data
        b = pin.nonLinearEffects(model, data, q, v)
        # Each sole's Jacobian from its own chain (cheaper than every joint's Jacobian).
        jacobians = [pin.computeFrameJacobian(model, data, q, sole_id, _LOCAL)
                     for sole_id, _ in self._jac_cols]
        out: dict[str, Optional[np.ndarray]] = {}
        if self._square:
            # Both legs' 6 x 6 systems in one call; a leg near a singularity (a straight knee)
            # gets the least-squares, minimum-norm answer below instead.
            a = self._a
            for k, (_, cols) in enumerate(self._jac_cols):
                a[k] = jacobians[k][:, cols].T
            rhs = (b[self._b_rows] - tau_joints[self._tau_rows]).reshape(len(SIDES), 6, 1)
            try:
                with np.errstate(invalid='ignore', divide='ignore'):   # singular: NaN, see below
                    solved = _solve(a, rhs).reshape(len(SIDES), 6)
            except np.linalg.LinAlgError:                   # the public function raises instead
                solved = np.full((len(SIDES), 6), np.nan)
            norm_sq = (solved * solved).sum(axis=1).tolist()       # NaN if not finite
            for k, side in enumerate(SIDES):
                if norm_sq[k] < self._max_wrench_sq:
                    out[side] = solved[k]
        for k, side in enumerate(SIDES):
            if side not in out:
                wrench, *_ = np.linalg.lstsq(jacobians[k][:, self.leg_v[side]].T,
                                             b[self.leg_v[side]] - tau_joints[self.leg_tau[side]],
                                             rcond=1e-6)
                out[side] = wrench if np.isfinite(wrench).all() else None
        return out

    def kinematic(self, com: np.ndarray, sole_pos: dict, sole_rot: dict,
                  contact_height_m: float) -> dict[str, Optional[np.ndarray]]:
        """Per side a static wrench (module docs) or None for a sole in the air; ``com``,
        ``sole_pos`` and ``sole_rot``: the CoM and the soles relative to the base origin, world
        axes (the estimator's)."""
        lowest = min(sole_pos[side][2] for side in SIDES)
        down = [side for side in SIDES if sole_pos[side][2] <= lowest + contact_height_m]
        weight_n = self.robot.total_mass_kg * 9.81
        share = {side: 1.0 for side in down}
        if len(down) == 2:
            a, b = sole_pos['l'][:2], sole_pos['r'][:2]
            ab = b - a
            lam = float(np.clip((com[:2] - a) @ ab / max(ab @ ab, 1e-12), 0.0, 1.0))
            share = {'l': 1.0 - lam, 'r': lam}
        out: dict[str, Optional[np.ndarray]] = {side: None for side in SIDES}
        for side in down:
            sole = self.robot.soles[side]
            local = sole_rot[side].T @ (com - sole_pos[side])   # CoM in the sole frame
            cop = np.clip(local[:2], [-sole.length_m / 2, -sole.width_m / 2],
                          [sole.length_m / 2, sole.width_m / 2])
            fz = share[side] * weight_n
            out[side] = np.array([0.0, 0.0, fz, cop[1] * fz, -cop[0] * fz, 0.0])
        return out
