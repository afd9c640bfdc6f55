"""What disturbed each run (fall_predictor.learning.run_groups): a push's impulse, the ambiguous
band found from the data, the groups cross-validation folds keep whole."""
import math

import numpy as np
import pytest

from fall_predictor.data.dataset import IndexRow
from fall_predictor.learning.run_groups import (RunDisturbance, ambiguous_band, disturbances,
                                                fold_groups)


def _row(tid: str, force_n: float, cause: str = 'push', t_onset=None) -> IndexRow:
    return IndexRow(tid, f'bags/{tid}', force_n, 0.0, 0.1, 2.0, 2.1, False, None, None, None,
                    1.0, 6.1, 5100, cause=cause, t_onset=t_onset)


def test_a_pushs_impulse_and_a_rows_cause():
    runs = disturbances([_row('a', 350.0), _row('b', 0.0, 'trip', 2.37), _row('c', 0.0, 'walk')],
                        prefix='dev')
    assert runs['dev/a'] == RunDisturbance('push', 2.0, pytest.approx(35.0))
    assert runs['dev/b'] == RunDisturbance('trip', 2.37, None)
    assert runs['dev/c'].onset_s is None and runs['dev/c'].impulse_ns is None


def test_a_push_of_unknown_force_has_no_impulse_and_no_band():
    """A robot's own recordings carry no push force (NaN): the push counts, of no impulse (no
    band: evaluate's per-band figures leave it out, as for a run without an index row)."""
    run = disturbances([_row('r', math.nan), _row('s', math.inf)])
    assert run['r'] == RunDisturbance('push', 2.0, None)
    assert run['s'].impulse_ns is None


def test_the_ambiguous_band_is_found_where_20_to_80_percent_fall():
    """Pushes of 0-80 N s whose fall probability is a logistic of centre 40 N s and scale 5 N s:
    the band is 40 -+ 5 ln 4 = [33.07, 46.93] N s, recovered within 2 N s from 4000 draws."""
    rng = np.random.default_rng(3)
    impulse = rng.uniform(0.0, 80.0, 4000)
    fallen = rng.uniform(size=impulse.size) < 1.0 / (1.0 + np.exp(-(impulse - 40.0) / 5.0))
    band = ambiguous_band(impulse, fallen)
    assert band.low_ns == pytest.approx(40.0 - 5.0 * math.log(4.0), abs=2.0)
    assert band.high_ns == pytest.approx(40.0 + 5.0 * math.log(4.0), abs=2.0)
    assert band.contains(40.0) and not band.contains(20.0) and not band.contains(None)


def test_a_threshold_that_separates_the_outcomes_gives_a_narrow_band_around_it():
    impulse = np.arange(0.0, 60.0, 1.0)
    band = ambiguous_band(impulse, impulse >= 30.0)
    assert 28.0 < band.low_ns < band.high_ns < 31.0


def test_no_band_without_a_rising_trend_or_enough_of_both_outcomes():
    impulse = np.arange(0.0, 60.0, 1.0)
    assert ambiguous_band(impulse, impulse < 30.0) is None          # falls drop with the impulse
    assert ambiguous_band(impulse, impulse >= 58.0) is None         # two falls
    assert ambiguous_band(impulse, np.zeros(60, bool)) is None


def test_fold_groups_band_pushes_by_impulse_and_keep_each_other_cause_whole():
    rows = [_row(f'p{i}', 10.0 * i) for i in range(10)] + [_row('t0', 0.0, 'trip', 2.2),
                                                            _row('t1', 0.0, 'trip', 2.4)]
    ids = [r.trajectory_id for r in rows][::-1]          # order does not matter
    groups = dict(zip(ids, fold_groups(ids, disturbances(rows), bands=5)))
    assert groups['t0'] == groups['t1'] == ('trip',)
    assert [groups[f'p{i}'] for i in range(10)] == [('push', i // 2) for i in range(10)]
    # a trajectory without an index row is a push of unknown impulse, at the bottom
    assert fold_groups(['x', 'p9'], disturbances(rows), bands=2) == [('push', 0), ('push', 1)]
