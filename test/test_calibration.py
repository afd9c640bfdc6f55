"""sim/calibration.py: the push range suggested from a calibration's runs (known answers), and one
real calibration run of the G1 under Unitree's policy."""
from __future__ import annotations

import numpy as np
import pytest

from fall_predictor.sim.calibration import CalibrationSetup, calibration_run, suggest_force_range


def rows(falls_above_n: float, probe_n: float = 1000.0, n: int = 2000) -> list[dict]:
    forces = np.linspace(0.0, probe_n, n)
    return [{'force_n': float(f), 'fallen': bool(f >= falls_above_n),
             'push_to_fall_s': 0.5 if f >= falls_above_n else None} for f in forces]


@pytest.mark.parametrize('threshold_n, target, expected_n', [
    (500.0, 0.5, 1000.0),       # falls above 500 N: U[0, 1000] fells half
    (300.0, 0.5, 600.0),
    (800.0, 0.5, 1600.0),       # beyond the probe: the last band's probability (1) carried on
    (500.0, 0.25, 700.0),       # a quarter: 0.25 = (F - 500) / F at F = 667, on the 100 N grid
])
def test_a_step_in_the_fall_probability_gives_the_range_of_the_wanted_fraction(
        threshold_n, target, expected_n) -> None:
    summary = suggest_force_range(rows(threshold_n), target)
    assert summary['suggested_push_force_n'][1] == pytest.approx(expected_n, abs=1.0)
    assert summary['predicted_fall_fraction'] == pytest.approx(target, abs=0.05)
    assert summary['fall_fraction'] == pytest.approx(1.0 - threshold_n / 1000.0, abs=0.01)


def test_noisy_bands_are_made_non_decreasing_with_force() -> None:
    """A band with fewer falls than the one below it (noise) counts as the lower band's."""
    data = rows(500.0)
    for r in data:
        if 700.0 <= r['force_n'] < 800.0:
            r['fallen'] = False
    summary = suggest_force_range(data, 0.5)
    assert summary['fall_probability_by_force'][7]['fall_fraction'] == 0.0
    assert summary['suggested_push_force_n'][1] == pytest.approx(1000.0, abs=1.0)


def test_a_calibration_run_of_the_g1_under_its_policy() -> None:
    """Runs of the dataset protocol with forces drawn up to the probe: a strong push fells the
    walking G1, a weak one does not (the policy's own range, far above C_bal's)."""
    weak = calibration_run((CalibrationSetup('g1_12dof', None, None, 100.0, seed=1), 0))
    strong = calibration_run((CalibrationSetup('g1_12dof', None, None, 4000.0, seed=1), 0))
    assert weak['force_n'] < 100.0 and not weak['fallen'] and weak['command'] is not None
    assert strong['force_n'] > 1000.0 and strong['fallen']
    assert 0.2 < strong['push_to_fall_s'] < 2.0
