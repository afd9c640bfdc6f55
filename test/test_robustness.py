"""Push robustness table (fall_predictor.sim.robustness, `fall-predictor robustness`)."""
import subprocess
import sys

import numpy as np

from fall_predictor.sim.robustness import RobustnessGrid, run_robustness, survival_table


def test_survival_table_by_hand():
    grid = RobustnessGrid(impulses_ns=(5.0, 15.0, 30.0), directions_deg=(0.0, 90.0), n_phases=2)
    survived = np.ones((3, 2, 2), dtype=bool)
    survived[2, 0, 1] = False          # 30 N s forward falls at phase 1
    survived[1, 1, 0] = False          # 15 N s to the left falls at phase 0 ...
    survived[2, 1, 0] = True           # ... although 30 N s there is survived (not counted)
    table = survival_table(grid, survived)
    assert table['largest_impulse_survived_at_every_phase_ns'] == {'0': 15.0, '90': 5.0}
    assert table['survival_fraction_by_impulse'] == {'5': 1.0, '15': 0.75, '30': 0.75}
    assert table['aim_15_ns_everywhere'] is False
    assert table['aim_30_ns_forward_backward'] is False
    assert survival_table(RobustnessGrid(impulses_ns=(5.0,), directions_deg=(0.0,), n_phases=1),
                          np.ones((1, 1, 1), bool))['aim_15_ns_everywhere'] is None


def test_a_small_push_is_survived_and_a_huge_one_is_not():
    grid = RobustnessGrid(impulses_ns=(5.0, 80.0), directions_deg=(0.0,), n_phases=1, horizon_s=2.0)
    result = run_robustness(grid)
    assert result['survived'] == [[[1]], [[0]]]
    assert result['largest_impulse_survived_at_every_phase_ns'] == {'0': 5.0}


def test_cli_robustness_help_and_bad_arguments():
    run = [sys.executable, '-m', 'fall_predictor.cli', 'robustness']
    assert 'largest impulse survived' in subprocess.run(run + ['--help'], capture_output=True, text=True).stdout
    bad = subprocess.run(run + ['--impulses', '-5'], capture_output=True, text=True)
    assert bad.returncode == 2 and '-5' in bad.stderr
