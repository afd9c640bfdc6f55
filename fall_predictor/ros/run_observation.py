"""What the bring-up's observer makes of one push run, without ROS: the states it records, where a
new run begins in streams that still carry the previous run's messages, and the run's JSON-ready
report (:class:`RunObservation`; fields: :mod:`fall_predictor.ros.bringup`). The observer node
(:mod:`fall_predictor.ros.observer`) feeds them."""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any, Optional

from fall_predictor.contract.topics import SIM_RATE_HZ
from fall_predictor.monitor.fall_monitor import STATUS_DEGRADED, STATUS_STALE, MonitorState
from fall_predictor.monitor.records import Measurement, PushSpec

#: After a reset, a message stamped before this [s] begins the new run (simulation time
#: restarts at 0; :class:`RunBoundary`).
NEW_RUN_T_S = 0.5

#: The measurement period [s] a run is taken to have when the simulator does not report its own.
DEFAULT_SAMPLE_PERIOD_S = 1.0 / SIM_RATE_HZ


@dataclass(frozen=True)
class ObservedState:
    """One ``fall_predictor/state`` message as the observer recorded it: the sample time [s]
    (its stamp, simulation time) and the monitor's state."""

    t: float
    state: MonitorState

    def __getattr__(self, name: str) -> Any:
        return getattr(self.state, name)   # status, falling, latched, ... of the state

    @property
    def unusable(self) -> bool:
        """No prediction: a DEGRADED or STALE state."""
        return self.state.status in (STATUS_DEGRADED, STATUS_STALE)


def round_time(t: Optional[float]) -> Optional[float]:
    """A sample time [s] without float noise (samples are whole physics steps of 1 ms or more)."""
    return None if t is None else round(t, 6)


#: Distinct reasons a run's report keeps for its unusable states (RunObservation), and the key
#: that counts the rest.
MAX_REASONS = 5
OTHER_REASONS = '(other reasons)'
#: A measured value in a reason ("arrived 0.057 s after its stamp", "1e-05"): a decimal or an
#: exponent, which joint and sensor names do not contain.
_MEASURED_VALUE = re.compile(r'[-+]?\d+(?:\.\d+(?:e[-+]?\d+)?|e[-+]?\d+)')


def reason_kind(reason: str) -> str:
    """A reason with its measured values as ``#``: the reasons of one fault, whatever the values
    (``'sample arrived # s after its stamp (max_sample_age_s #)'``)."""
    return _MEASURED_VALUE.sub('#', reason)


class RunBoundary:
    """Where the new run begins in the measurement and state streams after a reset.

    Simulation time restarts at 0 on a reset, and messages of the previous run may still be in
    flight. Each stream has one writer (the simulator, the predictor) and arrives in order, so
    the new run begins at the first message stamped earlier than the latest one received: the
    previous run's messages only go forward. A message stamped before :data:`NEW_RUN_T_S` also
    begins it (the first run, or a previous run shorter than that). Neither test needs the new
    run's first messages: an observer that fell more than its queue behind, or a monitor whose
    best-effort inputs lost the new run's first half second, loses them.
    """

    def __init__(self) -> None:
        self._in_new_run = {'samples': True, 'states': True}
        #: Per stream the latest stamp received [s], of whichever run.
        self._t_latest = {'samples': -math.inf, 'states': -math.inf}

    def reset(self) -> None:
        """A reset was requested: drop the previous run's messages until the new run begins."""
        self._in_new_run = {'samples': False, 'states': False}

    def take_sample(self, t: float) -> bool:
        """Whether the measurement stamped ``t`` [s] belongs to the current run."""
        return self._take('samples', t)

    def take_state(self, t: float) -> bool:
        """Whether the state stamped ``t`` [s] belongs to the current run."""
        return self._take('states', t)

    def _take(self, stream: str, t: float) -> bool:
        if not self._in_new_run[stream] and (t < NEW_RUN_T_S or t < self._t_latest[stream]):
            self._in_new_run[stream] = True
        self._t_latest[stream] = t
        return self._in_new_run[stream]


@dataclass
class RunObservation:
    """What the bring-up saw of one push run (times in simulation seconds)."""

    push: PushSpec
    #: The measurement stream's period [s] (the simulator's physics step, or its sensors' joint
    #: state period): gaps are counted in it.
    sample_period_s: float = DEFAULT_SAMPLE_PERIOD_S
    #: The robot's fallen CoM height [m] (its profile's, method §4); None: the default robot's.
    fallen_com_height_m: Optional[float] = None
    t_last: float = -1.0                    #: latest measurement time of this run
    t_last_state: float = -1.0              #: latest state time of this run
    t_fallen: Optional[float] = None
    t_predict: Optional[float] = None       #: first falling state at or after the push
    false_alarm_before_push: bool = False
    degraded_states: int = 0
    #: Why those states were unusable: each kind of reason (the state's own words, measured
    #: values as ``#``: :func:`reason_kind`) with its count, the first MAX_REASONS kinds; later
    #: kinds are counted under OTHER_REASONS.
    degraded_reasons: dict[str, int] = field(default_factory=dict)
    #: Per kind of reason, the first reason of that kind in full (its values).
    degraded_reason_examples: dict[str, str] = field(default_factory=dict)
    push_applied_n: Optional[list[float]] = None
    measurements_started: bool = False
    #: Measurements this observer did not receive (gaps in the stamps): its reliable queue
    #: overflowed while it lagged, so ``t_fallen`` may be late by up to a gap.
    lost_samples: int = 0

    def add_measurement(self, m: Measurement) -> None:
        """Take one measurement of this run."""
        if self.measurements_started:
            missing = round((m.t - self.t_last) / self.sample_period_s) - 1
            self.lost_samples += max(missing, 0)
        self.measurements_started = True
        self.t_last = m.t
        if self.push_applied_n is None and m.push_force.any():
            self.push_applied_n = [round(float(v), 6) for v in m.push_force]
        fallen = m.fallen if self.fallen_com_height_m is None else bool(
            m.com[2] < self.fallen_com_height_m or m.non_foot_contact)
        if self.t_fallen is None and fallen:
            self.t_fallen = m.t

    def add_state(self, state: ObservedState) -> None:
        """Take one predictor state of this run."""
        self.t_last_state = max(self.t_last_state, state.t)
        if state.unusable:
            # Degraded states before the run's first sample only say it had not started.
            if self.measurements_started:
                self.degraded_states += 1
                reasons = self.degraded_reasons
                reason = state.reason or f'status {state.status}, no reason given'
                kind = reason_kind(reason)
                if kind not in reasons and len(reasons) >= MAX_REASONS:
                    kind = OTHER_REASONS
                elif kind not in reasons:
                    self.degraded_reason_examples[kind] = reason
                reasons[kind] = reasons.get(kind, 0) + 1
        elif state.falling:
            if state.t < self.push.t_push:
                self.false_alarm_before_push = True
            elif self.t_predict is None:
                self.t_predict = state.t

    def result(self, index: int, horizon_end_s: float,
               controller_mode: Optional[str]) -> dict[str, object]:
        """The run's JSON-ready report (fields: see :mod:`fall_predictor.ros.bringup`)."""
        push = self.push
        fell = self.t_fallen is not None
        predicted_in_time = (self.t_predict is not None
                             and (not fell or self.t_predict <= self.t_fallen))
        if fell:
            outcome = 'fall_predicted' if predicted_in_time else 'fall_missed'
        else:
            outcome = 'predicted_no_fall' if self.t_predict is not None else 'no_fall'
        lead = (self.t_fallen - self.t_predict) if fell and predicted_in_time else None
        return {
            'index': index,
            'push': {'force_n': push.force_n, 'angle_deg': push.angle_deg,
                     'height_m': push.height_m, 't_push': push.t_push,
                     'duration_s': push.duration_s, 'impulse_ns': push.impulse_ns},
            'push_applied_world_n': self.push_applied_n,
            'fell': fell,
            't_predict': round_time(self.t_predict),
            't_fallen': round_time(self.t_fallen),
            'lead_time_s': None if lead is None else round(lead, 6),
            'oracle_lead_s': None if not fell else round(self.t_fallen - push.t_push, 6),
            'outcome': outcome,
            'stopped_by': 'fallen' if fell else 'horizon',
            't_end': round_time(self.t_last),
            'horizon_end_s': horizon_end_s,
            'controller_mode': controller_mode,
            'false_alarm_before_push': self.false_alarm_before_push,
            'degraded_states': self.degraded_states,
            'degraded_reasons': dict(self.degraded_reasons),
            'degraded_reason_examples': dict(self.degraded_reason_examples),
            'observer_lost_samples': self.lost_samples,
        }
