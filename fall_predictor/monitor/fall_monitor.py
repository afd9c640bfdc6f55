"""The monitor's decision per sample: the prediction, the trigger, the fall direction and time to
fall, and whether the robot is down (method §8, §12).

:class:`FallMonitor` is the predictor node's logic without ROS (the node only converts messages),
and it runs the same offline. Per sample of features it gives a :class:`MonitorState` (what
``fall_predictor/state`` carries) and, when the robot's fall state changes, a :class:`FallEvent`:

* **prediction**: :class:`~fall_predictor.monitor.predictor.OnlinePredictor` (per-mode decision
  lists or boosted trees, the ``tau_his`` window, the CoM guard);
* **trigger**: ``latched`` from the first falling prediction until :meth:`FallMonitor.reset`, the
  only way to undo it; a new run (a clock step), a degraded or stale sample, switching the trigger
  off and on (:meth:`FallMonitor.enable`) never undoes it, nor does a new monitor that takes over
  from this one (:meth:`FallMonitor.take_over`: a node reconfigured);
* **direction**: the heading-frame fall direction at each falling sample: the model's learned
  direction when it has one (:class:`~fall_predictor.monitor.fall_direction.LearnedDirection`),
  else the horizontal momentum's (:func:`~fall_predictor.monitor.fall_direction.momentum_direction`);
  **time to fall** from the model's regressor when it has one, clamped to [0, 1000] s (NaN
  otherwise);
* **fallen**: the robot is down when its CoM is below ``fallen_com_height_m`` above the support, or
  its floating base is tilted beyond ``fallen_tilt_rad`` (method §4), or no foot has touched the
  ground for ``unsupported_s`` (lying on its back, or carried); it stands again when a foot is on
  the ground with the CoM back above ``standing_com_height_m`` and the base within
  ``standing_tilt_rad`` of upright, for ``standing_time_s``. While down the state says FALLEN and
  nothing is predicted;
* **disabled** (:meth:`FallMonitor.enable`): states say DISABLED and nothing new triggers (a fall
  latched before stays latched);
* **degraded / stale** samples (:meth:`FallMonitor.unusable`): no prediction, the reason in words;
  such a sample is a hole in the data, as a lost one is, not evidence that the robot is not
  falling: the history window restarts after a hole longer than ``max_gap_s`` (no window spans
  one), not after each unusable sample (a loaded computer's late IMU reading now and then would
  otherwise hold the trigger back for good); the latch stays.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Sequence

from fall_predictor.monitor.decision_list import PerModeDecisionLists
from fall_predictor.monitor.fall_direction import LearnedDirection, momentum_direction
from fall_predictor.monitor.contact_modes import ContactMode
from fall_predictor.monitor.plausibility import bound_text
from fall_predictor.monitor.predictor import COM_HEIGHT_FEATURE, OnlinePredictor
from fall_predictor.monitor.records import N_FEATURES

#: ``MonitorState.status`` values (``fall_predictor/msg/FallState`` STATUS_*).
STATUS_OK, STATUS_DEGRADED, STATUS_STALE, STATUS_DISABLED, STATUS_FALLEN = range(5)
STATUS_NAMES = ('ok', 'degraded', 'stale', 'disabled', 'fallen')
#: ``FallEvent.kind`` values (``fall_predictor/msg/FallEvent`` EVENT_*).
EVENT_FALLING, EVENT_FALLEN, EVENT_STANDING, EVENT_RESET = range(4)
EVENT_NAMES = ('falling', 'fallen', 'standing', 'reset')
_OUTSIDE = int(ContactMode.OUTSIDE)
#: Largest time to fall reported [s].
MAX_TIME_TO_FALL_S = 1e3
#: Why a sample without the base's attitude is not predicted by a model that reads it.
NO_ATTITUDE = ('the model reads the base\'s attitude (method §8c) and this measurement has none '
               '(no base orientation, or no earlier one to take its angular velocity from)')
_NAN2 = (math.nan, math.nan)


@dataclass(frozen=True, slots=True)
class MonitorState:
    """The monitor's output for one input sample (``fall_predictor/state``)."""

    status: int
    reason: str = ''                    #: why status is not OK, in words
    falling: bool = False               #: the prediction (history window applied)
    latched: bool = False               #: falling predicted since the last reset: the trigger
    atomic: bool = False                #: the contact mode's decision list alone said falling
    guard: bool = False                 #: the CoM was below the guard height
    contact_mode: Optional[int] = None  #: index into CONTACT_MODE_NAMES; None if unknown
    time_to_fall_s: float = math.nan    #: predicted time left until fallen [s]
    fall_direction: tuple[float, float] = _NAN2     #: unit (x, y), heading frame
    tau_his_s: float = 0.0              #: history window in use [s]

    @property
    def word(self) -> str:
        """One word for logs: falling, balanced, or the status."""
        if self.status != STATUS_OK:
            return STATUS_NAMES[self.status]
        return 'falling' if self.falling else 'balanced'


@dataclass(frozen=True, slots=True)
class FallEvent:
    """A change of the robot's fall state (``fall_predictor/fall_event``)."""

    kind: int
    direction: tuple[float, float] = _NAN2
    time_to_fall_s: float = math.nan
    contact_mode: Optional[int] = None


@dataclass(frozen=True)
class FallenConfig:
    """When the robot is down and when it stands again (robot-specific heights: its profile)."""

    fallen_com_height_m: float
    standing_com_height_m: float
    fallen_tilt_rad: float = math.radians(60.0)
    standing_tilt_rad: float = math.radians(30.0)
    standing_time_s: float = 1.0
    unsupported_s: float = 0.5

    def __post_init__(self) -> None:
        if not 0.0 < self.fallen_com_height_m < self.standing_com_height_m:
            raise ValueError(f'need 0 < fallen_com_height_m < standing_com_height_m, got '
                             f'{self.fallen_com_height_m} and {self.standing_com_height_m}')
        if not 0.0 < self.standing_tilt_rad < self.fallen_tilt_rad <= math.pi:
            raise ValueError('need 0 < standing_tilt_rad < fallen_tilt_rad <= pi')
        for name in ('standing_time_s', 'unsupported_s'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f'{name} must be >= 0, got {value}')


class FallMonitor:
    """Features in, :class:`MonitorState` (and :class:`FallEvent` s) out; see the module docs.

    ``time_to_fall``: an object with ``predict_one(x, mode)`` (the model's regressor) or None;
    ``fall_direction``: the model's learned direction or None (the momentum's direction);
    ``mass_kg``: the robot's mass (the momentum's direction does not depend on it, its capture
    point would).
    """

    def __init__(self, lists: PerModeDecisionLists, tau_his_s: float, fallen: FallenConfig,
                 dt_s: float = 0.001, guard_com_height_m: Optional[float] = None,
                 mass_kg: float = 1.0, time_to_fall: Optional[object] = None,
                 max_gap_s: float = 0.1, fall_direction: Optional[LearnedDirection] = None
                 ) -> None:
        kwargs = {} if guard_com_height_m is None else {'guard_com_height_m': guard_com_height_m}
        self.predictor = OnlinePredictor(lists, tau_his_s, dt_s, **kwargs)
        self._n_inputs = lists.n_inputs     # another decision threshold keeps the trees' inputs
        self.fallen_config = fallen
        self.mass_kg = float(mass_kg)
        self.time_to_fall = time_to_fall
        self.direction_of = momentum_direction if fall_direction is None else fall_direction.direction
        self.max_gap_s = float(max_gap_s)
        self.enabled = True
        self.reset()

    @property
    def tau_his_s(self) -> float:
        return self.predictor.tau_his_s

    @tau_his_s.setter
    def tau_his_s(self, value: float) -> None:
        self.predictor.tau_his_s = value

    @property
    def decision_threshold(self) -> Optional[float]:
        """Boosted trees' decision threshold [log-odds] (None for decision lists); settable at
        any time, effective from the next step (ValueError for decision lists)."""
        return self.predictor.lists.decision_threshold

    @decision_threshold.setter
    def decision_threshold(self, value: float) -> None:
        self.predictor.lists = self.predictor.lists.with_decision_threshold(value)

    @property
    def latched(self) -> bool:
        return self._latched

    @property
    def fallen(self) -> bool:
        return self._fallen

    def reset(self) -> FallEvent:
        """Start over: no history, no latch, not fallen (the only way to undo a fall)."""
        self.predictor.reset()
        self._latched = False
        self._fallen = False
        self._standing_since: Optional[float] = None
        self._unsupported_since: Optional[float] = None
        self._last_t = -math.inf
        return FallEvent(EVENT_RESET)

    def new_run(self) -> None:
        """The input's clock jumped (a new run): the window restarts; latch and fallen stay."""
        self.predictor.reset()
        self._standing_since = None
        self._unsupported_since = None
        self._last_t = -math.inf

    def enable(self, enabled: bool) -> None:
        """Switch the trigger on or off; either way the window restarts. A latched fall stays
        latched: only :meth:`reset` undoes it."""
        if enabled != self.enabled:
            self.enabled = enabled
            self.predictor.reset()

    def take_over(self, latched: bool, fallen: bool) -> None:
        """Continue from a monitor this one replaces (a node reconfigured with its model read
        again): its latch and whether the robot is down carry over; only :meth:`reset` undoes
        them."""
        self._latched = bool(latched)
        self._fallen = bool(fallen)

    def unusable(self, reason: str, stale: bool = False) -> MonitorState:
        """The state of a sample that cannot be used (degraded sensors, or stale): a hole in the
        data, which restarts the window only when it lasts longer than ``max_gap_s`` (the next
        usable sample's :meth:`step` tells)."""
        self._standing_since = None
        return MonitorState(STATUS_STALE if stale else STATUS_DEGRADED, bound_text(reason),
                            latched=self._latched, tau_his_s=self.predictor.tau_his_s)

    @property
    def n_inputs(self) -> int:
        """Length of the input vector the model reads: 15 features, or 19 with the attitude."""
        return self._n_inputs

    def step(self, t: float, x: Sequence[float], mode: int, base_tilt_rad: float = 0.0
             ) -> tuple[MonitorState, Optional[FallEvent]]:
        """One sample at run time ``t`` [s]: inputs ``x`` (the 15 features, then the base's
        attitude for a model that reads it: :attr:`n_inputs`), contact mode, base tilt [rad].
        A model that reads the attitude gives a DEGRADED state for a sample without it."""
        values = x.tolist() if hasattr(x, 'tolist') else list(x)
        if self._n_inputs > N_FEATURES and not (
                len(values) >= self._n_inputs
                and all(v == v for v in values[N_FEATURES:self._n_inputs])):     # NaN != NaN
            return self.unusable(NO_ATTITUDE), None
        if t - self._last_t > self.max_gap_s:
            self.predictor.reset()              # a hole in the input: the window starts over
        self._last_t = t
        event = self._update_fallen(t, values[COM_HEIGHT_FEATURE], base_tilt_rad, mode)
        tau = self.predictor.tau_his_s
        if self._fallen:
            self.predictor.reset()
            return MonitorState(STATUS_FALLEN, 'the robot is down', latched=self._latched,
                                contact_mode=mode, tau_his_s=tau), event
        if not self.enabled:
            return MonitorState(STATUS_DISABLED, 'the fall trigger is disabled', latched=self._latched,
                                contact_mode=mode, tau_his_s=tau), event
        out = self.predictor.step(t, values, mode)
        direction, time_to_fall_s = _NAN2, math.nan
        if out.falling:
            d = self.direction_of(values, self.mass_kg)
            direction = (float(d[0]), float(d[1]))
            if self.time_to_fall is not None:
                time_to_fall_s = min(max(float(self.time_to_fall.predict_one(values, mode)), 0.0),
                                     MAX_TIME_TO_FALL_S)
            if not self._latched:
                self._latched = True
                event = FallEvent(EVENT_FALLING, direction, time_to_fall_s, mode)
        return MonitorState(STATUS_OK, '', out.falling, self._latched, out.atomic, out.guard, mode,
                            time_to_fall_s, direction, tau), event

    def _update_fallen(self, t: float, com_height_m: float, tilt_rad: float, mode: int
                       ) -> Optional[FallEvent]:
        cfg = self.fallen_config
        supported = mode != _OUTSIDE
        if supported:
            self._unsupported_since = None
        elif self._unsupported_since is None:
            self._unsupported_since = t
        if not self._fallen:
            unsupported = (self._unsupported_since is not None
                           and t - self._unsupported_since >= cfg.unsupported_s)
            if (com_height_m < cfg.fallen_com_height_m or tilt_rad > cfg.fallen_tilt_rad
                    or unsupported):
                self._fallen = True
                self._standing_since = None
                return FallEvent(EVENT_FALLEN, contact_mode=mode)
            return None
        upright = (supported and com_height_m > cfg.standing_com_height_m
                   and tilt_rad < cfg.standing_tilt_rad)
        if not upright:
            self._standing_since = None
            return None
        if self._standing_since is None:
            self._standing_since = t
        if t - self._standing_since >= cfg.standing_time_s:
            self._fallen = False
            self._standing_since = None
            return FallEvent(EVENT_STANDING, contact_mode=mode)
        return None
