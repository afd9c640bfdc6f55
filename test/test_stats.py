"""Robot-credibility statistics (fall_predictor.data.stats): CoM rise, airborne samples and
touchdown force peaks, on hand-made trajectories with known answers and on generated bags
against a computation straight from the recorded measurements."""
import numpy as np
import pytest

from fall_predictor.data.bagio import read_trajectory
from fall_predictor.data.dataset import load_features, read_index, robot_total_mass_kg
from fall_predictor.data.stats import com_rise_m, dataset_stats, robot_credibility, touchdown_force_peaks_n
from fall_predictor.monitor.records import N_FEATURES, STANDARD_GRAVITY_M_S2, TrajectoryFeatures

MASS_KG = 40.0
WEIGHT_N = MASS_KG * STANDARD_GRAVITY_M_S2


def trajectory(com_z, foot_force, t_push: float) -> TrajectoryFeatures:
    n = len(com_z)
    X = np.zeros((n, N_FEATURES))
    X[:, 2] = com_z
    t = np.arange(n) * 0.001
    return TrajectoryFeatures('synthetic', t, X, np.zeros(n, dtype=int), False, t_push, t_push + 0.1,
                              foot_force_n=np.asarray(foot_force, dtype=float))


def test_com_rise_is_measured_from_the_push_onset():
    z = np.full(1000, 0.58)
    z[100] = 0.70                      # before the push: not a rise caused by it
    z[600:650] = 0.60                  # after the push: 2 cm up
    traj = trajectory(z, np.full((1000, 2), WEIGHT_N / 2), t_push=0.5)
    assert com_rise_m(traj) == pytest.approx(0.02)


def test_airborne_upright_counts_only_flight_above_the_height_threshold():
    n = 1000
    z = np.full(n, 0.58)
    force = np.full((n, 2), WEIGHT_N / 2)
    force[200:230] = 0.0               # 30 samples of flight while upright
    force[800:900] = 0.0               # 100 samples with no foot contact ...
    z[800:900] = 0.30                  # ... while lying on the ground: not a launch
    stats = robot_credibility([trajectory(z, force, t_push=0.5)], MASS_KG)
    assert stats['airborne_upright_fraction'] == pytest.approx(30 / n)


def test_touchdown_peak_is_the_force_after_a_foot_lands_before_the_push():
    n = 2000
    force = np.zeros((n, 2))
    force[:, 1] = WEIGHT_N             # right foot stance all along
    force[300:, 0] = 0.2 * WEIGHT_N    # left foot lands at 0.3 s ...
    force[310:320, 0] = 0.9 * WEIGHT_N  # ... with a 0.9 BW spike: total 1.9 BW
    force[1600:, 0] = 0.0
    force[1700:, 0] = 3.0 * WEIGHT_N   # a landing after the push is not counted
    traj = trajectory(np.full(n, 0.58), force, t_push=1.5)
    peaks = touchdown_force_peaks_n(traj)
    assert peaks == [pytest.approx(1.9 * WEIGHT_N)]
    stats = robot_credibility([traj], MASS_KG)
    assert stats['touchdown_force_peak_bw']['max'] == pytest.approx(1.9)


def test_credibility_of_generated_bags_matches_the_recorded_measurements(small_dataset):
    rows = read_index(small_dataset)
    report = load_features(small_dataset, progress=False)
    mass = robot_total_mass_kg(small_dataset)
    stats = dataset_stats(rows, report.trajectories, mass)
    # Independent computation from the bags' measurements.
    airborne = samples = 0
    rises = []
    # Upright: above 0.45 / 0.589 of the median CoM height over each run's first 0.5 s.
    starts = []
    for row in rows:
        ms = read_trajectory(small_dataset / row.bag).measurements
        starts += [m.com[2] for m in ms if m.t <= ms[0].t + 0.5]
    upright = 0.45 / 0.589 * float(np.median(starts))
    for row in rows:
        ms = read_trajectory(small_dataset / row.bag).measurements
        z = np.array([m.com[2] for m in ms])
        t = np.array([m.t for m in ms])
        flight = np.array([len(m.left_contacts) == 0 and len(m.right_contacts) == 0 for m in ms])
        airborne += int((flight & (z > upright)).sum())
        samples += len(ms)
        k = int(np.argmin(np.abs(t - row.t_push)))
        rises.append(z[k:].max() - z[k])
    assert stats['airborne_upright_fraction'] == pytest.approx(airborne / samples)
    assert stats['com_rise_m']['max'] == pytest.approx(max(rises), abs=1e-9)
    # Walking puts the whole weight on the landing foot: each touchdown peak is at least about
    # one body weight, and a compliant landing stays well below the 2 BW aim's double.
    peaks = stats['touchdown_force_peak_bw']
    assert peaks is not None and peaks['n'] >= 4
    assert 0.9 < peaks['p50'] and peaks['max'] < 4.0
