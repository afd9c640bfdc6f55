"""FallMonitor (monitor/fall_monitor.py): the predictor node's logic, exactly, without ROS."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fall_predictor.monitor.contact_modes import ContactMode
from fall_predictor.monitor.decision_list import Condition, DecisionList, PerModeDecisionLists, Rule
from fall_predictor.monitor.fall_monitor import (EVENT_FALLEN, EVENT_FALLING, EVENT_RESET,
                                                 EVENT_STANDING, STATUS_DEGRADED, STATUS_DISABLED,
                                                 STATUS_FALLEN, STATUS_OK, STATUS_STALE,
                                                 FallenConfig, FallMonitor)
from fall_predictor.monitor.records import FALLING, FEATURE_NAMES, N_CONTACT_MODES

LIN_X = FEATURE_NAMES.index('lin_mom_x')
DT = 0.001
INSIDE, OUTSIDE = int(ContactMode.LR_INSIDE), int(ContactMode.OUTSIDE)


class Regressor:
    """A time-to-fall regressor that says 0.3 s, or what it is told."""

    def __init__(self, value: float = 0.3) -> None:
        self.value = value

    def predict_one(self, x, mode):
        return self.value


def monitor(tau_his_s: float = 0.01, **kwargs) -> FallMonitor:
    rule = Rule((Condition(LIN_X, '>', 25.0),), FALLING)
    lists = PerModeDecisionLists(tuple(DecisionList((rule,)) for _ in range(N_CONTACT_MODES)))
    return FallMonitor(lists, tau_his_s, FallenConfig(0.33, 0.48), DT, 0.48, 42.1, **kwargs)


def features(p_x: float = 0.0, com_z: float = 0.59, p_y: float = 0.0) -> np.ndarray:
    x = np.zeros(15)
    x[2], x[LIN_X], x[LIN_X + 1] = com_z, p_x, p_y
    return x


def run(m: FallMonitor, t0: float, n: int, mode: int = INSIDE, tilt: float = 0.0, **f):
    out = []
    for k in range(n):
        out.append(m.step(round(t0 + k * DT, 6), features(**f), mode, tilt))
    return out


def test_the_trigger_latches_after_the_window_with_direction_and_time_to_fall():
    m = monitor(tau_his_s=0.01, time_to_fall=Regressor(2e3))
    assert not any(s.falling for s, _ in run(m, 0.0, 50))
    out = run(m, 0.05, 20, p_x=30.0, p_y=30.0)
    falling = [k for k, (s, _) in enumerate(out) if s.falling]
    assert falling[0] == 10                                 # the run lasted tau_his (10 ms)
    state, event = out[10]
    assert event.kind == EVENT_FALLING and state.latched and state.status == STATUS_OK
    assert state.fall_direction == pytest.approx((math.sqrt(0.5), math.sqrt(0.5)))
    assert state.time_to_fall_s == 1e3                      # clamped to [0, 1000] s
    assert [e for _, e in out if e is not None] == [event]  # one FALLING event
    later = run(m, 0.07, 10)                                # back to balanced: still latched
    assert all(s.latched and not s.falling for s, _ in later)
    assert m.reset().kind == EVENT_RESET and not m.latched


def test_unusable_samples_are_holes_and_long_holes_restart_the_window_keeping_the_latch():
    m = monitor(tau_his_s=0.01)
    run(m, 0.0, 8, p_x=30.0)
    degraded = m.unusable('no /imu/data within 5 ms of /joint_states')     # the sample at 8 ms
    assert (degraded.status, degraded.reason, degraded.falling) == (
        STATUS_DEGRADED, 'no /imu/data within 5 ms of /joint_states', False)
    out = run(m, 0.009, 11, p_x=30.0)
    # A hole of one sample: the window that began at 0 s spans it and ends at 10 ms.
    assert [s.falling for s, _ in out].index(True) == 1
    assert m.unusable('late', stale=True).status == STATUS_STALE
    assert m.unusable('late', stale=True).latched           # the latch stays
    m.reset()
    run(m, 1.0, 8, p_x=30.0)
    for k in range(8, 110):                                 # degraded from 1.008 s to 1.109 s
        assert not m.unusable('joint l_knee_pitch stuck').falling
    out = run(m, 1.110, 11, p_x=30.0)                       # a hole of 0.103 s: a fresh window
    assert [s.falling for s, _ in out].index(True) == 10
    m.reset()
    run(m, 1.0, 8, p_x=30.0)
    out = run(m, 1.5, 11, p_x=30.0)                         # 0.5 s later: a gap, not one run
    assert [s.falling for s, _ in out].index(True) == 10


def test_disabled_means_no_prediction_and_no_latch():
    m = monitor()
    m.enable(False)
    out = run(m, 0.0, 30, p_x=30.0)
    assert all(s.status == STATUS_DISABLED and not s.falling for s, _ in out)
    assert not m.latched and all(e is None for _, e in out)
    m.enable(True)
    assert any(s.falling for s, _ in run(m, 0.03, 30, p_x=30.0))


def test_a_latched_fall_survives_the_trigger_switched_off_and_on_and_a_new_monitor():
    m = monitor()
    run(m, 0.0, 30, p_x=30.0)
    assert m.latched
    m.enable(False)
    out = run(m, 0.03, 5, p_x=0.0)
    assert all(s.status == STATUS_DISABLED and s.latched for s, _ in out)
    m.enable(True)
    assert m.latched and all(s.latched for s, _ in run(m, 0.035, 5, p_x=0.0))
    other = monitor()                               # a node reconfigured: its model read again
    other.take_over(m.latched, m.fallen)
    assert other.latched and all(s.latched for s, _ in run(other, 0.0, 5, p_x=0.0))
    assert other.reset().kind == EVENT_RESET and not other.latched


@pytest.mark.parametrize('how, kwargs', [
    ('CoM low', {'com_z': 0.30}),
    ('tilted', {'tilt': math.radians(70)}),
])
def test_the_robot_is_down_and_stands_again(how, kwargs):
    m = monitor()
    run(m, 0.0, 10)
    down = run(m, 0.01, 5, **kwargs)
    assert down[0][1].kind == EVENT_FALLEN and all(s.status == STATUS_FALLEN for s, _ in down)
    assert not any(s.falling for s, _ in down)
    # Upright again: standing after 1 s upright, on a foot.
    up = run(m, 0.1, 1100)
    events = [(k, e.kind) for k, (_, e) in enumerate(up) if e is not None]
    assert events == [(1000, EVENT_STANDING)]
    assert up[999][0].status == STATUS_FALLEN and up[1000][0].status == STATUS_OK


def test_no_foot_on_the_ground_for_half_a_second_is_down():
    m = monitor()
    out = run(m, 0.0, 600, mode=OUTSIDE)                    # lifted off the ground
    kinds = [(k, e.kind) for k, (_, e) in enumerate(out) if e is not None]
    assert kinds == [(500, EVENT_FALLEN)]
    # Upright but still without a foot on the ground: not standing.
    assert all(e is None for _, e in run(m, 0.6, 1500, mode=OUTSIDE))


def test_a_bad_configuration_is_refused():
    with pytest.raises(ValueError):
        FallenConfig(0.5, 0.4)
    with pytest.raises(ValueError):
        FallenConfig(0.3, 0.5, unsupported_s=-1.0)


def test_a_model_with_a_learned_direction_reports_it():
    from fall_predictor.monitor.fall_direction import DIRECTION_INPUT_NAMES, LearnedDirection
    from fall_predictor.monitor.time_to_fall import RegressionTree
    turn = RegressionTree((-1,), (0.0,), (-1,), (-1,), (0.5,), n_inputs=len(DIRECTION_INPUT_NAMES))
    m = monitor(tau_his_s=0.0, fall_direction=LearnedDirection((turn,)))
    state, event = run(m, 0.0, 1, p_x=30.0)[0]                 # momentum along +x
    assert state.falling and event.kind == EVENT_FALLING
    assert state.fall_direction == pytest.approx((math.cos(0.5), math.sin(0.5)))
    assert event.direction == state.fall_direction


def test_a_model_reading_the_attitude_says_degraded_without_it_and_predicts_with_it():
    """Boosted trees on the base's roll rate (input 17): falling when it exceeds 1 rad/s. Fed
    the 15 features only, or the attitude as NaN (a measurement without a base orientation),
    each sample is DEGRADED with the reason; fed the 19 inputs, the trees decide."""
    from fall_predictor.monitor.boosted_trees import BoostedTrees
    from fall_predictor.monitor.fall_monitor import NO_ATTITUDE, STATUS_DEGRADED, STATUS_OK
    from fall_predictor.monitor.time_to_fall import RegressionTree
    tree = RegressionTree((17, -1, -1), (1.0, 0.0, 0.0), (1, -1, -1), (2, -1, -1), (0.0, -5.0, 5.0),
                          n_inputs=19)
    lists = PerModeDecisionLists(tuple(BoostedTrees((tree,), 0.0) for _ in range(N_CONTACT_MODES)))
    m = FallMonitor(lists, 0.005, FallenConfig(0.33, 0.48), DT, 0.48, 42.1)
    assert m.n_inputs == 19
    state, _ = m.step(0.0, features(), INSIDE)
    assert state.status == STATUS_DEGRADED and state.reason == NO_ATTITUDE
    state, _ = m.step(0.001, np.concatenate([features(), [0.1, 0.0, np.nan, np.nan]]), INSIDE)
    assert state.status == STATUS_DEGRADED and 'no base orientation' in state.reason
    steady = np.concatenate([features(), [0.1, 0.0, 0.2, 0.0]])
    tipping = np.concatenate([features(), [0.1, 0.0, 1.5, 0.0]])
    states = [m.step(0.002 + k * DT, steady, INSIDE)[0] for k in range(10)]
    assert all(s.status == STATUS_OK and not s.falling for s in states)
    states = [m.step(0.012 + k * DT, tipping, INSIDE)[0] for k in range(10)]
    assert [s.falling for s in states] == [False] * 5 + [True] * 5     # after the 5 ms window
    assert states[-1].latched
