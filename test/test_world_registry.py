"""The world registry (sim/world.py): a third engine is one class and one line.

The engine registered here is a planar inverted pendulum: the robot's mass on a massless leg
pivoting between its feet, its pivot driven by the first joint's drive (a PD torque, clamped to
the command's torque limit). Registered under a name, it runs a pushed trajectory through the
same seam as PyBullet and MuJoCo (the push protocol, the controller switch, the fallen rule), and
the outcome is checked against the pendulum's energy barrier: the saturated drive holds the
robot up to the angle where gravity's torque exceeds its limit, so the robot falls exactly when
the push gives it more kinetic energy than the barrier up to that angle.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from fall_predictor.monitor.records import STANDARD_GRAVITY_M_S2, Measurement, PushSpec
from fall_predictor.profiles.profile import load_profile
from fall_predictor.robot.control import HoldControl, JointCommand
from fall_predictor.sim import world as world_registry
from fall_predictor.sim.pushes import PushProtocol
from fall_predictor.sim.trajectory import run_trajectory

MASS_KG, LEG_M = 40.0, 0.8
KP_NM_PER_RAD, TAU_LIMIT_NM = 1500.0, 150.0
PUSH_HEIGHT_M, PUSH_S = 0.1, 0.01


class PendulumWorld:
    """An inverted pendulum of the profile's robot, stepped by semi-implicit Euler."""

    def __init__(self, profile, dt_s=None, **options) -> None:
        self.profile = profile
        self.dt_s = dt_s or 0.001
        self.joint_names = tuple(profile.joint_names)
        self.t, self.tick = 0.0, 0
        self._theta = self._omega = 0.0
        self._drive = (0.0, 0.0, 0.0, math.inf)      # target, kp, kd, torque limit of the pivot
        self._push = PushProtocol()
        self._last: Measurement | None = None

    def start(self, posture) -> Measurement:
        self.t, self.tick, self._theta, self._omega = 0.0, 0, 0.0, 0.0
        self._push.clear()
        return self._measure(np.zeros(3))

    def apply(self, command) -> None:
        held = JointCommand(self.joint_names, np.zeros(len(self.joint_names)))
        fitted = command.fit_onto(self.joint_names, held)
        limit = math.inf if fitted.tau_limit_nm is None else fitted.tau_limit_nm[0]
        kp, kd = (0.0, 0.0) if not fitted.has_gains else (fitted.kp[0], fitted.kd[0])
        self._drive = (fitted.targets_rad[0], kp, kd, limit)

    def schedule_push(self, push: PushSpec) -> None:
        self._push.schedule(push)

    def step(self) -> Measurement:
        com = self._com()
        applied = self._push.force_at(self.t, com, self._rotation(), com)
        force, tau_push = np.zeros(3), 0.0
        if applied is not None:
            force, point = applied
            tau_push = point[2] * force[0] - point[0] * force[2]     # about the pivot, +y
        target, kp, kd, limit = self._drive
        tau_drive = float(np.clip(kp * (target - self._theta) - kd * self._omega, -limit, limit))
        gravity = MASS_KG * STANDARD_GRAVITY_M_S2 * LEG_M * math.sin(self._theta)
        self._omega += self.dt_s * (gravity + tau_drive + tau_push) / (MASS_KG * LEG_M ** 2)
        self._theta += self.dt_s * self._omega
        self.tick += 1
        self.t = self.tick * self.dt_s
        return self._measure(force)

    def _com(self) -> np.ndarray:
        return LEG_M * np.array([math.sin(self._theta), 0.0, math.cos(self._theta)])

    def _rotation(self) -> np.ndarray:
        c, s = math.cos(self._theta), math.sin(self._theta)
        return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])

    def _measure(self, push_force: np.ndarray) -> Measurement:
        com = self._com()
        velocity = LEG_M * self._omega * np.array([math.cos(self._theta), 0.0, -math.sin(self._theta)])
        half = 0.5 * MASS_KG * STANDARD_GRAVITY_M_S2
        self._last = Measurement(
            t=self.t, com=com, lin_mom=MASS_KG * velocity, ang_mom=np.zeros(3), heading=0.0,
            cop=np.zeros(3), left_contacts=np.array([[0.0, 0.1, half]]),
            right_contacts=np.array([[0.0, -0.1, half]]), left_foot=np.array([0.0, 0.1, 0.0]),
            right_foot=np.array([0.0, -0.1, 0.0]), non_foot_contact=False,
            push_force=np.asarray(push_force, float), torso_rotation=self._rotation())
        return self._last

    def joint_states(self):
        q = np.zeros(len(self.joint_names))
        q[0] = self._theta
        return q, np.zeros_like(q), np.zeros_like(q)

    def sensor_truth(self):
        raise NotImplementedError('the pendulum has no sensors')

    def save_state(self):
        return (self._theta, self._omega)

    def restore(self, state, tick, measurement) -> None:
        (self._theta, self._omega), self.tick = state, tick
        self.t, self._last = tick * self.dt_s, measurement
        self._push.clear()

    def render(self, width, height, target, yaw_deg, pitch_deg=-12.0, distance_m=2.6):
        return np.zeros((height, width, 3), dtype=np.uint8)

    def close(self) -> None:
        pass


def critical_force_n() -> float:
    """The push force [N] (PUSH_S long, PUSH_HEIGHT_M above the CoM) whose angular impulse gives
    the pendulum the energy of its barrier: the drive's spring up to its torque limit, then a
    constant torque, against gravity's, up to the angle where gravity's torque is the limit."""
    mgl = MASS_KG * STANDARD_GRAVITY_M_S2 * LEG_M
    theta_saturated = TAU_LIMIT_NM / KP_NM_PER_RAD
    theta_top = math.asin(TAU_LIMIT_NM / mgl)
    barrier_j = (0.5 * KP_NM_PER_RAD * theta_saturated ** 2
                 + TAU_LIMIT_NM * (theta_top - theta_saturated) - mgl * (1.0 - math.cos(theta_top)))
    omega0 = math.sqrt(2.0 * barrier_j / (MASS_KG * LEG_M ** 2))
    return omega0 * MASS_KG * LEG_M ** 2 / ((LEG_M + PUSH_HEIGHT_M) * PUSH_S)


@pytest.fixture
def pendulum(monkeypatch):
    """The pendulum registered as simulator 'pendulum' (the registry restored afterwards)."""
    monkeypatch.setitem(world_registry.WORLDS, 'pendulum', PendulumWorld)
    return world_registry.make_world(load_profile('asimo_like'), 'pendulum')


def _hold_the_pivot(world) -> HoldControl:
    names = world.joint_names
    held = JointCommand(names[:1], np.zeros(1), np.array([KP_NM_PER_RAD]), np.zeros(1),
                        np.array([TAU_LIMIT_NM]))
    return HoldControl(held, world.dt_s)


def test_a_registered_engine_is_made_by_name_and_listed(pendulum):
    assert isinstance(pendulum, PendulumWorld)
    assert 'pendulum' in world_registry.simulator_names()
    assert world_registry.SIMULATORS == ('pybullet', 'mujoco')      # the shipped ones


@pytest.mark.parametrize('fraction, falls', [(0.97, False), (1.03, True)])
def test_a_pushed_trajectory_on_a_registered_engine_falls_as_its_physics_says(pendulum, fraction,
                                                                               falls):
    """Pushed at 0.97 and 1.03 of the critical force: the run survives (the pendulum swings back
    within the barrier) or falls (the CoM below the profile's fallen height), through the seam's
    trajectory loop with C_fall holding the pivot's drive."""
    push = PushSpec(fraction * critical_force_n(), 0.0, PUSH_HEIGHT_M, 0.5, PUSH_S)
    result = run_trajectory(push, 4.0, world=pendulum, controller=_hold_the_pivot(pendulum))
    assert result.fallen is falls
    assert result.measurements[0].t == 0.0 and result.measurements[-1].t <= 4.0 + 1e-9
    pushed = [m for m in result.measurements if m.push_force[0] > 0]
    assert len(pushed) == round(PUSH_S / pendulum.dt_s)          # the push protocol's duration
    if not falls:
        tilt = max(math.atan2(m.com[0], m.com[2]) for m in result.measurements)
        assert 0.1 < tilt < math.asin(TAU_LIMIT_NM / (MASS_KG * STANDARD_GRAVITY_M_S2 * LEG_M))


def test_an_unregistered_simulator_is_refused_naming_the_registered_ones():
    profile = load_profile('asimo_like')
    with pytest.raises(ValueError, match='pybullet, mujoco.*got .warp'):
        world_registry.make_world(profile, 'warp')
