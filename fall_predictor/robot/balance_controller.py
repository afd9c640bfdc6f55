"""The model-based controller of method §2: C_bal (walking with a balance reflex); C_fall and the
one-way switch are the controller seam's (robot/control.py), for any walking controller.

C_bal walks with ZMP preview control and closed-form leg IK. Its reflex fires when the
horizontal linear momentum departs from the walking pattern's by more than a threshold
along the sagittal or frontal axis: the robot then steps outward towards where its capture
point will be at touchdown (widening its stance), lowers its CoM, and stands. C_fall
holds the joint targets C_bal had reached. The switch from C_bal to C_fall is one-way.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Optional

import numpy as np

from fall_predictor.monitor.robot_description import SIDES
from fall_predictor.profiles.profile import RobotProfile
from fall_predictor.profiles import asimo_like_urdf as rm
from fall_predictor.robot import kinematics as kin
from fall_predictor.robot.legs import ClosedFormLegs, LegSolver, leg_solver
from fall_predictor.robot.stabilizer import Stabilizer, StabilizerConfig
from fall_predictor.robot.gait import GRAVITY, Footstep, PreviewController, WalkingPlan, plan_walk, swing_position
from fall_predictor.monitor.records import Measurement

_EYE = np.eye(3)
#: Within a leg (the profile's hip-to-ankle order): the ankle pitch and roll joints.
_ANKLE_PITCH, _ANKLE_ROLL = 4, 5
#: A walk of an hour is planned at once, but only its next steps and seconds are kept in world
#: coordinates: each landing moves the plan with the measured foothold, and moving every step and
#: ZMP sample of the hour took ~50 ms a landing (tabulating the hour's ZMP, 0.3 s at the start).
#: Steps further ahead and later ZMP samples take the accumulated move when they come near.
_SHIFTED_STEPS = 4
_ZMP_CHUNK_S = 5.0



@dataclass(frozen=True)
class GaitConfig:
    single_support_s: float = 0.5
    double_support_s: float = 0.2
    step_length_m: float = 0.08       #: a slow walk (0.11 m/s); 0 steps in place
    lift_height_m: float = 0.04
    torso_height_m: float = 0.63      #: torso origin above the ground while walking
    stance_half_width_m: float = rm.HIP_HALF_WIDTH_M
    initial_stand_s: float = 0.5
    #: Stand still on both feet instead of walking (the stabilizer and the reflex still act).
    standing: bool = False
    preview_s: float = 1.6
    #: After touchdown a swing leg solved for the measured torso tilt blends back to the
    #: upright solution in this time [s].
    touchdown_blend_s: float = 0.15
    #: The plan follows a measured foothold at most this far from the planned one [m].
    max_reanchor_m: float = 0.05
    #: Legs shorten by this times the CoM's rise above walking height beyond the tolerance.
    height_compliance: float = 1.0
    height_tolerance_m: float = 0.005
    #: The swing leg follows the measured torso tilt up to this angle [rad]: beyond it the robot
    #: is falling, and a leg solved for that tilt is thrown up into the air.
    max_swing_tilt_rad: float = math.inf


@dataclass(frozen=True)
class ReflexConfig:
    enabled: bool = True
    #: Departure of horizontal momentum from the pattern's that fires the reflex [kg m/s].
    threshold_sagittal_ns: float = 6.0
    threshold_frontal_ns: float = 6.0
    step_duration_s: float = 0.3
    lift_height_m: float = 0.05
    lower_com_m: float = 0.06
    lower_duration_s: float = 0.3
    #: The step lands this far beyond the predicted capture point, away from the stance foot [m].
    capture_margin_m: float = 0.05
    min_stance_width_m: float = 0.26   #: lateral sole-centre distance after the reflex step
    max_stance_width_m: float = 0.45
    max_step_forward_m: float = 0.30
    max_step_backward_m: float = 0.25
    #: After touchdown the ZMP moves from the stance foot to between the feet in this time [s].
    transfer_s: float = 0.2
    #: A swing foot that cannot take the reflex step is set down in this time [s], and the
    #: weight moves onto it in ``weight_shift_s`` before the other foot steps.
    set_down_s: float = 0.08
    weight_shift_s: float = 0.08
    #: The stepping foot lifts only once it carries less than this fraction of the weight: the
    #: step waits for that as long as it takes (0-0.6 s after the ASIMO-like robot's sideways and
    #: backward pushes), since lifting a loaded leg throws the body up ...
    lift_load_fraction: float = 0.3
    #: ... and once its swing has run this long [s], a foot that meets the ground and takes load
    #: again is not held back (it would be pulled back to where the swing began).
    max_lift_delay_s: float = 0.1


@dataclass
class ReflexEvent:
    t: float
    side: str
    target: tuple[float, float]
    capture_point: tuple[float, float]


class BalanceController:
    """C_bal: walking pattern plus momentum-triggered stepping reflex. Call :meth:`update` every tick."""

    def __init__(self, gait: GaitConfig = GaitConfig(), reflex: ReflexConfig = ReflexConfig(),
                 dt_s: float = 0.001, walk_duration_s: float = 3600.0,
                 stabilizer: StabilizerConfig = StabilizerConfig(), model_mass_kg: Optional[float] = None,
                 com_bias_m: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 profile: Optional[RobotProfile] = None, legs: Optional[LegSolver] = None):
        #: The robot: its profile (posture, soles, mass) and its legs' inverse kinematics.
        self.profile = profile or rm.PROFILE
        self.legs = legs or leg_solver(self.profile)
        self.joint_names = self.legs.joint_names
        self.sides = SIDES
        self.gait = gait
        self.reflex = reflex
        self.stabilizer_config = stabilizer
        #: The mass the controller believes the robot has (a wrong model is a test case).
        self.model_mass_kg = self.profile.total_mass_kg if model_mass_kg is None else model_mass_kg
        #: Error of the controller's CoM model: it sees the CoM displaced by this much [m].
        self.com_bias_m = np.asarray(com_bias_m, dtype=float)
        self.stabilizer: Optional[Stabilizer] = None
        self.dt_s = dt_s
        self.walk_duration_s = walk_duration_s
        self.reflex_event: Optional[ReflexEvent] = None
        self.target = np.zeros(len(self.joint_names))
        for name, q in self.profile.posture.items():     # held outside the legs
            self.target[self.joint_names.index(name)] = q
        w = gait.stance_half_width_m
        self.feet = {'l': np.array([0.0, w]), 'r': np.array([0.0, -w])}
        self.com_offset = np.zeros(2)
        self._reflex_step: Optional[Footstep] = None
        self._started = False

    # -- set-up ----------------------------------------------------------------------------
    def initial_posture(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint angles and torso position for standing on both feet at the walking height."""
        torso = np.array([0.0, 0.0, self.gait.torso_height_m])
        self._set_legs(torso, {s: (self.feet[s][0], self.feet[s][1], 0.0) for s in SIDES})
        return self.target.copy(), torso

    def _start(self, m: Measurement) -> None:
        # The CoM sits at a fixed horizontal offset from the torso origin (placed at x = y = 0
        # by initial_posture); the pattern is planned for the CoM and the torso follows at
        # that offset.
        self.com_offset = m.com[:2].copy()
        self._tilt_ik_weight = {side: 0.0 for side in SIDES}
        self.com_height_m = float(m.com[2])
        self.omega = math.sqrt(GRAVITY / self.com_height_m)
        self.preview = PreviewController(self.dt_s, self.com_height_m, self.gait.preview_s)
        self.preview.reset(m.com[:2].copy())
        sole = self.profile.feet['l']
        self.stabilizer = Stabilizer(self.stabilizer_config, self.omega, self.dt_s, self.model_mass_kg,
                                     (sole.sole_length_m, sole.sole_width_m))
        g = self.gait
        plan = plan_walk(tuple(self.feet['l']), tuple(self.feet['r']), m.t,
                         0.0 if g.standing else self.walk_duration_s,
                         g.single_support_s, g.double_support_s, g.step_length_m, g.initial_stand_s)
        # The ZMP starts under the standing CoM and moves to between the feet while standing:
        # a reference that jumps asks the CoM for an impulsive start.
        plan.zmp_knots_xy[0] = m.com[:2]
        self._set_plan(plan, m.t)
        self.torso_height = g.torso_height_m
        self._lower_from: Optional[float] = None
        self._started = True

    def _set_plan(self, plan: WalkingPlan, t_now: float) -> None:
        self.plan = plan
        self._steps = list(plan.steps)
        #: How far the footholds have moved the plan since it was set, and how many steps at the
        #: head of ``_steps`` carry that move already.
        self._plan_shift = np.zeros(2)
        self._n_shifted = min(len(self._steps), _SHIFTED_STEPS)
        self._t0 = t_now
        self._ref_base = 0                     # tick (from _t0) of the first row of _zmp_ref
        self._zmp_ref = np.empty((0, 2))
        self._ref_index = 0
        self._extend_zmp_reference()

    def _extend_zmp_reference(self) -> None:
        """Tabulate the next chunk of the ZMP reference (the plan held at its end, moved by the
        footholds), dropping the rows already used."""
        start = self._ref_base + len(self._zmp_ref)
        horizon = max(self.plan.zmp_knots_t[-1] - self._t0 - start * self.dt_s, 0.0) + self.gait.preview_s + 1.0
        ticks = np.arange(start, start + int(min(horizon, _ZMP_CHUNK_S + self.gait.preview_s) / self.dt_s) + 2)
        rows = self.plan.zmp_reference(self._t0 + self.dt_s * ticks) + self._plan_shift
        self._zmp_ref = np.vstack([self._zmp_ref[self._ref_index:], rows])
        self._ref_base += self._ref_index
        self._ref_index = 0

    # -- control -----------------------------------------------------------------------------
    def update(self, m: Measurement) -> np.ndarray:
        """Joint position targets for the next physics step given the current measurement."""
        if self.com_bias_m.any():
            m = replace(m, com=m.com + self.com_bias_m)
        if not self._started:
            self._start(m)
        if self.reflex.enabled and self.reflex_event is None and self._momentum_departed(m):
            self._fire_reflex(m)
        if self._ref_index + self.preview.n_preview + 1 > len(self._zmp_ref):
            self._extend_zmp_reference()
        i = self._ref_index
        ref = self._zmp_ref
        com_xy = self.preview.step(ref[i:i + self.preview.n_preview + 1])
        self._ref_index += 1
        t = m.t + self.dt_s
        if self._lower_from is not None:
            s = min(1.0, (t - self._lower_from) / self.reflex.lower_duration_s)
            self.torso_height = self.gait.torso_height_m - self.reflex.lower_com_m * (0.5 - 0.5 * math.cos(math.pi * s))
        # Vertical compliance: when the measured CoM rises above its walking height (a leg
        # vaulting the body over itself, a hard landing rebounding), the legs shorten by as
        # much, so a stiff leg never throws the robot into the air.
        rise = float(m.com[2]) - self.com_height_m - self.gait.height_tolerance_m
        shorten = self.gait.height_compliance * max(0.0, rise)
        torso = np.array([com_xy[0] - self.com_offset[0], com_xy[1] - self.com_offset[1],
                          self.torso_height - shorten])
        self._land_finished_steps(m, t)
        soles, swinging = {}, set()
        for side in SIDES:
            step = self._active_step(side, t)
            if step is None:
                soles[side] = (self.feet[side][0], self.feet[side][1], 0.0)
            elif step is self._reflex_step and self._still_loaded(m, side, step, t):
                # The stepping foot still carries the robot: lifting it now would straighten a
                # loaded leg and throw the body up. Hold it down and start the swing later.
                held = replace(step, t_lift=step.t_lift + self.dt_s, t_land=step.t_land + self.dt_s,
                               start_height_m=0.0)
                self._steps[self._steps.index(step)] = held
                self._reflex_step = held
                soles[side] = (held.start[0], held.start[1], 0.0)
                # Planted there until it lifts: a foot whose walking step had just landed is
                # balanced on where it stands, not on the foothold it left.
                self.feet[side] = np.array(held.start)
            else:
                lift = self.reflex.lift_height_m if step is self._reflex_step else self.gait.lift_height_m
                soles[side] = swing_position(step, t, lift)
                swinging.add(side)
                if t >= step.t_land:
                    self.feet[side] = np.array(step.target)
        state = self.preview.state
        pattern_zmp = state[0] - state[2] / self.omega ** 2
        corrections = self.stabilizer.update(m, state[0], state[1], pattern_zmp, self.feet, frozenset(swinging))
        for side in SIDES:
            x, y, z = soles[side]
            soles[side] = (x, y, z + corrections[side].height_m)
        self._set_legs(torso, soles)
        self._swing_legs_for_measured_tilt(m, torso, soles, swinging)
        for side in SIDES:
            leg = self.legs.leg_indices[side]
            self.target[leg[_ANKLE_PITCH]] += corrections[side].pitch_rad
            self.target[leg[_ANKLE_ROLL]] += corrections[side].roll_rad
        return self.target.copy()

    def _still_loaded(self, m: Measurement, side: str, step: Footstep, t: float) -> bool:
        if t - step.t_lift > self.reflex.max_lift_delay_s:
            return False
        contacts = m.left_contacts if side == 'l' else m.right_contacts
        force = float(contacts[:, 2].sum()) if contacts.size else 0.0
        return force > self.reflex.lift_load_fraction * self.model_mass_kg * GRAVITY

    def _land_finished_steps(self, m: Measurement, t: float) -> None:
        """Plant the feet of finished steps where they are measured to be, and move the rest of
        the walking plan with them: the plan is anchored to the real footholds, so the small
        slips of every step do not add up to a drift the stabilizer would fight."""
        while self._steps and t > self._steps[0].t_land + 1e-9:
            done = self._pop_step()
            landed = np.array(done.target)
            if done is not self._reflex_step:
                measured = (m.left_foot if done.side == 'l' else m.right_foot)[:2]
                limit = self.gait.max_reanchor_m
                delta = np.clip(measured - landed, -limit, limit)
                self._move_plan(delta)
                landed = landed + delta
            self.feet[done.side] = landed

    def _move_plan(self, delta: np.ndarray) -> None:
        """Move the rest of the plan by ``delta``: the near steps and the tabulated ZMP now, the
        later steps when they come near (:data:`_SHIFTED_STEPS`)."""
        n = self._n_shifted
        self._steps[:n] = [_moved(step, delta) for step in self._steps[:n]]
        self._plan_shift = self._plan_shift + delta
        self._promote_steps()
        self._zmp_ref[self._ref_index:] += delta

    def _promote_steps(self) -> None:
        steps, n = self._steps, self._n_shifted
        while n < min(len(steps), _SHIFTED_STEPS):
            steps[n] = _moved(steps[n], self._plan_shift)
            n += 1
        self._n_shifted = n

    def _pop_step(self) -> Footstep:
        """The finished first step, taken off the plan."""
        done = self._steps.pop(0)
        self._n_shifted = max(0, self._n_shifted - 1)
        self._promote_steps()
        return done

    def _active_step(self, side: str, t: float) -> Optional[Footstep]:
        # Drop finished steps (their targets become the planted feet).
        while self._steps and t > self._steps[0].t_land + 1e-9:
            done = self._pop_step()
            self.feet[done.side] = np.array(done.target)
        for step in self._steps[:2]:
            if step.side == side and step.t_lift <= t <= step.t_land + 1e-9:
                return step
        return None

    def _set_legs(self, torso: np.ndarray, soles: dict) -> None:
        # Torso upright and soles flat, both facing the walking direction (world +x): the
        # closed-form IK's parallel case.
        tx, ty, tz = float(torso[0]), float(torso[1]), float(torso[2])
        legs = self.legs
        for side in SIDES:
            x, y, z = soles[side]
            if isinstance(legs, ClosedFormLegs):
                hx, hy, hz = legs.hip_in_base[side]
                ax, ay, az = legs.ankle_in_sole[side]
                hip = (tx + hx, ty + hy, tz + hz)
                ankle = (x + ax, y + ay, z + az)
                self.target[legs.leg_indices[side]] = kin.leg_ik_parallel(
                    hip, ankle, thigh=legs.thigh_m, shank=legs.shank_m)
            else:
                self.target[legs.leg_indices[side]] = legs.solve(
                    side, np.array([tx, ty, tz]), _EYE, np.array([x, y, z]), _EYE)

    def _swing_legs_for_measured_tilt(self, m: Measurement, torso: np.ndarray, soles: dict,
                                      swinging: set) -> None:
        """Solve the reflex step's swing leg for the measured torso tilt (roll and pitch), so its
        sole goes where planned in the world, flat, although the push has tilted the robot:
        solved for an upright torso, the swing foot of a robot tilted towards it is driven into
        the ground. Stance legs keep the upright solution, so their stiff servos push the torso
        back upright; so do the swing legs of the unpushed walk, whose tilt stays within a few
        degrees. After touchdown the leg blends back to the upright solution."""
        if m.torso_rotation is None:
            return
        weights = self._tilt_ik_weight
        decay = self.dt_s / self.gait.touchdown_blend_s
        reflex_side = self._reflex_step.side if self._reflex_step is not None else None
        for side in SIDES:
            stepping = side in swinging and side == reflex_side
            weights[side] = 1.0 if stepping else max(0.0, weights[side] - decay)
        active = [side for side in SIDES if weights[side] > 0.0]
        if not active:
            return
        rot = m.torso_rotation
        limit = self.gait.max_swing_tilt_rad
        pitch = max(-limit, min(limit, math.asin(max(-1.0, min(1.0, -rot[2, 0])))))
        roll = max(-limit, min(limit, math.atan2(rot[2, 1], rot[2, 2])))
        for side in active:
            w = weights[side]
            body = kin.rot_y(pitch * w) @ kin.rot_x(roll * w)
            x, y, z = soles[side]
            self.target[self.legs.leg_indices[side]] = self.legs.solve(
                side, np.asarray(torso, dtype=float), body, np.array([x, y, z]), np.eye(3),
                stream='tilted')

    def _momentum_departed(self, m: Measurement) -> bool:
        mass = self.model_mass_kg
        ref_vel = self.preview.state[1]
        c, s = math.cos(m.heading), math.sin(m.heading)
        dx = m.lin_mom[0] - mass * ref_vel[0]
        dy = m.lin_mom[1] - mass * ref_vel[1]
        sagittal, frontal = c * dx + s * dy, -s * dx + c * dy
        return abs(sagittal) > self.reflex.threshold_sagittal_ns or abs(frontal) > self.reflex.threshold_frontal_ns

    def _fire_reflex(self, m: Measurement) -> None:
        r = self.reflex
        t = m.t
        mass = self.model_mass_kg
        com = m.com[:2]
        vel = m.lin_mom[:2] / mass
        capture = com + vel / self.omega
        ch, sh = math.cos(m.heading), math.sin(m.heading)
        left_dir = np.array([-sh, ch])
        swinging = [s for s in SIDES if self._active_step(s, t) is not None]
        side = self._reflex_side(capture, left_dir, swinging)
        stance_side = 'r' if side == 'l' else 'l'
        steps: list[Footstep] = []
        t_lift = t
        if swinging and swinging[0] == stance_side:
            # The foot in the air cannot reach the capture point without crossing: put it down
            # where it is, then step with the other one.
            step = self._active_step(stance_side, t)
            now = swing_position(step, t, self.gait.lift_height_m)
            steps.append(Footstep(stance_side, t, t + r.set_down_s, tuple(now[:2]), tuple(now[:2]),
                                  start_height_m=float(now[2])))
            self.feet[stance_side] = np.array(now[:2])
            t_lift = t + r.set_down_s + r.weight_shift_s
            start, start_height = self.feet[side].copy(), 0.0
        elif swinging:
            step = self._active_step(side, t)
            now = swing_position(step, t, self.gait.lift_height_m)
            start, start_height = np.array(now[:2]), now[2]
        else:
            start, start_height = self.feet[side].copy(), 0.0
        stance = self.feet[stance_side]
        t_land = t_lift + r.step_duration_s
        # Where the capture point will be at touchdown if the CoP stays on the stance foot.
        growth = math.exp(self.omega * (t_land - t))
        predicted = stance + (capture - stance) * growth
        away = predicted - stance
        norm = float(np.linalg.norm(away))
        target = predicted + (away / norm * r.capture_margin_m if norm > 1e-9 else 0.0)
        # Reachable region relative to the stance foot, in the heading frame; never cross.
        rel = target - stance
        fwd, lat = ch * rel[0] + sh * rel[1], -sh * rel[0] + ch * rel[1]
        fwd = min(r.max_step_forward_m, max(-r.max_step_backward_m, fwd))
        outward = 1.0 if side == 'l' else -1.0
        lat = outward * min(r.max_stance_width_m, max(r.min_stance_width_m, outward * lat))
        target = stance + np.array([ch * fwd - sh * lat, sh * fwd + ch * lat])
        self._reflex_step = Footstep(side, t_lift, t_land, tuple(start), tuple(target),
                                     start_height_m=float(start_height))
        steps.append(self._reflex_step)
        mid = (target + stance) / 2
        if t_lift > t:
            # ZMP on the standing foot while the other sets down, then onto the set-down foot.
            knots_t = np.array([t, t + r.set_down_s, t_lift, t_land, t_land + r.transfer_s])
            knots = np.array([self.feet[side], self.feet[side], stance, stance, mid])
        else:
            knots_t = np.array([t, t_land, t_land + r.transfer_s])
            knots = np.array([stance, stance, mid])
        self._set_plan(WalkingPlan(steps, knots_t, knots), t)
        self.preview.reset(com.copy(), vel.copy())
        self.stabilizer.reset_integral()
        self._lower_from = t
        self.reflex_event = ReflexEvent(t, side, (float(target[0]), float(target[1])),
                                        (float(capture[0]), float(capture[1])))

    def _reflex_side(self, capture: np.ndarray, left_dir: np.ndarray, swinging: list[str]) -> str:
        """The foot that steps: the one on the capture point's side when the capture point lies
        beyond a foot laterally (a step with the other foot would have to cross), else the
        foot in the air, else the foot farther from the capture point."""
        if float((capture - self.feet['l']) @ left_dir) > 0.0:
            return 'l'
        if float((capture - self.feet['r']) @ left_dir) < 0.0:
            return 'r'
        if swinging:
            return swinging[0]
        return max(SIDES, key=lambda s_: float(np.linalg.norm(self.feet[s_] - capture)))


def _moved(step: Footstep, delta: np.ndarray) -> Footstep:
    return replace(step, start=tuple(np.add(step.start, delta)), target=tuple(np.add(step.target, delta)))


def controller_configs(profile: RobotProfile) -> tuple[GaitConfig, ReflexConfig, StabilizerConfig]:
    """The balance controller's settings for a robot: the defaults with its profile's changes."""
    parts = profile.controller
    try:
        return (replace(GaitConfig(), **parts.get('gait', {})),
                replace(ReflexConfig(), **parts.get('reflex', {})),
                replace(StabilizerConfig(), **parts.get('stabilizer', {})))
    except TypeError as error:           # a field the configuration does not have
        raise ValueError(f'{profile.source}: controller: {error}') from error

