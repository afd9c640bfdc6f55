"""A disturbance's run: how a dataset draws one of each cause for a robot and its controller, how
the walker goes towards it, and how the run measures its onset (sim/disturbances.py says what
each cause is).

Ranges: each cause's calibrated parameter (:data:`SEVERITY`) comes from the robot profile, per
controller (``causes:`` beside ``push_force_n``; ``fall-predictor calibrate --cause`` measures
it), else from :data:`DEFAULT_RANGES`, a wide probe; the other parameters are drawn from
:data:`DEFAULT_RANGES`.

The walker: for a trip, a slip or a step a learned policy walks straight ahead (vx drawn from the
faster half of its forward range, no sideways or turning command) and C_bal walks a drawn forward
gait (never in place), so the terrain laid across +x lies on its path; the terrain's near edge is
placed where the walk is expected between ``settle_s`` and one gait cycle later. A fault's walker
draws its command or gait as a push's does; a long walk's (a learned policy's) commands change
every few seconds (:class:`~fall_predictor.sim.disturbances.CommandSchedule`).

The onset is measured (:class:`OnsetProbe`): the first loaded contact of the robot with the
obstacle, the patch, the step up or the ramp; the first sample a sole's front edge (its centre
plus half its length along its heading) is beyond a step down's edge; the fault's start. A run that never reaches its terrain has no onset (None).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Optional

import numpy as np

from fall_predictor.sim.disturbances import (CAUSE_FAULT, CAUSE_SLIP, CAUSE_STEP, CAUSE_TRIP, CAUSE_WALK,
                                             CAUSES, FAULT_MODES, CommandSchedule, Disturbance, JointFault,
                                             slip_patch, step_terrain, trip_box)

#: The parameter of each cause its range is calibrated on, and whether a larger value is the
#: severer (a slip: a lower friction is).
SEVERITY: dict[str, tuple[str, bool]] = {CAUSE_TRIP: ('height_m', True), CAUSE_SLIP: ('friction', False),
                                         CAUSE_STEP: ('height_m', True), CAUSE_FAULT: ('torque_scale', False)}
#: Every cause's ranges unless its robot's profile says otherwise: the severity's a wide probe.
DEFAULT_RANGES: dict[str, dict[str, tuple[float, float]]] = {
    CAUSE_TRIP: {'height_m': (0.02, 0.12), 'depth_m': (0.04, 0.12)},
    CAUSE_SLIP: {'friction': (0.05, 1.0)},
    CAUSE_STEP: {'height_m': (0.03, 0.2), 'slope_deg': (4.0, 14.0)},
    CAUSE_FAULT: {'torque_scale': (0.0, 0.5), 'fade_s': (0.5, 3.0), 'period_s': (0.2, 1.0),
                  'duty': (0.3, 0.7)},
    CAUSE_WALK: {'segment_s': (2.0, 6.0)},
}
#: The share of each step kind (down, up, slope) and of a long walk's segments (standing,
#: turning on the spot or slowly, walking).
STEP_KIND_WEIGHTS = {'down': 0.5, 'up': 0.25, 'slope': 0.25}
WALK_SEGMENT_WEIGHTS = {'stand': 0.2, 'turn': 0.2, 'walk': 0.6}
#: The leg joints a fault strikes: their names end so (both legs'; the load-bearing axes).
FAULT_JOINT_SUFFIXES = ('hip_pitch_joint', 'hip_roll_joint', 'knee_joint', 'ankle_pitch_joint',
                        'hip_pitch', 'hip_roll', 'knee', 'ankle_pitch')
#: The slowest a learned policy walks towards terrain [m/s] (at most its range's top).
MIN_APPROACH_SPEED_M_S = 0.3
#: C_bal's slowest forward gait towards terrain [m/s].
MIN_GAIT_SPEED_M_S = 0.1
#: A toe's reach ahead of its sole's centre [m] (the soles start at x = 0): terrain is laid beyond.
START_CLEARANCE_M = 0.12


def cause_ranges(profile, controller: Optional[str], cause: str) -> dict[str, tuple[float, float]]:
    """The ranges of ``cause`` for ``profile``'s robot under ``controller``: the profile's
    (calibrated) over :data:`DEFAULT_RANGES`."""
    from fall_predictor.profiles.cause_ranges import parse_cause_ranges
    if cause not in DEFAULT_RANGES:
        raise ValueError(f'no ranges for cause {cause!r} (one of {", ".join(DEFAULT_RANGES)})')
    where = f'{profile.source}: {controller or profile.default_controller}'
    return {**DEFAULT_RANGES[cause], **parse_cause_ranges(where, profile.cause_ranges(controller)).get(cause, {})}


def fault_joints(profile) -> tuple[str, ...]:
    """The leg joints a fault may strike (:data:`FAULT_JOINT_SUFFIXES`)."""
    legs = [j for group, joints in profile.joint_groups.items() if 'leg' in group for j in joints]
    joints = tuple(j for j in legs if j.endswith(FAULT_JOINT_SUFFIXES))
    if not joints:
        raise ValueError(f'{profile.source}: no leg joint a fault can strike (joint groups named *leg*)')
    return joints


@dataclass(frozen=True)
class Walker:
    """How the robot walks before and through a disturbance: a learned policy's velocity range
    and settle time, or C_bal's gait distribution (``policy`` None); ``cycle_s``: one gait cycle."""

    settle_s: float
    cycle_s: float
    policy: Any = None                   #: profiles PolicyControllerProfile, or None (C_bal)
    gaits: Any = None                    #: sim/pushes.PushDistribution for C_bal
    #: C_bal's one gait when its profile draws none (``gait_variety: false``).
    fixed_gait: Any = None
    #: How long the walk takes to get going from standing [s]: a policy's first steps; C_bal's
    #: initial stand and first, shorter step.
    start_lag_s: float = 0.5

    def forward(self, rng: np.random.Generator):
        """(command, gait, speed [m/s]) of a walk straight ahead (module docs)."""
        if self.policy is not None:
            lo, hi = self.policy.command.vx_m_s
            vx = float(rng.uniform(min(max(lo, MIN_APPROACH_SPEED_M_S), hi), hi))
            return (vx, 0.0, 0.0), None, vx
        if self.fixed_gait is not None:
            gait = self.fixed_gait
            return None, gait, gait.step_length_m / (gait.single_support_s + gait.double_support_s)
        dist = replace(self.gaits, standing_fraction=0.0,
                       gait_speed_m_s=(max(MIN_GAIT_SPEED_M_S, self.gaits.gait_speed_m_s[0]),
                                       max(MIN_GAIT_SPEED_M_S, self.gaits.gait_speed_m_s[1])))
        gait = dist.sample_gait(rng)
        return None, gait, gait.step_length_m / (gait.single_support_s + gait.double_support_s)

    def any(self, rng: np.random.Generator):
        """(command, gait) as a push's run draws them."""
        if self.policy is not None:
            c = self.policy.command
            return (float(rng.uniform(*c.vx_m_s)), float(rng.uniform(*c.vy_m_s)),
                    float(rng.uniform(*c.yaw_rate_rad_s))), None
        return None, self.fixed_gait or self.gaits.sample_gait(rng)


def _u(rng: np.random.Generator, pair) -> float:
    return float(rng.uniform(pair[0], pair[1]))


def _pick(rng: np.random.Generator, weights: dict[str, float]) -> str:
    names = list(weights)
    p = np.array([weights[n] for n in names], float)
    return names[int(rng.choice(len(names), p=p / p.sum()))]


def sample_disturbance(cause: str, rng: np.random.Generator, walker: Walker,
                       ranges: dict[str, tuple[float, float]], joints: tuple[str, ...] = (),
                       walk_s: float = 60.0) -> tuple[Disturbance, Any, float]:
    """One run of ``cause``: (the disturbance, C_bal's gait or None, when it is expected to act
    [s]: the terrain reached, the fault's start; a long walk: ``walk_s``). Fixed order of draws."""
    if cause not in CAUSES[1:]:
        raise ValueError(f'sample_disturbance draws one of {CAUSES[1:]}, got {cause!r}')
    reach_s = walker.settle_s + _u(rng, (0.0, walker.cycle_s))
    if cause == CAUSE_WALK:
        return _long_walk(rng, walker, ranges, walk_s)
    if cause == CAUSE_FAULT:
        command, gait = walker.any(rng)
        mode = FAULT_MODES[int(rng.integers(len(FAULT_MODES)))]
        joint = joints[int(rng.integers(len(joints)))]
        t_start = round(reach_s, 3)
        fault = JointFault(joint, mode, t_start, torque_scale=_u(rng, ranges['torque_scale']),
                           fade_s=_u(rng, ranges['fade_s']), period_s=_u(rng, ranges['period_s']),
                           duty=_u(rng, ranges['duty']))
        params = {'joint': joint, 'mode': mode, 't_start_s': t_start}
        if mode != 'stuck':
            params['torque_scale'] = round(fault.torque_scale, 6)
        if mode == 'fade':
            params['fade_s'] = round(fault.fade_s, 6)
        if mode == 'intermittent':
            params.update(period_s=round(fault.period_s, 6), duty=round(fault.duty, 6))
        return Disturbance(cause, params, fault=fault, command=command), gait, t_start
    command, gait, speed = walker.forward(rng)
    # The walk starts from standing (Walker.start_lag_s); the toe is ahead of the sole's centre.
    distance = START_CLEARANCE_M + speed * max(reach_s - walker.start_lag_s, 0.0)
    params: dict[str, Any] = {'distance_m': round(distance, 6), 'speed_m_s': round(speed, 6)}
    edge = None
    if cause == CAUSE_TRIP:
        height, depth = _u(rng, ranges['height_m']), _u(rng, ranges['depth_m'])
        terrain = (trip_box(distance, height, depth),)
        params.update(height_m=round(height, 6), depth_m=round(depth, 6))
    elif cause == CAUSE_SLIP:
        friction = _u(rng, ranges['friction'])
        terrain = (slip_patch(distance, friction),)
        params['friction'] = round(friction, 6)
    else:
        kind = _pick(rng, STEP_KIND_WEIGHTS)
        height, slope = _u(rng, ranges['height_m']), _u(rng, ranges['slope_deg'])
        terrain = step_terrain(kind, distance, height, slope)
        params['kind'] = kind
        if kind == 'slope':
            params['slope_deg'] = round(slope, 6)
        else:
            params['height_m'] = round(height, 6)
        if kind == 'down':
            edge = distance
    return Disturbance(cause, params, terrain=terrain, edge_x_m=edge, command=command), gait, reach_s


def _long_walk(rng, walker: Walker, ranges, walk_s: float):
    """A long walk: a learned policy's commands changing every few seconds (standing, turning,
    walking), C_bal's one drawn gait."""
    if walker.policy is None:
        _, gait = walker.any(rng)
        return Disturbance(CAUSE_WALK, {'walk_s': walk_s}), gait, walk_s
    c = walker.policy.command
    times, commands, t = [], [], 0.0
    while t < walk_s:
        kind = _pick(rng, WALK_SEGMENT_WEIGHTS)
        if kind == 'stand':
            command = (0.0, 0.0, 0.0)
        elif kind == 'turn':
            command = (_u(rng, (c.vx_m_s[0], 0.5 * (c.vx_m_s[0] + c.vx_m_s[1]))), 0.0, _u(rng, c.yaw_rate_rad_s))
        else:
            command = (_u(rng, c.vx_m_s), _u(rng, c.vy_m_s), 0.0)
        times.append(round(t, 3))
        commands.append(tuple(round(v, 6) for v in command))
        t += _u(rng, ranges['segment_s'])
    schedule = CommandSchedule(tuple(times), tuple(commands))
    params = {'walk_s': walk_s, 'times_s': list(times), 'commands': [list(v) for v in commands]}
    return Disturbance(CAUSE_WALK, params, schedule=schedule), None, walk_s


class ScheduledCommand:
    """A learned policy's controller (robot/control.PolicyControl) whose velocity command follows
    a :class:`~fall_predictor.sim.disturbances.CommandSchedule` (a long walk); everything else is
    the wrapped controller's."""

    def __init__(self, controller, schedule: CommandSchedule) -> None:
        self._controller = controller
        self.schedule = schedule
        #: (t [s], command) each time the command changed, as the controller was asked.
        self.applied: list[tuple[float, tuple[float, float, float]]] = []

    def command(self, observation):
        wanted = self.schedule.at(observation.t_s)
        if wanted != self._controller.velocity_command:
            self._controller.velocity_command = wanted
            self.applied.append((observation.t_s, wanted))
        return self._controller.command(observation)

    def __getattr__(self, name):
        return getattr(self._controller, name)


class OnsetProbe:
    """Measures when a disturbance first acts (module docs); ``on_step(world, measurement)``
    after every physics step of the run."""

    def __init__(self, disturbance: Disturbance) -> None:
        self.disturbance = disturbance
        self.t_onset: Optional[float] = None
        #: The foot ('l', 'r') or link (None) of the first contact, for terrain.
        self.contact_side: Optional[str] = None
        self._toe_m: Optional[dict] = None        #: each sole's half length [m]

    def __call__(self, world, m) -> None:
        if self.t_onset is not None:
            return
        d = self.disturbance
        if d.fault is not None:
            if m.t >= d.fault.t_start_s - 1e-9:
                self.t_onset = round(m.t, 6)
        elif d.edge_x_m is not None:
            if self._toe_m is None:
                self._toe_m = {side: foot.sole().length_m / 2 for side, foot in world.profile.feet.items()}
            toes = [foot[0] + self._toe_m[side] * math.cos(foot[2])
                    for side, foot in (('l', m.left_foot), ('r', m.right_foot))]
            if max(toes) > d.edge_x_m:
                self.t_onset = round(m.t, 6)
        elif d.terrain:
            # The box laid for the cause (a step down's platform is under the start: its edge).
            contacts = [c for c in world.terrain_contacts() if c.box == 0]
            if contacts:
                self.t_onset = round(m.t, 6)
                self.contact_side = contacts[0].side


def walker_for(profile, controller: Optional[str], simulator_dt_s: Optional[float] = None) -> Walker:
    """The walker of ``profile``'s robot under ``controller`` (None: its default)."""
    policy = profile.controller_profile(controller)
    if policy is None:
        from fall_predictor.sim.pushes import PushDistribution, robot_gait
        dist = PushDistribution.for_robot(profile)
        gait = robot_gait(str(profile.source))
        return Walker(dist.settle_s, dist.walk_cycle_s(gait), None, dist,
                      None if profile.gait_variety else gait, start_lag_s=gait.initial_stand_s + 0.7)
    from fall_predictor.robot.policy_config import load_policy_config
    deploy = load_policy_config(policy.policy_path, check_network=False)
    return Walker(policy.settle_s, deploy.gait_period_s or 1.0, policy)


def run_length_s(cause: str, expected_onset_s: float, horizon_after_s: float) -> float:
    """How long a run of ``cause`` is simulated [s]: past the expected onset by one second of
    slack (terrain reached a little late) and the horizon; a long walk: its length."""
    if cause == CAUSE_WALK:
        return expected_onset_s
    return expected_onset_s + 1.0 + horizon_after_s

