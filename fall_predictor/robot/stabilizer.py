"""Closed-loop walking stabilizer of C_bal: DCM tracking realised through the feet.

The walking pattern (ZMP preview control) gives a reference CoM, CoM velocity and ZMP. On a
position-controlled robot the stiff legs would drive the measured CoM onto that reference
whatever the ground reaction can support, so errors turn into tipping feet and hops. The
stabilizer instead lets the ankles yield and steers the measured state back onto the pattern:

1. **DCM tracking.** With the divergent component of motion xi = c + c_dot / omega, the desired
   ZMP is ``p_d = p_ref + k_dcm (xi - xi_ref) + k_i * integral`` (a leaky integral removes a
   steady offset from a wrong mass or CoM model), clamped into the support polygon of the
   loaded feet. With ``k_dcm > 1`` the DCM error decays at ``omega (k_dcm - 1)``.
2. **Foot force distribution.** In double support ``p_d`` splits between the feet by its
   position along the line between the sole centres (the ratio ``alpha``); the component
   across that line is carried by both feet' CoPs.
3. **Ankle admittance (damping control) of each foot's CoP.** Each loaded foot's measured CoP
   is driven towards its desired CoP by rotating the commanded sole (pitch for the sagittal,
   roll for the lateral error), with a leak back to flat: ``dtheta/dt = K (cop_d - cop) -
   theta / T``. A swing foot's rotation relaxes to flat, so it touches down flat.
4. **Foot force difference control.** The difference of the feet's commanded heights follows the
   difference between the measured and the desired vertical forces (``alpha`` of the total on
   the left), so the leg with too much load shortens.
5. **Landing absorption.** A leg whose vertical force exceeds a landing threshold shortens in
   proportion to the excess (an admittance), so a hard touchdown is absorbed, not bounced off.

Gains follow the structure of Kajita et al. (IROS 2010) and the DCM stabilizer of Caron et al.
(ICRA 2019); the values were tuned on this robot (see docs/method.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from fall_predictor.monitor.geometry import closest_point_on_boundary, convex_hull, point_in_convex_polygon
from fall_predictor.monitor.records import STANDARD_GRAVITY_M_S2, Measurement
from fall_predictor.profiles import asimo_like_urdf as rm

SIDES = rm.SIDES


@dataclass(frozen=True)
class StabilizerConfig:
    """Gains of the stabilizer; ``enabled=False`` (or all gains 0) gives the open-loop pattern."""

    enabled: bool = True
    #: Proportional DCM gain k_dcm (dimensionless; > 1 for a converging DCM error).
    dcm_gain: float = 2.0
    #: Integral DCM gain [1/s] and the leak time of that integral [s].
    dcm_integral_gain: float = 1.0
    dcm_integral_leak_s: float = 3.0
    #: Ankle admittance: sole rotation rate per CoP error [rad/s per m] (pitch, roll).
    cop_admittance_pitch: float = 6.0
    cop_admittance_roll: float = 4.0
    #: Leak of the sole rotations back to flat [s] and their limit [rad].
    ankle_leak_s: float = 0.4
    max_ankle_offset_rad: float = 0.12
    #: Foot force difference control: height-difference rate per force error [m/s per N],
    #: its leak [s] and limit [m].
    force_difference_admittance: float = 4e-5
    force_difference_leak_s: float = 0.25
    max_height_difference_m: float = 0.03
    #: Landing absorption: a foot's vertical force beyond ``landing_force_bw`` body weights
    #: shortens its leg at this rate per newton [m/s per N], back with the leak [s], at most
    #: ``max_landing_m``.
    landing_force_bw: float = 1.3
    landing_admittance: float = 2e-3
    landing_leak_s: float = 0.2
    max_landing_m: float = 0.05
    #: A foot carries load above this vertical force [N].
    loaded_force_n: float = 25.0
    #: p_d is kept this far inside the support polygon's boundary [m].
    support_margin_m: float = 0.015

    def __post_init__(self) -> None:
        for name in ('dcm_gain', 'dcm_integral_gain', 'cop_admittance_pitch', 'cop_admittance_roll',
                     'force_difference_admittance', 'support_margin_m', 'loaded_force_n',
                     'landing_force_bw', 'landing_admittance'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f'StabilizerConfig.{name} must be finite and >= 0, got {value!r}')
        for name in ('dcm_integral_leak_s', 'ankle_leak_s', 'force_difference_leak_s',
                     'max_ankle_offset_rad', 'max_height_difference_m', 'landing_leak_s', 'max_landing_m'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f'StabilizerConfig.{name} must be finite and > 0, got {value!r}')

    def open_loop(self) -> 'StabilizerConfig':
        """The same configuration with every feedback gain at zero."""
        from dataclasses import replace
        return replace(self, dcm_gain=0.0, dcm_integral_gain=0.0, cop_admittance_pitch=0.0,
                       cop_admittance_roll=0.0, force_difference_admittance=0.0, landing_admittance=0.0)


def foot_wrench(contacts: np.ndarray) -> tuple[float, np.ndarray]:
    """Total normal force [N] and CoP (x, y) [m] of one foot's contact rows (x, y, force)."""
    if contacts.size == 0:
        return 0.0, np.full(2, np.nan)
    force = float(contacts[:, 2].sum())
    if force <= 1e-9:
        return 0.0, np.full(2, np.nan)
    return force, contacts[:, :2].T @ contacts[:, 2] / force


@dataclass
class FootCorrection:
    """What the stabilizer adds to one foot's commanded sole: rotations [rad], height [m]."""

    pitch_rad: float = 0.0
    roll_rad: float = 0.0
    height_m: float = 0.0


class Stabilizer:
    """DCM tracking + foot force distribution + ankle admittance + force difference control."""

    def __init__(self, config: StabilizerConfig, omega: float, dt_s: float, mass_kg: float,
                 sole_size_m: tuple[float, float] = (rm.SOLE_LENGTH_M, rm.SOLE_WIDTH_M)):
        #: The sole rectangle (length, width) [m]: the robot profile's.
        self.sole_length_m, self.sole_width_m = sole_size_m
        self.config = config
        self.omega = omega
        self.dt_s = dt_s
        self.mass_kg = mass_kg
        self.corrections = {side: FootCorrection() for side in SIDES}
        self.dcm_integral = np.zeros(2)
        self.height_difference_m = 0.0
        self.landing_m = {side: 0.0 for side in SIDES}
        self._polygons: dict = {}
        self.desired_zmp = np.zeros(2)
        self.dcm_error = np.zeros(2)

    def reset_integral(self) -> None:
        self.dcm_integral[:] = 0.0

    def update(self, m: Measurement, com_ref: np.ndarray, vel_ref: np.ndarray, zmp_ref: np.ndarray,
               planted: Mapping[str, np.ndarray], swinging: frozenset) -> dict[str, FootCorrection]:
        """Advance one tick; returns the per-foot corrections to apply to the commanded soles.

        Args:
            m: the measurement of this tick.
            com_ref, vel_ref, zmp_ref: the pattern's CoM, CoM velocity and ZMP (x, y).
            planted: sole centres (x, y) of the feet on the ground (the support).
            swinging: the sides in swing (their corrections relax to zero).
        """
        cfg = self.config
        dt = self.dt_s
        if not cfg.enabled:
            return self.corrections
        forces, cops = {}, {}
        for side, contacts in (('l', m.left_contacts), ('r', m.right_contacts)):
            forces[side], cops[side] = foot_wrench(contacts)
        loaded = [s for s in SIDES if s not in swinging and forces[s] > cfg.loaded_force_n]
        # 1. DCM tracking -> desired ZMP.
        xi = m.com[:2] + m.lin_mom[:2] / self.mass_kg / self.omega
        xi_ref = com_ref + vel_ref / self.omega
        error = xi - xi_ref
        self.dcm_error = error
        self.dcm_integral += dt * (error - self.dcm_integral / cfg.dcm_integral_leak_s)
        p_d = zmp_ref + cfg.dcm_gain * error + cfg.dcm_integral_gain * self.dcm_integral
        support = [s for s in SIDES if s not in swinging] or list(SIDES)
        p_d = self._inside(p_d, self._support_polygon(tuple([(s, *planted[s].tolist()) for s in support])))
        self.desired_zmp = p_d
        # 2. Force distribution.
        if len(support) == 2:
            left, right = planted['l'], planted['r']
            axis = left - right
            length2 = float(axis @ axis)
            alpha = _clamp(float((p_d - right) @ axis) / length2, 0.0, 1.0) if length2 > 1e-9 else 0.5
            on_line = right + alpha * axis
            desired_cop = {'l': left + (p_d - on_line), 'r': right + (p_d - on_line)}
        else:
            alpha = 1.0 if support[0] == 'l' else 0.0
            desired_cop = {support[0]: p_d}
        # 3. Ankle admittance, per foot.
        for side in SIDES:
            corr = self.corrections[side]
            d_pitch = -corr.pitch_rad / cfg.ankle_leak_s
            d_roll = -corr.roll_rad / cfg.ankle_leak_s
            if side in loaded and side in desired_cop:
                target = self._inside_sole(desired_cop[side], planted[side])
                err = target - cops[side]
                # Toe down (+pitch) moves the CoP forward; +roll lifts the left edge (CoP to -y).
                d_pitch += cfg.cop_admittance_pitch * err[0]
                d_roll -= cfg.cop_admittance_roll * err[1]
            limit = cfg.max_ankle_offset_rad
            corr.pitch_rad = _clamp(corr.pitch_rad + dt * d_pitch, -limit, limit)
            corr.roll_rad = _clamp(corr.roll_rad + dt * d_roll, -limit, limit)
        # 4. Foot force difference control (double support only).
        rate = -self.height_difference_m / cfg.force_difference_leak_s
        if len(loaded) == 2:
            total = forces['l'] + forces['r']
            desired_difference = (2.0 * alpha - 1.0) * total
            rate += cfg.force_difference_admittance * ((forces['l'] - forces['r']) - desired_difference)
        limit = cfg.max_height_difference_m
        self.height_difference_m = _clamp(self.height_difference_m + dt * rate, -limit, limit)
        # 5. Landing absorption: a leg loaded beyond the landing force shortens in proportion to
        # the excess, and extends back once it is below.
        weight = self.mass_kg * STANDARD_GRAVITY_M_S2
        for side in SIDES:
            excess = max(0.0, forces[side] - cfg.landing_force_bw * weight)
            rate = cfg.landing_admittance * excess - self.landing_m[side] / cfg.landing_leak_s
            self.landing_m[side] = _clamp(self.landing_m[side] + dt * rate, 0.0, cfg.max_landing_m)
        # Positive difference lifts the left sole (shortens the overloaded left leg).
        self.corrections['l'].height_m = 0.5 * self.height_difference_m + self.landing_m['l']
        self.corrections['r'].height_m = -0.5 * self.height_difference_m + self.landing_m['r']
        return self.corrections

    def _support_polygon(self, key: tuple) -> list:
        """The support polygon of the planted soles ``key`` ((side, x, y), ...), shrunk by the
        margin; cached, since the soles move only from one step to the next."""
        polygon = self._polygons.get(key)
        if polygon is None:
            margin = self.config.support_margin_m
            hl, hw = self.sole_length_m / 2 - margin, self.sole_width_m / 2 - margin
            corners = [(x + dx, y + dy) for _, x, y in key for dx in (-hl, hl) for dy in (-hw, hw)]
            polygon = convex_hull(corners)
            if len(self._polygons) > 16:
                self._polygons.clear()
            self._polygons[key] = polygon
        return polygon

    def _inside_sole(self, point: np.ndarray, centre: np.ndarray) -> np.ndarray:
        """``point`` clamped into the sole around ``centre`` shrunk by the margin."""
        margin = self.config.support_margin_m
        hl, hw = self.sole_length_m / 2 - margin, self.sole_width_m / 2 - margin
        return np.array([_clamp(float(point[0]), centre[0] - hl, centre[0] + hl),
                         _clamp(float(point[1]), centre[1] - hw, centre[1] + hw)])

    @staticmethod
    def _inside(point: np.ndarray, polygon: list) -> np.ndarray:
        """``point`` if it lies inside ``polygon``, else the nearest point of its boundary."""
        px, py = float(point[0]), float(point[1])
        if len(polygon) < 3 or point_in_convex_polygon(px, py, polygon):
            return np.array([px, py])
        return np.array(closest_point_on_boundary(px, py, polygon))


def _clamp(value: float, low: float, high: float) -> float:
    return low if value < low else high if value > high else value
