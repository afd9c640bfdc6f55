"""Baselines with cross-validated thresholds and the tau_his grid (fall_predictor.learning.
fair_baselines), on hand-made trajectories with a known answer."""
import numpy as np
import pytest

from fall_predictor.learning.evaluation import BaselineGrids
from fall_predictor.learning.fair_baselines import cross_validated_baselines, nested_baseline_json
from fall_predictor.monitor.records import FEATURE_NAMES, TrajectoryFeatures

DT = 0.001
COM_Z = FEATURE_NAMES.index('com_z')


def trajectory(name: str, fallen: bool, dip_m: float) -> TrajectoryFeatures:
    """3 s at CoM height 0.59 m; after the push (1 s) the CoM dips by ``dip_m`` for 5 ms
    (a balanced one) or sinks linearly to 0.30 m at t_fallen 2.5 s (a fallen one)."""
    t = np.arange(3000) * DT
    X = np.zeros((t.size, len(FEATURE_NAMES)))
    X[:, COM_Z] = 0.59
    if fallen:
        X[1000:2500, COM_Z] = np.linspace(0.59, 0.30, 1500)
    else:
        X[1500:1505, COM_Z] = 0.59 - dip_m
    return TrajectoryFeatures(name, t, X, np.zeros(t.size, int), fallen, 1.0, 1.1,
                              2.5 if fallen else None, 1.0 if fallen else None)


def test_a_short_window_removes_the_baselines_spurious_alarms():
    # Balanced trajectories dip to 0.53 m for 5 ms: CoM < 0.55 m alarms on them without a
    # window, never with tau_his >= 0.005 s; the fallen ones cross 0.55 m at t = 1.2 s.
    trajectories = [trajectory(f'b{i}', False, 0.06) for i in range(8)] + \
                   [trajectory(f'f{i}', True, 0.0) for i in range(4)]
    heights = [0.50, 0.55]
    entries = nested_baseline_json(trajectories, heights,
                                   lambda i, h: trajectories[i].X[:, COM_Z] < h,
                                   (0.0, 0.01), folds=4, seed=0, budgets=(0.0,))
    entry = entries[0]
    # every outer fold chooses h = 0.55 m with the 10 ms window: no false alarm, lead
    # t_fallen - (crossing of 0.55 m + 10 ms)
    assert all(c == {'threshold': 0.55, 'tau_his_s': 0.01} for c in entry['chosen_per_fold'])
    crossing = 1.0 + (0.59 - 0.55) / (0.29 / 1.5)
    assert entry['outer']['fpr'] == 0.0 and entry['outer']['n_balanced'] == 8
    assert entry['outer']['tau_lead_s'] == pytest.approx(2.5 - crossing - 0.01, abs=2e-3)


def test_all_three_baselines_are_reported():
    trajectories = [trajectory(f'b{i}', False, 0.02) for i in range(6)] + \
                   [trajectory(f'f{i}', True, 0.0) for i in range(4)]
    distances = [np.where(t.X[:, COM_Z] < 0.5, 0.1, -0.1) for t in trajectories]
    report = cross_validated_baselines(trajectories, distances, BaselineGrids.coarse(),
                                       (0.0, 0.03), folds=2, seed=1, budgets=(0.0, 0.5))
    assert set(report) == {'com_height', 'momentum', 'capture_point'}
    for entries in report.values():
        assert [e['max_fpr'] for e in entries] == [0.0, 0.5]
        assert all(len(e['chosen_per_fold']) == 2 for e in entries)


def test_the_baselines_run_with_the_robots_guard():
    """A momentum baseline that never alarms (zero momenta here) is its CoM guard alone: at the
    G1's 0.55 m it alarms on the 0.53 m dips and predicts the falls when the CoM crosses 0.55 m;
    at the default (the ASIMO-like robot's 0.48 m) it never alarms and is late by 0.07 m of
    sinking."""
    trajectories = [trajectory(f'b{i}', False, 0.06) for i in range(4)] + \
                   [trajectory(f'f{i}', True, 0.0) for i in range(4)]
    sink_m_s = 0.29 / 1.5
    for guard, fpr, crossing in ((0.55, 1.0, 1.0 + 0.04 / sink_m_s), (None, 0.0, 1.0 + 0.11 / sink_m_s)):
        kwargs = {} if guard is None else {'guard_com_height_m': guard}
        report = cross_validated_baselines(trajectories, None, BaselineGrids.coarse(), (0.0,),
                                           folds=2, seed=0, budgets=(0.0,), **kwargs)
        outer = report['momentum'][0]['outer']
        assert outer['fpr'] == fpr and outer['n_balanced'] == 4
        assert outer['tau_lead_s'] == pytest.approx(2.5 - crossing, abs=2e-3)
