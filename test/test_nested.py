"""Nested selection of operating points (fall_predictor.learning.nested) on hand-made fold
results with a known answer."""
import pytest

from fall_predictor.learning.crossval import FoldFit
from fall_predictor.learning.intervals import wilson_interval
from fall_predictor.learning.metrics import EvaluationResult
from fall_predictor.learning.nested import fixed_setting, nested_operating_point, nested_over_grid

A = (0.0, 0.0)      # long lead, false alarms concentrated in fold 2
B = (0.5, 0.0)      # short lead, no false alarms


def result(false_positives: int, lead_s: float) -> EvaluationResult:
    return EvaluationResult(12, 10, 2, false_positives, false_positives / 10, lead_s, 0, 0, 0,
                            1.5, lead_s / 1.5, leads_s=(lead_s, lead_s))


def fits() -> list[FoldFit]:
    a_false_positives = {0: 0, 1: 0, 2: 3}
    out = []
    for fold in range(3):
        for (tau_plus, tau_his), res in ((A, result(a_false_positives[fold], 1.0)),
                                         (B, result(0, 0.5))):
            out.append(FoldFit(fold, tau_plus, None, 900, (1,), (1,), 0.1, {tau_his: res}))
    return out


def test_nested_choice_differs_from_hindsight_and_is_reported_on_the_outer_fold():
    point = nested_operating_point(fits(), max_fpr=0.1)
    # in hindsight A qualifies (3/30 = 0.1) with lead 1.0 ...
    assert point.selected_in_hindsight == A
    assert point.hindsight.fpr == pytest.approx(0.1) and point.hindsight.tau_lead_s == 1.0
    # ... but leaving out fold 0 or 1 puts A at 3/20 = 0.15: those folds get B; fold 2 gets A
    assert point.chosen == (B, B, A)
    assert point.outer.n_false_positives == 3 and point.outer.n_balanced == 30
    assert point.outer.tau_lead_s == pytest.approx((4 * 0.5 + 2 * 1.0) / 6)
    assert point.outer.fpr_ci95 == pytest.approx(wilson_interval(3, 30))
    low, high = point.outer.tau_lead_ci95
    assert 0.5 <= low <= point.outer.tau_lead_s <= high <= 1.0


def test_a_grid_of_three_part_settings_is_chosen_as_the_two_part_one():
    # (tau_plus, decision threshold, tau_his): A and B of fits() at threshold 1.0, and at
    # threshold 2.0 a setting with no false alarm and a lead between theirs (0.8 s).
    grid = {fold: {} for fold in range(3)}
    for fit in fits():
        for tau_his, res in fit.results.items():
            grid[fit.fold][(fit.tau_plus_s, 1.0, tau_his)] = res
    for fold in range(3):
        grid[fold][(0.5, 2.0, 0.0)] = result(0, 0.8)
    point = nested_over_grid(grid, max_fpr=0.1)
    a, c = (0.0, 1.0, 0.0), (0.5, 2.0, 0.0)
    assert point.selected_in_hindsight == a
    # leaving out fold 0 or 1, A is over budget and C is the longest lead without false alarms
    assert point.chosen == (c, c, a)
    assert point.outer.n_false_positives == 3
    assert point.outer.tau_lead_s == pytest.approx((4 * 0.8 + 2 * 1.0) / 6)
    # without C the choice is the two-part grid's, B in place of C
    for fold in range(3):
        del grid[fold][c]
    two_part = nested_operating_point(fits(), max_fpr=0.1)
    three_part = nested_over_grid(grid, max_fpr=0.1)
    assert [s[0::2] for s in three_part.chosen] == list(two_part.chosen)
    assert three_part.outer == two_part.outer
    del grid[2][a]
    with pytest.raises(ValueError, match='same settings'):
        nested_over_grid(grid, max_fpr=0.1)


def test_fixed_setting_needs_no_selection_and_rejects_unknown_settings():
    pooled = fixed_setting(fits(), B)
    assert pooled.fpr == 0.0 and pooled.tau_lead_s == 0.5 and pooled.n_fallen == 6
    with pytest.raises(ValueError, match='not in the cross-validated grid'):
        fixed_setting(fits(), (0.25, 0.06))


def test_results_without_leads_cannot_be_pooled():
    bare = [FoldFit(k, 0.0, None, 9, (1,), (1,), 0.1,
                    {0.0: EvaluationResult(12, 10, 2, 0, 0.0, 1.0, 0, 0, 0, 1.5, 0.6)})
            for k in range(2)]
    with pytest.raises(ValueError, match='leads_s'):
        fixed_setting(bare, (0.0, 0.0))


def _pooled(false_positives: int, balanced: int, lead_s: float):
    from fall_predictor.learning.nested import PooledFigures
    return PooledFigures(balanced, false_positives, false_positives / balanced,
                         wilson_interval(false_positives, balanced), 10, lead_s, (lead_s, lead_s), 0)


def test_the_upper_bound_rule_chooses_a_stricter_point_than_the_point_estimate():
    """Budget 0.05 over 100 survived runs: 4 false alarms (0.04, bound 0.087) meet it on the
    point estimate with the longest lead; on the one-sided 95 % Wilson bound only the setting
    without a false alarm does (bound 0.026), with a shorter lead."""
    from fall_predictor.learning.nested import choose_setting, fpr_bound

    pooled = {(0.0, 0.0): _pooled(4, 100, 0.8), (0.0, 0.05): _pooled(2, 100, 0.6),
              (0.0, 0.1): _pooled(0, 100, 0.4)}
    assert choose_setting(pooled, 0.05) == (0.0, 0.0)
    assert choose_setting(pooled, 0.05, rule='ucb') == (0.0, 0.1)
    assert fpr_bound(pooled[0.0, 0.1], 'ucb') == pytest.approx(1.6449 ** 2 / (100 + 1.6449 ** 2), abs=1e-5)
    assert fpr_bound(pooled[0.0, 0.05], 'ucb') > 0.05 > pooled[0.0, 0.05].fpr
    # a lower level tightens the bound: at 60 % four false alarms fit the budget again (0.047)
    assert choose_setting(pooled, 0.05, rule='ucb', level=0.6) == (0.0, 0.0)
    # no setting within the budget: the lowest bound (here also the lowest FPR)
    assert choose_setting(pooled, 0.01, rule='ucb') == (0.0, 0.1)
    with pytest.raises(ValueError, match='FPR rule'):
        choose_setting(pooled, 0.05, rule='median')


def test_nested_selection_by_the_upper_bound_records_its_rule():
    point = nested_operating_point(fits(), max_fpr=0.1, rule='ucb', level=0.95)
    # no setting's bound meets 0.1 on 20 survived runs (0/20: 0.12): the lowest bound, B, where
    # A's 3 false alarms are among the inner folds, and the longer lead, A, where neither has any
    assert point.rule == 'ucb' and point.chosen == (B, B, A)
