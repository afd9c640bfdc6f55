"""Each sole's ground reaction for the state estimator (method §10): a wrench (fx, fy, fz [N],
tx, ty, tz [N m] about the sole origin) in the sole frame, as plain floats.

A foot with a force/torque sensor gives its reading, expressed in the sample's frame for that
foot (any frame of the robot description; empty: the sole frame) and carried to the sole frame.
A foot without one (``effort_feet``) takes its wrench from the leg's joint efforts when the sample
has an effort for every joint, else from the kinematics and statics
(:mod:`~fall_predictor.monitor.effort_wrench`). A missing or non-finite reading is no wrench
(the foot counts as unloaded); a frame the description lacks raises
:class:`~fall_predictor.monitor.robot_description.DescriptionError` each time it is named.
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np
import pinocchio as pin

from fall_predictor.monitor.effort_wrench import EffortWrench
from fall_predictor.monitor.geometry import cross3
from fall_predictor.monitor.robot_description import SIDES, RobotDescription
from fall_predictor.monitor.sensor_records import SensorSample

_ZEROS: dict[int, np.ndarray] = {}


def all_finite(values: np.ndarray) -> bool:
    """Whether every value of a float vector is finite: a product with zeros is NaN exactly when
    one is not (one numpy call; ``np.isfinite(...).all()`` is two)."""
    zeros = _ZEROS.get(len(values))
    if zeros is None:
        zeros = _ZEROS[len(values)] = np.zeros(len(values))
    return values.dot(zeros) == 0.0              # half the cost of the @ operator here


class FootWrenches:
    """Per sample, both soles' wrenches (module docs). ``effort_contact_height_m``: a foot whose
    wrench comes from efforts is in the air when its sole is this far above the lowest [m];
    ``kinematic_contact_height_m``: without efforts, soles this close to the lowest are down."""

    def __init__(self, robot: RobotDescription, effort_feet: tuple[str, ...],
                 effort_contact_height_m: float, kinematic_contact_height_m: float) -> None:
        self.robot = robot
        self.effort_feet = tuple(effort_feet)
        self.effort_contact_height_m = effort_contact_height_m
        self.kinematic_contact_height_m = kinematic_contact_height_m
        self._effort = EffortWrench(robot) if self.effort_feet else None
        #: Where the last sample's sensor-less feet took their wrench from: 'sensors' (every foot
        #: has one), 'efforts' or 'statics'.
        self.source = 'sensors'
        #: Per (side, wrench frame) the frame id to carry the wrench from; None: the sole frame.
        self._frames: dict[tuple[str, str], Optional[int]] = {}

    def read(self, s: SensorSample, order: Optional[np.ndarray], q: np.ndarray, v: np.ndarray,
             sole_pose: dict, com: list) -> dict[str, Optional[list]]:
        """Per side the sole's wrench, or None. The description's data must hold the kinematics of
        configuration ``q`` (velocity ``v``), whose soles are at ``sole_pose`` (per side the rows of
        the homogeneous transform) with the CoM at ``com``, all relative to the base origin in
        world axes; ``order`` maps the sample's joints onto the description's (None: the same)."""
        wrenches = {}
        for side, w, frame in (('l', s.left_wrench, s.wrench_frames[0]),
                               ('r', s.right_wrench, s.wrench_frames[1])):
            w = _six_floats(w)
            wrenches[side] = None if w is None else self._in_sole_frame(side, w, frame)
        if self._effort is not None:
            wrenches.update(self._without_sensors(s, order, q, v, sole_pose, com))
        return wrenches

    def _in_sole_frame(self, side: str, w: list, frame: str) -> list:
        """A wrench measured in ``frame`` carried to the sole frame (the ground reaction about the
        sole origin)."""
        if not frame:
            return w
        robot = self.robot
        sole_id = robot.sole_ids[side]
        try:
            fid = self._frames[side, frame]
        except KeyError:
            fid = robot.frame_id(frame, f'{"left" if side == "l" else "right"} foot force sensor')
            fid = self._frames[side, frame] = None if fid == sole_id else fid
        if fid is None:
            return w
        sensor = pin.updateFramePlacement(robot.model, robot.data, fid)
        placement = robot.data.oMf[sole_id].actInv(sensor)     # the sensor in the sole frame
        f = placement.rotation @ np.array(w[:3])
        tau = placement.rotation @ np.array(w[3:]) + cross3(placement.translation, f)
        return f.tolist() + tau.tolist()

    def _without_sensors(self, s: SensorSample, order: Optional[np.ndarray], q: np.ndarray,
                         v: np.ndarray, sole_pose: dict, com: list) -> dict[str, Optional[list]]:
        """The wrenches of the feet without a force sensor: from the joint efforts when the sample
        has them all, else from the kinematics and statics."""
        tau = np.asarray(s.tau, dtype=float)
        if tau.shape == (len(s.joint_names),) and all_finite(tau):
            found = self._effort.wrenches(q, v, tau if order is None else tau[order])
            heights = {side: sole_pose[side][2][3] for side in SIDES}
            lowest = min(heights.values())
            for side in SIDES:
                if heights[side] > lowest + self.effort_contact_height_m:
                    found[side] = None
            self.source = 'efforts'
        else:
            pose = {side: np.array(sole_pose[side]) for side in SIDES}
            found = self._effort.kinematic(np.array(com), {side: pose[side][:3, 3] for side in SIDES},
                                           {side: pose[side][:3, :3] for side in SIDES},
                                           self.kinematic_contact_height_m)
            self.source = 'statics'
        return {side: None if found[side] is None else found[side].tolist()
                for side in self.effort_feet}


def _six_floats(w) -> Optional[list]:
    """A foot wrench reading as six floats, or None where it is missing or not finite."""
    if w is None:
        return None
    w = np.asarray(w, dtype=float)
    if w.shape != (6,):
        return None
    values = w.tolist()
    return values if all(map(math.isfinite, values)) else None
