"""Plain data records shared by the simulator, the feature code, datasets and learners.

No ROS imports here: these records are the contract between the core library and the
thin rclpy nodes, and between a live system and a recorded bag.

Conventions: SI units, world frame z up, the ground plane at z = 0.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

#: Names of the 15 real-valued features (method §6), in column order. All are expressed in
#: the CoP frame: origin at the CoP (or the CoM ground projection in mode OUTSIDE),
#: x along the pelvis heading, y to its left, z up.
FEATURE_NAMES: tuple[str, ...] = (
    'com_x', 'com_y', 'com_z',                      # CoM position relative to the origin [m]
    'lin_mom_x', 'lin_mom_y', 'lin_mom_z',          # linear momentum [kg m/s]
    'ang_mom_x', 'ang_mom_y', 'ang_mom_z',          # angular momentum about the CoM [kg m^2/s]
    'd_lin_mom_x', 'd_lin_mom_y', 'd_lin_mom_z',    # rate of linear momentum [N]
    'd_ang_mom_x', 'd_ang_mom_y', 'd_ang_mom_z',    # rate of angular momentum about the CoM [N m]
)
N_FEATURES = len(FEATURE_NAMES)

#: The floating base's attitude beside the 15 features (method §8c): its fused roll and pitch
#: (the world z axis seen from the base, so that the heading does not enter) and its angular
#: velocity about its own x and y axes (its turn over the momentum rates' window: what a gyro on
#: it measures). A model may read them after the 15 features, as inputs 15-18
#: (:data:`INPUT_NAMES_WITH_ATTITUDE`).
ATTITUDE_NAMES: tuple[str, ...] = (
    'base_roll', 'base_pitch',                              # fused roll and pitch [rad]
    'base_angular_velocity_x', 'base_angular_velocity_y',   # about the base's x, y axes [rad/s]
)
N_ATTITUDE = len(ATTITUDE_NAMES)
#: A model's inputs when it reads the attitude: the 15 features, then the attitude.
INPUT_NAMES_WITH_ATTITUDE = FEATURE_NAMES + ATTITUDE_NAMES
N_INPUTS_WITH_ATTITUDE = len(INPUT_NAMES_WITH_ATTITUDE)

#: The 16 foot contact modes of method §7, in index order (the index is what data files store).
CONTACT_MODE_NAMES: tuple[str, ...] = (
    'LR-INSIDE', 'LR-FRONT', 'LR-BACK',
    'L-INSIDE', 'L-FRONT', 'L-BACK', 'L-LEFT', 'L-FRONT-LEFT', 'L-BACK-LEFT',
    'R-INSIDE', 'R-FRONT', 'R-BACK', 'R-RIGHT', 'R-FRONT-RIGHT', 'R-BACK-RIGHT',
    'OUTSIDE',
)
N_CONTACT_MODES = len(CONTACT_MODE_NAMES)

#: State classes of method §4 (label values in data arrays).
BALANCED, FALLING, FALLEN = 0, 1, 2
CLASS_NAMES = ('balanced', 'falling', 'fallen')

#: method §4 and §5 thresholds.
FALLEN_COM_HEIGHT_M = 0.33
GUARD_COM_HEIGHT_M = 0.48
PUSH_DURATION_S = 0.1

#: Standard gravity [m/s^2]: the simulator's, the walking pattern's and the capture point's.
STANDARD_GRAVITY_M_S2 = 9.81


@dataclass(frozen=True)
class SoleGeometry:
    """One sole: its frame, and the rectangle of its underside (centred on the frame origin).

    ``link``, ``origin_xyz`` and ``origin_rpy`` add the frame to the model when the URDF lacks it:
    fixed to ``link`` at ``origin_xyz`` [m] in the link's frame, turned from the link's axes by
    ``origin_rpy`` (URDF's roll, pitch, yaw [rad]; a sole frame has x forward and z up when the
    robot stands).
    """

    frame: str
    length_m: float
    width_m: float
    link: Optional[str] = None
    origin_xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    origin_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if not (0.0 < self.length_m < 1.0 and 0.0 < self.width_m < 1.0):
            raise ValueError(f'sole {self.frame}: length and width must lie in (0, 1) m, got '
                             f'{self.length_m} x {self.width_m}')

    def corners(self) -> np.ndarray:
        """(4, 3) corners of the sole in its frame: front left, front right, back right, back left."""
        half_l, half_w = self.length_m / 2, self.width_m / 2
        return np.array([[half_l, half_w, 0.0], [half_l, -half_w, 0.0],
                         [-half_l, -half_w, 0.0], [-half_l, half_w, 0.0]])


@dataclass(slots=True)
class Measurement:
    """Everything the robot measures at one simulation step (one 1 kHz sample).

    Contacts are ground contact points of each foot sole: rows of (x, y, normal_force)
    in world coordinates [m, m, N]; an empty (0, 3) array means the foot is off the ground.
    """

    t: float                        #: simulation time [s]
    com: np.ndarray                 #: (3,) whole-body CoM, world [m]
    lin_mom: np.ndarray             #: (3,) linear momentum, world [kg m/s]
    ang_mom: np.ndarray             #: (3,) angular momentum about the CoM, world [kg m^2/s]
    heading: float                  #: pelvis yaw [rad]
    cop: np.ndarray                 #: (3,) centre of pressure on the ground, NaN if no contact
    left_contacts: np.ndarray       #: (k, 3) left sole contacts: x, y [m], normal force [N]
    right_contacts: np.ndarray      #: (k, 3) right sole contacts
    left_foot: np.ndarray           #: (3,) left sole centre x, y [m] and yaw [rad]
    right_foot: np.ndarray          #: (3,) right sole centre x, y [m] and yaw [rad]
    non_foot_contact: bool          #: a link other than a foot touches the ground
    push_force: np.ndarray = field(default_factory=lambda: np.zeros(3))  #: (3,) external push now, world [N]
    #: (3, 3) torso orientation in the world (what the torso IMU measures); None where not
    #: measured. The monitor does not use it (its wire layout does not carry it); C_bal does.
    torso_rotation: Optional[np.ndarray] = None

    @property
    def fallen(self) -> bool:
        """method §4: CoM below 0.33 m, or any link other than the feet on the ground."""
        return bool(self.com[2] < FALLEN_COM_HEIGHT_M or self.non_foot_contact)


@dataclass(frozen=True, slots=True)
class PushSpec:
    """One push (method §3): a constant horizontal force on the torso for ``duration_s``.

    ``angle_deg`` is measured from the robot's sagittal (heading) direction, counter-clockwise
    seen from above: 0 pushes forward, 90 pushes to the robot's left. ``height_m`` is the
    application height above the CoM at push onset.
    """

    force_n: float
    angle_deg: float
    height_m: float
    t_push: float                   #: onset, simulation time [s]
    duration_s: float = PUSH_DURATION_S

    @property
    def t_force_end(self) -> float:
        return self.t_push + self.duration_s

    @property
    def impulse_ns(self) -> float:
        return self.force_n * self.duration_s


@dataclass(slots=True)
class TrajectoryFeatures:
    """One trajectory as the learners see it: features per sample plus its hindsight times.

    ``X`` columns follow :data:`FEATURE_NAMES`; ``mode`` holds contact mode indices
    (:data:`CONTACT_MODE_NAMES`). Times are simulation seconds; ``t_fallen`` and
    ``t_height_drop`` are None on trajectories that never fall.
    """

    trajectory_id: str
    t: np.ndarray                   #: (N,) sample times [s], 1 ms apart
    X: np.ndarray                   #: (N, 15) features
    mode: np.ndarray                #: (N,) int contact mode index
    fallen: bool
    t_push: float
    t_force_end: float
    t_fallen: Optional[float] = None
    t_height_drop: Optional[float] = None
    #: (N, 2) vertical ground force under the left and right sole [N], when known.
    foot_force_n: Optional[np.ndarray] = None
    #: (N, 4) the base's attitude (:data:`ATTITUDE_NAMES`) at each sample, when known.
    attitude: Optional[np.ndarray] = None

    @property
    def com_height(self) -> np.ndarray:
        """CoM height above the ground [m] (the frame origin lies on the ground)."""
        return self.X[:, 2]

    def with_attitude_inputs(self) -> 'TrajectoryFeatures':
        """This trajectory with ``X`` (N, 19): the features, then the base's attitude, the inputs
        of a model that reads it (method §8c). ValueError when the attitude is not known."""
        if self.attitude is None:
            raise ValueError(f'trajectory {self.trajectory_id}: no base attitude (features computed '
                             'before it was recorded with them: load the dataset again)')
        if self.X.shape[1] != N_FEATURES:
            return self
        return dataclasses.replace(self, X=np.hstack([self.X, self.attitude]))
