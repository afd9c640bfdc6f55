"""Mirror augmentation: every trajectory also as its left-right mirror image.

Reflecting the world in the robot's sagittal plane (y -> -y in the heading frame) maps a
trajectory of the robot onto one of a mirrored robot, which for a left-right symmetric robot
is as plausible as the original. Under the reflection

* polar vectors flip their y component: ``com_y``, ``lin_mom_y``, ``d_lin_mom_y``;
* axial vectors (angular momentum and its rate) flip their x and z components;
* the contact modes swap feet and sides: ``L-FRONT-LEFT <-> R-FRONT-RIGHT``,
  ``L-INSIDE <-> R-INSIDE``; the LR modes and OUTSIDE map to themselves;
* the left and right foot forces swap;
* the base's fused roll and its angular velocity about x flip, its pitch and angular velocity
  about y do not (method §8c).

Training on the union gives the sparse single-support modes (e.g. L-INSIDE, which had no rule
while R-INSIDE had one) the other foot's examples.
"""
from __future__ import annotations

import dataclasses
from typing import Sequence

import numpy as np

from fall_predictor.monitor.records import (ATTITUDE_NAMES, CONTACT_MODE_NAMES, FEATURE_NAMES,
                                            TrajectoryFeatures)

_FLIPPED = ('com_y', 'lin_mom_y', 'd_lin_mom_y', 'ang_mom_x', 'ang_mom_z', 'd_ang_mom_x',
            'd_ang_mom_z', 'base_roll', 'base_angular_velocity_x')
#: Appended to a trajectory's id to name its mirror image.
MIRROR_ID_SUFFIX = '-mirror'
#: Per feature, +1 or -1 under the left-right reflection.
MIRROR_SIGNS = np.array([-1.0 if name in _FLIPPED else 1.0 for name in FEATURE_NAMES])
#: Per attitude value (:data:`ATTITUDE_NAMES`), +1 or -1 under the reflection.
ATTITUDE_MIRROR_SIGNS = np.array([-1.0 if name in _FLIPPED else 1.0 for name in ATTITUDE_NAMES])


def _mirror_mode_name(name: str) -> str:
    parts = name.split('-')
    swap = {'L': 'R', 'R': 'L', 'LEFT': 'RIGHT', 'RIGHT': 'LEFT'}
    return '-'.join(swap.get(p, p) for p in parts)


#: ``MIRROR_MODES[m]`` is the index of mode ``m``'s mirror image (an involution).
MIRROR_MODES = np.array([CONTACT_MODE_NAMES.index(_mirror_mode_name(n)) for n in CONTACT_MODE_NAMES])


def mirror_trajectory(traj: TrajectoryFeatures) -> TrajectoryFeatures:
    """The left-right mirror image of ``traj`` (id suffixed :data:`MIRROR_ID_SUFFIX`)."""
    foot_force = traj.foot_force_n
    if foot_force is not None:
        foot_force = np.asarray(foot_force)[:, ::-1].copy()
    X = np.asarray(traj.X)
    signs = MIRROR_SIGNS if X.shape[1] == len(MIRROR_SIGNS) else np.concatenate(
        [MIRROR_SIGNS, ATTITUDE_MIRROR_SIGNS])            # the inputs of a model with the attitude
    attitude = None if traj.attitude is None else np.asarray(traj.attitude) * ATTITUDE_MIRROR_SIGNS
    return dataclasses.replace(traj, trajectory_id=traj.trajectory_id + MIRROR_ID_SUFFIX,
                               X=X * signs, mode=MIRROR_MODES[np.asarray(traj.mode)],
                               foot_force_n=foot_force, attitude=attitude)


def with_mirror_images(trajectories: Sequence[TrajectoryFeatures]) -> list[TrajectoryFeatures]:
    """The trajectories followed by their mirror images (for training only)."""
    return list(trajectories) + [mirror_trajectory(traj) for traj in trajectories]
