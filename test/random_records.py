"""Random but well-formed records for round-trip tests of the wire and bag formats."""
import numpy as np

from fall_predictor.monitor.records import Measurement


def make_measurement(rng, n_left, n_right, t=0.123):
    """Random values within the plausibility bounds (monitor/plausibility.py): a CoM at a
    standing height, points within half a metre of it, non-negative contact forces."""
    com = np.r_[rng.normal(size=2) * 0.3, rng.uniform(0.3, 0.9)]

    def near_com(n):
        rows = rng.normal(size=(n, 3)) * 0.1
        rows[:, :2] += com[:2]
        rows[:, 2] = np.abs(rows[:, 2]) * 1000.0
        return rows

    cop = np.r_[com[:2] + rng.normal(size=2) * 0.1, rng.normal() * 0.01]
    return Measurement(
        t=t, com=com, lin_mom=rng.normal(size=3), ang_mom=rng.normal(size=3),
        heading=float(rng.normal()),
        cop=cop if n_left + n_right else np.full(3, np.nan),
        left_contacts=near_com(n_left), right_contacts=near_com(n_right),
        left_foot=np.r_[com[:2] + rng.normal(size=2) * 0.1, rng.normal()],
        right_foot=np.r_[com[:2] + rng.normal(size=2) * 0.1, rng.normal()],
        non_foot_contact=bool(rng.integers(2)), push_force=rng.normal(size=3))
