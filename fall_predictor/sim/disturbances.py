"""Disturbances beyond pushes, engine-free: what each one is and how a dataset draws it.

A run is disturbed by one cause (the dataset index's ``cause``): a push (sim/pushes.py), or

- a **trip**: a low box fixed to the ground across the path, which a swing foot can catch;
- a **slip**: a low-friction patch across the path, under the feet from its edge on: flush with
  the ground (its top at z = 0), the ground around it laid as boxes (:func:`ground_around`) and the
  engine's own ground out of contact, so that a foot on the patch touches nothing but the patch and
  has no edge to catch;
- a **step**: a step down (the robot starts on a platform whose edge crosses its path), a step up,
  or an incline (a ramp rising from the ground across the path);
- a **fault** on a leg joint's actuator: its torque lost abruptly, fading over seconds, lost
  intermittently, or the joint stuck where it was;
- a **walk**: a long walk with no disturbance, the commanded velocity changing every few seconds
  (standing, walking, turning) for a learned policy; C_bal walks its one drawn gait (straight ahead,
  or in place: it has no turning or stopping command).

Terrain (:class:`TerrainBox`) and faults (:class:`JointFault`) reach an engine through the World
seam (``set_terrain``, ``terrain_contacts``, ``schedule_fault``: sim/world.py); the fault's torque
profile is computed here once for every engine (:class:`FaultProtocol`, as
:class:`~fall_predictor.sim.pushes.PushProtocol` is for pushes). How a run measures its onset and
how a dataset draws each cause: sim/disturbance_runs.py.

The robot starts at the origin facing +x (a posture's yaw 0): terrain is laid across +x.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Optional, Sequence

import numpy as np

CAUSE_PUSH, CAUSE_TRIP, CAUSE_SLIP, CAUSE_STEP, CAUSE_FAULT, CAUSE_WALK = (
    'push', 'trip', 'slip', 'step', 'fault', 'walk')
#: Every cause, in the dataset index's order (data/dataset.py CAUSES: the same names).
CAUSES = (CAUSE_PUSH, CAUSE_TRIP, CAUSE_SLIP, CAUSE_STEP, CAUSE_FAULT, CAUSE_WALK)
#: The kinds of step, and of actuator fault.
STEP_KINDS = ('down', 'up', 'slope')
FAULT_MODES = ('lost', 'fade', 'intermittent', 'stuck')
#: Terrain spans this much across the path [m]: a walk that drifts sideways still meets it.
TERRAIN_WIDTH_M = 4.0
#: A slip patch's depth [m]: its top flush with the ground, its body below it (a solid the
#: engines cannot tunnel through; a sheet on the ground has an edge a sole catches, and Bullet
#: feels the ground beneath a thin one within its contact margin).
PATCH_DEPTH_M = 0.5
#: Half the side of the ground laid as boxes around a flush patch [m]: far beyond any walk.
GROUND_HALF_EXTENT_M = 100.0
#: How far a platform, a step up or a slip patch reaches along the path [m] (beyond any run's walk).
STEP_LENGTH_M = 20.0
#: A stuck joint may move this far either side of where it stuck [rad] (the engines' joint limit).
STUCK_PLAY_RAD = 1e-3


@dataclass(frozen=True)
class TerrainBox:
    """A box fixed to the ground: its centre [m], half extents [m] along its own axes, its yaw and
    pitch [rad] (a ramp is pitched), and the Coulomb friction of a contact on it (the box's
    friction decides: MuJoCo by geom priority, PyBullet as the product with the feet's 1.0)."""

    centre_m: tuple[float, float, float]
    half_extents_m: tuple[float, float, float]
    yaw_rad: float = 0.0
    pitch_rad: float = 0.0
    friction: float = 1.0
    rgba: tuple[float, float, float, float] = (0.85, 0.45, 0.1, 1.0)

    def __post_init__(self) -> None:
        if min(self.half_extents_m) <= 0 or not self.friction > 0:
            raise ValueError(f'a terrain box needs positive half extents and friction, got {self}')

    def rotation(self) -> np.ndarray:
        """The box's axes in the world (yaw about z, then pitch about the box's y)."""
        cy, sy, cp, sp = (math.cos(self.yaw_rad), math.sin(self.yaw_rad),
                          math.cos(self.pitch_rad), math.sin(self.pitch_rad))
        yaw = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
        pitch = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
        return yaw @ pitch

    def quaternion_xyzw(self) -> tuple[float, float, float, float]:
        from fall_predictor.monitor import rotations
        return tuple(float(v) for v in rotations.from_matrix(self.rotation()))

    def top_at(self, xy: Sequence[float]) -> Optional[float]:
        """The height of the box's top face above ``xy`` [m], or None outside it (unpitched)."""
        local = self.rotation().T @ (np.array([xy[0], xy[1], 0.0]) - np.asarray(self.centre_m))
        if abs(local[0]) > self.half_extents_m[0] or abs(local[1]) > self.half_extents_m[1]:
            return None
        return float(self.centre_m[2] + self.half_extents_m[2])

    @property
    def flush(self) -> bool:
        """Whether the box is part of the ground's surface (its top at z = 0, unpitched): the
        ground around it is laid as boxes (:func:`ground_around`), none under it."""
        return self.pitch_rad == 0.0 and abs(self.centre_m[2] + self.half_extents_m[2]) < 1e-9


def start_height_m(boxes: Sequence[TerrainBox], xy: Sequence[float] = (0.0, 0.0)) -> float:
    """How high the robot starts above the ground [m]: on the highest box under ``xy`` (a step
    down's platform), else on the ground."""
    tops = [top for top in (b.top_at(xy) for b in boxes) if top is not None]
    return max(tops, default=0.0)


@dataclass(frozen=True)
class JointFault:
    """An actuator fault of one joint from ``t_start_s``: ``mode`` 'lost' (its torque scaled to
    ``torque_scale`` at once), 'fade' (scaled linearly from 1 to ``torque_scale`` over ``fade_s``),
    'intermittent' (scaled to ``torque_scale`` for ``duty`` of every ``period_s``, whole between),
    'stuck' (the joint held where it was at the start, whatever its drive does)."""

    joint: str
    mode: str
    t_start_s: float
    torque_scale: float = 0.0
    fade_s: float = 1.0
    period_s: float = 0.5
    duty: float = 0.5

    def __post_init__(self) -> None:
        if self.mode not in FAULT_MODES:
            raise ValueError(f'a fault mode is one of {FAULT_MODES}, got {self.mode!r}')
        if not (0.0 <= self.torque_scale <= 1.0 and self.fade_s > 0 and self.period_s > 0
                and 0.0 < self.duty <= 1.0):
            raise ValueError(f'invalid joint fault {self}')

    def torque_scale_at(self, t: float) -> float:
        """The fraction of its drive's torque the joint gets at ``t`` [s] (1 before the fault;
        a stuck joint's drive still pushes: the joint does not move)."""
        dt = t - self.t_start_s
        if dt < -1e-9 or self.mode == 'stuck':
            return 1.0
        if self.mode == 'lost':
            return self.torque_scale
        if self.mode == 'fade':
            return 1.0 + (self.torque_scale - 1.0) * min(1.0, max(dt, 0.0) / self.fade_s)
        phase = (max(dt, 0.0) % self.period_s) / self.period_s
        return self.torque_scale if phase < self.duty else 1.0

    def stuck_at(self, t: float) -> bool:
        return self.mode == 'stuck' and t >= self.t_start_s - 1e-9


class FaultProtocol:
    """A joint fault as every engine applies it: each physics step the engine asks
    :meth:`torques` for the drive torques the joints get, and :meth:`stuck_joint` whether to lock a
    joint (at the angle it had when the fault started: the engine locks it with its joint limits)."""

    def __init__(self) -> None:
        self.fault: Optional[JointFault] = None
        self.index = -1
        self.stuck_angle_rad: Optional[float] = None

    def schedule(self, fault: Optional[JointFault], joint_names: Sequence[str]) -> None:
        self.fault, self.stuck_angle_rad = fault, None
        if fault is None:
            self.index = -1
            return
        if fault.joint not in joint_names:
            raise ValueError(f'a fault on joint {fault.joint!r}, which the robot does not have')
        self.index = list(joint_names).index(fault.joint)

    def clear(self) -> None:
        self.schedule(None, ())

    def torques(self, t: float, tau: np.ndarray) -> np.ndarray:
        """``tau`` [N m] with the faulty joint's scaled at ``t`` (the same array without a fault)."""
        if self.fault is None:
            return tau
        scale = self.fault.torque_scale_at(t)
        if scale == 1.0:
            return tau
        tau = tau.copy()
        tau[self.index] *= scale
        return tau

    def stuck_joint(self, t: float, q: np.ndarray) -> Optional[tuple[int, float]]:
        """(joint index, the angle it is stuck at [rad]) once the joint is stuck; None before."""
        if self.fault is None or not self.fault.stuck_at(t):
            return None
        if self.stuck_angle_rad is None:
            self.stuck_angle_rad = float(q[self.index])
        return self.index, self.stuck_angle_rad


@dataclass(frozen=True)
class CommandSchedule:
    """A long walk's commanded velocities: ``commands[k]`` (vx, vy, yaw rate) from ``times_s[k]``
    (the first at 0) until the next."""

    times_s: tuple[float, ...]
    commands: tuple[tuple[float, float, float], ...]

    def __post_init__(self) -> None:
        if (len(self.times_s) != len(self.commands) or not self.times_s or self.times_s[0] != 0.0
                or any(b <= a for a, b in zip(self.times_s, self.times_s[1:]))):
            raise ValueError('a command schedule starts at 0 s and its times increase')

    def at(self, t: float) -> tuple[float, float, float]:
        k = int(np.searchsorted(np.asarray(self.times_s), t + 1e-9, side='right')) - 1
        return self.commands[max(k, 0)]


@dataclass(frozen=True)
class Disturbance:
    """What disturbs one run (not a push): its cause, its parameters (as the index records them),
    the terrain laid for it, the fault it schedules, and a long walk's command schedule.
    ``edge_x_m``: a step down's edge (its onset is a sole crossing it); ``command``: the velocity
    a learned policy walks at (None: C_bal's gait, or the schedule's)."""

    cause: str
    params: dict[str, Any] = field(default_factory=dict)
    terrain: tuple[TerrainBox, ...] = ()
    fault: Optional[JointFault] = None
    schedule: Optional[CommandSchedule] = None
    edge_x_m: Optional[float] = None
    command: Optional[tuple[float, float, float]] = None

    def __post_init__(self) -> None:
        if self.cause not in CAUSES or self.cause == CAUSE_PUSH:
            raise ValueError(f'a disturbance is one of {CAUSES[1:]}, got {self.cause!r}')


# -- the terrain of each cause --------------------------------------------------------------------
def trip_box(distance_m: float, height_m: float, depth_m: float) -> TerrainBox:
    """A low box across the path, its near face ``distance_m`` ahead of the start."""
    return TerrainBox((distance_m + depth_m / 2, 0.0, height_m / 2),
                      (depth_m / 2, TERRAIN_WIDTH_M / 2, height_m / 2))


def slip_patch(distance_m: float, friction: float, length_m: Optional[float] = None) -> TerrainBox:
    """A low-friction patch of the ground across the path from ``distance_m`` ahead, ``length_m``
    long (default: beyond any run's walk, :data:`STEP_LENGTH_M`): flush with the ground
    (:attr:`TerrainBox.flush`), so that its friction alone holds a foot on it."""
    length_m = STEP_LENGTH_M if length_m is None else length_m
    return TerrainBox((distance_m + length_m / 2, 0.0, -PATCH_DEPTH_M / 2),
                      (length_m / 2, TERRAIN_WIDTH_M / 2, PATCH_DEPTH_M / 2),
                      friction=friction, rgba=(0.3, 0.6, 0.95, 1.0))


def ground_around(boxes: Sequence[TerrainBox], half_extent_m: float = GROUND_HALF_EXTENT_M
                  ) -> tuple[tuple[tuple[float, float, float], tuple[float, float, float]], ...]:
    """The ground around the flush boxes of ``boxes`` (none: ()), as (centre [m], half extents [m])
    of level boxes, their tops at z = 0, :data:`PATCH_DEPTH_M` deep, tiling the square of half side
    ``half_extent_m`` less the flush boxes (a grid on their edges). An engine lays these with its
    ground's contact properties and takes its own ground out of contact, so that nothing lies
    under a patch (every contact of a foot on it is the patch's)."""
    flush = [b for b in boxes if b.flush]
    if not flush:
        return ()
    if any(b.yaw_rad != 0.0 for b in flush):
        raise ValueError('a flush terrain box is laid along the world axes (yaw 0)')
    h = half_extent_m
    xs = sorted({-h, h, *(b.centre_m[0] + s * b.half_extents_m[0] for b in flush for s in (-1, 1))})
    ys = sorted({-h, h, *(b.centre_m[1] + s * b.half_extents_m[1] for b in flush for s in (-1, 1))})
    out = []
    for x0, x1 in zip(xs, xs[1:]):
        for y0, y1 in zip(ys, ys[1:]):
            centre = ((x0 + x1) / 2, (y0 + y1) / 2)
            if x1 - x0 <= 0 or y1 - y0 <= 0 or any(b.top_at(centre) is not None for b in flush):
                continue
            out.append(((centre[0], centre[1], -PATCH_DEPTH_M / 2),
                        ((x1 - x0) / 2, (y1 - y0) / 2, PATCH_DEPTH_M / 2)))
    return tuple(out)


def step_terrain(kind: str, distance_m: float, height_m: float = 0.0, slope_deg: float = 0.0
                 ) -> tuple[TerrainBox, ...]:
    """The terrain of a step: 'down' (a platform ``height_m`` high under the start, its edge
    ``distance_m`` ahead), 'up' (a platform ``height_m`` high from ``distance_m`` on), 'slope'
    (a ramp rising at ``slope_deg`` from the ground ``distance_m`` ahead)."""
    if kind == 'down':
        back = STEP_LENGTH_M / 2
        return (TerrainBox(((distance_m - back) / 2, 0.0, height_m / 2),
                           ((distance_m + back) / 2, TERRAIN_WIDTH_M / 2, height_m / 2),
                           rgba=(0.6, 0.6, 0.65, 1.0)),)
    if kind == 'up':
        return (TerrainBox((distance_m + STEP_LENGTH_M / 2, 0.0, height_m / 2),
                           (STEP_LENGTH_M / 2, TERRAIN_WIDTH_M / 2, height_m / 2),
                           rgba=(0.6, 0.6, 0.65, 1.0)),)
    if kind != 'slope':
        raise ValueError(f'a step is one of {STEP_KINDS}, got {kind!r}')
    angle = math.radians(slope_deg)
    half_length, half_thickness = STEP_LENGTH_M / 2, 0.1
    # The top face's near edge on the ground at distance_m; the box below it.
    top_centre = np.array([distance_m + half_length * math.cos(angle), 0.0,
                           half_length * math.sin(angle)])
    normal = np.array([-math.sin(angle), 0.0, math.cos(angle)])
    centre = top_centre - half_thickness * normal
    return (TerrainBox(tuple(float(v) for v in centre), (half_length, TERRAIN_WIDTH_M / 2, half_thickness),
                       pitch_rad=-angle, rgba=(0.6, 0.6, 0.65, 1.0)),)
