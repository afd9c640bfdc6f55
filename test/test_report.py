"""The sweep's written results (fall_predictor.learning.report): sweep.json and table.md, from
a hand-made sweep result."""
import json

import pytest

from fall_predictor.learning.report import sweep_json, sweep_table
from fall_predictor.learning.selection import SELECTION_RULE

from learning_fixtures import sweep_result


def test_sweep_json_marks_the_front_and_writes_nan_and_infinity_as_null():
    result = sweep_result()
    document = sweep_json(result)
    json.dumps(document, allow_nan=False)
    assert document['format'] == 'fall_predictor/sweep/v1'
    assert document['dataset'] == {'path': 'data', 'fingerprint': 'abc123', 'n_trajectories': 20,
                                   'n_fallen': 10, 'n_balanced': 10,
                                   'unreadable': {'traj_9': 'truncated'}}
    assert [p['pareto'] for p in document['points']] == [True, True, True, False]
    assert document['points'][3]['tau_lead_s'] is None                   # NaN
    assert document['points'][0]['n_pre_push_alarms'] == 0 and document['points'][0]['per_fold'] == []
    assert [s['name'] for s in document['selected']] == ['FP-L1', 'FP-L2', 'FP-L3']
    assert 'per_fold' not in document['selected'][0]['ours']
    assert document['selected'][1]['ours']['tau_plus_s'] == 0.0          # FPR 0.05 <= 0.06
    assert document['selection_rule'] == SELECTION_RULE
    # Best lead within an FPR budget b, averaged over b in [0, 0.5], by hand: learned front
    # (0, 0.2), (0.05, 0.7), (0.3, 0.9): (0.05 * 0.2 + 0.25 * 0.7 + 0.2 * 0.9) / 0.5 = 0.73;
    # each baseline is one point (FPR f, lead l), worth l * (0.5 - f) / 0.5 (0 below f).
    assert document['pareto_mean_lead_s'] == pytest.approx(
        {'max_fpr': 0.5, 'learned': 0.73, 'baseline_com_height': 0.14 * 0.4 / 0.5,
         'baseline_momentum': 0.6 * 0.3 / 0.5, 'baseline_capture_point': 0.5 * 0.1 / 0.5})
    assert document['baselines']['momentum'][0]['threshold'] == [10.0, None]
    assert document['baselines']['com_height'][0]['threshold'] == 0.45
    assert [p['n_train'] for p in document['learning_curve']] == [5.0, 9.0]
    assert document['timing']['jobs'] == 2 and document['settings']['folds'] == 2


def test_sweep_table_lists_the_analogues_baselines_curve_and_every_point():
    table = sweep_table(sweep_result())
    lines = table.splitlines()
    assert lines[0] == '# Cross-validated sweep'
    assert '| | FP-L1 (paper) | ours | FP-L2 (paper) | ours | FP-L3 (paper) | ours |' in lines
    assert '| FPR | 0.460 | 0.300 | 0.060 | 0.050 | 0.005 | 0.000 |' in lines
    assert '| momentum | 10.000, inf | 0.200 | 0.60 | 1 |' in lines
    assert '| 5 | 0.200 ± 0.100 | 0.60 ± 0.00 | 1.0 |' in lines
    assert any(line.startswith('| +0.50* | 0.000 |') for line in lines)    # on the front
    assert any(line.startswith('| +0.50 | 0.060 | 0.000 | — |') for line in lines)  # NaN lead
    assert ('learned 0.730 s; com_height 0.112 s, momentum 0.360 s, capture_point 0.100 s.'
            in table)                                        # the same areas, by hand
    assert 'Command: `fall-predictor sweep`.' in table
    assert 'total 14 s with 2 job(s)' in table
    assert '## Learning curve' not in sweep_table(sweep_result(with_learning_curve=False))
