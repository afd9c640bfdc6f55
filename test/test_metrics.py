import math

import numpy as np
import pytest

from fall_predictor.learning.metrics import (TrajectoryAlarms, evaluate, evaluate_atomic,
                                             mean_or_nan, std_or_nan, trajectory_alarms)
from fall_predictor.monitor.records import FEATURE_NAMES, TrajectoryFeatures

DT = 0.001
COM_Z = FEATURE_NAMES.index('com_z')


def trajectory(name: str, fallen: bool, duration_s: float = 3.0, t_push: float = 1.0,
               t_fallen: float = 2.5, com_drop_at: float | None = None) -> TrajectoryFeatures:
    """Features all zero except a standing CoM height; optionally the CoM drops to 0.40 m."""
    t = np.arange(int(round(duration_s / DT))) * DT
    X = np.zeros((t.size, len(FEATURE_NAMES)))
    X[:, COM_Z] = 0.59
    if com_drop_at is not None:
        X[t >= com_drop_at - 1e-9, COM_Z] = 0.40
    return TrajectoryFeatures(name, t, X, np.zeros(t.size, dtype=int), fallen, t_push, t_push + 0.1,
                              t_fallen if fallen else None, t_fallen - 0.3 if fallen else None)


def alarm_at(traj: TrajectoryFeatures, *times: float, length_s: float = 0.0) -> np.ndarray:
    """Atomic predictions: falling from each of ``times`` for ``length_s`` seconds."""
    atomic = np.zeros(traj.t.size, dtype=bool)
    for start in times:
        atomic[(traj.t >= start - 1e-9) & (traj.t <= start + length_s + 1e-9)] = True
    return atomic


def test_fpr_and_lead_on_hand_made_trajectories():
    balanced = [trajectory(f'b{i}', False) for i in range(3)]
    fallen = trajectory('f', True, t_fallen=2.5)
    trajectories = balanced + [fallen]
    atomic = [np.zeros(3000, bool), alarm_at(balanced[1], 1.7), np.zeros(3000, bool),
              alarm_at(fallen, 2.0, length_s=0.5)]
    result = evaluate_atomic(trajectories, atomic, tau_his_values=(0.0,))[0.0]
    assert result.fpr == pytest.approx(1 / 3)
    assert result.n_false_positives == 1 and result.n_balanced == 3 and result.n_fallen == 1
    assert result.tau_lead_s == pytest.approx(0.5)
    assert result.n_missed == 0
    assert result.oracle_lead_s == pytest.approx(1.5)
    assert result.lead_fraction == pytest.approx(1 / 3)
    assert result.n_pre_push_alarms == 0


def test_history_window_suppresses_the_spike_but_delays_the_fall():
    balanced = [trajectory(f'b{i}', False) for i in range(3)]
    fallen = trajectory('f', True, t_fallen=2.5)
    atomic = [np.zeros(3000, bool), alarm_at(balanced[1], 1.7), np.zeros(3000, bool),
              alarm_at(fallen, 2.0, length_s=0.5)]
    results = evaluate_atomic(balanced + [fallen], atomic, tau_his_values=(0.0, 0.002, 0.1))
    assert results[0.0].fpr == pytest.approx(1 / 3)
    assert results[0.002].fpr == 0.0
    assert results[0.002].tau_lead_s == pytest.approx(0.498)
    assert results[0.1].tau_lead_s == pytest.approx(0.4)


def test_misses_count_zero_lead():
    fallen = [trajectory('early', True), trajectory('never', True), trajectory('at', True)]
    atomic = [alarm_at(fallen[0], 1.5, length_s=1.5), np.zeros(3000, bool), alarm_at(fallen[2], 2.5)]
    result = evaluate_atomic(fallen, atomic)[0.0]
    assert result.n_missed == 2                      # none, and exactly at t_fallen
    assert result.tau_lead_s == pytest.approx(1.0 / 3)
    assert math.isnan(result.fpr) and result.n_balanced == 0


def test_guard_catches_a_fall_the_list_misses():
    fallen = trajectory('f', True, t_fallen=2.5, com_drop_at=2.3)
    result = evaluate_atomic([fallen], [np.zeros(3000, bool)], tau_his_values=(0.0, 0.05, 1.0))
    assert result[0.0].tau_lead_s == pytest.approx(0.2)
    assert result[0.05].tau_lead_s == pytest.approx(0.15)   # the guard is windowed too
    assert result[0.0].n_missed == 0 and result[0.05].n_missed == 0
    assert result[1.0].n_missed == 1                        # 0.2 s of low CoM < 1 s window


def test_pre_push_alarms_are_reported_separately():
    balanced = trajectory('b', False)
    fallen = trajectory('f', True, t_fallen=2.5)
    atomic = [alarm_at(balanced, 0.5), alarm_at(fallen, 0.5, 2.2)]
    result = evaluate_atomic([balanced, fallen], atomic)[0.0]
    assert result.n_pre_push_alarms_balanced == 1      # also a false positive
    assert result.n_pre_push_alarms_fallen == 1        # not in FPR; lead from the first alarm after the push
    assert result.fpr == 1.0
    assert result.tau_lead_s == pytest.approx(0.3)
    assert result.n_pre_push_alarms == 2


def test_evaluate_from_alarm_times():
    fallen = trajectory('f', True, t_fallen=2.5)
    alarms = trajectory_alarms(fallen.t, alarm_at(fallen, 0.2, 1.9), fallen.t_push)
    assert alarms == TrajectoryAlarms(first_alarm_t=fallen.t[200], first_alarm_after_push_t=fallen.t[1900],
                                      pre_push_alarm=True)
    result = evaluate([fallen], [alarms], mean_rule_size=3.5)
    assert result.tau_lead_s == pytest.approx(0.6) and result.mean_rule_size == 3.5
    with pytest.raises(ValueError):
        evaluate([fallen], [])


def test_mean_and_std_leave_nan_out_and_are_nan_without_values():
    assert math.isnan(mean_or_nan([])) and math.isnan(std_or_nan([]))
    assert math.isnan(mean_or_nan([math.nan, math.nan])) and math.isnan(std_or_nan([math.nan]))
    assert mean_or_nan([1.0, math.nan, 3.0]) == 2.0
    assert std_or_nan([1.0, math.nan, 3.0]) == 1.0           # population standard deviation
    assert mean_or_nan((0.5,)) == 0.5 and std_or_nan((0.5,)) == 0.0
    assert mean_or_nan([1.0, math.inf]) == math.inf           # only NaN is left out


def test_lists_alone_and_guard_alone_are_reported_apart():
    # The list says falling 0.5 s before fallen on one trajectory and never on the other; the
    # guard fires 0.2 s before fallen on both.
    caught = trajectory('caught', True, t_fallen=2.5, com_drop_at=2.3)
    missed = trajectory('missed', True, t_fallen=2.5, com_drop_at=2.3)
    result = evaluate_atomic([caught, missed], [alarm_at(caught, 2.0, length_s=0.5),
                                                np.zeros(3000, bool)])[0.0]
    assert result.n_missed == 0                         # the guard hides the miss
    assert result.tau_lead_s == pytest.approx((0.5 + 0.2) / 2)
    assert result.n_missed_lists_only == 1
    assert result.tau_lead_lists_only_s == pytest.approx(0.5 / 2)
    assert result.tau_lead_guard_only_s == pytest.approx(0.2)


def test_fpr_interval_is_wilson_and_lead_interval_brackets_the_mean():
    balanced = [trajectory(f'b{i}', False) for i in range(10)]
    fallen = [trajectory(f'f{i}', True, t_fallen=2.5) for i in range(4)]
    atomic = ([alarm_at(balanced[0], 1.5), alarm_at(balanced[1], 1.5)]
              + [np.zeros(3000, bool)] * 8
              + [alarm_at(f, start, length_s=2.5 - start) for f, start in
                 zip(fallen, (1.1, 1.5, 2.0, 2.4))])
    result = evaluate_atomic(balanced + fallen, atomic)[0.0]
    assert result.fpr == pytest.approx(0.2)
    low, high = result.fpr_ci95
    # Wilson 95 % for 2/10 (Agresti & Coull 1998 tables): [0.0567, 0.5098]
    assert low == pytest.approx(0.0567, abs=5e-4) and high == pytest.approx(0.5098, abs=5e-4)
    lead_low, lead_high = result.tau_lead_ci95
    assert lead_low <= result.tau_lead_s <= lead_high
    assert 0.1 - 1e-9 <= lead_low < lead_high <= 1.4 + 1e-9   # within the smallest/largest lead
