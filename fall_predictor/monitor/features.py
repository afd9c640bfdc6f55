"""The 15 real features and the contact mode of method §6, sample by sample.

One implementation serves the live node and the training data: :class:`FeatureExtractor`
consumes measurements one at a time, and :func:`extract_features` only runs it over a
sequence, so batch and streaming results are identical by construction.

Frame: origin at the CoP on the ground (z = 0), or at the CoM's ground projection in mode
OUTSIDE (no foot contact); x along the pelvis heading, y to its left, z up. Positions are taken
relative to the origin; momenta and their rates are free vectors and are only rotated.

Rates are backward differences of the WORLD-frame momenta over ``rate_window_s`` seconds (the
oldest sample at most that long ago, whatever the sample rate: 1 kHz and 200 Hz streams give the
same rates), rotated into the current heading frame afterwards: differentiating the heading-frame momenta instead would
add a spurious term from the turning frame, whereas the world-frame rates are, by Newton and
Euler, the net external force and the net external moment about the CoM.
"""
from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Optional, Sequence

import numpy as np

from fall_predictor.monitor.contact_modes import ContactMode, classify_contact_mode_and_cop, float_list
from fall_predictor.monitor.plausibility import ContinuityCheck
from fall_predictor.monitor.geometry import fused_roll_pitch_of_rotation
from fall_predictor.monitor.records import GUARD_COM_HEIGHT_M, N_ATTITUDE, N_FEATURES, Measurement

_OUTSIDE = int(ContactMode.OUTSIDE)


class FeatureSettingsMismatch(ValueError):
    """A monitor configured differently from the model it runs (the message says how)."""


#: What a feature setting can physically be: [low, high] per setting (a model file that says
#: otherwise is refused, before any arithmetic overflows on it).
SETTING_RANGES = {'rate_window_s': (1e-4, 1.0), 'edge_tolerance_m': (0.0, 0.1),
                  'sample_period_s': (1e-4, 0.1), 'guard_com_height_m': (0.0, 2.0)}


@dataclass(frozen=True)
class FeatureSettings:
    """How features were computed for a model; the monitor must compute them the same way.

    A model learns thresholds on features computed with these settings; running it on
    features computed otherwise (another rate window, another sample period) silently changes
    what its rules mean. So the model file stores them and the nodes check them.
    """

    rate_window_s: float = 0.01          #: backward-difference window of the momentum rates [s]
    edge_tolerance_m: float = 0.01       #: CoP within this distance of an edge is on it [m]
    sample_period_s: float = 0.001       #: nominal period of the measurements [s]
    guard_com_height_m: float = GUARD_COM_HEIGHT_M   #: CoM guard: falling below this height [m]

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            low, high = SETTING_RANGES[name]
            if not (isinstance(value, (int, float)) and low <= value <= high):
                raise ValueError(f'{name} must be a number in [{low:g}, {high:g}], got {value!r}')
        if not 0.0 < self.sample_period_s <= self.rate_window_s:
            raise ValueError(f'need 0 < sample_period_s <= rate_window_s, got '
                             f'{self.sample_period_s} and {self.rate_window_s}')

    def resolve(self, requested: Mapping[str, Optional[float]], what: str = 'the model'
                ) -> 'FeatureSettings':
        """These settings, checked against a node's ``requested`` ones.

        A requested value of None (a parameter left unset) adopts this object's value; any
        other value must equal it, else :class:`FeatureSettingsMismatch` names every
        difference. Unknown names raise ``KeyError``.
        """
        known = asdict(self)
        differences = []
        for name, value in requested.items():
            if name not in known:
                raise KeyError(f'unknown feature setting {name!r}')
            if value is not None and not math.isclose(float(value), known[name], rel_tol=1e-9):
                differences.append(f'{name} = {value} but {what} was trained with {known[name]}')
        if differences:
            raise FeatureSettingsMismatch('; '.join(differences) + ' (leave the parameter unset '
                                          'to adopt the model\'s value, or retrain)')
        return self

    def extractor(self, attitude: bool = False) -> 'FeatureExtractor':
        """A fresh :class:`FeatureExtractor` computing features with these settings (and, with
        ``attitude``, the base's attitude after them)."""
        return FeatureExtractor(self.rate_window_s, self.sample_period_s, self.edge_tolerance_m,
                                attitude)


def _finite_vector3(a: object, name: str) -> list[float]:
    """``a`` as 3 finite floats; ValueError otherwise."""
    v = float_list(a, 3, name)
    if not (math.isfinite(v[0]) and math.isfinite(v[1]) and math.isfinite(v[2])):
        raise ValueError(f'{name} must be finite, got {v}')
    return v


class FeatureExtractor:
    """Streaming feature computation for one trajectory (or one live run).

    ``rate_window_s`` [s] is the backward-difference window of the momentum rates: the rate at
    ``t`` is the difference to the oldest sample no more than ``rate_window_s`` (plus a quarter of
    ``dt_s``, for stamp jitter) before ``t``, divided by the measured time span; when no earlier
    sample lies within the window (a slow stream, a gap), the newest one within twice the window
    serves; with none (the first sample, a long gap) the rates are zero. ``dt_s`` [s] is
    the nominal sample period (jitter tolerance only) and ``edge_tolerance_m`` [m] is passed to the
    contact mode classification. Call :meth:`reset` before feeding a new trajectory.

    With ``attitude`` each output also holds, after the 15 features, the base's attitude
    (:data:`~fall_predictor.monitor.records.ATTITUDE_NAMES`, method §8c): the fused roll and
    pitch of ``m.torso_rotation``, and the base's angular velocity about its own x and y axes
    from its turn since the momenta's reference sample (zero without one); all four NaN for a
    measurement without a base orientation, the angular velocity NaN when the reference sample
    had none.
    """

    def __init__(self, rate_window_s: float = 0.01, dt_s: float = 0.001,
                 edge_tolerance_m: float = 0.01, attitude: bool = False) -> None:
        if not dt_s > 0.0 or not rate_window_s >= dt_s:
            raise ValueError(f'need 0 < dt_s <= rate_window_s, got dt_s={dt_s}, '
                             f'rate_window_s={rate_window_s}')
        self.rate_window_s = rate_window_s
        self.dt_s = dt_s
        self.edge_tolerance_m = edge_tolerance_m
        self.attitude = bool(attitude)
        #: Length of each output: the 15 features, and the attitude's 4 with ``attitude``.
        self.n_outputs = N_FEATURES + (N_ATTITUDE if self.attitude else 0)
        self._window_s = rate_window_s + 0.25 * dt_s
        # Past samples within the window as (t, world linear momentum xyz, world angular
        # momentum xyz, base orientation or None), oldest first.
        self._history: deque[tuple[float, ...]] = deque()
        #: Rejects samples that jump further than physics allows (glitches), see
        #: :mod:`fall_predictor.monitor.plausibility`.
        self.continuity = ContinuityCheck()

    def reset(self) -> None:
        """Forget the momentum history (the next sample gets zero rates)."""
        self._history.clear()
        self.continuity.reset()

    def update(self, m: Measurement) -> tuple[np.ndarray, int]:
        """Features (15,) in :data:`FEATURE_NAMES` order (then the attitude's 4 values, with
        ``attitude``) and the contact mode index of ``m``.

        Raises ValueError, leaving the extractor unchanged, if the CoM, momenta, heading or
        time are not finite or have wrong shapes, if the contacts are malformed, or if the
        time does not increase (call :meth:`reset` when a new trajectory starts). Raises
        :class:`~fall_predictor.monitor.plausibility.ImplausibleSample` (a ValueError), also
        leaving it unchanged, if the CoM or a momentum jumped further than physics allows since
        the last accepted sample.
        """
        t = float(m.t)
        cx, cy, cz = _finite_vector3(m.com, 'com')
        px, py, pz = _finite_vector3(m.lin_mom, 'lin_mom')
        lx, ly, lz = _finite_vector3(m.ang_mom, 'ang_mom')
        heading = float(m.heading)
        if not (math.isfinite(t) and math.isfinite(heading)):
            raise ValueError(f'time and heading must be finite, got t={t}, heading={heading}')
        history = self._history
        if history and t <= history[-1][0]:
            raise ValueError(f'time must increase: got t={t} after t={history[-1][0]}; '
                             'reset() before a new trajectory')
        mode, ox, oy = classify_contact_mode_and_cop(m, self.edge_tolerance_m)
        if self.continuity.check(t, (cx, cy, cz), (px, py, pz), (lx, ly, lz)):
            history.clear()     # accepted after a real discontinuity: no rate across it
        if mode == _OUTSIDE:
            ox, oy = cx, cy

        horizon = t - self._window_s
        while len(history) > 1 and history[1][0] <= horizon:
            history.popleft()           # the next one is older than the window too, or at its edge
        reference = None
        if history:
            # The oldest sample within the window, else the newest within twice the window.
            if history[0][0] >= horizon:
                reference = history[0]
            elif len(history) > 1:
                reference = history[1]
            elif t - history[0][0] <= 2.0 * self._window_s:
                reference = history[0]
        roll = pitch = wx = wy = math.nan
        rotation = None
        if self.attitude and m.torso_rotation is not None:
            rotation = m.torso_rotation.tolist() if hasattr(m.torso_rotation, 'tolist') else m.torso_rotation
            roll, pitch = fused_roll_pitch_of_rotation(rotation)
            wx = wy = 0.0                       # until there is a reference to turn from
        if reference is not None:
            t0, px0, py0, pz0, lx0, ly0, lz0, rotation0 = reference
            inv = 1.0 / (t - t0)
            fx, fy, fz = (px - px0) * inv, (py - py0) * inv, (pz - pz0) * inv
            mx, my, mz = (lx - lx0) * inv, (ly - ly0) * inv, (lz - lz0) * inv
            if rotation is not None:
                wx, wy = _body_rates_xy(rotation0, rotation, inv)
        else:
            fx = fy = fz = mx = my = mz = 0.0
        history.append((t, px, py, pz, lx, ly, lz, rotation))

        # World -> heading frame: x' = c x + s y, y' = -s x + c y, z unchanged.
        c, s = math.cos(heading), math.sin(heading)
        dx, dy = cx - ox, cy - oy
        features = np.array((
            c * dx + s * dy, -s * dx + c * dy, cz,
            c * px + s * py, -s * px + c * py, pz,
            c * lx + s * ly, -s * lx + c * ly, lz,
            c * fx + s * fy, -s * fx + c * fy, fz,
            c * mx + s * my, -s * mx + c * my, mz,
        ) + ((roll, pitch, wx, wy) if self.attitude else ()))
        return features, mode


def _body_rates_xy(rotation0, rotation, inv_dt: float) -> tuple[float, float]:
    """The base's mean angular velocity about its own x and y axes [rad/s] from ``rotation0`` to
    ``rotation`` (base to world) over ``1 / inv_dt`` seconds: the rotation vector of
    ``rotation0^T rotation``, what a gyro on the base integrates (NaN without ``rotation0``)."""
    if rotation0 is None:
        return math.nan, math.nan
    (a00, a01, a02), (a10, a11, a12), (a20, a21, a22) = rotation0
    (b00, b01, b02), (b10, b11, b12), (b20, b21, b22) = rotation
    # Twice the skew part of D = rotation0^T rotation: 2 sin(angle) times the axis.
    vx = (a02 * b01 + a12 * b11 + a22 * b21) - (a01 * b02 + a11 * b12 + a21 * b22)
    vy = (a00 * b02 + a10 * b12 + a20 * b22) - (a02 * b00 + a12 * b10 + a22 * b20)
    vz = (a01 * b00 + a11 * b10 + a21 * b20) - (a00 * b01 + a10 * b11 + a20 * b21)
    sine = 0.5 * math.sqrt(vx * vx + vy * vy + vz * vz)
    # angle / sin(angle) (1 for small turns; a window turns a base by well under pi/2)
    scale = math.asin(min(sine, 1.0)) / sine if sine > 1e-9 else 1.0
    k = 0.5 * scale * inv_dt
    return vx * k, vy * k


def extract_features(measurements: Sequence[Measurement], rate_window_s: float = 0.01,
                     dt_s: float = 0.001, edge_tolerance_m: float = 0.01, attitude: bool = False
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Features ``X`` (N, 15), or (N, 19) with ``attitude``, and contact modes (N,) of one
    trajectory, by running a fresh :class:`FeatureExtractor` over it (so exactly what the live
    node computes)."""
    extractor = FeatureExtractor(rate_window_s, dt_s, edge_tolerance_m, attitude)
    X = np.empty((len(measurements), extractor.n_outputs))
    mode = np.empty(len(measurements), dtype=np.int64)
    for i, m in enumerate(measurements):
        X[i], mode[i] = extractor.update(m)
    return X, mode
