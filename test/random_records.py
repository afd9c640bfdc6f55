"""Random but well-formed records for round-trip tests of the wire and bag formats."""
import numpy as np

from fall_predictor.monitor.records import Measurement


def make_measurement(rng, n_left, n_right, t=0.123):
    return Measurement(
        t=t, com=rng.normal(size=3), lin_mom=rng.normal(size=3), ang_mom=rng.normal(size=3),
        heading=float(rng.normal()),
        cop=rng.normal(size=3) if n_left + n_right else np.full(3, np.nan),
        left_contacts=rng.normal(size=(n_left, 3)), right_contacts=rng.normal(size=(n_right, 3)),
        left_foot=rng.normal(size=3), right_foot=rng.normal(size=3),
        non_foot_contact=bool(rng.integers(2)), push_force=rng.normal(size=3))
