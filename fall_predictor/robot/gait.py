"""Walking pattern generation: footstep plans, ZMP references and ZMP preview control.

The CoM follows the cart-table (linear inverted pendulum) model; its horizontal motion is
produced by Kajita's ZMP preview controller (Kajita et al., ICRA 2003) tracking a ZMP
reference that sits under the stance foot in single support and moves between the feet in
double support.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_discrete_are

from fall_predictor.monitor.records import STANDARD_GRAVITY_M_S2

GRAVITY = STANDARD_GRAVITY_M_S2


@functools.lru_cache(maxsize=8)
def preview_gains(dt_s: float, com_height_m: float, preview_s: float = 1.6,
                  q_error: float = 1.0, r_jerk: float = 1e-6) -> tuple[float, np.ndarray, np.ndarray]:
    """Gains (Ks, Kx (3,), Gd (N,)) of the ZMP preview controller for one horizontal axis."""
    a = np.array([[1.0, dt_s, dt_s ** 2 / 2], [0.0, 1.0, dt_s], [0.0, 0.0, 1.0]])
    b = np.array([[dt_s ** 3 / 6], [dt_s ** 2 / 2], [dt_s]])
    c = np.array([[1.0, 0.0, -com_height_m / GRAVITY]])
    a_aug = np.block([[np.ones((1, 1)), c @ a], [np.zeros((3, 1)), a]])
    b_aug = np.vstack([c @ b, b])
    q_aug = np.zeros((4, 4))
    q_aug[0, 0] = q_error
    r = np.array([[r_jerk]])
    p = solve_discrete_are(a_aug, b_aug, q_aug, r)
    inv = np.linalg.inv(r + b_aug.T @ p @ b_aug)
    k = inv @ b_aug.T @ p @ a_aug
    ks, kx = float(k[0, 0]), k[0, 1:].copy()
    ac = a_aug - b_aug @ k
    i_aug = np.array([[1.0], [0.0], [0.0], [0.0]])
    x = -ac.T @ p @ i_aug
    n = int(round(preview_s / dt_s))
    gd = np.empty(n)
    gd[0] = -ks
    for j in range(1, n):
        gd[j] = (inv @ b_aug.T @ x).item()
        x = ac.T @ x
    return ks, kx, gd


class PreviewController:
    """ZMP preview control for x and y at once, stepping every ``dt_s``.

    State per axis: CoM position, velocity, acceleration. ``zmp_ref`` is indexed by tick;
    the caller keeps it at least ``preview`` samples ahead of the current tick.
    """

    def __init__(self, dt_s: float, com_height_m: float, preview_s: float = 1.6):
        self.dt_s = dt_s
        self.com_height_m = com_height_m
        self.ks, self.kx, self.gd = preview_gains(dt_s, com_height_m, preview_s)
        self.n_preview = len(self.gd)
        self.a = np.array([[1.0, dt_s, dt_s ** 2 / 2], [0.0, 1.0, dt_s], [0.0, 0.0, 1.0]])
        self.b = np.array([dt_s ** 3 / 6, dt_s ** 2 / 2, dt_s])
        self.c = np.array([1.0, 0.0, -com_height_m / GRAVITY])
        self.state = np.zeros((3, 2))        # rows: pos, vel, acc; columns: x, y
        self.error_sum = np.zeros(2)

    def reset(self, com_xy: np.ndarray, com_vel_xy: np.ndarray | None = None) -> None:
        """Start from a measured CoM (and velocity), zero acceleration and no integral error."""
        self.state[:] = 0.0
        self.state[0] = com_xy
        if com_vel_xy is not None:
            self.state[1] = com_vel_xy
        self.error_sum[:] = 0.0

    def step(self, zmp_ref_ahead: np.ndarray) -> np.ndarray:
        """Advance one tick; ``zmp_ref_ahead`` is (n_preview + 1, 2) starting at the current tick.

        Returns the new CoM position (2,).
        """
        zmp_now = self.c @ self.state
        self.error_sum += zmp_now - zmp_ref_ahead[0]
        u = -self.ks * self.error_sum - self.kx @ self.state - self.gd @ zmp_ref_ahead[1:self.n_preview + 1]
        self.state = self.a @ self.state + self.b[:, None] * u     # b u^T (np.outer's product)
        return self.state[0]


@dataclass(frozen=True)
class Footstep:
    """One swing: the foot ``side`` leaves ``start`` at ``t_lift`` and lands on ``target`` at ``t_land``.

    Positions are sole centres on the ground (x, y) [m].
    """

    side: str
    t_lift: float
    t_land: float
    start: tuple[float, float]
    target: tuple[float, float]
    #: Sole height at lift-off: 0 from the ground, > 0 for a step redirected in mid-swing [m].
    start_height_m: float = 0.0


@dataclass
class WalkingPlan:
    """A sequence of footsteps plus the ZMP reference knots that go with it."""

    steps: list[Footstep]
    zmp_knots_t: np.ndarray          # (K,) times [s]
    zmp_knots_xy: np.ndarray         # (K, 2) ZMP reference at the knots [m]

    def zmp_reference(self, t: np.ndarray) -> np.ndarray:
        """Piecewise-linear ZMP reference at times ``t`` (held constant past the ends)."""
        return np.column_stack([np.interp(t, self.zmp_knots_t, self.zmp_knots_xy[:, 0]),
                                np.interp(t, self.zmp_knots_t, self.zmp_knots_xy[:, 1])])


def plan_walk(left: tuple[float, float], right: tuple[float, float], t_start: float, duration_s: float,
              single_support_s: float, double_support_s: float, step_length_m: float,
              initial_stand_s: float, first_side: str = 'l') -> WalkingPlan:
    """Footsteps for a straight walk along +x (stepping in place when ``step_length_m`` is 0).

    The robot first stands ``initial_stand_s`` with the ZMP between its feet, then alternates
    single support (ZMP under the stance foot) and double support (ZMP moving to the next
    stance foot). The first step is half a step so the feet then alternate leading.
    """
    feet = {'l': np.array(left, float), 'r': np.array(right, float)}
    mid = (feet['l'] + feet['r']) / 2
    knots_t = [t_start, t_start + initial_stand_s]
    knots = [mid.copy(), mid.copy()]
    steps: list[Footstep] = []
    t = t_start + initial_stand_s
    swing = first_side
    first = True
    t_end = t_start + duration_s
    while t < t_end:
        stance = 'r' if swing == 'l' else 'l'
        # Double support: move the ZMP onto the stance foot.
        t += double_support_s
        knots_t.append(t)
        knots.append(feet[stance].copy())
        advance = step_length_m / 2 if first else step_length_m
        start = feet[swing].copy()
        target = start + np.array([(feet[stance][0] - start[0]) + advance, 0.0])
        steps.append(Footstep(swing, t, t + single_support_s, tuple(start), tuple(target)))
        t += single_support_s
        knots_t.append(t)
        knots.append(feet[stance].copy())
        feet[swing] = target
        swing = stance
        first = False
    return WalkingPlan(steps, np.array(knots_t), np.array(knots))


def swing_position(step: Footstep, t: float, lift_height_m: float) -> tuple[float, float, float]:
    """Sole centre of the swing foot at time ``t`` (smooth start and stop, zero touchdown speed)."""
    s = min(1.0, max(0.0, (t - step.t_lift) / (step.t_land - step.t_lift)))
    blend = 0.5 - 0.5 * math.cos(math.pi * s)
    x = step.start[0] + (step.target[0] - step.start[0]) * blend
    y = step.start[1] + (step.target[1] - step.start[1]) * blend
    z = lift_height_m * (0.5 - 0.5 * math.cos(2.0 * math.pi * s))
    if step.start_height_m > 0.0:
        # A redirected swing: rise from where the sole is instead of dropping it to the ground.
        z = max(z, step.start_height_m * (1.0 - blend)) if s < 0.5 else z
    return x, y, z
